// TOML profile loader of the Modbus drive stage (see modbus_stage/profile.hpp).
// SPDX-License-Identifier: MIT
#include <toml++/toml.h>

#include <filesystem>
#include <initializer_list>
#include <string_view>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/modbus_stage/profile.hpp"

namespace scanmesh::drivers::modbus_stage {

namespace {

class Reader {
 public:
  explicit Reader(std::vector<std::string>& problems) : problems_(problems) {}

  void problem(const std::string& key, const std::string& what) {
    problems_.push_back(key + ": " + what);
  }
  static std::string join(const std::string& where, std::string_view key) {
    return where.empty() ? std::string(key) : where + "." + std::string(key);
  }
  void check_keys(const toml::table& t, const std::string& where,
                  std::initializer_list<std::string_view> allowed) {
    for (const auto& [key, node] : t) {
      (void)node;
      bool ok = false;
      for (auto a : allowed) ok = ok || a == key.str();
      if (!ok) problem(join(where, key.str()), "unknown key");
    }
  }
  bool number(const toml::node* n, const std::string& key, double lo, double hi, bool integer,
              double& out) {
    if (n == nullptr) return false;
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
      problem(key, "must be in " + fmt(lo) + " .. " + fmt(hi));
      return false;
    }
    out = v;
    return true;
  }
  bool number(const toml::table& t, const std::string& where, std::string_view key, double lo,
              double hi, bool integer, double& out) {
    return number(t.get(key), join(where, key), lo, hi, integer, out);
  }
  bool string(const toml::table& t, const std::string& where, std::string_view key,
              std::string& out) {
    const toml::node* n = t.get(key);
    if (n == nullptr) return false;
    if (auto s = n->value_exact<std::string>()) {
      out = *s;
      return true;
    }
    problem(join(where, key), "must be a string");
    return false;
  }

  std::optional<RegisterRef> ref(const toml::table& root, std::string_view key, bool required) {
    const toml::node* n = root.get(key);
    const std::string where(key);
    if (n == nullptr) {
      if (required) problem(where, "missing");
      return std::nullopt;
    }
    const toml::table* t = n->as_table();
    if (t == nullptr) {
      problem(where, "must be a table { address, type }");
      return std::nullopt;
    }
    check_keys(*t, where, {"address", "type"});
    RegisterRef r;
    double a = 0;
    if (number(*t, where, "address", 0, 65535, true, a))
      r.address = static_cast<std::uint16_t>(a);
    else if (!t->contains("address"))
      problem(where + ".address", "missing");
    std::string type;
    if (string(*t, where, "type", type)) {
      if (auto rt = register_type_from_string(type))
        r.type = *rt;
      else
        problem(where + ".type", "unknown type \"" + type + "\" (u16, i16, u32, i32)");
    } else if (!t->contains("type")) {
      problem(where + ".type", "missing");
    }
    return r;
  }

  std::vector<RegisterWrite> writes(const toml::table& root, std::string_view key) {
    std::vector<RegisterWrite> out;
    const toml::node* n = root.get(key);
    if (n == nullptr) return out;
    const toml::array* arr = n->as_array();
    if (arr == nullptr) {
      problem(std::string(key), "must be an array of tables ([[" + std::string(key) + "]])");
      return out;
    }
    for (std::size_t i = 0; i < arr->size(); ++i) {
      const std::string where = std::string(key) + "[" + std::to_string(i + 1) + "]";
      const toml::table* t = arr->get(i)->as_table();
      if (t == nullptr) {
        problem(where, "must be a table");
        continue;
      }
      check_keys(*t, where, {"address", "values"});
      RegisterWrite w;
      double a = 0;
      if (number(*t, where, "address", 0, 65535, true, a))
        w.address = static_cast<std::uint16_t>(a);
      else if (!t->contains("address"))
        problem(where + ".address", "missing");
      const toml::array* values = t->get("values") ? t->get("values")->as_array() : nullptr;
      if (values == nullptr) {
        problem(where + ".values", "missing (an array of integers and placeholders)");
      } else {
        for (std::size_t k = 0; k < values->size(); ++k) {
          const std::string vk = where + ".values[" + std::to_string(k + 1) + "]";
          const toml::node* v = values->get(k);
          if (auto s = v->value_exact<std::string>()) {
            if (*s == "target") w.values.push_back({WriteValue::Kind::kTarget, 0});
            else if (*s == "speed") w.values.push_back({WriteValue::Kind::kSpeed, 0});
            else if (*s == "accel") w.values.push_back({WriteValue::Kind::kAccel, 0});
            else if (*s == "accel_time") w.values.push_back({WriteValue::Kind::kAccelTime, 0});
            else
              problem(vk, "unknown placeholder \"" + *s + "\" (target, speed, accel, accel_time)");
          } else {
            double c = 0;
            if (number(v, vk, 0, 65535, true, c))
              w.values.push_back({WriteValue::Kind::kConstant, static_cast<std::uint16_t>(c)});
          }
        }
      }
      out.push_back(std::move(w));
    }
    return out;
  }

 private:
  static std::string fmt(double v) {
    std::string s = std::to_string(v);
    if (s.find('.') != std::string::npos) {
      while (s.back() == '0') s.pop_back();
      if (s.back() == '.') s.pop_back();
    }
    return s;
  }
  std::vector<std::string>& problems_;
};

std::optional<StageAxis> axis_from_name(std::string_view s) {
  if (s == "x") return StageAxis::kX;
  if (s == "y") return StageAxis::kY;
  if (s == "z") return StageAxis::kZ;
  if (s == "a") return StageAxis::kA;
  return std::nullopt;
}

}  // namespace

