// A ScanEngine driven by the test itself: the test decides when samples arrive, when a device is
// lost or back and when the scan ends; every report reaches the daemon from the test's thread, as
// an engine's worker thread would deliver it. The mesh is the built-in part (sim::make_part).
// SPDX-License-Identifier: MIT
#pragma once

#include <map>
#include <mutex>
#include <stdexcept>

#include "scanmesh/daemon/engine.hpp"
#include "scanmesh/daemon/protocol.hpp"
#include "scanmesh/sim/parts.hpp"

namespace scanmesh::test {

class ScriptedEngine final : public daemon::ScanEngine {
 public:
  ScriptedEngine() {
    devices_.push_back({"probe-sensor", "sensor", "scripted", "/dev/null",
                        daemon::DeviceState::kClosed, "", 0, 0});
    devices_.push_back(
        {"probe-stage", "stage", "scripted", "", daemon::DeviceState::kClosed, "", 0, 0});
  }

  std::string_view backend() const override { return "scripted"; }
  void open(daemon::EngineListener& listener) override {
    std::lock_guard lock(m_);
    listener_ = &listener;
    for (auto& d : devices_) {
      d.state = daemon::DeviceState::kOk;
      listener_->on_device(d);
    }
  }
  std::vector<daemon::DeviceInfo> devices() const override {
    std::lock_guard lock(m_);
    return devices_;
  }
  daemon::ScanStatus status() const override {
    std::lock_guard lock(m_);
    return status_;
  }
  daemon::ScanRecord start(const std::string& name, const daemon::Parameters& parameters) override {
    std::lock_guard lock(m_);
    if (status_.state != daemon::ScanState::kIdle)
      throw daemon::EngineError(daemon::proto::errc::kBusy, "a scan is running");
    if (parameters.count("bogus"))
      throw daemon::EngineError(daemon::proto::errc::kBadArgument,
                                "parameters.bogus: unknown parameter");
    daemon::ScanRecord r;
    r.id = next_id_++;
    r.name = name;
    r.state = "running";
    r.started_utc = "2024-01-01T00:00:00Z";
    r.parameters = parameters;
    records_[r.id] = r;
    status_ = daemon::ScanStatus{};
    status_.state = daemon::ScanState::kRunning;
    status_.id = r.id;
    status_.name = name;
    status_.progress = 0;
    mesh_.reset();
    listener_->on_scan(status_);
    return r;
  }
  void pause(const std::string& reason) override {
    std::lock_guard lock(m_);
    if (status_.state != daemon::ScanState::kRunning)
      throw daemon::EngineError(daemon::proto::errc::kBadState, "no scan is running");
    status_.state = daemon::ScanState::kPaused;
    status_.reason = reason;
    listener_->on_scan(status_);
  }
  void resume() override {
    std::lock_guard lock(m_);
    if (status_.state != daemon::ScanState::kPaused)
      throw daemon::EngineError(daemon::proto::errc::kBadState, "no scan is paused");
    status_.state = daemon::ScanState::kRunning;
    status_.reason.clear();
    listener_->on_scan(status_);
  }
  void stop(const std::string& reason) override {
    std::lock_guard lock(m_);
    if (status_.state == daemon::ScanState::kIdle)
      throw daemon::EngineError(daemon::proto::errc::kBadState, "no scan is running");
    finish_locked("stopped: " + reason);
  }
  std::vector<daemon::ScanRecord> list_scans() const override {
    std::lock_guard lock(m_);
    std::vector<daemon::ScanRecord> out;
    for (const auto& [id, r] : records_) out.push_back(r);
    return out;
  }
  std::optional<daemon::ScanRecord> scan_info(std::int64_t id) const override {
    std::lock_guard lock(m_);
    auto it = records_.find(id);
    if (it == records_.end()) return std::nullopt;
    return it->second;
  }
  daemon::ScanRecord resume_interrupted(std::int64_t id) override {
    throw daemon::EngineError(daemon::proto::errc::kNotFound,
                              "no interrupted scan " + std::to_string(id));
  }
  daemon::ScanRecord close_interrupted(std::int64_t id) override {
    throw daemon::EngineError(daemon::proto::errc::kNotFound,
                              "no interrupted scan " + std::to_string(id));
  }
  std::shared_ptr<const recon::Mesh> mesh(std::optional<std::int64_t> scan) const override {
    std::lock_guard lock(m_);
    if (scan && !records_.count(*scan))
      throw daemon::EngineError(daemon::proto::errc::kNotFound, "no scan " + std::to_string(*scan));
    return mesh_;
  }
  void shutdown() noexcept override {
    std::lock_guard lock(m_);
    shutdowns_++;
    if (status_.state != daemon::ScanState::kIdle) finish_locked("stopped: daemon stopping");
  }

  // ---- the script (test thread)

  /// Samples arrive (only while running: a paused engine records nothing).
  void advance(std::uint64_t samples, std::uint64_t points) {
    std::lock_guard lock(m_);
    if (status_.state != daemon::ScanState::kRunning) return;
    status_.counters.samples += samples;
    status_.counters.points += points;
    status_.progress = std::min(1.0, status_.progress + 0.1);
    devices_[0].samples += samples;
  }
  void set_device(std::size_t index, daemon::DeviceState state, std::string detail = "") {
    std::lock_guard lock(m_);
    devices_[index].state = state;
    devices_[index].detail = std::move(detail);
    listener_->on_device(devices_[index]);
  }
  /// The scan ends with the built-in container as its mesh.
  void finish() {
    std::lock_guard lock(m_);
    mesh_ = std::make_shared<const recon::Mesh>(sim::make_part("container"));
    status_.counters.triangles = mesh_->triangles.size();
    status_.counters.vertices = mesh_->vertices.size();
    listener_->on_mesh(
        {status_.id, mesh_->vertices.size(), mesh_->triangles.size(), mesh_->triangles.size(), 0});
    finish_locked("finished");
  }
  /// Many events at once (slow-client tests): device reports with a long detail.
  void flood_device_events(std::size_t n, std::size_t detail_bytes) {
    std::lock_guard lock(m_);
    daemon::DeviceInfo d = devices_[0];
    d.detail = std::string(detail_bytes, 'x');
    for (std::size_t i = 0; i < n; ++i) listener_->on_device(d);
  }
  int shutdowns() const {
    std::lock_guard lock(m_);
    return shutdowns_;
  }

 private:
  void finish_locked(const std::string& reason) {
    status_.state = daemon::ScanState::kIdle;
    status_.reason = reason;
    status_.progress = 1;
    auto& r = records_[status_.id];
    r.state = reason == "finished" ? "finished" : "stopped";
    r.samples = status_.counters.samples;
    r.points = status_.counters.points;
    r.triangles = status_.counters.triangles;
    listener_->on_scan(status_);
  }

  mutable std::mutex m_;
  daemon::EngineListener* listener_ = nullptr;
  std::vector<daemon::DeviceInfo> devices_;
  daemon::ScanStatus status_;
  std::map<std::int64_t, daemon::ScanRecord> records_;
  std::shared_ptr<const recon::Mesh> mesh_;
  std::int64_t next_id_ = 1;
  int shutdowns_ = 0;
};

}  // namespace scanmesh::test
