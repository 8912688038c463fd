/**
 * @file param_docs.cpp
 * @brief `rosrun pedicle_drilling param_docs [--node CLASS] [--format markdown|json]`: every
 *        nodelet's parameters as declared in the code (ros/node_params.hpp), with type, default
 *        and allowed values. The README's parameter tables are checked against `--format json`
 *        (test_readme_parameters.py); `--format markdown` prints the rows to paste.
 */
#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>
#include <string>

#include "pedicle_drilling/ros/node_params.hpp"
#include "tool_cli.hpp"

namespace {

using pedicle_drilling::core::ParamInfo;

std::string jsonString(const std::string& text) {
  std::string out = "\"";
  for (char c : text) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\u%04x", c);
      out += buf;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string jsonNumber(double v) {
  if (std::isinf(v)) return v > 0 ? "\"inf\"" : "\"-inf\"";
  return pedicle_drilling::core::Range::format(v);
}

void printJson(const std::string& node, const std::vector<ParamInfo>& params, bool first) {
  std::cout << (first ? "" : ",\n") << "  " << jsonString(node) << ": [";
  for (std::size_t i = 0; i < params.size(); ++i) {
    const ParamInfo& p = params[i];
    const bool numeric = p.kind == pedicle_drilling::core::ParamKind::kDouble ||
                         p.kind == pedicle_drilling::core::ParamKind::kInt ||
                         p.kind == pedicle_drilling::core::ParamKind::kIntList;
    std::cout << (i ? "," : "") << "\n    {\"name\": " << jsonString(p.name)
              << ", \"type\": " << jsonString(kindName(p.kind))
              << ", \"default\": " << jsonString(p.default_text)
              << ", \"rule\": " << jsonString(p.rule());
    if (numeric) {
      std::cout << ", \"min\": " << jsonNumber(p.range.min)
                << ", \"max\": " << jsonNumber(p.range.max)
                << ", \"open_min\": " << (p.range.open_min ? "true" : "false")
                << ", \"open_max\": " << (p.range.open_max ? "true" : "false");
    }
    std::cout << "}";
  }
  std::cout << "\n  ]";
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
  if (format == "json") std::cout << "{\n";
  bool first = true;
  for (const auto& [name, params] : docs) {
    if (!node.empty() && name != node) continue;
    if (format == "json") {
      printJson(name, params, first);
    } else {
      printMarkdown(name, params);
    }
    first = false;
  }
  if (format == "json") std::cout << "\n}\n";
  return 0;
}
