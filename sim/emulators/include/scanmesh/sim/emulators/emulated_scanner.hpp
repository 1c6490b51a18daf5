// The simulated scanner on the device side of real protocols: a GRBL controller emulator moving
// the stage and a Micro-Epsilon ILD1420 emulator whose laser ray-casts the part at the stage's
// pose of each measurement, both on ptys for the real drivers to open.
// SPDX-License-Identifier: MIT
#pragma once

#include <filesystem>
#include <memory>
#include <random>
#include <string>

#include "scanmesh/acquisition/backend.hpp"
#include "scanmesh/acquisition/scan_program.hpp"
#include "scanmesh/recon/mesh.hpp"
#include "scanmesh/sim/emulators/grbl.hpp"
#include "scanmesh/sim/emulators/microepsilon_ild1420.hpp"
#include "scanmesh/sim/scan_settings.hpp"
#include "scanmesh/sim/simulator.hpp"

namespace scanmesh::sim {

struct EmulatedScannerOptions {
  /// Folder for the ports' links (sensor: ild0, stage: grbl0); empty: a fresh one under the
  /// temporary directory, removed with the scanner.
  std::filesystem::path port_dir;
  /// ILD1420 output blocks per 1 ms tick: the measuring rate in kHz, 1 .. 100. Default 10.
  int sensor_blocks_per_tick = 10;
  /// The ILD1420 model's measuring range, mm (10, 25, 50, 100, 200, 500). Default 50.
  double measuring_range_mm = 50;
  std::string sensor_name = "ild0";
  std::string stage_name = "grbl0";
};

/// The device side of a simulated scan. Plans the settings' path over the part (a point sensor
/// only: the ILD1420 is one), sets the GRBL emulator's axes to the plan's start and limits, and
/// feeds the ILD1420 emulator from a ray cast at `motion().pose(t)` of each measurement instant
/// through the sensor's mounting (the same RayTracer as the Simulator), with the settings'
/// range noise and dropouts. The scan motion itself is the host's job: program() is the plan as
/// absolute moves, for a DevicesBackend to send to the real GRBL driver.
class EmulatedScanner {
 public:
  /// Throws ConfigError for settings the emulators cannot do (a line profiler, a touch probe).
  EmulatedScanner(recon::Mesh part, const ScanSettings& settings,
                  EmulatedScannerOptions options = {});
  ~EmulatedScanner();
  EmulatedScanner(const EmulatedScanner&) = delete;
  EmulatedScanner& operator=(const EmulatedScanner&) = delete;

  void start();  ///< opens the ptys and starts both emulators
  void stop() noexcept;

  const std::string& sensor_port() const { return sensor_->port(); }
  const std::string& stage_port() const { return stage_->port(); }
  bool rotary() const { return rotary_; }  ///< the stage has an A axis (rotary and views paths)
  /// The sensor's optics and mounting (what calibration would give for a real machine).
  acq::ScannerModel model() const;
  /// The plan's moves as absolute moves with feeds.
  acq::ScanProgram program() const;
  double sensor_rate_hz() const { return 1000.0 * options_.sensor_blocks_per_tick; }
  const Simulator& planner() const { return *simulator_; }

  MicroEpsilonIld1420Emulator& sensor_emulator() { return *sensor_; }
  GrblEmulator& stage_emulator() { return *stage_; }

 private:
  drivers::SensorSample measure(drivers::Timestamp t);

  EmulatedScannerOptions options_;
  std::filesystem::path owned_dir_;
  std::unique_ptr<Scene> scene_;
  std::unique_ptr<Simulator> simulator_;  // the plan, the optics, the tracer's settings
  std::unique_ptr<RayTracer> tracer_;
  bool rotary_ = false;
  double noise_mm_ = 0;
  double dropout_ = 0;
  std::mt19937_64 rng_;  // the sensor emulator's thread only
  std::unique_ptr<GrblEmulator> stage_;
  std::unique_ptr<MicroEpsilonIld1420Emulator> sensor_;
};

}  // namespace scanmesh::sim
