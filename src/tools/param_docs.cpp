/**
 * @file param_docs.cpp
 * @brief `rosrun pedicle_drilling param_docs [--node CLASS] [--format markdown|json]`: every
 *        nodelet's parameters as declared in the code (ros/node_params.hpp), with type, default
 *        and allowed values. doc/nodes.md's parameter tables are checked against `--format json`
 *        (test_readme_parameters.py); `--format markdown` prints the rows to paste.
 */
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <iostream>
#include <string>

#include "pedicle_drilling/ros/node_params.hpp"
#include "tool_cli.hpp"

namespace {

using json = nlohmann::json;
using pedicle_drilling::core::ParamInfo;

/** @brief A bound as JSON: a number, or "inf" / "-inf" (JSON has no infinity). */
json jsonBound(double v) {
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  return v;
}

json paramsJson(const std::vector<ParamInfo>& params) {
  json out = json::array();
  for (const ParamInfo& p : params) {
    json entry = {{"name", p.name},
                  {"type", kindName(p.kind)},
                  {"default", p.default_text},
                  {"rule", p.rule()}};
    if (p.kind == pedicle_drilling::core::ParamKind::kDouble ||
        p.kind == pedicle_drilling::core::ParamKind::kInt ||
        p.kind == pedicle_drilling::core::ParamKind::kIntList) {
      entry["min"] = jsonBound(p.range.min);
      entry["max"] = jsonBound(p.range.max);
      entry["open_min"] = p.range.open_min;
      entry["open_max"] = p.range.open_max;
    }
    out.push_back(entry);
  }
  return out;
}

void printMarkdown(const std::string& node, const std::vector<ParamInfo>& params) {
  std::cout << "### " << node << "\n\n| parameter | type | default | range |\n|---|---|---|---|\n";
  for (const ParamInfo& p : params) {
    std::cout << "| `~" << p.name << "` | " << kindName(p.kind) << " | "
              << (p.default_text.empty() ? "`\"\"`" : "`" + p.default_text + "`") << " | "
              << p.rule() << " |\n";
  }
  std::cout << "\n";
}

}  // namespace

int main(int argc, char** argv) {
  namespace tools = pedicle_drilling::tools;
  CLI::App app{
      "Every nodelet's parameters as the code declares them (name, type, default, allowed "
      "values).",
      "param_docs"};
  tools::applyConventions(&app);
  std::string node;
  std::string format = "markdown";
  app.add_option("--node", node, "only this nodelet class, e.g. pedicle_drilling/SafetyMonitor");
  app.add_option("--format", format, "markdown or json")
      ->check(CLI::IsMember({"markdown", "json"}));
  if (const auto exit = tools::parseCommandLine(&app, argc, argv)) return *exit;
  const auto docs = pedicle_drilling::nodeParameterDocs();
  bool known_node = node.empty();
  std::string known;
  for (const auto& entry : docs) {
    known += " " + entry.first;
    known_node = known_node || entry.first == node;
  }
  if (!known_node) {
    return tools::usageError(app, "--node: no nodelet class '" + node + "' (known:" + known + ")");
  }
  json all = json::object();
  for (const auto& [name, params] : docs) {
    if (!node.empty() && name != node) continue;
    if (format == "json") {
      all[name] = paramsJson(params);
    } else {
      printMarkdown(name, params);
    }
  }
  if (format == "json") std::cout << all.dump(2) << "\n";
  return 0;
}
