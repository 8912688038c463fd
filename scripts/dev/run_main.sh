#!/usr/bin/env bash
# The main job of `make run`: the experiment campaign of the paper (Sec. V) on the simulator,
#   1. the paper's design on the paper's bench protocol (the SPMS plays the identified linear
#      model, scenario_paper.yaml): 3 cases, 200 trials per case at 12000 rpm and 100 at 16000
#      and 20000 rpm (core engine)
#   2. beyond the paper: the exact compensation profile on the same bench (scenario_exact.yaml),
#      and the bone moving as the virtual patient (lag, drift, small movements), compensated
#      with the paper's linear model (scenario_virtual_patient.yaml) and with the
#      hysteresis-aware model (scenario_hysteresis.yaml), 12000 rpm, 200 trials each (core);
#      the 1 kHz sensor; Table III's uncompensated row with one setting changed at a time
#      (uncompensated_row/); the fault campaign (200 trials per fault); the plan's depth limit (the paper's design
#      with it, every shipped class through every fault with it: depth_limit.md); Fig. 16's protocol at the calibrated sensor
#      rate (scenario_peak_forces.yaml, 200 trials per case); the realistic bench
#      (scenario_realistic.yaml, the paper's design), compared with the paper's bench
#      and the sensitivity of the conclusions to every uncertain constant, on both benches
#      the labelled dataset and the recognizer leaderboard (doc/dataset.md, doc/leaderboard.md);
#      the population bench (population.md); the AdaptiveModelCompensator beside the paper's
#      compensator (adaptive.md) and both against the model's error (robustness/); the
#      baselines (the tracker-feedback compensator, the breakthrough detector) on the paper
#      campaign's seeds
#   3. the integration check: 30 trials per case of design 1 through the full ROS pipeline
#      (lockstep, doc/running.md "Lockstep"), twice, each trial beside the core engine's, and 10 per case
#      of the realistic bench (engine_agreement.md)
# Every campaign draws EVALUATION seeds (the scenarios' seed_space; doc/experiments.md, "Seed
# spaces"): no constant was chosen on them. The calibrations are scripts/dev/run_calibration.sh.
# Reports in results/campaign*/report.md.
set -eu
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
# shellcheck source=scripts/dev/workspace_env.sh
source "${ROOT}/scripts/dev/workspace_env.sh"
OUT="${PEDICLE_DRILLING_OUT:-${ROOT}/results}"
JOBS="${JOBS:-2}"
mkdir -p "${OUT}"
start=$(date +%s)
# Where make run's time goes: `section NAME` closes the running section and opens NAME; the end
# prints each section's wall time (and writes it to ${OUT}/timings.tsv).
SECTIONS=()
section_start=${start}
section_name=""
section() {
  local now
  now=$(date +%s)
  [ -z "${section_name}" ] || SECTIONS+=("${section_name}"$'\t'"$(( now - section_start ))")
  section_name="$1"
  section_start=${now}
}
section "1 paper design"
# 1. The paper's design on the core engine (deterministic, all cores): 200 trials per case at
#    12000 rpm, 100 at 16000 and 20000 rpm, so that the Wilson intervals span a few points.
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_paper.yaml" \
  --rpm 12000,16000,20000 --trials 200,100,100 --jobs "${JOBS}" --out "${OUT}/campaign"
# The Table II identification takes no scenario setting: the campaigns below read the first
# one's (the same build) instead of identifying the five volunteers again.
IDENT=(--identification "${OUT}/campaign/identification")
# A trial that an earlier campaign of this run ran already (the same build, engine options and
# trial entry: the same record, bit for bit) is taken from it, row and trace, not run again
# (--reuse-trials; doc/experiments.md, "Reusing trials"): the sweeps' nominal benches repeat the
# main campaigns' first trials, the speed sweep repeats the paper bench's sweep at 12000 rpm.
REUSE=(--reuse-trials "${OUT}")
section "2 exact, virtual patient, hysteresis"
# 2. Beyond the paper: the exact profile on the paper's bench; the bone moving as the virtual
#    patient, linear vs hysteresis model.
for scenario in exact virtual_patient hysteresis; do
  rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_${scenario}.yaml" \
    --trials 200 --jobs "${JOBS}" "${IDENT[@]}" "${REUSE[@]}" \
    --out "${OUT}/campaign_${scenario}"
