"""Where the package's built tools and files are, for the scripts that run them."""
import argparse
import glob
import hashlib
import os

import rospkg

PACKAGE = 'pedicle_drilling'
_ROOT = os.path.join(os.path.dirname(os.path.realpath(__file__)), '..', '..')


class PackageNotFound(RuntimeError):
    """The environment does not have the package: no setup.bash of its workspace sourced."""


def package_dir():
    """The package's folder, the one with config/, urdf/, launch_scripts/ and rviz/, as rospack
    finds it: the source folder in a devel space, share/pedicle_drilling in an install space."""
    try:
        return rospkg.RosPack().get_path(PACKAGE)
    except rospkg.ResourceNotFound:
        raise PackageNotFound(
            'the package %s is not on ROS_PACKAGE_PATH (%s): source the setup.bash of the '
            'workspace that has it (its devel or install space)'
            % (PACKAGE, os.environ.get('ROS_PACKAGE_PATH') or 'not set')) from None


def tool(name):
    """Command of a built tool: $PEDICLE_DRILLING_BIN_DIR, the devel space, or rosrun."""
    candidates = [os.environ.get('PEDICLE_DRILLING_BIN_DIR', ''),
                  os.path.join(_ROOT, 'catkin_ws', 'devel', 'lib', 'pedicle_drilling')]
    for d in candidates:
        if d and os.access(os.path.join(d, name), os.X_OK):
            return [os.path.join(d, name)]
    return ['rosrun', 'pedicle_drilling', name]


def build_id():
    """What produced a trial row, as one digest: the trial_engine executable, the package's
    shared libraries beside it and this Python package's sources (a rebuild of changed C++ or a
    changed analysis changes it). None when trial_engine is not found in a folder (rosrun only)."""
    command = tool('trial_engine')
    if len(command) != 1:
        return None
    lib_dir = os.path.dirname(os.path.dirname(command[0]))  # devel/lib/pedicle_drilling -> lib
    package = os.path.dirname(os.path.realpath(__file__))
    paths = [command[0]] + sorted(glob.glob(os.path.join(lib_dir, 'libpedicle_drilling*.so')))
    # The package's sources, its sub-packages' included, each named by its path in it.
    sources = sorted(os.path.relpath(path, package) for path in
                     glob.glob(os.path.join(glob.escape(package), '**', '*.py'), recursive=True))
    digest = hashlib.sha256()
    for path in paths:
        digest.update(os.path.basename(path).encode() + b'\0')
        update_digest(digest, path)
    for name in sources:
        digest.update(name.encode() + b'\0')
        update_digest(digest, os.path.join(package, name))
    return digest.hexdigest()[:16]


def update_digest(digest, path):
    """`digest` (a hashlib object) updated with the content of the file `path`."""
    with open(path, 'rb') as handle:
        for chunk in iter(lambda: handle.read(1 << 20), b''):
            digest.update(chunk)


class _GivenOnce:
    """Refuses an option given twice on one command line (`--rpm 12000 ... --rpm 16000` would
    otherwise silently keep the last): the same rule as the C++ tools (src/tools/tool_cli.hpp).
    The options seen are kept in the namespace being filled, so a parser can be used again."""

    def __call__(self, parser, namespace, values, option_string=None):
        given = namespace.__dict__.setdefault('_options_given', set())
        if self.dest in given:
            parser.error('option %s given more than once: give it once'
                         % (option_string or self.dest))
        given.add(self.dest)
        super().__call__(parser, namespace, values, option_string)


class _StoreOnce(_GivenOnce, argparse._StoreAction):
    pass


class _StoreTrueOnce(_GivenOnce, argparse._StoreTrueAction):
    pass


def argument_parser(**kwargs):
    """An argparse parser whose options may each be given once (exit 2 naming a repeated one)."""
    parser = argparse.ArgumentParser(**kwargs)
    parser.register('action', None, _StoreOnce)
    parser.register('action', 'store', _StoreOnce)
    parser.register('action', 'store_true', _StoreTrueOnce)
    return parser
