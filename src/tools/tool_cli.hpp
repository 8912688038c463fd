/**
 * @file tool_cli.hpp
 * @brief The command-line conventions of the offline tools (src/tools/), on CLI11 (Debian
 *        libcli11-dev, header-only): `--help` prints the usage (with the defaults) on stdout and
 *        exits 0; an unknown option, a missing required one, a bad value (not a number, out of
 *        range, NaN or infinite, not one of the choices) and an option given twice exit 2 with
 *        a message on stderr that names the option ("<tool>: <message>" and a pointer to
 *        --help). Errors found while running (an unreadable file, ...) are each tool's own.
 */
#pragma once

#include <CLI/CLI.hpp>

#include <cmath>
#include <functional>
#include <iostream>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/wavelet.hpp"
#include "pedicle_drilling/core/common/param_table.hpp"
#include "pedicle_drilling/core/common/text_parse.hpp"

namespace pedicle_drilling::tools {

namespace core = pedicle_drilling::core;

/**
 * @brief A validator from a parameter's one declaration (core::ParamTable): the option's value
 *        is set into a default @p T by @p table, so that the tool accepts exactly what the
 *        nodelet and the core accept (range, choices, form), with the same message.
 * @throws std::logic_error if @p table declares no @p name (a programming error).
 */
template <class T>
CLI::Validator declared(const core::ParamTable<T>& table, const std::string& name) {
  const auto* entry = table.find(name);
  if (entry == nullptr) throw std::logic_error("no declared parameter '" + name + "'");
  return CLI::Validator(
      [&table, name](std::string& text) -> std::string {
        T probe;
        try {
          table.set(probe, name, text);
        } catch (const std::invalid_argument& e) {
          return e.what();
        }
        return std::string();
      },
      entry->info.rule());
}

/** @brief Exit status of a bad command line, in every tool. */
constexpr int kUsageExit = 2;

/** @brief No bound, for finiteNumber(). */
constexpr double kInf = std::numeric_limits<double>::infinity();

/** @brief Applies the conventions that are settings of @p app: --help shows the defaults. */
inline void applyConventions(CLI::App* app) { app->option_defaults()->always_capture_default(); }

/**
 * @brief A validator: a finite number in [lo, hi], or in (lo, hi] with @p open_low (CLI::Range
 *        and CLI::PositiveNumber let NaN through: every comparison with NaN is false).
 */
inline CLI::Validator finiteNumber(double lo = -kInf, double hi = kInf, bool open_low = false) {
  std::ostringstream d;
  if (std::isinf(lo) && std::isinf(hi)) {
    d << "finite";
  } else if (std::isinf(hi)) {
    d << (open_low ? "> " : ">= ") << lo;
  } else if (std::isinf(lo)) {
    d << "<= " << hi;
  } else {
    d << "in " << (open_low ? "(" : "[") << lo << ", " << hi << "]";
  }
  const std::string range = d.str();
  return CLI::Validator(
      [lo, hi, open_low, range](std::string& text) -> std::string {
        double v = 0.0;
        if (!CLI::detail::lexical_cast(text, v) || !std::isfinite(v)) {
          return "'" + text + "' is not a finite number";
        }
        if (!(open_low ? v > lo : v >= lo) || !(v <= hi)) return "'" + text + "' is not " + range;
        return std::string();
      },
      range == "finite" ? "FINITE" : range);
}

/**
 * @brief A validator: comma-separated integers (core::parseIntList()), each in [lo, hi]. A list
 *        is one value, so the option given twice is refused as any other (not appended to).
 */
inline CLI::Validator intList(int lo, int hi) {
  const std::string what =
      "comma-separated integers in " + std::to_string(lo) + ".." + std::to_string(hi);
  return CLI::Validator(
      [lo, hi, what](std::string& text) -> std::string {
        try {
          for (int v : core::parseIntList(text, "")) {
            if (v < lo || v > hi) return "'" + text + "' is not " + what;
          }
          return std::string();
        } catch (const core::UsageError&) {
          return "'" + text + "' is not " + what;
        }
      },
      what);
}

/**
 * @brief A validator from a check of the core: @p accepts(text) false is "'text' is not
 *        <what>" (e.g. findWavelet(), parseIeRatio()). @p what is also the help's description.
 */
inline CLI::Validator accepting(std::function<bool(const std::string&)> accepts,
                                const std::string& what) {
  return CLI::Validator(
      [accepts, what](std::string& text) -> std::string {
        return accepts(text) ? std::string() : "'" + text + "' is not " + what;
      },
      what);
}

/** @brief Deepest DWT level the generic DWT tools (denoise, dwt_coeffs) accept. */
constexpr int kMaxDwtLevel = 32;

/**
 * @brief The options of the DWT tools (denoise, dwt_coeffs), PyWavelets' conventions: --wavelet
 *        (required, a known basis), --level (1..kMaxDwtLevel) and --mode (signal extension).
 */
inline void addDwtOptions(CLI::App* app, std::string* wavelet, int* level, std::string* mode) {
  app->add_option("--wavelet", *wavelet, "db1-db20, sym2-sym20, coif1-coif5, bior1.1 ... bior6.8")
      ->required()
      ->check(accepting([](const std::string& name) { return core::findWavelet(name) != nullptr; },
                        "a known wavelet"));
  app->add_option("--level", *level, "decomposition level")->check(CLI::Range(1, kMaxDwtLevel));
  app->add_option("--mode", *mode, "signal extension")
      ->check(CLI::IsMember({"symmetric", "periodization"}));
}

/**
 * @brief Reports a bad command line found after parsing (a check across options): the tool's
 *        name, @p message (naming the option) and the pointer to --help, on stderr.
 * @return kUsageExit.
 */
inline int usageError(const CLI::App& app, const std::string& message) {
  std::cerr << app.get_name() << ": " << message << "\nRun with --help for more information.\n";
  return kUsageExit;
}

/**
 * @brief The option of one value (or the flag) that was given more than once, as the message
 *        of every tool and script (doc/development.md, "Tools"; CLI11's own would be
 *        "--x: At Most 1 required but received 2"); nothing when no option was.
 */
inline std::optional<std::string> givenTwice(const CLI::App& app) {
  for (const CLI::Option* opt : app.get_options()) {
    if (opt->count() > 1 && opt->get_items_expected_max() <= 1) {
      return "option '" + opt->get_name() + "' given more than once: give it once";
    }
  }
  return std::nullopt;
}

/**
 * @brief Parses the command line into @p app's options.
 * @return nothing when the tool goes on; else its exit status: 0 after --help (the usage on
 *         stdout), kUsageExit after a bad command line (the message on stderr names the option).
 */
inline std::optional<int> parseCommandLine(CLI::App* app, int argc, const char* const* argv) {
  try {
    app->parse(argc, argv);
    // CLI11 takes a flag given twice (and refuses an option of one value given twice).
    if (const auto twice = givenTwice(*app)) return usageError(*app, *twice);
    return std::nullopt;
  } catch (const CLI::Success& e) {  // --help
    return app->exit(e);
  } catch (const CLI::ParseError& e) {
    // An unknown option (often a typo) is named first, before what it may have caused (a
    // required option "missing").
    const std::vector<std::string> unknown = app->remaining();
    if (!unknown.empty()) return usageError(*app, CLI::ExtrasError(unknown).what());
    // So is a repeat (CLI11 validates each value before it counts them).
    if (const auto twice = givenTwice(*app)) return usageError(*app, *twice);
    return usageError(*app, e.what());
  }
}

}  // namespace pedicle_drilling::tools