done
section "2a 1 kHz sensor"
# 2a. A 1 kHz F/T sensor on the paper's bench (scenario_sensor_1khz.yaml), paired with the
#     333 Hz campaign above (doc/experiments.md, "A 1 kHz force sensor").
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_sensor_1khz.yaml" \
  --jobs "${JOBS}" "${IDENT[@]}" --out "${OUT}/campaign_sensor_1khz"
section "2a' uncompensated row"
# 2a'. Table III's uncompensated row by experiment (scenario_uncompensated_row.yaml): the paper's
#      bench's uncompensated case on the paper campaign's 200 seeds at 12000 rpm, one setting
#      changed at a time (each folder's summary.json records it): the recognizer's window in
#      time, the breathing stroke (the set tidal volume), the 1 kHz sensor with a short window,
#      and a short window on a smaller stroke (doc/results.md, "The uncompensated row").
ROW="${OUT}/uncompensated_row"
mkdir -p "${ROW}"
row() {  # row NAME SIMULATOR_PARAMS [campaign options]
  local name="$1" params="$2"
  shift 2
  { cat "${ROOT}/config/scenario_uncompensated_row.yaml"; echo "simulator_params: ${params}"; } \
    > "${ROW}/${name}.yaml"
  rosrun pedicle_drilling campaign --scenario "${ROW}/${name}.yaml" --jobs "${JOBS}" "${IDENT[@]}" \
    "${REUSE[@]}" --no-figures --out "${ROW}/${name}" "$@"
}
for window in 0.05 0.10 0.30; do
  row "window_${window}s" "{}" --recognizer-param "pre_average_s=${window}"
done
row stroke_x0.8 "{ventilator/tv_max_ml: 400.0}"
row stroke_x0.6 "{ventilator/tv_max_ml: 300.0}"
row sensor_1khz_window_0.05s "{force_sensor_rate_hz: 1000.0}" --recognizer-param pre_average_s=0.05
row stroke_x0.8_window_0.05s "{ventilator/tv_max_ml: 400.0}" --recognizer-param pre_average_s=0.05
# What the short window costs where the drill follows the bone, or the bone stands still.
row window_0.05s_stationary_compensated "{}" --recognizer-param pre_average_s=0.05 \
  --case stationary,compensated
section "2b fault campaign"
# 2b. Fail safe: the fault campaign (scenario_faults.yaml), every fault on 200 evaluation seeds.
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_faults.yaml" \
  --jobs "${JOBS}" "${IDENT[@]}" "${REUSE[@]}" --out "${OUT}/campaign_faults"
section "2b' depth limit"
# 2b'. The plan's depth limit (scenario_depth_limit*.yaml): the paper's design at 12000 rpm with
#      the limit on; every shipped compensator (with the paper's recognizer) and every shipped
#      recognizer (with the paper's compensator; the learned one needs a training run, see
#      doc/leaderboard.md) through every fault (20 trials each) and through the fault-free and
#      x1.3 amplitude trials (100 each), and the two C++ alternatives together.
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_depth_limit.yaml" \
  --jobs "${JOBS}" "${IDENT[@]}" "${REUSE[@]}" --out "${OUT}/campaign_depth_limit"
PD=pedicle_drilling
for classes in "${PD}/PaperCompensator ${PD}/PaperRecognizer" \
               "${PD}/TrackedMarkerCompensator ${PD}/PaperRecognizer" \
               "${PD}/AdaptiveModelCompensator ${PD}/PaperRecognizer" \
               "python:pd_campaign.compensators.PhaseTemplateCompensator ${PD}/PaperRecognizer" \
               "${PD}/PaperCompensator ${PD}/ForceDifferenceRecognizer" \
               "${PD}/PaperCompensator python:pd_campaign.recognizers.ThresholdRecognizer" \
               "${PD}/PaperCompensator python:pd_campaign.baselines.ChangePointRecognizer" \
               "${PD}/TrackedMarkerCompensator ${PD}/ForceDifferenceRecognizer"; do
  read -r compensator recognizer <<< "${classes}"
  # The folder: the classes' own names (ThresholdRecognizer, not its module path).
  name="${compensator##*[/.]}_${recognizer##*[/.]}"
  for scenario in faults amplitude; do
    rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_depth_limit_${scenario}.yaml" \
      --compensator "${compensator}" --recognizer "${recognizer}" \
      --jobs "${JOBS}" "${IDENT[@]}" "${REUSE[@]}" --no-figures \
      --out "${OUT}/depth_limit_${scenario}/${name}"
  done
