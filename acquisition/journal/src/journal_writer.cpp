// JournalWriter: typed channels over mcap::Writer, sample batches split to fill chunks, log
// times kept non-decreasing so that file order is log-time order (see JOURNAL.md).
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <set>

#include "messages.hpp"
#include "scanmesh/acquisition/journal.hpp"

namespace scanmesh::acq {

using namespace detail;

std::vector<std::string> JournalOptions::validate() const {
  mcap::WriterOptions w;
  w.chunk_bytes = chunk_bytes;
  w.chunk_duration = chunk_duration;
  w.fsync_interval = fsync_interval;
  w.fsync_bytes = fsync_bytes;
  return w.validate();
}

namespace {

mcap::WriterOptions writer_options(const JournalOptions& o) {
  if (auto bad = o.validate(); !bad.empty()) {
    std::string msg = "journal options:";
    for (const auto& b : bad) msg += " " + b + ";";
    msg.pop_back();
    throw ConfigError(msg);
  }
  mcap::WriterOptions w;
  w.chunk_bytes = o.chunk_bytes;
  w.chunk_duration = o.chunk_duration;
  w.fsync_interval = o.fsync_interval;
  w.fsync_bytes = o.fsync_bytes;
  return w;
}

std::uint64_t non_negative(std::int64_t t) { return t < 0 ? 0 : static_cast<std::uint64_t>(t); }

}  // namespace

struct JournalWriter::Impl {
  Impl(std::filesystem::path path, JournalOptions options)
      : metadata{"scanmesh.journal", options.metadata},
        writer(std::move(path), writer_options(options), &metadata),
        opt(std::move(options)) {}

  mcap::Metadata metadata;
  mcap::Writer writer;
  JournalOptions opt;
  std::uint16_t sensor_schema = 0;
  std::uint16_t stage_schema = 0;
  std::uint16_t probe_schema = 0;
  std::uint16_t events_channel = 0;
  std::uint16_t parameters_channel = 0;
  std::set<std::string> topics;
  std::vector<ChannelKind> kinds{ChannelKind::kOther};  // by channel id
  std::vector<std::uint32_t> sequence{0};               // by channel id
  std::uint64_t last_log_time = 0;
  std::uint64_t written = 0;

  /// Log time of a record at sample time t: never before the previous record's, so that the
  /// file's order is its log-time order.
  std::uint64_t log_time(std::int64_t t) {
    last_log_time = std::max(last_log_time, non_negative(t));
    return last_log_time;
  }
  [[nodiscard]] std::uint64_t peek_log_time(std::int64_t t) const {
    return std::max(last_log_time, non_negative(t));
  }

  std::uint16_t channel(ChannelKind kind, std::uint16_t& schema, std::string_view schema_name,
                        std::string_view schema_text, std::string_view schema_encoding,
                        std::string_view message_encoding, std::string topic, std::string device,
                        std::map<std::string, std::string> meta) {
    if (!topics.insert(topic).second)
      throw ConfigError("journal " + writer.path().string() + ": a channel " + topic +
                        " exists already (device names are unique per kind)");
    if (schema == 0)
      schema = writer.add_schema(std::string(schema_name), std::string(schema_encoding),
                                 std::string(schema_text));
    meta["kind"] = std::string(to_string(kind));
    if (!device.empty()) meta["device"] = std::move(device);
    const auto id = writer.add_channel(schema, std::move(topic), std::string(message_encoding),
                                       std::move(meta));
    kinds.resize(std::size_t{id} + 1, ChannelKind::kOther);
    sequence.resize(std::size_t{id} + 1, 0);
    kinds[id] = kind;
    return id;
  }

