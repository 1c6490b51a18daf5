// EmulatedScanBackend: emulators + real drivers + DevicesBackend (see emulated_backend.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/emulators/emulated_backend.hpp"

#include "scanmesh/drivers/microepsilon_ild1420/device.hpp"
#include "scanmesh/drivers/transports/serial_stream.hpp"

namespace scanmesh::sim {

EmulatedScanBackend::EmulatedScanBackend(recon::Mesh part, const ScanSettings& settings,
                                         EmulatedBackendOptions options)
    : scanner_(std::make_unique<EmulatedScanner>(std::move(part), settings, options.scanner)) {
  // The sensor: the real ILD1420 driver on the emulator's pty, with the timestamp and counter
  // words in its output blocks (the emulator's layout "dclh"), so every sample carries the
  // instant it was measured: the accumulator maps that clock onto the host's, and a read that
  // comes late (a loaded host) does not smear a burst of samples onto one receive time. The
  // drivers' factory has no key for the block layout yet, so the device is built here on the
  // same transport the factory would give it.
  const acq::ScannerModel model = scanner_->model();
  drivers::SensorOptions so;
  so.name = model.sensors[0].name;
  so.timeout = options.sensor_timeout;
  so.timeouts_until_lost = options.sensor_timeouts_until_lost;
  so.backoff_initial = std::chrono::milliseconds(50);
  so.backoff_max = std::chrono::milliseconds(500);
  drivers::SerialSettings serial;
  serial.path = scanner_->sensor_port();
  serial.baud = drivers::microepsilon_ild1420::kDefaultBaud;
  drivers::microepsilon_ild1420::Options ild;
  ild.layout = drivers::microepsilon_ild1420::BlockLayout::distance_counter_timestamp();
  ild.max_rate_hz = scanner_->sensor_rate_hz();
  auto sensor = std::make_unique<drivers::microepsilon_ild1420::Device>(
      so, [name = so.name, serial] { return drivers::open_serial_stream(name, serial); }, ild);
  // The stage: the drivers' factory, as a configuration names it.
  drivers::StageConfig stage;
  stage.driver = "grbl";
  stage.port = scanner_->stage_port();
  stage.rotary_a = scanner_->rotary();
  stage.options.name = model.stage;
  stage.options.poll_interval = options.stage_poll;
  acq::DevicesBackendOptions dopt;
  dopt.sensor_driver = "microepsilon-ild1420";
  dopt.sensor_port = scanner_->sensor_port();
  dopt.stage_driver = stage.driver;
  dopt.stage_port = stage.port;
  devices_ = std::make_unique<acq::DevicesBackend>(
      std::move(sensor), drivers::make_motion_stage(stage), model, scanner_->program(), dopt);
}

EmulatedScanBackend::~EmulatedScanBackend() { stop(); }

void EmulatedScanBackend::start(acq::SampleInput& input) {
  stop();
  scanner_->start();
  try {
    devices_->start(input);
  } catch (...) {
    scanner_->stop();
    throw;
  }
}

void EmulatedScanBackend::stop() noexcept {
  devices_->stop();
  scanner_->stop();
}

}  // namespace scanmesh::sim
