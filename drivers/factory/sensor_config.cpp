// TOML sensor configuration files (sensor_config.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/sensor_config.hpp"

#include <toml++/toml.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <vector>

#include "scanmesh/common/error.hpp"

namespace scanmesh::drivers {

namespace {

constexpr std::string_view kKeys[] = {
    "driver",  "name",       "port",     "tcp",           "baud",
    "unit",    "profile",    "timeout_ms", "poll_interval_ms", "timeouts_until_lost",
    "backoff_initial_ms", "backoff_max_ms", "parity", "measuring_range_mm"};

class Fields {
 public:
  Fields(const toml::table& t, std::string source) : t_(t), source_(std::move(source)) {}

  void problem(std::string_view key, const std::string& what) {
    problems_.push_back(source_ + ": sensor." + std::string(key) + ": " + what);
  }
  bool string(std::string_view key, std::string& out) {
    const toml::node* n = t_.get(key);
    if (!n) return false;
    if (auto s = n->value_exact<std::string>()) {
      if (s->empty()) {
        problem(key, "must not be empty");
        return false;
      }
      out = *s;
      return true;
    }
    problem(key, "must be a string");
    return false;
  }
  bool number(std::string_view key, double lo, double hi, bool integer, double& out) {
    const toml::node* n = t_.get(key);
    if (!n) return false;
    double v = 0;
    if (auto i = n->value_exact<std::int64_t>()) {
      v = static_cast<double>(*i);
    } else if (auto d = n->value_exact<double>(); d && !integer) {
      v = *d;
    } else {
      problem(key, integer ? "must be an integer" : "must be a number");
      return false;
    }
    if (!(v >= lo && v <= hi)) {
      std::ostringstream msg;
      msg << "must be in [" << lo << ", " << hi << "], got " << v;
      problem(key, msg.str());
      return false;
    }
    out = v;
    return true;
  }
  const std::vector<std::string>& problems() const { return problems_; }

 private:
  const toml::table& t_;
  std::string source_;
  std::vector<std::string> problems_;
};

}  // namespace

SensorConfig parse_sensor_config(std::string_view toml_text, std::string_view source,
                                 const std::filesystem::path& base_dir) {
  toml::table root;
  try {
    root = toml::parse(toml_text, source);
  } catch (const toml::parse_error& e) {
    std::ostringstream msg;
    msg << source << ":" << e.source().begin.line << ":" << e.source().begin.column << ": "
        << e.description();
    throw ConfigError(msg.str());
  }
  const toml::table* t = root["sensor"].as_table();
  if (!t) throw ConfigError(std::string(source) + ": missing [sensor] table");
  Fields f(*t, std::string(source));
  for (const auto& [key, node] : *t) {
    (void)node;
    bool known = false;
    for (auto k : kKeys) known = known || k == key.str();
    if (!known) f.problem(key.str(), "unknown key");
  }
  SensorConfig c;
  if (!f.string("driver", c.driver)) {
    if (!t->get("driver")) f.problem("driver", "is required");
  } else {
    bool registered = false;
    std::string known;
    for (const auto& d : displacement_drivers()) {
      registered = registered || d.name == c.driver;
      known += (known.empty() ? "" : ", ") + d.name;
    }
    if (!registered) f.problem("driver", "unknown driver '" + c.driver + "' (known: " + known + ")");
  }
  c.options.name = c.driver.empty() ? "sensor" : c.driver;
  f.string("name", c.options.name);
  f.string("port", c.port);
  f.string("tcp", c.tcp);
  if ((t->get("port") != nullptr) == (t->get("tcp") != nullptr))
    f.problem("port", "give exactly one of port and tcp");
  double v = 0;
  if (f.number("baud", 50, 4000000, true, v)) c.baud = static_cast<unsigned>(v);
  if (f.number("unit", 0, 247, true, v)) c.unit = static_cast<int>(v);
  std::string parity;
  if (f.string("parity", parity)) {
    if (parity == "none" || parity == "N") c.parity = 'N';
    else if (parity == "even" || parity == "E") c.parity = 'E';
    else if (parity == "odd" || parity == "O") c.parity = 'O';
    else f.problem("parity", "must be none, even or odd");
  }
  if (f.number("measuring_range_mm", 0, 10000, false, v)) c.measuring_range_mm = v;
  if (f.string("profile", c.profile) && !base_dir.empty() &&
      std::filesystem::path(c.profile).is_relative())
    c.profile = (base_dir / c.profile).string();
  if (f.number("timeout_ms", 1, 60000, true, v))
    c.options.timeout = std::chrono::milliseconds(static_cast<std::int64_t>(v));
  if (f.number("poll_interval_ms", 0, 60000, false, v))
    c.options.poll_interval = std::chrono::microseconds(std::llround(v * 1000));
  if (f.number("timeouts_until_lost", 1, 100, true, v))
    c.options.timeouts_until_lost = static_cast<int>(v);
  if (f.number("backoff_initial_ms", 1, 60000, true, v))
    c.options.backoff_initial = std::chrono::milliseconds(static_cast<std::int64_t>(v));
  if (f.number("backoff_max_ms", 1, 600000, true, v))
    c.options.backoff_max = std::chrono::milliseconds(static_cast<std::int64_t>(v));
  if (c.options.backoff_max < c.options.backoff_initial)
    f.problem("backoff_max_ms", "must be at least backoff_initial_ms");
  if (!f.problems().empty()) {
    std::string all;
    for (const auto& p : f.problems()) all += (all.empty() ? "" : "\n") + p;
    throw ConfigError(all);
  }
  return c;
}

SensorConfig load_sensor_config(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw ConfigError(file.string() + ": cannot read the sensor configuration");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_sensor_config(text.str(), file.string(), file.parent_path());
}

}  // namespace scanmesh::drivers