  std::uint16_t device_channel(ChannelKind kind, std::string_view device,
                               std::map<std::string, std::string> meta) {
    if (device.empty() || device.find('/') != std::string_view::npos)
      throw ConfigError("journal " + writer.path().string() + ": a device name must be non-empty " +
                        "and without '/', got '" + std::string(device) + "'");
    switch (kind) {
      case ChannelKind::kSensor:
        return channel(kind, sensor_schema, kSensorSchemaName, sensor_schema_text(), "ros2msg",
                       "cdr", "/sensors/" + std::string(device), std::string(device),
                       std::move(meta));
      case ChannelKind::kStage:
        return channel(kind, stage_schema, kStageSchemaName, stage_schema_text(), "ros2msg", "cdr",
                       "/stages/" + std::string(device), std::string(device), std::move(meta));
      default:
        return channel(kind, probe_schema, kProbeSchemaName, probe_schema_text(), "ros2msg", "cdr",
                       "/probes/" + std::string(device), std::string(device), std::move(meta));
    }
  }

  void check_channel(std::uint16_t id, ChannelKind kind, const char* what) const {
    if (id == 0 || id >= kinds.size() || kinds[id] != kind)
      throw ConfigError("journal " + writer.path().string() + ": " + what +
                        " on a channel that is not one of this journal's " +
                        std::string(to_string(kind)) + " channels");
  }

  void write_pose(std::uint16_t id, std::uint64_t seq, drivers::Timestamp t,
                  const drivers::StagePose& pose, bool probe) {
    const mcap::MessageHeader h{id, sequence[id]++, log_time(t.ns), non_negative(t.ns)};
    auto out = writer.add_message(h, kPoseMessageBytes, 1);
    if (probe) {
      drivers::ProbeTrigger g;
      g.seq = seq;
      g.t = t;
      g.pose = pose;
      encode_probe(g, out.data());
    } else {
      drivers::StageSample s;
      s.seq = seq;
      s.t = t;
      s.pose = pose;
      encode_stage(s, out.data());
    }
    ++written;
    writer.flush_if_due();
  }

