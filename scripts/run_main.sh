#!/usr/bin/env bash
# The main job of `make run`. Until the experiment campaign exists, it reproduces the paper's
# ventilator waveform (Sec. IV-A) and writes CSV and a plot to results/.
set -eu
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:${PATH}"
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
# setup.bash reads unset variables (ROS_DISTRO, ...): source it without `set -u`.
set +u
# shellcheck disable=SC1091
source "${ROOT}/catkin_ws/devel/setup.bash"
set -u
OUT="${PEDICLE_DRILLING_OUT:-${ROOT}/results}"
mkdir -p "${OUT}"
rosrun pedicle_drilling tidal_volume --tv-max 500 --rate 12 --ie 1:2 --waveform square \
  --fs 64 --duration 15 > "${OUT}/tidal_volume.csv"
/usr/bin/python3 "${ROOT}/scripts/plot_tidal_volume.py" "${OUT}/tidal_volume.csv" \
  "${OUT}/tidal_volume.png"
echo "main job: wrote ${OUT}/tidal_volume.csv and ${OUT}/tidal_volume.png"
