/**
 * @file test_cli_args.cpp
 * @brief core::CliArgs, the offline tools' option parser: values, flags, `--key=value`, and the
 *        errors that name the argument (an unknown option, a missing value, an option given
 *        twice, a value that is not a number).
 */
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "pedicle_drilling/core/common/cli_args.hpp"

namespace {

using pedicle_drilling::core::CliArgs;
using pedicle_drilling::core::UsageError;

CliArgs parse(std::vector<std::string> words) {
  words.insert(words.begin(), "tool");
  std::vector<char*> argv;
  for (std::string& w : words) argv.push_back(w.data());
  return CliArgs(static_cast<int>(argv.size()), argv.data(), {"rate", "name"}, {"json"});
}

std::string errorOf(const std::vector<std::string>& words) {
  try {
    parse(words);
  } catch (const UsageError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(CliArgs, ReadsValuesFlagsAndInlineValues) {
  const CliArgs a = parse({"--rate", "12", "--name=x", "--json"});
  EXPECT_DOUBLE_EQ(a.getDouble("rate", 0.0), 12.0);
  EXPECT_EQ(a.get("name", ""), "x");
  EXPECT_TRUE(a.flag("json"));
  const CliArgs b = parse({});
  EXPECT_DOUBLE_EQ(b.getDouble("rate", 7.5), 7.5);
  EXPECT_FALSE(b.flag("json"));
}

TEST(CliArgs, RefusesAnOptionGivenTwiceNamingItAndBothValues) {
  // `tidal_volume --rate 12 ... --rate 0` once ran with rate 12: now refused, in every form.
  const std::string twice = errorOf({"--rate", "12", "--name", "a", "--rate", "0"});
  EXPECT_NE(twice.find("'--rate' given more than once ('12', then '0')"), std::string::npos)
      << twice;
  EXPECT_NE(errorOf({"--rate=12", "--rate", "12"}).find("'--rate' given more than once"),
            std::string::npos);
  EXPECT_NE(errorOf({"--json", "--json"}).find("'--json' given more than once"), std::string::npos);
}

TEST(CliArgs, NamesUnknownOptionsMissingValuesAndBadNumbers) {
  EXPECT_NE(errorOf({"--speed", "1"}).find("unknown option '--speed'"), std::string::npos);
  EXPECT_NE(errorOf({"--rate"}).find("'--rate' needs a value"), std::string::npos);
  EXPECT_NE(errorOf({"rate"}).find("unexpected argument 'rate'"), std::string::npos);
  EXPECT_NE(errorOf({"--json=1"}).find("'--json' takes no value"), std::string::npos);
  for (const char* bad : {"fast", "nan", "inf", "12x"}) {
    try {
      parse({"--rate", bad}).getDouble("rate", 0.0);
      ADD_FAILURE() << "accepted " << bad;
    } catch (const UsageError& e) {
      EXPECT_NE(std::string(e.what()).find("'--rate'"), std::string::npos) << e.what();
    }
  }
}

TEST(ParseNameValue, SplitsAtTheFirstEqualsSignAndNamesTheOptionOtherwise) {
  EXPECT_EQ(pedicle_drilling::core::parseNameValue("extrapolate=true", "--compensator-param"),
            std::make_pair(std::string("extrapolate"), std::string("true")));
  EXPECT_EQ(pedicle_drilling::core::parseNameValue("a=b=c", "--param"),
            std::make_pair(std::string("a"), std::string("b=c")));
  EXPECT_EQ(pedicle_drilling::core::parseNameValue("empty=", "--param").second, "");
  for (const char* bad : {"nonsense", "=1", ""}) {
    try {
      pedicle_drilling::core::parseNameValue(bad, "--param");
      FAIL() << bad;
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()), std::string("--param '") + bad + "' is not name=value");
    }
  }
}
