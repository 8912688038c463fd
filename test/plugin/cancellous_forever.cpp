/**
 * @file cancellous_forever.cpp
 * @brief A recognizer plugin of the test tree that misses every layer on purpose: idle until the
 *        first raw sample above `threshold_n` (the contact), `cancellous` from then on, and never
 *        a stop. With the planner's layer bounds off, only the drilling plan's depth limit can
 *        stop its trial (rostest depth_limit_cancellous_forever).
 */
#include <pluginlib/class_list_macros.hpp>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "pedicle_drilling/core/drilling/recognizer_interface.hpp"

namespace test_plugins {

namespace pd = pedicle_drilling::core;

class CancellousForever : public pd::RecognizerInterface {
 public:
  void configure(const pd::RecognizerSettings& settings) override {
    for (const auto& [name, value] : settings) {
      if (name == "threshold_n") {
        threshold_n_ = std::stod(value);
      } else if (name == "block") {
        block_ = std::stoi(value);
      } else {
        throw std::invalid_argument(name + ": not a parameter of test_plugins/CancellousForever");
      }
    }
    if (!(threshold_n_ > 0.0)) throw std::invalid_argument("threshold_n: must be > 0");
    if (block_ < 1) throw std::invalid_argument("block: must be >= 1");
    reset();
  }
  void reset() override {
    out_ = pd::RecognizerOutput();
    sum_ = 0.0;
    count_ = 0;
  }
  const pd::RecognizerOutput& push(double t, double raw_force) override {
    if (!std::isfinite(t) || !std::isfinite(raw_force)) {
      throw std::invalid_argument("raw_force: must be finite");
    }
    if (raw_force > threshold_n_ && out_.state == pd::DrillingState::kIdle) {
      out_.state = pd::DrillingState::kCancellous;
      out_.layer_state = pd::DrillingState::kCancellous;
    }
    // A DrillingState message every `block` samples (the planner's recognizer watchdog hears it).
    sum_ += raw_force;
    out_.new_average = ++count_ >= block_;
    if (out_.new_average) {
      out_.averaged_force = sum_ / count_;
      sum_ = 0.0;
      count_ = 0;
    }
    return out_;
  }
  const pd::RecognizerOutput& output() const override { return out_; }
  std::string stopReason() const override { return ""; }
  std::string describe() const override {
    return "test plugin CancellousForever (cancellous from a sample above " +
           std::to_string(threshold_n_) + " N on, never a stop)";
  }
  std::vector<std::string> parameterNames() const override { return {"threshold_n", "block"}; }

 private:
  pd::RecognizerOutput out_;
  double threshold_n_ = 1.0;
  int block_ = 50;  ///< raw samples per published state (0.15 s at 1000/3 Hz)
  double sum_ = 0.0;
  int count_ = 0;
};

}  // namespace test_plugins

PLUGINLIB_EXPORT_CLASS(test_plugins::CancellousForever, pedicle_drilling::core::RecognizerInterface)
