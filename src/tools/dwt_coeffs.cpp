// dwt_coeffs: multilevel DWT coefficients of one column of numbers (pywt.wavedec order).
//
//   dwt_coeffs --wavelet db5 [--level 6] [--mode symmetric|periodization] < input.txt
//
// Prints one line per array, cA_L first then cD_L ... cD_1, values comma-separated with 17
// significant digits. Used by test/python/test_dwt_vs_pywt.py. Command-line parsing: CLI11
// with the tools' conventions (tool_cli.hpp). Exit status 2 on bad arguments or input.

#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/dwt.hpp"
#include "pedicle_drilling/core/breathing/wavelet.hpp"
#include "pedicle_drilling/core/common/text_parse.hpp"
#include "tool_cli.hpp"

int main(int argc, char** argv) {
  namespace pd = pedicle_drilling::core;
  namespace tools = pedicle_drilling::tools;
  CLI::App app{
      "Reads one column of numbers from stdin and prints the multilevel DWT coefficient arrays "
      "in pywt.wavedec order (cA_L, cD_L, ..., cD_1), one comma-separated line per array.",
      "dwt_coeffs"};
  tools::applyConventions(&app);
  app.footer("Exit status: 0 on success, 2 on bad arguments or input.");
  std::string wavelet_name;
  int level = 6;
  std::string mode_name = "symmetric";
  tools::addDwtOptions(&app, &wavelet_name, &level, &mode_name);
  if (const auto exit = tools::parseCommandLine(&app, argc, argv)) return *exit;
  try {
    const std::vector<double> x = pd::readNumberColumn(stdin);
    const pd::WaveletDecomposition dec =
        pd::wavedec(x, *pd::findWavelet(wavelet_name), level, pd::parseExtensionMode(mode_name));
    for (const std::vector<double>& arr : dec.toPywtOrder()) {
      for (std::size_t k = 0; k < arr.size(); ++k) {
        std::printf(k == 0 ? "%.17g" : ",%.17g", arr[k]);
      }
      std::printf("\n");
    }
    return std::fflush(stdout) == 0 ? 0 : 1;
  } catch (const pd::UsageError& e) {
    std::cerr << "dwt_coeffs: " << e.what() << "\n";
    return tools::kUsageExit;
  } catch (const std::invalid_argument& e) {
    std::cerr << "dwt_coeffs: " << e.what() << "\n";
    return tools::kUsageExit;
  }
}
