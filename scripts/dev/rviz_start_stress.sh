#!/usr/bin/env bash
# rviz started N times (default 100) with the demo's configuration (rviz/drilling.rviz) under
# Xvfb, each time beside a node that connects as the demo test does (the DrillingPanel's latched
# drilling_panel/summary and controls, presses on drilling_panel/press); counts the starts in
# which rviz died and keeps their logs and core files in OUT (default a new temporary folder).
# A diagnosis aid for the rviz startup abort seen twice in the demo's earlier runs
# (doc/campaign_results.md).
set -u
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
RUNS="${1:-100}"
OUT="${2:-$(mktemp -d)}"
if [ -z "${DISPLAY:-}" ]; then
  exec xvfb-run -a -s "-screen 0 1600x1000x24" "$0" "${RUNS}" "${OUT}"
fi
# shellcheck source=scripts/dev/workspace_env.sh
source "${ROOT}/scripts/dev/workspace_env.sh"
mkdir -p "${OUT}" && cd "${OUT}" || exit 1
ulimit -c unlimited
export ROS_MASTER_URI="http://127.0.0.1:$((11400 + $$ % 500))"
export ROS_HOSTNAME=127.0.0.1
roscore -p "${ROS_MASTER_URI##*:}" > roscore.log 2>&1 &
core_pid=$!
trap 'kill ${core_pid} 2>/dev/null' EXIT
for _ in $(seq 1 100); do rostopic list > /dev/null 2>&1 && break; sleep 0.1; done
cat > probe.py <<'PY'
import rospy
from std_msgs.msg import String
got = []
rospy.init_node('rviz_start_probe', anonymous=True)
rospy.Subscriber('/drilling_panel/summary', String, got.append)
rospy.Subscriber('/drilling_panel/controls', String, got.append)
press = rospy.Publisher('/drilling_panel/press', String, queue_size=1)
t0 = rospy.get_time()
while not rospy.is_shutdown() and not got and rospy.get_time() - t0 < 60:
    press.publish(String('reset'))
    rospy.sleep(0.1)
PY
crashes=0
for i in $(seq 1 "${RUNS}"); do
  rviz -d "${ROOT}/rviz/drilling.rviz" > "rviz_${i}.log" 2>&1 &
  pid=$!
  /usr/bin/python3 probe.py > /dev/null 2>&1
  sleep 2
  if kill -0 "${pid}" 2>/dev/null; then
    kill -INT "${pid}"
    wait "${pid}"
    rm -f "rviz_${i}.log"
  else
    wait "${pid}"
    echo "start ${i}: rviz died (exit $?), log ${OUT}/rviz_${i}.log"
    crashes=$((crashes + 1))
  fi
done
echo "rviz died in ${crashes} of ${RUNS} starts (${OUT})"
