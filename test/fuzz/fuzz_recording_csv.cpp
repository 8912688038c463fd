/**
 * @file fuzz_recording_csv.cpp
 * @brief libFuzzer target: the recording CSV readers (t,tv,ap,si,lr and the 64 Hz t,tv file) on
 *        arbitrary bytes. A refusal is RecordingFormatError (or its subclasses); anything else is
 *        a bug. An accepted recording has finite, strictly increasing time.
 */
#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "pedicle_drilling/core/breathing/virtual_volunteer.hpp"

namespace core = pedicle_drilling::core;

namespace {

/** @brief A file of this process for the readers, which take a path. */
std::string scratchPath() {
  static const std::string path =
      "/tmp/pd_fuzz_recording_" + std::to_string(static_cast<long>(getpid())) + ".csv";
  return path;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = scratchPath();
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) std::abort();
  if (size > 0 && std::fwrite(data, 1, size, f) != size) std::abort();
  std::fclose(f);
  try {
    const core::PairedSamples p = core::readRecordingCsv(path);
    for (std::size_t i = 0; i < p.t.size(); ++i) {
      if (!std::isfinite(p.t[i]) || (i > 0 && !(p.t[i] > p.t[i - 1]))) std::abort();
    }
  } catch (const core::RecordingFormatError&) {
  }
  try {
    const auto c = core::readTv64Csv(path);
    for (std::size_t i = 1; i < c[0].size(); ++i) {
      if (!(c[0][i] > c[0][i - 1])) std::abort();
    }
  } catch (const core::RecordingFormatError&) {
  }
  return 0;
}