done
# The control: the tracked-marker compensator on the same seeds without the plan.
sed 's/^depth_limit: true/depth_limit: false/' "${ROOT}/config/scenario_depth_limit_amplitude.yaml" \
  > "${OUT}/depth_limit_amplitude_without_plan.yaml"
rosrun pedicle_drilling campaign --scenario "${OUT}/depth_limit_amplitude_without_plan.yaml" \
  --compensator pedicle_drilling/TrackedMarkerCompensator --jobs "${JOBS}" "${IDENT[@]}" \
  "${REUSE[@]}" --no-figures --out "${OUT}/depth_limit_amplitude_without_plan"
python3 "${ROOT}/scripts/dev/depth_limit_tables.py" "${OUT}" > "${OUT}/depth_limit.md"
section "2c Fig. 16 peak forces"
# 2c. Fig. 16's protocol (scenario_peak_forces.yaml): the recognizer observes, every trial goes
#     through the inner layer; the force sensor at the DAQ rate calibrated against Fig. 16
#     (doc/simulator_physics.md, "Measurement chain").
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_peak_forces.yaml" \
  --jobs "${JOBS}" "${IDENT[@]}" "${REUSE[@]}" --out "${OUT}/campaign_peak_forces"
section "2d realistic bench"
# 2d. The realistic bench (scenario_realistic.yaml): the paper's design
#     on the same specimens with the imperfections the simulator can express at sourced values
#     (doc/bench_sources.md), beside the paper's bench trial by trial (campaign_compare
#     --benches: McNemar per case and speed).
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_realistic.yaml" \
  --jobs "${JOBS}" "${IDENT[@]}" "${REUSE[@]}" --out "${OUT}/campaign_realistic"
rosrun pedicle_drilling campaign_compare "${OUT}/campaign" "${OUT}/campaign_realistic" --benches \
  --label-a "paper bench" --label-b "realistic bench" --out "${OUT}/compare_benches" > /dev/null
section "2d' baselines"
# 2d'. The paper's classes against the baselines on the paper's bench, 12000 rpm, the paper
#     campaign's 200 seeds (its own trials are the paper's side; campaign_results.md,
#     "Recognizers and compensators against baselines"): the tracker-feedback compensator
#     (compensated) and the breakthrough detector (stationary and compensated).
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_paper.yaml" \
  --case compensated --rpm 12000 --trials 200 \
  --compensator pedicle_drilling/TrackedMarkerCompensator --jobs "${JOBS}" "${IDENT[@]}" \
  "${REUSE[@]}" --no-figures --out "${OUT}/baseline_tracked_marker"
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_paper.yaml" \
  --case stationary,compensated --rpm 12000 --trials 200 \
  --recognizer pedicle_drilling/ForceDifferenceRecognizer --jobs "${JOBS}" "${IDENT[@]}" \
  "${REUSE[@]}" --no-figures --out "${OUT}/baseline_force_difference"
section "2d-1 population bench"
# 2d-1. The population bench (scenario_population.yaml): a patient per seed who is not their
#     model, the paper's design with the paper's compensator, and the adaptive one compensated
#     at 12000 rpm on the same seeds (population.md; its row in adaptive.md below).
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_population.yaml" \
  --jobs "${JOBS}" "${IDENT[@]}" "${REUSE[@]}" --out "${OUT}/campaign_population"
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_population.yaml" \
  --case compensated --rpm 12000 --trials 200 \
  --compensator pedicle_drilling/AdaptiveModelCompensator --jobs "${JOBS}" "${IDENT[@]}" \
  "${REUSE[@]}" --no-figures --out "${OUT}/campaign_population_adaptive"
