/**
 * @file tidal_volume.cpp
 * @brief CLI: prints the ventilator's flow and tidal volume as CSV `t,flow,volume`.
 *
 *   rosrun pedicle_drilling tidal_volume --tv-max 500 --rate 12 --ie 1:2 --waveform square \
 *       --fs 64 --duration 10 [--pause 0.1] [--peak-ratio 1.5 | --tau 0.4]
 *
 * Command-line parsing: CLI11 with the tools' conventions (tool_cli.hpp). Exit status: 0 ok,
 * 2 bad options (including settings the ventilator model refuses), 1 another error.
 */
#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>
#include <memory>
#include <string>

#include "pedicle_drilling/core/breathing/ventilator.hpp"
#include "tool_cli.hpp"

namespace pd = pedicle_drilling::core;
namespace tools = pedicle_drilling::tools;

namespace {

/** @brief Everything the command line sets besides the ventilator settings. */
struct Options {
  std::string ie = "1:2";
  std::string waveform = "square";
  double fs = 64.0;
  double duration = 10.0;
};

/** @brief Declares every option of the tool (its values go to *o and *s). */
void addOptions(CLI::App* app, Options* o, pd::VentilatorSettings* s) {
  // Ranges and choices from the one declaration the Ventilator nodelet loads too
  // (core::VentilatorSettings::table(); parameter names in the messages).
  const auto& table = pd::VentilatorSettings::table();
  app->add_option("--tv-max", s->tv_max_ml, "set tidal volume, ml")
      ->check(tools::declared(table, "tv_max_ml"));
  app->add_option("--rate", s->rate_bpm, "breaths per minute")
      ->check(tools::declared(table, "rate_bpm"));
  app->add_option("--ie", o->ie, "I:E ratio")->check(tools::declared(table, "ie_ratio"));
  app->add_option("--waveform", o->waveform, "inspiratory flow shape")
      ->check(tools::declared(table, "waveform"));
  app->add_option("--fs", o->fs, "sample rate, Hz")->check(tools::finiteNumber(0.0, 1e5, true));
  app->add_option("--duration", o->duration, "s")->check(tools::finiteNumber(0.0, 86400.0));
  app->add_option("--pause", s->pause_fraction, "inspiratory pause, fraction of Ti")
      ->check(tools::declared(table, "pause_fraction"));
  CLI::Option* ratio =
      app->add_option("--peak-ratio", s->peak_flow_ratio, "peak expiratory / inspiratory flow")
          ->check(tools::declared(table, "peak_flow_ratio"));
  app->add_option("--tau", s->expiratory_tau_s, "expiratory time constant, s (instead of a ratio)")
      ->check(tools::declared(table, "expiratory_tau_s"))
      ->excludes(ratio);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Prints CSV t,flow,volume (s, ml/s, ml) of a volume-controlled ventilator. The defaults "
      "are the paper's settings.",
      "tidal_volume"};
  tools::applyConventions(&app);
  app.footer("Exit status: 0 ok, 2 bad options (or settings the ventilator model refuses).");
  Options o;
  pd::VentilatorSettings settings;
  addOptions(&app, &o, &settings);
  if (const auto exit = tools::parseCommandLine(&app, argc, argv)) return *exit;
  pd::parseIeRatio(o.ie, &settings.ie_inspiratory, &settings.ie_expiratory);
  pd::parseWaveform(o.waveform, &settings.waveform);
  if (app.count("--tau") > 0) settings.expiratory_spec = pd::ExpiratorySpec::kTimeConstant;
  std::unique_ptr<pd::VentilatorModel> model;
  try {
    model = std::make_unique<pd::VentilatorModel>(settings);
  } catch (const std::invalid_argument& e) {
    return tools::usageError(app, e.what());
  }
  try {
    std::printf("t,flow,volume\n");
    for (const auto& s : model->sampleStream(o.fs, o.duration)) {
      std::printf("%.6f,%.6f,%.6f\n", s.t, s.flow_ml_s, s.volume_ml);
    }
  } catch (const std::exception& e) {
    std::cerr << "tidal_volume: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
