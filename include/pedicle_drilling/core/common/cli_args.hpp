/**
 * @file cli_args.hpp
 * @brief Minimal command-line parsing shared by the offline tools: `--name value` and
 *        `--flag` options, with errors that name the argument. Tools exit with status 2 on a
 *        UsageError.
 */
#pragma once

#include <cstdio>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace pedicle_drilling::core {

/** @brief A bad command line; the message names the argument. */
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/** @brief Parsed `--key value` options and `--flag` switches. */
class CliArgs {
 public:
  /**
   * @brief Parses argv. @p value_options take a value, @p flag_options do not; anything else
   *        is a UsageError naming it, and so is an option given twice. `--key=value` is
   *        accepted too.
   */
  CliArgs(int argc, char** argv, const std::set<std::string>& value_options,
          const std::set<std::string>& flag_options);

  bool has(const std::string& key) const { return values_.count(key) > 0; }
  bool flag(const std::string& key) const { return flags_.count(key) > 0; }
  /** @brief The raw string value, or @p fallback when absent. */
  std::string get(const std::string& key, const std::string& fallback) const;
  /** @brief A finite double; UsageError naming the option otherwise. */
  double getDouble(const std::string& key, double fallback) const;
  /** @brief An integer; UsageError naming the option otherwise. */
  long getInt(const std::string& key, long fallback) const;

 private:
  std::map<std::string, std::string> values_;
  std::set<std::string> flags_;
};

/**
 * @brief Reads whitespace-separated finite numbers (one column, one per line) until EOF.
 *        UsageError naming the bad value and its line, or on empty input.
 */
std::vector<double> readNumberColumn(std::FILE* in);

/** @brief Parses "3,4,5" into integers; UsageError naming @p what otherwise. */
std::vector<int> parseIntList(const std::string& text, const std::string& what);

/** @brief Parses "1.5,2" into doubles; UsageError naming @p what otherwise. */
std::vector<double> parseDoubleList(const std::string& text, const std::string& what);

/**
 * @brief A class parameter given on a command line, "name=value", as (name, value) (recognize
 *        --param, trial_engine --recognizer-param / --compensator-param / --check-*).
 * @throws std::invalid_argument "<option> '<item>' is not name=value" without '=' or a name.
 */
std::pair<std::string, std::string> parseNameValue(const std::string& item,
                                                   const std::string& option);

}  // namespace pedicle_drilling::core
