/**
 * @file test_text_parse.cpp
 * @brief core/common/text_parse.hpp, values given as text: a column of numbers, integer and
 *        number lists, "name=value" class parameters, and the errors that name the bad value.
 *        (The tools' command lines are parsed by CLI11: test/python/test_tool_cli.py.)
 */
#include <gtest/gtest.h>

#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "pedicle_drilling/core/common/text_parse.hpp"

namespace {

namespace pd = pedicle_drilling::core;

/** @brief readNumberColumn() of @p text (through a temporary file). */
std::vector<double> column(const std::string& text) {
  std::FILE* f = std::tmpfile();
  EXPECT_NE(f, nullptr);
  std::fputs(text.c_str(), f);
  std::rewind(f);
  try {
    std::vector<double> out = pd::readNumberColumn(f);
    std::fclose(f);
    return out;
  } catch (...) {
    std::fclose(f);
    throw;
  }
}

/** @brief The UsageError message of @p f, "" when it throws none. */
template <typename F>
std::string usageErrorOf(F f) {
  try {
    f();
  } catch (const pd::UsageError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(ReadNumberColumn, ReadsFiniteNumbersAndNamesABadOneWithItsLine) {
  EXPECT_EQ(column("1\n-2.5\n  3e2 \n\n"), (std::vector<double>{1.0, -2.5, 300.0}));
  EXPECT_NE(usageErrorOf([] { column("1\n2\nnan\n"); }).find("'nan' on line 3"), std::string::npos);
  EXPECT_NE(usageErrorOf([] { column("1\n2.0x\n"); }).find("'2.0x' on line 2"), std::string::npos);
  EXPECT_NE(usageErrorOf([] { column("\n  \n"); }).find("empty"), std::string::npos);
}

TEST(ParseLists, ReadCommaSeparatedValuesAndNameTheOptionOtherwise) {
  EXPECT_EQ(pd::parseIntList("3,4,5", "--keep"), (std::vector<int>{3, 4, 5}));
  EXPECT_EQ(pd::parseDoubleList("1.5,-2", "--pose"), (std::vector<double>{1.5, -2.0}));
  for (const char* bad : {"3,x", "3.5", ""}) {
    const std::string error = usageErrorOf([bad] { pd::parseIntList(bad, "--keep"); });
    EXPECT_NE(error.find("--keep"), std::string::npos) << bad << ": " << error;
  }
  for (const char* bad : {"1,nan", "inf", "a", ""}) {
    const std::string error = usageErrorOf([bad] { pd::parseDoubleList(bad, "--pose"); });
    EXPECT_NE(error.find("--pose"), std::string::npos) << bad << ": " << error;
  }
}

TEST(ParseNameValue, SplitsAtTheFirstEqualsSignAndNamesTheOptionOtherwise) {
  EXPECT_EQ(pd::parseNameValue("extrapolate=true", "--compensator-param"),
            std::make_pair(std::string("extrapolate"), std::string("true")));
  EXPECT_EQ(pd::parseNameValue("a=b=c", "--param"),
            std::make_pair(std::string("a"), std::string("b=c")));
  EXPECT_EQ(pd::parseNameValue("empty=", "--param").second, "");
  for (const char* bad : {"nonsense", "=1", ""}) {
    try {
      pd::parseNameValue(bad, "--param");
      FAIL() << bad;
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()), std::string("--param '") + bad + "' is not name=value");
    }
  }
}
