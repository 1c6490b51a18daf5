// ScanEngine: what the daemon needs from a scanning back end (devices, scan control, counters,
// the mesh, the catalog). The server is written against this interface only; back ends are
// chosen by configuration (engine_factory.hpp).
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/daemon/messages.hpp"
#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::daemon {

/// A refused engine operation; `code` is the protocol error code (protocol.hpp, errc).
class EngineError : public Error {
 public:
  EngineError(std::string_view code, const std::string& message) : Error(message), code_(code) {}
  const std::string& code() const { return code_; }

 private:
  std::string code_;
};

/// What an engine reports as it happens. Called from the engine's own threads; the daemon's
/// implementation posts each call onto its io thread, so an implementation must be cheap and
/// must not call back into the engine.
class EngineListener {
 public:
  virtual ~EngineListener() = default;
  /// The scan state changed (started, paused, resumed, stopping, idle again).
  virtual void on_scan(const ScanStatus& status) = 0;
  /// A device changed state (opened, lost, back, failed).
  virtual void on_device(const DeviceInfo& device) = 0;
  /// The mesh changed (counts only).
  virtual void on_mesh(const MeshCounts& counts) = 0;
};

/// Thread safety: every member may be called from any thread; the daemon calls the cheap ones
/// (devices, status, start/pause/resume/stop) on its io thread and must never be blocked long
/// by them; the ones marked "may block" it calls on its job thread.
class ScanEngine {
 public:
  virtual ~ScanEngine() = default;

  /// "sim", "replay" or "devices".
  virtual std::string_view backend() const = 0;
  /// Opens the devices. Called once before the daemon reports READY. Throws DeviceError or
  /// ConfigError (the daemon then exits non-zero). `listener` outlives the engine's threads.
  virtual void open(EngineListener& listener) = 0;

  virtual std::vector<DeviceInfo> devices() const = 0;
  virtual ScanStatus status() const = 0;

  /// Starts a scan. `parameters` are the configured defaults with the request's on top.
  /// Throws EngineError: busy (a scan is running), bad_argument (an unknown or bad parameter).
  virtual ScanRecord start(const std::string& name, const Parameters& parameters) = 0;
  /// Throws EngineError(bad_state) when there is nothing to pause / resume / stop.
  virtual void pause(const std::string& reason) = 0;
  virtual void resume() = 0;
  virtual void stop(const std::string& reason) = 0;

  /// The catalog (may block).
  virtual std::vector<ScanRecord> list_scans() const = 0;
  virtual std::optional<ScanRecord> scan_info(std::int64_t id) const = 0;
  /// Continues an interrupted scan (new journal segment) or closes it (may block). Throws
  /// EngineError: not_found, bad_state (not interrupted), busy.
  virtual ScanRecord resume_interrupted(std::int64_t id) = 0;
  virtual ScanRecord close_interrupted(std::int64_t id) = 0;

  /// The mesh of the running or last scan (no id) or of a past scan (may block: a past scan may
  /// be re-meshed from its journal). Null when there is none yet. Throws EngineError(not_found).
  virtual std::shared_ptr<const recon::Mesh> mesh(std::optional<std::int64_t> scan) const = 0;
  /// Stops a running scan, flushes the journal and closes the devices; blocks until done.
  virtual void shutdown() noexcept = 0;
};

}  // namespace scanmesh::daemon
