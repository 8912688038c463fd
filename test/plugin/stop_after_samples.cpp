/**
 * @file stop_after_samples.cpp
 * @brief A recognizer plugin that lives only in the test tree: it proves that an
 *        outside class, built apart from our library and known to us only by its name, plugs in
 *        through pluginlib. It stops after `samples` raw samples above `threshold_n` (nothing a
 *        surgeon should use).
 */
#include <pluginlib/class_list_macros.hpp>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "pedicle_drilling/core/drilling/recognizer_interface.hpp"

namespace test_plugins {

namespace pd = pedicle_drilling::core;

class StopAfterSamples : public pd::RecognizerInterface {
 public:
  void configure(const pd::RecognizerSettings& settings) override {
    for (const auto& [name, value] : settings) {
      if (name == "samples") {
        samples_ = std::stoi(value);
      } else if (name == "threshold_n") {
        threshold_n_ = std::stod(value);
      } else {
        throw std::invalid_argument(name + ": not a parameter of test_plugins/StopAfterSamples");
      }
    }
    if (samples_ < 1) throw std::invalid_argument("samples: must be >= 1");
    reset();
  }
  void reset() override {
    out_ = pd::RecognizerOutput();
    count_ = 0;
    index_ = 0;
  }
  const pd::RecognizerOutput& push(double t, double raw_force) override {
    if (!std::isfinite(t) || !std::isfinite(raw_force)) {
      throw std::invalid_argument("raw_force: must be finite");
    }
    out_.new_average = true;
    out_.averaged_force = raw_force;
    if (raw_force > threshold_n_ && ++count_ >= samples_ && !out_.stop) {
      out_.stop = true;
      out_.stop_t = t;
      out_.stop_index = index_;
      out_.state = pd::DrillingState::kStopped;
    }
    ++index_;
    return out_;
  }
  const pd::RecognizerOutput& output() const override { return out_; }
  std::string stopReason() const override {
    return out_.stop ? "test plugin: " + std::to_string(samples_) + " samples in bone" : "";
  }
  std::string describe() const override { return "test plugin StopAfterSamples"; }
  std::vector<std::string> parameterNames() const override { return {"samples", "threshold_n"}; }

 private:
  pd::RecognizerOutput out_;
  int samples_ = 100;
  double threshold_n_ = 1.0;
  int count_ = 0;
  std::size_t index_ = 0;
};

}  // namespace test_plugins

PLUGINLIB_EXPORT_CLASS(test_plugins::StopAfterSamples, pedicle_drilling::core::RecognizerInterface)
