// The recognizer plugin interface: the paper recognizer behind it behaves as
// StateRecognizer itself, the force-difference baseline stops at the second breakthrough, the
// factory refuses unknown names and bad settings naming them.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "param_table_checks.hpp"
#include "pedicle_drilling/core/drilling/recognizer_interface.hpp"

namespace pd = pedicle_drilling::core;

namespace {

// A vertebra-like thrust profile at 1 kHz and 0.5 mm/s: air, outer cortex (rising to 3.5 N),
// cancellous (about 1.2 N), inner cortex (rising to 4 N), then the breakthrough (to 0).
std::vector<double> profile() {
  std::vector<double> f;
  const auto ramp = [&f](double from, double to, int n) {
    for (int i = 0; i < n; ++i) f.push_back(from + (to - from) * i / n);
  };
  ramp(0.0, 0.0, 1000);
  ramp(0.2, 3.5, 4000);
  ramp(3.5, 1.2, 1000);
  ramp(1.2, 1.2, 6000);
  ramp(1.2, 4.0, 3000);
  ramp(4.0, 0.0, 1500);
  ramp(0.0, 0.0, 1000);
  return f;
}

}  // namespace

TEST(RecognizerInterface, ThePaperRecognizerBehindTheInterfaceIsStateRecognizer) {
  pd::StateRecognizer direct;
  const auto plugin = pd::makeBuiltinRecognizer("pedicle_drilling/PaperRecognizer", {});
  const std::vector<double> f = profile();
  for (std::size_t i = 0; i < f.size(); ++i) {
    const double t = 1e-3 * static_cast<double>(i);
    const pd::RecognizerOutput& a = direct.push(t, f[i]);
    const pd::RecognizerOutput& b = plugin->push(t, f[i]);
    ASSERT_EQ(a.state, b.state) << i;
    ASSERT_EQ(a.stop, b.stop) << i;
    ASSERT_EQ(a.averaged_force, b.averaged_force) << i;
  }
  EXPECT_TRUE(plugin->output().stop);
  EXPECT_EQ(plugin->stopReason(), pd::stopReason(direct.output()));
  // Settings by name, as text; a bad one names itself.
  const auto tuned = pd::makeBuiltinRecognizer("pedicle_drilling/PaperRecognizer",
                                               {{"window", "5"}, {"c2", "0.8"}});
  EXPECT_EQ(dynamic_cast<const pd::PaperRecognizer&>(*tuned).params().window, 5);
  try {
    pd::makeBuiltinRecognizer("pedicle_drilling/PaperRecognizer", {{"c3", "1.5"}});
    FAIL() << "accepted c3 = 1.5";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("c3", 0), 0u) << e.what();
  }
}

TEST(RecognizerInterface, UnknownNamesAreRefusedListingTheBuiltInOnes) {
  try {
    pd::makeBuiltinRecognizer("someone/Else", {});
    FAIL() << "accepted an unknown class";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("someone/Else"), std::string::npos);
    EXPECT_NE(what.find("pedicle_drilling/ForceDifferenceRecognizer"), std::string::npos);
  }
}

TEST(ForceDifferenceRecognizer, StopsAtTheSecondBreakthroughNotTheFirst) {
  const auto r = pd::makeBuiltinRecognizer("pedicle_drilling/ForceDifferenceRecognizer", {});
  const std::vector<double> f = profile();
  double first_cancellous_t = -1.0;
  for (std::size_t i = 0; i < f.size(); ++i) {
    const double t = 1e-3 * static_cast<double>(i);
    const pd::RecognizerOutput& o = r->push(t, f[i]);
    if (first_cancellous_t < 0.0 && o.layer_state == pd::DrillingState::kCancellous) {
      first_cancellous_t = t;
      EXPECT_FALSE(o.stop) << "stopped at the outer cortex's breakthrough";
    }
  }
  const pd::RecognizerOutput& o = r->output();
  // The outer cortex ends at 5.0 s (drop to 6.0 s): the first breakthrough inside that drop.
  EXPECT_GT(first_cancellous_t, 5.0);
  EXPECT_LT(first_cancellous_t, 6.0);
  ASSERT_TRUE(o.stop);
  // The inner cortex's force falls from 15.0 s: the stop within that fall, not before it.
  EXPECT_GT(o.stop_t, 15.0);
  EXPECT_LT(o.stop_t, 16.5);
  EXPECT_EQ(o.state, pd::DrillingState::kStopped);
  EXPECT_NE(r->stopReason().find("breakthrough 2"), std::string::npos) << r->stopReason();
  // reset() forgets the trial.
  r->reset();
  EXPECT_FALSE(r->output().stop);
  EXPECT_EQ(r->output().state, pd::DrillingState::kIdle);
}

TEST(ForceDifferenceRecognizer, StopAtEntryTwoStopsWhereTheInnerCortexBegins) {
  const auto r = pd::makeBuiltinRecognizer("pedicle_drilling/ForceDifferenceRecognizer",
                                           {{"stop_at_entry", "2"}, {"rise_confirm", "2"}});
  const std::vector<double> f = profile();
  pd::DrillingState layer_at_stop = pd::DrillingState::kIdle;
  for (std::size_t i = 0; i < f.size(); ++i) {
    const bool stopped = r->output().stop;
    if (r->push(1e-3 * static_cast<double>(i), f[i]).stop && !stopped) {
      layer_at_stop = r->output().layer_state;
    }
  }
  const pd::RecognizerOutput& o = r->output();
  ASSERT_TRUE(o.stop);
  // The inner cortex's force rises from 12.0 s to 15.0 s: the stop in that rise, before the
  // breakthrough (its fall starts at 15.0 s).
  EXPECT_GT(o.stop_t, 12.0);
  EXPECT_LT(o.stop_t, 15.0);
  EXPECT_EQ(layer_at_stop, pd::DrillingState::kInnerCortical);
  EXPECT_NE(r->stopReason().find("cortex entry 2"), std::string::npos) << r->stopReason();
  // Two confirming blocks stop later than one, never earlier.
  const auto one = pd::makeBuiltinRecognizer("pedicle_drilling/ForceDifferenceRecognizer",
                                             {{"stop_at_entry", "2"}});
  for (std::size_t i = 0; i < f.size(); ++i) one->push(1e-3 * static_cast<double>(i), f[i]);
  ASSERT_TRUE(one->output().stop);
  EXPECT_LT(one->output().stop_t, o.stop_t);
}

