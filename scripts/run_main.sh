#!/usr/bin/env bash
# The main job of `make run`: the experiment campaign of the paper (Sec. V) on the simulator,
#   1. the paper's design on the paper's bench protocol (the SPMS plays the identified linear
#      model, scenario_paper.yaml): 3 cases x 3 spindle speeds x 200 trials (core engine)
#   2. beyond the bench: the bone moves as the virtual patient (lag, drift, small movements),
#      compensated with the paper's linear model (scenario_virtual_patient.yaml) and with the
#      hysteresis-aware model (scenario_hysteresis.yaml), 12000 rpm, 20 trials each (ROS
#      pipeline: the core engine does not agree with it there yet)
#   3. 5 trials per case of design 1 through the full ROS pipeline, twice, and their agreement
#      with the core engine (engine_agreement.md)
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
# 1. The paper's design on the core engine (deterministic, all cores): 200 trials per case and
#    spindle speed, so that the Wilson intervals span a few points.
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_paper.yaml" --trials 200 \
  --jobs "${JOBS}" --out "${OUT}/campaign"
# 2. Beyond the bench: the bone moves as the virtual patient, linear vs hysteresis model. On the
#    ROS pipeline: the core engine does not yet agree with it on this scenario (README,
#    "Engine agreement"), so these stay on the engine the earlier results came from.
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_virtual_patient.yaml" \
  --engine ros --jobs "${JOBS}" --out "${OUT}/campaign_virtual_patient"
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_hysteresis.yaml" \
  --engine ros --jobs "${JOBS}" --out "${OUT}/campaign_hysteresis"
# 3. The integration check: the first trials of the same design through the full ROS pipeline,
#    twice, trial by trial beside the core engine (the same seeds).
for run in ros ros_repeat; do
  rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_paper.yaml" \
    --rpm 12000 --trials 5 --engine ros --jobs "${JOBS}" --out "${OUT}/campaign_${run}"
done
export PYTHONPATH="${ROOT}/scripts:${PYTHONPATH:-}"
{
  echo "# Engine agreement (same seeds)"
  echo
  python3 -m pd_campaign.agreement "${OUT}/campaign_ros" "${OUT}/campaign" \
    --label-a ros --label-b core
  echo
  python3 -m pd_campaign.agreement "${OUT}/campaign_ros" "${OUT}/campaign_ros_repeat" \
    --label-a ros --label-b "ros (second run)"
} > "${OUT}/engine_agreement.md"
echo "main job: done in $(( $(date +%s) - start )) s"
echo "  ${OUT}/campaign/report.md"
echo "  ${OUT}/campaign_virtual_patient/report.md"
echo "  ${OUT}/campaign_hysteresis/report.md"
echo "  ${OUT}/engine_agreement.md"
sed -n '/^## Results/,/^## Figures/p' "${OUT}/campaign/report.md"
