// ScannerModel <-> JSON.
// SPDX-License-Identifier: MIT
#include "scanmesh/acquisition/scanner_json.hpp"

#include "scanmesh/common/error.hpp"

namespace scanmesh::acq {

namespace {

using nlohmann::json;

json vec(const Vec3& v) { return json::array({v.x(), v.y(), v.z()}); }

const json& field(const json& j, const char* key, const std::string& what) {
  if (!j.is_object() || !j.contains(key))
    throw InputError(what + ": missing field '" + key + "'");
  return j.at(key);
}

double number(const json& j, const char* key, const std::string& what) {
  const json& v = field(j, key, what);
  if (!v.is_number()) throw InputError(what + ": '" + key + "' must be a number");
  return v.get<double>();
}

std::int64_t integer(const json& j, const char* key, const std::string& what) {
  const json& v = field(j, key, what);
  if (!v.is_number_integer()) throw InputError(what + ": '" + key + "' must be an integer");
  return v.get<std::int64_t>();
}

Vec3 vec_from(const json& j, const char* key, const std::string& what) {
  const json& v = field(j, key, what);
  if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() ||
      !v[2].is_number())
    throw InputError(what + ": '" + key + "' must be 3 numbers");
  return {v[0].get<double>(), v[1].get<double>(), v[2].get<double>()};
}

}  // namespace

json to_json(const SensorConfig& c) {
  return json{{"kind", std::string(to_string(c.kind))},
              {"standoff_mm", c.standoff_mm},
              {"range_mm", c.range_mm},
              {"beam_dir", vec(c.beam_dir)},
              {"baseline_dir", vec(c.baseline_dir)},
              {"receiver_angle_rad", c.receiver_angle_rad},
              {"max_incidence_rad", c.max_incidence_rad},
              {"rate_hz", c.rate_hz},
              {"fan_dir", vec(c.fan_dir)},
              {"profile_points", c.profile_points},
              {"fan_angle_rad", c.fan_angle_rad},
              {"tip_radius_mm", c.tip_radius_mm},
              {"probe_speed_mm_s", c.probe_speed_mm_s}};
}

json to_json(const Calibration& c) {
  json mount = json::array();
  const Eigen::Matrix3d r = c.mount.linear();
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) mount.push_back(r(i, k));
  for (int i = 0; i < 3; ++i) mount.push_back(c.mount.translation()[i]);
  return json{{"mount", mount}, {"table_center_mm", vec(c.table_center_mm)}};
}

json to_json(const AccumulatorConfig& c) {
  return json{{"sensor_latency_ns", c.sensor_latency.count()},
              {"stage_latency_ns", c.stage_latency.count()},
              {"max_pose_gap_ns", c.max_pose_gap.count()},
              {"max_hold_ns", c.max_hold.count()},
              {"history_horizon_ns", c.history_horizon.count()},
              {"use_device_clock", c.use_device_clock},
              {"clock_block_samples", c.clock.block_samples},
              {"clock_blocks", c.clock.blocks}};
}

json to_json(const ScannerModel& m) {
  json sensors = json::array();
  for (const auto& s : m.sensors)
    sensors.push_back(
        json{{"name", s.name}, {"config", to_json(s.config)}, {"calibration", to_json(s.calibration)}});
  return json{{"sensors", sensors}, {"stage", m.stage}, {"accumulator", to_json(m.accumulator)}};
}