TEST(ForceDifferenceRecognizer, SettingsAreCheckedNamingThem) {
  for (const auto& [name, value] :
       std::vector<std::pair<std::string, std::string>>{{"drop_threshold_n", "-1"},
                                                        {"drop_confirm", "0"},
                                                        {"pre_average", "x"},
                                                        {"stop_at_breakthrough", "11"},
                                                        {"stop_at_entry", "-1"},
                                                        {"rise_confirm", "0"},
                                                        {"no_such_parameter", "1"}}) {
    try {
      pd::makeBuiltinRecognizer("pedicle_drilling/ForceDifferenceRecognizer", {{name, value}});
      FAIL() << "accepted " << name << " = " << value;
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()).rfind(name, 0), 0u) << e.what();
    }
  }
  pd::ForceDifferenceRecognizer r;
  EXPECT_THROW(r.push(0.0, std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
}

TEST(ForceDifferenceParams, TheTableDeclaresEveryFieldWithItsDefaultAndRange) {
  pedicle_drilling::test::expectDeclaredDefaults(pd::ForceDifferenceParams::table(),
                                                 {{"pre_average", "50"},
                                                  {"contact_force_n", "1"},
                                                  {"process_noise", "0.001"},
                                                  {"measurement_noise", "0.01"},
                                                  {"drop_threshold_n", "0.05"},
                                                  {"drop_confirm", "3"},
                                                  {"stop_at_breakthrough", "2"},
                                                  {"rearm_rise_n", "0.015"},
                                                  {"rise_confirm", "1"},
                                                  {"stop_at_entry", "0"}});
  pedicle_drilling::test::expectRangesRefusedNamingTheField(pd::ForceDifferenceParams::table());
  EXPECT_EQ(pd::ForceDifferenceRecognizer().parameterNames(),
            pd::ForceDifferenceParams::table().declaredNames());
  EXPECT_EQ(pd::PaperRecognizer().parameterNames(), pd::RecognizerParams::table().declaredNames());
  // The texts as every table writes them.
  pd::ForceDifferenceRecognizer r;
  EXPECT_EQ(pedicle_drilling::test::invalidArgumentOf([&] {
              r.configure({{"drop_confirm", "0"}});
            }),
            "drop_confirm = 0 is out of range [1, 10000] blocks");
  EXPECT_EQ(pedicle_drilling::test::invalidArgumentOf([&] {
              r.configure({{"gain", "2"}});
            }),
            "gain: not a parameter of pedicle_drilling/ForceDifferenceRecognizer");
}

namespace {

/// A class whose push() throws from its `fail_at`-th sample on (a plugin's bug).
class FailingRecognizer : public pd::ForceDifferenceRecognizer {
 public:
  explicit FailingRecognizer(int fail_at) : fail_at_(fail_at) {}
  const pd::RecognizerOutput& push(double t, double raw_force) override {
    if (++count_ >= fail_at_) throw std::out_of_range("vector::_M_range_check");
    return pd::ForceDifferenceRecognizer::push(t, raw_force);
  }
  void reset() override {
    count_ = 0;
    pd::ForceDifferenceRecognizer::reset();
  }

 private:
  int fail_at_;
  int count_ = 0;
};

}  // namespace

// The StateRecognizer nodelet and the core engine run every class behind this guard: an
// exception is a latched stop naming it (published at once), never an escaped exception.
TEST(GuardedRecognizer, AnExceptionOfTheClassIsALatchedStopNamingItUntilAReset) {
  pd::GuardedRecognizer guard(std::make_unique<FailingRecognizer>(120));
  guard.configure({});
  for (int i = 0; i < 119; ++i) EXPECT_FALSE(guard.push(1e-3 * i, 2.0).stop);
  const pd::RecognizerOutput& out = guard.push(0.119, 2.0);
  EXPECT_TRUE(out.stop);
  EXPECT_TRUE(out.new_average);  // published at once
  EXPECT_EQ(out.state, pd::DrillingState::kStopped);
  EXPECT_DOUBLE_EQ(out.stop_t, 0.119);
  EXPECT_EQ(guard.stopReason(), "recognizer error, stopping: vector::_M_range_check");
  EXPECT_EQ(guard.error(), "vector::_M_range_check");
  // Latched: later samples report the same stop, not new.
  const pd::RecognizerOutput& later = guard.push(0.2, 2.0);
  EXPECT_TRUE(later.stop);
  EXPECT_FALSE(later.new_average);
  EXPECT_TRUE(guard.output().stop);
  // A reset that succeeds clears it: the class runs again.
  guard.reset();
  EXPECT_EQ(guard.error(), "");
  EXPECT_FALSE(guard.push(0.3, 2.0).stop);
  EXPECT_FALSE(guard.output().stop);
  EXPECT_THROW(pd::GuardedRecognizer(nullptr), std::invalid_argument);
}
