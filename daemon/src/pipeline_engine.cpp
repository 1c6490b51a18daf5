// The pipeline engine (pipeline_engine.hpp).
// Threads: the callers' (the io thread: cheap calls; the job thread: catalog, past meshes); per
// scan the pipeline's own (ingest, meshing), the backend's, and one supervisor that waits for
// the scan's end and finishes its catalog row. Locks: m_ (the engine's state) may be held while
// calling into a pipeline; a scan's own mutex (Active::mu) is a leaf; catalog_mu_ guards the one
// SQLite connection and is never held while calling into a pipeline. Pipeline callbacks take
// Active::mu only, so a pipeline calling back from inside pause()/stop() cannot deadlock.
// SPDX-License-Identifier: MIT
#include "scanmesh/daemon/pipeline_engine.hpp"

#include <pthread.h>

#include <algorithm>
#include <chrono>
#include <deque>
#include <map>
#include <mutex>
#include <thread>

#include "scan_parameters.hpp"
#include "scanmesh/acquisition/catalog.hpp"
#include "scanmesh/acquisition/journal.hpp"
#include "scanmesh/acquisition/journal_backend.hpp"
#include "scanmesh/acquisition/meshers.hpp"
#include "scanmesh/acquisition/pipeline.hpp"
#include "scanmesh/acquisition/scanner_json.hpp"
#include "scanmesh/daemon/protocol.hpp"

namespace scanmesh::daemon {

namespace {

using Clock = std::chrono::steady_clock;
namespace errc = proto::errc;

acq::WallTime wall_now() { return std::chrono::system_clock::now(); }

/// The engine's own parameters; the rest goes to the backend factory.
struct EngineParams {
  nlohmann::json meshing;  ///< {"mesher": ..., "cube": ...} as make_mesher takes it
  Parameters backend;
};

EngineParams split_params(const Parameters& p) {
  EngineParams e;
  std::string mesher = "incremental";
  nlohmann::json cube = "auto";
  for (const auto& [key, v] : p) {
    if (key == "cube_mm") {
      const double c = params::number(key, v, 0, 1000);
      if (c > 0) cube = c;
    } else if (key == "mesher") {
      mesher = params::string(key, v);
      if (mesher != "incremental" && mesher != "batch")
        params::bad(key, "must be incremental or batch, got '" + mesher + "'");
    } else if (key == "remesh_points") {
      params::bad(key,
                  "is no longer used: the incremental mesher meshes while the scan runs "
                  "(mesher = \"batch\" meshes once at the end)");
    } else {
      e.backend[key] = v;
    }
  }
  e.meshing = nlohmann::json{{"mesher", mesher}, {"cube", cube}};
  return e;
}

/// A journal file name part from a scan name: letters, digits, '.', '-', '_' (others '_').
std::string file_safe(const std::string& name) {
  std::string s;
  for (const char c : name.substr(0, 64))
    s +=
        (std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == '_') ? c : '_';
  if (s.empty() || s.front() == '.') s.insert(s.begin(), '_');
  return s;
}

DeviceState device_state(drivers::DeviceState s) {
  switch (s) {
    case drivers::DeviceState::kClosed:
      return DeviceState::kClosed;
    case drivers::DeviceState::kOpen:
    case drivers::DeviceState::kAcquiring:
      return DeviceState::kOk;
    case drivers::DeviceState::kLost:
      return DeviceState::kLost;
  }
  return DeviceState::kFailed;
}

std::uint64_t device_errors(const drivers::DeviceStats& s) {
  return s.gaps + s.malformed + s.error_replies + s.timeouts;
}

/// The protocol's words for a catalog state; "closed" is a scan stopped after an interruption
/// without being resumed (its last segment is the recovered one).
std::string record_state(const acq::ScanRecord& r) {
  switch (r.state) {
    case acq::ScanState::kRunning:
      return "running";
    case acq::ScanState::kPaused:
      return "paused";
    case acq::ScanState::kCompleted:
      return "finished";
    case acq::ScanState::kStopped:
      return !r.segments.empty() && r.segments.back().state == "recovered" ? "closed" : "stopped";
    case acq::ScanState::kFailed:
      return "failed";
    case acq::ScanState::kInterrupted:
      return "interrupted";
  }
  return "?";
}

std::vector<std::filesystem::path> segment_paths(const acq::ScanRecord& r) {
  std::vector<std::filesystem::path> out;
  for (const auto& s : r.segments) out.emplace_back(s.path);
  return out;
}

std::uint64_t files_size(const std::vector<std::filesystem::path>& files) {
  std::uint64_t n = 0;
  for (const auto& f : files) {
    std::error_code ec;
    const auto s = std::filesystem::file_size(f, ec);
    if (!ec) n += s;
  }
  return n;
}

/// One scan in progress: a pipeline over one journal segment.
struct Active {
  std::int64_t id = 0;
  std::string name;
  int segment = 1;
  bool resumed = false;
  std::vector<std::filesystem::path> segments;  ///< every segment, this one last
  nlohmann::json meshing;
  std::uint64_t prior_samples = 0, prior_points = 0, prior_journal_bytes = 0;
  std::uint64_t planned = 0;  ///< sensor samples, 0 unknown
  Clock::time_point started = Clock::now();

