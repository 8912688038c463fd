#!/usr/bin/env bash
# `make bench`: runs every benchmark program; each prints `BENCH <name> <value> <unit>` lines.
set -eu
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
# shellcheck source=scripts/dev/workspace_env.sh
source "${ROOT}/scripts/dev/workspace_env.sh"
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
