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
// Command-line parsing: CLI11 with the tools' conventions (tool_cli.hpp).
// Exit status: 0 success; 2 bad arguments or bad input (message names the problem, no model
// file is written); 1 the model file could not be written.

#include <CLI/CLI.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <iomanip>
#include <iostream>
#include <limits>
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
#include "tool_cli.hpp"

namespace {

constexpr int kBadInput = 2;
constexpr int kWriteFailed = 1;

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

/** @brief Everything the command line sets besides the pipeline options. */
struct Options {
  std::string input, output, patient_id, fit_csv;
  std::string method = "ceres";
  std::string model = "linear";
  std::string keep = "3,4,5";
  std::string wavelets = "all";
  std::int64_t seed = 1;
  bool no_denoise = false;
};

/** @brief Declares every option of the tool (its values go to *o and *opts). */
void addOptions(CLI::App* app, Options* o, core::PipelineOptions* opts) {
  namespace tools = pedicle_drilling::tools;
  core::DenoiseOptions& dopts = opts->denoise_options;
  app->add_option("--input", o->input, "8 Hz CSV with columns t,tv,ap,si,lr (s, ml, mm)")
      ->required();
  app->add_option("--output", o->output, "model YAML written")->required();
  // Ranges and choices from the one declaration the MotionIdentification nodelet loads too
  // (core::PipelineOptions::table(); parameter names in the messages).
  const auto& table = core::PipelineOptions::table();
  app->add_option("--method", o->method, "ceres, or pso (paper: population 24, 2000 iterations)")
      ->check(tools::declared(table, "method"));
  app->add_option("--model", o->model, "linear or hysteresis")
      ->check(tools::declared(table, "model"));
  app->add_option("--level", dopts.level, "DWT level")->check(tools::declared(table, "level"));
  app->add_option("--keep", o->keep, "detail levels kept, each in 1..level")
      ->check(tools::declared(table, "kept_levels"));
  app->add_option("--wavelets", o->wavelets,
                  "candidate bases for the RMSE-DMM selection: all, or names comma-separated")
      ->check(tools::declared(table, "wavelets"));
  app->add_option("--delta-tv", dopts.delta_tv, "half-width of the Tv neighbourhood of Eq. 2, ml")
      ->check(tools::declared(table, "delta_tv_ml"));
  app->add_option("--patient-id", o->patient_id, "id written to the model (default: input name)");
  app->add_option("--seed", o->seed, "PSO seed")->check(tools::declared(table, "pso_seed"));
  CLI::Option* no_denoise =
      app->add_flag("--no-denoise", o->no_denoise, "fit the raw displacement");
  app->add_flag("--denoise-tv", opts->denoise_tv,
                "filter Tv with the same wavelet and levels (not in the paper)")
      ->excludes(no_denoise);
  app->add_option("--fit-csv", o->fit_csv,
                  "also write the raw, de-noised and model displacement per sample");
}

/** @brief Options given -> pipeline options; "" or what is wrong, naming the option. */
std::string finishOptions(Options* o, core::PipelineOptions* opts) {
  core::parseMethod(o->method, &opts->method);
  core::parseModelKind(o->model, &opts->kind);
  opts->denoise = !o->no_denoise;
  core::DenoiseOptions& dopts = opts->denoise_options;
  dopts.kept_levels = core::parseIntList(o->keep, "--keep");
  for (int k : dopts.kept_levels) {
    if (k > dopts.level) {
      return "--keep level " + std::to_string(k) + " outside 1.." + std::to_string(dopts.level);
    }
  }
  if (o->wavelets != "all") dopts.candidates = splitList(o->wavelets);
  opts->pso.seed = static_cast<std::uint64_t>(o->seed);
  if (o->patient_id.empty()) o->patient_id = baseName(o->input);
  try {
    opts->validate();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

}  // namespace

int main(int argc, char** argv) {
  namespace pd = pedicle_drilling::core;
  namespace tools = pedicle_drilling::tools;
  CLI::App app{
      "Identifies d = q1*Tv + q0 (linear) or d = q1*Tv + q2*dTv/dt + q0 (hysteresis) per axis "
      "from an 8 Hz recording after DWT de-noising.",
      "identify"};
  tools::applyConventions(&app);
  app.footer("Exit status: 0 ok, 2 bad arguments or input (no model written), 1 write failure.");
  Options o;
  pd::PipelineOptions opts;
  addOptions(&app, &o, &opts);
  if (const auto exit = tools::parseCommandLine(&app, argc, argv)) return *exit;
  const std::string bad = finishOptions(&o, &opts);
  if (!bad.empty()) return tools::usageError(app, bad);
  const std::string& input = o.input;
  const std::string& output = o.output;
  const std::string& fit_csv = o.fit_csv;
  const std::string& patient_id = o.patient_id;

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
