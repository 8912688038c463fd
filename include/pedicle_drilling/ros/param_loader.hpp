/**
 * @file param_loader.hpp
 * @brief Loading of validated nodelet parameters: a bad value is a clear error naming the
 *        parameter (never a silent default); a missing one takes the documented default.
 */
#pragma once

#include <ros/node_handle.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "pedicle_drilling/core/common/param_table.hpp"
#include "pedicle_drilling/core/common/text_parse.hpp"

namespace pedicle_drilling {

/** @brief Thrown when a parameter has the wrong type or is out of range. */
class ParameterError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/** @brief Reads private parameters of one node handle and checks types and ranges. */
class ParamLoader {
 public:
  explicit ParamLoader(const ros::NodeHandle& private_nh) : nh_(private_nh) {}

  /** @brief A double in [min, max] (inclusive unless open_min/open_max). */
  double getDouble(const std::string& name, double default_value, double min, double max,
                   bool open_min = false, bool open_max = false) const {
    double value = default_value;
    if (nh_.hasParam(name)) {
      XmlRpc::XmlRpcValue raw;
      nh_.getParam(name, raw);
      if (raw.getType() == XmlRpc::XmlRpcValue::TypeDouble) {
        value = static_cast<double>(raw);
      } else if (raw.getType() == XmlRpc::XmlRpcValue::TypeInt) {
        value = static_cast<int>(raw);
      } else {
        fail(name, "must be a number");
      }
    }
    const bool below = open_min ? !(value > min) : !(value >= min);
    const bool above = open_max ? !(value < max) : !(value <= max);
    if (!std::isfinite(value) || below || above) {
      std::ostringstream rule;
      rule << "= " << value << " is out of range " << (open_min ? "(" : "[") << min << ", " << max
           << (open_max ? ")" : "]");
      fail(name, rule.str());
    }
    return value;
  }

  /** @brief An integer in [min, max]. */
  int getInt(const std::string& name, int default_value, int min, int max) const {
    int value = default_value;
    if (nh_.hasParam(name)) {
      XmlRpc::XmlRpcValue raw;
      nh_.getParam(name, raw);
      if (raw.getType() != XmlRpc::XmlRpcValue::TypeInt) fail(name, "must be an integer");
      value = static_cast<int>(raw);
    }
    if (value < min || value > max) {
      std::ostringstream rule;
      rule << "= " << value << " is out of range [" << min << ", " << max << "]";
      fail(name, rule.str());
    }
    return value;
  }

  /** @brief A boolean. */
  bool getBool(const std::string& name, bool default_value) const {
    bool value = default_value;
    if (nh_.hasParam(name) && !nh_.getParam(name, value)) fail(name, "must be true or false");
    return value;
  }

  /** @brief A string; non-empty unless allow_empty. */
  std::string getString(const std::string& name, const std::string& default_value,
                        bool allow_empty = false) const {
    std::string value = default_value;
    if (nh_.hasParam(name) && !nh_.getParam(name, value)) fail(name, "must be a string");
    if (!allow_empty && value.empty()) fail(name, "must not be empty");
    return value;
  }

  /**
   * @brief A non-empty list of integers in [min, max], in any of its natural forms: a YAML list
   *        (`[3, 4, 5]`), one integer (`_kept_levels:=5` on the command line gives an int) or a
   *        comma-separated string (`_kept_levels:=3,4,5` gives a string).
   */
  std::vector<int> getIntList(const std::string& name, const std::vector<int>& default_value,
                              int min, int max) const {
    std::vector<int> value = default_value;
    if (nh_.hasParam(name)) {
      XmlRpc::XmlRpcValue raw;
      nh_.getParam(name, raw);
      value.clear();
      const std::string rule = "must be integers: a list [3, 4, 5], one integer or '3,4,5'";
      if (raw.getType() == XmlRpc::XmlRpcValue::TypeInt) {
        value.push_back(static_cast<int>(raw));
      } else if (raw.getType() == XmlRpc::XmlRpcValue::TypeArray) {
        for (int i = 0; i < raw.size(); ++i) {
          if (raw[i].getType() != XmlRpc::XmlRpcValue::TypeInt) fail(name, rule);
          value.push_back(static_cast<int>(raw[i]));
        }
      } else if (raw.getType() == XmlRpc::XmlRpcValue::TypeString) {
        try {
          value = core::parseIntList(static_cast<std::string>(raw), name);
        } catch (const std::exception&) {
          fail(name, rule);
        }
      } else {
        fail(name, rule);
      }
    }
    if (value.empty()) fail(name, "must not be empty");
    for (int v : value) {
      if (v < min || v > max) {
        std::ostringstream os;
        os << "has " << v << ", outside [" << min << ", " << max << "]";
        fail(name, os.str());
      }
    }
    return value;
  }

