// generate_volunteers: writes the virtual volunteers' recordings and ground truth.
//
//   generate_volunteers --out DIR [--duration 30] [--ids 1,2,3,4,5]
//
// For each id, in DIR (created if missing, one level):
//   volunteer_<id>.csv         8 Hz  t,tv,ap,si,lr  (tv interpolated to the marker times)
//   volunteer_<id>_tv64.csv    64 Hz t,tv
//   volunteer_<id>_truth.yaml  the true hysteresis-model coefficients in the model-file format
//                              (wavelet "none"); r2 is the truth model's R^2 against the
//                              noisy recording; meta holds the generator parameters.
// Command-line parsing: CLI11 with the tools' conventions (tool_cli.hpp).
// Exit status: 0 ok, 2 bad arguments, 1 a file could not be written.

#include <CLI/CLI.hpp>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include <sys/stat.h>

#include "pedicle_drilling/core/breathing/identification.hpp"
#include "pedicle_drilling/core/breathing/motion_model_io.hpp"
#include "pedicle_drilling/core/breathing/virtual_volunteer.hpp"
#include "tool_cli.hpp"

namespace {

std::string num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.17g", v);
  return buf;
}

}  // namespace

int main(int argc, char** argv) {
  namespace pd = pedicle_drilling::core;
  namespace tools = pedicle_drilling::tools;
  CLI::App app{
      "Writes volunteer_<id>.csv (8 Hz t,tv,ap,si,lr), volunteer_<id>_tv64.csv (64 Hz t,tv) and "
      "volunteer_<id>_truth.yaml for the default virtual volunteers (ids 1..5).",
      "generate_volunteers"};
  tools::applyConventions(&app);
  app.footer("Exit status: 0 ok, 2 bad arguments, 1 a file could not be written.");
  std::string dir;
  double duration = 30.0;
  std::string ids_text = "1,2,3,4,5";
  app.add_option("--out", dir, "output folder (created if missing, one level)")->required();
  app.add_option("--duration", duration, "recording length, s (two breaths at least)")
      ->check(tools::finiteNumber(6.0, 3600.0));
  app.add_option("--ids", ids_text, "volunteers")->check(tools::intList(1, 5));
  if (const auto exit = tools::parseCommandLine(&app, argc, argv)) return *exit;
  const std::vector<int> ids = pd::parseIntList(ids_text, "--ids");

  if (::mkdir(dir.c_str(), 0755) != 0 && errno != EEXIST) {
    std::cerr << "generate_volunteers: cannot create " << dir << ": " << std::strerror(errno)
              << "\n";
    return 1;
  }
  try {
    for (int id : ids) {
      pd::VolunteerParams p = pd::defaultVolunteer(id);
      p.duration_s = duration;
      const pd::VolunteerData v = pd::generateVolunteer(p);
      const std::string stem = dir + "/volunteer_" + std::to_string(id);
      pd::writeRecordingCsv(v.recording, stem + ".csv");

      pd::PatientModel truth;
      truth.patient_id = "volunteer_" + std::to_string(id);
      const pd::PairedSamples paired = pd::pairAtMarkerTimes(v.recording);
      for (pd::Axis a : pd::kAllAxes) {
        pd::AxisModelRecord& r = truth.axes[static_cast<int>(a)];
        r.model = p.truth.axis(a);
        pd::AxisSamples s;
        s.tv = pd::pairAtMarkerTimes(v.clean).tv;
        s.dtv_dt = v.dtv_dt_disp;
        s.d = paired.axis(a);
        const std::vector<double> pred = pd::predictAll(r.model, s);
        r.r2 = pd::rSquared(s.d, pred);
        r.rmse = pd::rootMeanSquareError(s.d, pred);
        r.wavelet = "none";
        truth.meta.emplace_back("lag_s_" + pd::axisName(a), num(r.model.lagSeconds()));
        truth.meta.emplace_back("tracker_noise_mm_" + pd::axisName(a),
                                num(p.tracker_noise_mm[static_cast<int>(a)]));
        truth.meta.emplace_back("drift_mm_" + pd::axisName(a),
                                num(p.drift_mm[static_cast<int>(a)]));
        truth.meta.emplace_back("movement_mm_" + pd::axisName(a),
                                num(p.movement_mm[static_cast<int>(a)]));
      }
      truth.meta.emplace_back("seed", std::to_string(p.seed));
      truth.meta.emplace_back("duration_s", num(p.duration_s));
      truth.meta.emplace_back("breaths_per_min", num(p.breaths_per_min));
      truth.meta.emplace_back("rate_cv", num(p.rate_cv));
      truth.meta.emplace_back("tidal_volume_ml", num(p.tidal_volume_ml));
      truth.meta.emplace_back("tidal_volume_cv", num(p.tidal_volume_cv));
      truth.meta.emplace_back("ti_over_ttot", num(p.ti_over_ttot));
      truth.meta.emplace_back("tv_noise_ml", num(p.tv_noise_ml));
      truth.meta.emplace_back("movements_per_min", num(p.movements_per_min));
      truth.meta.emplace_back("num_breaths", std::to_string(v.num_breaths));
      pd::writeModelYaml(truth, stem + "_truth.yaml");
      std::printf("volunteer %d: %d breaths, truth q1 AP %.5g SI %.5g LR %.5g mm/ml -> %s.csv\n",
                  id, v.num_breaths, p.truth.axis(pd::Axis::kAP).q1, p.truth.axis(pd::Axis::kSI).q1,
                  p.truth.axis(pd::Axis::kLR).q1, stem.c_str());
    }
  } catch (const std::exception& e) {
    std::cerr << "generate_volunteers: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
