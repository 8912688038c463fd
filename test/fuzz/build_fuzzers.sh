#!/usr/bin/env bash
# Builds the libFuzzer targets of test/fuzz with Debian's clang (clang-14, libfuzzer-14-dev) into
# OUT (default catkin_ws/build/fuzz): the reader or recognizer under test compiled with the
# fuzzer, AddressSanitizer and UndefinedBehaviorSanitizer; what it calls besides comes from the
# catkin-built core library. Rebuilds a target only when one of its sources is newer.
set -eu
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
OUT="${1:-${ROOT}/catkin_ws/build/fuzz}"
CXX="${FUZZ_CXX:-clang++-14}"
LIB_DIR="${ROOT}/catkin_ws/devel/lib"
mkdir -p "${OUT}"
command -v "${CXX}" > /dev/null || { echo "build_fuzzers: ${CXX} not found (make deps installs clang-14 and libfuzzer-14-dev)" >&2; exit 2; }
[ -e "${LIB_DIR}/libpedicle_drilling_core.so" ] || { echo "build_fuzzers: build the workspace first (make build)" >&2; exit 2; }
FLAGS=(-std=c++17 -O1 -g -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined
       -Wall -Wextra -Werror -I"${ROOT}/include" -isystem /usr/include/eigen3)
build() {  # build NAME SOURCES... [-- LIBRARIES...]: the system libraries the sources call
  local name="$1"; shift
  local sources=("${ROOT}/test/fuzz/${name}.cpp") libraries=()
  while [ "$#" -gt 0 ] && [ "$1" != "--" ]; do sources+=("$1"); shift; done
  if [ "$#" -gt 0 ]; then shift; libraries=("$@"); fi
  local binary="${OUT}/${name}"
  if [ -x "${binary}" ]; then
    local newer=0 s
    for s in "${sources[@]}" "${ROOT}"/include/pedicle_drilling/core/*/*.hpp; do
      [ "${s}" -nt "${binary}" ] && newer=1
    done
    [ "${newer}" -eq 0 ] && return 0
  fi
  echo "build_fuzzers: ${name}"
  "${CXX}" "${FLAGS[@]}" "${sources[@]}" -L"${LIB_DIR}" -lpedicle_drilling_core \
    "${libraries[@]}" -Wl,-rpath,"${LIB_DIR}" -o "${binary}.tmp"
  mv "${binary}.tmp" "${binary}"
}
CORE="${ROOT}/src/core"
build fuzz_model_yaml "${CORE}/breathing/motion_model_io.cpp" "${CORE}/breathing/motion_model.cpp" "${CORE}/common/atomic_file.cpp" -- -lyaml-cpp
build fuzz_recording_csv "${CORE}/breathing/virtual_volunteer.cpp" "${CORE}/common/atomic_file.cpp"
build fuzz_recognizer "${CORE}/drilling/state_recognizer.cpp"