  // Under mu (a leaf lock: pipeline callbacks take it).
  mutable std::mutex mu;
  std::string pause_reason;  ///< the daemon's words ("operator", "device_lost: NAME")
  std::string stop_reason;
  Clock::duration paused_total{0};
  std::optional<Clock::time_point> paused_since;
  std::optional<Clock::time_point> ended;
  mutable std::deque<std::pair<Clock::time_point, std::uint64_t>> window;  // rate, last second
  std::uint64_t reported_triangles = 0;

  std::unique_ptr<acq::ScanBackend> backend;
  const acq::JournalRecorder* recorder = nullptr;  // owned by the pipeline
  std::unique_ptr<acq::Pipeline> pipeline;         // last: destroyed (threads joined) first

  double elapsed_s_locked(Clock::time_point now) const {
    const auto end = ended.value_or(now);
    auto paused = paused_total;
    if (paused_since) paused += end - *paused_since;
    return std::chrono::duration<double>(end - started - paused).count();
  }
};

class PipelineEngine final : public ScanEngine {
 public:
  PipelineEngine(const DaemonConfig& config, const Log& log, std::string kind,
                 BackendFactory factory)
      : config_(config),
        log_(log),
        kind_(std::move(kind)),
        factory_(std::move(factory)),
        scans_dir_(config.state_dir / "scans") {}

  ~PipelineEngine() override { shutdown(); }

  std::string_view backend() const override { return kind_; }

  void open(EngineListener& listener) override {
    listener_ = &listener;
    std::error_code ec;
    std::filesystem::create_directories(scans_dir_, ec);
    if (ec)
      throw ConfigError(scans_dir_.string() + ": cannot create the scan folder: " + ec.message());
    {
      std::lock_guard lock(catalog_mu_);
      catalog_.emplace(acq::Catalog::open(config_.state_dir / "catalog.sqlite", wall_now()));
      for (const std::int64_t id : catalog_->newly_interrupted()) {
        std::string what;
        try {
          for (const auto& r : acq::recover_interrupted(*catalog_, id, wall_now()))
            if (r.mcap.cut_bytes > 0)
              what += ", " + std::to_string(r.mcap.cut_bytes) + " torn bytes cut";
        } catch (const std::exception& e) {
          log_.error("scan " + std::to_string(id) + ": recovering its journal failed: " + e.what());
        }
        const auto rec = catalog_->scan(id);
        if (rec)
          log_.notice("scan " + std::to_string(id) + " '" + rec->name +
                      "' was interrupted: " + std::to_string(rec->samples) +
                      " samples kept in its journal" + what + " (resume or close it)");
      }
    }
    // The configured backend is built once now, so a bad configuration stops the daemon before
    // READY; its devices are what `devices` shows between scans.
    ScanSource probe = make_source(config_.scan_defaults, std::nullopt, true);
    std::vector<DeviceInfo> list;
    for (const auto& d : probe.backend->devices()) list.push_back(device_info(d, 0));
    {
      std::lock_guard lock(m_);
      idle_devices_ = list;
    }
    for (const auto& d : list) listener_->on_device(d);
  }

  std::vector<DeviceInfo> devices() const override {
    std::lock_guard lock(m_);
    return devices_locked();
  }

  ScanStatus status() const override {
    std::lock_guard lock(m_);
    if (active_) return status_of(*active_, active_->pipeline->stats());
    return last_status_;
  }

