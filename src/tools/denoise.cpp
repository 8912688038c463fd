// denoise: wavelet de-noising of one column of numbers (paper Eq. 1, s_de = d3 + d4 + d5).
//
//   denoise --wavelet coif4 [--level 6] [--keep 3,4,5] [--mode symmetric|periodization]
//           [--approx] < input.txt > output.txt
//
// Reads whitespace-separated numbers (one per line) from stdin and writes the reconstruction
// from the kept levels, one value per line with 17 significant digits. Command-line parsing:
// CLI11 with the tools' conventions (tool_cli.hpp). Exit status 0 on success, 2 on bad
// arguments or bad input (with a message on stderr).

#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/denoising.hpp"
#include "pedicle_drilling/core/breathing/dwt.hpp"
#include "pedicle_drilling/core/breathing/wavelet.hpp"
#include "pedicle_drilling/core/common/text_parse.hpp"
#include "tool_cli.hpp"

namespace {

namespace pd = pedicle_drilling::core;
namespace tools = pedicle_drilling::tools;

/** @brief The levels of --keep: "none" is no level; else "3,4,5" (checked by the validator). */
std::vector<int> keptLevels(const std::string& text) {
  return text == "none" ? std::vector<int>{} : pd::parseIntList(text, "--keep");
}

/** @brief What is wrong with --keep given --level and --approx; "" when nothing is. */
std::string keepError(const std::string& text, const std::vector<int>& keep, int level,
                      bool approx) {
  std::vector<bool> seen(static_cast<std::size_t>(level) + 1, false);
  for (int j : keep) {
    if (j < 1 || j > level) {
      return "bad --keep '" + text + "': level " + std::to_string(j) + " outside 1.." +
             std::to_string(level);
    }
    if (seen[static_cast<std::size_t>(j)]) {
      return "bad --keep '" + text + "': level " + std::to_string(j) + " listed twice";
    }
    seen[static_cast<std::size_t>(j)] = true;
  }
  if (keep.empty() && !approx) return "bad --keep 'none' without --approx (nothing would be kept)";
  return "";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Wavelet de-noising (DWT reconstruction from selected levels), PyWavelets conventions. "
      "Reads one column of numbers from stdin, writes the reconstruction (same length) to "
      "stdout, one value per line with 17 significant digits.",
      "denoise"};
  tools::applyConventions(&app);
  app.footer("Exit status: 0 on success, 2 on bad arguments or input.");
  std::string wavelet_name;
  int level = 6;
  std::string keep_text = "3,4,5";
  std::string mode_name = "symmetric";
  bool approx = false;
  tools::addDwtOptions(&app, &wavelet_name, &level, &mode_name);
  app.add_option("--keep", keep_text,
                 "comma-separated detail levels to keep, each in 1..L, or 'none' (then --approx "
                 "is required)")
      ->check(tools::accepting(
          [](const std::string& text) {
            try {
              keptLevels(text);
              return true;
            } catch (const pd::UsageError&) {
              return false;
            }
          },
          "'none' or comma-separated levels"));
  app.add_flag("--approx", approx, "also keep the approximation a_L");
  if (const auto exit = tools::parseCommandLine(&app, argc, argv)) return *exit;
  const std::vector<int> keep = keptLevels(keep_text);
  const std::string bad_keep = keepError(keep_text, keep, level, approx);
  if (!bad_keep.empty()) return tools::usageError(app, bad_keep);
  try {
    const std::vector<double> x = pd::readNumberColumn(stdin);
    const std::vector<double> y = pd::denoise(x, *pd::findWavelet(wavelet_name), level, keep,
                                              approx, pd::parseExtensionMode(mode_name));
    for (double v : y) {
      std::printf("%.17g\n", v);
    }
    return std::fflush(stdout) == 0 ? 0 : 1;
  } catch (const pd::UsageError& e) {
    std::cerr << "denoise: " << e.what() << "\n";
    return tools::kUsageExit;
  } catch (const std::invalid_argument& e) {
    std::cerr << "denoise: " << e.what() << "\n";
    return tools::kUsageExit;
  }
}
