/**
 * @file motion_model_io.cpp
 * @brief Per-patient model YAML writer (atomic) and reader (yaml-cpp; see motion_model_io.hpp).
 */
#include "pedicle_drilling/core/breathing/motion_model_io.hpp"

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include "pedicle_drilling/core/common/atomic_file.hpp"

namespace pedicle_drilling::core {

namespace {

std::string formatDouble(double v) {
  std::ostringstream os;
  os.precision(17);
  os << v;
  return os.str();
}

/** A YAML double-quoted string: '"' and '\' escaped, control characters as YAML escapes. */
std::string quote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (c == '\n') {
      out += "\\n";
    } else if (c == '\t') {
      out += "\\t";
    } else if (u < 0x20 || u == 0x7f) {
      char escape[8];
      std::snprintf(escape, sizeof escape, "\\x%02x", u);
      out += escape;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

bool isAsciiAlnum(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9');
}

/**
 * A meta key as the writer writes it, plain: letters, digits, '_' and, after the first
 * character, '-' and '.'; never a word YAML reads as null. Such a key reads back unchanged.
 */
bool isMetaKey(const std::string& k) {
  if (k.empty() || !(isAsciiAlnum(k[0]) || k[0] == '_')) return false;
  if (k == "null" || k == "Null" || k == "NULL") return false;
  for (char c : k) {
    if (!(isAsciiAlnum(c) || c == '_' || c == '-' || c == '.')) return false;
  }
  return true;
}

/** How a value that is not what its key needs is shown in a message. */
std::string shown(const YAML::Node& n) {
  if (n.IsScalar() && n.Tag() == "!") return "\"" + n.Scalar() + "\" (quoted: a string)";
  if (n.IsScalar() && n.Tag() != "?") return "'" + n.Scalar() + "' (tagged " + n.Tag() + ")";
  if (n.IsScalar()) return "'" + n.Scalar() + "'";
  if (n.IsSequence()) return "a list";
  if (n.IsMap()) return "a mapping";
  return "empty";
}

/** The file's origin, for messages: "<source>:<line>: ...". */
struct Source {
  std::string name;

  [[noreturn]] void fail(const std::string& what) const {
    throw ModelFileError(name + ": " + what);
  }

  [[noreturn]] void fail(const YAML::Node& at, const std::string& what) const {
    const YAML::Mark mark = at.Mark();
    if (mark.is_null()) fail(what);
    throw ModelFileError(name + ":" + std::to_string(mark.line + 1) + ": " + what);
  }
};

/**
 * A mapping of the file, its keys checked when read (strings, each once). Keys it does not know
 * are ignored (units, equivalent_stiffness: informative only). A value's error names its key's
 * path and line.
 */
class Mapping {
 public:
  /**
   * @param node a mapping, or null (an empty document, `key:` alone): no entries.
   * @param path the mapping's key path ("axes.ap"), "" for the document.
   */
  Mapping(const YAML::Node& node, std::string path, const Source& source)
      : path_(std::move(path)), source_(source) {
    if (node.IsNull()) return;
    if (!node.IsMap()) source_.fail(node, "the file must be a mapping of keys to values");
    for (const auto& kv : node) {
      if (!kv.first.IsScalar()) source_.fail(kv.first, "a key must be a string");
      const std::string key = kv.first.Scalar();
      if (!entries_.emplace(key, Entry{kv.first, kv.second}).second) {
        source_.fail(kv.first, "duplicate key '" + pathOf(key) + "'");
      }
      order_.push_back(key);
    }
  }

  bool has(const std::string& key) const { return entries_.count(key) > 0; }

  /** The key path of @p key in this mapping ("axes.ap.q1"). */
  std::string pathOf(const std::string& key) const {
    return path_.empty() ? key : path_ + "." + key;
  }

  /** @throws ModelFileError "<source>:<line>: <message>", at @p key's line. */
  [[noreturn]] void failAt(const std::string& key, const std::string& message) const {
    source_.fail(entry(key).key, message);
  }

  /** @throws ModelFileError "<source>:<line>: key '<path>' <what>", at @p key's line. */
  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    failAt(key, "key '" + pathOf(key) + "' " + what);
  }

  /** @throws ModelFileError naming the key's path when it is missing. */
  const YAML::Node& get(const std::string& key) const { return entry(key).value; }

  Mapping mapping(const std::string& key) const {
    const YAML::Node& n = get(key);
    if (!n.IsMap() && !n.IsNull())
      fail(key, "must be a mapping of keys to values, not " + shown(n));
    return Mapping(n, pathOf(key), source_);
  }

  std::string text(const std::string& key) const {
    const YAML::Node& n = get(key);
    if (!n.IsScalar()) fail(key, "must be a string, not " + shown(n));
    return n.Scalar();
  }

  double number(const std::string& key) const {
    const YAML::Node& n = get(key);
    double v = 0.0;
    // Plain scalars only: a quoted "0.5" is a string (YAML's tag "?" marks a plain scalar).
    if (!n.IsScalar() || n.Tag() != "?" || !YAML::convert<double>::decode(n, v) ||
        !std::isfinite(v)) {
      fail(key, "is not a finite number: " + shown(n));
    }
    return v;
  }

  int integer(const std::string& key) const { return toInt(get(key), key); }

  std::vector<int> integers(const std::string& key) const {
    const YAML::Node& n = get(key);
    if (!n.IsSequence()) fail(key, "must be a list like [3, 4, 5], not " + shown(n));
    std::vector<int> out;
    for (const YAML::Node& item : n) out.push_back(toInt(item, key));
    return out;
  }

  /** The keys in file order. */
  const std::vector<std::string>& keys() const { return order_; }

 private:
  struct Entry {
    YAML::Node key;
    YAML::Node value;
  };

  const Entry& entry(const std::string& key) const {
    const auto it = entries_.find(key);
    if (it == entries_.end()) source_.fail("missing key '" + pathOf(key) + "'");
    return it->second;
  }

  /**
   * A decimal integer within +-1e6. yaml-cpp's own integer conversion is not used: it reads a
   * leading 0 as octal ("010" = 8) and "0x" as hexadecimal, and the file is decimal.
   */
  int toInt(const YAML::Node& n, const std::string& key) const {
    const std::string& s = n.Scalar();
    long v = 0;
    const char* first = s.data() + (!s.empty() && s[0] == '+' ? 1 : 0);
    const char* last = s.data() + s.size();
    const auto [end, error] = std::from_chars(first, last, v);
    if (!n.IsScalar() || n.Tag() != "?" || first == last || error != std::errc() || end != last ||
        v < -1000000 || v > 1000000) {
      fail(key, "has a bad integer " + shown(n));
    }
    return static_cast<int>(v);
  }

  std::map<std::string, Entry> entries_;
  std::vector<std::string> order_;
  std::string path_;
  const Source& source_;
};

/**
 * A hint for a YAML error at 0-based line @p last: the first line up to it indented with a tab
 * (yaml-cpp reports most of them as a map without end); "" if none.
 */
std::string tabHint(const std::string& text, int last) {
  std::istringstream in(text);
  std::string line;
  for (int i = 0; i <= last && std::getline(in, line); ++i) {
    const size_t content = line.find_first_not_of(" \t");
    if (content != std::string::npos && line.find('\t') < content) {
      return " (line " + std::to_string(i + 1) +
             " is indented with a tab character; YAML "
             "indents with spaces)";
    }
  }
  return "";
}

/** Records where each document of a YAML stream starts; nothing else. */
class DocumentStarts : public YAML::EventHandler {
 public:
  std::vector<YAML::Mark> marks;  ///< one per document, in order

