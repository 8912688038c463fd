// identify: per-patient vertebra displacement model from a recording (paper Sec. III, V-B).
//
//   identify --input rec.csv --output model.yaml [--method ceres|pso] [--model linear|hysteresis]
//            [--level 6] [--keep 3,4,5] [--wavelets all|NAME,NAME,...] [--delta-tv 5]
//            [--patient-id ID] [--seed 1] [--no-denoise] [--denoise-tv] [--fit-csv PATH]
//
// The pipeline (validation, DWT de-noising with RMSE-DMM basis choice, Ceres or PSO fit) is
// core::identifyPatient() (motion_pipeline.hpp), shared with the MotionIdentification nodelet.
// --denoise-tv (not in the paper, off by default) also filters Tv; see motion_pipeline.hpp.
// --fit-csv PATH writes, per sample, t,tv and for each axis the raw displacement, the fitted
// (de-noised) displacement, the model prediction and the Tv it was fitted against (the raw tv,
// or the de-noised one with --denoise-tv): t,tv,ap_raw,ap_fit,ap_model,ap_tv,si_raw,...
//
// Exit status: 0 success; 2 bad arguments or bad input (message names the problem, no model
// file is written); 1 the model file could not be written.

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <iomanip>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/denoising.hpp"
#include "pedicle_drilling/core/breathing/identification.hpp"
#include "pedicle_drilling/core/breathing/motion_model_io.hpp"
#include "pedicle_drilling/core/breathing/motion_pipeline.hpp"
#include "pedicle_drilling/core/breathing/pso.hpp"
#include "pedicle_drilling/core/breathing/virtual_volunteer.hpp"
#include "pedicle_drilling/core/breathing/wavelet.hpp"
#include "pedicle_drilling/core/common/atomic_file.hpp"
#include "pedicle_drilling/core/common/cli_args.hpp"

namespace {

using pedicle_drilling::core::CliArgs;
using pedicle_drilling::core::UsageError;

constexpr int kBadInput = 2;
constexpr int kWriteFailed = 1;

const char kUsage[] =
    "Usage: identify --input rec.csv --output model.yaml [--method ceres|pso]\n"
    "                [--model linear|hysteresis] [--level 6] [--keep 3,4,5]\n"
    "                [--wavelets all|NAME,...] [--delta-tv 5] [--patient-id ID] [--seed 1]\n"
    "                [--no-denoise] [--denoise-tv] [--fit-csv PATH]\n"
    "\n"
    "Identifies d = q1*Tv + q0 (linear) or d = q1*Tv + q2*dTv/dt + q0 (hysteresis) per axis\n"
    "from an 8 Hz CSV with columns t,tv,ap,si,lr (s, ml, mm) after DWT de-noising.\n"
    "  --method      ceres (default) or pso (paper: population 24, 2000 iterations)\n"
    "  --model       linear (default) or hysteresis\n"
    "  --level       DWT level (default 6); --keep detail levels kept (default 3,4,5)\n"
    "  --wavelets    candidate bases for the RMSE-DMM selection (default all)\n"
    "  --delta-tv    half-width of the Tv neighbourhood of Eq. 2, ml (default 5)\n"
    "  --patient-id  id written to the model (default: input file name)\n"
    "  --seed        PSO seed (default 1)\n"
    "  --no-denoise  fit the raw displacement\n"
    "  --denoise-tv  filter Tv with the same wavelet and levels (not in the paper)\n"
    "  --fit-csv     also write the raw, de-noised and model displacement per sample\n"
    "Exit status: 0 ok, 2 bad arguments or input (no model written), 1 write failure.\n";

std::vector<std::string> splitList(const std::string& text) {
  std::vector<std::string> out;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t comma = text.find(',', start);
    const size_t end = comma == std::string::npos ? text.size() : comma;
    out.push_back(text.substr(start, end - start));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return out;
}

std::string baseName(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  std::string b = slash == std::string::npos ? path : path.substr(slash + 1);
  const size_t dot = b.rfind(".csv");
  if (dot != std::string::npos && dot + 4 == b.size()) b = b.substr(0, dot);
  return b;
}

namespace core = pedicle_drilling::core;

/** @brief Per sample: t, tv and for each axis the raw, de-noised and model displacement. */
std::string fitCsv(const core::PairedSamples& rec, const core::PipelineResult& result) {
  std::ostringstream out;
  out << std::setprecision(17) << "t,tv";
  for (const core::AxisReport& a : result.axes) {
    const std::string n = core::axisName(a.axis);
    out << ',' << n << "_raw," << n << "_fit," << n << "_model," << n << "_tv";
  }
  out << '\n';
  std::array<std::vector<double>, 3> predicted;
  for (int k = 0; k < 3; ++k) {
    predicted[k] = core::predictAll(result.axes[k].fit.model, result.axes[k].samples);
  }
  for (size_t i = 0; i < rec.t.size(); ++i) {
    out << rec.t[i] << ',' << rec.tv[i];
    for (int k = 0; k < 3; ++k) {
      out << ',' << result.axes[k].raw[i] << ',' << result.axes[k].samples.d[i] << ','
          << predicted[k][i] << ',' << result.axes[k].samples.tv[i];
    }
    out << '\n';
  }
  return out.str();
}

}  // namespace