  void write_json(std::uint16_t& id, ChannelKind kind, drivers::Timestamp t,
                  const nlohmann::json& j, const char* key) {
    if (!j.is_object() || !j.contains(key) || !j[key].is_string())
      throw ConfigError("journal " + writer.path().string() + ": a " +
                        std::string(to_string(kind)) +
                        " record must be a JSON object with a string \"" + key + "\"");
    if (id == 0) {
      std::uint16_t schema = 0;
      const bool events = kind == ChannelKind::kEvents;
      id = channel(kind, schema, events ? kEventSchemaName : kParametersSchemaName,
                   events ? event_schema_text() : parameters_schema_text(), "jsonschema", "json",
                   events ? "/events" : "/parameters", "", {});
    }
    const std::string text = j.dump();
    const mcap::MessageHeader h{id, sequence[id]++, log_time(t.ns), non_negative(t.ns)};
    writer.write_message(h, std::as_bytes(std::span(text.data(), text.size())), 0);
    writer.flush_if_due();
  }
};

std::string_view to_string(ChannelKind kind) {
  switch (kind) {
    case ChannelKind::kSensor:
      return "sensor";
    case ChannelKind::kStage:
      return "stage";
    case ChannelKind::kProbe:
      return "probe";
    case ChannelKind::kEvents:
      return "events";
    case ChannelKind::kParameters:
      return "parameters";
    case ChannelKind::kOther:
      return "other";
  }
  return "other";
}

JournalWriter::JournalWriter(std::filesystem::path path, JournalOptions options)
    : impl_(std::make_unique<Impl>(std::move(path), std::move(options))) {}

JournalWriter::~JournalWriter() = default;

SensorChannel JournalWriter::add_sensor(std::string_view device,
                                        std::map<std::string, std::string> metadata) {
  return {impl_->device_channel(ChannelKind::kSensor, device, std::move(metadata))};
}
StageChannel JournalWriter::add_stage(std::string_view device,
                                      std::map<std::string, std::string> metadata) {
  return {impl_->device_channel(ChannelKind::kStage, device, std::move(metadata))};
}
ProbeChannel JournalWriter::add_probe(std::string_view device,
                                      std::map<std::string, std::string> metadata) {
  return {impl_->device_channel(ChannelKind::kProbe, device, std::move(metadata))};
}

void JournalWriter::write_sensor(SensorChannel channel,
                                 std::span<const drivers::SensorSample> samples) {
  Impl& j = *impl_;
  j.check_channel(channel.id, ChannelKind::kSensor, "write_sensor");
  if (samples.empty()) return;
  const SensorColumns cols = sensor_columns(samples);
  const std::size_t per_sample = sensor_message_bytes(2, cols) - sensor_message_bytes(1, cols);
  const auto duration = static_cast<std::uint64_t>(j.opt.chunk_duration.count());
  mcap::Writer& w = j.writer;
  std::size_t i = 0;
  while (i < samples.size()) {
    const auto rest = samples.subspan(i);
    const std::uint64_t t_first = j.peek_log_time(rest[0].t_host.ns);
    if (w.chunk_expired(t_first)) w.flush();
    // As many samples as fit in the open chunk, by size and by time.
    const std::size_t room = w.room();
    std::size_t k = room > 64 ? std::min(rest.size(), (room - 64) / per_sample) : 0;
    while (k < rest.size() && sensor_message_bytes(k + 1, cols) <= room) ++k;
    while (k > 0 && sensor_message_bytes(k, cols) > room) --k;
    const std::uint64_t limit = w.open_chunk_start().value_or(t_first) + duration;
    std::size_t in_time = 1;
    while (in_time < k && j.peek_log_time(rest[in_time].t_host.ns) < limit) ++in_time;
    k = std::min(k, in_time);
    if (k == 0) {
      if (w.open_chunk_start()) {
        w.flush();
        continue;
      }
      k = 1;  // a chunk always takes one message, however small chunk_bytes is
    }
    const auto piece = rest.first(k);
    const mcap::MessageHeader h{channel.id, j.sequence[channel.id]++,
                                j.log_time(piece.back().t_host.ns),
                                non_negative(piece.front().t_host.ns)};
    auto out = w.add_message(h, sensor_message_bytes(k, cols), k);
    encode_sensor(piece, cols, out.data());
    i += k;
    j.written += k;
    w.flush_if_due();
  }
}

void JournalWriter::write_stage(StageChannel channel, const drivers::StageSample& sample) {
  impl_->check_channel(channel.id, ChannelKind::kStage, "write_stage");
  impl_->write_pose(channel.id, sample.seq, sample.t, sample.pose, false);
}

void JournalWriter::write_probe(ProbeChannel channel, const drivers::ProbeTrigger& trigger) {
  impl_->check_channel(channel.id, ChannelKind::kProbe, "write_probe");
  impl_->write_pose(channel.id, trigger.seq, trigger.t, trigger.pose, true);
}

void JournalWriter::write_event(drivers::Timestamp t, const nlohmann::json& event) {
  impl_->write_json(impl_->events_channel, ChannelKind::kEvents, t, event, "event");
}

void JournalWriter::write_parameters(drivers::Timestamp t, const nlohmann::json& parameters) {
  impl_->write_json(impl_->parameters_channel, ChannelKind::kParameters, t, parameters, "kind");
}

void JournalWriter::tick(drivers::Timestamp now) {
  impl_->writer.tick(impl_->peek_log_time(now.ns));
}
void JournalWriter::flush() { impl_->writer.flush(); }
void JournalWriter::sync() { impl_->writer.sync(); }
void JournalWriter::close() { impl_->writer.close(); }

std::uint64_t JournalWriter::acknowledged_samples() const noexcept {
  return impl_->writer.acknowledged_units();
}
std::uint64_t JournalWriter::durable_samples() const noexcept {
  return impl_->writer.durable_units();
}
std::uint64_t JournalWriter::written_samples() const noexcept { return impl_->written; }
mcap::WriterStats JournalWriter::stats() const noexcept { return impl_->writer.stats(); }
const std::filesystem::path& JournalWriter::path() const noexcept { return impl_->writer.path(); }
bool JournalWriter::failed() const noexcept { return impl_->writer.failed(); }

}  // namespace scanmesh::acq