python3 "${ROOT}/scripts/dev/population_tables.py" "${OUT}" > "${OUT}/population.md"
section "2d-2 adaptive compensator"
# 2d-2. The AdaptiveModelCompensator beside the paper's compensator, seed for seed at 12000 rpm:
#     the x1.3 amplitude fault (scenario_adaptive_amplitude.yaml), no fault on the paper's and the
#     realistic bench, and 30 trials through the ROS pipeline: adaptive.md.
ADAPTIVE=(--compensator pedicle_drilling/AdaptiveModelCompensator)
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_adaptive_amplitude.yaml" \
  --jobs "${JOBS}" "${IDENT[@]}" "${REUSE[@]}" --no-figures --out "${OUT}/adaptive_amplitude"
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_adaptive_amplitude.yaml" \
  --compensator pedicle_drilling/PaperCompensator --jobs "${JOBS}" "${IDENT[@]}" "${REUSE[@]}" \
  --no-figures --out "${OUT}/adaptive_amplitude_paper"
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_paper.yaml" --case compensated \
  --rpm 12000 --trials 200 "${ADAPTIVE[@]}" --jobs "${JOBS}" "${IDENT[@]}" "${REUSE[@]}" \
  --no-figures --out "${OUT}/campaign_adaptive"
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_realistic.yaml" \
  --case compensated --rpm 12000 --trials 200 "${ADAPTIVE[@]}" --jobs "${JOBS}" "${IDENT[@]}" \
  "${REUSE[@]}" --no-figures --out "${OUT}/campaign_realistic_adaptive"
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_paper.yaml" --case compensated \
  --rpm 12000 --trials 30 --engine ros "${ADAPTIVE[@]}" --jobs "${JOBS}" "${IDENT[@]}" \
  --no-figures --out "${OUT}/campaign_adaptive_ros"
python3 "${ROOT}/scripts/dev/adaptive_tables.py" "${OUT}" > "${OUT}/adaptive.md"
section "2d-3 robustness curves"
# 2d-3. Robustness curves (config/robustness.yaml): both compensators against the size of the
#     model's error in slope, lag and breathing rate, 100 trials per point on the realistic
#     bench, paired seeds (robustness/robustness.md and its figures).
rosrun pedicle_drilling campaign_robustness --sweep "${ROOT}/config/robustness.yaml" \
  --jobs "${JOBS}" --out "${OUT}/robustness"
section "2e sensitivity"
# 2e. Sensitivity of the conclusions: every uncertain constant of
#     config/sensitivity.yaml at each end of its documented range on the paper's bench, and the
#     realistic bench's own imperfections (config/sensitivity_realistic.yaml) on that bench, the
#     population bench's distributions (config/sensitivity_population.yaml) on that one, one
#     at a time on the same seeds, 12000 rpm, SENSITIVITY_TRIALS per case (default 20: a screen,
#     not a measurement; doc/experiments.md, "Sensitivity of the conclusions").
rosrun pedicle_drilling campaign_sensitivity --scenario "${ROOT}/config/scenario_paper.yaml" \
  --sweep "${ROOT}/config/sensitivity.yaml" --rpm 12000 --trials "${SENSITIVITY_TRIALS:-20}" \
  --jobs "${JOBS}" "${REUSE[@]}" --out "${OUT}/sensitivity_paper" > /dev/null
rosrun pedicle_drilling campaign_sensitivity --scenario "${ROOT}/config/scenario_realistic.yaml" \
  --sweep "${ROOT}/config/sensitivity_realistic.yaml" --rpm 12000 \
  --trials "${SENSITIVITY_TRIALS:-20}" --jobs "${JOBS}" "${REUSE[@]}" \
  --out "${OUT}/sensitivity_realistic" \
  > /dev/null
rosrun pedicle_drilling campaign_sensitivity --scenario "${ROOT}/config/scenario_population.yaml" \
  --sweep "${ROOT}/config/sensitivity_population.yaml" --rpm 12000 \
  --trials "${SENSITIVITY_TRIALS:-20}" --jobs "${JOBS}" "${REUSE[@]}" \
  --out "${OUT}/sensitivity_population" > /dev/null
section "2f Fig. 15 speed sweep"
# 2f. Fig. 15's question: the compensated case at 12000/16000/20000 rpm, 50 trials per speed,
#     over every speed-dependent candidate (config/sensitivity_speed.yaml).
rosrun pedicle_drilling campaign_sensitivity --scenario "${ROOT}/config/scenario_speed.yaml" \
  --sweep "${ROOT}/config/sensitivity_speed.yaml" --jobs "${JOBS}" "${REUSE[@]}" \
  --out "${OUT}/sensitivity_speed" > /dev/null
section "2g dataset and leaderboard"
# 2g. The open benchmark: a small labelled dataset (doc/dataset.md; `--large` for the
#     full one) and the leaderboard of literature baselines tuned on its training split, run in
#     closed loop on its test split's specimens on both benches (doc/leaderboard.md; 10 trials
#     per case here, LEADERBOARD_TRIALS).
rosrun pedicle_drilling campaign_dataset --out "${OUT}/dataset" --jobs "${JOBS}"
rosrun pedicle_drilling campaign_leaderboard --dataset "${OUT}/dataset" \
  --trials "${LEADERBOARD_TRIALS:-10}" --jobs "${JOBS}" --out "${OUT}/leaderboard"
