// The stream-playback engine (sim_engine.hpp).
// Threads: the caller's (io thread: cheap calls under the mutex), one scan worker (delivery,
// journal, point mapping), one mesher (batch reconstruction of the points so far).
// SPDX-License-Identifier: MIT
#include "sim_engine.hpp"

#include <pthread.h>
#include <toml++/toml.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <ctime>
#include <deque>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>

#include "scanmesh/acquisition/accumulator.hpp"
#include "scanmesh/daemon/protocol.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/recon/reconstruct.hpp"
#include "scanmesh/sim/parts.hpp"
#include "scanmesh/sim/simulator.hpp"
#include "scanmesh/sim/stream.hpp"

namespace scanmesh::daemon {

namespace {

using Clock = std::chrono::steady_clock;
namespace errc = proto::errc;

/// One scan's settings: the backend's configuration with the request's parameters on top.
struct ScanParams {
  SimBackendConfig sim;
  std::filesystem::path stream;  ///< replay source
  double playback = 1;
  double cube_mm = 0;  ///< 0: auto
  std::uint64_t remesh_points = 20000;
};

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  ::gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

[[noreturn]] void bad_param(const std::string& key, const std::string& what) {
  throw EngineError(errc::kBadArgument, "parameters." + key + ": " + what);
}

double number_param(const std::string& key, const Scalar& v, double lo, double hi) {
  double d = 0;
  if (const auto* i = std::get_if<std::int64_t>(&v))
    d = static_cast<double>(*i);
  else if (const auto* f = std::get_if<double>(&v))
    d = *f;
  else
    bad_param(key, "must be a number");
  if (!(d >= lo && d <= hi)) {
    std::ostringstream m;
    m << "must be in [" << lo << ", " << hi << "], got " << d;
    bad_param(key, m.str());
  }
  return d;
}

std::string string_param(const std::string& key, const Scalar& v) {
  if (const auto* s = std::get_if<std::string>(&v)) return *s;
  bad_param(key, "must be a string");
}

ScanParams parse_params(const DaemonConfig& config, const Parameters& p, bool replay) {
  ScanParams s;
  s.sim = config.sim;
  s.stream = config.replay.stream;
  s.playback = replay ? config.replay.playback : config.sim.playback;
  for (const auto& [key, v] : p) {
    if (key == "playback") {
      s.playback = number_param(key, v, 0, 10000);
    } else if (key == "cube_mm") {
      s.cube_mm = number_param(key, v, 0, 1000);
    } else if (key == "remesh_points") {
      s.remesh_points = static_cast<std::uint64_t>(number_param(key, v, 100, 1e9));
    } else if (replay) {
      bad_param(key, "unknown parameter for the replay backend (playback, cube_mm, remesh_points)");
    } else if (key == "part") {
      s.sim.part = string_param(key, v);
      s.sim.mesh.clear();
      const auto names = sim::part_names();
      if (std::find(names.begin(), names.end(), s.sim.part) == names.end())
        bad_param(key, "unknown part '" + s.sim.part + "'");
    } else if (key == "mesh") {
      s.sim.mesh = string_param(key, v);
      s.sim.part.clear();
      std::error_code ec;
      if (!s.sim.mesh.is_absolute() || !std::filesystem::is_regular_file(s.sim.mesh, ec))
        bad_param(key, "must be an absolute path to a mesh file the daemon can read");
    } else if (key == "sensor") {
      s.sim.sensor = string_param(key, v);
      if (s.sim.sensor != "point" && s.sim.sensor != "line")
        bad_param(key, "must be point or line");
    } else if (key == "path") {
      s.sim.path = string_param(key, v);
      if (s.sim.path != "raster" && s.sim.path != "serpentine" && s.sim.path != "rotary" &&
          s.sim.path != "views")
        bad_param(key, "must be raster, serpentine, rotary or views");
    } else if (key == "spacing_mm") {
      s.sim.spacing_mm = number_param(key, v, 1e-3, 50);
    } else if (key == "line_spacing_mm") {
      s.sim.line_spacing_mm = number_param(key, v, 0, 500);
    } else if (key == "speed_mm_s") {
      s.sim.speed_mm_s = number_param(key, v, 1e-3, 5000);
    } else if (key == "noise_mm") {
      s.sim.noise_mm = number_param(key, v, 0, 5);
    } else if (key == "seed") {
      s.sim.seed = static_cast<std::int64_t>(number_param(key, v, 0, 9e15));
    } else {
      bad_param(key,
                "unknown parameter (part, mesh, sensor, path, spacing_mm, line_spacing_mm, "
                "speed_mm_s, noise_mm, seed, playback, cube_mm, remesh_points)");
    }
  }
  return s;
}

/// The samples of a scan, in memory, with the header that maps them to points.
struct Source {
  sim::StreamHeader header;
  std::vector<sim::SensorSample> sensor;
  std::vector<sim::StageSample> stage;
};

Source simulate_source(const ScanParams& p, std::vector<std::pair<std::string, std::string>> info) {
  recon::Mesh mesh;
  if (!p.sim.mesh.empty()) {
    mesh = meshio::read_mesh(p.sim.mesh);
    info.emplace_back("source", p.sim.mesh.string());
  } else {
    mesh = sim::make_part(p.sim.part);
    info.emplace_back("source", "part:" + p.sim.part);
  }
  const sim::Scene scene(std::move(mesh));
  sim::SimConfig cfg;
  const sim::SensorKind kind = sim::sensor_kind_from_string(p.sim.sensor);
  cfg.sensor = sim::default_sensor(kind);
  cfg.path.kind = sim::path_kind_from_string(p.sim.path);
  cfg.path.spacing_mm = p.sim.spacing_mm;
  cfg.path.line_spacing_mm = p.sim.line_spacing_mm;
  cfg.sensor.rate_hz = p.sim.speed_mm_s / p.sim.spacing_mm;
  cfg.imperfections.seed = static_cast<std::uint64_t>(p.sim.seed);
  cfg.imperfections.range_noise_mm = p.sim.noise_mm;
  cfg.threads = 1;  // the daemon shares the machine: one thread casts the rays
  const sim::Simulator simulator(scene, cfg);
  sim::SimulatedScan scan = sim::simulate(simulator);
  Source s;
  info.emplace_back("recorder", "scanmeshd");
  s.header = sim::stream_header(simulator, std::move(info));
  s.sensor = std::move(scan.sensor);
  s.stage = std::move(scan.stage);
  return s;
}

/// A journal read back; a torn last line (a crash mid-write) is cut, not an error.
sim::RecordedStream read_journal(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file.string() + ": cannot read the journal");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto nl = text.rfind('\n');
  text.resize(nl == std::string::npos ? 0 : nl + 1);
  return sim::parse_stream(text, file.string(), {true});
}

std::vector<std::filesystem::path> journal_segments(const std::filesystem::path& dir,
                                                    std::int64_t id) {
  std::vector<std::filesystem::path> out;
  for (int seg = 1;; ++seg) {
    const auto p = dir / ("scan-" + std::to_string(id) +
                          (seg == 1 ? "" : "." + std::to_string(seg)) + ".stream");
    std::error_code ec;
    if (!std::filesystem::exists(p, ec)) break;
    out.push_back(p);
  }
  return out;
}

/// Delivers a stream's records in time order (stage first at equal times) from the positions
/// `si` / `pi` up to `due`, calling `stage(k)` and `measurement(begin, end)` (one measurement:
/// the samples sharing a seq). Returns the number of sensor samples delivered.
template <class StageFn, class MeasurementFn>
std::size_t deliver(const Source& src, std::size_t& si, std::size_t& pi, sim::Timestamp due,
                    std::size_t max_samples, StageFn&& stage, MeasurementFn&& measurement) {
  std::size_t delivered = 0;
  while (delivered < max_samples) {
    const bool stage_next = pi < src.stage.size() &&
                            (si >= src.sensor.size() || src.stage[pi].t <= src.sensor[si].t_host);
    if (stage_next) {
      if (src.stage[pi].t > due) break;
      stage(pi++);
    } else if (si < src.sensor.size()) {
      if (src.sensor[si].t_host > due) break;
      std::size_t end = si + 1;
      while (end < src.sensor.size() && src.sensor[end].seq == src.sensor[si].seq) ++end;
      measurement(si, end);
      delivered += end - si;
      si = end;
    } else {
      break;
    }
  }
  return delivered;
}

/// Samples that are errors rather than misses (no target and over range are normal in a scan).
std::uint64_t error_count(const acq::AccumulatorStats& st) {
  using S = drivers::SensorStatus;
  return st.invalid[static_cast<std::size_t>(S::kOk)] +
         st.invalid[static_cast<std::size_t>(S::kAlarm)] +
         st.invalid[static_cast<std::size_t>(S::kDeviceError)] + st.no_pose() + st.lost;
}

recon::ReconstructOptions recon_options(double cube_mm) {
  recon::ReconstructOptions o;
  if (cube_mm > 0) {
    o.cube_mode = recon::ReconstructOptions::CubeMode::kFixed;
    o.cube_mm = cube_mm;
  }
  return o;
}

void write_record(const std::filesystem::path& file, const ScanRecord& r) {
  toml::table t;
  t.insert("id", r.id);
  t.insert("name", r.name);
  t.insert("state", r.state);
  t.insert("started_utc", r.started_utc);
  t.insert("stopped_utc", r.stopped_utc);
  t.insert("reason", r.reason);
  t.insert("samples", static_cast<std::int64_t>(r.samples));
  t.insert("points", static_cast<std::int64_t>(r.points));
  t.insert("triangles", static_cast<std::int64_t>(r.triangles));
  t.insert("journal_bytes", static_cast<std::int64_t>(r.journal_bytes));
  t.insert("journal", r.journal);
  toml::table params;
  for (const auto& [k, v] : r.parameters)
    std::visit([&](const auto& x) { params.insert(k, x); }, v);
  t.insert("parameters", std::move(params));
  const auto tmp = file.string() + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << t << "\n";
    out.flush();
    if (!out) throw OutputError(tmp + ": cannot write the scan record");
  }
  std::filesystem::rename(tmp, file);
}