int main(int argc, char** argv) {
  namespace pd = pedicle_drilling::core;
  for (int i = 1; i < argc; ++i) {
    if (std::string(argv[i]) == "--help") {
      std::cout << kUsage;
      return 0;
    }
  }

  // ---------------------------------------------------------------- arguments
  std::string input, output, patient_id, fit_csv;
  pd::PipelineOptions opts;
  try {
    const CliArgs args(argc, argv,
                       {"input", "output", "method", "model", "level", "keep", "wavelets",
                        "delta-tv", "patient-id", "seed", "fit-csv"},
                       {"no-denoise", "denoise-tv"});
    if (!args.has("input")) throw UsageError("missing required option --input");
    if (!args.has("output")) throw UsageError("missing required option --output");
    input = args.get("input", "");
    output = args.get("output", "");
    fit_csv = args.get("fit-csv", "");
    const std::string method = args.get("method", "ceres");
    if (!pd::parseMethod(method, &opts.method)) {
      throw UsageError("unknown method '" + method + "' (expected ceres or pso)");
    }
    const std::string model = args.get("model", "linear");
    if (!pd::parseModelKind(model, &opts.kind)) {
      throw UsageError("unknown model '" + model + "' (expected linear or hysteresis)");
    }
    opts.denoise = !args.flag("no-denoise");
    opts.denoise_tv = args.flag("denoise-tv");
    if (opts.denoise_tv && !opts.denoise) throw UsageError("--denoise-tv needs de-noising on");
    pd::DenoiseOptions& dopts = opts.denoise_options;
    const long level = args.getInt("level", 6);
    if (level < 1 || level > 16) throw UsageError("--level must be in 1..16");
    dopts.level = static_cast<int>(level);
    dopts.kept_levels = pd::parseIntList(args.get("keep", "3,4,5"), "--keep");
    for (int k : dopts.kept_levels) {
      if (k < 1 || k > dopts.level) {
        throw UsageError("--keep level " + std::to_string(k) + " outside 1.." +
                         std::to_string(dopts.level));
      }
    }
    const std::string wavelets = args.get("wavelets", "all");
    if (wavelets != "all") {
      dopts.candidates = splitList(wavelets);
      for (const std::string& w : dopts.candidates) {
        if (pd::findWavelet(w) == nullptr) {
          throw UsageError("--wavelets: unknown wavelet '" + w + "'");
        }
      }
    }
    dopts.delta_tv = args.getDouble("delta-tv", 5.0);
    if (!(dopts.delta_tv >= 0.0)) throw UsageError("--delta-tv must be >= 0");
    const long s = args.getInt("seed", 1);
    if (s < 0) throw UsageError("--seed must be >= 0");
    opts.pso.seed = static_cast<std::uint64_t>(s);
    patient_id = args.get("patient-id", baseName(input));
    opts.validate();
  } catch (const std::exception& e) {
    std::cerr << "identify: " << e.what() << "\n" << kUsage;
    return kBadInput;
  }

  // ---------------------------------------------------------------- data and fits
  pd::PipelineResult result;
  pd::PairedSamples rec;
  std::string model_text;
  try {
    rec = pd::readRecordingCsv(input);
    result = pd::identifyPatient(rec, opts, patient_id, input);
    std::printf("identify: %s, %zu samples, %d breaths, method %s, model %s\n", input.c_str(),
                result.samples, result.breaths, pd::methodName(opts.method).c_str(),
                pd::modelKindName(opts.kind).c_str());
    for (const pd::AxisReport& axis : result.axes) {
      std::printf("  %s\n", pd::formatAxisReport(axis).c_str());
    }
    std::fflush(stdout);
    model_text = pd::modelToYaml(result.model);  // a model that is not finite is bad input
  } catch (const std::exception& e) {
    std::cerr << "identify: " << e.what() << "\n";
    return kBadInput;
  }

  // ---------------------------------------------------------------- output
  // Every output's temporary file is created before any is written, and all are renamed at
  // the end: a destination that cannot be written leaves no output at all.
  try {
    pd::AtomicFile model_file(output);
    std::optional<pd::AtomicFile> fit_file;
    if (!fit_csv.empty()) fit_file.emplace(fit_csv);
    model_file.write(model_text);
    if (fit_file) fit_file->write(fitCsv(rec, result));
    model_file.commit();
    std::printf("identify: wrote %s\n", output.c_str());
    if (fit_file) {
      fit_file->commit();
      std::printf("identify: wrote %s\n", fit_csv.c_str());
    }
  } catch (const std::exception& e) {
    std::cerr << "identify: " << e.what() << "\n";
    return kWriteFailed;
  }
  return 0;
}
