// Loads a Modbus sensor register map (RegisterMap, codec.hpp) from a TOML profile file such as
// config/devices/baumer-om30.toml. Part of scanmesh_device_factory (toml++ stays out of the
// pure driver library).
// SPDX-License-Identifier: MIT
//
// File format (every key optional unless marked; unknown keys are errors):
//   profile = "baumer-om30"      # name for messages; default: the file name without .toml
//   quality_critical = 2         # RegisterMap::quality_critical
//   max_gap = 16                 # RegisterMap::max_gap
//   max_rate_hz = 0              # capabilities, 0 = unknown
//   range_min_mm = 0
//   range_max_mm = 0
//   [identity]                   # strings read by open(): vendor, model, serial, firmware
//   vendor = { kind = "input", address = 0, count = 16 }
//   [[field]]                    # one per value; name/address/type required
//   name = "distance"            # distance|status|quality|alarm|timestamp_s|timestamp_us
//   kind = "input"               # input (FC04, default) | holding (FC03)
//   address = 202                # 0-based PDU address, 0..65535
//   type = "f32"                 # u16|i16|u32|i32|f32
//   word_order = "low_first"     # low_first (default) | high_first
//   scale = 1.0                  # value = raw * scale + offset
//   offset = 0.0
//   bit = 1                      # optional: this bit of an integer field (0/1)
#pragma once

#include <string>

#include "scanmesh/drivers/modbus_sensor/codec.hpp"

namespace scanmesh::drivers::modbus_sensor {

/// Reads and validates a profile. Throws ConfigError naming the file and every bad key at once
/// ("config/devices/x.toml: field[2].type: unknown type \"f64\"; ...").
RegisterMap load_register_map_profile(const std::string& path);

}  // namespace scanmesh::drivers::modbus_sensor
