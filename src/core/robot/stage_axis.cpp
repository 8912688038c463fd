#include "pedicle_drilling/core/robot/stage_axis.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace pedicle_drilling::core {

namespace {
constexpr double kPi = 3.14159265358979323846;
}

const ParamTable<StageAxisParams>& StageAxisParams::table() {
  static const ParamTable<StageAxisParams> t = [] {
    using P = StageAxisParams;
    const Range positive = Range::open(0, std::numeric_limits<double>::infinity());
    ParamTable<P> d;
    d.number("max_speed_m_s", &P::max_speed_m_s, positive, "m/s")
        .number("max_accel_m_s2", &P::max_accel_m_s2, positive, "m/s^2")
        .number("bandwidth_hz", &P::bandwidth_hz, positive, "Hz");
    return d;
  }();
  return t;
}

void StageAxisParams::validate() const { table().validate(*this); }

StageAxis::StageAxis(const StageAxisParams& params, double position) : params_(params) {
  params_.validate();
  reset(position);
}

void StageAxis::reset(double position) {
  x_ = position;
  u_ = 0.0;
}

double StageAxis::step(double dt, double ref_position, double ref_velocity) {
  if (!(dt > 0.0) || !std::isfinite(ref_position) || !std::isfinite(ref_velocity)) return x_;
  const double v = params_.max_speed_m_s;
  // A loop gain above 1 / dt would overshoot in one step: the drive is at most dead-beat.
  const double gain = std::min(2.0 * kPi * params_.bandwidth_hz, 1.0 / dt);
  const double wanted = std::clamp(ref_velocity + gain * (ref_position - x_), -v, v);
  const double dv = params_.max_accel_m_s2 * dt;
  u_ += std::clamp(wanted - u_, -dv, dv);
  x_ += u_ * dt;
  return x_;
}

}  // namespace pedicle_drilling::core
