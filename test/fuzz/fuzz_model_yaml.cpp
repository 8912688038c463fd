/**
 * @file fuzz_model_yaml.cpp
 * @brief libFuzzer target: the per-patient model YAML reader on arbitrary text. A refusal is
 *        ModelFileError; anything else (another exception, a crash, a sanitizer report) is a
 *        bug. A file that is accepted must survive a write/read round trip unchanged.
 */
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "pedicle_drilling/core/breathing/motion_model_io.hpp"

namespace core = pedicle_drilling::core;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  core::PatientModel model;
  try {
    model = core::modelFromYaml(text, "<fuzz>");
  } catch (const core::ModelFileError&) {
    return 0;  // refused with the documented error
  }
  // Accepted: what we write from it must read back to the same text.
  const std::string written = core::modelToYaml(model);
  const std::string again = core::modelToYaml(core::modelFromYaml(written, "<round trip>"));
  if (written != again) std::abort();
  return 0;
}
