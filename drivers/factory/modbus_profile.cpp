// TOML profile loader of the generic Modbus sensor (see modbus_sensor/profile.hpp).
// SPDX-License-Identifier: MIT
#include <toml++/toml.h>

#include <filesystem>
#include <set>
#include <string_view>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/modbus_sensor/profile.hpp"

namespace scanmesh::drivers::modbus_sensor {

namespace {

class Reader {
 public:
  explicit Reader(std::vector<std::string>& problems) : problems_(problems) {}

  void check_keys(const toml::table& t, const std::string& where,
                  std::initializer_list<std::string_view> allowed) {
    for (const auto& [key, node] : t) {
      (void)node;
      bool ok = false;
      for (auto a : allowed) ok = ok || a == key.str();
      if (!ok) problem(join(where, std::string(key.str())), "unknown key");
    }
  }

  template <class T>
  bool number(const toml::table& t, const std::string& where, std::string_view key, T& out,
              double lo, double hi) {
    const toml::node* n = t.get(key);
    if (n == nullptr) return false;
    double v = 0;
    if (auto i = n->value_exact<std::int64_t>()) {
      v = static_cast<double>(*i);
    } else if (auto d = n->value_exact<double>()) {
      v = *d;
    } else {
      problem(join(where, std::string(key)), "must be a number");
      return false;
    }
    if (!(v >= lo && v <= hi)) {
      problem(join(where, std::string(key)), "must be in " + fmt(lo) + " .. " + fmt(hi));
      return false;
    }
    if constexpr (std::is_integral_v<T>) {
      if (v != static_cast<double>(static_cast<std::int64_t>(v))) {
        problem(join(where, std::string(key)), "must be an integer");
        return false;
      }
    }
    out = static_cast<T>(v);
    return true;
  }

  bool string(const toml::table& t, const std::string& where, std::string_view key,
              std::string& out) {
    const toml::node* n = t.get(key);
    if (n == nullptr) return false;
    if (auto s = n->value_exact<std::string>()) {
      out = *s;
      return true;
    }
    problem(join(where, std::string(key)), "must be a string");
    return false;
  }

  RegisterKind kind(const toml::table& t, const std::string& where) {
    std::string s;
    if (!string(t, where, "kind", s) || s == "input") return RegisterKind::kInput;
    if (s == "holding") return RegisterKind::kHolding;
    problem(join(where, "kind"), "must be \"input\" or \"holding\", not \"" + s + "\"");
    return RegisterKind::kInput;
  }

  void problem(const std::string& key, const std::string& what) {
    problems_.push_back(key + ": " + what);
  }

  static std::string join(const std::string& where, const std::string& key) {
    return where.empty() ? key : where + "." + key;
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

}  // namespace

RegisterMap load_register_map_profile(const std::string& path) {
  toml::table root;
  try {
    root = toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    const auto& where = e.source().begin;
    throw ConfigError(path + ":" + std::to_string(where.line) + ":" + std::to_string(where.column) +
                      ": " + std::string(e.description()));
  }
  std::vector<std::string> problems;
  Reader r(problems);
  RegisterMap map;
  map.profile = std::filesystem::path(path).stem().string();
  r.check_keys(root, "",
               {"profile", "quality_critical", "max_gap", "max_rate_hz", "range_min_mm",
                "range_max_mm", "identity", "field"});
  r.string(root, "", "profile", map.profile);
  r.number(root, "", "quality_critical", map.quality_critical, 0, 65535);
  r.number(root, "", "max_gap", map.max_gap, 0, 100);
  r.number(root, "", "max_rate_hz", map.max_rate_hz, 0, 1e9);
  r.number(root, "", "range_min_mm", map.range_min_mm, -1e6, 1e6);
  r.number(root, "", "range_max_mm", map.range_max_mm, -1e6, 1e6);

  if (const toml::node* id = root.get("identity")) {
    if (const toml::table* t = id->as_table()) {
      r.check_keys(*t, "identity", {"vendor", "model", "serial", "firmware"});
      const std::pair<std::string_view, std::optional<RegisterString>*> entries[] = {
          {"vendor", &map.vendor},
          {"model", &map.model},
          {"serial", &map.serial},
          {"firmware", &map.firmware}};
      for (const auto& [key, out] : entries) {
        const toml::node* n = t->get(key);
        if (n == nullptr) continue;
        const std::string where = "identity." + std::string(key);
        const toml::table* s = n->as_table();
        if (s == nullptr) {
          r.problem(where, "must be a table { kind, address, count }");
          continue;
        }
        r.check_keys(*s, where, {"kind", "address", "count"});
        RegisterString rs;
        rs.kind = r.kind(*s, where);
        if (!r.number(*s, where, "address", rs.address, 0, 65535))
          if (!s->contains("address")) r.problem(Reader::join(where, "address"), "missing");
        if (!r.number(*s, where, "count", rs.count, 1, 125))
          if (!s->contains("count")) r.problem(Reader::join(where, "count"), "missing");
        *out = rs;
      }
    } else {
      r.problem("identity", "must be a table");
    }
  }

  if (const toml::node* fn = root.get("field")) {
    const toml::array* arr = fn->as_array();
    if (arr == nullptr) {
      r.problem("field", "must be an array of tables ([[field]])");
    } else {
      for (std::size_t i = 0; i < arr->size(); ++i) {
        const std::string where = "field[" + std::to_string(i + 1) + "]";
        const toml::table* t = arr->get(i)->as_table();
        if (t == nullptr) {
          r.problem(where, "must be a table");
          continue;
        }
        r.check_keys(*t, where,
                     {"name", "kind", "address", "type", "word_order", "scale", "offset", "bit"});
        RegisterField f;
        if (!r.string(*t, where, "name", f.name) && !t->contains("name"))
          r.problem(where + ".name", "missing");
        f.kind = r.kind(*t, where);
        if (!r.number(*t, where, "address", f.address, 0, 65535) && !t->contains("address"))
          r.problem(where + ".address", "missing");
        std::string type;
        if (r.string(*t, where, "type", type)) {
          if (auto ft = field_type_from_string(type))
            f.type = *ft;
          else
            r.problem(where + ".type", "unknown type \"" + type + "\" (u16, i16, u32, i32, f32)");
        } else if (!t->contains("type")) {
          r.problem(where + ".type", "missing");
        }
        std::string order;
        if (r.string(*t, where, "word_order", order)) {
          if (order == "low_first")
            f.word_order = WordOrder::kLowFirst;
          else if (order == "high_first")
            f.word_order = WordOrder::kHighFirst;
          else
            r.problem(where + ".word_order", "must be \"low_first\" or \"high_first\"");
        }
        r.number(*t, where, "scale", f.scale, -1e12, 1e12);
        r.number(*t, where, "offset", f.offset, -1e12, 1e12);
        r.number(*t, where, "bit", f.bit, 0, 31);
        map.fields.push_back(std::move(f));
      }
    }
  }
  // The map's own checks (duplicates, missing distance, bit vs type, ...), reported together.
  try {
    map.validate();
  } catch (const ConfigError& e) {
    problems.push_back(e.what());
  }
  if (!problems.empty()) {
    std::string msg = path + ": ";
    for (std::size_t i = 0; i < problems.size(); ++i) msg += (i ? "; " : "") + problems[i];
    throw ConfigError(msg);
  }
  return map;
}

}  // namespace scanmesh::drivers::modbus_sensor
