/**
 * @file motion_model_io.cpp
 * @brief Per-patient model YAML writer (atomic) and reader (see motion_model_io.hpp).
 */
#include "pedicle_drilling/core/breathing/motion_model_io.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
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

std::string quote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out += c;
  }
  return out + "\"";
}

std::string trim(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  const size_t e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

struct Entry {
  std::string value;
  bool quoted = false;
  int line = 0;
};

/** Removes a trailing comment that starts with '#' outside double quotes. */
std::string stripComment(const std::string& s) {
  bool in_quotes = false;
  for (size_t i = 0; i < s.size(); ++i) {
    if (in_quotes && s[i] == '\\') {
      ++i;
      continue;
    }
    if (s[i] == '"') in_quotes = !in_quotes;
    if (!in_quotes && s[i] == '#' && (i == 0 || s[i - 1] == ' ')) return s.substr(0, i);
  }
  return s;
}

std::string unquote(const std::string& v, const std::string& where, bool* quoted) {
  *quoted = false;
  if (v.empty() || v.front() != '"') return v;
  if (v.size() < 2 || v.back() != '"') throw ModelFileError(where + ": unterminated string");
  std::string out;
  for (size_t i = 1; i + 1 < v.size(); ++i) {
    if (v[i] == '\\') {
      if (i + 2 >= v.size()) throw ModelFileError(where + ": bad escape in string");
      ++i;
      out += v[i] == 'n' ? '\n' : v[i];
    } else if (v[i] == '"') {
      throw ModelFileError(where + ": unescaped quote in string");
    } else {
      out += v[i];
    }
  }
  *quoted = true;
  return out;
}

/** Parses the block-mapping subset into path -> entry ("axes.ap.q1"), keeping file order. */
std::vector<std::pair<std::string, Entry>> parseFlat(const std::string& text,
                                                     const std::string& source) {
  struct Level {
    int indent;
    std::string key;
    int child_indent;
  };
  std::vector<Level> stack;
  int root_child_indent = -1;
  std::vector<std::pair<std::string, Entry>> out;
  std::map<std::string, int> seen;
  std::istringstream in(text);
  std::string raw;
  int line_no = 0;
  while (std::getline(in, raw)) {
    ++line_no;
    const std::string where = source + ":" + std::to_string(line_no);
    if (raw.find('\t') != std::string::npos) throw ModelFileError(where + ": tab character");
    const std::string line = stripComment(raw);
    if (trim(line).empty()) continue;
    const int indent = static_cast<int>(line.find_first_not_of(' '));
    const std::string content = trim(line);
    const size_t colon = content.find(':');
    if (colon == std::string::npos || colon == 0) {
      throw ModelFileError(where + ": expected 'key: value'");
    }
    const std::string key = trim(content.substr(0, colon));
    const std::string value = trim(content.substr(colon + 1));
    if (key.find_first_of(" \"[]{}") != std::string::npos) {
      throw ModelFileError(where + ": invalid key '" + key + "'");
    }
    while (!stack.empty() && stack.back().indent >= indent) stack.pop_back();
    int& child_indent = stack.empty() ? root_child_indent : stack.back().child_indent;
    if (child_indent < 0) child_indent = indent;
    if (child_indent != indent) throw ModelFileError(where + ": inconsistent indentation");
    std::string path;
    for (const Level& l : stack) path += l.key + ".";
    path += key;
    if (seen.count(path)) throw ModelFileError(where + ": duplicate key '" + path + "'");
    seen[path] = line_no;
    if (value.empty()) {
      stack.push_back({indent, key, -1});
      continue;
    }
    Entry e;
    e.value = unquote(value, where, &e.quoted);
    e.line = line_no;
    out.emplace_back(path, e);
  }
  return out;
}

class Fields {
 public:
  Fields(std::vector<std::pair<std::string, Entry>> flat, std::string source)
      : flat_(std::move(flat)), source_(std::move(source)) {
    for (size_t i = 0; i < flat_.size(); ++i) index_[flat_[i].first] = i;
  }

  const Entry& get(const std::string& key) const {
    auto it = index_.find(key);
    if (it == index_.end()) throw ModelFileError(source_ + ": missing key '" + key + "'");
    return flat_[it->second].second;
  }
  bool has(const std::string& key) const { return index_.count(key) > 0; }

  double getDouble(const std::string& key) const {
    const Entry& e = get(key);
    char* end = nullptr;
    const double v = std::strtod(e.value.c_str(), &end);
    if (e.quoted || e.value.empty() || *end != '\0' || !std::isfinite(v)) {
      throw ModelFileError(where(e) + ": key '" + key + "' is not a finite number: '" + e.value +
                           "'");
    }
    return v;
  }

  int getInt(const std::string& key) const {
    const Entry& e = get(key);
    return parseInt(e.value, e, key);
  }

  std::vector<int> getIntList(const std::string& key) const {
    const Entry& e = get(key);
    const std::string& v = e.value;
    if (e.quoted || v.size() < 2 || v.front() != '[' || v.back() != ']') {
      throw ModelFileError(where(e) + ": key '" + key + "' must be a list like [3, 4, 5]");
    }
    std::vector<int> out;
    const std::string inner = trim(v.substr(1, v.size() - 2));
    if (inner.empty()) return out;
    std::istringstream is(inner);
    std::string item;
    while (std::getline(is, item, ',')) out.push_back(parseInt(trim(item), e, key));
    if (inner.back() == ',') throw ModelFileError(where(e) + ": trailing comma in '" + key + "'");
    return out;
  }

  const std::vector<std::pair<std::string, Entry>>& flat() const { return flat_; }

 private:
  std::string where(const Entry& e) const { return source_ + ":" + std::to_string(e.line); }

  int parseInt(const std::string& s, const Entry& e, const std::string& key) const {
    char* end = nullptr;
    errno = 0;
    const long v = std::strtol(s.c_str(), &end, 10);
    if (e.quoted || s.empty() || *end != '\0' || errno != 0 || v < -1000000 || v > 1000000) {
      throw ModelFileError(where(e) + ": key '" + key + "' has a bad integer '" + s + "'");
    }
    return static_cast<int>(v);
  }

  std::vector<std::pair<std::string, Entry>> flat_;
  std::map<std::string, size_t> index_;
  std::string source_;
};

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
    for (const auto& kv : model.meta) {
      if (kv.first.empty() || kv.first.find_first_of(" :#\"[]{}\n\t") != std::string::npos) {
        throw ModelFileError("modelToYaml: invalid meta key '" + kv.first + "'");
      }
      os << "  " << kv.first << ": " << quote(kv.second) << "\n";
    }
  }
  return os.str();
}

