#!/usr/bin/env bash
# Runs every test tier and prints one summary line "N passed, N failed".
#   1. gtest suites of the core (test/gtest -> devel/lib/pedicle_drilling/test_*)
#   2. rostest scenarios (test/rostest/*.test, and test/rostest_gtest/*.test with a C++ test
#      node), one at a time, the rviz offscreen check included
#   3. python tests (test/python), pytest
# Needs a DISPLAY for the rviz scenario: `make test` runs this under xvfb-run.
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

echo "== rostest scenarios"
[ "${TIER}" = fast ] && echo "  (none in the fast tier)"
for scenario in "${ROOT}"/test/rostest/*.test "${ROOT}"/test/rostest_gtest/*.test; do
  name="$(basename "${scenario}" .test)"
  [ "${TIER}" = all ] || continue
  [[ -z "${FILTER}" || "${name}" == *"${FILTER}"* ]] || continue
  start=$(date +%s)
  timeout 900 rostest --results-filename "rostest_${name}.xml" --results-base-dir "${WS}/build/test_results" \
    pedicle_drilling "${name}.test" > "${LOGS}/rostest_${name}.log" 2>&1
  status=$?
  if [ ${status} -eq 0 ]; then
    echo "  ok     ${name} ($(( $(date +%s) - start )) s)"
  else
    echo "  FAILED ${name} ($(( $(date +%s) - start )) s), log: ${LOGS}/rostest_${name}.log"
    grep -E "FAIL|Error|error|Traceback|assert|Assertion|not true" "${LOGS}/rostest_${name}.log" \
      | cut -c1-300 | head -n 20
    # A python test's failure message and the lines it adds, each cut short enough to be printed.
    grep -E -A4 "^AssertionError" "${LOGS}/rostest_${name}.log" | cut -c1-300 | head -n 10
    if ! ls "${RESULTS}"/*"${name}"*.xml >/dev/null 2>&1; then
      printf '<testsuite name="%s" tests="1" failures="1"><testcase classname="rostest" name="%s"><failure message="rostest exit %s"/></testcase></testsuite>\n' \
        "${name}" "${name}" "${status}" > "${RESULTS}/rostest-${name}-crash.xml"
    fi
  fi
done

echo "== python tests"
PYTHON_TESTS=("${ROOT}/test/python")
if [ "${TIER}" = fast ]; then
  PYTHON_TESTS=("${FAST_PYTHON[@]/#/${ROOT}/test/python/}")
fi
if ls "${ROOT}"/test/python/test_*.py >/dev/null 2>&1; then
  /usr/bin/python3 -m pytest -q -p no:cacheprovider ${FILTER:+-k "${FILTER}"} "${PYTHON_TESTS[@]}" \
    --junitxml="${RESULTS}/pytest-python.xml" 2>&1 | tail -n 25
fi

echo "== summary"
/usr/bin/python3 "${ROOT}/scripts/dev/summarize_test_results.py" "${RESULTS}"
