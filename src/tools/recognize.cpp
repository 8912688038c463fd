// recognize: offline run of the drilling-state recognizer over a raw force recording.
//
//   recognize --input force.csv [--json] [--recognizer CLASS] [--param name=value ...]
//   recognize --json --input a.csv --input b.csv ...   (one JSON line per trace)
//   recognize --json --param-sets sets.txt --input a.csv ...   (every set over every trace)
//
// force.csv has the header "t,force" (time in s, thrust in N at the sensor's rate), or, for the
// whole sample (kWholeHeader: the dataset's columns, format 1.1.0 on), "t,force,force_x,force_y,
// torque_x,torque_y,torque_z,feed_depth_m,spindle_rpm,feed_command_m,tracker_x,tracker_y,
// tracker_z,tracker_stamp" (N, N m, m, rpm, m, m, s; the force's z is the thrust; the context
// after the torques may be nan: unknown), each sample then given to the
// recognizer's pushSample (a Python class's push_sample). Prints the key points and the stop.
// Command-line parsing: CLI11 with the tools' conventions (tool_cli.hpp). Exit codes: 0 ok, 2 bad
// input or parameters.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <geometry_msgs/WrenchStamped.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include "pedicle_drilling/core/common/text_parse.hpp"
#include "pedicle_drilling/core/drilling/recognizer_interface.hpp"
#include "pedicle_drilling/core/drilling/state_recognizer.hpp"
#include "pedicle_drilling/ros/plugin_loader.hpp"
#include "tool_cli.hpp"

namespace {

using pedicle_drilling::core::KeyPoint;
using pedicle_drilling::core::RecognizerOutput;

struct InputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

std::string trim(const std::string& s) {
  const char* ws = " \t\r\n";
  const auto b = s.find_first_not_of(ws);
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(ws);
  return s.substr(b, e - b + 1);
}

/** @brief The number a field holds (nan and inf included), its text trimmed into @p trimmed. */
double parseNumber(const std::string& text, const std::string& what, std::size_t line,
                   std::string* trimmed) {
  *trimmed = trim(text);
  const std::string& f = *trimmed;
  char* end = nullptr;
  const double v = std::strtod(f.c_str(), &end);
  if (f.empty() || end == f.c_str() || *end != '\0') {
    throw InputError("line " + std::to_string(line) + ": cannot parse " + what + " '" + f + "'");
  }
  return v;
}

/** @brief A measured field: a finite number. */
double parseField(const std::string& text, const std::string& what, std::size_t line) {
  std::string f;
  const double v = parseNumber(text, what, line, &f);
  if (!std::isfinite(v)) {
    throw InputError("line " + std::to_string(line) + ": " + what + " is not finite (" + f + ")");
  }
  return v;
}

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.9g", v);
  return buf;
}

struct Sample {
  double t;
  double f;
  bool whole = false;  ///< a kWholeHeader line: `sample` holds it all, for pushSample
  pedicle_drilling::core::RecognizerSample sample;
};

/** @brief The header of a whole-sample trace (the dataset's columns, format 1.1.0 on). */
constexpr const char* kWholeHeader =
    "t,force,force_x,force_y,torque_x,torque_y,torque_z,feed_depth_m,spindle_rpm,"
    "feed_command_m,tracker_x,tracker_y,tracker_z,tracker_stamp";
constexpr std::size_t kWholeFields = 14;

/** @brief A context field: a number, or nan (unknown); never infinite. */
double parseContext(const std::string& text, const std::string& what, std::size_t line) {
  std::string f;
  const double v = parseNumber(text, what, line, &f);
  if (std::isinf(v)) {
    throw InputError("line " + std::to_string(line) + ": " + what + " is infinite (" + f + ")");
  }
  return v;
}

/** @brief The comma-separated fields of a line. */
std::vector<std::string> splitFields(const std::string& line) {
  std::vector<std::string> fields;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = line.find(',', start);
    fields.push_back(line.substr(start, comma == std::string::npos ? comma : comma - start));
    if (comma == std::string::npos) return fields;
    start = comma + 1;
  }
}

/** @brief The raw force of a recording (a campaign bag): `topic`'s WrenchStamped, the `axis`
 *         component (x, y, z, -x, -y, -z), at the header stamps. */
