// SimulatedSensor: a simulated scan delivered through the DisplacementSensor interface.
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/simulated_sensor.hpp"

#include <chrono>
#include <cmath>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"

namespace scanmesh::sim {

SimulatedSensor::SimulatedSensor(std::vector<drivers::SensorSample> samples,
                                 SimulatedSensorOptions options)
    : samples_(std::move(samples)), options_(std::move(options)) {
  if (!(options_.speed >= 0) || !std::isfinite(options_.speed))
    throw ConfigError(options_.name + ": speed must be >= 0 (0: as fast as possible)");
}

SimulatedSensor::~SimulatedSensor() { close(); }

void SimulatedSensor::open() {
  if (running_) return;
  state_.set(drivers::DeviceState::kOpen, "", nullptr);
}

void SimulatedSensor::close() noexcept {
  stop();
  state_.set(drivers::DeviceState::kClosed, "", nullptr);
}

void SimulatedSensor::start(drivers::SensorCallbacks callbacks) {
  if (running_) return;
  if (state_.get() == drivers::DeviceState::kClosed)
    throw drivers::DeviceError(drivers::DeviceErrorKind::kProtocol, options_.name, "start",
                               "open() first");
  callbacks_ = std::move(callbacks);
  running_ = true;
  state_.set(drivers::DeviceState::kAcquiring, options_.name + ": acquiring", &callbacks_);
  worker_.start([this](drivers::Worker& w) { run(w); },
                [this](const std::exception& e) {
                  state_.set(drivers::DeviceState::kLost,
                             options_.name + ": lost: " + e.what(), &callbacks_);
                });
}

void SimulatedSensor::stop() noexcept {
  if (!running_) return;
  worker_.stop();
  running_ = false;
  state_.set(drivers::DeviceState::kOpen, "", nullptr);  // no callback after stop()
}

drivers::DeviceIdentity SimulatedSensor::identify() const {
  return {"scanmesh", "simulated displacement sensor", "", "sim"};
}

drivers::SensorCapabilities SimulatedSensor::capabilities() const {
  drivers::SensorCapabilities c;
  if (samples_.size() >= 2) {
    const double span_s =
        static_cast<double>((samples_.back().t_host - samples_.front().t_host).count()) * 1e-9;
    if (span_s > 0) c.max_rate_hz = static_cast<double>(samples_.size() - 1) / span_s;
  }
  c.device_clock = !samples_.empty() && samples_.front().t_device.has_value();
  c.streaming = true;
  return c;
}

void SimulatedSensor::run(drivers::Worker& worker) {
  using namespace std::chrono;
  if (samples_.empty()) return;
  // Resume where a previous start() stopped: anchor the remaining samples to now.
  const std::size_t first = next_.load();
  const drivers::Timestamp anchor_rec = samples_[std::min(first, samples_.size() - 1)].t_host;
  const drivers::Timestamp anchor_now = drivers::monotonic_now();
  std::uint64_t last_seq = first > 0 ? samples_[first - 1].seq : 0;
  bool have_last = first > 0;
  for (std::size_t i = first; i < samples_.size(); ++i) {
    if (worker.stop_requested()) return;
    drivers::SensorSample s = samples_[i];
    if (options_.speed > 0) {
      const auto offset = nanoseconds(static_cast<std::int64_t>(
          static_cast<double>((s.t_host - anchor_rec).count()) / options_.speed));
      const drivers::Timestamp due = anchor_now + offset;
      const auto wait = due - drivers::monotonic_now();
      if (wait.count() > 0 && !worker.sleep_for(wait)) return;
      s.t_host = drivers::monotonic_now();
    }
    // Profile points share one seq: only a jump of more than one between measurements is a gap.
    if (have_last && s.seq > last_seq + 1) stats_.gaps.fetch_add(s.seq - last_seq - 1);
    last_seq = s.seq;
    have_last = true;
    stats_.samples.fetch_add(1);
    if (callbacks_.on_sample) callbacks_.on_sample(s);
    next_.store(i + 1);
  }
}

}  // namespace scanmesh::sim
