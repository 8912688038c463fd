// dwt_coeffs: multilevel DWT coefficients of one column of numbers (pywt.wavedec order).
//
//   dwt_coeffs --wavelet db5 [--level 6] [--mode symmetric|periodization] < input.txt
//
// Prints one line per array, cA_L first then cD_L ... cD_1, values comma-separated with 17
// significant digits. Used by test/python/test_dwt_vs_pywt.py. Exit status 2 on bad
// arguments or input.

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/dwt.hpp"
#include "pedicle_drilling/core/breathing/wavelet.hpp"
#include "pedicle_drilling/core/common/cli_args.hpp"

namespace {

constexpr int kUsageError = 2;
constexpr int kMaxLevel = 32;

const char kUsage[] =
    "Usage: dwt_coeffs --wavelet NAME [--level L] [--mode symmetric|periodization]\n"
    "\n"
    "Reads one column of numbers from stdin and prints the multilevel DWT coefficient arrays\n"
    "in pywt.wavedec order (cA_L, cD_L, ..., cD_1), one comma-separated line per array.\n"
    "  --wavelet NAME   db1-db20, sym2-sym20, coif1-coif5, bior1.1 ... bior6.8 (required)\n"
    "  --level L        decomposition level, 1..32 (default 6)\n"
    "  --mode M         symmetric (default) or periodization\n"
    "Exit status: 0 on success, 2 on bad arguments or input.\n";

using pedicle_drilling::core::readNumberColumn;
using pedicle_drilling::core::UsageError;

int parseLevel(const std::string& text) {
  char* end = nullptr;
  const long v = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || v < 1 || v > kMaxLevel) {
    throw UsageError("bad --level '" + text + "' (expected an integer 1.." +
                     std::to_string(kMaxLevel) + ")");
  }
  return static_cast<int>(v);
}

}  // namespace

int main(int argc, char** argv) {
  try {
    std::string wavelet_name;
    int level = 6;
    pedicle_drilling::core::ExtensionMode mode = pedicle_drilling::core::ExtensionMode::kSymmetric;
    for (int i = 1; i < argc; ++i) {
      const std::string arg = argv[i];
      auto next = [&]() -> std::string {
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
        level = parseLevel(next());
      } else if (arg == "--mode") {
        const std::string m = next();
        try {
          mode = pedicle_drilling::core::parseExtensionMode(m);
        } catch (const std::invalid_argument& e) {
          throw UsageError(e.what());
        }
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
    const std::vector<double> x = readNumberColumn(stdin);
    const pedicle_drilling::core::WaveletDecomposition dec =
        pedicle_drilling::core::wavedec(x, *wavelet, level, mode);
    for (const std::vector<double>& arr : dec.toPywtOrder()) {
      for (std::size_t k = 0; k < arr.size(); ++k) {
        std::printf(k == 0 ? "%.17g" : ",%.17g", arr[k]);
      }
      std::printf("\n");
    }
    return std::fflush(stdout) == 0 ? 0 : 1;
  } catch (const UsageError& e) {
    std::cerr << "dwt_coeffs: " << e.what() << "\n(run 'dwt_coeffs --help' for usage)\n";
    return kUsageError;
  } catch (const std::invalid_argument& e) {
    std::cerr << "dwt_coeffs: " << e.what() << "\n";
    return kUsageError;
  }
}
