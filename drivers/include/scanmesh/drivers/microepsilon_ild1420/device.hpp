// Device class of the Micro-Epsilon optoNCDT ILD1420: identifies the sensor over its ASCII
// command interface and decodes its binary RS422 measurement stream (see codec.hpp).
// SPDX-License-Identifier: MIT
//
// Models: optoNCDT ILD1420 (MR 10..500 mm), also ILD1320/1220.
// Vendor document: optoNCDT 1420 manual §8 p. 84, §7.5.2 pp. 65-66, App. A3 pp. 94, 97
//   (PROTOCOLS.md §1.3).
// Transport: ByteStream (RS422 via USB adapter, 8N1, default 921600 baud, max 1 MBaud; the pty
//   emulator accepts the same rate). Streaming: the sensor pushes values, nothing is polled.
// Quirks: see codec.hpp. Command sessions stop the stream first (OUTPUT NONE), and acquisition
//   restarts it (OUTPUT RS422); binary values still in flight are separated from the reply.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "scanmesh/drivers/byte_stream.hpp"
#include "scanmesh/drivers/common/sensor_lifecycle.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/microepsilon_ild1420/codec.hpp"

namespace scanmesh::drivers::microepsilon_ild1420 {

/// ILD1420-specific options.
struct Options {
  /// Measuring range in mm, used when GETINFO does not report one (or does not answer).
  /// 0 (default) = GETINFO must tell it. Valid: 0 or 10, 25, 50, 100, 200, 500 (any > 0 is
  /// accepted for other models of the family).
  double measuring_range_mm = 0;
  /// Values of one output block, as configured on the sensor (GETOUTINFO_RS422). Default:
  /// distance only.
  BlockLayout layout;
  /// The sensor outputs mastered (18-bit) distances.
  bool mastering = false;
  /// Fastest measuring rate, for capabilities(). Default 4000 Hz.
  double max_rate_hz = 4000;
};

/// open() opens the port, stops the output (OUTPUT NONE), reads GETINFO. The output stays
/// stopped until start(). It throws DeviceError
/// ("ild0 (/dev/ttyUSB0): GETINFO: no reply within 500 ms") or, when neither GETINFO nor the
/// options give a measuring range, DeviceError kProtocol. start() sends OUTPUT RS422 and decodes
/// the stream on the worker thread.
class Device final : public SensorLifecycle {
 public:
  /// Throws ConfigError for an invalid layout or measuring range.
  Device(SensorOptions options, ByteStreamFactory transport, Options ild = {});
  ~Device() override;

  SensorCapabilities capabilities() const override;

  /// Measuring range in use (from GETINFO or the options).
  double measuring_range_mm() const { return scaling_.measuring_range_mm; }

 private:
  /// Sends a command and waits for its "->" prompt (binary bytes are skipped); bytes after the
  /// prompt are handed to the stream decoder when `stream_after` is set. Throws DeviceError.
  Reply command(const Command& cmd, bool stream_after);
  /// Sends OUTPUT RS422 (values after its prompt go to the decoder); an error reply is counted.
  void start_output();
  void deliver(std::span<const std::uint8_t> bytes, Timestamp t_host);

  // ---- SensorLifecycle hooks ----
  void open_device() override;
  bool reconnect_once() override;
  Step acquire(std::string& timeout_detail) override;
  void drop_transport() noexcept override { stream_.reset(); }
  bool has_transport() const override { return stream_ != nullptr; }
  std::string lost_after_timeouts(int count, const std::string& detail) const override;
  void on_start() override;

  ByteStreamFactory transport_;
  Options ild_;
  Scaling scaling_;
  std::unique_ptr<ByteStream> stream_;
  StreamDecoder decoder_;
  ReplyParser replies_;
  bool need_output_ = true;  // the worker's first step (re)starts the stream
  std::vector<std::uint8_t> buffer_;
};

}  // namespace scanmesh::drivers::microepsilon_ild1420
