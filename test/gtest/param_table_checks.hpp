// Checks shared by the gtest suites of the structs whose parameters are declared in a
// core::ParamTable: every field's default as the table writes it, and every numeric field out of
// its declared range refused naming the field, by the struct's validate() and by the table's
// set() from text.
#ifndef PEDICLE_DRILLING_TEST_GTEST_PARAM_TABLE_CHECKS_HPP_
#define PEDICLE_DRILLING_TEST_GTEST_PARAM_TABLE_CHECKS_HPP_

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "pedicle_drilling/core/common/param_table.hpp"

namespace pedicle_drilling::test {

/** @brief The message of the std::invalid_argument @p f throws ("no error" when none). */
inline std::string invalidArgumentOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no error";
}

/** @brief Values just outside @p r (each finite bound crossed, NaN for a double). */
inline std::vector<double> outsideOf(const core::Range& r, core::ParamKind kind) {
  const bool integer = kind == core::ParamKind::kInt;
  const double int_limit = 2147483647.0;  // an int field cannot hold a value past it
  std::vector<double> out;
  const auto step = [integer](double bound) {
    return integer ? 1.0 : 1e-3 * (1.0 + std::fabs(bound));
  };
  if (std::isfinite(r.min) && !(integer && r.min <= -int_limit)) {
    out.push_back(r.open_min ? r.min : r.min - step(r.min));
  }
  if (std::isfinite(r.max) && !(integer && r.max >= int_limit)) {
    out.push_back(r.open_max ? r.max : r.max + step(r.max));
  }
  if (!integer) out.push_back(std::numeric_limits<double>::quiet_NaN());
  return out;
}

/**
 * @brief The table declares exactly @p defaults, in order: each name with its default as text
 *        (ParamTable::describe of a default-constructed T).
 */
template <class T>
void expectDeclaredDefaults(const core::ParamTable<T>& table,
                            const std::vector<std::pair<std::string, std::string>>& defaults) {
  const std::vector<core::ParamInfo> described = table.describe(T());
  ASSERT_EQ(described.size(), defaults.size());
  for (std::size_t i = 0; i < defaults.size(); ++i) {
    EXPECT_EQ(described[i].name, defaults[i].first);
    EXPECT_EQ(described[i].default_text, defaults[i].second) << described[i].name;
  }
}

/**
 * @brief Every numeric field of T set just outside its declared range: T::validate() refuses it
 *        with a message starting with the field's name, and so does the table's set() from text.
 */
template <class T>
void expectRangesRefusedNamingTheField(const core::ParamTable<T>& table) {
  for (const auto& e : table.entries()) {
    if (!e.set_number || e.info.kind == core::ParamKind::kBool) continue;
    const std::string& name = e.info.name;
    for (const double bad : outsideOf(e.info.range, e.info.kind)) {
      T v;
      e.set_number(v, bad);
      const std::string by_validate = invalidArgumentOf([&v] { v.validate(); });
      EXPECT_EQ(by_validate.rfind(name, 0), 0u) << name << " = " << bad << ": " << by_validate;
      T w;
      const std::string text = std::isnan(bad) ? "nan" : core::Range::format(bad);
      const std::string by_set = invalidArgumentOf([&] { table.set(w, name, text); });
      EXPECT_EQ(by_set.rfind(name, 0), 0u) << name << " = " << text << ": " << by_set;
    }
  }
}

}  // namespace pedicle_drilling::test

#endif  // PEDICLE_DRILLING_TEST_GTEST_PARAM_TABLE_CHECKS_HPP_
