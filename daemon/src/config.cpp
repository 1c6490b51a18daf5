// scanmeshd's TOML configuration (config.hpp): parsing with toml++, every problem collected.
// SPDX-License-Identifier: MIT
#include "scanmesh/daemon/config.hpp"

#include <grp.h>
#include <pwd.h>
#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/sensor_config.hpp"
#include "scanmesh/sim/parts.hpp"

namespace scanmesh::daemon {

namespace {

/// Reads one table's keys with type and range checks, collecting problems.
class TableReader {
 public:
  TableReader(const toml::table* t, std::string table, std::string source,
              std::vector<std::string>& problems)
      : t_(t), table_(std::move(table)), source_(std::move(source)), problems_(problems) {}

  void problem(std::string_view key, const std::string& what) {
    problems_.push_back(source_ + ": " + table_ + "." + std::string(key) + ": " + what);
  }
  const toml::node* node(std::string_view key) {
    seen_.insert(std::string(key));
    return t_ ? t_->get(key) : nullptr;
  }
  void string(std::string_view key, std::string& out, bool allow_empty = false) {
    const toml::node* n = node(key);
    if (!n) return;
    if (auto s = n->value_exact<std::string>()) {
      if (s->empty() && !allow_empty) return problem(key, "must not be empty");
      out = *s;
    } else {
      problem(key, "must be a string");
    }
  }
  void choice(std::string_view key, std::string& out, std::initializer_list<std::string_view> ok) {
    std::string v = out;
    string(key, v);
    if (std::find(ok.begin(), ok.end(), v) == ok.end()) {
      std::string list;
      for (auto w : ok) list += (list.empty() ? "" : ", ") + std::string(w);
      return problem(key, "must be one of " + list + ", got '" + v + "'");
    }
    out = v;
  }
  void path(std::string_view key, std::filesystem::path& out, const std::filesystem::path& base) {
    std::string s;
    string(key, s);
    if (s.empty()) return;
    std::filesystem::path p(s);
    out = p.is_relative() && !base.empty() ? base / p : p;
  }
  template <class T>
  void number(std::string_view key, T& out, double lo, double hi) {
    const toml::node* n = node(key);
    if (!n) return;
    double v = 0;
    constexpr bool kInteger = std::is_integral_v<T>;
    if (auto i = n->value_exact<std::int64_t>()) {
      v = static_cast<double>(*i);
    } else if (auto d = n->value_exact<double>(); d && !kInteger) {
      v = *d;
    } else {
      return problem(key, kInteger ? "must be an integer" : "must be a number");
    }
    if (!(v >= lo && v <= hi)) {
      std::ostringstream msg;
      msg << "must be in [" << lo << ", " << hi << "], got " << v;
      return problem(key, msg.str());
    }
    out = static_cast<T>(v);
  }
  void strings(std::string_view key, std::vector<std::string>& out) {
    const toml::node* n = node(key);
    if (!n) return;
    const toml::array* a = n->as_array();
    if (!a) return problem(key, "must be an array of strings");
    out.clear();
    for (const auto& e : *a) {
      if (auto s = e.value_exact<std::string>(); s && !s->empty())
        out.push_back(*s);
      else
        return problem(key, "must be an array of non-empty strings");
    }
  }
  /// Every key of the table that no reader asked for is a problem (a typo loses a setting).
  void check_unknown() {
    if (!t_) return;
    for (const auto& [k, v] : *t_)
      if (!seen_.count(std::string(k.str()))) problem(k.str(), "unknown key");
  }

