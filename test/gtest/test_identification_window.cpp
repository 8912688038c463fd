// Tests of the sliding identification window.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>

#include "pedicle_drilling/core/breathing/identification_window.hpp"

namespace pedicle_drilling::core {
namespace {

// Tidal volume at 64 Hz and markers at 8 Hz over [t0, t1), in time order as they arrive.
void fill(IdentificationWindow* w, double t0, double t1) {
  for (int k = 0; t0 + k / 64.0 < t1; ++k) {
    const double t = t0 + k / 64.0;
    w->addTidalVolume(t, 100.0 + k);
    if (k % 8 == 0) w->addMarker(t, {{1.0 * k, 2.0, 3.0}});
  }
}

TEST(IdentificationWindowTest, KeepsOnlyTheLastWindowSeconds) {
  IdentificationWindow w(10.0);
  fill(&w, 0.0, 30.0);
  const WindowRecording r = w.take();
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_GE(r.recording.t_tv.front(), 30.0 - 1.0 / 64.0 - 10.0);
  EXPECT_NEAR(r.recording.t_tv.back() - r.recording.t_tv.front(), 10.0, 2.0 / 64.0);
  // Markers only inside the tidal volume's span, in order, mapped AP, SI, LR.
  EXPECT_GE(r.recording.t_disp.front(), r.recording.t_tv.front());
  EXPECT_LE(r.recording.t_disp.back(), r.recording.t_tv.back());
  EXPECT_EQ(r.recording.t_disp.size(), r.recording.ap.size());
  EXPECT_DOUBLE_EQ(r.recording.si.front(), 2.0);
  EXPECT_DOUBLE_EQ(r.recording.lr.front(), 3.0);
}

TEST(IdentificationWindowTest, DropsDuplicatesAndOutOfOrderSamples) {
  IdentificationWindow w(30.0);
  fill(&w, 0.0, 5.0);
  const WindowRecording before = w.take();
  ASSERT_TRUE(before.ok) << before.error;
  const double newest = before.recording.t_tv.back();
  // Older than the newest but less than 1 s back (not a jump): dropped.
  EXPECT_DOUBLE_EQ(w.addTidalVolume(newest - 0.5, 1.0), 0.0);
  w.addTidalVolume(newest, 1.0);  // duplicate stamp: dropped
  w.addMarker(newest - 0.5, {{0.0, 0.0, 0.0}});
  const WindowRecording after = w.take();
  EXPECT_EQ(after.recording.t_tv.size(), before.recording.t_tv.size());
  EXPECT_EQ(after.recording.tv, before.recording.tv);
  EXPECT_EQ(after.recording.t_disp.size(), before.recording.t_disp.size());
}

TEST(IdentificationWindowTest, TimeJumpingBackClearsTheWindow) {
  IdentificationWindow w(30.0);
  fill(&w, 100.0, 110.0);
  EXPECT_DOUBLE_EQ(w.addTidalVolume(110.0, 1.0), 0.0);
  const double jump = w.addTidalVolume(5.0, 1.0);  // a bag restarted
  EXPECT_NEAR(jump, 105.0, 1e-9);
  const WindowRecording r = w.take();
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("no tidal volume: 1 samples"), std::string::npos) << r.error;
}

TEST(IdentificationWindowTest, RefusesTooLittleOrNonFiniteData) {
  IdentificationWindow w(30.0);
  EXPECT_FALSE(w.take().ok);
  fill(&w, 0.0, 1.0);  // 8 markers < 16
  WindowRecording r = w.take();
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("too few marker samples: 8"), std::string::npos) << r.error;
  fill(&w, 1.0, 4.0);
  EXPECT_TRUE(w.take().ok);
  w.addTidalVolume(4.5, std::numeric_limits<double>::quiet_NaN());
  r = w.take();
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("not finite"), std::string::npos) << r.error;
}

TEST(IdentificationWindowTest, RejectsAnEmptyWindowLength) {
  EXPECT_THROW(IdentificationWindow(0.0), std::invalid_argument);
  EXPECT_THROW(IdentificationWindow(std::nan("")), std::invalid_argument);
}

}  // namespace
}  // namespace pedicle_drilling::core
