// Reading, checking and recovering journals: the MCAP scan with a visitor that decodes the
// journal's channels, counts samples per channel and hands records to a JournalVisitor.
// SPDX-License-Identifier: MIT
#include <algorithm>

#include "file.hpp"
#include "messages.hpp"
#include "scan_internal.hpp"
#include "scanmesh/acquisition/journal.hpp"

namespace scanmesh::acq {

using namespace detail;

namespace {

ChannelKind kind_of(const mcap::Channel& c, const std::map<std::uint16_t, mcap::Schema>& schemas) {
  const auto s = schemas.find(c.schema_id);
  if (s == schemas.end()) return ChannelKind::kOther;
  const std::string& name = s->second.name;
  if (c.message_encoding == "cdr" && s->second.encoding == "ros2msg") {
    if (name == kSensorSchemaName) return ChannelKind::kSensor;
    if (name == kStageSchemaName) return ChannelKind::kStage;
    if (name == kProbeSchemaName) return ChannelKind::kProbe;
  }
  if (c.message_encoding == "json") {
    if (name == kEventSchemaName) return ChannelKind::kEvents;
    if (name == kParametersSchemaName) return ChannelKind::kParameters;
  }
  return ChannelKind::kOther;
}

/// Decodes the journal's messages as the scan delivers them.
class Decoder final : public mcap::ScanVisitor {
 public:
  Decoder(std::string file, JournalVisitor* out, JournalReport& report, bool strict)
      : file_(std::move(file)), out_(out), report_(report), strict_(strict) {}

  void on_schema(const mcap::Schema& s) override { schemas_.emplace(s.id, s); }

  void on_channel(const mcap::Channel& c) override {
    ChannelInfo info;
    info.id = c.id;
    info.kind = kind_of(c, schemas_);
    info.topic = c.topic;
    info.metadata = c.metadata;
    if (auto d = c.metadata.find("device"); d != c.metadata.end()) info.device = d->second;
    if (report_.channels.size() <= c.id) report_.channels.resize(std::size_t{c.id} + 1);
    report_.channels[c.id].channel = info;
    if (out_ != nullptr) out_->on_channel(info);
  }

  void on_message(const mcap::Message& m) override {
    ChannelTotals& t = report_.channels[m.header.channel_id];
    const ChannelInfo& info = t.channel;
    ++t.messages;
    switch (info.kind) {
      case ChannelKind::kSensor:
        if (!decode_sensor(m.data, samples_)) return undecodable(t, m);
        count(t, samples_.size());
        for (const auto& s : samples_) time(s.t_host.ns);
        if (out_ != nullptr) out_->on_sensor(info, samples_);
        break;
      case ChannelKind::kStage: {
        const auto s = decode_stage(m.data);
        if (!s) return undecodable(t, m);
        count(t, 1);
        time(s->t.ns);
        if (out_ != nullptr) out_->on_stage(info, *s);
        break;
      }
      case ChannelKind::kProbe: {
        const auto p = decode_probe(m.data);
        if (!p) return undecodable(t, m);
        count(t, 1);
        time(p->t.ns);
        if (out_ != nullptr) out_->on_probe(info, *p);
        break;
      }
      case ChannelKind::kEvents:
      case ChannelKind::kParameters: {
        const std::string_view text(reinterpret_cast<const char*>(m.data.data()), m.data.size());
        if (!nlohmann::json::accept(text)) return undecodable(t, m);
        const drivers::Timestamp ts{static_cast<std::int64_t>(m.header.publish_time)};
        if (out_ == nullptr) break;
        if (info.kind == ChannelKind::kEvents) {
          out_->on_event(info, ts, text);
        } else {
          out_->on_parameters(info, ts, text);
        }
        break;
      }
      case ChannelKind::kOther:
        if (out_ != nullptr) out_->on_other(info, m);
        break;
    }
  }

 private:
  void count(ChannelTotals& t, std::uint64_t n) {
    t.samples += n;
    report_.samples += n;
  }
  void time(std::int64_t ns) {
    if (!any_time_) {
      report_.first_sample_ns = report_.last_sample_ns = ns;
      any_time_ = true;
      return;
    }
    report_.first_sample_ns = std::min(report_.first_sample_ns, ns);
    report_.last_sample_ns = std::max(report_.last_sample_ns, ns);
  }
  void undecodable(ChannelTotals& t, const mcap::Message& m) {
    if (strict_)
      throw InputError("journal " + file_ + ": message " + std::to_string(m.header.sequence) +
                       " on " + t.channel.topic + " (log time " +
                       std::to_string(m.header.log_time) + ") does not decode as " +
                       std::string(to_string(t.channel.kind)) + " data");
    ++t.undecodable;
    ++report_.undecodable_messages;
  }

