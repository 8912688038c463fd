# Sourced by the dev scripts (run_main, run_bench, run_calibration, run_tests) after they set
# ROOT: /usr/bin first in PATH (Debian's ROS Python modules are only visible to /usr/bin/python3)
# and the built workspace's environment. setup.bash reads unset variables (ROS_DISTRO, ...):
# it is sourced without `set -u`, which is restored after.
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:${PATH}"
set +u
# shellcheck disable=SC1091
source "${ROOT}/catkin_ws/devel/setup.bash"
set -u