std::vector<Sample> readBag(const std::string& path, const std::string& topic,
                            const std::string& axis) {
  int index = 2;
  double sign = 1.0;
  std::string a = axis;
  if (!a.empty() && a[0] == '-') {
    sign = -1.0;
    a = a.substr(1);
  }
  if (a == "x") {
    index = 0;
  } else if (a == "y") {
    index = 1;
  } else if (a != "z") {
    throw InputError("--axis '" + axis + "' must be one of x, y, z, -x, -y, -z");
  }
  std::vector<Sample> samples;
  try {
    rosbag::Bag bag(path, rosbag::bagmode::Read);
    rosbag::View view(bag, rosbag::TopicQuery(std::vector<std::string>{topic}));
    for (const rosbag::MessageInstance& m : view) {
      const geometry_msgs::WrenchStamped::ConstPtr w =
          m.instantiate<geometry_msgs::WrenchStamped>();
      if (!w) throw InputError(topic + " is not geometry_msgs/WrenchStamped");
      const geometry_msgs::Vector3& f = w->wrench.force;
      const double v = sign * (index == 0 ? f.x : (index == 1 ? f.y : f.z));
      const double t = w->header.stamp.toSec();
      if (!std::isfinite(v) || !std::isfinite(t)) continue;  // as the nodelet: skipped
      if (!samples.empty() && !(t > samples.back().t)) {
        throw InputError("time " + num(t) + " does not increase (previous " +
                         num(samples.back().t) + ")");
      }
      Sample s;
      s.t = t;
      s.f = v;
      samples.push_back(s);
    }
  } catch (const rosbag::BagException& e) {
    throw InputError("bag '" + path + "': " + e.what());
  }
  if (samples.empty()) throw InputError("bag '" + path + "' has no message on " + topic);
  return samples;
}

std::vector<Sample> readCsv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("cannot open input file '" + path + "'");
  std::string line;
  if (!std::getline(in, line)) throw InputError("input file '" + path + "' is empty");
  std::string header = trim(line);
  if (header.size() >= 3 && header.compare(0, 3, "\xEF\xBB\xBF") == 0) header = header.substr(3);
  std::string compact;
  for (char c : header) {
    if (c != ' ' && c != '\t') compact += c;
  }
  const bool whole = compact == kWholeHeader;
  if (compact != "t,force" && !whole) {
    throw InputError("bad header '" + header + "' (expected 't,force' or '" + kWholeHeader + "')");
  }
  std::vector<Sample> out;
  std::size_t lineno = 1;
  while (std::getline(in, line)) {
    ++lineno;
    if (trim(line).empty()) continue;
    const std::vector<std::string> fields = splitFields(line);
    if (!whole && fields.size() != 2) {
      throw InputError("line " + std::to_string(lineno) + ": expected 2 fields 't,force'");
    }
    if (whole && fields.size() != kWholeFields) {
      throw InputError("line " + std::to_string(lineno) + ": expected " +
                       std::to_string(kWholeFields) + " fields '" + kWholeHeader + "'");
    }
    Sample s;
    s.t = parseField(fields[0], "time", lineno);
    s.f = parseField(fields[1], "force", lineno);
    if (whole) {
      s.whole = true;
      s.sample.t = s.t;
      s.sample.thrust_n = s.f;
      s.sample.force_n = {parseField(fields[2], "force_x", lineno),
                          parseField(fields[3], "force_y", lineno), s.f};
      s.sample.torque_nm = {parseField(fields[4], "torque_x", lineno),
                            parseField(fields[5], "torque_y", lineno),
                            parseField(fields[6], "torque_z", lineno)};
      s.sample.feed_depth_m = parseContext(fields[7], "feed_depth_m", lineno);
      s.sample.spindle_rpm = parseContext(fields[8], "spindle_rpm", lineno);
      s.sample.feed_command_m = parseContext(fields[9], "feed_command_m", lineno);
      s.sample.tracker_m = {parseContext(fields[10], "tracker_x", lineno),
                            parseContext(fields[11], "tracker_y", lineno),
                            parseContext(fields[12], "tracker_z", lineno)};
      s.sample.tracker_stamp = parseContext(fields[13], "tracker_stamp", lineno);
    }
    if (!out.empty() && !(s.t > out.back().t)) {
      throw InputError("line " + std::to_string(lineno) + ": time is not increasing (" + num(s.t) +
                       " after " + num(out.back().t) + ")");
    }
    out.push_back(s);
  }
  if (out.empty()) throw InputError("input file '" + path + "' has no samples");
  return out;
}

/** @brief Everything the command line sets. */
struct Options {
  std::vector<std::string> inputs;
  std::string bag;
  std::string topic = "/ft_sensor/wrench";
  std::string axis = "z";
  bool json = false;
  std::string recognizer_class = "pedicle_drilling/PaperRecognizer";
  std::vector<std::string> params;
  std::string param_sets;
};

