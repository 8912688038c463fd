#include "pedicle_drilling/core/drilling/recognizer_interface.hpp"

#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>

namespace pedicle_drilling::core {

namespace {

const char* const kPaperRecognizer = "pedicle_drilling/PaperRecognizer";
const char* const kForceDifferenceRecognizer = "pedicle_drilling/ForceDifferenceRecognizer";

}  // namespace

// ----------------------------------------------------------------------- PaperRecognizer

PaperRecognizer::PaperRecognizer(const RecognizerParams& params) : recognizer_(params) {}

void PaperRecognizer::configure(const RecognizerSettings& settings) {
  RecognizerParams p;
  for (const auto& [name, value] : settings) p.set(name, value);
  recognizer_ = StateRecognizer(p);  // validates
}

std::string PaperRecognizer::stopReason() const {
  return pedicle_drilling::core::stopReason(recognizer_.output());
}

std::string PaperRecognizer::describe() const {
  const RecognizerParams& p = recognizer_.params();
  char text[300];
  std::snprintf(text, sizeof(text),
                "paper recognizer (Sec. IV-C/D): pre-average %.6g s = %d samples at %.6g Hz, "
                "window %d, K %.2f, F_th %.2f N, G %.2f, H_g %.2f, C1 %.2f, C2 %.2f, C3 %.2f",
                p.pre_average_s, p.blockSamples(), p.sensor_rate_hz, p.window, p.k_ratio, p.f_th,
                p.gain, p.h_g, p.c1, p.c2, p.c3);
  return text;
}

std::vector<std::string> PaperRecognizer::parameterNames() const {
  return RecognizerParams::table().declaredNames();
}

// ------------------------------------------------------------- ForceDifferenceRecognizer

const ParamTable<ForceDifferenceParams>& ForceDifferenceParams::table() {
  static const ParamTable<ForceDifferenceParams> t = [] {
    using P = ForceDifferenceParams;
    const Range count = Range::closed(1, 10000);
    const Range per_block = Range::aboveUpTo(0, 100);
    ParamTable<P> d;
    d.integer("pre_average", &P::pre_average, Range::closed(1, 100000), "samples")
        .number("contact_force_n", &P::contact_force_n, Range::aboveUpTo(0, 1000), "N")
        .number("process_noise", &P::process_noise, Range::aboveUpTo(0, 1e3), "N^2")
        .number("measurement_noise", &P::measurement_noise, Range::aboveUpTo(0, 1e3), "N^2")
        .number("drop_threshold_n", &P::drop_threshold_n, per_block, "N/block")
        .integer("drop_confirm", &P::drop_confirm, count, "blocks")
        .integer("stop_at_breakthrough", &P::stop_at_breakthrough, Range::closed(1, 10))
        .number("rearm_rise_n", &P::rearm_rise_n, per_block, "N/block")
        .integer("rise_confirm", &P::rise_confirm, count, "blocks")
        .integer("stop_at_entry", &P::stop_at_entry, Range::closed(0, 10));
    return d;
  }();
  return t;
}

void ForceDifferenceParams::validate() const { table().validate(*this); }

void ForceDifferenceRecognizer::configure(const RecognizerSettings& settings) {
  const ParamTable<ForceDifferenceParams>& table = ForceDifferenceParams::table();
  for (const auto& [name, value] : settings) {
    if (table.find(name) == nullptr) {
      throw std::invalid_argument(name + ": not a parameter of " +
                                  std::string(kForceDifferenceRecognizer));
    }
  }
  const ForceDifferenceParams p = table.withSettings(settings);
  p.validate();
  p_ = p;
  reset();
}

void ForceDifferenceRecognizer::reset() {
  out_ = RecognizerOutput();
  raw_count_ = 0;
  block_n_ = 0;
  block_sum_ = 0.0;
  cur_t_ = 0.0;
  have_previous_ = false;
  previous_ = 0.0;
  x_ = 0.0;
  P_ = 1.0;
  in_bone_ = false;
  armed_ = true;
  rising_ = 0;
  falling_ = 0;
  breakthroughs_ = 0;
  entries_ = 0;
}

const RecognizerOutput& ForceDifferenceRecognizer::push(double t, double raw_force) {
  if (!std::isfinite(t)) throw std::invalid_argument("t: time must be finite");
  if (!std::isfinite(raw_force)) throw std::invalid_argument("raw_force: force must be finite");
  out_.new_average = false;
  ++raw_count_;
  block_sum_ += raw_force;
  if (++block_n_ == p_.pre_average) {
    const double f = block_sum_ / p_.pre_average;
    block_sum_ = 0.0;
    block_n_ = 0;
    cur_t_ = t;
    onBlock(f);
  }
  return out_;
}

void ForceDifferenceRecognizer::onBlock(double f) {
  out_.new_average = true;
  out_.filter_ready = true;
  out_.averaged_force = f;
  if (!have_previous_) {
    have_previous_ = true;
    previous_ = f;
    return;
  }
  // Force difference between successive (block-mean) samples, Kalman-filtered as a random walk.
  const double fdss = f - previous_;
  previous_ = f;
  P_ += p_.process_noise;
  const double gain = P_ / (P_ + p_.measurement_noise);
  x_ += gain * (fdss - x_);
  P_ *= 1.0 - gain;
  out_.feature = x_;  // the filtered FDSS [N per block], shown as the feature

  if (!in_bone_) {
    if (f <= p_.contact_force_n) return;
    in_bone_ = true;
    entries_ = 1;
    out_.layer_state = DrillingState::kOuterCortical;
    if (!out_.stop) out_.state = out_.layer_state;
    if (p_.stop_at_entry == 1) latchStop();
  }
  if (armed_) {
    falling_ = x_ < -p_.drop_threshold_n ? falling_ + 1 : 0;
    if (falling_ >= p_.drop_confirm) {
      ++breakthroughs_;
      armed_ = false;
      falling_ = 0;
      out_.layer_state =
          breakthroughs_ == 1 ? DrillingState::kCancellous : DrillingState::kBreakthrough;
      if (breakthroughs_ >= p_.stop_at_breakthrough) latchStop();
    }
  } else {
    rising_ = x_ > p_.rearm_rise_n ? rising_ + 1 : 0;
    if (rising_ >= p_.rise_confirm) {
      armed_ = true;  // the force rises again: the next cortex
      rising_ = 0;
      ++entries_;
      if (breakthroughs_ >= 1) out_.layer_state = DrillingState::kInnerCortical;
      if (entries_ == p_.stop_at_entry) latchStop();
    }
  }
  out_.state = out_.stop ? DrillingState::kStopped : out_.layer_state;
}

void ForceDifferenceRecognizer::latchStop() {
  if (out_.stop) return;
  out_.stop = true;
  out_.stop_t = cur_t_;
  out_.stop_index = raw_count_ - 1;
  out_.stop_key_point = 0;
}

std::string ForceDifferenceRecognizer::stopReason() const {
  if (!out_.stop) return "";
  char text[200];
  if (p_.stop_at_entry > 0 && entries_ >= p_.stop_at_entry) {
    std::snprintf(text, sizeof(text),
                  "force-difference cortex entry %d detected (filtered FDSS above %.3f N per "
                  "block for %d blocks after breakthrough %d) at t=%.3f s, raw sample %lu",
                  entries_, p_.rearm_rise_n, p_.rise_confirm, breakthroughs_, out_.stop_t,
                  static_cast<unsigned long>(out_.stop_index));
    return text;
  }
  std::snprintf(text, sizeof(text),
                "force-difference breakthrough %d detected (filtered FDSS below -%.3f N per "
                "block for %d blocks) at t=%.3f s, raw sample %lu",
                breakthroughs_, p_.drop_threshold_n, p_.drop_confirm, out_.stop_t,
                static_cast<unsigned long>(out_.stop_index));
  return text;
}

std::string ForceDifferenceRecognizer::describe() const {
  std::ostringstream os;
  os << "force-difference baseline (Ong and Bouazza-Marouf 1999): pre-average " << p_.pre_average
     << ", contact " << p_.contact_force_n << " N, q " << p_.process_noise << ", r "
     << p_.measurement_noise << ", drop " << p_.drop_threshold_n << " N/block x " << p_.drop_confirm
     << ", stop at breakthrough " << p_.stop_at_breakthrough << ", re-arm " << p_.rearm_rise_n
     << " N/block x " << p_.rise_confirm << ", stop at entry " << p_.stop_at_entry;
  return os.str();
}

std::vector<std::string> ForceDifferenceRecognizer::parameterNames() const {
  return ForceDifferenceParams::table().declaredNames();
}

// ---------------------------------------------------------------------------- guard

GuardedRecognizer::GuardedRecognizer(std::unique_ptr<RecognizerInterface> inner)
    : inner_(std::move(inner)) {
  if (!inner_) throw std::invalid_argument("recognizer: none given");
}

void GuardedRecognizer::reset() {
  samples_ = 0;
  try {
    inner_->reset();
    error_.clear();
  } catch (const std::exception& e) {
    latchError(failed_.stop_t, std::string("reset: ") + e.what());
  } catch (...) {
    latchError(failed_.stop_t, "reset: unknown exception");
  }
}

const RecognizerOutput& GuardedRecognizer::push(double t, double raw_force) {
  return guarded(t, [&]() -> const RecognizerOutput& { return inner_->push(t, raw_force); });
}

const RecognizerOutput& GuardedRecognizer::pushSample(const RecognizerSample& sample) {
  return guarded(sample.t, [&]() -> const RecognizerOutput& { return inner_->pushSample(sample); });
}

template <typename Push>
const RecognizerOutput& GuardedRecognizer::guarded(double t, Push push_one) {
  if (!error_.empty()) {
    ++samples_;
    failed_.new_average = false;
    return failed_;
  }
  try {
    const RecognizerOutput& out = push_one();
    ++samples_;
    return out;
  } catch (const std::exception& e) {
    latchError(t, e.what());
  } catch (...) {
    latchError(t, "unknown exception");
  }
  ++samples_;
  return failed_;
}

void GuardedRecognizer::latchError(double t, const std::string& what) {
  error_ = what.empty() ? "an exception without a message" : what;
  RecognizerOutput out;
  try {
    out = inner_->output();  // the layer it last reported
  } catch (...) {
  }
  out.state = DrillingState::kStopped;
  out.new_average = true;  // published at once
  if (!out.stop) {
    out.stop = true;
    out.stop_t = t;
    out.stop_index = samples_;
  }
  failed_ = out;
}

const RecognizerOutput& GuardedRecognizer::output() const {
  return error_.empty() ? inner_->output() : failed_;
}

std::string GuardedRecognizer::stopReason() const {
  if (error_.empty()) {
    try {
      return inner_->stopReason();
    } catch (const std::exception& e) {
      return std::string("recognizer stop (its reason failed: ") + e.what() + ")";
    } catch (...) {
      return "recognizer stop (its reason failed)";
    }
  }
  return "recognizer error, stopping: " + error_;
}

// ---------------------------------------------------------------------------- factory

std::vector<std::string> builtinRecognizerNames() {
  return {kPaperRecognizer, kForceDifferenceRecognizer};
}

std::unique_ptr<RecognizerInterface> makeBuiltinRecognizer(const std::string& name,
                                                           const RecognizerSettings& settings) {
  std::unique_ptr<RecognizerInterface> r;
  if (name == kPaperRecognizer) {
    r = std::make_unique<PaperRecognizer>();
  } else if (name == kForceDifferenceRecognizer) {
    r = std::make_unique<ForceDifferenceRecognizer>();
  } else {
    std::string known;
    for (const std::string& n : builtinRecognizerNames()) known += (known.empty() ? "" : ", ") + n;
    throw std::invalid_argument("recognizer '" + name + "' is not built in (known: " + known +
                                "; a plugin of another package is loaded through pluginlib)");
  }
  r->configure(settings);
  return r;
}

}  // namespace pedicle_drilling::core