  ScanRecord start(const std::string& name, const Parameters& parameters) override {
    std::lock_guard control(control_mu_);
    busy_check();
    const EngineParams ep = split_params(parameters);
    ScanSource source = make_source(parameters, std::nullopt, false);
    auto mesher = make_mesher(ep.meshing);
    const acq::ScannerModel model = source.backend->model();

    auto a = std::make_shared<Active>();
    a->name = name;
    a->meshing = ep.meshing;
    a->planned = source.planned_sensor_samples;
    const std::int64_t predicted = next_id();
    a->segments.push_back(scans_dir_ /
                          ("scan-" + std::to_string(predicted) + "-" + file_safe(name) + ".mcap"));
    auto recorder = make_recorder(a->segments.back(), model, predicted, name, 1);
    {
      std::lock_guard lock(catalog_mu_);
      acq::NewScan ns;
      ns.name = name;
      ns.journal = a->segments.back();
      const nlohmann::json m = acq::to_json(model);
      ns.devices = nlohmann::json{{"backend", kind_},
                                  {"source", source.description},
                                  {"parameters", params::to_json(parameters)},
                                  {"sensors", m["sensors"]},
                                  {"stage", m["stage"]}};
      nlohmann::json calibration = nlohmann::json::array();
      for (const auto& s : m["sensors"]) calibration.push_back(s["calibration"]);
      ns.calibration = nlohmann::json{{"sensors", calibration}, {"accumulator", m["accumulator"]}};
      ns.reduction = nlohmann::json{{"cube", ep.meshing["cube"]}};
      ns.meshing = ep.meshing;
      a->id = catalog_->create_scan(ns, wall_now());
    }
    const std::int64_t id = a->id;
    launch(std::move(a), std::move(source), std::move(recorder), std::move(mesher), parameters);
    return record_of(id);
  }

  void pause(const std::string& reason) override {
    std::int64_t id = 0;
    {
      std::lock_guard lock(m_);
      Active* a = running_locked("pause");
      if (a->pipeline->stats().state != acq::PipelineState::kRunning)
        throw EngineError(errc::kBadState,
                          "no scan is running (state " +
                              std::string(to_string(status_of(*a, a->pipeline->stats()).state)) +
                              ")");
      {
        std::lock_guard s(a->mu);
        a->pause_reason = reason;
        a->paused_since = Clock::now();
      }
      a->pipeline->pause();
      id = a->id;
    }
    catalog_paused(id, true);
  }

  void resume() override {
    std::int64_t id = 0;
    {
      std::lock_guard lock(m_);
      Active* a = running_locked("resume");
      if (a->pipeline->stats().state != acq::PipelineState::kPaused)
        throw EngineError(errc::kBadState,
                          "no scan is paused (state " +
                              std::string(to_string(status_of(*a, a->pipeline->stats()).state)) +
                              ")");
      {
        std::lock_guard s(a->mu);
        if (a->paused_since) a->paused_total += Clock::now() - *a->paused_since;
        a->paused_since.reset();
        a->pause_reason.clear();
      }
      a->pipeline->resume();
      id = a->id;
    }
    catalog_paused(id, false);
  }

  void stop(const std::string& reason) override {
    std::lock_guard lock(m_);
    Active* a = running_locked("stop");
    const auto st = a->pipeline->stats().state;
    if (st != acq::PipelineState::kRunning && st != acq::PipelineState::kPaused)
      throw EngineError(errc::kBadState, "no scan is running (it is ending)");
    {
      std::lock_guard s(a->mu);
      a->stop_reason = reason;
    }
    a->pipeline->stop();
  }

  std::vector<ScanRecord> list_scans() const override {
    std::vector<acq::ScanRecord> rows;
    {
      std::lock_guard lock(catalog_mu_);
      rows = catalog_->scans();
    }
    std::vector<ScanRecord> out;
    for (const auto& r : rows) out.push_back(to_record(r));
    return out;
  }

  std::optional<ScanRecord> scan_info(std::int64_t id) const override {
    std::optional<acq::ScanRecord> r;
    {
      std::lock_guard lock(catalog_mu_);
      r = catalog_->scan(id);
    }
    if (!r) return std::nullopt;
    return to_record(*r);
  }

  ScanRecord resume_interrupted(std::int64_t id) override {
    std::lock_guard control(control_mu_);
    const acq::ScanRecord rec = interrupted(id);
    busy_check();
    const Parameters parameters =
        params::from_json(rec.devices.value("parameters", nlohmann::json()));
    const EngineParams ep = split_params(parameters);
    // The new segment's samples come after everything the earlier segments hold.
    std::vector<std::filesystem::path> segments = segment_paths(rec);
    std::int64_t last_ns = 0;
    for (const auto& s : segments) {
      std::error_code ec;
      if (!std::filesystem::exists(s, ec)) continue;
      try {
        last_ns = std::max(last_ns, acq::check_journal(s).last_sample_ns);
      } catch (const std::exception& e) {
        throw EngineError(errc::kBadState, s.string() + ": " + e.what());
      }
    }
    ScanSource source = make_source(parameters, drivers::Timestamp{last_ns}, false);
    auto mesher = make_mesher(ep.meshing);
    const acq::ScannerModel model = source.backend->model();

    auto a = std::make_shared<Active>();
    a->id = id;
    a->name = rec.name;
    a->resumed = true;
    a->meshing = ep.meshing;
    a->planned = source.planned_sensor_samples;
    a->prior_samples = rec.samples;
    a->prior_points = rec.points;
    a->prior_journal_bytes = files_size(segments);
    a->segment = static_cast<int>(rec.segments.size()) + 1;
    a->segments = segments;
    a->segments.push_back(scans_dir_ / ("scan-" + std::to_string(id) + "-" + file_safe(rec.name) +
                                        "." + std::to_string(a->segment) + ".mcap"));
    auto recorder = make_recorder(a->segments.back(), model, id, rec.name, a->segment);
    {
      std::lock_guard lock(catalog_mu_);
      a->segment = catalog_->resume(id, a->segments.back(), wall_now());
    }
    {
      std::lock_guard lock(m_);
      meshes_.erase(id);
    }
    launch(std::move(a), std::move(source), std::move(recorder), std::move(mesher), parameters);
    return record_of(id);
  }

