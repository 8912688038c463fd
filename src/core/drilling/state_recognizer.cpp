// Force-based drilling-state recognizer. See doc/state_machine.md for the state machine.
#include "pedicle_drilling/core/drilling/state_recognizer.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace pedicle_drilling::core {

namespace {

[[noreturn]] void fail(const std::string& name, const std::string& why, double value) {
  std::ostringstream os;
  os << name << ": " << why << " (got " << value << ")";
  throw std::invalid_argument(os.str());
}

}  // namespace

const ParamTable<RecognizerParams>& RecognizerParams::table() {
  static const ParamTable<RecognizerParams> t = [] {
    using P = RecognizerParams;
    const Range count = Range::closed(1, 100000);
    const Range count_or_off = Range::closed(0, 100000);
    ParamTable<P> d;
    d.number("pre_average_s", &P::pre_average_s, Range::aboveUpTo(0, 10), "s")
        .number("sensor_rate_hz", &P::sensor_rate_hz, Range::aboveUpTo(0, 100000), "Hz")
        .integer("window", &P::window, count, "samples")
        .number("k_ratio", &P::k_ratio, Range::open(0, 1))
        .number("f_th", &P::f_th, Range::aboveUpTo(0, 1000), "N")
        .number("gain", &P::gain, Range::closed(1, 100))
        .number("h_g", &P::h_g, Range::closed(0, 1000), "N")
        .number("c1", &P::c1, Range::aboveUpTo(0, 1000))
        .number("c2", &P::c2, Range::aboveUpTo(0, 1000))
        .number("c3", &P::c3, Range::open(0, 1))
        .integer("cancellous_confirm", &P::cancellous_confirm, count, "samples")
        .integer("cancellous_deadline", &P::cancellous_deadline, count_or_off, "samples")
        .integer("inner_confirm", &P::inner_confirm, count, "samples")
        .integer("stop_delay", &P::stop_delay, count_or_off, "samples")
        .flag("normalize_feature", &P::normalize_feature)
        .retired("pre_average",
                 "the block is a duration: pre_average_s [s] at the force sensor's declared "
                 "rate sensor_rate_hz [Hz], round(pre_average_s x sensor_rate_hz) samples; N "
                 "samples at R Hz is pre_average_s N / R (50 at 1000/3 Hz: 0.15)");
    return d;
  }();
  return t;
}

int RecognizerParams::blockSamples() const {
  const double samples = pre_average_s * sensor_rate_hz;
  // Out of int's range only for parameters validate() refuses anyway.
  if (!(samples < 2e9)) return std::numeric_limits<int>::max();
  return static_cast<int>(std::lround(samples));
}

void RecognizerParams::validate() const {
  table().validate(*this);
  const double exact = pre_average_s * sensor_rate_hz;
  const int n = blockSamples();
  const auto blockFail = [&](const std::string& why) {
    std::ostringstream os;
    os << "pre_average_s: " << pre_average_s << " s at sensor_rate_hz " << sensor_rate_hz
       << " Hz is a block of " << n << " sample(s) (" << exact << " to the nearest): " << why;
    throw std::invalid_argument(os.str());
  };
  if (n < 2) blockFail("a block needs at least 2 samples (pre_average_s >= 2 / sensor_rate_hz)");
  if (n > 100000) blockFail("a block holds at most 100000 samples");
  if (std::fabs(n - exact) > 0.1 * exact) {
    std::ostringstream os;
    os << "the block would last " << n / sensor_rate_hz
       << " s, more than 10 % from pre_average_s (give a duration nearer a whole number of "
          "samples)";
    blockFail(os.str());
  }
  if (!(c2 >= c1)) fail("c2", "must be >= c1 (hysteresis between cancellous and cortical)", c2);
  if (cancellous_deadline != 0 && cancellous_deadline < window + cancellous_confirm) {
    fail("cancellous_deadline",
         "must be 0 (off) or >= window + cancellous_confirm (the filter settles in window "
         "samples, then the confirmation takes cancellous_confirm)",
         cancellous_deadline);
  }
}

void RecognizerParams::set(const std::string& name, const std::string& value) {
  if (table().find(name) == nullptr && table().retiredWhy(name) == nullptr) {
    throw std::invalid_argument(name + ": unknown recognizer parameter");
  }
  table().set(*this, name, value);
}

const char* toString(DrillingState s) {
  switch (s) {
    case DrillingState::kIdle:
      return "idle";
    case DrillingState::kOuterCortical:
      return "outer_cortical";
    case DrillingState::kOuterPunctured:
      return "outer_punctured";
    case DrillingState::kCancellous:
      return "cancellous";
    case DrillingState::kInnerCortical:
      return "inner_cortical";
    case DrillingState::kBreakthrough:
      return "breakthrough";
    case DrillingState::kStopped:
      return "stopped";
  }
  return "unknown";
}