PatientModel modelFromYaml(const std::string& text, const std::string& source) {
  const Fields f(parseFlat(text, source), source);
  // Files written before the key existed are version 1; a newer one is refused, never guessed.
  if (f.has("format_version")) {
    const int version = f.getInt("format_version");
    if (version != kModelFormatVersion) {
      throw ModelFileError(source + ": format_version " + std::to_string(version) +
                           " is not supported (this build reads format_version " +
                           std::to_string(kModelFormatVersion) + ")");
    }
  }
  PatientModel m;
  m.patient_id = f.get("patient_id").value;
  for (Axis a : kAllAxes) {
    const std::string p = "axes." + axisName(a) + ".";
    AxisModelRecord& r = m.axes[static_cast<int>(a)];
    const Entry& kind = f.get(p + "model");
    if (!parseModelKind(kind.value, &r.model.kind)) {
      throw ModelFileError(source + ":" + std::to_string(kind.line) + ": unknown model kind '" +
                           kind.value + "' for axis " + axisName(a) +
                           " (expected linear or hysteresis)");
    }
    r.model.q1 = f.getDouble(p + "q1");
    r.model.q0 = f.getDouble(p + "q0");
    r.model.q2 = 0.0;
    if (r.model.kind == ModelKind::kHysteresis) r.model.q2 = f.getDouble(p + "q2");
    r.r2 = f.getDouble(p + "r2");
    r.rmse = f.has(p + "rmse") ? f.getDouble(p + "rmse") : 0.0;
    r.wavelet = f.get(p + "wavelet").value;
    r.level = f.getInt(p + "level");
    r.kept_levels = f.getIntList(p + "kept_levels");
  }
  for (const auto& kv : f.flat()) {
    if (kv.first.rfind("meta.", 0) == 0) m.meta.emplace_back(kv.first.substr(5), kv.second.value);
  }
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