section "3 ROS pipeline agreement"
# 3. The integration check: the first 30 trials per case of the paper's design through the full
#    ROS pipeline, twice, trial by trial beside the core engine (the same seeds: the first 30 of
#    the core campaign's 200). test_engine_agreement.py checks 8 such trials in make test.
#    The second run waits for the participants at every step (--lockstep-every-step): the
#    same trials as the first, which waits only where a participant needs it (StepAck.next_step).
for run in ros ros_repeat; do
  every=()
  [ "${run}" = ros_repeat ] && every=(--lockstep-every-step)
  rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_paper.yaml" \
    --rpm 12000 --trials 30 --engine ros --jobs "${JOBS}" "${every[@]}" "${IDENT[@]}" \
    --out "${OUT}/campaign_${run}"
done
# ... and the realistic bench's first 10 trials per case (its simulator_params and delays on the
# Simulator nodelet), beside the core engine's.
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_realistic.yaml" \
  --rpm 12000 --trials 10 --engine ros --jobs "${JOBS}" "${IDENT[@]}" \
  --out "${OUT}/campaign_realistic_ros"
# ... and the plan's depth limit (scenario_depth_limit.yaml): its first 10 trials per case.
rosrun pedicle_drilling campaign --scenario "${ROOT}/config/scenario_depth_limit.yaml" \
  --trials 10 --engine ros --jobs "${JOBS}" "${IDENT[@]}" --no-figures \
  --out "${OUT}/campaign_depth_limit_ros"
{
  echo "# Engine agreement (same seeds)"
  echo
  echo "## The paper's design (scenario_paper.yaml), 12000 rpm"
  echo
  python3 -m pd_campaign.agreement "${OUT}/campaign_ros" "${OUT}/campaign" \
    --label-a ros --label-b core
  echo
  python3 -m pd_campaign.agreement "${OUT}/campaign_ros" "${OUT}/campaign_ros_repeat" \
    --label-a ros --label-b "ros (second run, every step waited for)"
  echo
  echo "## The realistic bench (scenario_realistic.yaml), 12000 rpm"
  echo
  python3 -m pd_campaign.agreement "${OUT}/campaign_realistic_ros" "${OUT}/campaign_realistic" \
    --label-a ros --label-b core
  echo
  echo "## The plan's depth limit (scenario_depth_limit.yaml), 12000 rpm"
  echo
  python3 -m pd_campaign.agreement "${OUT}/campaign_depth_limit_ros" "${OUT}/campaign_depth_limit" \
    --label-a ros --label-b core
} > "${OUT}/engine_agreement.md.tmp"
mv "${OUT}/engine_agreement.md.tmp" "${OUT}/engine_agreement.md"
section ""
echo "main job: done in $(( $(date +%s) - start )) s; where the time went:"
{
  printf 'section\tseconds\n'
  printf '%s\n' "${SECTIONS[@]}"
} > "${OUT}/timings.tsv.tmp" && mv "${OUT}/timings.tsv.tmp" "${OUT}/timings.tsv"
for entry in "${SECTIONS[@]}"; do
  printf '  %-40s %6s s\n' "${entry%%$'\t'*}" "${entry##*$'\t'}"
done
echo "reports:"
echo "  ${OUT}/campaign/report.md"
echo "  ${OUT}/campaign_exact/report.md"
echo "  ${OUT}/campaign_peak_forces/report.md"
echo "  ${OUT}/campaign_virtual_patient/report.md"
echo "  ${OUT}/campaign_hysteresis/report.md"
echo "  ${OUT}/campaign_faults/report.md"
echo "  ${OUT}/campaign_realistic/report.md and ${OUT}/compare_benches/compare.md"
echo "  ${OUT}/sensitivity_paper/sensitivity.md, ${OUT}/sensitivity_realistic/sensitivity.md,"
echo "  ${OUT}/sensitivity_speed/sensitivity.md, ${OUT}/sensitivity_population/sensitivity.md"
echo "  ${OUT}/dataset/DATASHEET.md and ${OUT}/leaderboard/leaderboard.md"
echo "  ${OUT}/engine_agreement.md"
echo "  ${OUT}/adaptive.md, ${OUT}/population.md, ${OUT}/robustness/robustness.md"
sed -n '/^## Results/,/^## Figures/p' "${OUT}/campaign/report.md"