std::optional<ScanRecord> read_record(const std::filesystem::path& file) {
  try {
    const toml::table t = toml::parse_file(file.string());
    ScanRecord r;
    r.id = t["id"].value_or<std::int64_t>(0);
    r.name = t["name"].value_or<std::string>("");
    r.state = t["state"].value_or<std::string>("");
    r.started_utc = t["started_utc"].value_or<std::string>("");
    r.stopped_utc = t["stopped_utc"].value_or<std::string>("");
    r.reason = t["reason"].value_or<std::string>("");
    r.samples = static_cast<std::uint64_t>(t["samples"].value_or<std::int64_t>(0));
    r.points = static_cast<std::uint64_t>(t["points"].value_or<std::int64_t>(0));
    r.triangles = static_cast<std::uint64_t>(t["triangles"].value_or<std::int64_t>(0));
    r.journal_bytes = static_cast<std::uint64_t>(t["journal_bytes"].value_or<std::int64_t>(0));
    r.journal = t["journal"].value_or<std::string>("");
    if (const toml::table* p = t["parameters"].as_table()) {
      for (const auto& [k, v] : *p) {
        if (auto b = v.value_exact<bool>())
          r.parameters[std::string(k.str())] = *b;
        else if (auto i = v.value_exact<std::int64_t>())
          r.parameters[std::string(k.str())] = *i;
        else if (auto d = v.value_exact<double>())
          r.parameters[std::string(k.str())] = *d;
        else if (auto s = v.value_exact<std::string>())
          r.parameters[std::string(k.str())] = *s;
      }
    }
    if (r.id <= 0) return std::nullopt;
    return r;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

class PlaybackEngine final : public ScanEngine {
 public:
  PlaybackEngine(const DaemonConfig& config, const Log& log)
      : config_(config),
        log_(log),
        replay_(config.backend == "replay"),
        scans_dir_(config.state_dir / "scans") {
    const std::string prefix = replay_ ? "replay-" : "sim-";
    const std::string port = replay_ ? config.replay.stream.string() : std::string();
    devices_.push_back({prefix + "sensor", "sensor", replay_ ? "replay" : "sim", port,
                        DeviceState::kClosed, "", 0, 0});
    devices_.push_back({prefix + "stage", "stage", replay_ ? "replay" : "sim", port,
                        DeviceState::kClosed, "", 0, 0});
  }

  ~PlaybackEngine() override { shutdown(); }

  std::string_view backend() const override { return replay_ ? "replay" : "sim"; }

  void open(EngineListener& listener) override {
    listener_ = &listener;
    std::error_code ec;
    std::filesystem::create_directories(scans_dir_, ec);
    if (ec)
      throw ConfigError(scans_dir_.string() + ": cannot create the scan folder: " + ec.message());
    load_catalog();
    std::vector<DeviceInfo> opened;
    {
      std::lock_guard lock(m_);
      for (auto& d : devices_) d.state = DeviceState::kOk;
      opened = devices_;
    }
    for (const auto& d : opened) listener_->on_device(d);
  }

  std::vector<DeviceInfo> devices() const override {
    std::lock_guard lock(m_);
    return devices_;
  }

  ScanStatus status() const override {
    std::lock_guard lock(m_);
    ScanStatus s = status_;
    if (s.state == ScanState::kRunning || s.state == ScanState::kStopping)
      s.elapsed_s = elapsed_locked();
    return s;
  }

  ScanRecord start(const std::string& name, const Parameters& parameters) override {
    const ScanParams params = parse_params(config_, parameters, replay_);
    std::unique_lock lock(m_);
    busy_check_locked();
    ScanRecord rec;
    rec.id = next_id_++;
    rec.name = name;
    rec.state = "running";
    rec.started_utc = utc_now();
    rec.parameters = parameters;
    rec.journal = (scans_dir_ / ("scan-" + std::to_string(rec.id) + ".stream")).string();
    records_[rec.id] = rec;
    write_record(record_file(rec.id), rec);
    begin_locked(rec, params, std::nullopt);
    lock.unlock();
    emit_status();
    return rec;
  }

  void pause(const std::string& reason) override {
    {
      std::lock_guard lock(m_);
      if (status_.state != ScanState::kRunning)
        throw EngineError(errc::kBadState, "no scan is running (state " +
                                               std::string(to_string(status_.state)) + ")");
      active_s_ += std::chrono::duration<double>(Clock::now() - run_start_).count();
      status_.state = ScanState::kPaused;
      status_.reason = reason;
      status_.elapsed_s = active_s_;
      pause_ = true;
      records_[status_.id].state = "paused";
    }
    cv_.notify_all();
    emit_status();
  }

  void resume() override {
    {
      std::lock_guard lock(m_);
      if (status_.state != ScanState::kPaused)
        throw EngineError(errc::kBadState, "no scan is paused (state " +
                                               std::string(to_string(status_.state)) + ")");
      run_start_ = Clock::now();
      status_.state = ScanState::kRunning;
      status_.reason.clear();
      pause_ = false;
      records_[status_.id].state = "running";
    }
    cv_.notify_all();
    emit_status();
  }

  void stop(const std::string& reason) override {
    {
      std::lock_guard lock(m_);
      if (status_.state != ScanState::kRunning && status_.state != ScanState::kPaused)
        throw EngineError(errc::kBadState, "no scan is running");
      if (status_.state == ScanState::kRunning)
        active_s_ += std::chrono::duration<double>(Clock::now() - run_start_).count();
      run_start_ = Clock::now();
      status_.state = ScanState::kStopping;
      status_.reason = reason;
      stop_ = true;
      pause_ = false;
    }
    cv_.notify_all();
    emit_status();
  }

  std::vector<ScanRecord> list_scans() const override {
    std::lock_guard lock(m_);
    std::vector<ScanRecord> out;
    for (const auto& [id, r] : records_) out.push_back(live_record_locked(r));
    return out;
  }

  std::optional<ScanRecord> scan_info(std::int64_t id) const override {
    std::lock_guard lock(m_);
    const auto it = records_.find(id);
    if (it == records_.end()) return std::nullopt;
    return live_record_locked(it->second);
  }

  ScanRecord resume_interrupted(std::int64_t id) override {
    ScanRecord rec;
    {
      std::lock_guard lock(m_);
      rec = interrupted_locked(id);
      busy_check_locked();
    }
    const ScanParams params = parse_params(config_, rec.parameters, replay_);
    std::unique_lock lock(m_);
    busy_check_locked();
    rec.state = "running";
    rec.reason = "resumed after an interruption";
    rec.stopped_utc.clear();
    records_[id] = rec;
    write_record(record_file(id), rec);
    begin_locked(rec, params, id);
    lock.unlock();
    emit_status();
    return rec;
  }

  ScanRecord close_interrupted(std::int64_t id) override {
    std::lock_guard lock(m_);
    ScanRecord rec = interrupted_locked(id);
    rec.state = "closed";
    rec.stopped_utc = utc_now();
    rec.reason = "closed after an interruption";
    records_[id] = rec;
    write_record(record_file(id), rec);
    return rec;
  }

  std::shared_ptr<const recon::Mesh> mesh(std::optional<std::int64_t> scan) const override {
    std::int64_t id = 0;
    ScanParams params;
    {
      std::lock_guard lock(m_);
      id = scan.value_or(status_.id);
      if (id == 0) return nullptr;
      const auto it = records_.find(id);
      if (it == records_.end())
        throw EngineError(errc::kNotFound, "no scan " + std::to_string(id) + " in the catalog");
      if (id == status_.id) return current_mesh_;
      if (const auto m = meshes_.find(id); m != meshes_.end()) return m->second;
      params = parse_params(config_, it->second.parameters, replay_);
    }
    // A past scan: re-meshed from its journal.
    std::vector<recon::Vec3> points, towards;
    for (const auto& file : journal_segments(scans_dir_, id)) {
      for (const auto& p : sim::points_from_stream(read_journal(file))) {
        points.push_back(p.point_mm);
        towards.push_back(p.sensor_mm - p.point_mm);
      }
    }
    if (points.empty()) return nullptr;
    std::shared_ptr<const recon::Mesh> m;
    try {
      m = std::make_shared<const recon::Mesh>(
          recon::reconstruct(points, recon_options(params.cube_mm), {}, towards).mesh);
    } catch (const GeometryError& e) {
      log_.warning("scan " + std::to_string(id) + ": its points make no mesh: " + e.what());
      return nullptr;
    }
    std::lock_guard lock(m_);
    meshes_[id] = m;
    return m;
  }

  void shutdown() noexcept override {
    {
      std::lock_guard lock(m_);
      shutdown_ = true;
      if (status_.state == ScanState::kRunning || status_.state == ScanState::kPaused) {
        stop_ = true;
        pause_ = false;
        status_.reason = "daemon stopping";
      }
    }
    cv_.notify_all();
    mesh_cv_.notify_all();
    if (worker_.joinable()) worker_.join();
  }

 private:
  std::filesystem::path record_file(std::int64_t id) const {
    return scans_dir_ / ("scan-" + std::to_string(id) + ".toml");
  }

  /// The running scan's record carries its live counts.
  ScanRecord live_record_locked(ScanRecord r) const {
    if (r.id == status_.id && status_.state != ScanState::kIdle) {
      r.samples = status_.counters.samples;
      r.points = status_.counters.points;
      r.triangles = status_.counters.triangles;
      r.journal_bytes = status_.counters.journal_bytes;
    }
    return r;
  }

  void busy_check_locked() const {
    if (status_.state != ScanState::kIdle)
      throw EngineError(errc::kBusy, "scan " + std::to_string(status_.id) + " '" + status_.name +
                                         "' is " + std::string(to_string(status_.state)));
    if (shutdown_) throw EngineError(errc::kShuttingDown, "the daemon is stopping");
  }

  ScanRecord interrupted_locked(std::int64_t id) const {
    const auto it = records_.find(id);
    if (it == records_.end())
      throw EngineError(errc::kNotFound, "no scan " + std::to_string(id) + " in the catalog");
    if (it->second.state != "interrupted")
      throw EngineError(errc::kBadState, "scan " + std::to_string(id) + " is " + it->second.state +
                                             ", not interrupted");
    return it->second;
  }

  /// Scans the folder: a record left "running" or "paused" belongs to a daemon that died; its
  /// counts are what its journal holds.
  void load_catalog() {
    std::lock_guard lock(m_);
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator(scans_dir_, ec)) {
      if (e.path().extension() != ".toml") continue;
      auto rec = read_record(e.path());
      if (!rec) {
        log_.warning(e.path().string() + ": unreadable scan record, ignored");
        continue;
      }
      if (rec->state == "running" || rec->state == "paused" || rec->state == "stopping") {
        rec->state = "interrupted";
        rec->reason = "the daemon stopped during the scan";
        rec->samples = rec->points = rec->journal_bytes = 0;
        for (const auto& file : journal_segments(scans_dir_, rec->id)) {
          try {
            const sim::RecordedStream s = read_journal(file);
            rec->samples += s.sensor.size();
            rec->journal_bytes += std::filesystem::file_size(file, ec);
          } catch (const std::exception& err) {
            log_.warning(file.string() + ": " + err.what());
          }
        }
        write_record(e.path(), *rec);
        log_.notice("scan " + std::to_string(rec->id) + " '" + rec->name + "' was interrupted: " +
                    std::to_string(rec->samples) + " samples in its journal (resume or close it)");
      }
      next_id_ = std::max(next_id_, rec->id + 1);
      records_[rec->id] = *rec;
    }
  }

  double elapsed_locked() const {
    if (status_.state == ScanState::kRunning)
      return active_s_ + std::chrono::duration<double>(Clock::now() - run_start_).count();
    return active_s_;
  }

  void emit_status() {
    const ScanStatus s = status();
    if (listener_) listener_->on_scan(s);
  }

  void begin_locked(const ScanRecord& rec, const ScanParams& params,
                    std::optional<std::int64_t> resumed) {
    if (worker_.joinable()) worker_.join();  // the last scan's worker has finished
    status_ = ScanStatus{};
    status_.state = ScanState::kRunning;
    status_.id = rec.id;
    status_.name = rec.name;
    status_.progress = 0;
    active_s_ = 0;
    run_start_ = Clock::now();
    pause_ = stop_ = false;
    current_mesh_.reset();
    worker_ = std::thread([this, rec, params, resumed] { run_scan(rec, params, resumed); });
  }

  // ---- the worker

  struct Live {  // shared between the worker and the mesher, under m_
    std::vector<recon::Vec3> points, towards;
    std::uint64_t meshed = 0;
    bool final_requested = false, final_done = false, quit = false;
  };

  void run_scan(ScanRecord rec, ScanParams params, std::optional<std::int64_t> resumed) noexcept {
    ::pthread_setname_np(::pthread_self(), "scan-playback");  // visible in top -H and the bench
    std::string failure;
    try {
      play(rec, params, resumed.has_value());
    } catch (const std::exception& e) {
      failure = e.what();
      log_.error("scan " + std::to_string(rec.id) + " failed: " + failure);
    }
    ScanStatus final_status;
    {
      std::lock_guard lock(m_);
      ScanRecord& r = records_[rec.id];
      r.samples = status_.counters.samples;
      r.points = status_.counters.points;
      r.triangles = status_.counters.triangles;
      r.journal_bytes = status_.counters.journal_bytes;
      r.stopped_utc = utc_now();
      if (!failure.empty()) {
        r.state = "failed";
        r.reason = failure;
      } else if (stop_) {
        r.state = "stopped";
        r.reason = status_.reason;
      } else {
        r.state = "finished";
        r.reason.clear();
      }
      try {
        write_record(record_file(rec.id), r);
      } catch (const std::exception& e) {
        log_.error(e.what());
      }
      if (current_mesh_) meshes_[rec.id] = current_mesh_;
      if (status_.state == ScanState::kRunning) active_s_ = elapsed_locked();
      status_.elapsed_s = active_s_;
      status_.state = ScanState::kIdle;
      status_.reason =
          r.state == "finished" ? "finished" : r.state + (r.reason.empty() ? "" : ": " + r.reason);
      final_status = status_;
    }
    if (listener_) listener_->on_scan(final_status);
  }

  void play(const ScanRecord& rec, const ScanParams& params, bool resumed) {
    std::vector<std::pair<std::string, std::string>> info{{"scan_id", std::to_string(rec.id)},
                                                          {"scan_name", rec.name},
                                                          {"started_utc", rec.started_utc}};
    Source src;
    if (replay_) {
      sim::RecordedStream s = sim::read_stream(params.stream);
      src.header = s.header;
      src.sensor = std::move(s.sensor);
      src.stage = std::move(s.stage);
    } else {
      src = simulate_source(params, info);
    }
    {
      // Scanning time starts now that the samples are ready (the simulation's ray casting is the
      // scanner's work, not scanning time).
      std::lock_guard lock(m_);
      if (status_.state == ScanState::kRunning) {
        run_start_ = Clock::now();
        active_s_ = 0;
      }
    }
    std::size_t si = 0, pi = 0;  // next sensor sample and stage sample to deliver
    Live live;
    // Acquisition's own mapping: stage poses interpolated at each sample, the calibration applied.
    acq::Accumulator accumulator;
    const std::uint16_t device = accumulator.add_sensor(src.header.sensor, src.header.calibration);
    std::vector<acq::MeasuredPoint> mapped;
    auto to_live = [&](std::vector<recon::Vec3>& points, std::vector<recon::Vec3>& towards) {
      for (const auto& p : mapped) {
        points.push_back(p.point_mm);
        towards.push_back(p.sensor_mm - p.point_mm);
      }
      mapped.clear();
    };
    std::uint64_t journal_before = 0;
    int segment = 1;
    if (resumed) {
      // What the earlier segments acknowledged is kept; delivery continues after it. The source
      // is deterministic: its prefix must be what the journal holds.
      std::uint64_t recorded = 0, recorded_stage = 0;
      for (const auto& file : journal_segments(scans_dir_, rec.id)) {
        const sim::RecordedStream s = read_journal(file);
        for (std::size_t i = 0; i < s.sensor.size(); ++i) {
          const std::size_t k = recorded + i;
          if (k >= src.sensor.size() || src.sensor[k].seq != s.sensor[i].seq ||
              src.sensor[k].t_host != s.sensor[i].t_host)
            throw EngineError(errc::kBadState,
                              file.string() + ": the journal does not match its source (sample " +
                                  std::to_string(k) + ")");
        }
        recorded += s.sensor.size();
        recorded_stage += s.stage.size();
        std::error_code ec;
        journal_before += std::filesystem::file_size(file, ec);
        ++segment;
      }
      // The journal holds whole measurements (one line each): the recorded prefix is mapped again
      // (without journalling it twice) and delivery continues after it.
      std::size_t rs = 0, rp = 0;
      const std::size_t stage_end = std::min<std::size_t>(recorded_stage, src.stage.size());
      const std::size_t sensor_end = std::min<std::size_t>(recorded, src.sensor.size());
      deliver(
          src, rs, rp, sim::Timestamp{INT64_MAX}, SIZE_MAX,
          [&](std::size_t k) {
            if (k < stage_end) accumulator.add_stage(src.stage[k], mapped);
          },
          [&](std::size_t b, std::size_t e) {
            if (e <= sensor_end)
              accumulator.add_sensor_samples(device, std::span(src.sensor).subspan(b, e - b),
                                             mapped);
          });
      si = sensor_end;
      pi = stage_end;
      to_live(live.points, live.towards);
      std::lock_guard lock(m_);
      status_.counters.samples = recorded;
      status_.counters.points = live.points.size();
      status_.counters.journal_bytes = journal_before;
    }
    const auto journal_path =
        scans_dir_ / ("scan-" + std::to_string(rec.id) +
                      (segment == 1 ? "" : "." + std::to_string(segment)) + ".stream");
    std::ofstream out(journal_path, std::ios::binary | std::ios::trunc);
    if (!out) throw OutputError(journal_path.string() + ": cannot create the journal");
    sim::StreamHeader header = src.header;
    for (auto& kv : info) header.info.push_back(kv);
    sim::StreamWriter writer(out, header);

    std::thread mesher([this, &live, &params, id = rec.id] { mesh_loop(live, params, id); });
    struct JoinMesher {
      std::thread& t;
      PlaybackEngine& e;
      Live& live;
      ~JoinMesher() {
        {
          std::lock_guard lock(e.m_);
          live.quit = true;
        }
        e.mesh_cv_.notify_all();
        if (t.joinable()) t.join();
      }
    } join_mesher{mesher, *this, live};

    const sim::Timestamp t0 =
        std::min(si < src.sensor.size() ? src.sensor[si].t_host : sim::Timestamp{INT64_MAX},
                 pi < src.stage.size() ? src.stage[pi].t : sim::Timestamp{INT64_MAX});
    std::deque<std::pair<Clock::time_point, std::uint64_t>> window;  // rate over the last second
    std::vector<recon::Vec3> new_points, new_towards;
    constexpr std::size_t kChunk = 20000;  // samples per step when playing as fast as possible
    const auto tick = std::chrono::milliseconds(20);
    for (;;) {
      double active = 0;
      {
        std::unique_lock lock(m_);
        cv_.wait(lock, [&] { return !pause_ || stop_; });
        if (stop_) break;
        active = elapsed_locked();
      }
      // Deliver everything due, stage and sensor merged by time: journal first, then mapping.
      const bool unpaced = params.playback <= 0;
      const sim::Timestamp due = unpaced ? sim::Timestamp{INT64_MAX}
                                         : t0 + std::chrono::nanoseconds(static_cast<std::int64_t>(
                                                    active * params.playback * 1e9));
      const std::size_t delivered = deliver(
          src, si, pi, due, unpaced ? kChunk : SIZE_MAX,
          [&](std::size_t k) {
            writer.on_stage(src.stage[k]);
            accumulator.add_stage(src.stage[k], mapped);
          },
          [&](std::size_t b, std::size_t e) {
            const auto m = std::span(src.sensor).subspan(b, e - b);
            writer.on_sensor(m);
            accumulator.add_sensor_samples(device, m, mapped);
          });
      const bool done = si >= src.sensor.size() && pi >= src.stage.size();
      if (done) accumulator.finish(mapped);
      out.flush();  // what is flushed is acknowledged
      if (!out) throw OutputError(journal_path.string() + ": write failed (disk full?)");
      new_points.clear();
      new_towards.clear();
      to_live(new_points, new_towards);
      const auto now = Clock::now();
      bool want_mesh = false;
      {
        std::lock_guard lock(m_);
        live.points.insert(live.points.end(), new_points.begin(), new_points.end());
        live.towards.insert(live.towards.end(), new_towards.begin(), new_towards.end());
        auto& c = status_.counters;
        c.samples = si;
        c.points = live.points.size();
        c.journal_bytes = journal_before + static_cast<std::uint64_t>(out.tellp());
        c.errors = error_count(accumulator.stats());
        window.emplace_back(now, c.samples);
        while (window.size() > 2 && now - window.front().first > std::chrono::seconds(1))
          window.pop_front();
        const double dt = std::chrono::duration<double>(now - window.front().first).count();
        c.rate_hz = dt > 0 ? static_cast<double>(c.samples - window.front().second) / dt : 0;
        c.meshing_lag_points = c.points - live.meshed;
        const double points_per_sample =
            c.samples > 0 ? static_cast<double>(c.points) / static_cast<double>(c.samples) : 0;
        c.meshing_lag_s =
            c.rate_hz * points_per_sample > 0
                ? static_cast<double>(c.meshing_lag_points) / (c.rate_hz * points_per_sample)
                : 0;
        status_.progress = src.sensor.empty()
                               ? 1.0
                               : static_cast<double>(si) / static_cast<double>(src.sensor.size());
        devices_[0].samples += delivered;
        devices_[1].samples = pi;
        want_mesh = live.points.size() - live.meshed >= params.remesh_points;
      }
      if (want_mesh) mesh_cv_.notify_all();
      if (done) break;
      if (!unpaced) {
        std::unique_lock lock(m_);
        cv_.wait_for(lock, tick, [&] { return stop_ || pause_; });
      }
    }
    writer.finish();
    out.flush();
    if (!out) throw OutputError(journal_path.string() + ": write failed (disk full?)");
    {
      std::lock_guard lock(m_);
      status_.counters.journal_bytes = journal_before + static_cast<std::uint64_t>(out.tellp());
      if (shutdown_) return;  // stopping the daemon: the journal has everything; no final mesh
      live.final_requested = true;
    }
    mesh_cv_.notify_all();
    std::unique_lock lock(m_);
    mesh_cv_.wait(lock, [&] { return live.final_done || shutdown_; });
  }

  void mesh_loop(Live& live, const ScanParams& params, std::int64_t id) noexcept {
    ::pthread_setname_np(::pthread_self(), "scan-mesher");
    for (;;) {
      std::vector<recon::Vec3> points, towards;
      bool final = false;
      {
        std::unique_lock lock(m_);
        mesh_cv_.wait(lock, [&] {
          return live.quit || live.final_requested ||
                 live.points.size() - live.meshed >= params.remesh_points;
        });
        if (live.quit) return;
        if (live.final_requested && live.meshed == live.points.size() && current_mesh_) {
          live.final_done = true;
          mesh_cv_.notify_all();
          continue;
        }
        final = live.final_requested;
        points = live.points;
        towards = live.towards;
      }
      std::shared_ptr<const recon::Mesh> mesh;
      try {
        if (!points.empty())
          mesh = std::make_shared<const recon::Mesh>(
              recon::reconstruct(points, recon_options(params.cube_mm), {}, towards).mesh);
      } catch (const std::exception& e) {
        if (final) log_.warning("scan " + std::to_string(id) + ": meshing failed: " + e.what());
      }
      MeshCounts counts;
      {
        std::lock_guard lock(m_);
        const std::uint64_t before = current_mesh_ ? current_mesh_->triangles.size() : 0;
        live.meshed = points.size();
        if (mesh) current_mesh_ = mesh;
        auto& c = status_.counters;
        c.triangles = current_mesh_ ? current_mesh_->triangles.size() : 0;
        c.vertices = current_mesh_ ? current_mesh_->vertices.size() : 0;
        c.meshing_lag_points = c.points - std::min<std::uint64_t>(c.points, live.meshed);
        counts.scan = id;
        counts.vertices = c.vertices;
        counts.triangles = c.triangles;
        // A batch re-mesh replaces the mesh: everything old is removed, everything new added.
        counts.added = mesh ? c.triangles : 0;
        counts.removed = mesh ? before : 0;
        if (final && live.meshed == live.points.size()) {
          live.final_done = true;
          if (!current_mesh_) current_mesh_ = std::make_shared<const recon::Mesh>();
        }
      }
      mesh_cv_.notify_all();
      if (mesh && listener_) listener_->on_mesh(counts);
    }
  }

  DaemonConfig config_;
  const Log& log_;
  bool replay_;
  std::filesystem::path scans_dir_;
  EngineListener* listener_ = nullptr;

  mutable std::mutex m_;
  std::condition_variable cv_;       // pause / stop
  std::condition_variable mesh_cv_;  // worker <-> mesher
  std::vector<DeviceInfo> devices_;
  ScanStatus status_;
  double active_s_ = 0;
  Clock::time_point run_start_;
  bool pause_ = false, stop_ = false, shutdown_ = false;
  std::map<std::int64_t, ScanRecord> records_;
  mutable std::map<std::int64_t, std::shared_ptr<const recon::Mesh>> meshes_;
  std::shared_ptr<const recon::Mesh> current_mesh_;
  std::int64_t next_id_ = 1;
  std::thread worker_;
};

}  // namespace

std::unique_ptr<ScanEngine> make_playback_engine(const DaemonConfig& config, const Log& log) {
  return std::make_unique<PlaybackEngine>(config, log);
}

}  // namespace scanmesh::daemon
