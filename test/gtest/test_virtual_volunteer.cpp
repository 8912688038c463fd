// Tests of the virtual-volunteer generator and the recording CSV files.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numeric>
#include <string>
#include <type_traits>
#include <vector>

#include <stdlib.h>
#include <unistd.h>

#include "pedicle_drilling/core/breathing/identification.hpp"
#include "pedicle_drilling/core/breathing/virtual_volunteer.hpp"

namespace pedicle_drilling::core {
namespace {

double mean(const std::vector<double>& x) {
  return std::accumulate(x.begin(), x.end(), 0.0) / static_cast<double>(x.size());
}

double stddev(const std::vector<double>& x) {
  const double m = mean(x);
  double s = 0.0;
  for (double v : x) s += (v - m) * (v - m);
  return std::sqrt(s / static_cast<double>(x.size()));
}

TEST(Volunteer, DeterministicPerSeedAndDistinctAcrossIds) {
  const VolunteerData a = generateVolunteer(defaultVolunteer(3));
  const VolunteerData b = generateVolunteer(defaultVolunteer(3));
  EXPECT_EQ(a.recording.tv, b.recording.tv);
  EXPECT_EQ(a.recording.lr, b.recording.lr);
  const VolunteerData c = generateVolunteer(defaultVolunteer(4));
  EXPECT_NE(a.recording.ap, c.recording.ap);
  EXPECT_THROW(defaultVolunteer(0), std::invalid_argument);
  EXPECT_THROW(defaultVolunteer(6), std::invalid_argument);
}

TEST(Volunteer, SamplingRatesAndDuration) {
  const VolunteerData v = generateVolunteer(defaultVolunteer(1));
  ASSERT_EQ(v.recording.t_tv.size(), 30u * 64u);
  ASSERT_EQ(v.recording.t_disp.size(), 30u * 8u);
  EXPECT_EQ(v.recording.ap.size(), v.recording.t_disp.size());
  for (size_t i = 1; i < v.recording.t_tv.size(); ++i) {
    ASSERT_NEAR(v.recording.t_tv[i] - v.recording.t_tv[i - 1], 1.0 / 64.0, 1e-12);
  }
  for (size_t i = 1; i < v.recording.t_disp.size(); ++i) {
    ASSERT_NEAR(v.recording.t_disp[i] - v.recording.t_disp[i - 1], 1.0 / 8.0, 1e-12);
  }
}

TEST(Volunteer, BreathingRateDepthAndNoVolumeDrift) {
  for (int id = 1; id <= 5; ++id) {
    const VolunteerParams p = defaultVolunteer(id);
    const VolunteerData v = generateVolunteer(p);
    // About 20 breaths/min (paper Sec. III-A): 30 s hold 7-13 breaths.
    EXPECT_GE(v.num_breaths, 7) << id;
    EXPECT_LE(v.num_breaths, 13) << id;
    EXPECT_NEAR(p.breaths_per_min, 20.0, 2.5);
    EXPECT_NEAR(countBreaths(v.clean.tv), v.num_breaths, 1) << id;
    EXPECT_NEAR(countBreaths(v.recording.tv), v.num_breaths, 1) << id;
    // Volume stays between the end-expiratory level 0 and about 1.5 x 500 ml.
    const auto mm = std::minmax_element(v.clean.tv.begin(), v.clean.tv.end());
    EXPECT_GE(*mm.first, -1e-9) << id;
    EXPECT_LT(*mm.first, 20.0) << id;  // returns to the end-expiratory level
    EXPECT_GT(*mm.second, 400.0) << id;
    EXPECT_LT(*mm.second, 800.0) << id;
  }
}

TEST(Volunteer, AnalyticFlowMatchesFiniteDifferences) {
  const VolunteerData v = generateVolunteer(defaultVolunteer(2).noiseFree());
  const std::vector<double> fd = timeDerivative(v.clean.t_tv, v.clean.tv);
  double max_err = 0.0, max_flow = 0.0;
  for (size_t i = 1; i + 1 < fd.size(); ++i) {
    max_err = std::max(max_err, std::abs(fd[i] - v.dtv_dt[i]));
    max_flow = std::max(max_flow, std::abs(v.dtv_dt[i]));
  }
  EXPECT_GT(max_flow, 300.0);  // resting peak flows of several hundred ml/s
  EXPECT_LT(max_err, 0.02 * max_flow);
}

TEST(Volunteer, AmplitudesAboutFiveTwoOneMillimetres) {
  for (int id = 1; id <= 5; ++id) {
    const VolunteerParams p = defaultVolunteer(id);
    const double vt = p.tidal_volume_ml;
    EXPECT_NEAR(std::abs(p.truth.axis(Axis::kAP).q1) * vt, 5.0, 1.0) << id;
    EXPECT_NEAR(std::abs(p.truth.axis(Axis::kSI).q1) * vt, 2.0, 0.5) << id;
    EXPECT_NEAR(std::abs(p.truth.axis(Axis::kLR).q1) * vt, 1.0, 0.3) << id;
    for (Axis a : kAllAxes) EXPECT_EQ(p.truth.axis(a).kind, ModelKind::kHysteresis);
  }
}

TEST(Volunteer, CleanDisplacementIsTheTruthModelAndLagsVolume) {
  const VolunteerParams p = defaultVolunteer(4);
  const VolunteerData v = generateVolunteer(p);
  const AxisModel& ap = p.truth.axis(Axis::kAP);
  EXPECT_GT(ap.lagSeconds(), 0.0);
  double inhale = 0.0, exhale = 0.0;
  int n_in = 0, n_ex = 0;
  for (size_t i = 0; i < v.clean.t_disp.size(); ++i) {
    const double tv = v.clean.tv[i * 8];  // 64 Hz sample at the same instant
    EXPECT_NEAR(v.clean.ap[i], ap.predict(tv, v.dtv_dt_disp[i]), 1e-9);
    const double above_line = v.clean.ap[i] - (ap.q1 * tv + ap.q0);
    if (v.dtv_dt_disp[i] > 50.0) {
      inhale += above_line;
      ++n_in;
    } else if (v.dtv_dt_disp[i] < -50.0) {
      exhale += above_line;
      ++n_ex;
    }
  }
  // Lagging displacement: below the static line while inhaling, above while exhaling (a loop).
  EXPECT_LT(inhale / n_in, -0.1);
  EXPECT_GT(exhale / n_ex, 0.1);
}

TEST(Volunteer, TrackerNoiseMatchesPolarisSpec) {
  VolunteerParams p = defaultVolunteer(3);
  p.drift_mm = {{0.0, 0.0, 0.0}};
  p.movements_per_min = 0.0;
  p.duration_s = 300.0;  // long for a tight estimate
  const VolunteerData v = generateVolunteer(p);
  std::vector<double> e;
  for (size_t i = 0; i < v.recording.si.size(); ++i) e.push_back(v.recording.si[i] - v.clean.si[i]);
  // 0.25 mm RMS 3-D per marker, relative to a reference marker: 0.25 * sqrt(2/3) per axis.
  EXPECT_NEAR(stddev(e), 0.25 * std::sqrt(2.0 / 3.0), 0.02);
  EXPECT_NEAR(mean(e), 0.0, 0.02);
}

TEST(Volunteer, DriftAndMovementsAreSmall) {
  for (int id = 1; id <= 5; ++id) {
    VolunteerParams p = defaultVolunteer(id);
    p.tracker_noise_mm = {{0.0, 0.0, 0.0}};
    const VolunteerData v = generateVolunteer(p);
    for (size_t i = 0; i < v.recording.ap.size(); ++i) {
      ASSERT_LT(std::abs(v.recording.ap[i] - v.clean.ap[i]), 1.5) << id;
      ASSERT_LT(std::abs(v.recording.lr[i] - v.clean.lr[i]), 1.5) << id;
    }
  }
}

TEST(Volunteer, LeftRightIsTheNoisiestAxisForEveryDefaultVolunteer) {
  for (int id = 1; id <= 5; ++id) {
    const VolunteerData v = generateVolunteer(defaultVolunteer(id));
    const PairedSamples ps = pairAtMarkerTimes(v.recording);
    double r2[3];
    for (Axis a : kAllAxes) {
      r2[static_cast<int>(a)] = fitOls(ModelKind::kLinear, axisSamples(ps, a)).r2;
    }
    EXPECT_LT(r2[2], r2[1]) << id;
    EXPECT_LT(r2[2], r2[0]) << id;
  }
}

TEST(CountBreaths, SinesAndFlatSignals) {
  std::vector<double> tv;
  for (int i = 0; i < 8 * 9; ++i) tv.push_back(250.0 * (1.0 - std::cos(2.0 * M_PI * i / 24.0)));
  EXPECT_EQ(countBreaths(tv), 3);
  EXPECT_EQ(countBreaths(std::vector<double>(100, 5.0)), 0);
  EXPECT_EQ(countBreaths({}), 0);
}

// ------------------------------------------------------------------------------ CSV files

class CsvTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char tmpl[] = "/tmp/pd_vv_XXXXXX";
    ASSERT_NE(mkdtemp(tmpl), nullptr);
    dir_ = tmpl;
  }
  void TearDown() override {
    for (const std::string& f : files_) std::remove(f.c_str());
    rmdir(dir_.c_str());
  }
  std::string path(const std::string& name) {
    files_.push_back(dir_ + "/" + name);
    return files_.back();
  }
  std::string write(const std::string& name, const std::string& text) {
    const std::string p = path(name);
    std::ofstream(p) << text;
    return p;
  }
  std::string dir_;
  std::vector<std::string> files_;
};