  void OnDocumentStart(const YAML::Mark& mark) override { marks.push_back(mark); }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t,
                const std::string&) override {}
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {}
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {}
  void OnMapEnd() override {}
};

/**
 * Where a second document starts, or text yaml-cpp cannot begin a document with (its mark
 * repeats: the parser never consumes it), if any. Driven here for two documents at most:
 * YAML::LoadAll of yaml-cpp 0.7 loops forever, allocating, on such text (a ',' at the top
 * level: jbeder/yaml-cpp issue 1040), and YAML::Load ignores what follows the first document.
 */
std::optional<YAML::Mark> afterFirstDocument(const std::string& text) {
  std::istringstream in(text);
  YAML::Parser parser(in);
  DocumentStarts starts;
  while (starts.marks.size() < 2 && parser.HandleNextDocument(starts)) {
  }
  if (starts.marks.size() < 2) return std::nullopt;
  return starts.marks[1];
}

/** The single YAML document of @p text (null for an empty text: no entries). */
YAML::Node loadDocument(const std::string& text, const Source& source) {
  const auto where = [&source](const YAML::Mark& m) {
    return source.name + ":" + std::to_string(m.line + 1) + ":" + std::to_string(m.column + 1);
  };
  try {
    if (const std::optional<YAML::Mark> after = afterFirstDocument(text)) {
      throw ModelFileError(where(*after) +
                           ": more than one YAML document, or text after the document");
    }
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    if (e.mark.is_null()) source.fail("not YAML: " + e.msg);
    throw ModelFileError(where(e.mark) + ": not YAML: " + e.msg + tabHint(text, e.mark.line));
  }
}

/** Files written before the key existed are version 1; a newer one is refused, never guessed. */
void checkFormatVersion(const Mapping& root) {
  if (!root.has("format_version")) return;
  const int version = root.integer("format_version");
  if (version != kModelFormatVersion) {
    root.failAt("format_version", "format_version " + std::to_string(version) +
                                      " is not supported (this build reads format_version " +
                                      std::to_string(kModelFormatVersion) + ")");
  }
}

/** The DWT provenance: a level >= 0 and distinct kept detail levels within [1, level]. */
void readDenoising(const Mapping& m, AxisModelRecord* r) {
  r->wavelet = m.text("wavelet");
  r->level = m.integer("level");
  if (r->level < 0) m.fail("level", "is negative");
  r->kept_levels = m.integers("kept_levels");
  std::set<int> seen;
  for (int k : r->kept_levels) {
    if (k < 1 || k > r->level || !seen.insert(k).second) {
      m.fail("kept_levels", "must list distinct detail levels in [1, " + std::to_string(r->level) +
                                "] (level), not " + std::to_string(k) +
                                (seen.count(k) ? " twice" : ""));
    }
  }
}

AxisModelRecord readAxis(const Mapping& m, Axis a) {
  AxisModelRecord r;
  const YAML::Node& kind = m.get("model");
  if (!kind.IsScalar() || !parseModelKind(kind.Scalar(), &r.model.kind)) {
    m.failAt("model", "unknown model kind " + shown(kind) + " for axis " + axisName(a) +
                          " (expected linear or hysteresis)");
  }
  r.model.q1 = m.number("q1");
  r.model.q0 = m.number("q0");
  r.model.q2 = r.model.kind == ModelKind::kHysteresis ? m.number("q2") : 0.0;
  r.r2 = m.number("r2");
  r.rmse = m.has("rmse") ? m.number("rmse") : 0.0;
  readDenoising(m, &r);
  return r;
}

/** The optional free key/value strings, in file order. */
std::vector<std::pair<std::string, std::string>> readMeta(const Mapping& root) {
  std::vector<std::pair<std::string, std::string>> out;
  if (!root.has("meta")) return out;
  const Mapping meta = root.mapping("meta");
  for (const std::string& key : meta.keys()) {
    if (!isMetaKey(key)) {
      meta.failAt(key, "invalid meta key '" + key + "' (letters, digits, '_', '-' and '.' only)");
    }
    out.emplace_back(key, meta.text(key));
  }
  return out;
}

}  // namespace
MotionModel PatientModel::motionModel() const {
  MotionModel m;
  for (size_t i = 0; i < axes.size(); ++i) m.axes[i] = axes[i].model;
  return m;
}