 private:
  const toml::table* t_;
  std::string table_;
  std::string source_;
  std::vector<std::string>& problems_;
  std::set<std::string> seen_;
};

const toml::table* sub_table(const toml::table& root, std::string_view name,
                             const std::string& source, std::vector<std::string>& problems) {
  const toml::node* n = root.get(name);
  if (!n) return nullptr;
  if (const toml::table* t = n->as_table()) return t;
  problems.push_back(source + ": " + std::string(name) + ": must be a table");
  return nullptr;
}

std::optional<LogLevel> log_level_from(std::string_view w) {
  for (LogLevel l :
       {LogLevel::kError, LogLevel::kWarning, LogLevel::kNotice, LogLevel::kInfo, LogLevel::kDebug})
    if (to_string(l) == w) return l;
  return std::nullopt;
}

void read_daemon(const toml::table* t, const std::string& source, const std::filesystem::path& base,
                 DaemonConfig& c, std::vector<std::string>& problems) {
  TableReader r(t, "daemon", source, problems);
  // The socket is a runtime path, never relative to the configuration file.
  r.path("socket", c.socket_path, {});
  r.string("socket_group", c.socket_group, true);
  r.path("state_dir", c.state_dir, base);
  r.number("max_clients", c.max_clients, 1, 4096);
  r.number("client_output_limit_bytes", c.client_output_limit_bytes, 64 * 1024,
           1024.0 * 1024 * 1024);
  std::int64_t interval_ms = c.progress_interval.count();
  r.number("progress_interval_ms", interval_ms, 10, 60000);
  c.progress_interval = std::chrono::milliseconds(interval_ms);
  r.strings("control_users", c.control_users);
  std::vector<std::string> dirs;
  r.strings("export_dirs", dirs);
  for (const auto& d : dirs) {
    std::filesystem::path p(d);
    c.export_dirs.push_back(p.is_relative() && !base.empty() ? base / p : p);
  }
  std::string level(to_string(c.log_level));
  r.string("log_level", level);
  if (auto l = log_level_from(level))
    c.log_level = *l;
  else
    r.problem("log_level",
              "must be one of error, warning, notice, info, debug, got '" + level + "'");
  r.check_unknown();
  if (!c.socket_path.is_absolute())
    r.problem("socket", "must be an absolute path, got '" + c.socket_path.string() + "'");
  // sockaddr_un holds 108 bytes, the terminating NUL included.
  if (c.socket_path.string().size() > 107)
    r.problem("socket", "is longer than a Unix socket path may be (107 bytes)");
  if (!c.socket_group.empty() && ::getgrnam(c.socket_group.c_str()) == nullptr)
    r.problem("socket_group", "no such group '" + c.socket_group + "'");
  for (const auto& u : c.control_users) {
    if (const passwd* pw = ::getpwnam(u.c_str()))
      c.control_uids.push_back(pw->pw_uid);
    else
      r.problem("control_users", "no such user '" + u + "'");
  }
}

void read_sim(const toml::table* t, const std::string& source, const std::filesystem::path& base,
              SimBackendConfig& s, std::vector<std::string>& problems) {
  TableReader r(t, "sim", source, problems);
  const bool has_part = t && t->contains("part");
  r.string("part", s.part);
  r.path("mesh", s.mesh, base);
  if (!s.mesh.empty()) {
    if (has_part) r.problem("mesh", "give either 'part' or 'mesh', not both");
    s.part.clear();
    std::error_code ec;
    if (!std::filesystem::is_regular_file(s.mesh, ec))
      r.problem("mesh", "cannot read '" + s.mesh.string() + "': no such file");
  } else {
    const auto names = sim::part_names();
    if (std::find(names.begin(), names.end(), s.part) == names.end()) {
      std::string list;
      for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
      r.problem("part", "unknown part '" + s.part + "' (built-in parts: " + list + ")");
    }
  }
  r.choice("sensor", s.sensor, {"point", "line", "probe"});
  r.choice("path", s.path, {"raster", "serpentine", "rotary", "views"});
  r.number("spacing_mm", s.spacing_mm, 1e-3, 50);
  r.number("line_spacing_mm", s.line_spacing_mm, 0, 500);
  r.number("speed_mm_s", s.speed_mm_s, 1e-3, 5000);
  r.number("noise_mm", s.noise_mm, 0, 5);
  r.number("seed", s.seed, 0, 9.0e15);
  r.number("views", s.views, 1, 360);
  r.number("profile_points", s.profile_points, 1, 65536);
  r.number("playback", s.playback, 0, 10000);
  r.number("sensor_loss_at_s", s.sensor_loss_at_s, 0, 86400);
  r.number("sensor_loss_s", s.sensor_loss_s, 1e-3, 60);
  r.choice("transport", s.transport, {"in-process", "emulators"});
  if (s.transport == "emulators" && s.sensor != "point")
    r.problem("transport", "the emulators are a point sensor (ILD1420) on a GRBL stage: "
                           "sensor must be \"point\", got '" + s.sensor + "'");
  r.check_unknown();
}

void read_replay(const toml::table* t, const std::string& source, const std::filesystem::path& base,
                 ReplayBackendConfig& p, bool needed, std::vector<std::string>& problems) {
  TableReader r(t, "replay", source, problems);
  r.path("journal", p.journal, base);
  r.number("playback", p.playback, 0, 10000);
  r.check_unknown();
  if (!needed) return;
  std::error_code ec;
  if (p.journal.empty())
    r.problem("journal", "is required with backend = \"replay\"");
  else if (!std::filesystem::is_regular_file(p.journal, ec))
    r.problem("journal", "cannot read '" + p.journal.string() + "': no such file");
}

void read_devices(const toml::table& root, const std::string& source,
                  const std::filesystem::path& base, DaemonConfig& c, bool needed,
                  std::vector<std::string>& problems) {
  const toml::node* n = root.get("devices");
  if (!n) {
    if (needed)
      problems.push_back(source + ": devices: backend \"devices\" needs [[devices]] entries");
    return;
  }
  const toml::array* a = n->as_array();
  if (!a || !a->is_array_of_tables()) {
    problems.push_back(source + ": devices: must be an array of tables ([[devices]])");
    return;
  }
  for (std::size_t i = 0; i < a->size(); ++i) {
    TableReader r((*a)[i].as_table(), "devices[" + std::to_string(i) + "]", source, problems);
    DeviceEntry e;
    r.choice("role", e.role, {"sensor", "stage"});
    r.path("config", e.config, base);
    r.check_unknown();
    if (e.config.empty()) {
      r.problem("config", "is required (a sensor configuration file)");
    } else if (e.role == "sensor") {
      // The device's own file is validated now too, so every error shows before any port opens.
      try {
        drivers::load_sensor_config(e.config);
      } catch (const Error& err) {
        std::istringstream lines(err.what());
        for (std::string line; std::getline(lines, line);) r.problem("config", line);
      }
    }
    c.devices.push_back(std::move(e));
  }
}

void read_scan_defaults(const toml::table* t, const std::string& source, DaemonConfig& c,
                        std::vector<std::string>& problems) {
  if (!t) return;
  for (const auto& [k, v] : *t) {
    const std::string key(k.str());
    if (auto b = v.value_exact<bool>())
      c.scan_defaults[key] = *b;
    else if (auto i = v.value_exact<std::int64_t>())
      c.scan_defaults[key] = *i;
    else if (auto d = v.value_exact<double>())
      c.scan_defaults[key] = *d;
    else if (auto s = v.value_exact<std::string>())
      c.scan_defaults[key] = *s;
    else
      problems.push_back(source + ": scan." + key + ": must be a string, number or boolean");
  }
}

}  // namespace

std::string_view to_string(LogLevel level) {
  switch (level) {
    case LogLevel::kError:
      return "error";
    case LogLevel::kWarning:
      return "warning";
    case LogLevel::kNotice:
      return "notice";
    case LogLevel::kInfo:
      return "info";
    case LogLevel::kDebug:
      return "debug";
  }
  return "info";
}

DaemonConfig parse_config(std::string_view toml_text, const std::filesystem::path& source) {
  const std::string src = source.empty() ? std::string("<config>") : source.string();
  toml::table root;
  try {
    root = toml::parse(toml_text, src);
  } catch (const toml::parse_error& e) {
    std::ostringstream msg;
    msg << src << ":" << e.source().begin.line << ":" << e.source().begin.column << ": "
        << e.description();
    throw ConfigError(msg.str());
  }
  const std::filesystem::path base =
      source.empty() ? std::filesystem::path() : source.parent_path();
  std::vector<std::string> problems;
  DaemonConfig c;
  c.source = source;
  for (const auto& [k, v] : root) {
    static constexpr std::string_view kTables[] = {"daemon", "backend", "sim",
                                                   "replay", "devices", "scan"};
    if (std::find(std::begin(kTables), std::end(kTables), k.str()) == std::end(kTables))
      problems.push_back(src + ": " + std::string(k.str()) + ": unknown table");
  }
  read_daemon(sub_table(root, "daemon", src, problems), src, base, c, problems);
  {
    TableReader r(sub_table(root, "backend", src, problems), "backend", src, problems);
    r.choice("kind", c.backend, {"sim", "replay", "devices"});
    r.check_unknown();
  }
  if (c.backend == "sim" || root.contains("sim"))
    read_sim(sub_table(root, "sim", src, problems), src, base, c.sim, problems);
  read_replay(sub_table(root, "replay", src, problems), src, base, c.replay, c.backend == "replay",
              problems);
  read_devices(root, src, base, c, c.backend == "devices", problems);
  read_scan_defaults(sub_table(root, "scan", src, problems), src, c, problems);
  if (c.export_dirs.empty()) c.export_dirs.push_back(c.state_dir / "exports");
  if (!problems.empty()) {
    std::string all;
    for (const auto& p : problems) all += (all.empty() ? "" : "\n") + p;
    throw ConfigError(all);
  }
  return c;
}

DaemonConfig load_config(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw ConfigError(file.string() + ": cannot read the configuration file");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_config(text.str(), file);
}

std::vector<std::string> restart_needed(const DaemonConfig& a, const DaemonConfig& b) {
  std::vector<std::string> out;
  if (a.socket_path != b.socket_path) out.push_back("daemon.socket");
  if (a.socket_group != b.socket_group) out.push_back("daemon.socket_group");
  if (a.state_dir != b.state_dir) out.push_back("daemon.state_dir");
  if (a.backend != b.backend) out.push_back("backend.kind");
  const auto& s = a.sim;
  const auto& t = b.sim;
  if (s.part != t.part || s.mesh != t.mesh || s.sensor != t.sensor || s.path != t.path ||
      s.spacing_mm != t.spacing_mm || s.line_spacing_mm != t.line_spacing_mm ||
      s.speed_mm_s != t.speed_mm_s || s.noise_mm != t.noise_mm || s.seed != t.seed ||
      s.views != t.views || s.profile_points != t.profile_points || s.playback != t.playback ||
      s.sensor_loss_at_s != t.sensor_loss_at_s || s.sensor_loss_s != t.sensor_loss_s ||
      s.transport != t.transport)
    out.push_back("sim");
  if (a.replay.journal != b.replay.journal || a.replay.playback != b.replay.playback)
    out.push_back("replay");
  bool devices_same = a.devices.size() == b.devices.size();
  for (std::size_t i = 0; devices_same && i < a.devices.size(); ++i)
    devices_same =
        a.devices[i].role == b.devices[i].role && a.devices[i].config == b.devices[i].config;
  if (!devices_same) out.push_back("devices");
  return out;
}

}  // namespace scanmesh::daemon
