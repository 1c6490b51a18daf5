// Modbus drive stage emulator: one emulated servo/stepper drive per axis (one Modbus unit each)
// behind a register map (StageRegisterMap: Leadshine-style PR block, Delta-style parameters),
// plugged into the Modbus TCP or RTU emulator. Moves, homing, stops, alarm resets and probe
// arming are the map's register writes; position, status word, alarm and probe latch are served
// from the per-axis motion model; the probe latches when its tip touches the reference mesh.
// SPDX-License-Identifier: MIT
//
// Decoding of the writes and encoding of the served registers are written here, apart from the
// driver's codec, so the tests check two readings of the same map against each other.
#pragma once

#include <array>
#include <functional>
#include <random>
#include <memory>
#include <mutex>
#include <vector>

#include "scanmesh/drivers/modbus_stage/codec.hpp"
#include "scanmesh/sim/emulators/modbus_emulator.hpp"
#include "scanmesh/sim/emulators/stage_motion.hpp"

namespace scanmesh::sim {

struct ModbusStageOptions {
  drivers::modbus_stage::StageRegisterMap map;  ///< registers of the drives and the axes
  /// Per-axis motion: limits.linear_* are each drive's own speed (units/s) and acceleration
  /// limits (mm or deg); start/home poses give every axis its start and home position (A in
  /// radians, as everywhere in StagePose). The probe (scene, calibration, tip radius, noise)
  /// sees the combined X/Y/Z/A pose.
  StageMotionOptions motion;
};

class ModbusStageModel final : public ModbusHandler {
 public:
  explicit ModbusStageModel(ModbusStageOptions options);

  ModbusTables tables(int unit) override;
  void before_reply(const ModbusRequest& request) override;
  void after_write(const ModbusRequest& request) override;

  /// Combined pose of the axes now (A in radians).
  StagePose pose(Timestamp now);
  /// Fault: the drive of `axis` goes into alarm `code` (it stops; its fault bit and alarm
  /// register say so until the map's reset write).
  void raise_alarm(drivers::StageAxis axis, int code);
  void set_probe_never_triggers(bool on);
  /// Every axis follows its component of `path` until `until` (A: path's a_rad).
  void follow(std::function<StagePose(Timestamp)> path, Timestamp until);
  /// Moves started through the move registers so far.
  std::uint64_t moves_started() const;

 private:
  struct Axis {
    drivers::modbus_stage::AxisMap map;
    std::vector<std::uint16_t> holding;
    std::unique_ptr<StageMotion> motion;  // 1-D: the axis position in its unit is x_mm
    bool armed = false, latched = false, homed = false, homing = false, fault = false;
    std::int64_t latched_counts = 0;
    int alarm_code = 0;
  };
  Axis* axis_of_unit(int unit);
  StagePose combined(Timestamp t);
  bool touching(const StagePose& p) const;
  /// Finds a probe contact between the last check and `now` and stops every axis there.
  void check_probe(Timestamp now);
  void refresh(Axis& a, Timestamp now);
  /// Whether the write [address, address+count) ends with the last write of `list` with its
  /// constants in place.
  bool matches(const Axis& a, const ModbusRequest& r,
               const std::vector<drivers::modbus_stage::RegisterWrite>& list) const;
  std::int64_t read_value(const Axis& a, std::uint16_t address, bool wide, bool is_signed) const;
  void start_move(Axis& a, Timestamp now);

  ModbusStageOptions options_;
  std::vector<Axis> axes_;
  std::vector<std::uint16_t> no_input_;
  mutable std::mutex mutex_;  // the emulator thread vs. tests (faults, pose)
  Timestamp last_check_{};
  bool never_triggers_ = false;
  std::uint64_t moves_started_ = 0;
  std::mt19937_64 rng_;
};

}  // namespace scanmesh::sim
