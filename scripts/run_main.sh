#!/usr/bin/env bash
# The main job of `make run`: the experiment campaign of the paper (Sec. V) on the simulator,
#   1. the paper's design on the paper's bench protocol (the SPMS plays the identified linear
#      model, scenario_paper.yaml): 3 cases x 3 spindle speeds x 20 trials
#   2. beyond the bench: the bone moves as the virtual patient (lag, drift, small movements),
#      compensated with the paper's linear model (scenario_virtual_patient.yaml) and with the
#      hysteresis-aware model (scenario_hysteresis.yaml), 12000 rpm, 20 trials each
# Reports in results/campaign*/report.md.
set -eu
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:${PATH}"
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
# setup.bash reads unset variables (ROS_DISTRO, ...): source it without `set -u`.
set +u
# shellcheck disable=SC1091
source "${ROOT}/catkin_ws/devel/setup.bash"
set -u
OUT="${PEDICLE_DRILLING_OUT:-${ROOT}/results}"
JOBS="${JOBS:-2}"
mkdir -p "${OUT}"
start=$(date +%s)
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_paper.yaml" \
  --jobs "${JOBS}" --out "${OUT}/campaign"
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_virtual_patient.yaml" \
  --jobs "${JOBS}" --out "${OUT}/campaign_virtual_patient"
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_hysteresis.yaml" \
  --jobs "${JOBS}" --out "${OUT}/campaign_hysteresis"
echo "main job: done in $(( $(date +%s) - start )) s"
echo "  ${OUT}/campaign/report.md"
echo "  ${OUT}/campaign_virtual_patient/report.md"
echo "  ${OUT}/campaign_hysteresis/report.md"
sed -n '/^## Results/,/^## Figures/p' "${OUT}/campaign/report.md"
