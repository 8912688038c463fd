/**
 * @file tidal_volume.cpp
 * @brief CLI: prints the ventilator's flow and tidal volume as CSV `t,flow,volume`.
 *
 *   rosrun pedicle_drilling tidal_volume --tv-max 500 --rate 12 --ie 1:2 --waveform square \
 *       --fs 64 --duration 10 [--pause 0.1] [--peak-ratio 1.5 | --tau 0.4]
 */
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>

#include "pedicle_drilling/core/breathing/ventilator.hpp"
#include "pedicle_drilling/core/common/cli_args.hpp"

namespace pd = pedicle_drilling::core;

namespace {

const char kUsage[] =
    "usage: tidal_volume [--tv-max ML] [--rate BPM] [--ie I:E] [--waveform NAME] [--fs HZ]\n"
    "                    [--duration S] [--pause FRACTION] [--peak-ratio R | --tau S]\n"
    "Prints CSV t,flow,volume (s, ml/s, ml) of a volume-controlled ventilator.\n"
    "Defaults: the paper's settings, 500 ml, 12 /min, 1:2, square, 64 Hz, 10 s, ratio 1.5.\n"
    "Waveforms: square ascending_ramp descending_ramp sine exponential_rise exponential_decay\n";

int run(int argc, char** argv) {
  const pd::CliArgs args(
      argc, argv,
      {"tv-max", "rate", "ie", "waveform", "fs", "duration", "pause", "peak-ratio", "tau"},
      {"help"});
  if (args.flag("help")) {
    std::cout << kUsage;
    return 0;
  }
  pd::VentilatorSettings settings;
  settings.tv_max_ml = args.getDouble("tv-max", settings.tv_max_ml);
  if (!(settings.tv_max_ml > 0.0)) throw pd::UsageError("--tv-max must be > 0 ml");
  settings.rate_bpm = args.getDouble("rate", settings.rate_bpm);
  if (!(settings.rate_bpm > 0.0)) throw pd::UsageError("--rate must be > 0 breaths/min");
  const std::string ie = args.get("ie", "1:2");
  if (!pd::parseIeRatio(ie, &settings.ie_inspiratory, &settings.ie_expiratory)) {
    throw pd::UsageError("--ie '" + ie + "' is not of the form a:b with positive numbers");
  }
  const std::string waveform = args.get("waveform", "square");
  if (!pd::parseWaveform(waveform, &settings.waveform)) {
    throw pd::UsageError("--waveform '" + waveform + "' is unknown (see --help)");
  }
  settings.pause_fraction = args.getDouble("pause", 0.0);
  if (args.has("peak-ratio") && args.has("tau")) {
    throw pd::UsageError("--peak-ratio and --tau are exclusive");
  }
  if (args.has("tau")) {
    settings.expiratory_spec = pd::ExpiratorySpec::kTimeConstant;
    settings.expiratory_tau_s = args.getDouble("tau", settings.expiratory_tau_s);
  }
  settings.peak_flow_ratio = args.getDouble("peak-ratio", settings.peak_flow_ratio);
  const double fs = args.getDouble("fs", 64.0);
  if (!(fs > 0.0 && fs <= 100000.0)) throw pd::UsageError("--fs must be in (0, 100000] Hz");
  const double duration = args.getDouble("duration", 10.0);
  if (!(duration >= 0.0 && duration <= 86400.0)) {
    throw pd::UsageError("--duration must be in [0, 86400] s");
  }
  std::unique_ptr<pd::VentilatorModel> model;
  try {
    model = std::make_unique<pd::VentilatorModel>(settings);
  } catch (const std::invalid_argument& e) {
    throw pd::UsageError(e.what());
  }
  std::printf("t,flow,volume\n");
  for (const auto& s : model->sampleStream(fs, duration)) {
    std::printf("%.6f,%.6f,%.6f\n", s.t, s.flow_ml_s, s.volume_ml);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const pd::UsageError& e) {
    std::cerr << "tidal_volume: " << e.what() << "\n" << kUsage;
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "tidal_volume: error: " << e.what() << "\n";
    return 1;
  }
}
