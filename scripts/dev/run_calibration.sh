#!/usr/bin/env bash
# Every calibration of a constant chosen by looking at simulated outcomes, on
# CALIBRATION seeds only (doc/experiments.md, "Seed spaces"). Published numbers come from
# `make run`, on evaluation seeds. Outputs in results/calibration/ (or $PEDICLE_DRILLING_CAL_OUT);
# what each part decided is in doc/campaign_results.md, "Constants chosen on simulated outcomes".
#   1. the plausibility bounds (planner outer_cortical_max_mm, recognizer cancellous_deadline):
#      the fault campaign, 100 calibration seeds per fault (no breakthrough; who stops), and the
#      fault-free paper design and virtual patient (no plausibility stop of a fault-free trial)
#   2. the force sensor's DAQ rate and the chisel-edge share against Fig. 16 (peak_forces
#      protocol, 100 calibration seeds per case, the candidate rows of doc/simulator_physics.md)
#   3. the planner's stop_hold_s (hold after a recognizer stop, or retreat at once): the
#      amplitude fault, 400 calibration seeds, and the paper design at 12000 rpm, 200 per case,
#      each with a 1 s hold and without (paired seeds); then the retreat's acceleration
#      (retreat_accel_m_s2, 0.05 against 1 m/s^2) on the same trials
#   4. the planner's controller watch (controller_watch/*_tolerance_*): how close the
#      fault-free trials of both benches and the command faults come to each tolerance (the
#      worst |desired - commanded| and |error| per trial as a fraction of it), 100 calibration
#      seeds per case (scripts/dev/calibration_watch.py writes watch.md)
#   5. the plan's depth margin (simulator plan/margin_mm): the plan's far-side error and the depth
#      limit's estimate error on the paper design (3 cases, 12000 rpm), the virtual patient, and
#      the tracked-marker compensator with the amplitude fault, 100 calibration seeds each
#      (scripts/dev/calibration_depth_margin.py writes depth_margin.md; outcomes are not read)
#   6. the AdaptiveModelCompensator's memory (forgetting_time_s 1, 2, 3 s) and its gate
#      (gate_mm, disagree_samples): the amplitude fault and the realistic bench, compensated at
#      12000 rpm, 100 calibration seeds of base seed 11 each, beside the paper's compensator
# Usage: scripts/dev/run_calibration.sh [bounds|fig16|hold|watch|depth|adaptive|all]
#        (default all)
set -eu
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
# shellcheck source=scripts/dev/workspace_env.sh
source "${ROOT}/scripts/dev/workspace_env.sh"
OUT="${PEDICLE_DRILLING_CAL_OUT:-${ROOT}/results/calibration}"
JOBS="${JOBS:-2}"
WHAT="${1:-all}"
SEED=1  # the calibration base seed of every part below
mkdir -p "${OUT}"
campaign() { rosrun pedicle_drilling campaign --seed-space calibration --seed "${SEED}" --jobs "${JOBS}" "$@"; }
if [ "${WHAT}" = bounds ] || [ "${WHAT}" = all ]; then
  campaign --scenario "${ROOT}/config/scenario_faults.yaml" --trials 100 --out "${OUT}/faults"
  campaign --scenario "${ROOT}/config/scenario_paper.yaml" --rpm 12000,16000,20000 --trials 100 \
    --out "${OUT}/paper"
  campaign --scenario "${ROOT}/config/scenario_virtual_patient.yaml" --trials 100 \
    --out "${OUT}/virtual_patient"
fi
if [ "${WHAT}" = fig16 ] || [ "${WHAT}" = all ]; then
  rows=()
  # rate [Hz] and chisel-edge share: the rows of doc/simulator_physics.md that came within a
  # factor of 5 of the best Fig. 16 error on the earlier seeds. The grid's recognizer averages
  # blocks of 50 samples at every rate (pre_average_s = 50 / rate), as when it was calibrated:
  # each row's rate sets the block's length too.
  for row in 333.3333333333333:0.5 333.3333333333333:0.6 333.3333333333333:0.7 250:0.6 500:0.6 \
             250:0 200:0; do
    rate="${row%%:*}"; share="${row##*:}"
    block=$(awk "BEGIN { printf \"%.10g\", 50 / ${rate} }")
    scenario="${OUT}/peak_forces_${rate%%.*}_${share}.yaml"
    sed '/^seed_space/d' "${ROOT}/config/scenario_peak_forces.yaml" > "${scenario}"
    echo "simulator_params: {force_sensor_rate_hz: ${rate}, chisel_edge_share: ${share}}" \
      >> "${scenario}"
    echo "recognizer_params: {pre_average_s: ${block}}" >> "${scenario}"
    campaign --scenario "${scenario}" --trials 100 --out "${OUT}/peak_forces_${rate%%.*}_${share}"
    rows+=("${rate%%.*} Hz, s ${share}=${OUT}/peak_forces_${rate%%.*}_${share}")
  done
  python3 "${ROOT}/scripts/dev/calibration_fig16.py" "${rows[@]}" > "${OUT}/fig16_grid.md"
  cat "${OUT}/fig16_grid.md"
