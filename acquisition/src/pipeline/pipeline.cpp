// The scan pipeline's threads: ingest (journal, accumulator) and meshing.
// SPDX-License-Identifier: MIT
#include "scanmesh/acquisition/pipeline.hpp"

#include <nlohmann/json.hpp>

#include "scanmesh/common/error.hpp"

namespace scanmesh::acq {

std::string_view to_string(PipelineState state) {
  switch (state) {
    case PipelineState::kIdle:
      return "idle";
    case PipelineState::kRunning:
      return "running";
    case PipelineState::kPaused:
      return "paused";
    case PipelineState::kStopping:
      return "stopping";
    case PipelineState::kCompleted:
      return "completed";
    case PipelineState::kStopped:
      return "stopped";
    case PipelineState::kFailed:
      return "failed";
  }
  return "?";
}

/// The SampleInput the backend's threads call: records are queued for the ingest thread.
class Pipeline::Input final : public SampleInput {
 public:
  explicit Input(Pipeline& p) : p_(p) {}
  void on_sensor(std::uint16_t device, std::span<const SensorSample> samples) override {
    std::lock_guard lock(p_.in_mutex_);
    for (const auto& s : samples) p_.incoming_.push_back(Record{s, device});
  }
  void on_stage(const StageSample& sample) override {
    std::lock_guard lock(p_.in_mutex_);
    p_.incoming_.push_back(Record{sample, 0});
  }
  void on_probe(std::uint16_t device, const ProbeTrigger& trigger) override {
    std::lock_guard lock(p_.in_mutex_);
    p_.incoming_.push_back(Record{trigger, device});
  }
  void on_device_state(std::string_view device, drivers::DeviceState state,
                       std::string_view reason) override {
    {
      std::lock_guard lock(p_.in_mutex_);
      p_.incoming_.push_back(
          Record{DeviceChange{std::string(device), state, std::string(reason)}, 0});
    }
    p_.in_cv_.notify_one();
  }
  void on_end() override {
    {
      std::lock_guard lock(p_.in_mutex_);
      p_.end_ = true;
    }
    p_.in_cv_.notify_one();
  }
  void on_failure(std::string_view message) override {
    {
      std::lock_guard lock(p_.in_mutex_);
      if (p_.failure_.empty()) p_.failure_ = std::string(message);
    }
    p_.in_cv_.notify_one();
  }

