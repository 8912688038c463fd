/**
 * @file motion_pipeline.cpp
 * @brief Per-patient identification pipeline shared by the identify CLI and the nodelet.
 */
#include "pedicle_drilling/core/breathing/motion_pipeline.hpp"

#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>

#include "pedicle_drilling/core/breathing/wavelet.hpp"

namespace pedicle_drilling::core {

namespace {

double mean(const std::vector<double>& x) {
  double s = 0.0;
  for (double v : x) s += v;
  return s / static_cast<double>(x.size());
}

}  // namespace

std::string methodName(IdentificationMethod method) {
  return method == IdentificationMethod::kPso ? "pso" : "ceres";
}

bool parseMethod(const std::string& name, IdentificationMethod* method) {
  if (name == "ceres") {
    *method = IdentificationMethod::kCeres;
  } else if (name == "pso") {
    *method = IdentificationMethod::kPso;
  } else {
    return false;
  }
  return true;
}

namespace {

const ParamTable<DenoiseOptions>& keptLevelsTable() {
  static const ParamTable<DenoiseOptions> t = [] {
    ParamTable<DenoiseOptions> d;
    d.integers("kept_levels", &DenoiseOptions::kept_levels, Range::closed(1, 16));
    return d;
  }();
  return t;
}

}  // namespace

const ParamTable<PipelineOptions>& PipelineOptions::table() {
  static const ParamTable<PipelineOptions> t = [] {
    using O = PipelineOptions;
    ParamTable<O> d;
    d.parsed(
         "model", {"linear", "hysteresis"}, "", [](const O& v) { return modelKindName(v.kind); },
         [](O& v, const std::string& x) { parseModelKind(x, &v.kind); })
        .parsed(
            "method", {"ceres", "pso"}, "", [](const O& v) { return methodName(v.method); },
            [](O& v, const std::string& x) { parseMethod(x, &v.method); })
        .flag("denoise", &O::denoise)
        .flag("denoise_tv", &O::denoise_tv)
        .integer(
            "level", [](const O& v) { return static_cast<double>(v.denoise_options.level); },
            [](O& v, double x) { v.denoise_options.level = static_cast<int>(x); },
            Range::closed(1, 16))
        .include(keptLevelsTable(), &O::denoise_options)
        .parsed(
            "wavelets", {}, "all, or comma-separated wavelet names",
            [](const O& v) {
              if (v.denoise_options.candidates == allWaveletNames()) return std::string("all");
              std::string s;
              for (const std::string& w : v.denoise_options.candidates)
                s += (s.empty() ? "" : ",") + w;
              return s;
            },
            [](O& v, const std::string& x) {
              std::vector<std::string> names;
              if (x == "all") {
                names = allWaveletNames();
              } else {
                std::stringstream items(x);
                std::string w;
                while (std::getline(items, w, ',')) {
                  if (findWavelet(w) == nullptr) {
                    throw std::invalid_argument("names an unknown wavelet '" + w + "'");
                  }
                  names.push_back(w);
                }
              }
              v.denoise_options.candidates = names;
            })
        .number(
            "delta_tv_ml", [](const O& v) { return v.denoise_options.delta_tv; },
            [](O& v, double x) { v.denoise_options.delta_tv = x; }, Range::closed(0, 1000), "ml")
        .integer(
            "pso_seed", [](const O& v) { return static_cast<double>(v.pso.seed); },
            [](O& v, double x) { v.pso.seed = static_cast<std::uint64_t>(x); },
            Range::closed(0, 2147483647));
    return d;
  }();
  return t;
}

void PipelineOptions::validate() const {
  table().validate(*this);
  const DenoiseOptions& d = denoise_options;
  for (int k : d.kept_levels) {
    if (k > d.level) {
      throw std::invalid_argument("kept_levels has " + std::to_string(k) + ", above level " +
                                  std::to_string(d.level));
    }
  }
  if (d.candidates.empty()) throw std::invalid_argument("wavelets: no candidate wavelet");
  for (const std::string& w : d.candidates) {
    if (findWavelet(w) == nullptr)
      throw std::invalid_argument("wavelets: unknown wavelet '" + w + "'");
  }
  if (denoise_tv && !denoise) throw std::invalid_argument("denoise_tv needs denoise true");
  if (pso.population < 1 || pso.iterations < 1) {
    throw std::invalid_argument("PSO population and iterations must be >= 1");
  }
}

void validatePairedSamples(const PairedSamples& p, const std::string& source) {
  const size_t n = p.t.size();
  if (n == 0) throw MissingColumnError(source + ": no samples");
  if (p.tv.size() != n || p.ap.size() != n || p.si.size() != n || p.lr.size() != n) {
    throw MissingColumnError(source + ": columns t, tv, ap, si, lr have different lengths");
  }
  const std::array<std::pair<const char*, const std::vector<double>*>, 5> columns = {
      {{"t", &p.t}, {"tv", &p.tv}, {"ap", &p.ap}, {"si", &p.si}, {"lr", &p.lr}}};
  for (const auto& column : columns) {
    for (size_t i = 0; i < n; ++i) {
      if (!std::isfinite((*column.second)[i])) {
        throw NonFiniteValueError(source + ": sample " + std::to_string(i) + ", column '" +
                                  column.first + "' is not finite (NaN or inf)");
      }
    }
  }
  for (size_t i = 1; i < n; ++i) {
    if (!(p.t[i] > p.t[i - 1])) {
      throw NonIncreasingTimeError(source + ": time is not strictly increasing at sample " +
                                   std::to_string(i));
    }
  }
  const int breaths = countBreaths(p.tv);
  if (breaths < 2) {
    throw TooFewBreathsError(source + ": fewer than two breaths in the tidal volume (found " +
                             std::to_string(breaths) + " over " + std::to_string(n) + " samples)");
  }
}

PipelineResult identifyPatient(const PairedSamples& rec, const PipelineOptions& options,
                               const std::string& patient_id, const std::string& source) {
  options.validate();
  validatePairedSamples(rec, source);
  PipelineResult result;
  result.model.patient_id = patient_id;
  result.breaths = countBreaths(rec.tv);
  result.samples = rec.t.size();
  result.duration_s = rec.t.back() - rec.t.front();
  const DenoiseOptions& dopts = options.denoise_options;
  const std::vector<double> dtv = timeDerivative(rec.t, rec.tv);
  for (Axis axis : kAllAxes) {
    const int index = static_cast<int>(axis);
    AxisReport& report = result.axes[index];
    AxisModelRecord& out = result.model.axes[index];
    report.axis = axis;
    report.raw = rec.axis(axis);
    AxisSamples& samples = report.samples;
    samples.tv = rec.tv;
    samples.dtv_dt = dtv;
    if (options.denoise) {
      const DenoiseResult dr = selectAndDenoise(report.raw, rec.tv, dopts);
      const double offset = mean(report.raw);  // s_de has no DC: add the raw mean back
      samples.d = dr.denoised;
      for (double& v : samples.d) v += offset;
      report.wavelet = dr.wavelet;
      out.level = dopts.level;
      out.kept_levels = dopts.kept_levels;
      if (options.denoise_tv) {
        const double tv_mean = mean(rec.tv);
        samples.tv = denoise(rec.tv, dr.wavelet, dopts.level, dopts.kept_levels);
        for (double& v : samples.tv) v += tv_mean;
        samples.dtv_dt = timeDerivative(rec.t, samples.tv);
      }
    } else {
      samples.d = report.raw;
      report.wavelet = "none";
      out.level = 0;
      out.kept_levels.clear();
    }
    report.fit = options.method == IdentificationMethod::kPso
                     ? fitPso(options.kind, samples, options.pso)
                     : fitCeres(options.kind, samples, options.ceres);
    report.r2_raw = rSquared(report.raw, predictAll(report.fit.model, samples));
    out.wavelet = report.wavelet;
    out.model = report.fit.model;
    out.r2 = report.fit.r2;
    out.rmse = report.fit.rmse;
  }
  return result;
}

std::array<double, 3> AxisMapping::map(double x, double y, double z) const {
  const std::array<double, 3> p{{x, y, z}};
  std::array<double, 3> d{};
  for (int k = 0; k < 3; ++k) d[k] = sign[k] * p[index[k]];
  return d;
}

AxisMapping parseAxisMapping(const std::string& ap, const std::string& si, const std::string& lr) {
  AxisMapping m;
  const std::array<const std::string*, 3> specs{{&ap, &si, &lr}};
  std::array<bool, 3> used{{false, false, false}};
  for (int k = 0; k < 3; ++k) {
    const std::string& spec = *specs[k];
    const std::string name = axisName(static_cast<Axis>(k));
    std::string letter = spec;
    double sign = 1.0;
    if (!letter.empty() && (letter[0] == '+' || letter[0] == '-')) {
      sign = letter[0] == '-' ? -1.0 : 1.0;
      letter = letter.substr(1);
    }
    int index = -1;
    if (letter == "x") index = 0;
    if (letter == "y") index = 1;
    if (letter == "z") index = 2;
    if (index < 0) {
      throw std::invalid_argument(name + " axis '" + spec +
                                  "' is not one of x, y, z with an optional + or - sign");
    }
    if (used[index]) {
      throw std::invalid_argument(name + " axis '" + spec +
                                  "' uses a tracker axis already taken by another axis");
    }
    used[index] = true;
    m.index[k] = index;
    m.sign[k] = sign;
  }
  return m;
}

std::string formatAxisReport(const AxisReport& r) {
  char buf[320];
  std::snprintf(buf, sizeof(buf),
                "%s: wavelet %-8s q1 %.6g mm/ml  q2 %.6g mm*s/ml  q0 %.6g mm  R2 %.4f "
                "(raw %.4f)  RMSE %.4f mm  %d it  %.3f ms",
                axisName(r.axis).c_str(), r.wavelet.c_str(), r.fit.model.q1, r.fit.model.q2,
                r.fit.model.q0, r.fit.r2, r.r2_raw, r.fit.rmse, r.fit.iterations,
                r.fit.time_s * 1e3);
  std::string line = buf;
  const std::string label = equivalentStiffnessLabel(r.axis);
  if (!label.empty()) {
    std::snprintf(buf, sizeof(buf), "  stiffness %.4g %s",
                  equivalentStiffness(r.axis, r.fit.model.q1), label.c_str());
    line += buf;
  }
  return line;
}

}  // namespace pedicle_drilling::core
