// Tests of PythonRecognizer: a recognizer class written in Python, driven through the
// C++ interface. The classes under test are written here into a module on the Python path.
#include "pedicle_drilling/python/python_recognizer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>

#include "pedicle_drilling/core/drilling/recognizer_interface.hpp"

namespace pd = pedicle_drilling;

namespace {

/** @brief Writes the test module into a fresh directory put first on PYTHONPATH, once, before
 *         the interpreter starts (the first PythonRecognizer). */
class PythonModule : public ::testing::Environment {
 public:
  void SetUp() override {
    char pattern[] = "/tmp/pd_python_recognizer_XXXXXX";
    const char* dir = mkdtemp(pattern);
    ASSERT_NE(dir, nullptr);
    std::ofstream(std::string(dir) + "/pd_test_recognizers.py") << R"(
class StopAfter:
    """Stops at the first sample past `after_s`; a block mean every 3 samples."""
    def __init__(self):
        self.after_s = 1.0
        self.reset()
    def configure(self, settings):
        for name, text in settings.items():
            if name != 'after_s':
                raise ValueError(name + ': unknown parameter')
            self.after_s = float(text)
    def reset(self):
        self.n = 0
        self.total = 0.0
    def push(self, t, f):
        self.n += 1
        self.total += f
        out = {'state': 'outer_cortical' if t > 0.5 else 'idle'}
        if self.n % 3 == 0:
            out.update(new_average=True, averaged_force=self.total / 3)
            self.total = 0.0
        if t > self.after_s:
            out['stop'] = True
        return out
    def stop_reason(self):
        return 'past after_s'
    def parameter_names(self):
        return ['after_s']

class ForgetsStop(StopAfter):
    """Says stop once, then no more: the C++ side latches it."""
    def push(self, t, f):
        return {'stop': abs(t - 2.0) < 1e-9}

class BadKey(StopAfter):
    def push(self, t, f):
        return {'stahp': True}

class NoPush:
    def configure(self, settings): pass
    def reset(self): pass

class ReadsTheWrench(StopAfter):
    """push_sample: keeps each sample; stops when the torque about z passes 5 N mm."""
    def reset(self):
        super().reset()
        self.samples = []
    def push(self, t, f):
        raise AssertionError('push_sample is defined: push is not called')
    def push_sample(self, sample):
        if sample['tracker_stamp'] == sample['tracker_stamp']:  # not NaN
            assert sample['tracker'] == (0.3, -0.1, 1.2), sample
            assert sample['feed_command_m'] == 0.0065, sample
        self.samples.append(sample)
        return {'stop': sample['torque'][2] > 0.005, 'averaged_force': sample['force'][0]}

class RaisesAt(StopAfter):
    """A bug from `after_s` on: push raises."""
    def push(self, t, f):
        if t > self.after_s:
            raise KeyError('layer_table')
        return super().push(t, f)
)";
    const char* old = std::getenv("PYTHONPATH");
    setenv("PYTHONPATH", (std::string(dir) + (old ? std::string(":") + old : "")).c_str(), 1);
    dir_ = dir;
  }
  void TearDown() override {  // the module has been imported: its files may go
    std::remove((dir_ + "/pd_test_recognizers.py").c_str());
    std::system(("rm -rf '" + dir_ + "/__pycache__'").c_str());
    std::remove(dir_.c_str());
  }

 private:
  std::string dir_;
};

const ::testing::Environment* const kModule = ::testing::AddGlobalTestEnvironment(new PythonModule);

}  // namespace

TEST(PythonRecognizer, RunsThePythonClassThroughTheInterface) {
  EXPECT_TRUE(pd::isPythonClassName("python:pd_test_recognizers.StopAfter"));
  EXPECT_FALSE(pd::isPythonClassName("pedicle_drilling/PaperRecognizer"));
  pd::PythonRecognizer r("pd_test_recognizers.StopAfter");
  r.configure({{"after_s", "1.5"}});
  EXPECT_EQ(r.parameterNames(), std::vector<std::string>{"after_s"});
  int averages = 0;
  for (int i = 0; i < 20; ++i) {
    const double t = 0.1 * i;
    const pd::core::RecognizerOutput& out = r.push(t, 2.0);
    if (out.new_average) {
      ++averages;
      EXPECT_DOUBLE_EQ(out.averaged_force, 2.0);
    }
    EXPECT_EQ(out.stop, t > 1.5) << t;
    if (!out.stop) {
      EXPECT_EQ(out.state,
                t > 0.5 ? pd::core::DrillingState::kOuterCortical : pd::core::DrillingState::kIdle);
    }
  }
  EXPECT_EQ(averages, 6);
  EXPECT_EQ(r.output().state, pd::core::DrillingState::kStopped);
  EXPECT_NEAR(r.output().stop_t, 1.6, 1e-12);  // the first sample past 1.5 s
  EXPECT_EQ(r.output().stop_index, 16u);
  EXPECT_EQ(r.stopReason(), "past after_s");
  r.reset();
  EXPECT_FALSE(r.output().stop);
  EXPECT_FALSE(r.push(0.0, 1.0).stop);
}

