#!/usr/bin/env bash
# Runs every test tier and prints one summary line "N passed, N failed".
#   1. gtest suites of the core (test/gtest -> devel/lib/pedicle_drilling/test_*)
#   2. rostest scenarios (test/rostest/*.test, and test/rostest_gtest/*.test with a C++ test
#      node), the rviz offscreen checks included: ROSTEST_JOBS lanes at once (default 2), each
#      lane's scenarios one after another on an X display of its own, the wall-clock scenarios
#      alone at the end (run_rostests.py)
#   3. python tests (test/python), pytest on PYTEST_JOBS workers (default 2)
# Needs a DISPLAY for the python tests that draw: `make test` runs this under xvfb-run.
# Optional: TEST_FILTER=<substring> runs only the gtests/rostests/python files whose name has it.
# TEST_TIER=fast (`make test-fast`): the gtest suites and the python files of FAST_PYTHON (unit
# tests and the documents' checks), no rostest: a developer's loop of about a minute.
set -u
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
WS="${ROOT}/catkin_ws"
# shellcheck source=scripts/dev/workspace_env.sh
source "${ROOT}/scripts/dev/workspace_env.sh"
FILTER="${TEST_FILTER:-}"
TIER="${TEST_TIER:-all}"
# The fast tier's python files: each runs in seconds, and none starts a ROS master or a campaign.
FAST_PYTHON=(test_format.py test_function_length.py test_no_issue_numbers.py test_doc_links.py
  test_node_reference.py test_generated_docs.py test_no_machine_paths.py test_readme.py
  test_hardware_guide.py test_atomic_outputs.py test_commit_msg_hook.py test_outcome.py
  test_summarize_test_results.py test_noninferiority.py test_doc_numbers.py
  test_package_imports.py test_sensitivity_tables.py)
if [ "${TIER}" != all ] && [ "${TIER}" != fast ]; then
  echo "run_tests: TEST_TIER=${TIER}: not all or fast" >&2
  exit 2
fi
RESULTS="${WS}/build/test_results/pedicle_drilling"
export PEDICLE_DRILLING_ARTIFACTS="${WS}/build/test_artifacts"
export PEDICLE_DRILLING_BIN_DIR="${WS}/devel/lib/pedicle_drilling"
export ROS_LOG_DIR="${WS}/build/ros_log"
rm -rf "${RESULTS}" "${PEDICLE_DRILLING_ARTIFACTS}"
mkdir -p "${RESULTS}" "${PEDICLE_DRILLING_ARTIFACTS}"
LOGS="${WS}/build/test_logs"
mkdir -p "${LOGS}"

echo "== gtest suites"
# One suite per test/gtest/test_<module>.cpp: a binary left in devel by a removed test is not
# run, and a test whose binary is missing fails.
for source in "${ROOT}"/test/gtest/test_*.cpp; do
  name="$(basename "${source}" .cpp)"
  binary="${PEDICLE_DRILLING_BIN_DIR}/${name}"
  [[ -z "${FILTER}" || "${name}" == *"${FILTER}"* ]] || continue
  if [ ! -x "${binary}" ]; then
    echo "  FAILED ${name}: no binary ${binary} (make tests)"
    printf '<testsuite name="%s" tests="1" failures="1"><testcase classname="%s" name="built"><failure message="no binary"/></testcase></testsuite>\n' \
      "${name}" "${name}" > "${RESULTS}/gtest-${name}.xml"
    continue
  fi
  start=$(date +%s)
  if timeout 600 "${binary}" --gtest_output="xml:${RESULTS}/gtest-${name}.xml" \
      > "${LOGS}/${name}.log" 2>&1; then
    echo "  ok     ${name} ($(( $(date +%s) - start )) s)"
  else
    echo "  FAILED ${name} ($(( $(date +%s) - start )) s), log: ${LOGS}/${name}.log"
    grep -E "Failure|FAILED|Expected|Which is|error" "${LOGS}/${name}.log" | head -n 20
    if [ ! -s "${RESULTS}/gtest-${name}.xml" ]; then  # crashed before writing its results
      printf '<testsuite name="%s" tests="1" failures="1"><testcase classname="%s" name="crashed"><failure message="no result file"/></testcase></testsuite>\n' \
        "${name}" "${name}" > "${RESULTS}/gtest-${name}.xml"
    fi
  fi
done

# The python tests: PYTEST_JOBS workers (pytest-xdist, default 2), a test file to one worker, so
# that a file's module fixtures are built once.
python_tier() {
  local tests=("${ROOT}/test/python")
  if [ "${TIER}" = fast ]; then
    tests=("${FAST_PYTHON[@]/#/${ROOT}/test/python/}")
  fi
  /usr/bin/python3 -m pytest -q -p no:cacheprovider -n "${PYTEST_JOBS:-2}" --dist loadfile \
    ${FILTER:+-k "${FILTER}"} "${tests[@]}" --junitxml="${RESULTS}/pytest-python.xml" 2>&1
}

# The rostest scenarios: ROSTEST_JOBS lanes at once (default 2), each on a private X display;
# ROSTEST_JOBS=1 runs them one at a time.
run_rostests() {
  /usr/bin/python3 "${ROOT}/scripts/dev/run_rostests.py" --root "${ROOT}" \
    --results-base-dir "${WS}/build/test_results" --logs "${LOGS}" \
    --jobs "${ROSTEST_JOBS:-2}" ${FILTER:+--filter "${FILTER}"}
}

# One tier after the other: the python tests beside the rostest lanes loaded the machine (load
# average above 10 on 2 cores) until the lockstep scenarios' wall-time watchdogs tripped.
echo "== rostest scenarios"
if [ "${TIER}" = fast ]; then
  echo "  (none in the fast tier)"
else
  run_rostests
fi
echo "== python tests"
python_tier | tail -n 25

echo "== summary"
/usr/bin/python3 "${ROOT}/scripts/dev/summarize_test_results.py" "${RESULTS}"