  ScanRecord close_interrupted(std::int64_t id) override {
    std::lock_guard control(control_mu_);
    interrupted(id);
    {
      std::lock_guard lock(catalog_mu_);
      catalog_->close_interrupted(id, "closed after an interruption", wall_now());
    }
    return record_of(id);
  }

  std::shared_ptr<const recon::Mesh> mesh(std::optional<std::int64_t> scan) const override {
    std::shared_ptr<Active> a;
    std::int64_t id = 0;
    {
      std::lock_guard lock(m_);
      id = scan.value_or(active_ ? active_->id : last_status_.id);
      if (id == 0) return nullptr;
      if (active_ && active_->id == id)
        a = active_;
      else if (const auto it = meshes_.find(id); it != meshes_.end())
        return it->second;
    }
    if (a) return std::make_shared<const recon::Mesh>(a->pipeline->snapshot());
    // A past scan: its journal segments replayed through the recorded meshing.
    std::optional<acq::ScanRecord> rec;
    {
      std::lock_guard lock(catalog_mu_);
      rec = catalog_->scan(id);
    }
    if (!rec)
      throw EngineError(errc::kNotFound, "no scan " + std::to_string(id) + " in the catalog");
    auto m = replay_mesh(*rec);
    std::lock_guard lock(m_);
    meshes_[id] = m;
    return m;
  }

  void shutdown() noexcept override {
    std::lock_guard control(control_mu_);
    {
      std::lock_guard lock(m_);
      shutting_down_ = true;
      if (active_) {
        {
          std::lock_guard s(active_->mu);
          if (active_->stop_reason.empty()) active_->stop_reason = "daemon stopping";
        }
        active_->pipeline->stop();
      }
    }
    if (supervisor_.joinable()) supervisor_.join();
  }

 private:
  // ---- helpers on the caller's thread

  ScanSource make_source(const Parameters& parameters, std::optional<drivers::Timestamp> after,
                         bool at_open) const {
    const EngineParams ep = split_params(parameters);
    BackendRequest req{ep.backend, after};
    try {
      ScanSource s = factory_(req);
      if (!s.backend) throw ConfigError("the backend factory made no backend");
      return s;
    } catch (const EngineError& e) {
      if (at_open) throw ConfigError(config_.source.string() + ": [scan] " + e.what());
      throw;
    } catch (const ConfigError& e) {
      if (at_open) throw;
      throw EngineError(errc::kBadArgument, e.what());
    } catch (const InputError& e) {
      if (at_open) throw ConfigError(e.what());
      throw EngineError(errc::kBadArgument, e.what());
    }
  }

  static std::unique_ptr<acq::Mesher> make_mesher(const nlohmann::json& meshing) {
    try {
      return acq::make_mesher(meshing);
    } catch (const ConfigError& e) {
      throw EngineError(errc::kBadArgument, std::string("parameters: ") + e.what());
    }
  }

  std::unique_ptr<acq::JournalRecorder> make_recorder(const std::filesystem::path& path,
                                                      const acq::ScannerModel& model,
                                                      std::int64_t id, const std::string& name,
                                                      int segment) const {
    acq::JournalOptions options;
    options.metadata = {{"scan_id", std::to_string(id)},
                        {"scan_name", name},
                        {"segment", std::to_string(segment)},
                        {"recorder", "scanmeshd"}};
    try {
      return std::make_unique<acq::JournalRecorder>(path, model, options);
    } catch (const Error& e) {
      throw EngineError(errc::kIoError, e.what());
    }
  }

  std::int64_t next_id() const {
    std::lock_guard lock(catalog_mu_);
    std::int64_t n = 0;
    for (const auto& r : catalog_->scans()) n = std::max(n, r.id);
    return n + 1;
  }

