// Reading scan.start's parameters (JSON scalars) with errors that name the key; shared by the
// pipeline engine (its own parameters) and the backend factories (theirs).
// SPDX-License-Identifier: MIT
#pragma once

#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "scanmesh/daemon/engine.hpp"
#include "scanmesh/daemon/protocol.hpp"

namespace scanmesh::daemon::params {

[[noreturn]] inline void bad(const std::string& key, const std::string& what) {
  throw EngineError(proto::errc::kBadArgument, "parameters." + key + ": " + what);
}

inline double number(const std::string& key, const Scalar& v, double lo, double hi) {
  double d = 0;
  if (const auto* i = std::get_if<std::int64_t>(&v))
    d = static_cast<double>(*i);
  else if (const auto* f = std::get_if<double>(&v))
    d = *f;
  else
    bad(key, "must be a number");
  if (!(d >= lo && d <= hi)) {
    std::ostringstream m;
    m << "must be in [" << lo << ", " << hi << "], got " << d;
    bad(key, m.str());
  }
  return d;
}

inline std::string string(const std::string& key, const Scalar& v) {
  if (const auto* s = std::get_if<std::string>(&v)) return *s;
  bad(key, "must be a string");
}

inline nlohmann::json to_json(const Parameters& p) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [k, v] : p) std::visit([&, key = k](const auto& x) { j[key] = x; }, v);
  return j;
}

/// The inverse of to_json (scalars only; anything else is skipped).
inline Parameters from_json(const nlohmann::json& j) {
  Parameters p;
  if (!j.is_object()) return p;
  for (const auto& [k, v] : j.items()) {
    if (v.is_boolean())
      p[k] = v.get<bool>();
    else if (v.is_number_integer())
      p[k] = v.get<std::int64_t>();
    else if (v.is_number())
      p[k] = v.get<double>();
    else if (v.is_string())
      p[k] = v.get<std::string>();
  }
  return p;
}

}  // namespace scanmesh::daemon::params
