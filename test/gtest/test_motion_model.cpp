// Tests of the displacement models (Eq. 6-9), the stiffness groups, and the model YAML file.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>

#include <dirent.h>
#include <grp.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "pedicle_drilling/core/breathing/motion_model.hpp"
#include "pedicle_drilling/core/breathing/motion_model_io.hpp"

namespace pedicle_drilling::core {
namespace {

TEST(MotionModel, LinearPredictIgnoresRate) {
  AxisModel m;
  m.kind = ModelKind::kLinear;
  m.q1 = 0.01;
  m.q2 = 5.0;  // must be ignored by the linear model
  m.q0 = -0.5;
  EXPECT_DOUBLE_EQ(m.predict(400.0, 300.0), 0.01 * 400.0 - 0.5);
}

TEST(MotionModel, HysteresisPredictUsesRate) {
  AxisModel m;
  m.kind = ModelKind::kHysteresis;
  m.q1 = 0.01;
  m.q2 = -0.002;
  m.q0 = 0.3;
  EXPECT_DOUBLE_EQ(m.predict(250.0, 400.0), 2.5 - 0.8 + 0.3);
  EXPECT_NEAR(m.lagSeconds(), 0.2, 1e-15);
}

TEST(MotionModel, MotionModelPredictPerAxis) {
  MotionModel mm;
  mm.axis(Axis::kSI).q1 = 0.004;
  mm.axis(Axis::kSI).q0 = 1.0;
  mm.axis(Axis::kLR).q1 = -0.002;
  EXPECT_DOUBLE_EQ(mm.predict(Axis::kSI, 100.0, 0.0), 1.4);
  EXPECT_DOUBLE_EQ(mm.predict(Axis::kLR, 100.0, 0.0), -0.2);
  EXPECT_DOUBLE_EQ(mm.predict(Axis::kAP, 100.0, 0.0), 0.0);
}

TEST(MotionModel, CoefficientOrderAndSize) {
  AxisModel lin;
  lin.setCoefficients({2.0, 3.0});
  EXPECT_EQ(lin.q1, 2.0);
  EXPECT_EQ(lin.q0, 3.0);
  EXPECT_EQ(lin.q2, 0.0);
  EXPECT_THROW(lin.setCoefficients({1.0, 2.0, 3.0}), std::invalid_argument);
  AxisModel hys;
  hys.kind = ModelKind::kHysteresis;
  hys.setCoefficients({2.0, 4.0, 3.0});
  EXPECT_EQ(hys.q1, 2.0);
  EXPECT_EQ(hys.q2, 4.0);
  EXPECT_EQ(hys.q0, 3.0);
  EXPECT_EQ(hys.coefficients(), (std::vector<double>{2.0, 4.0, 3.0}));
  EXPECT_THROW(hys.setCoefficients({1.0}), std::invalid_argument);
  EXPECT_EQ(numCoefficients(ModelKind::kLinear), 2);
  EXPECT_EQ(numCoefficients(ModelKind::kHysteresis), 3);
}

TEST(MotionModel, NamesParse) {
  ModelKind k = ModelKind::kLinear;
  EXPECT_TRUE(parseModelKind("hysteresis", &k));
  EXPECT_EQ(k, ModelKind::kHysteresis);
  EXPECT_TRUE(parseModelKind("linear", &k));
  EXPECT_EQ(k, ModelKind::kLinear);
  EXPECT_FALSE(parseModelKind("quadratic", &k));
  EXPECT_EQ(modelKindName(ModelKind::kHysteresis), "hysteresis");
  Axis a = Axis::kAP;
  EXPECT_TRUE(parseAxis("LR", &a));
  EXPECT_EQ(a, Axis::kLR);
  EXPECT_FALSE(parseAxis("xy", &a));
  EXPECT_EQ(axisName(Axis::kSI), "si");
}

TEST(SpineGeometry, DefaultsAreTableOneWithEqualDiscs) {
  const SpineGeometry g;
  EXPECT_DOUBLE_EQ(g.centrum_length_mm, 23.10);
  EXPECT_NEAR(g.disc_length_mm, 5.49, 1e-12);  // (5.31 + 5.67) / 2
  EXPECT_NEAR(g.totalDiscLengthMm(), 10.98, 1e-12);
}

TEST(SpineGeometry, BeamFactorEqualsEq7AtXEqualsM) {
  // Evaluate Eq. 7 literally (per unit q/EI) at x = m with the paper's c1 and c2 = 0.
  const SpineGeometry g;
  const double l = g.centrum_length_mm;
  const double m = g.disc_length_mm;
  const double x = m;
  const double c1 = m * m * m / 3.0 + l * m * m / 4.0;
  const double v = std::pow(x, 4) / 24.0 - (l + 2.0 * m) / 12.0 * std::pow(x, 3) + c1 * x;
  EXPECT_NEAR(g.apBeamFactorMm4(), v, 1e-9 * v);
  EXPECT_GT(v, 0.0);
}

TEST(Stiffness, ApRecoversBendingGroupFromForwardModel) {
  // Forward model Eq. 8 with assumed physical values, in N and mm.
  const SpineGeometry g;
  const double ei = 2.5e5;     // N mm^2
  const double v0 = 3.0e6;     // mm^3 (3 L)
  const double p0 = 0.101325;  // N/mm^2 (1 atm)
  const double bw = 250.0;     // mm
  const double m = g.disc_length_mm;
  const double l = g.centrum_length_mm;
  const double q1_mm_per_mm3 =
      (5.0 * std::pow(m, 4) / (24.0 * ei) + l * std::pow(m, 3) / (6.0 * ei)) * p0 * bw / v0;
  const double q1_mm_per_ml = q1_mm_per_mm3 * 1000.0;
  const double expected = ei * v0 / (p0 * bw);
  EXPECT_NEAR(apEquivalentBendingStiffness(q1_mm_per_ml, g), expected, 1e-12 * expected);
  EXPECT_THROW(apEquivalentBendingStiffness(0.0, g), std::invalid_argument);
}

TEST(Stiffness, SiRecoversAxialGroupsFromForwardModel) {
  const SpineGeometry g;
  const double e = 0.0758;     // N/mm^2, 75.8 kPa disc modulus (paper Sec. III-B)
  const double a = 1500.0;     // mm^2
  const double v0 = 3.0e6;     // mm^3
  const double p0 = 0.101325;  // N/mm^2
  const double s = 4.0e4;      // mm^2
  const double big_l = 2.0 * g.disc_length_mm;
  const double q1_mm_per_ml = 2.0 * p0 * s * big_l / (e * a * v0) * 1000.0;
  const double group = e * a * v0 / (2.0 * p0 * s * big_l);
  EXPECT_NEAR(siEquivalentAxialStiffness(q1_mm_per_ml), group, 1e-12 * group);
  const double rigidity = e * a * v0 / (p0 * s);
  EXPECT_NEAR(siAxialRigidityGroup(q1_mm_per_ml, g), rigidity, 1e-12 * rigidity);
  EXPECT_THROW(siEquivalentAxialStiffness(0.0), std::invalid_argument);
}

// ------------------------------------------------------------------------------ model YAML

PatientModel sampleModel() {
  PatientModel pm;
  pm.patient_id = "vol \"7\" # odd\\id";
  AxisModelRecord& ap = pm.axes[0];
  ap.model.kind = ModelKind::kLinear;
  ap.model.q1 = 0.1;
  ap.model.q0 = -1.0 / 3.0;
  ap.r2 = 0.9712345678901234;
  ap.rmse = 0.123;
  ap.wavelet = "coif4";
  ap.level = 6;
  ap.kept_levels = {3, 4, 5};
  AxisModelRecord& si = pm.axes[1];
  si.model.kind = ModelKind::kHysteresis;
  si.model.q1 = 4.123456789012345e-3;
  si.model.q2 = -7.5e-4;
  si.model.q0 = 1e-300;
  si.r2 = 0.5;
  si.wavelet = "bior2.8";
  si.level = 5;
  si.kept_levels = {2, 3};
  AxisModelRecord& lr = pm.axes[2];
  lr.model.kind = ModelKind::kLinear;
  lr.model.q1 = -2e-3;
  lr.model.q0 = 12345.678;
  lr.r2 = -0.25;
  lr.wavelet = "none";
  lr.level = 0;
  lr.kept_levels = {};
  pm.meta = {{"breaths_per_min", "20"}, {"note", "lag 0.15 s: truth"}};
  return pm;
}

void expectSameModel(const PatientModel& a, const PatientModel& b) {
  EXPECT_EQ(a.patient_id, b.patient_id);
  for (int i = 0; i < 3; ++i) {
    SCOPED_TRACE("axis " + std::to_string(i));
    EXPECT_EQ(a.axes[i].model.kind, b.axes[i].model.kind);
    EXPECT_EQ(a.axes[i].model.q1, b.axes[i].model.q1);  // exact: 17 digits
    EXPECT_EQ(a.axes[i].model.q2, b.axes[i].model.q2);
    EXPECT_EQ(a.axes[i].model.q0, b.axes[i].model.q0);
    EXPECT_EQ(a.axes[i].r2, b.axes[i].r2);
    EXPECT_EQ(a.axes[i].rmse, b.axes[i].rmse);
    EXPECT_EQ(a.axes[i].wavelet, b.axes[i].wavelet);
    EXPECT_EQ(a.axes[i].level, b.axes[i].level);
    EXPECT_EQ(a.axes[i].kept_levels, b.axes[i].kept_levels);
  }
  EXPECT_EQ(a.meta, b.meta);
}

std::string makeTempDir() {
  char tmpl[] = "/tmp/pd_motion_model_XXXXXX";
  const char* d = mkdtemp(tmpl);
  EXPECT_NE(d, nullptr);
  return d ? std::string(d) : std::string("/tmp");
}

std::vector<std::string> listDir(const std::string& dir) {
  std::vector<std::string> names;
  DIR* d = opendir(dir.c_str());
  if (!d) return names;
  while (dirent* e = readdir(d)) {
    const std::string n = e->d_name;
    if (n != "." && n != "..") names.push_back(n);
  }
  closedir(d);
  return names;
}

bool exists(const std::string& path) {
  struct stat st;
  return stat(path.c_str(), &st) == 0;
}

TEST(ModelYaml, StringRoundTripIsExact) {
  const PatientModel pm = sampleModel();
  const std::string text = modelToYaml(pm);
  expectSameModel(pm, modelFromYaml(text));
  // The motion model carries kinds and coefficients.
  const MotionModel mm = modelFromYaml(text).motionModel();
  EXPECT_EQ(mm.axis(Axis::kSI).kind, ModelKind::kHysteresis);
  EXPECT_EQ(mm.axis(Axis::kSI).q2, -7.5e-4);
}

TEST(ModelYaml, FileRoundTripAndOverwriteLeaveNoTemporaries) {
  const std::string dir = makeTempDir();
  const std::string path = dir + "/model.yaml";
  PatientModel pm = sampleModel();
  writeModelYaml(pm, path);
  expectSameModel(pm, readModelYaml(path));
  pm.axes[0].model.q1 = 0.25;
  writeModelYaml(pm, path);  // overwrite
  expectSameModel(pm, readModelYaml(path));
  EXPECT_EQ(listDir(dir), std::vector<std::string>{"model.yaml"});
  std::remove(path.c_str());
  rmdir(dir.c_str());
}

TEST(ModelYaml, ReadsHandWrittenFileWithComments) {
  const std::string text =
      "# comment\n"
      "patient_id: p1   # trailing comment\n"
      "axes:\n"
      "  ap:\n"
      "    model: hysteresis\n"
      "    q1: 0.01\n"
      "    q2: -0.0015\n"
      "    q0: 0.3\n"
      "    r2: 0.97\n"
      "    wavelet: coif4\n"
      "    level: 6\n"
      "    kept_levels: [3,4, 5]\n"
      "  si:\n"
      "    model: linear\n"
      "    q1: 0.004\n"
      "    q0: -0.2\n"
      "    r2: 0.94\n"
      "    wavelet: \"bior2.8\"\n"
      "    level: 6\n"
      "    kept_levels: [3, 4, 5]\n"
      "  lr:\n"
      "    model: linear\n"
      "    q1: 0.002\n"
      "    q0: 0.1\n"
      "    r2: 0.8\n"
      "    wavelet: coif5\n"
      "    level: 6\n"
      "    kept_levels: []\n";
  const PatientModel pm = modelFromYaml(text);
  EXPECT_EQ(pm.patient_id, "p1");
  EXPECT_EQ(pm.axes[0].model.kind, ModelKind::kHysteresis);
  EXPECT_DOUBLE_EQ(pm.axes[0].model.q2, -0.0015);
  EXPECT_EQ(pm.axes[0].kept_levels, (std::vector<int>{3, 4, 5}));
  EXPECT_EQ(pm.axes[1].wavelet, "bior2.8");
  EXPECT_EQ(pm.axes[1].model.q2, 0.0);
  EXPECT_TRUE(pm.axes[2].kept_levels.empty());
}

void expectYamlError(const std::string& text, const std::string& fragment) {
  try {
    modelFromYaml(text, "m.yaml");
    ADD_FAILURE() << "no error; expected one mentioning '" << fragment << "'";
  } catch (const ModelFileError& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

std::string replaceFirst(std::string s, const std::string& from, const std::string& to) {
  const size_t p = s.find(from);
  EXPECT_NE(p, std::string::npos) << from;
  if (p != std::string::npos) s.replace(p, from.size(), to);
  return s;
}

/** The 1-based line of the first @p fragment in @p text. */
int lineOf(const std::string& text, const std::string& fragment) {
  const size_t p = text.find(fragment);
  EXPECT_NE(p, std::string::npos) << fragment;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + p, '\n'));
}

TEST(ModelYaml, ReaderRejectsBadFiles) {
  const std::string good = modelToYaml(sampleModel());
  ASSERT_NO_THROW(modelFromYaml(good));
  expectYamlError(replaceFirst(good, "    r2: 0.5\n", ""), "axes.si.r2");
  expectYamlError(replaceFirst(good, "model: hysteresis", "model: cubic"), "cubic");
  expectYamlError(replaceFirst(good, "q1: 0.10000000000000001", "q1: abc"), "axes.ap.q1");
  expectYamlError(replaceFirst(good, "q1: 0.10000000000000001", "q1: nan"), "axes.ap.q1");
  expectYamlError(
      replaceFirst(good, "    level: 6", "\tlevel: 6"),
      "line " + std::to_string(lineOf(good, "    level: 6")) + " is indented with a tab character");
  // Not YAML: yaml-cpp's message, with the file and the line.
  expectYamlError(replaceFirst(good, "    level: 6", "     level: 6"),
                  "m.yaml:" + std::to_string(lineOf(good, "    level: 6")) + ":");
  expectYamlError(replaceFirst(good, "kept_levels: [3, 4, 5]", "kept_levels: 3"), "kept_levels");
  expectYamlError(good + "patient_id: \"again\"\n", "duplicate");
  expectYamlError("", "patient_id");
  EXPECT_THROW(readModelYaml("/nonexistent/dir/model.yaml"), ModelFileError);
  // Wrong version: refused naming it; truncated: the missing key named.
  EXPECT_NE(good.find("format_version: 1\n"), std::string::npos);
  expectYamlError(replaceFirst(good, "format_version: 1", "format_version: 2"),
                  "format_version 2 is not supported");
  expectYamlError(replaceFirst(good, "format_version: 1", "format_version: one"), "format_version");
  ASSERT_NO_THROW(modelFromYaml(replaceFirst(good, "format_version: 1\n", "")));  // older file
  expectYamlError(good.substr(0, good.find("  lr:")), "axes.lr");
}

TEST(ModelYaml, ReaderNamesTheFileTheLineAndTheKey) {
  const std::string good = modelToYaml(sampleModel());
  const std::string where = "m.yaml:" + std::to_string(lineOf(good, "q1: 0.1")) + ": ";
  expectYamlError(replaceFirst(good, "q1: 0.10000000000000001", "q1: abc"),
                  where + "key 'axes.ap.q1' is not a finite number: 'abc'");
  // Missing keys: the document's, an axis's, a whole axis.
  expectYamlError(replaceFirst(good, "patient_id:", "patient:"),
                  "m.yaml: missing key 'patient_id'");
  expectYamlError(replaceFirst(good, "    q0: -0.33333333333333331\n", ""),
                  "m.yaml: missing key 'axes.ap.q0'");
  expectYamlError(replaceFirst(good, "  si:", "  xx:"), "missing key 'axes.si'");
  // Not a number: text, a quoted number (a string), a list.
  expectYamlError(replaceFirst(good, "q1: 0.10000000000000001", "q1: \"0.1\""),
                  "key 'axes.ap.q1' is not a finite number: \"0.1\" (quoted: a string)");
  expectYamlError(replaceFirst(good, "q1: 0.10000000000000001", "q1: !!float 0.1"), "axes.ap.q1");
  expectYamlError(replaceFirst(good, "q1: 0.10000000000000001", "q1: [0.1]"),
                  "key 'axes.ap.q1' is not a finite number: a list");
  expectYamlError(replaceFirst(good, "r2: 0.5", "r2: 0.5 0.6"), "axes.si.r2");
  // Not finite, in YAML's spellings too.
  for (const char* bad : {"nan", ".nan", ".NaN", ".inf", "-.inf", "1e999"}) {
    SCOPED_TRACE(bad);
    expectYamlError(replaceFirst(good, "q0: 1e-300", std::string("q0: ") + bad),
                    "key 'axes.si.q0' is not a finite number");
  }
  // Not a decimal integer (yaml-cpp alone would read 0x6 as 6 and 010 as 8).
  expectYamlError(replaceFirst(good, "level: 6", "level: 0x6"), "axes.ap.level");
  expectYamlError(replaceFirst(good, "level: 6", "level: 6.0"), "axes.ap.level");
  expectYamlError(replaceFirst(good, "level: 6", "level: \"6\""), "axes.ap.level");
  expectYamlError(replaceFirst(good, "format_version: 1", "format_version: 1.0"), "format_version");
}

TEST(ModelYaml, ReaderRejectsBadLists) {
  const std::string good = modelToYaml(sampleModel());
  const std::string key = "key 'axes.ap.kept_levels'";
  // More kept detail levels than the decomposition has, one listed twice, one out of range.
  expectYamlError(replaceFirst(good, "[3, 4, 5]", "[1, 2, 3, 4, 5, 6, 7]"), key);
  expectYamlError(replaceFirst(good, "[3, 4, 5]", "[3, 4, 4]"), key);
  expectYamlError(replaceFirst(good, "[3, 4, 5]", "[0, 4]"), key);
  expectYamlError(replaceFirst(good, "[2, 3]", "[2, 3, 6]"), "key 'axes.si.kept_levels'");
  expectYamlError(replaceFirst(good, "    level: 0", "    level: -1"), "key 'axes.lr.level'");
  // Not a list of integers.
  expectYamlError(replaceFirst(good, "[3, 4, 5]", "[3, x]"), key);
  expectYamlError(replaceFirst(good, "[3, 4, 5]", "[3, [4]]"), key);
  expectYamlError(replaceFirst(good, "[3, 4, 5]", "{3: 4}"), key + " must be a list");
  expectYamlError(replaceFirst(good, "kept_levels: [3, 4, 5]", "kept_levels:"), key);
  // A block list is YAML too.
  const PatientModel block =
      modelFromYaml(replaceFirst(good, " [3, 4, 5]", "\n      - 3\n      - 5"));
  EXPECT_EQ(block.axes[0].kept_levels, (std::vector<int>{3, 5}));
}

TEST(ModelYaml, ReaderRejectsBadStructure) {
  const std::string good = modelToYaml(sampleModel());
  expectYamlError(good + "---\npatient_id: \"second\"\n",
                  "more than one YAML document, or text after the document");
  // yaml-cpp's LoadAll loops forever on these (a ',' where a document starts: fuzzing).
  expectYamlError(
      ",\xff"
      "e%",
      "m.yaml:1:1: more than one YAML document, or text after");
  expectYamlError(good + ",\n", "m.yaml:");
  expectYamlError("[1] x\n", "m.yaml:1:5: more than one YAML document, or text after");
  expectYamlError("just text\n", "must be a mapping");
  expectYamlError(replaceFirst(good, "    r2: 0.5\n", "    r2: 0.5\n    r2: 0.5\n"),
                  "duplicate key 'axes.si.r2'");
  expectYamlError(replaceFirst(good, "  si:\n", "  si: 3\n  ignored:\n"),
                  "key 'axes.si' must be a mapping");
  expectYamlError(replaceFirst(good, "patient_id: ", "patient_id: [a]\nx: "),
                  "key 'patient_id' must be a string");
  expectYamlError(good + "meta:\n  a: \"1\"\n", "duplicate key 'meta'");
  expectYamlError(replaceFirst(good, "  note:", "  \"a b\":"), "invalid meta key 'a b'");
  expectYamlError(replaceFirst(good, "  note:", "  null:"), "a key must be a string");
  expectYamlError(replaceFirst(good, "  note: ", "  note:\n    deeper: "), "meta.note");
  expectYamlError(replaceFirst(good, "model: linear", "model: [linear]"), "unknown model kind");
  // Truncated inside a value.
  expectYamlError(good.substr(0, good.find("wavelet: \"coif4\"") + 12), "m.yaml:");
}

TEST(ModelYaml, WriterRefusesMetaKeysTheReaderWouldRefuse) {
  PatientModel pm = sampleModel();
  for (const std::string bad : {"", "a b", "x:y", "&anchor", "-dash", "null", "tab\t"}) {
    SCOPED_TRACE(bad);
    pm.meta = {{bad, "v"}};
    EXPECT_THROW(modelToYaml(pm), ModelFileError);
  }
  pm.meta = {{"seed", "1"}, {"seed", "2"}};
  EXPECT_THROW(modelToYaml(pm), ModelFileError);
  pm.meta = {{"lag_s_ap", "0.08"}, {"x.y-z", "2"}, {"_1", ""}};
  expectSameModel(pm, modelFromYaml(modelToYaml(pm)));
}

TEST(ModelYaml, AnyStringRoundTrips) {
  PatientModel pm = sampleModel();
  const char id[] = "q\"b\\s\nn\tt\rr\x01\x7f\0z \xc3\xa9 # : [x] ";  // \0: a NUL
  pm.patient_id = std::string(id, sizeof id - 1);
  pm.axes[1].wavelet = "  spaces  ";
  pm.meta = {{"empty", ""}, {"yes", "true"}, {"number", "1e5"}, {"tilde", "~"}};
  expectSameModel(pm, modelFromYaml(modelToYaml(pm)));
}

TEST(ModelYaml, AtomicWriteIntoMissingDirectoryLeavesNothing) {
  const std::string path = "/tmp/pd_no_such_dir_for_sure_9731/model.yaml";
  EXPECT_THROW(writeModelYaml(sampleModel(), path), ModelFileError);
  EXPECT_FALSE(exists(path));
}

TEST(ModelYaml, FailedRenameRemovesTemporaryAndKeepsDestination) {
  // The destination is a non-empty directory: the temporary is written, rename() fails, and
  // the writer must clean up; this failure path works even when running as root.
  const std::string dir = makeTempDir();
  const std::string dest = dir + "/model.yaml";
  ASSERT_EQ(mkdir(dest.c_str(), 0755), 0);
  const std::string inside = dest + "/keep";
  { std::ofstream(inside) << "x"; }
  EXPECT_THROW(writeModelYaml(sampleModel(), dest), ModelFileError);
  EXPECT_EQ(listDir(dir), std::vector<std::string>{"model.yaml"});
  EXPECT_TRUE(exists(inside));
  std::remove(inside.c_str());
  rmdir(dest.c_str());
  rmdir(dir.c_str());
}

/**
 * Runs `body` in a child process that, when this test runs as root (as `make test` does), first
 * drops to the unprivileged user `nobody` (uid/gid 65534): root ignores directory permissions,
 * so the failure the test needs could not happen otherwise. @return the child's exit status.
 */
int runUnprivileged(const std::function<int()>& body) {
  const pid_t pid = fork();
  if (pid == 0) {
    const bool root = geteuid() == 0;
    if (root && (setgroups(0, nullptr) != 0 || setgid(65534) != 0 || setuid(65534) != 0)) {
      _exit(90);
    }
    _exit(body());
  }
  int status = 0;
  if (pid < 0 || waitpid(pid, &status, 0) != pid) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(ModelYaml, AtomicWriteIntoReadOnlyDirectoryLeavesOldFile) {
  const std::string dir = makeTempDir();
  const std::string path = dir + "/model.yaml";
  PatientModel old = sampleModel();
  writeModelYaml(old, path);
  ASSERT_EQ(chmod(dir.c_str(), 0555), 0);  // readable and searchable by all, writable by none
  PatientModel changed = old;
  changed.axes[0].model.q1 = 99.0;
  const int status = runUnprivileged([&]() {
    try {
      writeModelYaml(changed, path);
    } catch (const ModelFileError&) {
      return 0;  // refused, as it must be
    } catch (...) {
      return 3;  // another exception type than the documented one
    }
    return 1;  // written
  });
  chmod(dir.c_str(), 0755);
  EXPECT_EQ(status, 0) << "90: could not drop privileges; 1: the write succeeded; 3: wrong error";
  expectSameModel(old, readModelYaml(path));
  EXPECT_EQ(listDir(dir), std::vector<std::string>{"model.yaml"});
  std::remove(path.c_str());
  rmdir(dir.c_str());
}

}  // namespace
}  // namespace pedicle_drilling::core