  void busy_check() const {
    std::lock_guard lock(m_);
    if (shutting_down_) throw EngineError(errc::kShuttingDown, "the daemon is stopping");
    if (active_) {
      const ScanStatus s = status_of(*active_, active_->pipeline->stats());
      throw EngineError(errc::kBusy, "scan " + std::to_string(s.id) + " '" + s.name + "' is " +
                                         std::string(to_string(s.state)));
    }
  }

  Active* running_locked(const char* what) const {
    if (!active_)
      throw EngineError(errc::kBadState,
                        std::string("no scan is running (state idle): nothing to ") + what);
    return active_.get();
  }

  acq::ScanRecord interrupted(std::int64_t id) const {
    std::optional<acq::ScanRecord> r;
    {
      std::lock_guard lock(catalog_mu_);
      r = catalog_->scan(id);
    }
    if (!r) throw EngineError(errc::kNotFound, "no scan " + std::to_string(id) + " in the catalog");
    if (r->state != acq::ScanState::kInterrupted)
      throw EngineError(errc::kBadState, "scan " + std::to_string(id) + " is " + record_state(*r) +
                                             ", not interrupted");
    return *r;
  }

  void catalog_paused(std::int64_t id, bool paused) {
    try {
      std::lock_guard lock(catalog_mu_);
      catalog_->set_paused(id, paused, wall_now());
    } catch (const std::exception& e) {
      log_.warning("scan " + std::to_string(id) + ": catalog: " + e.what());
    }
  }

  ScanRecord record_of(std::int64_t id) const {
    auto r = scan_info(id);
    if (!r) throw EngineError(errc::kInternal, "scan " + std::to_string(id) + " left the catalog");
    return *r;
  }

  /// Starts the pipeline of `a` and its supervisor. On failure the catalog row is finished as
  /// failed and EngineError(io_error) names what could not start.
  void launch(std::shared_ptr<Active> a, ScanSource source,
              std::unique_ptr<acq::JournalRecorder> recorder, std::unique_ptr<acq::Mesher> mesher,
              const Parameters& parameters) {
    const acq::ScannerModel model = source.backend->model();
    acq::PipelineConfig pc;
    pc.progress_interval = config_.progress_interval;
    // The daemon's policy pauses on a lost device (server.cpp), so that an operator's pause is
    // never undone by a device coming back.
    pc.pause_on_device_loss = false;
    pc.parameters_json = nlohmann::json{{"kind", "scan"},
                                        {"source", source.description},
                                        {"scanner", acq::to_json(model)},
                                        {"meshing", a->meshing},
                                        {"scan_id", a->id},
                                        {"scan_name", a->name},
                                        {"segment", a->segment},
                                        {"parameters", params::to_json(parameters)}}
                             .dump();
    a->backend = std::move(source.backend);
    a->recorder = recorder.get();
    Active* raw = a.get();
    a->pipeline = std::make_unique<acq::Pipeline>(
        *a->backend, std::move(recorder), std::move(mesher), pc,
        [this, raw](const acq::PipelineEvent& e) { on_pipeline_event(*raw, e); });
    if (supervisor_.joinable()) supervisor_.join();  // the last scan's, already over
    {
      std::lock_guard lock(m_);
      active_ = a;
    }
    // The pipeline's and the backend's threads inherit the name of the thread that creates
    // them: "scan-pipeline" in top -H and the benchmark, not the io thread's.
    char caller_name[16] = {};
    ::pthread_getname_np(::pthread_self(), caller_name, sizeof caller_name);
    ::pthread_setname_np(::pthread_self(), "scan-pipeline");
    struct RestoreName {
      const char* name;
      ~RestoreName() { ::pthread_setname_np(::pthread_self(), name); }
    } restore{caller_name};
    try {
      a->pipeline->start();
    } catch (const std::exception& e) {
      ScanStatus failed;
      {
        std::lock_guard lock(m_);
        active_.reset();
        failed = last_status_ = ScanStatus{
            ScanState::kIdle, std::string("failed: ") + e.what(), a->id, a->name, 0, -1, {}};
      }
      if (listener_) listener_->on_scan(failed);
      try {
        std::lock_guard lock(catalog_mu_);
        catalog_->finish(a->id, acq::ScanState::kFailed, e.what(), a->prior_samples,
                         a->prior_points, wall_now());
      } catch (const std::exception& c) {
        log_.error("scan " + std::to_string(a->id) + ": catalog: " + c.what());
      }
      throw EngineError(errc::kIoError, std::string("the scan could not start: ") + e.what());
    }
    log_.info("scan " + std::to_string(a->id) + " '" + a->name + "' " +
              (a->resumed ? "resumed" : "started") + ": journal " + a->segments.back().string());
    supervisor_ = std::thread([this, a] { supervise(a); });
  }

