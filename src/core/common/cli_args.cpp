#include "pedicle_drilling/core/common/cli_args.hpp"

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <sstream>

namespace pedicle_drilling::core {

CliArgs::CliArgs(int argc, char** argv, const std::set<std::string>& value_options,
                 const std::set<std::string>& flag_options) {
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    if (arg.rfind("--", 0) != 0) throw UsageError("unexpected argument '" + arg + "'");
    std::string key = arg.substr(2);
    std::string value;
    bool has_inline_value = false;
    const auto eq = key.find('=');
    if (eq != std::string::npos) {
      value = key.substr(eq + 1);
      key = key.substr(0, eq);
      has_inline_value = true;
    }
    if (flag_options.count(key)) {
      if (has_inline_value) throw UsageError("option '--" + key + "' takes no value");
      if (!flags_.insert(key).second) {
        throw UsageError("option '--" + key + "' given more than once: give it once");
      }
    } else if (value_options.count(key)) {
      if (!has_inline_value) {
        if (i + 1 >= argc) throw UsageError("option '--" + key + "' needs a value");
        value = argv[++i];
      }
      const auto first = values_.find(key);
      if (first != values_.end()) {
        // getopt would keep the last, argparse too; a drilling tool refuses, the same way in
        // every tool (the campaign scripts' parser does too): `--rate 12 ... --rate 0` is a
        // mistake to report, not a choice to guess.
        throw UsageError("option '--" + key + "' given more than once ('" + first->second +
                         "', then '" + value + "'): give it once");
      }
      values_.emplace(key, value);
    } else {
      throw UsageError("unknown option '--" + key + "'");
    }
  }
}

std::string CliArgs::get(const std::string& key, const std::string& fallback) const {
  const auto it = values_.find(key);
  return it == values_.end() ? fallback : it->second;
}

double CliArgs::getDouble(const std::string& key, double fallback) const {
  if (!has(key)) return fallback;
  const std::string text = get(key, "");
  try {
    size_t used = 0;
    const double value = std::stod(text, &used);
    if (used != text.size() || !std::isfinite(value)) throw std::invalid_argument(text);
    return value;
  } catch (const std::exception&) {
    throw UsageError("option '--" + key + "' = '" + text + "' is not a finite number");
  }
}

long CliArgs::getInt(const std::string& key, long fallback) const {
  if (!has(key)) return fallback;
  const std::string text = get(key, "");
  try {
    size_t used = 0;
    const long value = std::stol(text, &used);
    if (used != text.size()) throw std::invalid_argument(text);
    return value;
  } catch (const std::exception&) {
    throw UsageError("option '--" + key + "' = '" + text + "' is not an integer");
  }
}

std::vector<int> parseIntList(const std::string& text, const std::string& what) {
  std::vector<int> out;
  std::stringstream stream(text);
  std::string item;
  while (std::getline(stream, item, ',')) {
    try {
      size_t used = 0;
      const int value = std::stoi(item, &used);
      if (used != item.size()) throw std::invalid_argument(item);
      out.push_back(value);
    } catch (const std::exception&) {
      throw UsageError(what + " = '" + text + "' is not a comma-separated list of integers");
    }
  }
  if (out.empty()) throw UsageError(what + " is empty");
  return out;
}

std::vector<double> parseDoubleList(const std::string& text, const std::string& what) {
  std::vector<double> out;
  std::stringstream stream(text);
  std::string item;
  while (std::getline(stream, item, ',')) {
    try {
      size_t used = 0;
      const double value = std::stod(item, &used);
      if (used != item.size() || !std::isfinite(value)) throw std::invalid_argument(item);
      out.push_back(value);
    } catch (const std::exception&) {
      throw UsageError(what + " = '" + text + "' is not a comma-separated list of numbers");
    }
  }
  if (out.empty()) throw UsageError(what + " is empty");
  return out;
}

std::vector<double> readNumberColumn(std::FILE* in) {
  std::string data;
  char buf[1 << 16];
  std::size_t got = 0;
  while ((got = std::fread(buf, 1, sizeof(buf), in)) > 0) {
    data.append(buf, got);
  }
  std::vector<double> values;
  std::size_t line_no = 1;
  std::size_t i = 0;
  const char* base = data.c_str();
  while (i < data.size()) {
    const char c = data[i];
    if (c == '\n') {
      ++line_no;
      ++i;
      continue;
    }
    if (std::isspace(static_cast<unsigned char>(c)) != 0) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < data.size() && std::isspace(static_cast<unsigned char>(data[j])) == 0) {
      ++j;
    }
    char* end = nullptr;
    const double v = std::strtod(base + i, &end);
    if (end != base + j || !std::isfinite(v)) {
      throw UsageError("bad input value '" + data.substr(i, j - i) + "' on line " +
                       std::to_string(line_no) + " (expected a finite number)");
    }
    values.push_back(v);
    i = j;
  }
  if (values.empty()) {
    throw UsageError("empty input (no numbers on stdin)");
  }
  return values;
}

std::pair<std::string, std::string> parseNameValue(const std::string& item,
                                                   const std::string& option) {
  const auto eq = item.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw std::invalid_argument(option + " '" + item + "' is not name=value");
  }
  return {item.substr(0, eq), item.substr(eq + 1)};
}

}  // namespace pedicle_drilling::core