  std::string file_;
  JournalVisitor* out_;
  JournalReport& report_;
  bool strict_;
  std::map<std::uint16_t, mcap::Schema> schemas_;
  std::vector<drivers::SensorSample> samples_;
  bool any_time_ = false;
};

void drop_empty_slots(JournalReport& r) {
  std::erase_if(r.channels, [](const ChannelTotals& t) { return t.channel.id == 0; });
}

}  // namespace

JournalReport read_journal(const std::filesystem::path& file, JournalVisitor& visitor,
                           ReadOptions options) {
  const auto f = File::open_read(file);
  JournalReport report;
  Decoder decoder(file.string(), &visitor, report, !options.tolerate_damage);
  mcap::ScanOptions so;
  so.strict = !options.tolerate_damage;
  report.scan = mcap::detail::scan_file(f, &decoder, so, nullptr);
  drop_empty_slots(report);
  return report;
}

std::vector<JournalReport> read_journals(std::span<const std::filesystem::path> files,
                                         JournalVisitor& visitor, ReadOptions options) {
  std::vector<JournalReport> reports;
  for (const auto& f : files) reports.push_back(read_journal(f, visitor, options));
  return reports;
}

JournalReport check_journal(const std::filesystem::path& file) {
  const auto f = File::open_read(file);
  JournalReport report;
  report.being_written = f.locked_elsewhere();
  Decoder decoder(file.string(), nullptr, report, false);
  report.scan = mcap::detail::scan_file(f, &decoder, {}, nullptr);
  drop_empty_slots(report);
  return report;
}

JournalRecovery recover_journal(const std::filesystem::path& file) {
  JournalRecovery r;
  Decoder decoder(file.string(), nullptr, r.kept, false);
  r.mcap = mcap::recover(file, &decoder);
  r.kept.scan = r.mcap.before;
  drop_empty_slots(r.kept);
  return r;
}

namespace {

nlohmann::json channels_json(const JournalReport& r) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& t : r.channels) {
    a.push_back({{"id", t.channel.id},
                 {"topic", t.channel.topic},
                 {"kind", std::string(to_string(t.channel.kind))},
                 {"device", t.channel.device},
                 {"messages", t.messages},
                 {"samples", t.samples},
                 {"undecodable_messages", t.undecodable}});
  }
  return a;
}

nlohmann::json damage_json(const mcap::ScanReport& s) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& d : s.damage)
    a.push_back({{"offset", d.offset}, {"bytes", d.length}, {"what", d.what}});
  return a;
}

nlohmann::json time_span_json(std::uint64_t start, std::uint64_t end, bool any) {
  if (!any) return nullptr;
  return {
      {"start_ns", start}, {"end_ns", end}, {"seconds", static_cast<double>(end - start) * 1e-9}};
}

}  // namespace

nlohmann::json to_json(const JournalReport& r) {
  const mcap::ScanReport& s = r.scan;
  nlohmann::json j;
  j["file"] = s.file;
  j["bytes"] = s.file_bytes;
  j["complete"] = s.complete();
  j["being_written"] = r.being_written;
  j["profile"] = s.profile;
  j["library"] = s.library;
  j["header_ok"] = s.header_ok;
  j["chunks"] = s.chunks.size();
  j["crc_failures"] = s.crc_failures;
  j["damage"] = damage_json(s);
  nlohmann::json wrapped = nlohmann::json::array();
  for (const auto& d : s.wrapped_damage)
    wrapped.push_back({{"offset", d.offset}, {"bytes", d.length}});
  j["wrapped_damage"] = wrapped;
  j["torn_tail"] = s.torn_tail ? nlohmann::json{{"offset", s.torn_offset}, {"bytes", s.torn_bytes}}
                               : nlohmann::json(nullptr);
  j["data_end"] = s.data_end_offset.has_value();
  j["data_section_crc_ok"] = s.data_section_crc_ok;
  j["summary_ok"] = s.summary_ok;
  j["summary_problems"] = s.summary_problems;
  j["messages"] = s.messages;
  j["samples"] = r.samples;
  j["undecodable_messages"] = r.undecodable_messages;
  j["out_of_order_messages"] = s.out_of_order_messages;
  j["unknown_channel_messages"] = s.unknown_channel_messages;
  j["time_span"] = time_span_json(s.message_start_time, s.message_end_time, s.messages > 0);
  j["channels"] = channels_json(r);
  nlohmann::json meta = nlohmann::json::object();
  for (const auto& m : s.metadata) meta[m.name] = m.metadata;
  j["metadata"] = meta;
  return j;
}

nlohmann::json to_json(const JournalRecovery& rec) {
  const mcap::RecoveryReport& m = rec.mcap;
  const mcap::ScanReport& s = m.before;
  nlohmann::json j;
  j["file"] = s.file;
  j["already_complete"] = m.already_complete;
  j["bytes_before"] = s.file_bytes;
  j["bytes_after"] = m.file_bytes_after;
  j["kept"] = {
      {"chunks", m.kept_chunks},
      {"messages", m.kept_messages},
      {"samples", rec.kept.samples},
      {"time_span", time_span_json(s.message_start_time, s.message_end_time, s.messages > 0)}};
  j["cut"] = {{"offset", m.cut_offset}, {"bytes", m.cut_bytes}};
  j["torn_tail"] = s.torn_tail ? nlohmann::json{{"offset", s.torn_offset}, {"bytes", s.torn_bytes}}
                               : nlohmann::json(nullptr);
  j["crc_failures"] = s.crc_failures;
  j["skipped_damage"] = damage_json(s);
  j["reindexed_chunks"] = m.reindexed_chunks;
  j["wrapped_damage"] = m.wrapped_regions;
  j["summary_rewritten"] = !m.already_complete;
  j["channels"] = channels_json(rec.kept);
  return j;
}

}  // namespace scanmesh::acq
