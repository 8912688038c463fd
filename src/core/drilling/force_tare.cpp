#include "pedicle_drilling/core/drilling/force_tare.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace pedicle_drilling::core {

void TareRequest::validate() const {
  if (samples < 1 || samples > 100000) {
    throw std::invalid_argument("tare samples must be in [1, 100000], got " +
                                std::to_string(samples));
  }
  if (!(std::isfinite(max_spread_n) && max_spread_n > 0.0)) {
    throw std::invalid_argument("tare max_spread_n must be positive and finite");
  }
}

void ForceTare::request(const TareRequest& request) {
  request.validate();
  request_ = request;
  remaining_ = request.samples;
  count_ = 0;
  finite_ = true;
  sum_.setZero();
  sum_sq_.setZero();
}

ForceTare::Wrench ForceTare::apply(double t, const Wrench& raw) {
  const Wrench tared = raw - bias_;
  if (remaining_ > 0) {
    if (raw.allFinite()) {
      sum_ += raw;
      sum_sq_ += raw.head<3>().cwiseProduct(raw.head<3>());
    } else {
      finite_ = false;
    }
    ++count_;
    if (--remaining_ == 0) finish(t);
  }
  return tared;
}

void ForceTare::finish(double t) {
  TareResult r;
  r.t = t;
  r.samples = count_;
  std::ostringstream os;
  if (!finite_) {
    os << "tare failed: a non-finite sample in the window of " << count_ << "; bias kept";
  } else {
    const Wrench mean = sum_ / count_;
    const Eigen::Vector3d variance =
        (sum_sq_ / count_ - mean.head<3>().cwiseProduct(mean.head<3>())).cwiseMax(0.0);
    r.spread_n = std::sqrt(variance.sum());
    r.bias = mean;
    if (r.spread_n > request_.max_spread_n) {
      os << "tare failed: the force spread " << r.spread_n << " N over " << count_
         << " samples exceeds " << request_.max_spread_n
         << " N (is the tool touching something?); bias kept";
    } else {
      r.success = true;
      bias_ = mean;
      os << "tared over " << count_ << " samples: bias (" << mean[0] << ", " << mean[1] << ", "
         << mean[2] << ") N, spread " << r.spread_n << " N";
    }
  }
  r.message = os.str();
  result_ = r;
}

std::optional<TareResult> ForceTare::takeResult() {
  std::optional<TareResult> r = std::move(result_);
  result_.reset();
  return r;
}

void ForceTare::reset() {
  remaining_ = 0;
  count_ = 0;
  bias_.setZero();
  result_.reset();
}

}  // namespace pedicle_drilling::core
