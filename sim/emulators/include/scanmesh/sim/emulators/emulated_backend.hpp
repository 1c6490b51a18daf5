// The simulated scanner through the real drivers: the GRBL and ILD1420 protocol emulators on
// ptys (EmulatedScanner), the real grbl and microepsilon-ild1420 drivers opened on them by the
// drivers' factory, and the DevicesBackend running the scan program over those drivers. What the
// CLI's `scan --sim` and the daemon's [sim] transport = "emulators" run.
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <memory>

#include "scanmesh/acquisition/devices_backend.hpp"
#include "scanmesh/sim/emulators/emulated_scanner.hpp"

namespace scanmesh::sim {

struct EmulatedBackendOptions {
  EmulatedScannerOptions scanner;
  /// Stage position report (status poll) period. Default 5 ms (200 Hz).
  std::chrono::microseconds stage_poll{5000};
  /// The sensor driver's read timeout and the timeouts until it counts as lost (how fast a
  /// silent sensor is noticed). Defaults 100 ms and 2.
  std::chrono::milliseconds sensor_timeout{100};
  int sensor_timeouts_until_lost = 2;
};

/// A ScanBackend: start() starts the emulators, then the DevicesBackend (which opens the drivers
/// on the emulators' ports); stop() stops both, the drivers first.
class EmulatedScanBackend final : public acq::ScanBackend {
 public:
  /// Throws ConfigError for settings the emulators cannot do (see EmulatedScanner).
  EmulatedScanBackend(recon::Mesh part, const ScanSettings& settings,
                      EmulatedBackendOptions options = {});
  ~EmulatedScanBackend() override;

  std::string_view kind() const override { return "emulators"; }
  acq::ScannerModel model() const override { return devices_->model(); }
  std::vector<acq::DeviceStatus> devices() const override { return devices_->devices(); }
  void start(acq::SampleInput& input) override;
  void pause() override { devices_->pause(); }
  void resume() override { devices_->resume(); }
  void stop() noexcept override;

  EmulatedScanner& scanner() { return *scanner_; }
  acq::DevicesBackend& devices_backend() { return *devices_; }

 private:
  std::unique_ptr<EmulatedScanner> scanner_;
  std::unique_ptr<acq::DevicesBackend> devices_;
};

}  // namespace scanmesh::sim
