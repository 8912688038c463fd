// Tests of PythonCompensator: a motion compensator written in Python, driven through
// the C++ interface. The classes under test are written here into a module on the Python path.
#include "pedicle_drilling/python/python_compensator.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "pedicle_drilling/core/control/compensation_planner.hpp"

namespace pd = pedicle_drilling;

namespace {

/** @brief Writes the test module into a fresh directory put first on PYTHONPATH, once, before
 *         the interpreter starts. */
class PythonModule : public ::testing::Environment {
 public:
  void SetUp() override {
    char pattern[] = "/tmp/pd_python_compensator_XXXXXX";
    const char* dir = mkdtemp(pattern);
    ASSERT_NE(dir, nullptr);
    std::ofstream(std::string(dir) + "/pd_test_compensators.py") << R"(
import numpy as np

class Echo:
    """Reports what it was given: the AP model's q1 as x, the rate as y, the last marker's z."""
    def __init__(self):
        self.gain = 1.0
        self.q1 = self.rate = self.start = None
        self.marker = None
    def configure(self, settings):
        for name, text in settings.items():
            if name != 'gain':
                raise ValueError(name + ': unknown parameter')
            self.gain = float(text)
    def set_patient(self, model, params):
        assert set(model) == {'ap', 'si', 'lr'} and model['ap']['kind'] == 'linear'
        assert params['predict_axis'] == [True, False, False]
        assert len(params['axis_direction']['ap']) == 3
        self.q1 = model['ap']['q1']
    def set_ventilator(self, settings):
        self.rate = settings['rate_bpm']
    def set_breath_start(self, t):
        self.start = t
    def observe_marker(self, stamp, position):
        assert isinstance(position, np.ndarray) and position.shape == (3,)
        self.marker = position
    def ready(self):
        return self.marker is not None
    def displacement(self, t):
        return np.array([self.q1, self.rate, self.gain * self.marker[2] + t - self.start])
    def velocity_steps(self, t0, t1):
        return [t0 + 0.5 * (t1 - t0)]
    def parameter_names(self):
        return ['gain']

class TwoNumbers(Echo):
    def displacement(self, t):
        return (1.0, 2.0)

class NotFinite(Echo):
    def displacement(self, t):
        return [0.0, float('nan'), 0.0]

class NoDisplacement:
    def configure(self, settings): pass
    def set_patient(self, model, params): pass
    def set_ventilator(self, settings): pass
    def set_breath_start(self, t): pass
    def ready(self): return True
)";
    const char* old = std::getenv("PYTHONPATH");
    setenv("PYTHONPATH", (std::string(dir) + (old ? std::string(":") + old : "")).c_str(), 1);
    dir_ = dir;
  }
  void TearDown() override {
    std::remove((dir_ + "/pd_test_compensators.py").c_str());
    std::system(("rm -rf '" + dir_ + "/__pycache__'").c_str());
    std::remove(dir_.c_str());
  }

 private:
  std::string dir_;
};

const ::testing::Environment* const kModule = ::testing::AddGlobalTestEnvironment(new PythonModule);

pd::core::MotionModel linearModel(double q1) {
  pd::core::MotionModel m;
  m.axis(pd::core::Axis::kAP).q1 = q1;
  return m;
}

std::string message(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST(PythonCompensator, EveryInputReachesThePythonClassAndItsPredictionComesBack) {
  pd::PythonCompensator c("pd_test_compensators.Echo");
  c.configure({{"gain", "2"}});
  EXPECT_EQ(c.parameterNames(), std::vector<std::string>{"gain"});
  c.setPatient(linearModel(0.004), pd::core::CompensationParams());
  pd::core::VentilatorSettings v;
  v.rate_bpm = 15.0;
  c.setVentilator(v);
  c.setBreathStart(10.0);
  EXPECT_FALSE(c.ready());
  c.observeMarker(10.5, Eigen::Vector3d(0.1, 0.2, 0.3));
  ASSERT_TRUE(c.ready());
  const Eigen::Vector3d d = c.displacement(11.0);
  EXPECT_DOUBLE_EQ(d.x(), 0.004);
  EXPECT_DOUBLE_EQ(d.y(), 15.0);
  EXPECT_DOUBLE_EQ(d.z(), 2.0 * 0.3 + 1.0);
  EXPECT_EQ(c.velocitySteps(1.0, 2.0), std::vector<double>{1.5});
}

TEST(PythonCompensator, ErrorsNameTheClassTheParameterOrTheMethod) {
  EXPECT_NE(message([] { pd::PythonCompensator("no_such_module.Comp"); }).find("no_such_module"),
            std::string::npos);
  EXPECT_NE(message([] {
              pd::PythonCompensator("pd_test_compensators.NoDisplacement");
            }).find("displacement"),
            std::string::npos);
  EXPECT_NE(message([] { pd::PythonCompensator("NoDot"); }).find("python:<module>.<Class>"),
            std::string::npos);
  pd::PythonCompensator c("pd_test_compensators.Echo");
  try {
    c.configure({{"gian", "2"}});
    FAIL() << "accepted an unknown parameter";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("gian", 0), 0u) << e.what();
  }
  pd::core::VentilatorSettings bad;
  bad.rate_bpm = -1.0;
  EXPECT_THROW(c.setVentilator(bad), std::invalid_argument);
  for (const char* name : {"pd_test_compensators.TwoNumbers", "pd_test_compensators.NotFinite"}) {
    pd::PythonCompensator w(name);
    w.setPatient(linearModel(0.004), pd::core::CompensationParams());
    w.setVentilator(pd::core::VentilatorSettings());
    w.setBreathStart(0.0);
    w.observeMarker(0.1, Eigen::Vector3d::Zero());
    const std::string m = message([&w] { w.displacement(1.0); });
    EXPECT_NE(m.find(name), std::string::npos) << m;
    EXPECT_NE(m.find("displacement"), std::string::npos) << m;
  }
}

TEST(PythonCompensator, ThePhaseTemplateExamplePredictsABreathItHasSeen) {
  // pd_campaign.compensators.PhaseTemplateCompensator on a sinusoidal marker motion at the
  // ventilator's period: after two breaths of 8 Hz samples it predicts the motion ahead.
  pd::PythonCompensator c("pd_campaign.compensators.PhaseTemplateCompensator");
  c.configure({{"bins", "16"}});
  c.setPatient(linearModel(0.004), pd::core::CompensationParams());
  pd::core::VentilatorSettings v;
  v.rate_bpm = 12.0;  // 5 s breaths
  c.setVentilator(v);
  c.setBreathStart(0.0);
  const auto motion = [](double t) { return 0.003 * std::sin(2.0 * M_PI * t / 5.0); };
  for (double t = 0.0; t < 10.0; t += 0.125) c.observeMarker(t, Eigen::Vector3d(0, 0, motion(t)));
  ASSERT_TRUE(c.ready());
  for (double t = 10.0; t < 15.0; t += 0.37) {
    EXPECT_NEAR(c.displacement(t).z(), motion(t), 0.0003) << t;  // within 10 % of the amplitude
  }
}