std::string stopReason(const RecognizerOutput& out) {
  if (!out.stop) return "";
  char reason[200];
  if (out.stop_implausible) {
    std::snprintf(reason, sizeof(reason),
                  "implausible force: cancellous bone not confirmed after the outer cortical "
                  "layer (sensor drift?); stop after key point %d at t=%.3f s, raw sample %lu",
                  out.stop_key_point, out.stop_t, static_cast<unsigned long>(out.stop_index));
    return reason;
  }
  std::snprintf(reason, sizeof(reason),
                "inner cortical layer reached: stop after key point %d (%s) at t=%.3f s, "
                "raw sample %lu",
                out.stop_key_point, toString(out.layer_state), out.stop_t,
                static_cast<unsigned long>(out.stop_index));
  return reason;
}

StateRecognizer::StateRecognizer(const RecognizerParams& params) : params_(params) {
  params_.validate();
  reset();
}

void StateRecognizer::reset() {
  out_ = Output();
  raw_count_ = 0;
  t_last_ = 0.0;
  block_samples_ = params_.blockSamples();
  block_sum_ = 0.0;
  block_n_ = 0;
  ring_.assign(static_cast<std::size_t>(params_.window), 0.0);
  ring_pos_ = 0;
  ring_fill_ = 0;
  filtered_count_ = 0;
  punctured_samples_ = 0;
  cur_raw_index_ = 0;
  cur_t_ = 0.0;
  f_max_ = -std::numeric_limits<double>::infinity();
  f_min_ = std::numeric_limits<double>::infinity();
  contact_ = false;
  records_.clear();
  records_.reserve(256);
  run_ = 0;
  run_start_ = 0;
  run_start_t_ = 0.0;
  delay_left_ = -1;
  inner_peak_ = 0.0;
  inner_peak_index_ = 0;
  inner_peak_t_ = 0.0;
}

double StateRecognizer::feature(const RecognizerParams& p, double fbar, double f_min, double d) {
  const double fstar = (fbar - f_min) / d;  // normalised force, 1 at the outer-layer peak
  double a_unit;                            // Eq. 14 divided by D
  if (fstar > 1.0) {
    a_unit = 1.0;
  } else if (fstar >= 0.0) {
    a_unit = fstar * fstar * fstar;
  } else {
    a_unit = 0.0;
  }
  const double a = p.normalize_feature ? a_unit : d * a_unit;
  return a > p.h_g ? p.gain * a : a;  // Eq. 15
}

const StateRecognizer::Output& StateRecognizer::push(double t, double raw_force) {
  if (!std::isfinite(t)) throw std::invalid_argument("t: time must be finite");
  if (!std::isfinite(raw_force)) throw std::invalid_argument("raw_force: force must be finite");
  out_.new_average = false;
  t_last_ = t;
  ++raw_count_;
  block_sum_ += raw_force;
  if (++block_n_ == block_samples_) {
    const double f_block = block_sum_ / block_samples_;
    block_sum_ = 0.0;
    block_n_ = 0;
    cur_raw_index_ = raw_count_ - 1;
    cur_t_ = t;
    processAverage(f_block);
  }
  return out_;
}

void StateRecognizer::processAverage(double f_block) {
  out_.new_average = true;
  ring_[ring_pos_] = f_block;
  ring_pos_ = (ring_pos_ + 1) % ring_.size();
  if (ring_fill_ < ring_.size()) ++ring_fill_;
  if (ring_fill_ < ring_.size()) return;  // Eq. 13 needs n values (i >= n)
  double sum = 0.0;
  for (double v : ring_) sum += v;
  out_.filter_ready = true;
  onFiltered(sum / static_cast<double>(ring_.size()));
  ++filtered_count_;
}

void StateRecognizer::addKeyPoint(int id, std::size_t index, double t) {
  KeyPoint kp;
  kp.id = id;
  kp.index = index;
  kp.t = t;
  kp.recognized_index = cur_raw_index_;
  kp.recognized_t = cur_t_;
  out_.key_points[static_cast<std::size_t>(out_.num_key_points++)] = kp;
  if (!out_.stop) out_.last_key_point = id;
}

void StateRecognizer::setLayerState(DrillingState s) {
  out_.layer_state = s;
  if (!out_.stop) out_.state = s;
}

