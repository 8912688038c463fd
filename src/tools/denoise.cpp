// denoise: wavelet de-noising of one column of numbers (paper Eq. 1, s_de = d3 + d4 + d5).
//
//   denoise --wavelet coif4 [--level 6] [--keep 3,4,5] [--mode symmetric|periodization]
//           [--approx] < input.txt > output.txt
//
// Reads whitespace-separated numbers (one per line) from stdin and writes the reconstruction
// from the kept levels, one value per line with 17 significant digits. Exit status 0 on
// success, 2 on bad arguments or bad input (with a message on stderr).

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/denoising.hpp"
#include "pedicle_drilling/core/breathing/dwt.hpp"
#include "pedicle_drilling/core/breathing/wavelet.hpp"
#include "pedicle_drilling/core/common/cli_args.hpp"

namespace {

constexpr int kUsageError = 2;
constexpr int kMaxLevel = 32;

const char kUsage[] =
    "Usage: denoise --wavelet NAME [--level L] [--keep J1,J2,...] "
    "[--mode symmetric|periodization] [--approx]\n"
    "\n"
    "Wavelet de-noising (DWT reconstruction from selected levels), PyWavelets conventions.\n"
    "Reads one column of numbers from stdin, writes the reconstruction (same length) to\n"
    "stdout, one value per line with 17 significant digits.\n"
    "\n"
    "  --wavelet NAME   db1-db20, sym2-sym20, coif1-coif5, bior1.1 ... bior6.8 (required)\n"
    "  --level L        decomposition level, 1..32 (default 6)\n"
    "  --keep LIST      comma-separated detail levels to keep, each in 1..L (default 3,4,5),\n"
    "                   or 'none' (then --approx is required)\n"
    "  --mode M         symmetric (default) or periodization\n"
    "  --approx         also keep the approximation a_L\n"
    "  --help           print this help\n"
    "\n"
    "Exit status: 0 on success, 2 on bad arguments or input.\n";

using pedicle_drilling::core::readNumberColumn;
using pedicle_drilling::core::UsageError;

int parseInt(const std::string& text, const std::string& what) {
  if (text.empty()) {
    throw UsageError("empty " + what);
  }
  errno = 0;
  char* end = nullptr;
  const long v = std::strtol(text.c_str(), &end, 10);
  if (errno != 0 || end == text.c_str() || *end != '\0' || v < -1000000 || v > 1000000) {
    throw UsageError("bad " + what + " '" + text + "' (expected an integer)");
  }
  return static_cast<int>(v);
}

std::vector<int> parseKeep(const std::string& text) {
  std::vector<int> levels;
  if (text == "none") {
    return levels;
  }
  if (text.empty()) {
    throw UsageError("bad --keep '' (expected comma-separated levels, e.g. 3,4,5)");
  }
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = text.find(',', start);
    const std::string item =
        text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    try {
      levels.push_back(parseInt(item, "--keep level"));
    } catch (const UsageError&) {
      throw UsageError("bad --keep '" + text + "' (expected comma-separated levels, e.g. 3,4,5)");
    }
    if (comma == std::string::npos) {
      break;
    }
    start = comma + 1;
  }
  return levels;
}

}  // namespace

int main(int argc, char** argv) {
  using pedicle_drilling::core::ExtensionMode;
  try {
    std::string wavelet_name;
    int level = 6;
    std::string keep_text = "3,4,5";
    ExtensionMode mode = ExtensionMode::kSymmetric;
    bool approx = false;
    for (int i = 1; i < argc; ++i) {
      std::string arg = argv[i];
      std::string value;
      bool has_inline_value = false;
      const std::size_t eq = arg.find('=');
      if (arg.rfind("--", 0) == 0 && eq != std::string::npos) {
        value = arg.substr(eq + 1);
        arg = arg.substr(0, eq);
        has_inline_value = true;
      }
      auto next = [&]() -> std::string {
        if (has_inline_value) {
          return value;
        }
        if (i + 1 >= argc) {
          throw UsageError("missing value after " + arg);
        }
        return argv[++i];
      };
      if (arg == "--help" || arg == "-h") {
        std::cout << kUsage;
        return 0;
      } else if (arg == "--wavelet") {
        wavelet_name = next();
      } else if (arg == "--level") {
        level = parseInt(next(), "--level");
      } else if (arg == "--keep") {
        keep_text = next();
      } else if (arg == "--mode") {
        const std::string m = next();
        try {
          mode = pedicle_drilling::core::parseExtensionMode(m);
        } catch (const std::invalid_argument& e) {
          throw UsageError(e.what());
        }
      } else if (arg == "--approx") {
        approx = true;
      } else {
        throw UsageError("unknown argument '" + arg + "'");
      }
    }
    if (wavelet_name.empty()) {
      throw UsageError("missing --wavelet");
    }
    const pedicle_drilling::core::Wavelet* wavelet =
        pedicle_drilling::core::findWavelet(wavelet_name);
    if (wavelet == nullptr) {
      throw UsageError("unknown wavelet '" + wavelet_name + "'");
    }
    if (level < 1 || level > kMaxLevel) {
      throw UsageError("bad --level " + std::to_string(level) + " (expected 1.." +
                       std::to_string(kMaxLevel) + ")");
    }
    const std::vector<int> keep = parseKeep(keep_text);
    std::vector<bool> seen(static_cast<std::size_t>(level) + 1, false);
    for (int j : keep) {
      if (j < 1 || j > level) {
        throw UsageError("bad --keep '" + keep_text + "': level " + std::to_string(j) +
                         " outside 1.." + std::to_string(level));
      }
      if (seen[static_cast<std::size_t>(j)]) {
        throw UsageError("bad --keep '" + keep_text + "': level " + std::to_string(j) +
                         " listed twice");
      }
      seen[static_cast<std::size_t>(j)] = true;
    }
    if (keep.empty() && !approx) {
      throw UsageError("bad --keep 'none' without --approx (nothing would be kept)");
    }
    const std::vector<double> x = readNumberColumn(stdin);
    const std::vector<double> y =
        pedicle_drilling::core::denoise(x, *wavelet, level, keep, approx, mode);
    for (double v : y) {
      std::printf("%.17g\n", v);
    }
    return std::fflush(stdout) == 0 ? 0 : 1;
  } catch (const UsageError& e) {
    std::cerr << "denoise: " << e.what() << "\n(run 'denoise --help' for usage)\n";
    return kUsageError;
  } catch (const std::invalid_argument& e) {
    std::cerr << "denoise: " << e.what() << "\n";
    return kUsageError;
  }
}