  // ---- the pipeline's threads

  void on_pipeline_event(Active& a, const acq::PipelineEvent& e) {
    if (!listener_) return;
    if (e.kind == "state") {
      switch (e.stats.state) {
        case acq::PipelineState::kRunning:
        case acq::PipelineState::kPaused:
        case acq::PipelineState::kStopping:
          listener_->on_scan(status_of(a, e.stats));
          break;
        default:  // the end is reported by the supervisor once the catalog has it
          break;
      }
    } else if (e.kind == "device") {
      for (const auto& d : a.backend->devices())
        if (d.name == e.device) {
          DeviceInfo info = device_info(d, 0);
          if (info.state != DeviceState::kOk && info.detail.empty()) info.detail = e.message;
          listener_->on_device(info);
        }
    } else if (e.kind == "progress") {
      const ScanStatus s = status_of(a, e.stats);  // keeps the rate window fed
      std::uint64_t before = 0;
      {
        std::lock_guard lock(a.mu);
        before = a.reported_triangles;
        a.reported_triangles = e.stats.mesh.triangles;
      }
      if (before != e.stats.mesh.triangles) {
        MeshCounts c;
        c.scan = a.id;
        c.vertices = s.counters.vertices;
        c.triangles = s.counters.triangles;
        c.added = c.triangles > before ? c.triangles - before : 0;
        c.removed = before > c.triangles ? before - c.triangles : 0;
        listener_->on_mesh(c);
      }
    } else if (e.kind == "failure") {
      log_.error("scan " + std::to_string(a.id) + ": " + e.message);
    }
  }

  void supervise(std::shared_ptr<Active> a) noexcept {
    ::pthread_setname_np(::pthread_self(), "scan-supervisor");
    // While the scan runs, its row's counts follow every few seconds: after a crash the row
    // keeps the points mapped so far (recovery recounts the samples from the journal).
    for (int tick = 1; !a->pipeline->wait_for(std::chrono::seconds(1)); ++tick) {
      if (tick % 5 != 0) continue;
      const acq::PipelineStats now = a->pipeline->stats();
      try {
        std::lock_guard lock(catalog_mu_);
        catalog_->update_counts(a->id, a->prior_samples + now.samples_recorded,
                                a->prior_points + now.points, wall_now());
      } catch (const std::exception& e) {
        log_.warning("scan " + std::to_string(a->id) + ": catalog: " + e.what());
      }
    }
    acq::PipelineState final_state = a->pipeline->wait();
    acq::PipelineStats st = a->pipeline->stats();
    // The pipeline publishes its last ingest counts after it hands the meshing thread its last
    // points, so wait() can return before they are in stats() (a scan stopped early, whose
    // meshing ends at once). The journal was closed before that hand-over: its counts are final.
    st.samples_recorded = std::max(st.samples_recorded, a->recorder->acknowledged_samples());
    st.journal_bytes = std::max(st.journal_bytes, a->recorder->bytes());
    st.points = std::max(st.points, st.mesh.points_in);
    {
      std::lock_guard lock(a->mu);
      a->ended = Clock::now();
      if (a->paused_since) {
        a->paused_total += *a->ended - *a->paused_since;
        a->paused_since.reset();
      }
    }
    bool stopping_daemon = false;
    {
      std::lock_guard lock(m_);
      stopping_daemon = shutting_down_;
    }
    // The scan's mesh: the pipeline's own, or, for a resumed scan, all its segments replayed
    // (the live pipeline meshed the new segment only). Skipped when the daemon is stopping.
    std::shared_ptr<const recon::Mesh> mesh;
    try {
      if (!a->resumed)
        mesh = std::make_shared<const recon::Mesh>(a->pipeline->result());
      else if (!stopping_daemon)
        mesh = replay_segments(a->segments, a->meshing, a->id);
    } catch (const std::exception& e) {
      log_.warning("scan " + std::to_string(a->id) + ": no mesh: " + e.what());
    }
    std::string stop_reason;
    {
      std::lock_guard lock(a->mu);
      stop_reason = a->stop_reason;
    }
    // Stopped before any point reached the mesher: the mesher's finish refuses an empty input,
    // which the pipeline reports as a failure; the scan was stopped, with no surface.
    if (final_state == acq::PipelineState::kFailed && !stop_reason.empty() &&
        st.mesh.points_in == 0 && st.reason.rfind("meshing: ", 0) == 0)
      final_state = acq::PipelineState::kStopped;
    const acq::ScanState cat_state =
        final_state == acq::PipelineState::kCompleted ? acq::ScanState::kCompleted
        : final_state == acq::PipelineState::kStopped ? acq::ScanState::kStopped
                                                      : acq::ScanState::kFailed;
    std::string reason = cat_state == acq::ScanState::kStopped
                             ? (stop_reason.empty() ? st.reason : stop_reason)
                         : cat_state == acq::ScanState::kFailed ? st.reason
                                                                : "";
    try {
      std::lock_guard lock(catalog_mu_);
      catalog_->finish(a->id, cat_state, reason, a->prior_samples + st.samples_recorded,
                       a->prior_points + st.points, wall_now());
    } catch (const std::exception& e) {
      log_.error("scan " + std::to_string(a->id) + ": catalog: " + e.what());
    }
    ScanStatus final_status = status_of(*a, st);
    final_status.state = ScanState::kIdle;
    final_status.reason = cat_state == acq::ScanState::kCompleted ? "finished"
                          : cat_state == acq::ScanState::kStopped
                              ? "stopped" + (reason.empty() ? "" : ": " + reason)
                              : "failed: " + reason;
    if (cat_state == acq::ScanState::kCompleted) final_status.progress = 1.0;
    final_status.counters.meshing_lag_points = 0;
    final_status.counters.meshing_lag_s = 0;
    if (mesh) {
      final_status.counters.triangles = mesh->triangles.size();
      final_status.counters.vertices = mesh->vertices.size();
    }
    log_.write(cat_state == acq::ScanState::kFailed ? LogLevel::kWarning : LogLevel::kInfo,
               "scan " + std::to_string(a->id) + " '" + a->name + "' " + final_status.reason +
                   ": " + std::to_string(final_status.counters.samples) + " samples, " +
                   std::to_string(final_status.counters.points) + " points, " +
                   std::to_string(final_status.counters.triangles) + " triangles");
    {
      std::lock_guard lock(m_);
      for (const auto& d : a->backend->devices()) totals_[d.name] += d.stats.samples;
      if (mesh) meshes_[a->id] = mesh;
      last_status_ = final_status;
      active_.reset();
    }
    if (listener_) listener_->on_scan(final_status);
  }