void StateRecognizer::commandStop() {
  if (out_.stop) return;
  out_.stop = true;
  out_.stop_index = cur_raw_index_;
  out_.stop_t = cur_t_;
  out_.stop_key_point = out_.last_key_point;
  out_.state = DrillingState::kStopped;
}

void StateRecognizer::onFiltered(double fbar) {
  out_.averaged_force = fbar;
  const RecognizerParams& p = params_;

  if (!out_.params_ready) {
    // Algorithm 2 (F_max starts at -inf instead of 0: identical decisions because the exit test
    // also requires F_max > F_th > 0, and it lets the running-maxima record start at i = 1).
    if (fbar < f_min_) f_min_ = fbar;
    if (fbar > f_max_) {
      f_max_ = fbar;
      records_.push_back(Record{fbar, cur_raw_index_, cur_t_});
    }
    if (!contact_ && f_max_ > p.f_th) {
      contact_ = true;
      setLayerState(DrillingState::kOuterCortical);
    }
    if (!(f_max_ > p.f_th && fbar < p.k_ratio * f_max_)) {
      out_.feature = 0.0;
      return;
    }
    out_.params_ready = true;
    out_.k = filtered_count_;
    out_.d = f_max_ - f_min_;
    out_.f_min = f_min_;
    // Key point 1 (retrospective): first fbar before k whose A* reaches C1. Because A* is
    // monotone in fbar, it is the first running maximum that does. Fallback (D too small for
    // A* to ever reach C1): the first sample above F_th.
    const Record* kp1 = nullptr;
    for (const Record& r : records_) {
      if (feature(p, r.fbar, f_min_, out_.d) >= p.c1) {
        kp1 = &r;
        break;
      }
    }
    if (kp1 == nullptr) {
      for (const Record& r : records_) {
        if (r.fbar > p.f_th) {
          kp1 = &r;
          break;
        }
      }
    }
    addKeyPoint(1, kp1->raw_index, kp1->t);
    addKeyPoint(2, cur_raw_index_, cur_t_);
    records_.clear();
    records_.shrink_to_fit();
    setLayerState(DrillingState::kOuterPunctured);
    run_ = 0;
    punctured_samples_ = 0;
    out_.feature = feature(p, fbar, out_.f_min, out_.d);
    return;  // the cancellous dwell starts with the next sample
  }

  const double a = feature(p, fbar, out_.f_min, out_.d);
  out_.feature = a;

  switch (out_.layer_state) {
    case DrillingState::kOuterPunctured:
      if (p.cancellous_deadline > 0 && ++punctured_samples_ > p.cancellous_deadline && !out_.stop) {
        commandStop();
        out_.stop_implausible = true;
      }
      if (a < p.c1) {
        // Key point 3 is placed where the dwell is confirmed: the first sample known to be in
        // cancellous bone (the start of the dwell would coincide with key point 2).
        if (++run_ >= p.cancellous_confirm) {
          addKeyPoint(3, cur_raw_index_, cur_t_);
          setLayerState(DrillingState::kCancellous);
          run_ = 0;
        }
      } else {
        run_ = 0;
      }
      break;
    case DrillingState::kCancellous:
      if (a > p.c2) {
        if (run_++ == 0) {
          run_start_ = cur_raw_index_;
          run_start_t_ = cur_t_;
          inner_peak_ = -1.0;
        }
        if (a > inner_peak_) {
          inner_peak_ = a;
          inner_peak_index_ = cur_raw_index_;
          inner_peak_t_ = cur_t_;
        }
        if (run_ >= p.inner_confirm) {
          addKeyPoint(4, run_start_, run_start_t_);
          setLayerState(DrillingState::kInnerCortical);
          run_ = 0;
          delay_left_ = p.stop_delay;
          if (delay_left_ == 0) commandStop();
        }
      } else {
        run_ = 0;
      }
      break;
    case DrillingState::kInnerCortical:
      if (delay_left_ > 0 && --delay_left_ == 0) commandStop();
      // The layer's own key point (last_key_point freezes at the stop).
      if (out_.key_points[static_cast<std::size_t>(out_.num_key_points - 1)].id == 4) {
        if (a > inner_peak_) {
          inner_peak_ = a;
          inner_peak_index_ = cur_raw_index_;
          inner_peak_t_ = cur_t_;
        } else if (a < p.c3 * inner_peak_) {
          addKeyPoint(5, inner_peak_index_, inner_peak_t_);
          commandStop();  // fail-safe: never later than key point 5
        }
      } else if (a < p.c1) {
        addKeyPoint(6, cur_raw_index_, cur_t_);
        setLayerState(DrillingState::kBreakthrough);
      }
      break;
    default:
      break;
  }
}

}  // namespace pedicle_drilling::core
