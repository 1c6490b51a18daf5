// Loads a Modbus drive-stage register map (StageRegisterMap, codec.hpp) from a TOML profile such
// as config/devices/leadshine-pr.toml. Part of scanmesh_device_factory (toml++ stays out of the
// pure driver library).
// SPDX-License-Identifier: MIT
//
// File format (unknown keys are errors; addresses are 0-based PDU holding-register addresses,
// TOML hex integers welcome):
//   profile = "leadshine-pr"            # name for messages; default: the file name
//   vendor = "..."  model = "..."
//   word_order = "high_first"           # high_first | low_first: every 32-bit register
//   speed_scale = 12                    # register value per unit/s ("speed" values)
//   accel_scale = 83333.3               # per unit/s^2 ("accel"), or over it ("accel_time")
//   max_speed = 250                     # units/s, 0 = no limit
//   accel = 1000                        # units/s^2 of every move
//   position = { address = 0x602A, type = "i32" }      # required; u16|i16|u32|i32
//   status = { address = 0x1003, type = "u16" }        # required
//   alarm = { address = 0x2203, type = "u16" }         # optional
//   probe_position = { address = 0x2212, type = "i32" } # optional (with [[probe_arm]])
//   [status_bits]  moving, homing, homed, fault, probe_latched, in_position = bit 0..15
//   [alarms]  "0x0E0" = "Er0E0 over-current"           # code (decimal or 0x hex) = name
//   [[init]] / [[move]] / [[home]] / [[stop]] / [[reset]] / [[probe_arm]]
//     address = 0x6200
//     values = [1, "target", "speed", "accel_time", "accel_time", 0, 0x10]
//              # integers 0..65535, or "target" (2 registers), "speed", "accel", "accel_time"
//   [[axis]]  name = "x"|"y"|"z"|"a", unit = 1..247, counts_per_unit = 2000, min, max
#pragma once

#include <string>

#include "scanmesh/drivers/modbus_stage/codec.hpp"

namespace scanmesh::drivers::modbus_stage {

/// Reads and validates a profile. Throws ConfigError naming the file and every bad key at once
/// ("config/devices/x.toml: move[1].values[2]: unknown placeholder \"sped\"; ...").
StageRegisterMap load_stage_profile(const std::string& path);

}  // namespace scanmesh::drivers::modbus_stage
