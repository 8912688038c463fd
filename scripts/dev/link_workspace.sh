#!/usr/bin/env bash
# Makes catkin_ws/src/pedicle_drilling a directory of symlinks back to the repository root:
# one link per top-level entry, except catkin_ws itself. A single link to the root would put
# the workspace inside its own package, and ROS's resource lookup (roslaunch, rostest, rosrun),
# which follows symlinks while walking the package, would loop through it.
set -eu
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
PKG="${ROOT}/catkin_ws/src/pedicle_drilling"
if [ -L "${PKG}" ]; then rm -f "${PKG}"; fi
mkdir -p "${PKG}"
# Remove links whose target is gone, then add a link for every new top-level entry. Existing
# links are left alone, so a build never removes a file from under a running test.
for link in "${PKG}"/* "${PKG}"/.clang-format; do
  if [ -L "${link}" ] && [ ! -e "${link}" ]; then rm -f "${link}"; fi
done
for entry in "${ROOT}"/* "${ROOT}"/.clang-format; do
  name="$(basename "${entry}")"
  case "${name}" in
    catkin_ws|results|out) continue ;;
  esac
  [ -e "${entry}" ] || continue
  [ -L "${PKG}/${name}" ] || ln -s "../../../${name}" "${PKG}/${name}"
done
