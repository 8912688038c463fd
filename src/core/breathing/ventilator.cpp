#include "pedicle_drilling/core/breathing/ventilator.hpp"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace pedicle_drilling::core {
namespace {

constexpr double kPi = 3.14159265358979323846;

struct WaveformEntry {
  InspiratoryWaveform waveform;
  const char* name;
};

constexpr WaveformEntry kWaveforms[] = {
    {InspiratoryWaveform::kSquare, "square"},
    {InspiratoryWaveform::kAscendingRamp, "ascending_ramp"},
    {InspiratoryWaveform::kDescendingRamp, "descending_ramp"},
    {InspiratoryWaveform::kSine, "sine"},
    {InspiratoryWaveform::kExponentialRise, "exponential_rise"},
    {InspiratoryWaveform::kExponentialDecay, "exponential_decay"},
};

void require(bool condition, const std::string& field, const std::string& rule, double value) {
  if (!condition) {
    std::ostringstream message;
    message << "ventilator setting '" << field << "' = " << value << " is invalid: must be "
            << rule;
    throw std::invalid_argument(message.str());
  }
}

/**
 * @brief Ceres residual of the three balance equations for unknowns (A, P, tau).
 *        r0: inspired volume - Tv_max, r1: expired volume - Tv_max, r2: the third condition
 *        (P - ratio * A * peak_shape in ratio mode, tau - tau_given in time-constant mode).
 *        All residuals are scaled to be dimensionless.
 */
struct BreathBalanceResidual {
  BreathBalanceResidual(double tv_max, double flow_time, double shape_integral,
                        double expiratory_time, bool ratio_mode, double ratio, double tau_given)
      : tv_max_(tv_max),
        flow_time_(flow_time),
        shape_integral_(shape_integral),
        expiratory_time_(expiratory_time),
        ratio_mode_(ratio_mode),
        ratio_(ratio),
        tau_given_(tau_given) {}

  template <typename T>
  bool operator()(const T* const x, T* residual) const {
    const T& amplitude = x[0];
    const T& peak = x[1];
    const T& tau = x[2];
    residual[0] = (amplitude * flow_time_ * shape_integral_ - tv_max_) / tv_max_;
    residual[1] = (peak * tau * (1.0 - exp(-expiratory_time_ / tau)) - tv_max_) / tv_max_;
    if (ratio_mode_) {
      residual[2] = (peak - ratio_ * amplitude) * (flow_time_ / tv_max_);
    } else {
      residual[2] = (tau - tau_given_) / tau_given_;
    }
    return true;
  }

  /** @brief AutoDiff cost function with 3 residuals and one block of 3 parameters. */
  static ceres::CostFunction* Create(double tv_max, double flow_time, double shape_integral,
                                     double expiratory_time, bool ratio_mode, double ratio,
                                     double tau_given) {
    return new ceres::AutoDiffCostFunction<BreathBalanceResidual, 3, 3>(new BreathBalanceResidual(
        tv_max, flow_time, shape_integral, expiratory_time, ratio_mode, ratio, tau_given));
  }

  double tv_max_, flow_time_, shape_integral_, expiratory_time_;
  bool ratio_mode_;
  double ratio_, tau_given_;
};

}  // namespace

bool parseWaveform(const std::string& name, InspiratoryWaveform* waveform) {
  for (const auto& entry : kWaveforms) {
    if (name == entry.name) {
      *waveform = entry.waveform;
      return true;
    }
  }
  return false;
}

std::string waveformName(InspiratoryWaveform waveform) {
  for (const auto& entry : kWaveforms) {
    if (entry.waveform == waveform) return entry.name;
  }
  return "unknown";
}

std::vector<std::string> waveformNames() {
  std::vector<std::string> names;
  for (const auto& entry : kWaveforms) names.emplace_back(entry.name);
  return names;
}