  // ---- values

  DeviceInfo device_info(const acq::DeviceStatus& d, std::uint64_t before) const {
    DeviceInfo info;
    info.name = d.name;
    info.role = d.kind;
    info.driver = d.driver;
    info.port = d.port;
    info.state = device_state(d.state);
    if (info.state == DeviceState::kLost) info.detail = d.reason;
    info.samples = before + d.stats.samples;
    info.errors = device_errors(d.stats);
    return info;
  }

  std::vector<DeviceInfo> devices_locked() const {
    if (!active_) {
      std::vector<DeviceInfo> out = idle_devices_;
      for (auto& d : out)
        if (const auto it = totals_.find(d.name); it != totals_.end()) d.samples = it->second;
      return out;
    }
    std::vector<DeviceInfo> out;
    for (const auto& d : active_->backend->devices()) {
      const auto it = totals_.find(d.name);
      out.push_back(device_info(d, it == totals_.end() ? 0 : it->second));
    }
    return out;
  }

  ScanStatus status_of(const Active& a, const acq::PipelineStats& st) const {
    ScanStatus s;
    s.id = a.id;
    s.name = a.name;
    switch (st.state) {
      case acq::PipelineState::kIdle:
      case acq::PipelineState::kRunning:
        s.state = ScanState::kRunning;
        break;
      case acq::PipelineState::kPaused:
        s.state = ScanState::kPaused;
        break;
      default:  // stopping, or over and being finished by the supervisor
        s.state = ScanState::kStopping;
        break;
    }
    auto& c = s.counters;
    c.samples = a.prior_samples + st.samples_recorded;
    c.points = a.prior_points + st.points;
    c.triangles = st.mesh.triangles;
    c.vertices = st.mesh.vertices;
    c.meshing_lag_points = st.meshing_lag;
    c.journal_bytes = a.prior_journal_bytes + st.journal_bytes;
    c.errors = st.lost + st.no_pose;
    const auto now = Clock::now();
    std::lock_guard lock(a.mu);
    if (s.state == ScanState::kPaused)
      s.reason = a.pause_reason.empty() ? st.reason : a.pause_reason;
    else if (s.state == ScanState::kStopping)
      s.reason = a.stop_reason.empty() ? st.reason : a.stop_reason;
    s.elapsed_s = a.elapsed_s_locked(now);
    if (a.planned > 0)
      s.progress = std::min(
          0.999, static_cast<double>(st.samples_received) / static_cast<double>(a.planned));
    // Rate over the last second of what the journal acknowledged.
    auto& w = a.window;
    if (!a.ended && (w.empty() || w.back().second != c.samples ||
                     now - w.back().first > std::chrono::milliseconds(100)))
      w.emplace_back(now, c.samples);
    while (w.size() > 2 && now - w.front().first > std::chrono::seconds(1)) w.pop_front();
    if (w.size() >= 2) {
      const double dt = std::chrono::duration<double>(w.back().first - w.front().first).count();
      if (dt > 0) c.rate_hz = static_cast<double>(w.back().second - w.front().second) / dt;
    }
    const double points_per_sample =
        c.samples > 0 ? static_cast<double>(c.points) / static_cast<double>(c.samples) : 0;
    c.meshing_lag_s =
        c.rate_hz * points_per_sample > 0
            ? static_cast<double>(c.meshing_lag_points) / (c.rate_hz * points_per_sample)
            : 0;
    return s;
  }