/** @brief Declares every option of the tool (its values go to *o). */
void addOptions(CLI::App* app, Options* o) {
  CLI::Option* input = app->add_option(
      "--input", o->inputs,
      "force trace, CSV t,force (s, N); repeatable with --json: one line per trace, the "
      "recognizer reset between traces (the same object, as trials of a campaign)");
  app->add_option("--bag", o->bag,
                  "a recording (a campaign bag): the raw force of --topic "
                  "(geometry_msgs/WrenchStamped), its --axis component, at the header stamps")
      ->excludes(input);
  app->add_option("--topic", o->topic, "force topic of --bag");
  app->add_option("--axis", o->axis, "force component of --bag")
      ->check(CLI::IsMember({"x", "y", "z", "-x", "-y", "-z"}));
  app->add_flag("--json", o->json, "print JSON {key_points, stop}");
  app->add_option("--recognizer", o->recognizer_class,
                  "pedicle_drilling/PaperRecognizer, pedicle_drilling/ForceDifferenceRecognizer or "
                  "any pluginlib class of base pedicle_drilling::core::RecognizerInterface");
  app->add_option("--param", o->params,
                  "name=value for the recognizer (repeatable, each name once). The paper "
                  "recognizer's: pre_average_s sensor_rate_hz (the trace's rate: its block is "
                  "round(pre_average_s x sensor_rate_hz) samples) window k_ratio f_th gain h_g "
                  "c1 c2 c3 cancellous_confirm cancellous_deadline inner_confirm "
                  "stop_delay normalize_feature")
      ->allow_extra_args(false)
      ->check(pedicle_drilling::tools::accepting(
          [](const std::string& item) {
            try {
              pedicle_drilling::core::parseNameValue(item, "--param");
              return true;
            } catch (const std::invalid_argument&) {
              return false;
            }
          },
          "name=value"));
  app->add_option("--param-sets", o->param_sets,
                  "a file of parameter sets, one per line (name=value items separated by blanks, "
                  "added to --param; an empty line: --param alone): each set's recognizer over "
                  "every trace, the traces read once (a tuning grid). Needs --json; each line "
                  "then carries \"param_set\", the set's line from 0");
}

/** @brief The lines of a --param-sets file, each split into name=value items. */
std::vector<std::vector<std::string>> readParamSets(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("--param-sets: cannot open '" + path + "'");
  std::vector<std::vector<std::string>> sets;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream items(line);
    std::vector<std::string> set;
    for (std::string item; items >> item;) {
      try {
        pedicle_drilling::core::parseNameValue(item, "--param-sets");
      } catch (const std::invalid_argument& e) {
        throw InputError("--param-sets '" + path + "' line " + std::to_string(sets.size() + 1) +
                         ": " + e.what());
      }
      set.push_back(item);
    }
    sets.push_back(set);
  }
  if (sets.empty()) throw InputError("--param-sets '" + path + "' has no line");
  return sets;
}

/** @brief The --param settings and `extra` (a --param-sets line); what is wrong (a name given
 *         twice) in *error, else "". */
pedicle_drilling::core::RecognizerSettings settingsOf(const Options& o, std::string* error,
                                                      const std::vector<std::string>& extra = {}) {
  pedicle_drilling::core::RecognizerSettings settings;
  std::set<std::string> given;
  std::vector<std::string> items = o.params;
  items.insert(items.end(), extra.begin(), extra.end());
  for (const std::string& item : items) {
    const auto setting = pedicle_drilling::core::parseNameValue(item, "--param");
    if (!given.insert(setting.first).second) {
      *error = "option '--param " + setting.first + "' given more than once: give it once";
    }
    settings.push_back(setting);
  }
  return settings;
}

/** @brief The result as one JSON line {key_points, stop} (and the input's path, and the
 *         parameter set's line, if given: `set` >= 0). */
std::string jsonLine(const RecognizerOutput& o, const std::string* input, int set = -1) {
  std::ostringstream os;
  os << "{";
  if (set >= 0) os << "\"param_set\":" << set << ",";
  if (input) os << "\"input\":" << nlohmann::json(*input).dump() << ",";
  os << "\"key_points\":[";
  for (int j = 0; j < o.num_key_points; ++j) {
    const KeyPoint& kp = o.key_points[static_cast<std::size_t>(j)];
    os << (j ? "," : "") << "{\"index\":" << kp.index << ",\"t\":" << num(kp.t) << "}";
  }
  os << "],\"stop\":";
  if (o.stop) {
    os << "{\"index\":" << o.stop_index << ",\"t\":" << num(o.stop_t)
       << ",\"key_point\":" << o.stop_key_point << "}";
  } else {
    os << "null";
  }
  os << "}\n";
  return os.str();
}

