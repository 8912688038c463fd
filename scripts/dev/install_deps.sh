#!/usr/bin/env bash
# Installs the Debian 12 packages pedicle_drilling needs, only those that are missing.
# Runs as root, or through sudo when not root.
set -euo pipefail
PACKAGES=(
  build-essential cmake pkg-config ccache
  catkin python3-catkin-pkg catkin-lint
  ros-core-dev ros-message-generation ros-message-runtime rosbash
  libactionlib-dev python3-actionlib libactionlib-msgs-dev python3-actionlib-msgs
  libroscpp-dev libnodeletlib-dev libnodeletlib-tools python3-nodelet
  libtf2-ros-dev libtf2-eigen-dev libtf2-geometry-msgs-dev python3-tf2-ros
  libgeometry-msgs-dev libsensor-msgs-dev libtrajectory-msgs-dev libdiagnostic-msgs-dev
  libstd-msgs-dev ros-std-srvs libstd-srvs-dev libvisualization-msgs-dev
  librosbag-dev python3-rosbag python3-rospy python3-rostopic python3-rosservice
  python3-diagnostic-msgs python3-geometry-msgs python3-sensor-msgs python3-trajectory-msgs
  python3-std-srvs python3-tf2-msgs python3-visualization-msgs
  librostest-dev python3-rostest python3-roslaunch
  librviz-dev rviz
  libkdl-parser-dev liborocos-kdl-dev liburdfdom-dev liburdf-dev libyaml-cpp-dev
  libdiagnostic-updater-dev ros-robot-state-publisher
  libeigen3-dev libceres-dev libbullet-dev pybind11-dev python3-dev
  libgtest-dev libgmock-dev libbenchmark-dev nlohmann-json3-dev libcli11-dev
  python3-numpy python3-scipy python3-sklearn python3-yaml python3-pywt python3-matplotlib python3-pytest
  python3-pytest-xdist
  python3-h5py python3-pandas python3-nbconvert python3-ipykernel jupyter-nbconvert
  xvfb xauth x11-utils imagemagick liburdfdom-tools libgl1-mesa-dri mesa-utils
  clang-14 libfuzzer-14-dev libclang-rt-14-dev clang-format-14
  slurm-wlm munge
)
missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install_deps: installing ${#missing[@]} missing packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install_deps: done"
