#include "pedicle_drilling/core/drilling/force_tare.hpp"

#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace pedicle_drilling::core {

const ParamTable<TareRequest>& TareRequest::table() {
  static const ParamTable<TareRequest> t = [] {
    ParamTable<TareRequest> d;
    d.integer("samples", &TareRequest::samples, Range::closed(1, 100000), "samples")
        .number("max_spread_n", &TareRequest::max_spread_n,
                Range::open(0, std::numeric_limits<double>::infinity()), "N");
    return d;
  }();
  return t;
}

void TareRequest::validate() const { table().validate(*this); }

void ForceTare::request(const TareRequest& request) {
  request.validate();
  request_ = request;
  checking_zero_ = false;
  remaining_ = request.samples;
  count_ = 0;
  finite_ = true;
  sum_.setZero();
  sum_sq_.setZero();
}

void ForceTare::checkZero(const TareRequest& request, double tolerance_n, double from_t) {
  if (!(std::isfinite(tolerance_n) && tolerance_n > 0.0)) {
    throw std::invalid_argument("the zero's tolerance must be positive and finite");
  }
  this->request(request);
  checking_zero_ = true;
  zero_tolerance_n_ = tolerance_n;
  from_t_ = from_t;
}

ForceTare::Wrench ForceTare::apply(double t, const Wrench& raw) {
  const Wrench tared = raw - bias_;
  // A zero's check counts only the samples stamped once the zero was done.
  if (remaining_ > 0 && (!checking_zero_ || t >= from_t_)) {
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
    os << (checking_zero_ ? "zero check" : "tare")
       << " failed: a non-finite sample in the window of " << count_
       << (checking_zero_ ? "" : "; bias kept");
  } else {
    const Wrench mean = sum_ / count_;
    const Eigen::Vector3d variance =
        (sum_sq_ / count_ - mean.head<3>().cwiseProduct(mean.head<3>())).cwiseMax(0.0);
    r.spread_n = std::sqrt(variance.sum());
    r.bias = mean;
    judge(&r, mean, &os);
  }
  r.message = os.str();
  result_ = r;
}

void ForceTare::judge(TareResult* r, const Wrench& mean, std::ostringstream* os) {
  const Eigen::Vector3d force = mean.head<3>();
  if (r->spread_n > request_.max_spread_n) {
    *os << (checking_zero_ ? "zero check" : "tare") << " failed: the force spread " << r->spread_n
        << " N over " << count_ << " samples exceeds " << request_.max_spread_n
        << " N (is the tool touching something?)" << (checking_zero_ ? "" : "; bias kept");
  } else if (checking_zero_ && force.norm() > zero_tolerance_n_) {
    *os << "zero check failed: the mean force over the " << count_ << " samples after the zero is ("
        << force[0] << ", " << force[1] << ", " << force[2] << ") N, " << force.norm()
        << " N from zero, beyond the tolerance " << zero_tolerance_n_
        << " N: the driver did not zero the sensor";
  } else if (checking_zero_) {
    r->success = true;
    *os << "zero checked over " << count_ << " samples: the mean force is " << force.norm()
        << " N from zero (tolerance " << zero_tolerance_n_ << " N), spread " << r->spread_n << " N";
  } else {
    r->success = true;
    bias_ = mean;
    *os << "tared over " << count_ << " samples: bias (" << mean[0] << ", " << mean[1] << ", "
        << mean[2] << ") N, spread " << r->spread_n << " N";
  }
}

std::optional<TareResult> ForceTare::takeResult() {
  std::optional<TareResult> r = std::move(result_);
  result_.reset();
  return r;
}

void ForceTare::reset() {
  remaining_ = 0;
  checking_zero_ = false;
  count_ = 0;
  bias_.setZero();
  result_.reset();
}

}  // namespace pedicle_drilling::core
