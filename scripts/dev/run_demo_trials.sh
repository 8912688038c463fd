#!/usr/bin/env bash
# The demo's trial, N times (default 10), as a user runs it: demo.launch with rviz drawing
# (software rendering under Xvfb), the trial started from the DrillingPanel's Start button
# (rostest demo_panel_trial). Prints each run's panel summary and the count of SUCCESS verdicts
# (the demo's acceptance: "10 runs on a 2-core machine: 10 successes"). Results in
# ${OUT}/demo_trials.md.
set -eu
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
# shellcheck source=scripts/dev/workspace_env.sh
source "${ROOT}/scripts/dev/workspace_env.sh"
OUT="${PEDICLE_DRILLING_OUT:-${ROOT}/results}"
RUNS="${1:-10}"
mkdir -p "${OUT}"
log="$(mktemp)"
successes=0
{
  echo "# The demo's trial, ${RUNS} runs (demo.launch, rviz under Xvfb, Start in the panel)"
  echo
  echo "| run | panel summary |"
  echo "|---|---|"
} > "${OUT}/demo_trials.md.tmp"
for run in $(seq 1 "${RUNS}"); do
  xvfb-run -a -s "-screen 0 1600x1000x24" \
    rostest --text pedicle_drilling demo_panel_trial.test > "${log}" 2>&1 || true
  summary="$(grep -o 'panel: .*' "${log}" | tail -1 | sed 's/\x1b\[[0-9;]*m//g')"
  if [ -z "${summary}" ]; then
    # Kept for diagnosis: the whole rostest output of a run without the panel's summary.
    cp "${log}" "${OUT}/demo_run_${run}.log"
    summary="(no summary: $(grep -E 'FAIL|Error' "${log}" | grep -v 'media_export' | head -1); log ${OUT}/demo_run_${run}.log)"
  fi
  case "${summary}" in *"verdict SUCCESS"*) successes=$((successes + 1)) ;; esac
  echo "run ${run}: ${summary}"
  echo "| ${run} | ${summary} |" >> "${OUT}/demo_trials.md.tmp"
done
rm -f "${log}"
{ echo; echo "${successes} of ${RUNS} runs: verdict SUCCESS."; } >> "${OUT}/demo_trials.md.tmp"
mv "${OUT}/demo_trials.md.tmp" "${OUT}/demo_trials.md"
echo "${successes} of ${RUNS} runs: verdict SUCCESS (${OUT}/demo_trials.md)"