  /** @brief A list of non-empty strings (YAML list); may be empty unless !allow_empty. */
  std::vector<std::string> getStringList(const std::string& name,
                                         const std::vector<std::string>& default_value,
                                         bool allow_empty = true) const {
    std::vector<std::string> value = default_value;
    if (nh_.hasParam(name)) {
      XmlRpc::XmlRpcValue raw;
      nh_.getParam(name, raw);
      if (raw.getType() != XmlRpc::XmlRpcValue::TypeArray) fail(name, "must be a list of strings");
      value.clear();
      for (int i = 0; i < raw.size(); ++i) {
        if (raw[i].getType() != XmlRpc::XmlRpcValue::TypeString ||
            static_cast<std::string>(raw[i]).empty()) {
          fail(name, "item " + std::to_string(i) + " must be a non-empty string");
        }
        value.push_back(static_cast<std::string>(raw[i]));
      }
    }
    if (!allow_empty && value.empty()) fail(name, "must not be empty");
    return value;
  }

  /**
   * @brief The mapping `name` ({key: value}, values numbers, bools or strings) as text pairs,
   *        for a plugin's configure() (~recognizer_params, ~compensator_params); absent: empty.
   */
  std::vector<std::pair<std::string, std::string>> getTextMap(const std::string& name) const {
    std::vector<std::pair<std::string, std::string>> out;
    if (!nh_.hasParam(name)) return out;
    XmlRpc::XmlRpcValue raw;
    nh_.getParam(name, raw);
    if (raw.getType() != XmlRpc::XmlRpcValue::TypeStruct) {
      fail(name, "must be a mapping {name: value}");
    }
    for (auto& [key, value] : raw) {
      std::string text;
      switch (value.getType()) {
        case XmlRpc::XmlRpcValue::TypeInt:
          text = std::to_string(static_cast<int>(value));
          break;
        case XmlRpc::XmlRpcValue::TypeDouble: {
          std::ostringstream os;
          os.precision(17);
          os << static_cast<double>(value);
          text = os.str();
          break;
        }
        case XmlRpc::XmlRpcValue::TypeBoolean:
          text = static_cast<bool>(value) ? "true" : "false";
          break;
        case XmlRpc::XmlRpcValue::TypeString:
          text = static_cast<std::string>(value);
          break;
        default:
          fail(name + "/" + key, "must be a number, a bool or a string");
      }
      out.emplace_back(key, text);
    }
    return out;
  }

  /**
   * @brief The contents of the file whose path is `path` (the value of parameter `name`).
   * @throws ParameterError naming the parameter when it cannot be read.
   */
  std::string readFile(const std::string& name, const std::string& path) const {
    std::ifstream in(path);
    if (!in) fail(name, "= '" + path + "': the file cannot be opened");
    std::stringstream contents;
    contents << in.rdbuf();
    return contents.str();
  }

  /**
   * @brief Every parameter declared in @p table, read into @p out (whose values are the
   *        defaults of the absent ones), each checked against its declaration: type, range,
   *        choices. Then the struct's own validate() (the checks between fields) runs, its error
   *        becoming a ParameterError under this node's namespace. A retired name set on the
   *        server (core::ParamTable::retired()) is refused, naming what replaced it.
   * @throws ParameterError naming the first bad parameter.
   */
  template <class T>
  void load(const core::ParamTable<T>& table, T* out) const {
    read(table, out);
    check(*out);
  }

  /**
   * @brief load()'s first step: every declared parameter read into @p out, each checked against
   *        its declaration, a retired name refused; not the struct's validate() (check()).
   * @throws ParameterError naming the first bad parameter.
   */
  template <class T>
  void read(const core::ParamTable<T>& table, T* out) const {
    for (const auto& [name, why] : table.retiredNames()) {
      if (has(name)) fail(name, "is retired: " + why);
    }
    for (const auto& e : table.entries()) loadEntry(e, out);
  }