bool parseIeRatio(const std::string& text, double* inspiratory, double* expiratory) {
  const auto colon = text.find(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 >= text.size()) return false;
  try {
    size_t used_i = 0;
    size_t used_e = 0;
    const std::string left = text.substr(0, colon);
    const std::string right = text.substr(colon + 1);
    const double i = std::stod(left, &used_i);
    const double e = std::stod(right, &used_e);
    if (used_i != left.size() || used_e != right.size()) return false;
    if (!std::isfinite(i) || !std::isfinite(e) || i <= 0.0 || e <= 0.0) return false;
    *inspiratory = i;
    *expiratory = e;
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

const ParamTable<VentilatorSettings>& VentilatorSettings::table() {
  static const ParamTable<VentilatorSettings> t = [] {
    using S = VentilatorSettings;
    ParamTable<S> d;
    d.number("tv_max_ml", &S::tv_max_ml, Range::aboveUpTo(0, 3000), "ml")
        .number("rate_bpm", &S::rate_bpm, Range::aboveUpTo(0, 60), "breaths/min")
        .parsed(
            "ie_ratio", {}, "a:b with positive a and b",
            [](const S& v) {
              return Range::format(v.ie_inspiratory) + ":" + Range::format(v.ie_expiratory);
            },
            [](S& v, const std::string& x) {
              if (!parseIeRatio(x, &v.ie_inspiratory, &v.ie_expiratory)) {
                throw std::invalid_argument("is not of the form a:b with positive a and b");
              }
            })
        .parsed(
            "waveform", waveformNames(), "", [](const S& v) { return waveformName(v.waveform); },
            [](S& v, const std::string& x) { parseWaveform(x, &v.waveform); })
        .number("pause_fraction", &S::pause_fraction, Range::closed(0, 0.5))
        .parsed(
            "expiratory_spec", {"peak_ratio", "time_constant"}, "",
            [](const S& v) {
              return std::string(v.expiratory_spec == ExpiratorySpec::kPeakRatio ? "peak_ratio"
                                                                                 : "time_constant");
            },
            [](S& v, const std::string& x) {
              v.expiratory_spec =
                  x == "peak_ratio" ? ExpiratorySpec::kPeakRatio : ExpiratorySpec::kTimeConstant;
            })
        .number("peak_flow_ratio", &S::peak_flow_ratio, Range::closed(0.2, 10))
        .number("expiratory_tau_s", &S::expiratory_tau_s, Range::aboveUpTo(0, 10), "s")
        .number("ramp_start_fraction", &S::ramp_start_fraction, Range::fromBelow(0, 1))
        .number("exponential_shape", &S::exponential_shape, Range::aboveUpTo(0, 10));
    return d;
  }();
  return t;
}

void VentilatorSettings::validate() const {
  table().validate(*this);
  require(std::isfinite(ie_inspiratory) && ie_inspiratory > 0.0, "ie_inspiratory", "> 0",
          ie_inspiratory);
  require(std::isfinite(ie_expiratory) && ie_expiratory > 0.0, "ie_expiratory", "> 0",
          ie_expiratory);
}

VentilatorModel::VentilatorModel(const VentilatorSettings& settings) : settings_(settings) {
  settings_.validate();
  period_ = 60.0 / settings_.rate_bpm;
  inspiratory_time_ =
      period_ * settings_.ie_inspiratory / (settings_.ie_inspiratory + settings_.ie_expiratory);
  flow_time_ = inspiratory_time_ * (1.0 - settings_.pause_fraction);
  const double expiratory_time = period_ - inspiratory_time_;
  const double shape_integral = shapeIntegral(1.0);
  const bool ratio_mode = settings_.expiratory_spec == ExpiratorySpec::kPeakRatio;

  if (ratio_mode) {
    // P tau (1 - exp(-Te / tau)) < P Te for any tau, so the expiration can only return Tv_max
    // if the peak expiratory flow exceeds Tv_max / Te.
    const double peak_expiratory =
        settings_.peak_flow_ratio * settings_.tv_max_ml / (flow_time_ * shape_integral);
    if (peak_expiratory * expiratory_time <= settings_.tv_max_ml * 1.0001) {
      std::ostringstream message;
      message << "ventilator setting 'peak_flow_ratio' = " << settings_.peak_flow_ratio
              << " is too small: an exponential expiration of peak " << peak_expiratory
              << " ml/s cannot return " << settings_.tv_max_ml << " ml within the expiratory time "
              << expiratory_time << " s";
      throw std::invalid_argument(message.str());
    }
  }

  // Initial guess: closed-form amplitude, tau a third of the expiratory time.
  double x[3] = {settings_.tv_max_ml / (flow_time_ * shape_integral), 0.0,
                 ratio_mode ? expiratory_time / 3.0 : settings_.expiratory_tau_s};
  x[1] = ratio_mode ? settings_.peak_flow_ratio * x[0]
                    : settings_.tv_max_ml / (x[2] * (1.0 - std::exp(-expiratory_time / x[2])));

  ceres::Problem problem;
  problem.AddResidualBlock(BreathBalanceResidual::Create(
                               settings_.tv_max_ml, flow_time_, shape_integral, expiratory_time,
                               ratio_mode, settings_.peak_flow_ratio, settings_.expiratory_tau_s),
                           nullptr, x);
  problem.SetParameterLowerBound(x, 0, 1e-9);
  problem.SetParameterLowerBound(x, 1, 1e-9);
  problem.SetParameterLowerBound(x, 2, 1e-6);
  ceres::Solver::Options options;
  options.trust_region_strategy_type = ceres::DOGLEG;
  options.dogleg_type = ceres::TRADITIONAL_DOGLEG;
  options.linear_solver_type = ceres::DENSE_QR;
  options.function_tolerance = 1e-20;
  options.gradient_tolerance = 1e-20;
  options.parameter_tolerance = 1e-15;
  options.max_num_iterations = 200;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  solver_iterations_ = static_cast<int>(summary.iterations.size());

  amplitude_ = x[0];
  expiratory_peak_ = x[1];
  expiratory_tau_ = x[2];
  const ConstraintResiduals r = residuals();
  const double tolerance = 1e-9 * settings_.tv_max_ml;
  if (!(std::abs(r.inspired_minus_tv_ml) < tolerance &&
        std::abs(r.expired_plus_tv_ml) < tolerance)) {
    std::ostringstream message;
    message << "ventilator: Ceres did not balance the breath (inspired residual "
            << r.inspired_minus_tv_ml << " ml, expired residual " << r.expired_plus_tv_ml
            << " ml): " << summary.BriefReport();
    throw std::runtime_error(message.str());
  }
}

double VentilatorModel::shapeValue(double x) const {
  const double r0 = settings_.ramp_start_fraction;
  const double k = settings_.exponential_shape;
  switch (settings_.waveform) {
    case InspiratoryWaveform::kSquare:
      return 1.0;
    case InspiratoryWaveform::kAscendingRamp:
      return r0 + (1.0 - r0) * x;
    case InspiratoryWaveform::kDescendingRamp:
      return 1.0 - (1.0 - r0) * x;
    case InspiratoryWaveform::kSine:
      return std::sin(kPi * x);
    case InspiratoryWaveform::kExponentialRise:
      return (1.0 - std::exp(-x / k)) / (1.0 - std::exp(-1.0 / k));
    case InspiratoryWaveform::kExponentialDecay:
      return std::exp(-x / k);
  }
  return 0.0;
}

double VentilatorModel::shapeIntegral(double x) const {
  const double r0 = settings_.ramp_start_fraction;
  const double k = settings_.exponential_shape;
  switch (settings_.waveform) {
    case InspiratoryWaveform::kSquare:
      return x;
    case InspiratoryWaveform::kAscendingRamp:
      return r0 * x + 0.5 * (1.0 - r0) * x * x;
    case InspiratoryWaveform::kDescendingRamp:
      return x - 0.5 * (1.0 - r0) * x * x;
    case InspiratoryWaveform::kSine:
      return (1.0 - std::cos(kPi * x)) / kPi;
    case InspiratoryWaveform::kExponentialRise:
      return (x - k * (1.0 - std::exp(-x / k))) / (1.0 - std::exp(-1.0 / k));
    case InspiratoryWaveform::kExponentialDecay:
      return k * (1.0 - std::exp(-x / k));
  }
  return 0.0;
}

double VentilatorModel::peakInspiratoryFlow() const {
  // Every shape is normalised to a peak of 1 on [0, 1].
  return amplitude_;
}

double VentilatorModel::flowInCycle(double tau) const {
  if (tau < 0.0) return 0.0;
  if (tau < flow_time_) return amplitude_ * shapeValue(tau / flow_time_);
  if (tau < inspiratory_time_) return 0.0;
  if (tau < period_) {
    return -expiratory_peak_ * std::exp(-(tau - inspiratory_time_) / expiratory_tau_);
  }
  return 0.0;
}

double VentilatorModel::volumeInCycle(double tau) const {
  tau = std::clamp(tau, 0.0, period_);
  if (tau < flow_time_) return amplitude_ * flow_time_ * shapeIntegral(tau / flow_time_);
  const double inspired = amplitude_ * flow_time_ * shapeIntegral(1.0);
  if (tau < inspiratory_time_) return inspired;
  const double elapsed = tau - inspiratory_time_;
  return inspired -
         expiratory_peak_ * expiratory_tau_ * (1.0 - std::exp(-elapsed / expiratory_tau_));
}

VentilatorSample VentilatorModel::sample(double t) const {
  VentilatorSample out;
  out.t = t;
  const double cycle = std::floor(t / period_);
  double tau = t - cycle * period_;
  if (tau < 0.0) tau = 0.0;
  if (tau >= period_) tau = 0.0;
  out.flow_ml_s = flowInCycle(tau);
  out.volume_ml = volumeInCycle(tau);
  return out;
}

std::vector<VentilatorSample> VentilatorModel::sampleStream(double fs_hz, double duration_s) const {
  if (!(std::isfinite(fs_hz) && fs_hz > 0.0)) {
    throw std::invalid_argument("sampling rate fs must be finite and > 0");
  }
  if (!(std::isfinite(duration_s) && duration_s >= 0.0)) {
    throw std::invalid_argument("duration must be finite and >= 0");
  }
  const auto count = static_cast<size_t>(std::ceil(duration_s * fs_hz - 1e-9));
  std::vector<VentilatorSample> stream;
  stream.reserve(count);
  for (size_t i = 0; i < count; ++i) stream.push_back(sample(static_cast<double>(i) / fs_hz));
  return stream;
}

ConstraintResiduals VentilatorModel::residuals() const {
  ConstraintResiduals r;
  const double expiratory_time = period_ - inspiratory_time_;
  r.inspired_minus_tv_ml = amplitude_ * flow_time_ * shapeIntegral(1.0) - settings_.tv_max_ml;
  r.expired_plus_tv_ml =
      -expiratory_peak_ * expiratory_tau_ * (1.0 - std::exp(-expiratory_time / expiratory_tau_)) +
      settings_.tv_max_ml;
  r.end_flow_jump_ml_s = expiratory_peak_ * std::exp(-expiratory_time / expiratory_tau_);
  r.peak_ratio_error = expiratory_peak_ / peakInspiratoryFlow() - settings_.peak_flow_ratio;
  return r;
}

ConstraintResiduals paperConstantsResiduals() {
  // Eq. 10 with T = 5 s, Ti = 5/3 s, read literally: F = a on [0, 5/3),
  // F = -(3a/2) b^(t - 5/3) + c on [5/3, 5).
  const double a = 300.0;
  const double b = 0.4602;
  const double c = 0.0753;
  const double ti = 5.0 / 3.0;
  const double te = 10.0 / 3.0;
  ConstraintResiduals r;
  r.inspired_minus_tv_ml = a * ti - 500.0;
  const double expired = -1.5 * a * (std::pow(b, te) - 1.0) / std::log(b) + c * te;
  r.expired_plus_tv_ml = expired + 500.0;
  r.end_flow_jump_ml_s = std::abs(-1.5 * a * std::pow(b, te) + c);
  r.peak_ratio_error = std::abs(-1.5 * a + c) / a - 1.5;
  return r;
}

BreathScheduler::BreathScheduler(const VentilatorSettings& settings, double start_time)
    : model_(settings), pending_(settings), breath_start_(start_time), last_t_(start_time) {}

void BreathScheduler::requestSettings(const VentilatorSettings& settings) {
  requestSettings(settings, breath_index_ + 1);
}

void BreathScheduler::requestSettings(const VentilatorSettings& settings, long from_breath) {
  pending_ = VentilatorModel(settings);
  pending_valid_ = true;
  pending_from_ = std::max(from_breath, breath_index_ + 1);  // never mid-breath
}

void BreathScheduler::beginBreath() {
  ++breath_index_;
  if (pending_valid_ && breath_index_ >= pending_from_) {
    model_ = pending_;
    pending_valid_ = false;
  }
}

void BreathScheduler::restart(double start_time) {
  if (!std::isfinite(start_time)) {
    throw std::invalid_argument("BreathScheduler::restart: start_time must be finite");
  }
  breath_start_ = start_time;
  last_t_ = start_time;
  beginBreath();
}

void BreathScheduler::rephase(double start_time) {
  if (!std::isfinite(start_time)) {
    throw std::invalid_argument("BreathScheduler::rephase: start_time must be finite");
  }
  breath_start_ = start_time;
  last_t_ = std::max(last_t_, start_time);
}

VentilatorSample BreathScheduler::sample(double t) {
  if (!(t >= last_t_)) t = last_t_;  // also catches NaN
  last_t_ = t;
  while (t >= breath_start_ + model_.period()) {
    breath_start_ += model_.period();
    beginBreath();
  }
  VentilatorSample out;
  out.t = t;
  const double tau = t - breath_start_;
  out.flow_ml_s = model_.flowInCycle(tau);
  out.volume_ml = model_.volumeInCycle(tau);
  return out;
}

}  // namespace pedicle_drilling::core