SensorConfig sensor_config_from_json(const json& j, const std::string& what) {
  SensorConfig c;
  const json& kind = field(j, "kind", what);
  if (!kind.is_string()) throw InputError(what + ": 'kind' must be a string");
  try {
    c.kind = sensor_kind_from_string(kind.get<std::string>());
  } catch (const ConfigError& e) {
    throw InputError(what + ": " + e.what());
  }
  c.standoff_mm = number(j, "standoff_mm", what);
  c.range_mm = number(j, "range_mm", what);
  c.beam_dir = vec_from(j, "beam_dir", what);
  c.baseline_dir = vec_from(j, "baseline_dir", what);
  c.receiver_angle_rad = number(j, "receiver_angle_rad", what);
  c.max_incidence_rad = number(j, "max_incidence_rad", what);
  c.rate_hz = number(j, "rate_hz", what);
  c.fan_dir = vec_from(j, "fan_dir", what);
  const auto pp = integer(j, "profile_points", what);
  if (pp < 1 || pp > 65536) throw InputError(what + ": 'profile_points' out of range");
  c.profile_points = static_cast<std::uint32_t>(pp);
  c.fan_angle_rad = number(j, "fan_angle_rad", what);
  c.tip_radius_mm = number(j, "tip_radius_mm", what);
  c.probe_speed_mm_s = number(j, "probe_speed_mm_s", what);
  const auto problems = c.problems();
  if (!problems.empty()) throw InputError(what + ": " + problems.front());
  return c;
}

Calibration calibration_from_json(const json& j, const std::string& what) {
  const json& m = field(j, "mount", what);
  if (!m.is_array() || m.size() != 12)
    throw InputError(what + ": 'mount' must be 12 numbers (rotation row by row, translation)");
  double v[12];
  for (std::size_t i = 0; i < 12; ++i) {
    if (!m[i].is_number()) throw InputError(what + ": 'mount' must be 12 numbers");
    v[i] = m[i].get<double>();
  }
  Calibration c;
  Eigen::Matrix3d r;
  r << v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8];
  c.mount.linear() = r;
  c.mount.translation() = Vec3(v[9], v[10], v[11]);
  c.table_center_mm = vec_from(j, "table_center_mm", what);
  return c;
}

AccumulatorConfig accumulator_config_from_json(const json& j, const std::string& what) {
  AccumulatorConfig c;
  using std::chrono::nanoseconds;
  c.sensor_latency = nanoseconds(integer(j, "sensor_latency_ns", what));
  c.stage_latency = nanoseconds(integer(j, "stage_latency_ns", what));
  c.max_pose_gap = nanoseconds(integer(j, "max_pose_gap_ns", what));
  c.max_hold = nanoseconds(integer(j, "max_hold_ns", what));
  c.history_horizon = nanoseconds(integer(j, "history_horizon_ns", what));
  const json& dc = field(j, "use_device_clock", what);
  if (!dc.is_boolean()) throw InputError(what + ": 'use_device_clock' must be true or false");
  c.use_device_clock = dc.get<bool>();
  c.clock.block_samples = static_cast<std::uint32_t>(integer(j, "clock_block_samples", what));
  c.clock.blocks = static_cast<std::uint32_t>(integer(j, "clock_blocks", what));
  const auto problems = c.problems();
  if (!problems.empty()) throw InputError(what + ": " + problems.front());
  return c;
}

ScannerModel scanner_model_from_json(const json& j, const std::string& what) {
  ScannerModel m;
  const json& sensors = field(j, "sensors", what);
  if (!sensors.is_array()) throw InputError(what + ": 'sensors' must be an array");
  for (const json& s : sensors) {
    const json& name = field(s, "name", what);
    if (!name.is_string()) throw InputError(what + ": a sensor's 'name' must be a string");
    const std::string w = what + ": sensor " + name.get<std::string>();
    m.sensors.push_back({name.get<std::string>(),
                         sensor_config_from_json(field(s, "config", w), w),
                         calibration_from_json(field(s, "calibration", w), w)});
  }
  const json& stage = field(j, "stage", what);
  if (!stage.is_string()) throw InputError(what + ": 'stage' must be a string");
  m.stage = stage.get<std::string>();
  m.accumulator = accumulator_config_from_json(field(j, "accumulator", what), what + ": accumulator");
  return m;
}

}  // namespace scanmesh::acq
