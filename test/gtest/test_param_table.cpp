// core::ParamTable: parameters declared once (name, kind, range, unit) validate, set from text,
// nest with a prefix and document themselves; every shipped declaration accepts its defaults.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "pedicle_drilling/core/common/param_table.hpp"
#include "pedicle_drilling/ros/node_params.hpp"

namespace pd = pedicle_drilling;
using pd::core::ParamKind;
using pd::core::ParamTable;
using pd::core::Range;

namespace {

struct Inner {
  double gain = 2.0;
  std::vector<int> levels{3, 4};
};

struct Outer {
  double threshold_m = 1e-3;
  int count = 5;
  bool enabled = true;
  std::string mode = "fast";
  std::string frame = "world";
  Inner inner;
};

const ParamTable<Inner>& innerTable() {
  static const ParamTable<Inner> t = [] {
    ParamTable<Inner> d;
    d.number("gain", &Inner::gain, Range::closed(1, 10))
        .integers("levels", &Inner::levels, Range::closed(1, 16));
    return d;
  }();
  return t;
}

const ParamTable<Outer>& outerTable() {
  static const ParamTable<Outer> t = [] {
    ParamTable<Outer> d;
    d.number("threshold_m", &Outer::threshold_m, Range::aboveUpTo(0, 0.1), "m")
        .integer("count", &Outer::count, Range::closed(1, 100))
        .flag("enabled", &Outer::enabled)
        .parsed(
            "mode", {"fast", "exact"}, "", [](const Outer& v) { return v.mode; },
            [](Outer& v, const std::string& x) { v.mode = x; })
        .text("frame", &Outer::frame)
        .include(innerTable(), &Outer::inner, "inner/");
    return d;
  }();
  return t;
}

std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST(Range, ContainsHonoursOpenBoundsAndRejectsNaN) {
  const Range r = Range::aboveUpTo(0, 1);
  EXPECT_FALSE(r.contains(0.0));
  EXPECT_TRUE(r.contains(1e-12));
  EXPECT_TRUE(r.contains(1.0));
  EXPECT_FALSE(r.contains(1.0 + 1e-12));
  EXPECT_FALSE(r.contains(std::nan("")));
  EXPECT_FALSE(Range::open(0, 1).contains(1.0));
  EXPECT_TRUE(Range::fromBelow(0, 1).contains(0.0));
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(Range::aboveUpTo(0, inf).contains(inf));  // "+inf disables" timeouts
  EXPECT_EQ(Range::aboveUpTo(0, 0.1).text(), "(0, 0.1]");
  EXPECT_EQ(Range::fromBelow(0, 1).text(), "[0, 1)");
  EXPECT_EQ(Range::aboveUpTo(0, inf).text(), "(0, inf]");
}

TEST(ParamTable, ValidateNamesTheFirstFieldOutOfRange) {
  Outer v;
  EXPECT_NO_THROW(outerTable().validate(v));
  v.threshold_m = 0.0;
  EXPECT_EQ(errorOf([&] { outerTable().validate(v); }),
            "threshold_m = 0 is out of range (0, 0.1] m");
  v = Outer();
  v.inner.gain = std::nan("");
  EXPECT_EQ(errorOf([&] { outerTable().validate(v); }).rfind("inner/gain = nan", 0), 0u);
  v = Outer();
  v.inner.levels = {3, 17};
  EXPECT_EQ(errorOf([&] { outerTable().validate(v); }),
            "inner/levels = 17 is out of range [1, 16]");
  v.inner.levels.clear();
  EXPECT_EQ(errorOf([&] { outerTable().validate(v); }), "inner/levels must not be empty");
}

TEST(ParamTable, SetParsesTextOfEveryKindAndChecksIt) {
  Outer v;
  const ParamTable<Outer>& t = outerTable();
  t.set(v, "threshold_m", "0.002");
  EXPECT_DOUBLE_EQ(v.threshold_m, 0.002);
  t.set(v, "count", "7");
  EXPECT_EQ(v.count, 7);
  t.set(v, "enabled", "false");
  EXPECT_FALSE(v.enabled);
  t.set(v, "mode", "exact");
  EXPECT_EQ(v.mode, "exact");
  t.set(v, "inner/levels", "2,5,6");
  EXPECT_EQ(v.inner.levels, (std::vector<int>{2, 5, 6}));
  t.set(v, "inner/gain", "3.5");
  EXPECT_DOUBLE_EQ(v.inner.gain, 3.5);

  EXPECT_EQ(errorOf([&] { t.set(v, "count", "7.5"); }), "count = '7.5' is not an integer");
  EXPECT_EQ(errorOf([&] { t.set(v, "count", "0"); }), "count = 0 is out of range [1, 100]");
  EXPECT_EQ(errorOf([&] { t.set(v, "threshold_m", "abc"); }),
            "threshold_m = 'abc' is not a number");
  EXPECT_EQ(errorOf([&] { t.set(v, "enabled", "maybe"); }),
            "enabled = 'maybe' is not true or false");
  EXPECT_EQ(errorOf([&] { t.set(v, "mode", "slow"); }), "mode = 'slow' is not one of: fast, exact");
  EXPECT_EQ(errorOf([&] { t.set(v, "frame", ""); }), "frame must not be empty");
  EXPECT_EQ(errorOf([&] { t.set(v, "nope", "1"); }), "unknown parameter 'nope'");
  EXPECT_EQ(v.count, 7);  // a refused value leaves the field alone
}

TEST(ParamTable, DescribeGivesKindsRulesAndDefaultsInDeclarationOrder) {
  const std::vector<pd::core::ParamInfo> info = outerTable().describe(Outer());
  ASSERT_EQ(info.size(), 7u);
  EXPECT_EQ(info[0].name, "threshold_m");
  EXPECT_EQ(info[0].rule(), "(0, 0.1] m");
  EXPECT_EQ(info[0].default_text, "0.001");
  EXPECT_EQ(info[1].default_text, "5");
  EXPECT_EQ(info[2].kind, ParamKind::kBool);
  EXPECT_EQ(info[2].default_text, "true");
  EXPECT_EQ(info[3].rule(), "one of: fast, exact");
  EXPECT_EQ(info[4].rule(), "any non-empty text");
  EXPECT_EQ(info[6].name, "inner/levels");
  EXPECT_EQ(info[6].default_text, "3,4");
  EXPECT_STREQ(kindName(info[6].kind), "integers");
}

TEST(ParamTable, ADuplicateNameIsAProgrammingError) {
  ParamTable<Outer> d;
  d.number("x", &Outer::threshold_m, Range::closed(0, 1));
  EXPECT_THROW(d.integer("x", &Outer::count, Range::closed(0, 1)), std::logic_error);
}

// Every nodelet's declaration accepts its own defaults, and each core struct's validate() uses
// the declared name: a default out of its own range, or a name typed twice differently, fails.
TEST(NodeParams, EveryDeclarationAcceptsItsDefaults) {
  EXPECT_NO_THROW(pd::VentilatorNodeParams().validate());
  EXPECT_NO_THROW(pd::SimulatorNodeParams().validate());
  EXPECT_NO_THROW(pd::MotionIdentificationParams().validate());
  EXPECT_NO_THROW(pd::StateRecognizerNodeParams().validate());
  EXPECT_NO_THROW(pd::SafetyMonitorNodeParams().validate());
  EXPECT_NO_THROW(pd::CompensationPlannerNodeParams().validate());
  EXPECT_NO_THROW(pd::FaultInjectorNodeParams().validate());
  EXPECT_NO_THROW(pd::TfPoseRelayNodeParams().validate());
  EXPECT_NO_THROW(pd::ForceTareNodeParams().validate());
  EXPECT_NO_THROW(pd::TrialActionNodeParams().validate());
  const auto docs = pd::nodeParameterDocs();
  ASSERT_EQ(docs.size(), 10u);
  for (const auto& [node, params] : docs) EXPECT_FALSE(params.empty()) << node;
}

TEST(NodeParams, ChecksBetweenFieldsNameTheParameter) {
  pd::SafetyMonitorNodeParams monitor;
  monitor.check_rate_hz = 10.0;  // one check per 0.1 s force timeout
  EXPECT_EQ(errorOf([&] { monitor.validate(); }).rfind("check_rate_hz", 0), 0u);
  pd::StateRecognizerNodeParams recognizer;
  recognizer.recognizer.c2 = 0.3;  // below c1 = 0.4
  EXPECT_EQ(errorOf([&] { recognizer.validate(); }).rfind("c2", 0), 0u);
  pd::MotionIdentificationParams identification;
  identification.si_axis = "+z";  // the same axis as AP
  EXPECT_EQ(errorOf([&] { identification.validate(); }).rfind("si_axis", 0), 0u);
  identification = pd::MotionIdentificationParams();
  identification.defaults.denoise_options.kept_levels = {7};  // above level 6
  EXPECT_EQ(errorOf([&] { identification.validate(); }).rfind("kept_levels", 0), 0u);
  pd::SimulatorNodeParams simulator;
  simulator.sim.arm_rate_hz = 300.0;
  EXPECT_EQ(errorOf([&] { simulator.validate(); }).rfind("arm_rate_hz", 0), 0u);
  simulator = pd::SimulatorNodeParams();
  simulator.sim.sensor.output_rate_hz = 300.0;  // not a divisor of the 1000 Hz physics
  EXPECT_EQ(errorOf([&] { simulator.validate(); }).rfind("force_sensor_rate_hz", 0), 0u);
  pd::TfPoseRelayNodeParams relay;
  relay.marker_frame = relay.tracker_frame;
  EXPECT_EQ(errorOf([&] { relay.validate(); }).rfind("marker_frame", 0), 0u);
  pd::ForceTareNodeParams tare;
  tare.zero_tolerance_n = 0.0;  // (0, 100] N
  EXPECT_EQ(errorOf([&] { tare.validate(); }).rfind("zero_tolerance_n", 0), 0u);
}

// A parameter that switches a watchdog off is refused naming it, unless the node is told
// ~unsafe_allow_disabled_watchdogs (then disabledWatchdogs() lists it, for the WARN at load).
TEST(NodeParams, AParameterThatSwitchesAWatchdogOffIsRefusedUnlessAllowedExplicitly) {
  pd::CompensationPlannerNodeParams planner;
  EXPECT_TRUE(planner.disabledWatchdogs().empty());
  const std::vector<std::pair<std::string, std::function<void(pd::core::TrialSequencerParams&)>>>
      switches{{"recognizer_timeout_s", [](auto& s) { s.recognizer_timeout_s = 0.0; }},
               {"monitor_timeout_s", [](auto& s) { s.monitor_timeout_s = 0.0; }},
               {"controller_watch/enabled", [](auto& s) { s.controller_watch.enabled = false; }},
               {"outer_cortical_max_mm", [](auto& s) { s.outer_cortical_max_mm = 0.0; }},
               {"cancellous_max_mm", [](auto& s) { s.cancellous_max_mm = 0.0; }}};
  for (const auto& [name, off] : switches) {
    planner = pd::CompensationPlannerNodeParams();
    off(planner.sequencer);
    const std::string error = errorOf([&] { planner.validate(); });
    EXPECT_EQ(error.rfind(name + " = ", 0), 0u) << error;
    EXPECT_NE(error.find("unsafe_allow_disabled_watchdogs"), std::string::npos) << error;
    planner.unsafe_allow_disabled_watchdogs = true;
    EXPECT_NO_THROW(planner.validate());
    ASSERT_EQ(planner.disabledWatchdogs().size(), 1u);
    EXPECT_EQ(planner.disabledWatchdogs()[0].rfind(name, 0), 0u);
  }
  pd::StateRecognizerNodeParams recognizer;
  EXPECT_TRUE(recognizer.disabledWatchdogs().empty());
  recognizer.recognizer.cancellous_deadline = 0;
  EXPECT_EQ(errorOf([&] { recognizer.validate(); }).rfind("cancellous_deadline = 0", 0), 0u);
  recognizer.unsafe_allow_disabled_watchdogs = true;
  EXPECT_NO_THROW(recognizer.validate());
  EXPECT_EQ(recognizer.disabledWatchdogs().size(), 1u);
}

// The paper recognizer takes its settings as text in ~recognizer_params like any class, over
// the node's own keys (the nodelet refuses a key given both ways: paperSettingNames()).
TEST(NodeParams, ThePaperRecognizerTakesRecognizerParamsAsTextCheckedByItsTable) {
  pd::StateRecognizerNodeParams node;
  node.recognizer_params = {{"window", "3"}, {"inner_confirm", "4.0"}};
  EXPECT_NO_THROW(node.validate());
  EXPECT_EQ(node.recognizerInUse().window, 3);
  EXPECT_EQ(node.recognizerInUse().inner_confirm, 4);
  EXPECT_EQ(node.recognizer.window, 10);  // the node's own key keeps its value
  EXPECT_EQ(node.paperSettingNames(), (std::vector<std::string>{"window", "inner_confirm"}));
  const std::vector<std::pair<std::string, std::string>> refused{
      {"window", "recognizer_params/window = '4.5' is not an integer"},
      {"nonsense", "recognizer_params/nonsense: unknown recognizer parameter"},
      {"c3", "recognizer_params/c3 = 1.5 is out of range (0, 1)"},
      {"pre_average", "recognizer_params/pre_average is retired: "},
      {"c2", "recognizer_params/c2: must be >= c1"},  // a check between fields, named as set
      {"cancellous_deadline", "cancellous_deadline = 0 (no bound"}};  // a watchdog switched off
  const std::vector<std::string> values{"4.5", "1", "1.5", "50", "0.3", "0"};
  for (std::size_t i = 0; i < refused.size(); ++i) {
    node.recognizer_params = {{refused[i].first, values[i]}};
    const std::string error = errorOf([&] { node.validate(); });
    EXPECT_EQ(error.rfind(refused[i].second, 0), 0u) << error;
  }
  // The node's own key, checked between fields with the mapping's: named as the node's.
  node.recognizer_params = {{"window", "30"}};
  EXPECT_EQ(errorOf([&] { node.validate(); }).rfind("cancellous_deadline: ", 0), 0u);
  // Another class reads its own settings: the paper recognizer's stay the node's keys.
  node.recognizer_class = "pedicle_drilling/ForceDifferenceRecognizer";
  EXPECT_NO_THROW(node.validate());
  EXPECT_EQ(node.recognizerInUse().window, 10);
  EXPECT_TRUE(node.paperSettingNames().empty());
}

TEST(NodeParams, TheRecognizerTableServesPluginSettingsToo) {
  pd::core::RecognizerParams p;
  p.set("k_ratio", "0.25");
  EXPECT_DOUBLE_EQ(p.k_ratio, 0.25);
  EXPECT_EQ(errorOf([&] { p.set("k_ratio", "1.5"); }), "k_ratio = 1.5 is out of range (0, 1)");
  EXPECT_EQ(errorOf([&] { p.set("no_such", "1"); }), "no_such: unknown recognizer parameter");
}