 private:
  Pipeline& p_;
};

Pipeline::Pipeline(ScanBackend& backend, std::unique_ptr<Recorder> recorder,
                   std::unique_ptr<Mesher> mesher, PipelineConfig config,
                   PipelineEventCallback on_event)
    : backend_(&backend),
      recorder_(std::move(recorder)),
      mesher_(std::move(mesher)),
      config_(std::move(config)),
      on_event_(std::move(on_event)),
      input_(std::make_unique<Input>(*this)),
      accumulator_(backend.model().accumulator) {
  if (!mesher_) throw ConfigError("pipeline: a mesher is required");
  if (config_.cycle < std::chrono::milliseconds(1) || config_.cycle > std::chrono::seconds(1))
    throw ConfigError("pipeline: cycle must be in 1 .. 1000 ms");
  for (const auto& s : backend.model().sensors) accumulator_.add_sensor(s.config, s.calibration);
}

Pipeline::~Pipeline() {
  if (ingest_thread_.joinable() || mesh_thread_.joinable()) {
    stop();
    if (ingest_thread_.joinable()) ingest_thread_.join();
    if (mesh_thread_.joinable()) mesh_thread_.join();
  }
}

void Pipeline::start() {
  {
    std::lock_guard lock(state_mutex_);
    if (stats_.state != PipelineState::kIdle) throw ConfigError("pipeline: already started");
  }
  if (recorder_) recorder_->write_parameters(config_.parameters_json);
  started_ = std::chrono::steady_clock::now();
  last_progress_ = started_;
  ingest_thread_ = std::jthread([this] { ingest_loop(); });
  mesh_thread_ = std::jthread([this] { mesh_loop(); });
  set_state(PipelineState::kRunning, "");
  try {
    backend_->start(*input_);
  } catch (const std::exception& e) {
    input_->on_failure(e.what());
    ingest_thread_.join();
    mesh_thread_.join();
    throw;
  }
}

void Pipeline::pause() {
  {
    std::lock_guard lock(state_mutex_);
    if (stats_.state != PipelineState::kRunning) return;
  }
  backend_->pause();
  set_state(PipelineState::kPaused, "paused by request");
}

void Pipeline::resume() {
  {
    std::lock_guard lock(state_mutex_);
    if (stats_.state != PipelineState::kPaused) return;
    auto_paused_ = false;
  }
  backend_->resume();
  set_state(PipelineState::kRunning, "");
}

void Pipeline::stop() {
  {
    std::lock_guard lock(in_mutex_);
    stop_requested_ = true;
  }
  in_cv_.notify_one();
}

PipelineState Pipeline::wait() {
  std::unique_lock lock(state_mutex_);
  state_cv_.wait(lock, [this] { return over_ || stats_.state == PipelineState::kIdle; });
  return stats_.state;
}

bool Pipeline::wait_for(std::chrono::milliseconds timeout) {
  std::unique_lock lock(state_mutex_);
  return state_cv_.wait_for(lock, timeout, [this] { return over_; });
}

PipelineStats Pipeline::stats() const {
  std::lock_guard lock(state_mutex_);
  PipelineStats s = stats_;
  if (stats_.state != PipelineState::kIdle)
    s.elapsed = (over_ ? ended_ : std::chrono::steady_clock::now()) - started_;
  return s;
}

recon::Mesh Pipeline::snapshot() {
  std::future<recon::Mesh> f;
  {
    std::lock_guard lock(mesh_mutex_);
    {
      std::lock_guard s(state_mutex_);
      if (over_) return result_;
      if (stats_.state == PipelineState::kIdle) return {};
    }
    snapshot_requests_.emplace_back();
    f = snapshot_requests_.back().get_future();
  }
  mesh_cv_.notify_one();
  return f.get();
}

void Pipeline::set_state(PipelineState state, std::string reason) {
  {
    std::lock_guard lock(state_mutex_);
    if (stats_.state == state && stats_.reason == reason) return;
    stats_.state = state;
    stats_.reason = reason;
  }
  state_cv_.notify_all();
  emit("state", "", std::move(reason));
}

void Pipeline::emit(std::string kind, std::string device, std::string message) {
  if (!on_event_) return;
  PipelineEvent e{std::move(kind), std::move(device), std::move(message), stats()};
  try {
    on_event_(e);
  } catch (...) {
    // An observer's failure must not stop the scan.
  }
}

void Pipeline::fail(std::string message) {
  {
    std::lock_guard lock(in_mutex_);
    if (failure_.empty()) failure_ = std::move(message);
  }
  in_cv_.notify_one();
}

void Pipeline::ingest_loop() {
  std::vector<Record> records;
  bool finishing = false;
  while (true) {
    {
      std::unique_lock lock(in_mutex_);
      in_cv_.wait_for(lock, config_.cycle,
                      [this] { return end_ || stop_requested_ || !failure_.empty(); });
      records.swap(incoming_);
      if (!finishing && (end_ || stop_requested_ || !failure_.empty())) {
        finishing = true;
        std::lock_guard s(state_mutex_);
        if (!failure_.empty()) {
          final_state_ = PipelineState::kFailed;
          final_reason_ = failure_;
        } else if (stop_requested_ && !end_) {
          final_state_ = PipelineState::kStopped;
          final_reason_ = "stopped by request";
        }
      }
    }
    if (finishing) {
      // Nothing is pushed after the backend's stop() returns: take what came before it.
      set_state(PipelineState::kStopping, final_reason());
      backend_->stop();
      std::lock_guard lock(in_mutex_);
      records.insert(records.end(), std::make_move_iterator(incoming_.begin()),
                     std::make_move_iterator(incoming_.end()));
      incoming_.clear();
    }
    process(records);
    records.clear();
    if (finishing) accumulator_.finish(points_);
    if (recorder_ && !recorder_failed_) {
      try {
        if (finishing) {
          recorder_->close();
        } else {
          recorder_->flush();
        }
      } catch (const std::exception& e) {
        recorder_error(e.what());
      }
    }
    // The counts first: once ingest_done_ is seen, the meshing thread may end the scan and
    // wait() return, and the final counts must already be there.
    publish_ingest_stats();
    {
      std::lock_guard lock(mesh_mutex_);
      to_mesh_.insert(to_mesh_.end(), points_.begin(), points_.end());
      if (finishing) ingest_done_ = true;
    }
    points_.clear();
    mesh_cv_.notify_one();
    if (finishing) break;
  }
}

void Pipeline::recorder_error(const std::string& what) {
  // The journal refuses further writes; the scan stops with what was recorded.
  recorder_failed_ = true;
  {
    std::lock_guard s(state_mutex_);
    if (final_state_ != PipelineState::kFailed) {
      final_state_ = PipelineState::kFailed;
      final_reason_ = "journal: " + what;
    }
  }
  fail("journal: " + what);
}

std::string Pipeline::final_reason() const {
  std::lock_guard s(state_mutex_);
  return final_reason_;
}

void Pipeline::process(std::vector<Record>& records) {
  std::size_t i = 0;
  while (i < records.size()) {
    Record& r = records[i];
    if (auto* s = std::get_if<SensorSample>(&r.value)) {
      // A run of one device's samples goes to the journal and the accumulator as one batch.
      run_.clear();
      run_.push_back(*s);
      std::size_t j = i + 1;
      while (j < records.size() && records[j].device == r.device &&
             std::holds_alternative<SensorSample>(records[j].value)) {
        run_.push_back(std::get<SensorSample>(records[j].value));
        ++j;
      }
      if (record([&] { recorder_->write_sensor(r.device, run_); }))
        accumulator_.add_sensor_samples(r.device, run_, points_);
      i = j;
      continue;
    }
    if (auto* g = std::get_if<StageSample>(&r.value)) {
      if (record([&] { recorder_->write_stage(*g); })) accumulator_.add_stage(*g, points_);
    } else if (auto* p = std::get_if<ProbeTrigger>(&r.value)) {
      if (record([&] { recorder_->write_probe(r.device, *p); }))
        accumulator_.add_probe(r.device, *p, points_);
    } else if (auto* d = std::get_if<DeviceChange>(&r.value)) {
      device_changed(*d);
    }
    ++i;
  }
}

void Pipeline::device_changed(const DeviceChange& change) {
  record([&] {
    nlohmann::json j{{"event", "device"},
                     {"device", change.name},
                     {"state", drivers::to_string(change.state)},
                     {"reason", change.reason}};
    recorder_->write_event(j.dump());
  });
  emit("device", change.name,
       change.reason.empty() ? std::string(drivers::to_string(change.state)) : change.reason);
  if (!config_.pause_on_device_loss) return;
  bool pause_now = false, resume_now = false;
  {
    std::lock_guard lock(state_mutex_);
    if (change.state == drivers::DeviceState::kLost && stats_.state == PipelineState::kRunning) {
      auto_paused_ = true;
      pause_now = true;
    } else if (change.state == drivers::DeviceState::kAcquiring && auto_paused_ &&
               stats_.state == PipelineState::kPaused) {
      auto_paused_ = false;
      resume_now = true;
    }
  }
  if (pause_now) {
    backend_->pause();
    set_state(PipelineState::kPaused,
              "device lost: " + (change.reason.empty() ? change.name : change.reason));
  } else if (resume_now) {
    backend_->resume();
    set_state(PipelineState::kRunning, "");
  }
}

void Pipeline::publish_ingest_stats() {
  const AccumulatorStats& a = accumulator_.stats();
  bool progress = false;
  {
    std::lock_guard lock(state_mutex_);
    stats_.samples_received = a.samples;
    stats_.stage_samples = a.stage_samples;
    stats_.points = a.points;
    stats_.invalid = a.invalid_total();
    stats_.no_pose = a.no_pose();
    stats_.lost = a.lost;
    if (recorder_) {
      stats_.samples_recorded = recorder_->acknowledged_samples();
      stats_.journal_bytes = recorder_->bytes();
    }
    stats_.meshing_lag = stats_.points - stats_.mesh.points_in + stats_.mesh.pending_points;
    const auto now = std::chrono::steady_clock::now();
    if (now - last_progress_ >= config_.progress_interval) {
      last_progress_ = now;
      progress = true;
    }
  }
  if (progress) emit("progress", "", "");
}

void Pipeline::mesh_loop() {
  std::vector<MeasuredPoint> batch;
  bool failed = false;
  while (true) {
    std::vector<std::promise<recon::Mesh>> requests;
    bool done = false;
    {
      std::unique_lock lock(mesh_mutex_);
      mesh_cv_.wait(lock, [this] {
        return !to_mesh_.empty() || ingest_done_ || !snapshot_requests_.empty();
      });
      batch.swap(to_mesh_);
      requests.swap(snapshot_requests_);
      done = ingest_done_ && to_mesh_.empty();
    }
    try {
      if (!failed && !batch.empty()) mesher_->add(batch);
      batch.clear();
      {
        std::lock_guard lock(state_mutex_);
        stats_.mesh = mesher_->progress();
        stats_.meshing_lag = stats_.points - stats_.mesh.points_in + stats_.mesh.pending_points;
      }
      if (done) {
        if (!failed) result_ = mesher_->finish();
        for (auto& r : requests) r.set_value(result_);
        requests.clear();
      } else if (!requests.empty()) {
        const recon::Mesh m = mesher_->snapshot();
        for (auto& r : requests) r.set_value(m);
      }
    } catch (const std::exception& e) {
      for (auto& r : requests) r.set_exception(std::current_exception());
      failed = true;
      {
        std::lock_guard s(state_mutex_);
        final_state_ = PipelineState::kFailed;
        final_reason_ = std::string("meshing: ") + e.what();
      }
      fail(std::string("meshing: ") + e.what());
    }
    if (done) break;
  }
  PipelineState final_state;
  std::string reason;
  {
    std::lock_guard lock(state_mutex_);
    stats_.mesh = mesher_->progress();
    stats_.meshing_lag = 0;
    final_state = final_state_;
    reason = final_reason_;
    ended_ = std::chrono::steady_clock::now();
  }
  // Observers hear the final state before wait() returns.
  set_state(final_state, reason);
  emit("progress", "", "");
  {
    std::lock_guard mesh_lock(mesh_mutex_);
    std::lock_guard lock(state_mutex_);
    over_ = true;
    stats_.elapsed = ended_ - started_;
    // Snapshot requests that came in after the final mesh get it.
    for (auto& r : snapshot_requests_) r.set_value(result_);
    snapshot_requests_.clear();
  }
  state_cv_.notify_all();
}

}  // namespace scanmesh::acq
