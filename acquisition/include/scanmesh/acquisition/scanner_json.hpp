// The scanner model (sensors' optics and calibrated mountings, the accumulator's timing) as
// JSON: recorded in every scan journal's parameters so that a replay maps samples exactly as the
// live scan did. Numbers round-trip exactly.
// SPDX-License-Identifier: MIT
#pragma once

#include <nlohmann/json.hpp>

#include "scanmesh/acquisition/backend.hpp"

namespace scanmesh::acq {

nlohmann::json to_json(const SensorConfig& config);
nlohmann::json to_json(const Calibration& calibration);
nlohmann::json to_json(const AccumulatorConfig& config);
nlohmann::json to_json(const ScannerModel& model);

/// Inverses; throw InputError naming the missing or mistyped field (`what` prefixes messages).
SensorConfig sensor_config_from_json(const nlohmann::json& j, const std::string& what);
Calibration calibration_from_json(const nlohmann::json& j, const std::string& what);
AccumulatorConfig accumulator_config_from_json(const nlohmann::json& j, const std::string& what);
ScannerModel scanner_model_from_json(const nlohmann::json& j, const std::string& what);

}  // namespace scanmesh::acq
