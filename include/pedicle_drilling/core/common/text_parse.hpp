/**
 * @file text_parse.hpp
 * @brief Values given as text, parsed with errors that name them: a column of numbers
 *        (the wavelet tools' stdin), "3,4,5" and "1.5,2" lists (tool options, nodelet string
 *        parameters) and "name=value" class parameters. No argv parsing here: the tools parse
 *        their command lines with CLI11 (src/tools/tool_cli.hpp).
 */
#pragma once

#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace pedicle_drilling::core {

/** @brief A bad value given by the user (option, parameter, input); the message names it. */
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/**
 * @brief Reads whitespace-separated finite numbers (one column, one per line) until EOF.
 * @throws UsageError naming the bad value and its line, or on empty input.
 */
std::vector<double> readNumberColumn(std::FILE* in);

/** @brief Parses "3,4,5" into integers. @throws UsageError naming @p what otherwise. */
std::vector<int> parseIntList(const std::string& text, const std::string& what);

/** @brief Parses "1.5,2" into finite doubles. @throws UsageError naming @p what otherwise. */
std::vector<double> parseDoubleList(const std::string& text, const std::string& what);

/**
 * @brief A class parameter given on a command line, "name=value", as (name, value) (recognize
 *        --param, trial_engine --recognizer-param / --compensator-param / --check-*).
 * @throws std::invalid_argument "<option> '<item>' is not name=value" without '=' or a name.
 */
std::pair<std::string, std::string> parseNameValue(const std::string& item,
                                                   const std::string& option);

}  // namespace pedicle_drilling::core
