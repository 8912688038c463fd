#!/usr/bin/env bash
# Runs every test tier and prints one summary line "N passed, N failed".
#   1. gtest suites of the core (test/gtest), through catkin
#   2. rostest scenarios (test/rostest/*.test), through catkin, rviz offscreen included
#   3. python tests (test/python), pytest
# Needs a DISPLAY for the rviz scenario: `make test` runs this under xvfb-run.
set -u
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:${PATH}"
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
WS="${ROOT}/catkin_ws"
# setup.bash reads unset variables (ROS_DISTRO, ...): source it without `set -u`.
set +u
# shellcheck disable=SC1091
source "${WS}/devel/setup.bash"
set -u
RESULTS="${WS}/build/test_results"
export PEDICLE_DRILLING_ARTIFACTS="${WS}/build/test_artifacts"
export PEDICLE_DRILLING_BIN_DIR="${WS}/devel/lib/pedicle_drilling"
export ROS_LOG_DIR="${WS}/build/ros_log"
rm -rf "${RESULTS}" "${PEDICLE_DRILLING_ARTIFACTS}"
mkdir -p "${RESULTS}/pedicle_drilling" "${PEDICLE_DRILLING_ARTIFACTS}"

echo "== gtest and rostest suites"
# -j1: rostests share fixed ports and the two cores; run them one at a time.
(cd "${WS}/build" && make -j1 run_tests 2>&1) | grep -E "^\[( RUN|  FAILED|  PASSED|==========|       OK)|^\[ROSTEST\]|^\[Testcase|FAILURE|ERROR|Error|error:" || true

echo "== python tests"
if ls "${ROOT}"/test/python/test_*.py >/dev/null 2>&1; then
  /usr/bin/python3 -m pytest -q -p no:cacheprovider "${ROOT}/test/python" \
    --junitxml="${RESULTS}/pedicle_drilling/pytest-python.xml" 2>&1 | tail -n 25
fi

echo "== summary"
/usr/bin/python3 "${ROOT}/scripts/summarize_test_results.py" "${RESULTS}"
