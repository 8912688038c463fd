#include "pedicle_drilling/core/drilling/sample_rate_check.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace pedicle_drilling::core {

const ParamTable<SampleRateCheckParams>& SampleRateCheckParams::table() {
  static const ParamTable<SampleRateCheckParams> t = [] {
    using P = SampleRateCheckParams;
    ParamTable<P> d;
    d.number("declared_hz", &P::declared_hz,
             Range::open(0, std::numeric_limits<double>::infinity()), "Hz")
        .number("tolerance", &P::tolerance, Range::open(0, 1))
        .number("window_s", &P::window_s, Range::aboveUpTo(0, 60), "s");
    return d;
  }();
  return t;
}

void SampleRateCheckParams::validate() const { table().validate(*this); }

SampleRateCheck::SampleRateCheck(const SampleRateCheckParams& params) : params_(params) {
  params_.validate();
}

void SampleRateCheck::restart(double stamp_s) {
  started_ = true;
  window_start_s_ = stamp_s;
  last_s_ = stamp_s;
  spacings_ = 0;
}

bool SampleRateCheck::observe(double stamp_s) {
  if (!std::isfinite(stamp_s)) return false;
  if (!started_ || stamp_s < last_s_ || stamp_s - last_s_ > pauseS()) {
    restart(stamp_s);
    return false;
  }
  last_s_ = stamp_s;
  ++spacings_;
  const double span = stamp_s - window_start_s_;
  if (span < params_.window_s) return false;
  measured_hz_ = static_cast<double>(spacings_) / span;
  measured_over_s_ = span;
  verdict_ = ratesAgree(params_.declared_hz, measured_hz_, params_.tolerance)
                 ? RateVerdict::kMatch
                 : RateVerdict::kMismatch;
  window_start_s_ = stamp_s;
  spacings_ = 0;
  return true;
}

std::string SampleRateCheck::describe() const {
  char text[200];
  if (verdict_ == RateVerdict::kUnknown) {
    std::snprintf(text, sizeof(text), "not measured yet, declared %.6g Hz", params_.declared_hz);
    return text;
  }
  std::snprintf(
      text, sizeof(text),
      "measured %.6g Hz over %.3g s, declared %.6g Hz (off by %+.1f %%, tolerance %.3g %%)",
      measured_hz_, measured_over_s_, params_.declared_hz,
      100.0 * (measured_hz_ / params_.declared_hz - 1.0), 100.0 * params_.tolerance);
  return text;
}

}  // namespace pedicle_drilling::core