  ScanRecord to_record(const acq::ScanRecord& r) const {
    ScanRecord out;
    out.id = r.id;
    out.name = r.name;
    out.state = record_state(r);
    out.started_utc = r.started_at;
    out.stopped_utc = r.stopped_at;
    out.reason = r.stop_reason;
    out.samples = r.samples;
    out.points = r.points;
    const auto files = segment_paths(r);
    out.journal_bytes = files_size(files);
    out.journal = files.empty() ? std::string() : files.front().string();
    out.parameters = params::from_json(r.devices.value("parameters", nlohmann::json()));
    std::lock_guard lock(m_);
    if (active_ && active_->id == r.id) {  // the running scan: its live counts
      const ScanStatus s = status_of(*active_, active_->pipeline->stats());
      out.samples = s.counters.samples;
      out.points = s.counters.points;
      out.triangles = s.counters.triangles;
      out.journal_bytes = s.counters.journal_bytes;
    } else if (const auto it = meshes_.find(r.id); it != meshes_.end() && it->second) {
      out.triangles = it->second->triangles.size();
    }
    return out;
  }

  // ---- past scans

  std::shared_ptr<const recon::Mesh> replay_mesh(const acq::ScanRecord& rec) const {
    std::vector<std::filesystem::path> files;
    for (const auto& f : segment_paths(rec)) {
      std::error_code ec;
      if (std::filesystem::exists(f, ec)) files.push_back(f);
    }
    if (files.empty()) return nullptr;
    return replay_segments(files, rec.meshing, rec.id);
  }

  /// The segments replayed through a pipeline without a journal: the recorded order, the
  /// recorded meshing; the live scan's mesh byte for byte.
  std::shared_ptr<const recon::Mesh> replay_segments(
      const std::vector<std::filesystem::path>& files, const nlohmann::json& meshing,
      std::int64_t id) const {
    acq::ReplayOptions ro;
    ro.speed = 0;
    acq::ReplayBackend backend(files, ro);
    nlohmann::json m = meshing.is_object() && !meshing.empty()
                           ? meshing
                           : backend.parameters().value("meshing", nlohmann::json::object());
    acq::Pipeline pipeline(backend, nullptr, acq::make_mesher(m));
    pipeline.start();
    const acq::PipelineState state = pipeline.wait();
    if (state == acq::PipelineState::kFailed)
      log_.warning("scan " + std::to_string(id) +
                   ": replaying its journal: " + pipeline.stats().reason);
    return std::make_shared<const recon::Mesh>(pipeline.result());
  }

  DaemonConfig config_;
  const Log& log_;
  std::string kind_;
  BackendFactory factory_;
  std::filesystem::path scans_dir_;
  EngineListener* listener_ = nullptr;

  std::mutex control_mu_;  // start, resume, close, shutdown: one at a time
  mutable std::mutex catalog_mu_;
  std::optional<acq::Catalog> catalog_;

  mutable std::mutex m_;
  std::shared_ptr<Active> active_;
  ScanStatus last_status_;
  std::vector<DeviceInfo> idle_devices_;
  std::map<std::string, std::uint64_t> totals_;  // device samples of finished scans
  mutable std::map<std::int64_t, std::shared_ptr<const recon::Mesh>> meshes_;
  bool shutting_down_ = false;
  std::thread supervisor_;
};

}  // namespace

std::unique_ptr<ScanEngine> make_pipeline_engine(const DaemonConfig& config, const Log& log,
                                                 std::string kind, BackendFactory factory) {
  return std::make_unique<PipelineEngine>(config, log, std::move(kind), std::move(factory));
}

}  // namespace scanmesh::daemon