  /**
   * @brief load()'s second step: @p v's validate() (the checks between fields), its error a
   *        ParameterError naming the parameter its message starts with, under this namespace.
   */
  template <class T>
  void check(const T& v) const {
    try {
      v.validate();
    } catch (const std::invalid_argument& err) {
      throw ParameterError("parameter '" + nh_.resolveName(firstWord(err.what())) +
                           "': " + err.what());
    }
  }

  /**
   * @brief Fails on any key under the namespace @p ns that @p table does not declare (a typo
   *        would otherwise be a silent default), or when @p ns is set but is not a mapping.
   */
  template <class T>
  void rejectUndeclared(const core::ParamTable<T>& table, const std::string& ns) const {
    if (!nh_.hasParam(ns)) return;
    XmlRpc::XmlRpcValue raw;
    nh_.getParam(ns, raw);
    if (raw.getType() != XmlRpc::XmlRpcValue::TypeStruct) fail(ns, "must be a mapping");
    rejectUndeclaredIn(table, raw, ns + "/");
  }

  /** @brief True when the parameter is set. */
  bool has(const std::string& name) const { return nh_.hasParam(name); }

  /** @brief Throws ParameterError naming the fully resolved parameter. */
  [[noreturn]] void fail(const std::string& name, const std::string& what) const {
    throw ParameterError("parameter '" + nh_.resolveName(name) + "' " + what);
  }

 private:
  template <class T>
  void rejectUndeclaredIn(const core::ParamTable<T>& table, XmlRpc::XmlRpcValue& raw,
                          const std::string& prefix) const {
    for (auto it = raw.begin(); it != raw.end(); ++it) {
      const std::string name = prefix + it->first;
      if (it->second.getType() == XmlRpc::XmlRpcValue::TypeStruct && table.find(name) == nullptr) {
        rejectUndeclaredIn(table, it->second, name + "/");
        continue;
      }
      if (table.find(name) != nullptr) continue;
      std::string known;
      for (const auto& e : table.entries()) {
        if (e.info.name.rfind(prefix, 0) == 0) {
          known += (known.empty() ? "" : ", ") + e.info.name.substr(prefix.size());
        }
      }
      fail(name, "is not a known parameter (known under " + prefix + ": " + known + ")");
    }
  }

  template <class T>
  void loadEntry(const typename core::ParamTable<T>::Entry& e, T* out) const {
    const core::ParamInfo& info = e.info;
    const core::Range& r = info.range;
    switch (info.kind) {
      case core::ParamKind::kDouble:
        e.set_number(
            *out, getDouble(info.name, e.get_number(*out), r.min, r.max, r.open_min, r.open_max));
        break;
      case core::ParamKind::kInt:
        e.set_number(*out, getInt(info.name, static_cast<int>(e.get_number(*out)),
                                  intBound(r, true), intBound(r, false)));
        break;
      case core::ParamKind::kBool:
        e.set_number(*out, getBool(info.name, e.get_number(*out) != 0.0) ? 1.0 : 0.0);
        break;
      case core::ParamKind::kText: {
        const std::string value = getString(info.name, e.get_text(*out), info.allow_empty);
        try {
          e.set_text(*out, value);
        } catch (const std::invalid_argument& err) {
          fail(info.name, std::string(": ") + err.what());
        }
        break;
      }
      case core::ParamKind::kIntList:
        e.set_ints(*out,
                   getIntList(info.name, e.get_ints(*out), intBound(r, true), intBound(r, false)));
        break;
      case core::ParamKind::kTextList:
        e.set_texts(*out, getStringList(info.name, e.get_texts(*out)));
        break;
      case core::ParamKind::kTextMap:
        if (has(info.name)) e.set_map(*out, getTextMap(info.name));
        break;
    }
  }

  static int intBound(const core::Range& r, bool lower) {
    const double b = lower ? (r.open_min ? std::floor(r.min) + 1.0 : std::ceil(r.min))
                           : (r.open_max ? std::ceil(r.max) - 1.0 : std::floor(r.max));
    const double limit = lower ? -2147483648.0 : 2147483647.0;
    return static_cast<int>(lower ? std::max(b, limit) : std::min(b, limit));
  }

  static std::string firstWord(const std::string& text) {
    const std::size_t end = text.find_first_of(" :=");
    return text.substr(0, end);
  }

  ros::NodeHandle nh_;
};

}  // namespace pedicle_drilling