/** @brief The result as text lines. */
void printText(const RecognizerOutput& o, std::size_t samples) {
  std::cout << "samples " << samples << "\n";
  // The layer the force shows at the end of the trace (the key points go on after the stop).
  std::cout << "final_state " << pedicle_drilling::core::toString(o.layer_state) << "\n";
  if (o.params_ready) {
    std::cout << "algorithm2 k " << o.k << " D " << num(o.d) << " f_min " << num(o.f_min) << "\n";
  }
  for (int j = 0; j < o.num_key_points; ++j) {
    const KeyPoint& kp = o.key_points[static_cast<std::size_t>(j)];
    std::cout << "key_point " << kp.id << " index " << kp.index << " t " << num(kp.t)
              << " recognized_index " << kp.recognized_index << " recognized_t "
              << num(kp.recognized_t) << "\n";
  }
  if (o.stop) {
    std::cout << "stop index " << o.stop_index << " t " << num(o.stop_t) << " key_point "
              << o.stop_key_point << "\n";
  } else {
    std::cout << "stop none\n";
  }
}

}  // namespace

int main(int argc, char** argv) {
  namespace tools = pedicle_drilling::tools;
  CLI::App app{
      "Offline run of a drilling-state recognizer over a raw force recording (--input or --bag): "
      "prints the key points and the stop.",
      "recognize"};
  tools::applyConventions(&app);
  app.footer("Exit status: 0 ok, 2 bad input or parameters.");
  Options options;
  addOptions(&app, &options);
  if (const auto exit = tools::parseCommandLine(&app, argc, argv)) return *exit;
  if (options.inputs.empty() == options.bag.empty()) {
    return tools::usageError(app, "give one of --input (CSV t,force) and --bag (a recording)");
  }
  if (options.inputs.size() > 1 && !options.json) {
    return tools::usageError(app, "several --input traces need --json (one line each)");
  }
  std::vector<std::vector<std::string>> sets{{}};  // no --param-sets: --param alone
  if (!options.param_sets.empty()) {
    if (!options.json) return tools::usageError(app, "--param-sets needs --json (one line each)");
    try {
      sets = readParamSets(options.param_sets);
    } catch (const InputError& e) {
      std::cerr << "recognize: bad input: " << e.what() << "\n";
      return tools::kUsageExit;
    }
  }
  // Every set's recognizer is made before any trace is run: a bad set is exit 2, nothing printed.
  pedicle_drilling::RecognizerLoader loader;  // outlives the recognizers
  std::vector<std::unique_ptr<pedicle_drilling::core::RecognizerInterface>> recognizers;
  for (std::size_t k = 0; k < sets.size(); ++k) {
    const std::string where =
        options.param_sets.empty() ? "" : "--param-sets line " + std::to_string(k + 1) + ": ";
    std::string error;
    const pedicle_drilling::core::RecognizerSettings settings =
        settingsOf(options, &error, sets[k]);
    if (!error.empty()) return tools::usageError(app, where + error);
    try {
      recognizers.push_back(loader.create(options.recognizer_class, settings));
    } catch (const std::exception& e) {
      std::cerr << "recognize: " << where << "--recognizer " << options.recognizer_class << ": "
                << e.what() << "\n";
      return tools::kUsageExit;
    }
  }
  // Every trace is read before any is run: a bad one is exit 2 with nothing printed.
  std::vector<std::vector<Sample>> traces;
  try {
    if (options.bag.empty()) {
      for (const std::string& input : options.inputs) traces.push_back(readCsv(input));
    } else {
      traces.push_back(readBag(options.bag, options.topic, options.axis));
    }
  } catch (const InputError& e) {
    std::cerr << "recognize: bad input: " << e.what() << "\n";
    return tools::kUsageExit;
  }
  for (std::size_t set = 0; set < recognizers.size(); ++set) {
    pedicle_drilling::core::RecognizerInterface& rec = *recognizers[set];
    for (std::size_t k = 0; k < traces.size(); ++k) {
      rec.reset();
      for (const Sample& s : traces[k]) {
        if (s.whole) {
          rec.pushSample(s.sample);
        } else {
          rec.push(s.t, s.f);
        }
      }
      if (options.json) {
        std::cout << jsonLine(rec.output(),
                              options.inputs.size() > 1 ? &options.inputs[k] : nullptr,
                              options.param_sets.empty() ? -1 : static_cast<int>(set));
      } else {
        printText(rec.output(), traces[k].size());
      }
    }
  }
  return 0;
}