std::string modelToYaml(const PatientModel& model) {
  std::ostringstream os;
  os << "# pedicle_drilling vertebra displacement model, d = q1*Tv + q2*dTv/dt + q0\n";
  os << "format_version: " << kModelFormatVersion << "\n";
  os << "patient_id: " << quote(model.patient_id) << "\n";
  os << "units: " << quote("Tv ml, dTv/dt ml/s, d mm; q1 mm/ml, q2 mm*s/ml, q0 mm") << "\n";
  os << "axes:\n";
  for (Axis a : kAllAxes) {
    const AxisModelRecord& r = model.axes[static_cast<int>(a)];
    // The reader refuses what is not finite: never write a file that cannot be read back.
    for (const auto& [name, value] : {std::pair<const char*, double>{"q1", r.model.q1},
                                      {"q2", r.model.q2},
                                      {"q0", r.model.q0},
                                      {"r2", r.r2},
                                      {"rmse", r.rmse}}) {
      if (!std::isfinite(value)) {
        throw ModelFileError("model of axis " + axisName(a) + ": " + name + " is " +
                             formatDouble(value) +
                             ", not a finite number (the fit failed on this input)");
      }
    }
    os << "  " << axisName(a) << ":\n";
    os << "    model: " << modelKindName(r.model.kind) << "\n";
    os << "    q1: " << formatDouble(r.model.q1) << "\n";
    os << "    q2: " << formatDouble(r.model.kind == ModelKind::kLinear ? 0.0 : r.model.q2) << "\n";
    os << "    q0: " << formatDouble(r.model.q0) << "\n";
    os << "    r2: " << formatDouble(r.r2) << "\n";
    os << "    rmse: " << formatDouble(r.rmse) << "\n";
    const std::string stiffness_label = equivalentStiffnessLabel(a);
    if (!stiffness_label.empty()) {
      // Informative only (derived from q1 and Table I), not read back.
      os << "    equivalent_stiffness: " << formatDouble(equivalentStiffness(a, r.model.q1))
         << "  # " << stiffness_label << "\n";
    }
    os << "    wavelet: " << quote(r.wavelet) << "\n";
    os << "    level: " << r.level << "\n";
    os << "    kept_levels: [";
    for (size_t i = 0; i < r.kept_levels.size(); ++i) {
      os << (i ? ", " : "") << r.kept_levels[i];
    }
    os << "]\n";
  }
  if (!model.meta.empty()) {
    os << "meta:\n";
    std::set<std::string> written;  // the reader refuses a repeated key
    for (const auto& kv : model.meta) {
      if (!isMetaKey(kv.first) || !written.insert(kv.first).second) {
        throw ModelFileError("modelToYaml: invalid or repeated meta key '" + kv.first + "'");
      }
      os << "  " << kv.first << ": " << quote(kv.second) << "\n";
    }
  }
  return os.str();
}

PatientModel modelFromYaml(const std::string& text, const std::string& source) {
  const Source origin{source};
  const Mapping root(loadDocument(text, origin), "", origin);
  checkFormatVersion(root);
  PatientModel m;
  m.patient_id = root.text("patient_id");
  const Mapping axes = root.mapping("axes");
  for (Axis a : kAllAxes) m.axes[static_cast<int>(a)] = readAxis(axes.mapping(axisName(a)), a);
  m.meta = readMeta(root);
  return m;
}

void writeModelYaml(const PatientModel& model, const std::string& path) {
  const std::string text = modelToYaml(model);  // checks the model before anything is created
  try {
    writeFileAtomically(path, text);
  } catch (const FileWriteError& e) {
    throw ModelFileError(e.what());
  }
}

PatientModel readModelYaml(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ModelFileError(path + ": cannot open file");
  std::ostringstream ss;
  ss << in.rdbuf();
  return modelFromYaml(ss.str(), path);
}

}  // namespace pedicle_drilling::core