TEST(PythonRecognizer, TheStopIsLatchedUntilTheReset) {
  pd::PythonRecognizer r("pd_test_recognizers.ForgetsStop");
  r.configure({});
  EXPECT_FALSE(r.push(1.0, 1.0).stop);
  EXPECT_TRUE(r.push(2.0, 1.0).stop);
  EXPECT_TRUE(r.push(3.0, 1.0).stop);  // Python says no more; the stop stays
  EXPECT_DOUBLE_EQ(r.output().stop_t, 2.0);
  r.reset();
  EXPECT_FALSE(r.push(4.0, 1.0).stop);
}

TEST(PythonRecognizer, ErrorsNameTheClassTheParameterOrTheKey) {
  const auto message = [](auto&& f) {
    try {
      f();
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message([] { pd::PythonRecognizer("no_such_module.Rec"); }).find("no_such_module"),
            std::string::npos);
  EXPECT_NE(message([] { pd::PythonRecognizer("pd_test_recognizers.Nope"); }).find("Nope"),
            std::string::npos);
  EXPECT_NE(message([] { pd::PythonRecognizer("nodot"); }).find("python:<module>.<Class>"),
            std::string::npos);
  EXPECT_NE(message([] { pd::PythonRecognizer("pd_test_recognizers.NoPush"); }).find("push"),
            std::string::npos);
  pd::PythonRecognizer r("pd_test_recognizers.StopAfter");
  EXPECT_THROW(r.configure({{"speed", "3"}}), std::invalid_argument);
  EXPECT_EQ(message([&r] { r.configure({{"speed", "3"}}); }).rfind("speed", 0), 0u);
  EXPECT_THROW(r.push(std::nan(""), 1.0), std::invalid_argument);
  EXPECT_THROW(r.push(0.0, std::numeric_limits<double>::infinity()), std::invalid_argument);
  pd::PythonRecognizer bad("pd_test_recognizers.BadKey");
  EXPECT_NE(message([&bad] { bad.push(0.0, 1.0); }).find("stahp"), std::string::npos);
}

// What the StateRecognizer nodelet and the core engine run: the Python class behind the guard.
// A Python exception mid-drill is a stop whose reason names the class and the error.
TEST(PythonRecognizer, APythonExceptionBehindTheGuardIsAStopNamingIt) {
  pd::core::GuardedRecognizer r(
      std::make_unique<pd::PythonRecognizer>("pd_test_recognizers.RaisesAt"));
  r.configure({{"after_s", "0.55"}});
  for (int i = 0; i <= 5; ++i) EXPECT_FALSE(r.push(0.1 * i, 2.0).stop) << i;
  const pd::core::RecognizerOutput& out = r.push(0.6, 2.0);
  EXPECT_TRUE(out.stop);
  EXPECT_TRUE(out.new_average);
  EXPECT_EQ(out.state, pd::core::DrillingState::kStopped);
  const std::string reason = r.stopReason();
  EXPECT_EQ(reason.rfind("recognizer error, stopping: ", 0), 0u) << reason;
  EXPECT_NE(reason.find("RaisesAt"), std::string::npos) << reason;
  EXPECT_NE(reason.find("layer_table"), std::string::npos) << reason;
  EXPECT_TRUE(r.push(0.7, 2.0).stop);  // latched
  r.reset();
  EXPECT_FALSE(r.push(0.1, 2.0).stop);
}

TEST(PythonRecognizer, AClassWithPushSampleGetsTheWholeSample) {
  pd::PythonRecognizer r("pd_test_recognizers.ReadsTheWrench");
  r.configure({});
  pd::core::RecognizerSample sample;
  sample.t = 0.25;
  sample.thrust_n = 3.0;
  sample.force_n = {0.5, -0.25, 3.0};
  sample.torque_nm = {0.0, 0.0, 0.004};
  sample.feed_depth_m = 0.006;
  EXPECT_FALSE(r.pushSample(sample).stop);
  EXPECT_DOUBLE_EQ(r.output().averaged_force, 0.5);  // the lateral force, as the class read it
  sample.t = 0.5;
  sample.torque_nm[2] = 0.006;
  sample.feed_command_m = 0.0065;
  sample.tracker_m = {0.3, -0.1, 1.2};
  sample.tracker_stamp = 0.375;
  EXPECT_TRUE(r.pushSample(sample).stop);
  EXPECT_DOUBLE_EQ(r.output().stop_t, 0.5);
  // A thrust-only class behind the same call gets push(t, thrust).
  pd::PythonRecognizer thrust_only("pd_test_recognizers.StopAfter");
  thrust_only.configure({{"after_s", "0.3"}});
  sample.t = 0.1;
  EXPECT_FALSE(thrust_only.pushSample(sample).stop);
  sample.t = 0.4;
  EXPECT_TRUE(thrust_only.pushSample(sample).stop);
  sample.thrust_n = std::nan("");
  EXPECT_THROW(r.pushSample(sample), std::invalid_argument);
}
