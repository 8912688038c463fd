#include "pedicle_drilling/core/control/adaptive_compensator.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "pedicle_drilling/core/control/compensation_planner.hpp"

namespace pedicle_drilling::core {

namespace {

constexpr double kMm = 1e-3;

}  // namespace

const ParamTable<AdaptiveModelParams>& AdaptiveModelParams::table() {
  static const ParamTable<AdaptiveModelParams> t = [] {
    using P = AdaptiveModelParams;
    ParamTable<P> d;
    d.number("forgetting_time_s", &P::forgetting_time_s, Range::aboveUpTo(0.1, 60), "s")
        .number("lag_forgetting_time_s", &P::lag_forgetting_time_s, Range::aboveUpTo(0.1, 120), "s")
        .number("gain_min", &P::gain_min, Range::closed(0.1, 1))
        .number("gain_max", &P::gain_max, Range::closed(1, 10))
        .number("gain_agreement", &P::gain_agreement, Range::aboveUpTo(0, 1))
        .number("lag_switch_margin", &P::lag_switch_margin, Range::closed(0, 0.9))
        .number("gain_prior_mm2", &P::gain_prior_mm2, Range::closed(0, 1e4), "mm^2")
        .number("lag_max_s", &P::lag_max_s, Range::closed(0, 0.5), "s")
        .number("lag_step_s", &P::lag_step_s, Range::closed(0.001, 0.1), "s")
        .number("max_correction_mm", &P::max_correction_mm, Range::aboveUpTo(0, 20), "mm")
        .number("gate_mm", &P::gate_mm, Range::aboveUpTo(0, 20), "mm")
        .integer("disagree_samples", &P::disagree_samples, Range::closed(1, 100));
    return d;
  }();
  return t;
}

void AdaptiveModelParams::validate() const { table().validate(*this); }

AdaptiveModelCompensator::AdaptiveModelCompensator() = default;
AdaptiveModelCompensator::~AdaptiveModelCompensator() = default;

void AdaptiveModelCompensator::configure(const CompensatorSettings& settings) {
  const AdaptiveModelParams p = AdaptiveModelParams::table().withSettings(settings);
  p.validate();
  p_ = p;
  // Candidates in order of |lag|: a tie keeps the smaller lag.
  lags_ = {0.0};
  const int n = static_cast<int>(std::floor(p_.lag_max_s / p_.lag_step_s + 1e-9));
  for (int i = 1; i <= n; ++i) {
    lags_.push_back(i * p_.lag_step_s);
    lags_.push_back(-i * p_.lag_step_s);
  }
  short_ = Memory{p_.forgetting_time_s, std::vector<Sums>(lags_.size()), 0.0};
  long_ = Memory{p_.lag_forgetting_time_s, std::vector<Sums>(lags_.size()), 0.0};
}

void AdaptiveModelCompensator::Memory::decay(double dt) {
  const double f = std::exp(-dt / time_s);
  weight *= f;
  for (Sums& s : sums) {
    for (int j = 0; j < 3; ++j) {
      s.x[j] *= f;
      s.y[j] *= f;
      s.xx[j] *= f;
      s.xy[j] *= f;
      s.yy[j] *= f;
    }
  }
}

double AdaptiveModelCompensator::Memory::fit(std::size_t i, const std::array<bool, 3>& used,
                                             const AdaptiveModelParams& p, double* residual,
                                             std::array<double, 3>* baseline) const {
  const double prior = p.gain_prior_mm2 * kMm * kMm;
  const Sums& s = sums[i];
  double cxx = 0.0, cxy = 0.0, cyy = 0.0;
  for (int j = 0; j < 3; ++j) {
    if (!used[j]) continue;
    cxx += s.xx[j] - s.x[j] * s.x[j] / weight;
    cxy += s.xy[j] - s.x[j] * s.y[j] / weight;
    cyy += s.yy[j] - s.y[j] * s.y[j] / weight;
  }
  const double denominator = cxx + prior;
  const double a =
      denominator > 1e-18 ? std::clamp((cxy + prior) / denominator, p.gain_min, p.gain_max) : 1.0;
  if (residual != nullptr) {
    *residual = cyy - 2.0 * a * cxy + a * a * cxx + prior * (a - 1.0) * (a - 1.0);
  }
  if (baseline != nullptr) {
    for (int j = 0; j < 3; ++j) (*baseline)[j] = used[j] ? (s.y[j] - a * s.x[j]) / weight : 0.0;
  }
  return a;
}

void AdaptiveModelCompensator::setPatient(const MotionModel& model,
                                          const CompensationParams& params) {
  paper_.setPatient(model, params);
  axis_used_ = params.predict_axis;
  axis_dir_ = params.axis_direction;
  for (Eigen::Vector3d& u : axis_dir_) u.normalize();
  if (lags_.empty()) configure({});
}

void AdaptiveModelCompensator::setVentilator(const VentilatorSettings& settings) {
  paper_.setVentilator(settings);
}

void AdaptiveModelCompensator::setBreathStart(double t) { paper_.setBreathStart(t); }

std::array<double, 3> AdaptiveModelCompensator::axes(const Eigen::Vector3d& v) const {
  std::array<double, 3> out{};
  for (int j = 0; j < 3; ++j) out[j] = axis_used_[j] ? axis_dir_[j].dot(v) : 0.0;
  return out;
}

std::array<double, 3> AdaptiveModelCompensator::modelAxes(double t) const {
  return axes(paper_.displacement(t));
}

std::array<double, 3> AdaptiveModelCompensator::fittedAxes(double t,
                                                           const std::array<double, 3>& now) const {
  const std::array<double, 3> lagged = lag_ == 0.0 ? now : modelAxes(t - lag_);
  const double bound = p_.max_correction_mm * kMm;
  std::array<double, 3> out{};
  for (int j = 0; j < 3; ++j) {
    if (!axis_used_[j]) continue;
    const double correction = baseline_[j] + gain_ * lagged[j] - now[j];
    out[j] = now[j] + std::clamp(correction, -bound, bound);
  }
  return out;
}

Eigen::Vector3d AdaptiveModelCompensator::displacement(double t) const {
  Eigen::Vector3d d = paper_.displacement(t);
  if (!offset_) return d;
  const std::array<double, 3> model = axes(d);
  const std::array<double, 3> fitted = fittedAxes(t, model);
  for (int j = 0; j < 3; ++j) {
    if (axis_used_[j]) d += axis_dir_[j] * ((*offset_)[j] + fitted[j] - model[j]);
  }
  return d;
}

void AdaptiveModelCompensator::observeMarker(double stamp, const Eigen::Vector3d& position) {
  if (!ready() || !std::isfinite(stamp) || !position.allFinite()) return;  // a lost sample
  if (offset_ && !(stamp > last_stamp_)) return;                           // late or repeated
  const std::array<double, 3> tracked = axes(position);
  if (!offset_) {
    // The first sample fixes the tracker's origin against the model's: the fit works on the
    // tracked positions relative to it, so that its sums stay of the size of the motion.
    const std::array<double, 3> model = modelAxes(stamp);
    std::array<double, 3> offset{};
    for (int j = 0; j < 3; ++j) offset[j] = tracked[j] - model[j];
    offset_ = offset;
  } else {
    const std::array<double, 3> fitted = fittedAxes(stamp, modelAxes(stamp));
    double r2 = 0.0;
    for (int j = 0; j < 3; ++j) {
      const double r = tracked[j] - (*offset_)[j] - fitted[j];
      r2 += r * r;
    }
    if (std::sqrt(r2) > p_.gate_mm * kMm) {
      ++gated_total_;
      if (++gated_in_row_ >= p_.disagree_samples) {
        char text[200];
        std::snprintf(text, sizeof(text),
                      "model and tracker disagree: %d tracker samples in a row %.2f mm or more "
                      "from the corrected prediction (gate %.2f mm); re-register",
                      gated_in_row_, std::sqrt(r2) / kMm, p_.gate_mm);
        throw std::runtime_error(text);
      }
      return;
    }
    short_.decay(stamp - last_stamp_);
    long_.decay(stamp - last_stamp_);
  }
  gated_in_row_ = 0;
  last_stamp_ = stamp;
  short_.weight += 1.0;
  long_.weight += 1.0;
  for (std::size_t i = 0; i < lags_.size(); ++i) {
    const std::array<double, 3> x = modelAxes(stamp - lags_[i]);
    for (Memory* m : {&short_, &long_}) {
      Sums& s = m->sums[i];
      for (int j = 0; j < 3; ++j) {
        if (!axis_used_[j]) continue;
        const double y = tracked[j] - (*offset_)[j];
        s.x[j] += x[j];
        s.y[j] += y;
        s.xx[j] += x[j] * x[j];
        s.xy[j] += x[j] * y;
        s.yy[j] += y * y;
      }
    }
  }
  ++used_;
  refit();
}

void AdaptiveModelCompensator::refit() {
  // The lag of least residual over the long memory (candidates in order of |lag|: a tie keeps
  // the smaller), unless the gain is changing; then the gain and the baseline at that lag over
  // the short memory.
  const bool steady =
      std::abs(short_.fit(lag_index_, axis_used_, p_, nullptr, nullptr) -
               long_.fit(lag_index_, axis_used_, p_, nullptr, nullptr)) <= p_.gain_agreement;
  if (steady) {
    double current = 0.0;
    long_.fit(lag_index_, axis_used_, p_, &current, nullptr);
    double best = std::numeric_limits<double>::infinity();
    std::size_t best_index = lag_index_;
    for (std::size_t i = 0; i < lags_.size(); ++i) {
      double residual = 0.0;
      long_.fit(i, axis_used_, p_, &residual, nullptr);
      if (residual < best) {
        best = residual;
        best_index = i;
      }
    }
    // A new lag must explain the motion clearly better than the one in use.
    if (best < (1.0 - p_.lag_switch_margin) * current) lag_index_ = best_index;
  }
  lag_ = lags_[lag_index_];
  gain_ = short_.fit(lag_index_, axis_used_, p_, nullptr, &baseline_);
}

std::vector<double> AdaptiveModelCompensator::velocitySteps(double t0, double t1) const {
  std::vector<double> steps = paper_.velocitySteps(t0, t1);
  if (lag_ != 0.0 && offset_) {
    for (double t : paper_.velocitySteps(t0 - lag_, t1 - lag_)) steps.push_back(t + lag_);
    std::sort(steps.begin(), steps.end());
  }
  return steps;
}

std::string AdaptiveModelCompensator::describe() const {
  char text[320];
  std::snprintf(text, sizeof(text),
                "adaptive model compensator (paper's prediction corrected from the tracker: "
                "gain %.3f in [%.2f, %.2f], lag %+.3f s in +-%.3f s, forgetting %.2f s, "
                "correction <= %.2f mm, gate %.2f mm x %d)",
                gain_, p_.gain_min, p_.gain_max, lag_, p_.lag_max_s, p_.forgetting_time_s,
                p_.max_correction_mm, p_.gate_mm, p_.disagree_samples);
  return text;
}

std::vector<std::string> AdaptiveModelCompensator::parameterNames() const {
  return AdaptiveModelParams::table().declaredNames();
}

}  // namespace pedicle_drilling::core
