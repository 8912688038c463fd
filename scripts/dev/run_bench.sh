#!/usr/bin/env bash
# `make bench`: runs every benchmark program; each prints `BENCH <name> <value> <unit>` lines.
set -eu
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:${PATH}"
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
# setup.bash reads unset variables (ROS_DISTRO, ...): source it without `set -u`.
set +u
# shellcheck disable=SC1091
source "${ROOT}/catkin_ws/devel/setup.bash"
set -u
BIN="${ROOT}/catkin_ws/devel/lib/pedicle_drilling"
status=0
for bench in "${BIN}"/bench_*; do
  [ -x "${bench}" ] || continue
  echo "# $(basename "${bench}")" >&2
  "${bench}" || status=1
done
for script in "${ROOT}"/bench/*.sh; do
  [ -x "${script}" ] || continue
  echo "# $(basename "${script}")" >&2
  "${script}" || status=1
done
exit ${status}