TEST_F(CsvTest, RoundTripIsExact) {
  const VolunteerData v = generateVolunteer(defaultVolunteer(5));
  const std::string csv = path("rec.csv");
  path("rec_tv64.csv");
  writeRecordingCsv(v.recording, csv);
  EXPECT_EQ(tv64PathFor(csv), dir_ + "/rec_tv64.csv");
  const PairedSamples expected = pairAtMarkerTimes(v.recording);
  const PairedSamples got = readRecordingCsv(csv);
  EXPECT_EQ(got.t, expected.t);
  EXPECT_EQ(got.tv, expected.tv);
  EXPECT_EQ(got.ap, expected.ap);
  EXPECT_EQ(got.si, expected.si);
  EXPECT_EQ(got.lr, expected.lr);
  // The marker times are every 8th flow sample, so the paired tv is the raw 64 Hz value.
  EXPECT_EQ(got.tv[10], v.recording.tv[80]);
  const auto tv64 = readTv64Csv(tv64PathFor(csv));
  EXPECT_EQ(tv64[0], v.recording.t_tv);
  EXPECT_EQ(tv64[1], v.recording.tv);
}

std::string breathingCsv(double seconds, const std::string& header = "t,tv,ap,si,lr") {
  std::string s = header + "\n";
  char line[200];
  for (int i = 0; i < static_cast<int>(seconds * 8); ++i) {
    const double t = i / 8.0;
    const double tv = 250.0 * (1.0 - std::cos(2.0 * M_PI * t / 3.0));
    std::snprintf(line, sizeof(line), "%.3f,%.3f,%.4f,%.4f,%.4f\n", t, tv, 0.01 * tv, 0.004 * tv,
                  0.002 * tv);
    s += line;
  }
  return s;
}

