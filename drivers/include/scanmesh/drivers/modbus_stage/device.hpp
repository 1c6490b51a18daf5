// Device class of Modbus servo / stepper drive stages: a MotionStage whose axes are drives on
// one Modbus line or TCP gateway (one unit per axis), described by a StageRegisterMap (see
// modbus_stage/codec.hpp for the models, documents and quirks).
// SPDX-License-Identifier: MIT
//
// Transport: RegisterBus from a RegisterBusFactory (libmodbus RTU or TCP), used only by the
//   worker (and by open()); select_unit() switches between the axes' drives.
// Behaviour:
//   - open(): runs the map's init writes on every drive, then reads every axis once (DeviceError
//     naming the device, the unit and the request otherwise).
//   - Position polling at StageOptions::poll_interval on a fixed schedule (a late poll shortens
//     the next pause; commands wake the worker at once): each poll reads position, status word
//     and alarm register of every axis and delivers one StageSample.
//   - Status: any drive faulted -> kAlarm with "<axis>: <alarm name>" and the drive's code; a
//     homing bit, or a homing command not yet finished -> kHoming; any drive moving -> kMoving.
//   - A Modbus exception is an error reply (counted; a command that got one throws it); timeouts
//     in a row make the stage lost.
//   - probe_move(): arms the probe latch of the moving drives, starts the move, polls until a
//     drive reports the latch (its latched position is read back: the position at the trigger,
//     not where the axes stopped) or every drive stands (no contact). A latch already set after
//     arming, before the move, is kTriggeredAtStart.
#pragma once

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "scanmesh/drivers/common/stage_base.hpp"
#include "scanmesh/drivers/modbus_stage/codec.hpp"
#include "scanmesh/drivers/register_bus.hpp"

namespace scanmesh::drivers::modbus_stage {

class Device final : public StageBase {
 public:
  /// Validates the map (throws ConfigError). `transport` opens the bus (and reopens it).
  Device(StageOptions options, RegisterBusFactory transport, StageRegisterMap map);
  ~Device() override;

  StageCapabilities capabilities() const override;

  void move_to(const StageTarget& target, double feed_mm_min) override;
  void move_by(const StageTarget& delta, double feed_mm_min) override;
  void jog(const StageTarget& delta, double feed_mm_min) override;
  void home() override;
  void halt() override;
  void clear_alarm() override;
  ProbeMoveResult probe_move(const ProbeMove& move) override;

  const StageRegisterMap& map() const { return map_; }

 private:
  /// Axis targets in the axis units (A in degrees), one per map axis (NaN: stays).
  std::vector<double> targets_of(const StageTarget& t, bool relative) const;
  /// Worker: starts the moves of the axes whose target differs (proportional feed shares).
  std::vector<std::size_t> start_moves(const std::vector<double>& targets, double feed_per_min);
  void write_list(const std::vector<RegisterWrite>& list, const AxisMap& axis,
                  std::int32_t target, double speed, double accel, const std::string& what);
  void command_all(const std::vector<RegisterWrite>& list, const std::string& what);
  /// Worker: reads every axis and delivers one report. Throws DeviceError from the bus.
  void poll_axes();
  ProbeMoveResult run_probe(const ProbeMove& move);
  [[noreturn]] void rethrow_named(const DeviceError& e, const AxisMap& axis,
                                  const std::string& operation) const;

  // ---- StageBase / lifecycle hooks ----
  void open_device() override;
  bool reconnect_once() override;
  Step acquire(std::string& timeout_detail) override;
  void drop_transport() noexcept override { bus_.reset(); }
  bool has_transport() const override { return bus_ != nullptr; }
  std::string lost_after_timeouts(int count, const std::string& detail) const override;
  void on_start() override;
  void on_reconnected() override;
  bool pause(Worker& worker) override;

  RegisterBusFactory factory_;
  StageRegisterMap map_;
  std::vector<ReadBlock> plan_;
  std::size_t image_size_ = 0;
  std::unique_ptr<RegisterBus> bus_;
  // Worker state.
  std::vector<std::uint16_t> image_;
  std::vector<AxisReading> readings_;
  std::chrono::steady_clock::time_point next_poll_{};
  bool homing_requested_ = false;
};

}  // namespace scanmesh::drivers::modbus_stage
