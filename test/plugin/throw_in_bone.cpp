/**
 * @file throw_in_bone.cpp
 * @brief A recognizer plugin of the test tree with a bug on purpose: it reports `idle` (never a
 *        stop of its own) and throws std::runtime_error from push() once `samples` raw samples
 *        were above `threshold_n`, i.e. mid-drill. The StateRecognizer nodelet must turn that
 *        into a stop naming the error, and its manager must live on (rostest
 *        recognizer_plugin_error).
 */
#include <pluginlib/class_list_macros.hpp>

#include <stdexcept>
#include <string>
#include <vector>

#include "pedicle_drilling/core/drilling/recognizer_interface.hpp"

namespace test_plugins {

namespace pd = pedicle_drilling::core;

class ThrowInBone : public pd::RecognizerInterface {
 public:
  void configure(const pd::RecognizerSettings& settings) override {
    for (const auto& [name, value] : settings) {
      if (name == "samples") {
        samples_ = std::stoi(value);
      } else if (name == "threshold_n") {
        threshold_n_ = std::stod(value);
      } else {
        throw std::invalid_argument(name + ": not a parameter of test_plugins/ThrowInBone");
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
  const pd::RecognizerOutput& push(double, double raw_force) override {
    if (raw_force > threshold_n_ && ++count_ >= samples_) {
      throw std::runtime_error("test plugin ThrowInBone: a bug after " + std::to_string(samples_) +
                               " samples in bone");
    }
    out_.new_average = ++index_ % 50 == 0;  // a state every 50 samples, as the paper's
    out_.averaged_force = raw_force;
    return out_;
  }
  const pd::RecognizerOutput& output() const override { return out_; }
  std::string stopReason() const override { return ""; }
  std::string describe() const override { return "test plugin ThrowInBone"; }
  std::vector<std::string> parameterNames() const override { return {"samples", "threshold_n"}; }

 private:
  pd::RecognizerOutput out_;
  int samples_ = 300;
  double threshold_n_ = 1.0;
  int count_ = 0;
  std::size_t index_ = 0;
};

}  // namespace test_plugins

PLUGINLIB_EXPORT_CLASS(test_plugins::ThrowInBone, pedicle_drilling::core::RecognizerInterface)
