// PolledSerialSensor: the SensorLifecycle of the request/response ASCII sensor drivers over a
// ByteStream (KEYENCE LK-G / IL, Panasonic HL-G1): open and identify, one exchange per worker step,
// lost / reconnect through the ByteStream factory. A driver adds only its protocol through a few
// hooks.
// SPDX-License-Identifier: MIT
//
// Behaviour (drivers/README.md "How a device behaves"):
// - open() creates the transport through the factory, discards stale input and makes the device
//   answer one exchange; failures are DeviceError naming the device, the port, the operation and
//   the device's own words ("lkg0 (/dev/ttyUSB0): M0: no reply within 500 ms").
// - One exchange: send request() (nothing when it is empty: the device pushes records on its
//   own), then feed whatever arrives to the driver's codec until it reports the answer or the
//   reply timeout expires.
// - After timeouts_until_lost timeouts in a row, or any exception from the transport (port
//   gone, write timeout), the state becomes kLost; the worker reopens the transport with
//   bounded exponential backoff until the device answers again.
// Threading: open/close/start/stop from the owner's thread; the hooks run on that thread during
// open() and on the worker thread while running, never concurrently.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>

#include "scanmesh/drivers/byte_stream.hpp"
#include "scanmesh/drivers/common/sensor_lifecycle.hpp"

namespace scanmesh::drivers {

class PolledSerialSensor : public SensorLifecycle {
 public:
  /// Stops the worker (a subclass must call close() in its own destructor too: the worker calls
  /// its hooks, which must not outlive the subclass's members).
  ~PolledSerialSensor() override;

 protected:
  /// One exchange in progress: the driver's feed() reports what its codec found through it.
  /// Polling: the first sample, error reply or malformed reply ends the exchange, anything after
  /// it is stale. Streaming (empty request): every record is a sample, the exchange ends after
  /// the chunk that brought at least one.
  class Exchange {
   public:
    /// True once the exchange has its answer: later replies in the same chunk are stale.
    bool done() const { return done_; }
    /// A measurement (t_host, status and value_mm filled in by the driver); it is numbered and
    /// delivered to the callback when the exchange emits samples.
    void sample(SensorSample& sample);
    /// An error reply of the device: counted; detail is its text for messages.
    void error_reply(std::string detail);
    /// Bytes the codec rejected: counted; when polling, the exchange ends as an error.
    void malformed(std::string_view why);
    /// A well-formed reply that cannot be used (detail says why): counted as malformed.
    void invalid(std::string detail);

   private:
    friend class PolledSerialSensor;
    enum class Outcome { kSample, kError, kTimeout };
    Exchange(PolledSerialSensor& owner, bool emit) : owner_(owner), emit_(emit) {}
    PolledSerialSensor& owner_;
    bool emit_;
    bool done_ = false;
    Outcome outcome_ = Outcome::kTimeout;
    std::string detail_;
  };

  static constexpr std::size_t kMaxReadBuffer = 512;
  /// read_buffer: bytes read from the transport at most per read_some() (1 .. kMaxReadBuffer).
  PolledSerialSensor(SensorOptions options, ByteStreamFactory transport,
                     std::size_t read_buffer = 256);

  /// Validates the common options (timeout 1 ms .. 60 s, timeouts_until_lost >= 1, a factory);
  /// throws ConfigError. Called by the subclass constructor after its own checks.
  void check_options() const;

  // ---- protocol hooks ----
  /// Bytes of one request. Empty: nothing is sent, the device streams records on its own.
  virtual std::string_view request() const = 0;
  /// Operation named in messages: "M0" in "lkg0 (/dev/ttyS0): M0: no reply within 100 ms".
  virtual std::string operation() const = 0;
  /// Operation named in open() errors (default: operation()).
  virtual std::string open_operation() const { return operation(); }
  /// What the device says it is, once it answered in open().
  virtual DeviceIdentity device_identity() const = 0;
  /// Feeds one received chunk (arrived at t_host) to the codec and reports every reply that
  /// concerns this device to the exchange (nothing reported: more bytes are needed).
  virtual void feed(std::span<const std::uint8_t> bytes, Timestamp t_host, Exchange& exchange) = 0;
  /// Drops the codec's partial input (after a timeout and with the transport).
  virtual void reset_codec() = 0;

 private:
  using Outcome = Exchange::Outcome;
  bool streaming() const { return request().empty(); }
  /// One exchange; samples go to the callback when emit. detail explains a non-sample.
  Outcome exchange(bool emit, std::string& detail);
  void emit(SensorSample& sample);
  std::string where() const;

  // ---- SensorLifecycle hooks ----
  void open_device() override;
  bool reconnect_once() override;
  Step acquire(std::string& timeout_detail) override;
  void drop_transport() noexcept override { transport_.reset(); }
  bool has_transport() const override { return transport_ != nullptr; }
  std::string lost_after_timeouts(int count, const std::string& detail) const override;
  void on_timeout() override;
  bool pause(Worker& worker) override;

  ByteStreamFactory factory_;
  std::size_t read_buffer_;
  std::unique_ptr<ByteStream> transport_;  // used by the worker while running
};

}  // namespace scanmesh::drivers
