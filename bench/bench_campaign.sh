#!/usr/bin/env bash
# Campaign throughput (make bench): the core engine on the paper's three cases at 12000 rpm,
# 200 trials each (600 trials, --jobs 2), and the same 10 seeds through both engines (stationary
# case, 12000 rpm): the whole campaigns' times, and a trial's marginal cost, ROS over core.
# Prints BENCH lines; each campaign's time includes its Table II identification (about 3 s), so
# the figures are conservative. Then Fig. 16's protocol, and a profiled campaign: the share of
# each component of the engine's steps (campaign --profile).
set -eu
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:${PATH}"
OUT="$(mktemp -d)"
trap 'rm -rf "${OUT}"' EXIT
seconds() {
  local start end
  start=$(date +%s.%N)
  "$@" > /dev/null 2>&1
  end=$(date +%s.%N)
  python3 -c "print(${end} - ${start})"
}
paper=$(seconds rosrun pedicle_drilling campaign --rpm 12000 --trials 200 --jobs 2 --seed 101 \
  --out "${OUT}/paper")
trials=$(python3 -c "import csv; print(sum(1 for _ in csv.DictReader(open('${OUT}/paper/trials.csv'))))")
python3 -c "print('BENCH campaign_trials_per_min %.0f trials/min (core engine, --jobs 2, %d trials in %.1f s)' % (${trials} * 60.0 / ${paper}, ${trials}, ${paper}))"
core=$(seconds rosrun pedicle_drilling campaign --case stationary --rpm 12000 --trials 10 \
  --jobs 1 --seed 102 --engine core --out "${OUT}/core")
ros=$(seconds rosrun pedicle_drilling campaign --case stationary --rpm 12000 --trials 10 \
  --jobs 1 --seed 102 --engine ros --out "${OUT}/ros")
python3 -c "print('BENCH campaign_core_over_ros_speedup %.1f x (10 seeds, --jobs 1: core %.1f s, ros %.1f s)' % (${ros} / ${core}, ${core}, ${ros}))"
# The cost of a trial alone (no start-up, no identification): the marginal wall time of 10 more
# trials, 20 against 10 on the same seeds, per engine; ROS over core.
core20=$(seconds rosrun pedicle_drilling campaign --case stationary --rpm 12000 --trials 20 \
  --jobs 1 --seed 102 --engine core --out "${OUT}/core20")
ros20=$(seconds rosrun pedicle_drilling campaign --case stationary --rpm 12000 --trials 20 \
  --jobs 1 --seed 102 --engine ros --out "${OUT}/ros20")
python3 -c "print('BENCH ros_over_core_trial_cost %.1f (the marginal wall time of 10 trials, --jobs 1: ros %.2f s, core %.2f s per trial)' % ((${ros20} - ${ros}) / (${core20} - ${core}), (${ros20} - ${ros}) / 10, (${core20} - ${core}) / 10))"
# Fig. 16's protocol (the drill goes through the inner layer: longer trials), 100 trials per case.
peak=$(seconds rosrun pedicle_drilling campaign --scenario "$(rospack find pedicle_drilling)/config/scenario_peak_forces.yaml" \
  --trials 100 --jobs 2 --seed 103 --out "${OUT}/peak")
peak_trials=$(python3 -c "import csv; print(sum(1 for _ in csv.DictReader(open('${OUT}/peak/trials.csv'))))")
python3 -c "print('BENCH campaign_peak_forces_trials_per_min %.0f trials/min (core engine, --jobs 2, %d trials in %.1f s)' % (${peak_trials} * 60.0 / ${peak}, ${peak_trials}, ${peak}))"
# Where the engine's time goes: the paper's three cases at 12000 rpm, 20 trials each,
# profiled by component (campaign --profile; the trials are the unprofiled ones, bit for bit).
rosrun pedicle_drilling campaign --rpm 12000 --trials 20 --jobs 2 --seed 104 --profile \
  --out "${OUT}/profile" > /dev/null 2>&1
python3 - "${OUT}/profile/profile.json" <<'PY'
import json
import sys
from pd_campaign import profile
data = json.load(open(sys.argv[1]))
for name, _, seconds, share, per_sim in profile.rows(data):
    if name == 'engine_step':
        print('BENCH engine_step_cost_per_sim_s %.3f ms (%d trials, %.0f s simulated)'
              % (per_sim, data['trials'], data['sim_s']))
    else:
        print('BENCH component_share_%s %.1f %%' % (name, 100 * share))
PY
