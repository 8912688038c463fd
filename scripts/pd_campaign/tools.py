"""Where the package's built tools are, for the scripts that run them."""
import os

_ROOT = os.path.join(os.path.dirname(os.path.realpath(__file__)), '..', '..')


def tool(name):
    """Command of a built tool: $PEDICLE_DRILLING_BIN_DIR, the devel space, or rosrun."""
    candidates = [os.environ.get('PEDICLE_DRILLING_BIN_DIR', ''),
                  os.path.join(_ROOT, 'catkin_ws', 'devel', 'lib', 'pedicle_drilling')]
    for d in candidates:
        if d and os.access(os.path.join(d, name), os.X_OK):
            return [os.path.join(d, name)]
    return ['rosrun', 'pedicle_drilling', name]