template <typename E>
void expectReadError(const std::string& file, const std::string& fragment) {
  try {
    readRecordingCsv(file);
    ADD_FAILURE() << "no error; expected one mentioning '" << fragment << "'";
  } catch (const E& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type: " << e.what();
  }
}

std::string replaceLine(const std::string& csv, int data_row, const std::string& row) {
  std::vector<std::string> lines;
  size_t start = 0;
  while (start < csv.size()) {
    const size_t end = csv.find('\n', start);
    lines.push_back(csv.substr(start, end - start));
    start = end + 1;
  }
  lines[static_cast<size_t>(data_row)] = row;
  std::string out;
  for (const std::string& l : lines) out += l + "\n";
  return out;
}

TEST_F(CsvTest, ValidFileReadsAndIsARuntimeError) {
  const PairedSamples p = readRecordingCsv(write("ok.csv", breathingCsv(10.0)));
  EXPECT_EQ(p.t.size(), 80u);
  // Columns in another order with an extra column are fine.
  std::string reordered = "quality,lr,si,ap,tv,t\n";
  for (size_t i = 0; i < p.t.size(); ++i) {
    reordered += "1," + std::to_string(p.lr[i]) + "," + std::to_string(p.si[i]) + "," +
                 std::to_string(p.ap[i]) + "," + std::to_string(p.tv[i]) + "," +
                 std::to_string(p.t[i]) + "\n";
  }
  const PairedSamples q = readRecordingCsv(write("order.csv", reordered));
  ASSERT_EQ(q.t.size(), 80u);
  EXPECT_NEAR(q.t[7], p.t[7], 1e-6);
  EXPECT_NEAR(q.ap[7], p.ap[7], 1e-6);
  EXPECT_NEAR(q.lr[7], p.lr[7], 1e-6);
  static_assert(std::is_base_of<std::runtime_error, RecordingFormatError>::value, "");
}

TEST_F(CsvTest, EveryReaderError) {
  const std::string good = breathingCsv(10.0);
  expectReadError<MissingColumnError>(write("nosi.csv", breathingCsv(10.0, "t,tv,ap,xx,lr")),
                                      "'si'");
  expectReadError<MissingColumnError>(write("empty.csv", ""), "header");
  expectReadError<MissingColumnError>(dir_ + "/absent.csv", "cannot open");
  expectReadError<NonFiniteValueError>(write("nan.csv", replaceLine(good, 5, "0.5,1,nan,1,1")),
                                       "'ap'");
  expectReadError<NonFiniteValueError>(write("inf.csv", replaceLine(good, 5, "0.5,inf,1,1,1")),
                                       "'tv'");
  expectReadError<NonIncreasingTimeError>(write("back.csv", replaceLine(good, 6, "0.2,1,1,1,1")),
                                          "not strictly increasing");
  expectReadError<NonIncreasingTimeError>(write("same.csv", replaceLine(good, 6, "0.5,1,1,1,1")),
                                          "not strictly increasing");
  expectReadError<MalformedRowError>(write("short.csv", replaceLine(good, 4, "0.375,1,1")),
                                     "fields");
  expectReadError<MalformedRowError>(write("text.csv", replaceLine(good, 4, "0.375,1,x,1,1")),
                                     "not a number");
  expectReadError<TooFewBreathsError>(write("one.csv", breathingCsv(3.5)), "two breaths");
  expectReadError<TooFewBreathsError>(write("flat.csv", "t,tv,ap,si,lr\n0,1,1,1,1\n1,1,1,1,1\n"),
                                      "two breaths");
}

}  // namespace
}  // namespace pedicle_drilling::core
