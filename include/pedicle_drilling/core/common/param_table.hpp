/**
 * @file param_table.hpp
 * @brief Parameters declared once: each options struct of the core lists its fields with name,
 *        kind, range and unit in one ParamTable. The same table validates the struct (the core's
 *        validate()), sets a field from text (plugin settings, command lines), loads it from the
 *        ROS parameter server (ros/param_loader.hpp) and documents it (the `param_docs` tool,
 *        against which a test checks doc/nodes.md's parameter tables). No ROS type.
 */
#pragma once

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace pedicle_drilling {
namespace core {

/** @brief Interval of the allowed values of a numeric parameter; NaN is never allowed. */
struct Range {
  double min = -std::numeric_limits<double>::infinity();  ///< Lower bound.
  double max = std::numeric_limits<double>::infinity();   ///< Upper bound.
  bool open_min = false;                                  ///< Lower bound excluded.
  bool open_max = false;                                  ///< Upper bound excluded.

  /** @brief [lo, hi]. */
  static Range closed(double lo, double hi) { return {lo, hi, false, false}; }
  /** @brief (lo, hi]. */
  static Range aboveUpTo(double lo, double hi) { return {lo, hi, true, false}; }
  /** @brief [lo, hi). */
  static Range fromBelow(double lo, double hi) { return {lo, hi, false, true}; }
  /** @brief (lo, hi). */
  static Range open(double lo, double hi) { return {lo, hi, true, true}; }

  /** @brief True when @p v is a number inside the interval. */
  bool contains(double v) const {
    if (std::isnan(v)) return false;
    const bool above_min = open_min ? v > min : v >= min;
    const bool below_max = open_max ? v < max : v <= max;
    return above_min && below_max;
  }

  /** @brief The interval as text, e.g. "(0, 0.1]" (bounds with up to 6 significant digits). */
  std::string text() const {
    return (open_min ? "(" : "[") + format(min) + ", " + format(max) + (open_max ? ")" : "]");
  }

  /** @brief A number as the tables show it (%g: "0.0012", "1e+06", "inf"). */
  static std::string format(double v) {
    char buf[64];
    std::snprintf(buf, sizeof(buf), "%.10g", v);
    return buf;
  }
};

/** @brief What a parameter holds. */
enum class ParamKind {
  kDouble,    ///< A floating-point number in a Range.
  kInt,       ///< An integer in a Range.
  kBool,      ///< true or false.
  kText,      ///< A string: free, one of a list of choices, or parsed by the struct.
  kIntList,   ///< A non-empty list of integers, each in a Range.
  kTextList,  ///< A list of non-empty strings.
  kTextMap,   ///< A mapping {name: value} kept as text pairs (a plugin's own parameters).
};

/** @brief Name-value pairs as text (a plugin's settings). */
using TextPairs = std::vector<std::pair<std::string, std::string>>;

/** @brief The name of a kind as the tables of doc/nodes.md write it ("double", "int", ...). */
inline const char* kindName(ParamKind kind) {
  switch (kind) {
    case ParamKind::kDouble:
      return "double";
    case ParamKind::kInt:
      return "int";
    case ParamKind::kBool:
      return "bool";
    case ParamKind::kText:
      return "string";
    case ParamKind::kIntList:
      return "integers";
    case ParamKind::kTextList:
      return "string list";
    case ParamKind::kTextMap:
      return "mapping";
  }
  return "?";
}

/** @brief One declared parameter, independent of the struct that holds it. */
struct ParamInfo {
  std::string name;                     ///< Name relative to its node or tool (e.g. "window_s").
  ParamKind kind = ParamKind::kDouble;  ///< What it holds.
  Range range;                          ///< Numeric kinds (an int list: each item).
  std::string unit;                     ///< Unit of a number ("m", "N", "" when none).
  std::vector<std::string> choices;     ///< A text parameter's allowed values (empty: any).
  std::string form;                     ///< A parsed text parameter's form (e.g. "a:b").
  bool allow_empty = false;             ///< A text parameter may be "".
  std::string default_text;             ///< The default value as text (filled by describe()).

  /** @brief The allowed values as one phrase: "(0, 0.1] m", "one of: a, b", "a:b", "any". */
  std::string rule() const {
    switch (kind) {
      case ParamKind::kDouble:
      case ParamKind::kInt:
      case ParamKind::kIntList:
        return range.text() + (unit.empty() ? "" : " " + unit);
      case ParamKind::kBool:
        return "true or false";
      case ParamKind::kTextList:
        return "list of names";
      case ParamKind::kTextMap:
        return "{name: value}";
      case ParamKind::kText: {
        if (!form.empty()) return form;
        if (choices.empty()) return allow_empty ? "any text" : "any non-empty text";
        std::string list;
        for (const std::string& c : choices) list += (list.empty() ? "" : ", ") + c;
        return "one of: " + list;
      }
    }
    return "";
  }
};

/**
 * @brief The declaration of every parameter of options struct T, in the order documented.
 *        Names may carry a prefix ("specimen/c1") when a sub-struct is included.
 */
template <class T>
class ParamTable {
 public:
  /** @brief One parameter: its description and how to read and write it in a T. */
  struct Entry {
    ParamInfo info;                                               ///< Name, kind, range.
    std::function<double(const T&)> get_number;                   ///< kDouble, kInt, kBool.
    std::function<void(T&, double)> set_number;                   ///< kDouble, kInt, kBool.
    std::function<std::string(const T&)> get_text;                ///< Every kind (for docs).
    std::function<void(T&, const std::string&)> set_text;         ///< kText (throws on bad text).
    std::function<std::vector<int>(const T&)> get_ints;           ///< kIntList.
    std::function<void(T&, const std::vector<int>&)> set_ints;    ///< kIntList.
    std::function<std::vector<std::string>(const T&)> get_texts;  ///< kTextList.
    std::function<void(T&, const std::vector<std::string>&)> set_texts;  ///< kTextList.
    std::function<TextPairs(const T&)> get_map;                          ///< kTextMap.
    std::function<void(T&, const TextPairs&)> set_map;                   ///< kTextMap.
  };

  /** @brief A double field. */
  ParamTable& number(const std::string& name, double T::*field, Range range,
                     const std::string& unit = "") {
    Entry e = numberEntry(name, ParamKind::kDouble, range, unit);
    e.get_number = [field](const T& v) { return v.*field; };
    e.set_number = [field](T& v, double x) { v.*field = x; };
    return add(std::move(e));
  }

  /** @brief A double read and written through functions (a derived unit, a nested field). */
  ParamTable& number(const std::string& name, std::function<double(const T&)> get,
                     std::function<void(T&, double)> set, Range range,
                     const std::string& unit = "") {
    Entry e = numberEntry(name, ParamKind::kDouble, range, unit);
    e.get_number = std::move(get);
    e.set_number = std::move(set);
    return add(std::move(e));
  }

  /** @brief An int field. */
  ParamTable& integer(const std::string& name, int T::*field, Range range,
                      const std::string& unit = "") {
    Entry e = numberEntry(name, ParamKind::kInt, range, unit);
    e.get_number = [field](const T& v) { return static_cast<double>(v.*field); };
    e.set_number = [field](T& v, double x) { v.*field = static_cast<int>(x); };
    return add(std::move(e));
  }

  /** @brief An integer read and written through functions (e.g. a std::uint64_t seed). */
  ParamTable& integer(const std::string& name, std::function<double(const T&)> get,
                      std::function<void(T&, double)> set, Range range,
                      const std::string& unit = "") {
    Entry e = numberEntry(name, ParamKind::kInt, range, unit);
    e.get_number = std::move(get);
    e.set_number = std::move(set);
    return add(std::move(e));
  }

  /** @brief A bool field. */
  ParamTable& flag(const std::string& name, bool T::*field) {
    Entry e;
    e.info.name = name;
    e.info.kind = ParamKind::kBool;
    e.get_number = [field](const T& v) { return (v.*field) ? 1.0 : 0.0; };
    e.set_number = [field](T& v, double x) { v.*field = x != 0.0; };
    e.get_text = [field](const T& v) { return std::string((v.*field) ? "true" : "false"); };
    return add(std::move(e));
  }

  /** @brief A free string field (non-empty unless allow_empty). */
  ParamTable& text(const std::string& name, std::string T::*field, bool allow_empty = false) {
    Entry e;
    e.info.name = name;
    e.info.kind = ParamKind::kText;
    e.info.allow_empty = allow_empty;
    e.get_text = [field](const T& v) { return v.*field; };
    e.set_text = [field, name, allow_empty](T& v, const std::string& x) {
      if (!allow_empty && x.empty()) throw std::invalid_argument(name + " must not be empty");
      v.*field = x;
    };
    return add(std::move(e));
  }

  /**
   * @brief A text parameter with a fixed set of values or a form, stored in any type: @p get
   *        writes the field as text, @p set parses it and throws std::invalid_argument on a
   *        value it does not accept. With @p choices the value is checked against them first.
   */
  ParamTable& parsed(const std::string& name, std::vector<std::string> choices,
                     const std::string& form, std::function<std::string(const T&)> get,
                     std::function<void(T&, const std::string&)> set) {
    Entry e;
    e.info.name = name;
    e.info.kind = ParamKind::kText;
    e.info.choices = std::move(choices);
    e.info.form = form;
    e.get_text = std::move(get);
    e.set_text = [name, inner = std::move(set), allowed = e.info.choices, rule = e.info.rule()](
                     T& v, const std::string& x) {
      bool ok = allowed.empty();
      for (const std::string& c : allowed) ok = ok || c == x;
      if (!ok) throw std::invalid_argument(name + " = '" + x + "' is not " + rule);
      try {
        inner(v, x);
      } catch (const std::invalid_argument& err) {
        throw std::invalid_argument(name + " = '" + x + "': " + err.what());
      }
    };
    return add(std::move(e));
  }

  /** @brief A list of ints, each in @p item_range. */
  ParamTable& integers(const std::string& name, std::vector<int> T::*field, Range item_range) {
    Entry e = numberEntry(name, ParamKind::kIntList, item_range, "");
    e.get_ints = [field](const T& v) { return v.*field; };
    e.set_ints = [field](T& v, const std::vector<int>& x) { v.*field = x; };
    e.get_text = [field](const T& v) {
      std::string s;
      for (int i : v.*field) s += (s.empty() ? "" : ",") + std::to_string(i);
      return s;
    };
    return add(std::move(e));
  }

  /** @brief A list of non-empty names. */
  ParamTable& names(const std::string& name, std::vector<std::string> T::*field) {
    Entry e;
    e.info.name = name;
    e.info.kind = ParamKind::kTextList;
    e.get_texts = [field](const T& v) { return v.*field; };
    e.set_texts = [field](T& v, const std::vector<std::string>& x) { v.*field = x; };
    e.get_text = [field](const T& v) {
      std::string s;
      for (const std::string& x : v.*field) s += (s.empty() ? "" : ", ") + x;
      return "[" + s + "]";
    };
    return add(std::move(e));
  }

  /** @brief A mapping {name: value} kept as text (a plugin's parameters, checked by it). */
  ParamTable& pairs(const std::string& name, TextPairs T::*field) {
    Entry e;
    e.info.name = name;
    e.info.kind = ParamKind::kTextMap;
    e.get_map = [field](const T& v) { return v.*field; };
    e.set_map = [field](T& v, const TextPairs& x) { v.*field = x; };
    e.get_text = [field](const T& v) {
      std::string s;
      for (const auto& [k, x] : v.*field) s += (s.empty() ? "" : ", ") + k + ": " + x;
      return "{" + s + "}";
    };
    return add(std::move(e));
  }

  /** @brief Every parameter of @p sub, held in field @p member, with @p prefix on its names. */
  template <class U>
  ParamTable& include(const ParamTable<U>& sub, U T::*member, const std::string& prefix = "") {
    for (const auto& s : sub.entries()) {
      Entry e;
      e.info = s.info;
      e.info.name = prefix + s.info.name;
      if (s.get_number)
        e.get_number = [f = s.get_number, member](const T& v) { return f(v.*member); };
      if (s.set_number)
        e.set_number = [f = s.set_number, member](T& v, double x) { f(v.*member, x); };
      if (s.get_text) e.get_text = [f = s.get_text, member](const T& v) { return f(v.*member); };
      if (s.set_text) {
        e.set_text = [f = s.set_text, member](T& v, const std::string& x) { f(v.*member, x); };
      }
      if (s.get_ints) e.get_ints = [f = s.get_ints, member](const T& v) { return f(v.*member); };
      if (s.set_ints) {
        e.set_ints = [f = s.set_ints, member](T& v, const std::vector<int>& x) { f(v.*member, x); };
      }
      if (s.get_texts) e.get_texts = [f = s.get_texts, member](const T& v) { return f(v.*member); };
      if (s.set_texts) {
        e.set_texts = [f = s.set_texts, member](T& v, const std::vector<std::string>& x) {
          f(v.*member, x);
        };
      }
      if (s.get_map) e.get_map = [f = s.get_map, member](const T& v) { return f(v.*member); };
      if (s.set_map)
        e.set_map = [f = s.set_map, member](T& v, const TextPairs& x) { f(v.*member, x); };
      add(std::move(e));
    }
    for (const auto& [name, why] : sub.retiredNames()) retired(prefix + name, why);
    return *this;
  }

  /**
   * @brief A name no longer accepted: set() refuses it, and so does ParamLoader::load() when the
   *        parameter is on the server, with @p why (what replaced it). Not a declared parameter:
   *        not in entries(), describe() or the documents.
   */
  ParamTable& retired(const std::string& name, const std::string& why) {
    if (find(name) != nullptr || retiredWhy(name) != nullptr) {
      throw std::logic_error("parameter '" + name + "' declared twice");
    }
    retired_.emplace_back(name, why);
    return *this;
  }

  /** @brief Why @p name is retired (what replaced it), or nullptr when it is not. */
  const std::string* retiredWhy(const std::string& name) const {
    for (const auto& [n, why] : retired_) {
      if (n == name) return &why;
    }
    return nullptr;
  }

  /** @brief Every retired name with what replaced it, in order. */
  const std::vector<std::pair<std::string, std::string>>& retiredNames() const { return retired_; }

  /** @brief The declared parameters in order. */
  const std::vector<Entry>& entries() const { return entries_; }

  /** @brief The declared names in declaration order (a plugin class's parameterNames()). */
  std::vector<std::string> declaredNames() const {
    std::vector<std::string> out;
    for (const Entry& e : entries_) out.push_back(e.info.name);
    return out;
  }

  /**
   * @brief @p start with each of @p settings set from text by set(), in order: a plugin class's
   *        configure(). The checks between fields (the struct's validate()) are the caller's.
   * @throws std::invalid_argument as set() does, naming the parameter.
   */
  T withSettings(const TextPairs& settings, T start = T()) const {
    for (const auto& [name, value] : settings) set(start, name, value);
    return start;
  }

  /** @brief The entry named @p name, or nullptr. */
  const Entry* find(const std::string& name) const {
    for (const Entry& e : entries_) {
      if (e.info.name == name) return &e;
    }
    return nullptr;
  }

  /**
   * @brief Checks every numeric field against its range (and every int-list item).
   * @throws std::invalid_argument "<name> = <value> is out of range <range>" for the first.
   */
  void validate(const T& v) const {
    for (const Entry& e : entries_) {
      if (e.get_number && e.info.kind != ParamKind::kBool) {
        const double x = e.get_number(v);
        if (!e.info.range.contains(x)) throw outOfRange(e.info, Range::format(x));
      }
      if (e.get_ints) {
        const std::vector<int> items = e.get_ints(v);
        if (items.empty()) throw std::invalid_argument(e.info.name + " must not be empty");
        for (int i : items) {
          if (!e.info.range.contains(i)) throw outOfRange(e.info, std::to_string(i));
        }
      }
    }
  }

  /**
   * @brief Sets the parameter @p name of @p v from text (a number, true/false, a list "3,4,5"
   *        or the text itself), range-checked.
   * @throws std::invalid_argument naming the parameter (unknown or retired name, bad text, out
   *         of range).
   */
  void set(T& v, const std::string& name, const std::string& value) const {
    if (const std::string* why = retiredWhy(name)) {
      throw std::invalid_argument(name + " is retired: " + *why);
    }
    const Entry* e = find(name);
    if (e == nullptr) throw std::invalid_argument("unknown parameter '" + name + "'");
    switch (e->info.kind) {
      case ParamKind::kDouble:
      case ParamKind::kInt: {
        const double x = parseNumber(e->info, value);
        if (!e->info.range.contains(x)) throw outOfRange(e->info, value);
        e->set_number(v, x);
        break;
      }
      case ParamKind::kBool:
        if (value != "true" && value != "false" && value != "1" && value != "0") {
          throw std::invalid_argument(name + " = '" + value + "' is not true or false");
        }
        e->set_number(v, (value == "true" || value == "1") ? 1.0 : 0.0);
        break;
      case ParamKind::kText:
        e->set_text(v, value);
        break;
      case ParamKind::kTextList:
      case ParamKind::kTextMap:
        throw std::invalid_argument(name + " cannot be set from one text value");
      case ParamKind::kIntList: {
        std::vector<int> items;
        std::size_t start = 0;
        while (start <= value.size()) {
          const std::size_t comma = value.find(',', start);
          const std::string item =
              value.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
          ParamInfo one = e->info;
          one.kind = ParamKind::kInt;
          const double x = parseNumber(one, item);
          if (!e->info.range.contains(x)) throw outOfRange(e->info, item);
          items.push_back(static_cast<int>(x));
          if (comma == std::string::npos) break;
          start = comma + 1;
        }
        e->set_ints(v, items);
        break;
      }
    }
  }

  /** @brief The declarations with each default (taken from @p defaults) as text. */
  std::vector<ParamInfo> describe(const T& defaults) const {
    std::vector<ParamInfo> out;
    for (const Entry& e : entries_) {
      ParamInfo info = e.info;
      if (e.get_text) {
        info.default_text = e.get_text(defaults);
      } else {
        const double x = e.get_number(defaults);
        info.default_text = info.kind == ParamKind::kInt ? std::to_string(static_cast<long long>(x))
                                                         : Range::format(x);
      }
      out.push_back(std::move(info));
    }
    return out;
  }

 private:
  static Entry numberEntry(const std::string& name, ParamKind kind, Range range,
                           const std::string& unit) {
    Entry e;
    e.info.name = name;
    e.info.kind = kind;
    e.info.range = range;
    e.info.unit = unit;
    return e;
  }

  ParamTable& add(Entry e) {
    if (find(e.info.name) != nullptr) {
      throw std::logic_error("parameter '" + e.info.name + "' declared twice");
    }
    entries_.push_back(std::move(e));
    return *this;
  }

  static std::invalid_argument outOfRange(const ParamInfo& info, const std::string& value) {
    return std::invalid_argument(info.name + " = " + value + " is out of range " +
                                 info.range.text() + (info.unit.empty() ? "" : " " + info.unit));
  }

  static double parseNumber(const ParamInfo& info, const std::string& text) {
    const char* begin = text.c_str();
    char* end = nullptr;
    const double x = std::strtod(begin, &end);
    const bool whole = !text.empty() && end != begin && *end == '\0';
    if (!whole ||
        (info.kind == ParamKind::kInt && (std::floor(x) != x || std::fabs(x) > 2147483647.0))) {
      throw std::invalid_argument(info.name + " = '" + text + "' is not " +
                                  (info.kind == ParamKind::kInt ? "an integer" : "a number"));
    }
    return x;
  }

  std::vector<Entry> entries_;
  std::vector<std::pair<std::string, std::string>> retired_;  // name, what replaced it
};

}  // namespace core
}  // namespace pedicle_drilling