fi
if [ "${WHAT}" = hold ] || [ "${WHAT}" = all ]; then
  for hold in 1 0; do
    scenario="${OUT}/amplitude_hold${hold}.yaml"
    sed -e '/^seed_space/d' -e '/^faults:/,/command_delayed\]/d' \
      "${ROOT}/config/scenario_faults.yaml" > "${scenario}"
    printf 'faults: [breathing_amplitude]\nplanner_params: {stop_hold_s: %s}\n' "${hold}" \
      >> "${scenario}"
    campaign --scenario "${scenario}" --trials 400 --out "${OUT}/amplitude_hold${hold}"
    scenario="${OUT}/paper_hold${hold}.yaml"
    sed '/^seed_space/d' "${ROOT}/config/scenario_paper.yaml" > "${scenario}"
    printf 'planner_params: {stop_hold_s: %s}\n' "${hold}" >> "${scenario}"
    campaign --scenario "${scenario}" --rpm 12000 --trials 200 --out "${OUT}/paper_hold${hold}"
  done
  # Both runs above retreat at 1 m/s^2 (the default since); 0.05 m/s^2, the earlier default:
  for name in amplitude_hold0 paper_hold0; do
    sed 's/planner_params: {stop_hold_s: 0}/planner_params: {stop_hold_s: 0, retreat_accel_m_s2: 0.05}/' \
      "${OUT}/${name}.yaml" > "${OUT}/${name}_slow_retreat.yaml"
    args=(--trials 400)
    [ "${name}" = paper_hold0 ] && args=(--rpm 12000 --trials 200)
    campaign --scenario "${OUT}/${name}_slow_retreat.yaml" "${args[@]}" \
      --out "${OUT}/${name}_slow_retreat"
  done
fi
if [ "${WHAT}" = watch ] || [ "${WHAT}" = all ]; then
  campaign --scenario "${ROOT}/config/scenario_paper.yaml" --rpm 12000 --trials 100 \
    --out "${OUT}/watch_paper"
  campaign --scenario "${ROOT}/config/scenario_realistic.yaml" --rpm 12000 --trials 100 \
    --out "${OUT}/watch_realistic"
  scenario="${OUT}/watch_command_faults.yaml"
  sed -e '/^seed_space/d' -e '/^faults:/,/command_delayed\]/d' \
    "${ROOT}/config/scenario_faults.yaml" > "${scenario}"
  printf 'faults: [command_lost, command_delayed]\n' >> "${scenario}"
  campaign --scenario "${scenario}" --trials 100 --out "${OUT}/watch_command_faults"
  python3 "${ROOT}/scripts/dev/calibration_watch.py" "${OUT}/watch_paper" \
    "${OUT}/watch_realistic" "${OUT}/watch_command_faults" > "${OUT}/watch.md"
  cat "${OUT}/watch.md"
fi
if [ "${WHAT}" = depth ] || [ "${WHAT}" = all ]; then
  # The shipped scenarios run the paper's system (depth_limit false): here with the limit on.
  for name in paper virtual_patient; do
    sed -e '/^seed_space/d' -e '/^depth_limit/d' "${ROOT}/config/scenario_${name}.yaml" \
      > "${OUT}/depth_${name}.yaml"
    echo 'depth_limit: true' >> "${OUT}/depth_${name}.yaml"
  done
  campaign --scenario "${OUT}/depth_paper.yaml" --rpm 12000 --trials 100 \
    --out "${OUT}/depth_paper"
  campaign --scenario "${OUT}/depth_virtual_patient.yaml" --trials 100 \
    --out "${OUT}/depth_virtual_patient"
  scenario="${OUT}/depth_tracked_marker.yaml"
  sed -e '/^seed_space/d' -e '/^seed:/d' "${ROOT}/config/scenario_depth_limit_amplitude.yaml" \
    > "${scenario}"
  campaign --scenario "${scenario}" --trials 100 \
    --compensator pedicle_drilling/TrackedMarkerCompensator --out "${OUT}/depth_tracked_marker"
  python3 "${ROOT}/scripts/dev/calibration_depth_margin.py" "${OUT}/depth_paper" \
    "${OUT}/depth_virtual_patient" "${OUT}/depth_tracked_marker" > "${OUT}/depth_margin.md"
  cat "${OUT}/depth_margin.md"
fi
if [ "${WHAT}" = adaptive ] || [ "${WHAT}" = all ]; then
  adaptive() { rosrun pedicle_drilling campaign --seed-space calibration --seed 11 --trials 100 \
    --jobs "${JOBS}" --no-figures "$@"; }
  for memory in 1 2 3; do
    adaptive --scenario "${ROOT}/config/scenario_adaptive_amplitude.yaml" \
      --compensator-param "forgetting_time_s=${memory}" --out "${OUT}/adaptive_amplitude_${memory}"
    adaptive --scenario "${ROOT}/config/scenario_realistic.yaml" --case compensated --rpm 12000 \
      --compensator pedicle_drilling/AdaptiveModelCompensator \
      --compensator-param "forgetting_time_s=${memory}" --out "${OUT}/adaptive_realistic_${memory}"
  done
  adaptive --scenario "${ROOT}/config/scenario_adaptive_amplitude.yaml" \
    --compensator pedicle_drilling/PaperCompensator --out "${OUT}/adaptive_amplitude_paper"
  adaptive --scenario "${ROOT}/config/scenario_realistic.yaml" --case compensated --rpm 12000 \
    --out "${OUT}/adaptive_realistic_paper"
fi
echo "calibration: done; outputs in ${OUT}"
