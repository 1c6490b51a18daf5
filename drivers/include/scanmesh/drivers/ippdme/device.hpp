// Device class of CMM controllers speaking I++ DME: a MotionStage client over a TCP ByteStream
// (session, tagged transactions, the OnMoveReportE daemon, GoTo, Home, PtMeas, AbortE,
// ClearAllErrors); see ippdme/codec.hpp for the protocol and its quirks.
// SPDX-License-Identifier: MIT
//
// Behaviour:
//   - open(): StartSession(), OnPtMeasReport(X(), Y(), Z(), IJK()), the OnMoveReportE daemon on
//     E0001, GetDMEVersion() and the tool radius (GetProp(Tool.A.Radius()) [unverified]), then
//     one Get(X(), Y(), Z()); DeviceError naming the device, the command and the server's error.
//   - Positions: while no motion transaction is open, Get(X(), Y(), Z()[, R()]) at the poll
//     interval; while one is, the daemon's E0001 reports (the normal queue is busy with the
//     motion). A Get without reply, or a motion without a report, within the timeout is a
//     timeout; timeouts in a row make the stage lost.
//   - Commands in flight on the normal queue are bounded (Options::max_in_flight); more wait in
//     the driver. A reply for a tag that is not in flight is counted (malformed) and ignored.
//   - move_to() returns at the server's `&`; the motion ends with its `%` (status kMoving until
//     then, kHoming for Home()). An error of severity >= 2 is an alarm with its number and text
//     until clear_alarm() (ClearAllErrors()).
//   - probe_move(): PtMeas with the nominal point half the travel ahead and Approach = Search =
//     travel / 2 (so the search starts where the probe stands and covers the travel), Retract
//     back to the start; the server's compensated point and normal become ProbeTrigger::surface,
//     the tip centre (surface + radius * normal) its pose. 1006 "Surface not found" is
//     kNoContact, 1001 "Illegal touch" kTriggeredAtStart; both are cleared (ClearAllErrors()).
//   - halt(): AbortE() on the fast queue, then ClearAllErrors().
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <string>

#include "scanmesh/drivers/byte_stream.hpp"
#include "scanmesh/drivers/common/stage_base.hpp"
#include "scanmesh/drivers/ippdme/codec.hpp"

namespace scanmesh::drivers::ippdme {

struct Options {
  /// Transactions on the normal queue in flight at once. Default 8; valid 1..64.
  int max_in_flight = 8;
  /// The CMM has a rotary table (R() in degrees). Default false.
  bool rotary_table = false;
};

class Device final : public StageBase {
 public:
  Device(StageOptions options, ByteStreamFactory transport, Options ipp = {});
  ~Device() override;

  StageCapabilities capabilities() const override;

  void move_to(const StageTarget& target, double feed_mm_min) override;
  void move_by(const StageTarget& delta, double feed_mm_min) override;
  void jog(const StageTarget& delta, double feed_mm_min) override;
  void home() override;
  void halt() override;
  void clear_alarm() override;
  ProbeMoveResult probe_move(const ProbeMove& move) override;

  /// Replies whose tag was not in flight (also counted in stats().malformed).
  std::uint64_t unknown_tags() const { return unknown_tags_.load(); }
  /// Tip radius the server reported (0: unknown).
  double tip_radius_mm() const { return tip_radius_mm_.load(); }
  /// Most transactions that were in flight at once on the normal queue.
  int max_in_flight_seen() const { return max_seen_.load(); }

 private:
  enum class Kind { kPlain, kMotion, kHome, kGet };
  struct Transaction {
    Tag tag;
    std::string method;
    Kind kind = Kind::kPlain;
    std::function<void()> on_ack;
    std::function<void(const Reply&)> on_data;
    std::function<void()> on_done;
    std::function<void(const Reply&)> on_error;
  };

  void submit(Transaction t);
  void send(Transaction t);
  void flush();
  void dispatch(const Reply& r, Timestamp t_host, bool& answered);
  void fail_all(const std::string& reason);
  /// Before the worker runs: submits `method` and reads until it completes; throws DeviceError.
  void transact_sync(const std::string& method, std::function<void(const Reply&)> on_data = {});
  void read_once(std::chrono::milliseconds wait, bool& answered);
  void handshake();
  std::string where() const;
  std::string position_items() const;
  StagePose pose_from(const Reply& r, StagePose base) const;
  StageStatus motion_status() const;
  /// Submits a transaction from a caller thread and waits for its ack (or its end).
  void call_transaction(const std::string& op, const std::string& method, Kind kind,
                        bool wait_done, std::chrono::milliseconds timeout);
  std::string goto_method(const StageTarget& target, const StagePose& from) const;

  // ---- StageBase / lifecycle hooks ----
  void open_device() override;
  bool reconnect_once() override;
  Step acquire(std::string& timeout_detail) override;
  void drop_transport() noexcept override;
  bool has_transport() const override { return transport_ != nullptr; }
  std::string lost_after_timeouts(int count, const std::string& detail) const override;
  void on_start() override;
  void on_reconnected() override;

  ByteStreamFactory factory_;
  Options ipp_;
  std::unique_ptr<ByteStream> transport_;
  Decoder decoder_;
  std::atomic<std::uint64_t> unknown_tags_{0};
  std::atomic<double> tip_radius_mm_{0};
  std::atomic<int> max_seen_{0};

  // Worker state (open()/reconnect, then only the worker).
  std::map<std::uint32_t, Transaction> open_;  // normal tags in flight
  std::map<std::uint32_t, Transaction> events_;  // E-tags in flight (fast queue)
  std::deque<Transaction> waiting_;
  std::uint32_t next_tag_ = 1;
  std::uint32_t next_event_ = 2;  // E0001 is the move-report daemon
  int motions_open_ = 0;
  int homes_open_ = 0;
  bool get_outstanding_ = false;
  std::chrono::steady_clock::time_point get_sent_{};
  std::chrono::steady_clock::time_point next_poll_{};
  std::chrono::steady_clock::time_point last_report_{};
  std::string version_;
};

}  // namespace scanmesh::drivers::ippdme
