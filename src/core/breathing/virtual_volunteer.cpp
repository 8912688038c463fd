/**
 * @file virtual_volunteer.cpp
 * @brief Virtual-volunteer generator and recording CSV files (see virtual_volunteer.hpp).
 */
#include "pedicle_drilling/core/breathing/virtual_volunteer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <map>
#include <random>
#include <sstream>

#include "pedicle_drilling/core/common/atomic_file.hpp"
#include "pedicle_drilling/core/common/portable_random.hpp"

namespace pedicle_drilling::core {

namespace {

constexpr double kPi = 3.14159265358979323846;

struct Breath {
  double start;  // s
  double ti;     // s
  double te;     // s
  double vt;     // ml
};

/** Tidal volume and its derivative inside one breath at local time tau in [0, ti + te). */
void breathVolume(const Breath& b, double tau, double* v, double* dv) {
  if (tau < b.ti) {
    const double s = tau / b.ti;
    *v = b.vt * s * s * (3.0 - 2.0 * s);
    *dv = b.vt * 6.0 * s * (1.0 - s) / b.ti;
  } else {
    const double s = std::min(1.0, (tau - b.ti) / b.te);
    const double u = 1.0 - s;
    *v = b.vt * u * u * u * (1.0 + 3.0 * s);
    *dv = -b.vt * 12.0 * s * u * u / b.te;
  }
}

double interpolate(const std::vector<double>& t, const std::vector<double>& x, double tq) {
  if (tq <= t.front()) return x.front();
  if (tq >= t.back()) return x.back();
  const size_t k = static_cast<size_t>(std::upper_bound(t.begin(), t.end(), tq) - t.begin());
  const double a = (tq - t[k - 1]) / (t[k] - t[k - 1]);
  return x[k - 1] + a * (x[k] - x[k - 1]);
}

// ------------------------------------------------------------------------------ CSV reading

std::string trim(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  const size_t e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

std::vector<std::string> splitComma(const std::string& line) {
  std::vector<std::string> out;
  std::string field;
  std::istringstream is(line);
  while (std::getline(is, field, ',')) out.push_back(trim(field));
  if (!line.empty() && line.back() == ',') out.push_back("");
  return out;
}

/** Reads a CSV, returns the requested columns in order; validates numbers and time. */
std::vector<std::vector<double>> readColumns(const std::string& path,
                                             const std::vector<std::string>& required) {
  std::ifstream in(path);
  if (!in) throw MissingColumnError(path + ": cannot open file");
  std::string line;
  std::vector<std::string> header;
  while (std::getline(in, line)) {
    if (!trim(line).empty()) {
      header = splitComma(line);
      break;
    }
  }
  if (header.empty()) throw MissingColumnError(path + ": empty file, no header");
  std::map<std::string, size_t> index;
  for (size_t i = 0; i < header.size(); ++i) index[header[i]] = i;
  std::vector<size_t> cols;
  for (const std::string& name : required) {
    auto it = index.find(name);
    if (it == index.end()) {
      throw MissingColumnError(path + ": missing required column '" + name + "'");
    }
    cols.push_back(it->second);
  }
  std::vector<std::vector<double>> data(required.size());
  size_t line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    if (trim(line).empty()) continue;
    const std::vector<std::string> fields = splitComma(line);
    if (fields.size() != header.size()) {
      throw MalformedRowError(path + ": line " + std::to_string(line_no) + " has " +
                              std::to_string(fields.size()) + " fields, header has " +
                              std::to_string(header.size()));
    }
    for (size_t c = 0; c < cols.size(); ++c) {
      const std::string& cell = fields[cols[c]];
      char* end = nullptr;
      const double v = std::strtod(cell.c_str(), &end);
      if (cell.empty() || end == cell.c_str() || *end != '\0') {
        throw MalformedRowError(path + ": line " + std::to_string(line_no) + ", column '" +
                                required[c] + "': '" + cell + "' is not a number");
      }
      if (!std::isfinite(v)) {
        throw NonFiniteValueError(path + ": line " + std::to_string(line_no) + ", column '" +
                                  required[c] + "' is NaN or infinite");
      }
      data[c].push_back(v);
    }
  }
  const std::vector<double>& t = data[0];
  if (t.size() < 2) {
    throw TooFewBreathsError(path + ": fewer than 2 samples, fewer than two breaths");
  }
  for (size_t i = 1; i < t.size(); ++i) {
    if (!(t[i] > t[i - 1])) {
      throw NonIncreasingTimeError(path + ": time is not strictly increasing at data row " +
                                   std::to_string(i + 1) + " (t = " + std::to_string(t[i]) +
                                   " after " + std::to_string(t[i - 1]) + ")");
    }
  }
  return data;
}

void checkBreaths(const std::string& path, const std::vector<double>& tv) {
  const int n = countBreaths(tv);
  if (n < 2) {
    throw TooFewBreathsError(path + ": fewer than two breaths in column 'tv' (found " +
                             std::to_string(n) + ")");
  }
}

}  // namespace

const std::vector<double>& PairedSamples::axis(Axis a) const {
  switch (a) {
    case Axis::kAP:
      return ap;
    case Axis::kSI:
      return si;
    case Axis::kLR:
      return lr;
  }
  return ap;
}

VolunteerParams VolunteerParams::noiseFree() const {
  VolunteerParams p = *this;
  p.tv_noise_ml = 0.0;
  p.tracker_noise_mm = {{0.0, 0.0, 0.0}};
  p.drift_mm = {{0.0, 0.0, 0.0}};
  p.movements_per_min = 0.0;
  p.movement_mm = {{0.0, 0.0, 0.0}};
  return p;
}

double movementDisplacementMm(const std::vector<PatientMovement>& movements, int axis, double t) {
  // Smooth 0 -> 1 transition over [0, w] (raised cosine).
  auto smooth_step = [](double x, double w) {
    if (x <= 0.0) return 0.0;
    if (x >= w) return 1.0;
    return 0.5 * (1.0 - std::cos(kPi * x / w));
  };
  double d = 0.0;
  for (const PatientMovement& m : movements) {
    if (t <= m.t) continue;
    double f = smooth_step(t - m.t, m.ramp);
    if (m.hold >= 0.0) f -= smooth_step(t - m.t - m.ramp - m.hold, m.ramp);
    d += m.size[axis] * f;
  }
  return d;
}

VolunteerParams defaultVolunteer(int id) {
  if (id < 1 || id > 5) {
    throw std::invalid_argument("defaultVolunteer: id must be 1..5, got " + std::to_string(id));
  }
  const size_t k = static_cast<size_t>(id - 1);
  // Per-volunteer diversity (Benchetrit 2000): rate, depth, pattern, amplitude, lag, noise.
  const double rate[5] = {20.0, 18.0, 22.0, 19.0, 21.0};     // breaths/min
  const double vt[5] = {500.0, 540.0, 460.0, 520.0, 480.0};  // ml
  const double rate_cv[5] = {0.10, 0.12, 0.15, 0.11, 0.13};
  const double vt_cv[5] = {0.12, 0.15, 0.18, 0.13, 0.16};
  const double ti_frac[5] = {0.42, 0.40, 0.44, 0.41, 0.43};
  const double amp_ap[5] = {5.0, 4.6, 4.2, 5.4, 4.8};  // mm peak-to-peak per VT
  const double amp_si[5] = {2.0, 1.8, 2.2, 1.9, 2.1};
  const double amp_lr[5] = {1.0, -0.9, 1.1, -0.8, 1.2};  // sign: side of the tilt
  const double lag[5] = {0.08, 0.12, 0.06, 0.14, 0.10};  // s (assumed)
  const double tracker_scale[5] = {0.80, 0.90, 1.00, 0.85, 0.95};
  const double drift[5] = {0.15, 0.20, 0.30, 0.10, 0.25};  // mm
  const double moves[5] = {1.5, 2.0, 3.0, 2.0, 2.5};       // per min

  VolunteerParams p;
  p.id = id;
  p.seed = 0x5eedULL * 1000003ULL + static_cast<std::uint64_t>(id) * 7919ULL;
  p.breaths_per_min = rate[k];
  p.tidal_volume_ml = vt[k];
  p.rate_cv = rate_cv[k];
  p.tidal_volume_cv = vt_cv[k];
  p.ti_over_ttot = ti_frac[k];
  const double amps[3] = {amp_ap[k], amp_si[k], amp_lr[k]};
  const double q0s[3] = {0.3, -0.2, 0.1};  // arbitrary tracker zero offsets, mm
  for (Axis a : kAllAxes) {
    AxisModel& m = p.truth.axis(a);
    const int i = static_cast<int>(a);
    m.kind = ModelKind::kHysteresis;
    m.q1 = amps[i] / vt[k];
    m.q2 = -m.q1 * lag[k];
    m.q0 = q0s[i];
  }
  // NDI Polaris 0.25 mm RMS (3-D) per marker, relative to a reference marker: 0.25 sqrt(2/3).
  const double sigma = 0.25 * std::sqrt(2.0 / 3.0) * tracker_scale[k];
  p.tracker_noise_mm = {{sigma, sigma, sigma}};
  p.drift_mm = {{drift[k], drift[k], drift[k]}};
  p.movements_per_min = moves[k];
  p.movement_mm = {{0.10, 0.10, 0.25}};
  return p;
}

VolunteerData generateVolunteer(const VolunteerParams& p) {
  if (!(p.duration_s > 0.0) || !(p.tv_rate_hz > 0.0) || !(p.disp_rate_hz > 0.0) ||
      !(p.breaths_per_min > 0.0) || !(p.tidal_volume_ml > 0.0) || !(p.ti_over_ttot > 0.0) ||
      !(p.ti_over_ttot < 1.0)) {
    throw std::invalid_argument("generateVolunteer: invalid parameters");
  }
  std::mt19937_64 rng(p.seed);
  // Portable transforms (common/portable_random.hpp): the same recording on every library.
  PolarNormal normal;
  const auto unit = [](std::mt19937_64& r) { return canonical(r); };

  // Breaths: AR(1) unit-variance fluctuations of duration and depth, clipped to +-2.5 sigma.
  const double rho = p.breath_autocorrelation;
  const double innov = std::sqrt(std::max(0.0, 1.0 - rho * rho));
  const double mean_ttot = 60.0 / p.breaths_per_min;
  std::vector<Breath> breaths;
  double e = normal(rng);
  double u = normal(rng);
  double t = -unit(rng) * mean_ttot;  // the recording starts at a random phase
  while (t < p.duration_s + 1.0) {
    const double ttot = mean_ttot * (1.0 + p.rate_cv * std::clamp(e, -2.5, 2.5));
    const double vt = p.tidal_volume_ml * (1.0 + p.tidal_volume_cv * std::clamp(u, -2.5, 2.5));
    breaths.push_back({t, p.ti_over_ttot * ttot, (1.0 - p.ti_over_ttot) * ttot, vt});
    t += ttot;
    e = rho * e + innov * normal(rng);
    u = rho * u + innov * normal(rng);
  }
  auto volumeAt = [&breaths](double tq, double* v, double* dv) {
    size_t k = 0;
    while (k + 1 < breaths.size() && breaths[k + 1].start <= tq) ++k;
    breathVolume(breaths[k], tq - breaths[k].start, v, dv);
  };

  VolunteerData out;
  out.params = p;

  // Small patient movements: Poisson process over the recording.
  std::vector<PatientMovement> moves;
  if (p.movements_per_min > 0.0) {
    const auto gap = [&p](std::mt19937_64& r) {
      return exponential(r, p.movements_per_min / 60.0);
    };
    double tm = gap(rng);
    while (tm < p.duration_s) {
      PatientMovement m;
      m.t = tm;
      m.ramp = 0.5 + 0.5 * unit(rng);
      m.hold = unit(rng) < 0.5 ? -1.0 : 1.0 + 2.0 * unit(rng);
      for (int i = 0; i < 3; ++i) m.size[i] = p.movement_mm[i] * normal(rng);
      moves.push_back(m);
      tm += gap(rng);
    }
  }
  // Slow drift: ramp + slow sinusoid per axis.
  std::array<double, 3> drift_slope{}, drift_period{}, drift_phase{};
  for (int i = 0; i < 3; ++i) {
    drift_slope[i] = (unit(rng) < 0.5 ? -1.0 : 1.0) * 0.6 * p.drift_mm[i] / p.duration_s;
    drift_period[i] = 40.0 + 50.0 * unit(rng);
    drift_phase[i] = 2.0 * kPi * unit(rng);
  }

  // 64 Hz tidal volume.
  const size_t n_tv = static_cast<size_t>(std::ceil(p.duration_s * p.tv_rate_hz - 1e-9));
  for (size_t k = 0; k < n_tv; ++k) {
    const double tk = static_cast<double>(k) / p.tv_rate_hz;
    double v = 0.0, dv = 0.0;
    volumeAt(tk, &v, &dv);
    out.clean.t_tv.push_back(tk);
    out.clean.tv.push_back(v);
    out.dtv_dt.push_back(dv);
    out.recording.t_tv.push_back(tk);
    out.recording.tv.push_back(v + p.tv_noise_ml * normal(rng));
  }

  // 8 Hz displacement.
  const size_t n_d = static_cast<size_t>(std::ceil(p.duration_s * p.disp_rate_hz - 1e-9));
  for (size_t k = 0; k < n_d; ++k) {
    const double tk = static_cast<double>(k) / p.disp_rate_hz;
    double v = 0.0, dv = 0.0;
    volumeAt(tk, &v, &dv);
    out.clean.t_disp.push_back(tk);
    out.recording.t_disp.push_back(tk);
    out.dtv_dt_disp.push_back(dv);
    std::array<double, 3> clean{}, noisy{};
    for (Axis a : kAllAxes) {
      const int i = static_cast<int>(a);
      clean[i] = p.truth.predict(a, v, dv);
      const double drift =
          drift_slope[i] * tk +
          0.4 * p.drift_mm[i] * std::sin(2.0 * kPi * tk / drift_period[i] + drift_phase[i]);
      noisy[i] = clean[i] + drift + movementDisplacementMm(moves, i, tk) +
                 p.tracker_noise_mm[i] * normal(rng);
    }
    out.clean.ap.push_back(clean[0]);
    out.clean.si.push_back(clean[1]);
    out.clean.lr.push_back(clean[2]);
    out.recording.ap.push_back(noisy[0]);
    out.recording.si.push_back(noisy[1]);
    out.recording.lr.push_back(noisy[2]);
  }
  // One definition of a breath: what `identify` and ~identify count in the written recording
  // (countBreaths on the tidal volume at the marker times). Counting the breaths that start
  // inside the recording once gave 10 where identify reported 9 (the last inspiration cut off).
  out.num_breaths = countBreaths(pairAtMarkerTimes(out.recording).tv);
  return out;
}

PairedSamples pairAtMarkerTimes(const Recording& r) {
  if (r.t_tv.size() != r.tv.size() || r.t_tv.empty()) {
    throw std::invalid_argument("pairAtMarkerTimes: empty or inconsistent tidal-volume stream");
  }
  if (r.ap.size() != r.t_disp.size() || r.si.size() != r.t_disp.size() ||
      r.lr.size() != r.t_disp.size()) {
    throw std::invalid_argument("pairAtMarkerTimes: inconsistent displacement stream");
  }
  PairedSamples p;
  p.t = r.t_disp;
  p.ap = r.ap;
  p.si = r.si;
  p.lr = r.lr;
  p.tv.reserve(p.t.size());
  for (double tq : p.t) p.tv.push_back(interpolate(r.t_tv, r.tv, tq));
  return p;
}

AxisSamples axisSamples(const PairedSamples& paired, Axis axis) {
  AxisSamples s;
  s.tv = paired.tv;
  s.dtv_dt = timeDerivative(paired.t, paired.tv);
  s.d = paired.axis(axis);
  return s;
}

int countBreaths(const std::vector<double>& tv) {
  if (tv.size() < 2) return 0;
  // Robust levels: 5th and 95th percentiles, so that one deep breath does not hide the
  // shallower ones (tidal volumes vary by 10-30 % breath to breath).
  std::vector<double> sorted = tv;
  std::sort(sorted.begin(), sorted.end());
  const size_t n = sorted.size();
  const double base = sorted[static_cast<size_t>(0.05 * static_cast<double>(n - 1))];
  const double top = sorted[static_cast<size_t>(0.95 * static_cast<double>(n - 1))];
  const double range = top - base;
  if (!(range > 0.0)) return 0;
  const double lo = base + 0.25 * range;
  const double hi = base + 0.5 * range;
  int breaths = 0;
  bool armed = false;  // seen a sample below lo since the last counted inspiration
  for (double v : tv) {
    if (v < lo) {
      armed = true;
    } else if (v > hi && armed) {
      ++breaths;
      armed = false;
    }
  }
  return breaths;
}

std::string tv64PathFor(const std::string& csv_path) {
  const std::string ext = ".csv";
  if (csv_path.size() >= ext.size() &&
      csv_path.compare(csv_path.size() - ext.size(), ext.size(), ext) == 0) {
    return csv_path.substr(0, csv_path.size() - ext.size()) + "_tv64.csv";
  }
  return csv_path + "_tv64.csv";
}

void writeRecordingCsv(const Recording& r, const std::string& csv_path) {
  const PairedSamples p = pairAtMarkerTimes(r);
  std::ostringstream paired;
  paired << std::setprecision(17) << "t,tv,ap,si,lr\n";
  for (size_t i = 0; i < p.t.size(); ++i) {
    paired << p.t[i] << ',' << p.tv[i] << ',' << p.ap[i] << ',' << p.si[i] << ',' << p.lr[i]
           << '\n';
  }
  std::ostringstream tv64;
  tv64 << std::setprecision(17) << "t,tv\n";
  for (size_t i = 0; i < r.t_tv.size(); ++i) tv64 << r.t_tv[i] << ',' << r.tv[i] << '\n';
  // Both files or neither, each complete (temporary files renamed into place).
  try {
    AtomicFile paired_file(csv_path);
    AtomicFile tv64_file(tv64PathFor(csv_path));
    paired_file.write(paired.str());
    tv64_file.write(tv64.str());
    paired_file.commit();
    tv64_file.commit();
  } catch (const FileWriteError& e) {
    throw std::runtime_error(std::string("writeRecordingCsv: ") + e.what());
  }
}

PairedSamples readRecordingCsv(const std::string& csv_path) {
  std::vector<std::vector<double>> c = readColumns(csv_path, {"t", "tv", "ap", "si", "lr"});
  checkBreaths(csv_path, c[1]);
  PairedSamples p;
  p.t = std::move(c[0]);
  p.tv = std::move(c[1]);
  p.ap = std::move(c[2]);
  p.si = std::move(c[3]);
  p.lr = std::move(c[4]);
  return p;
}

std::array<std::vector<double>, 2> readTv64Csv(const std::string& csv_path) {
  std::vector<std::vector<double>> c = readColumns(csv_path, {"t", "tv"});
  checkBreaths(csv_path, c[1]);
  return {std::move(c[0]), std::move(c[1])};
}

}  // namespace pedicle_drilling::core
