/**
 * @file text_parse.cpp
 * @brief Values given as text (see text_parse.hpp).
 */
#include "pedicle_drilling/core/common/text_parse.hpp"

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <sstream>

namespace pedicle_drilling::core {

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