StageRegisterMap load_stage_profile(const std::string& path) {
  toml::table root;
  try {
    root = toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    const auto& where = e.source().begin;
    throw ConfigError(path + ":" + std::to_string(where.line) + ":" +
                      std::to_string(where.column) + ": " + std::string(e.description()));
  }
  std::vector<std::string> problems;
  Reader r(problems);
  StageRegisterMap m;
  m.profile = std::filesystem::path(path).stem().string();
  r.check_keys(root, "",
               {"profile", "vendor", "model", "word_order", "speed_scale", "accel_scale",
                "max_speed", "accel", "position", "status", "alarm", "probe_position",
                "status_bits", "alarms", "init", "move", "home", "stop", "reset", "probe_arm",
                "axis"});
  r.string(root, "", "profile", m.profile);
  r.string(root, "", "vendor", m.vendor);
  r.string(root, "", "model", m.model);
  std::string order;
  if (r.string(root, "", "word_order", order)) {
    if (order == "high_first")
      m.word_order = WordOrder::kHighFirst;
    else if (order == "low_first")
      m.word_order = WordOrder::kLowFirst;
    else
      r.problem("word_order", "must be \"high_first\" or \"low_first\"");
  } else if (!root.contains("word_order")) {
    r.problem("word_order", "missing (high_first or low_first: drives differ)");
  }
  r.number(root, "", "speed_scale", 1e-9, 1e9, false, m.speed_scale);
  r.number(root, "", "accel_scale", 1e-9, 1e12, false, m.accel_scale);
  r.number(root, "", "max_speed", 0, 1e9, false, m.max_speed_units_s);
  r.number(root, "", "accel", 1e-9, 1e12, false, m.default_accel_units_s2);
  if (auto p = r.ref(root, "position", true)) m.position = *p;
  if (auto s = r.ref(root, "status", true)) m.status = *s;
  m.alarm = r.ref(root, "alarm", false);
  m.probe_position = r.ref(root, "probe_position", false);

  if (const toml::node* n = root.get("status_bits")) {
    if (const toml::table* t = n->as_table()) {
      r.check_keys(*t, "status_bits",
                   {"moving", "homing", "homed", "fault", "probe_latched", "in_position"});
      const std::pair<std::string_view, int*> bits[] = {
          {"moving", &m.bits.moving},
          {"homing", &m.bits.homing},
          {"homed", &m.bits.homed},
          {"fault", &m.bits.fault},
          {"probe_latched", &m.bits.probe_latched},
          {"in_position", &m.bits.in_position}};
      for (const auto& [key, out] : bits) {
        double b = 0;
        if (r.number(*t, "status_bits", key, 0, 15, true, b)) *out = static_cast<int>(b);
      }
    } else {
      r.problem("status_bits", "must be a table");
    }
  }
  if (const toml::node* n = root.get("alarms")) {
    if (const toml::table* t = n->as_table()) {
      for (const auto& [key, node] : *t) {
        const std::string k(key.str());
        long code = -1;
        try {
          std::size_t used = 0;
          code = std::stol(k, &used, 0);
          if (used != k.size()) code = -1;
        } catch (const std::exception&) {
          code = -1;
        }
        auto name = node.value_exact<std::string>();
        if (code < 0 || code > 0xFFFF)
          r.problem("alarms." + k, "the key must be an alarm code 0..65535 (decimal or 0x hex)");
        else if (!name)
          r.problem("alarms." + k, "must be a string (the alarm's name)");
        else
          m.alarm_names[static_cast<int>(code)] = *name;
      }
    } else {
      r.problem("alarms", "must be a table of code = \"name\"");
    }
  }
  m.init = r.writes(root, "init");
  m.move = r.writes(root, "move");
  m.home = r.writes(root, "home");
  m.stop = r.writes(root, "stop");
  m.reset = r.writes(root, "reset");
  m.probe_arm = r.writes(root, "probe_arm");

  if (const toml::node* n = root.get("axis")) {
    const toml::array* arr = n->as_array();
    if (arr == nullptr) {
      r.problem("axis", "must be an array of tables ([[axis]])");
    } else {
      for (std::size_t i = 0; i < arr->size(); ++i) {
        const std::string where = "axis[" + std::to_string(i + 1) + "]";
        const toml::table* t = arr->get(i)->as_table();
        if (t == nullptr) {
          r.problem(where, "must be a table");
          continue;
        }
        r.check_keys(*t, where, {"name", "unit", "counts_per_unit", "min", "max"});
        AxisMap a;
        std::string name;
        if (r.string(*t, where, "name", name)) {
          if (auto ax = axis_from_name(name))
            a.axis = *ax;
          else
            r.problem(where + ".name", "must be x, y, z or a, not \"" + name + "\"");
        } else if (!t->contains("name")) {
          r.problem(where + ".name", "missing");
        }
        double v = 0;
        if (r.number(*t, where, "unit", 1, 247, true, v)) a.unit = static_cast<int>(v);
        r.number(*t, where, "counts_per_unit", -1e12, 1e12, false, a.counts_per_unit);
        r.number(*t, where, "min", -1e9, 1e9, false, a.min);
        r.number(*t, where, "max", -1e9, 1e9, false, a.max);
        m.axes.push_back(a);
      }
    }
  }
  try {
    m.validate();
  } catch (const ConfigError& e) {
    problems.push_back(e.what());
  }
  if (!problems.empty()) {
    std::string msg = path + ": ";
    for (std::size_t i = 0; i < problems.size(); ++i) msg += (i ? "; " : "") + problems[i];
    throw ConfigError(msg);
  }
  return m;
}

}  // namespace scanmesh::drivers::modbus_stage
