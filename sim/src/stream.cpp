// Stream file v1: a line-oriented text format with a key=value header and an end record that
// carries the record counts and an FNV-1a checksum (see sim/README.md). Also the acquisition-side
// mapping of samples + stage positions to points.
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/stream.hpp"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <ostream>
#include <sstream>
#include <string>
#include <system_error>

#include "scanmesh/common/error.hpp"

namespace scanmesh::sim {

namespace {

constexpr std::string_view kMagic = "# scanmesh-stream v";
constexpr int kVersion = 1;
constexpr std::uint64_t kFnvOffset = 0xcbf29ce484222325ULL;
constexpr std::uint64_t kFnvPrime = 0x100000001b3ULL;

std::uint64_t fnv1a(std::uint64_t h, std::string_view bytes) {
  for (const char ch : bytes) {
    h ^= static_cast<unsigned char>(ch);
    h *= kFnvPrime;
  }
  return h;
}

void put_double(std::string& out, double v) {
  if (std::isnan(v)) {
    out += "nan";
    return;
  }
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);  // shortest exact round trip
  out.append(buf, r.ptr);
}

template <class Int>
void put_int(std::string& out, Int v) {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

void put_vec(std::string& out, const Vec3& v) {
  put_double(out, v.x());
  out += ',';
  put_double(out, v.y());
  out += ',';
  put_double(out, v.z());
}

std::string header_text(const StreamHeader& h) {
  const SensorConfig& s = h.sensor;
  std::string out;
  out += kMagic;
  out += std::to_string(kVersion);
  out += '\n';
  auto kv = [&](std::string_view key, auto&& put) {
    out += "# ";
    out += key;
    out += '=';
    put();
    out += '\n';
  };
  kv("sensor.kind", [&] { out += to_string(s.kind); });
  kv("sensor.standoff_mm", [&] { put_double(out, s.standoff_mm); });
  kv("sensor.range_mm", [&] { put_double(out, s.range_mm); });
  kv("sensor.beam_dir", [&] { put_vec(out, s.beam_dir); });
  kv("sensor.baseline_dir", [&] { put_vec(out, s.baseline_dir); });
  kv("sensor.receiver_angle_rad", [&] { put_double(out, s.receiver_angle_rad); });
  kv("sensor.max_incidence_rad", [&] { put_double(out, s.max_incidence_rad); });
  kv("sensor.rate_hz", [&] { put_double(out, s.rate_hz); });
  kv("sensor.fan_dir", [&] { put_vec(out, s.fan_dir); });
  kv("sensor.profile_points", [&] { put_int(out, s.profile_points); });
  kv("sensor.fan_angle_rad", [&] { put_double(out, s.fan_angle_rad); });
  kv("sensor.tip_radius_mm", [&] { put_double(out, s.tip_radius_mm); });
  kv("sensor.probe_speed_mm_s", [&] { put_double(out, s.probe_speed_mm_s); });
  kv("calibration.mount", [&] {
    const Eigen::Matrix3d& r = h.calibration.mount.linear();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        put_double(out, r(i, j));
        out += ',';
      }
    put_vec(out, h.calibration.mount.translation());
  });
  kv("calibration.table_center_mm", [&] { put_vec(out, h.calibration.table_center_mm); });
  kv("stage.rate_hz", [&] { put_double(out, h.stage_rate_hz); });
  for (const auto& [k, v] : h.info) {
    std::string key = k, value = v;
    std::replace_if(
        key.begin(), key.end(), [](char ch) { return ch == ' ' || ch == '=' || ch == '\n'; }, '_');
    std::replace(value.begin(), value.end(), '\n', ' ');
    kv("info." + key, [&] { out += value; });
  }
  return out;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Writer

StreamHeader stream_header(const Simulator& simulator,
                           std::vector<std::pair<std::string, std::string>> info) {
  StreamHeader h;
  h.sensor = simulator.optics().config();
  h.calibration = simulator.calibration();
  h.stage_rate_hz = simulator.stage_rate_hz();
  h.info = std::move(info);
  return h;
}

StreamWriter::StreamWriter(std::ostream& out, const StreamHeader& header)
    : out_(&out), hash_(kFnvOffset), profiles_(header.sensor.kind == SensorKind::kLine) {
  emit(header_text(header));
}

void StreamWriter::emit(std::string_view text) {
  hash_ = fnv1a(hash_, text);
  out_->write(text.data(), static_cast<std::streamsize>(text.size()));
}

void StreamWriter::on_sensor(std::span<const SensorSample> samples) {
  if (samples.empty()) return;
  const SensorSample& first = samples.front();
  line_.clear();
  line_ += profiles_ ? "L " : "S ";
  put_int(line_, first.seq);
  line_ += ' ';
  put_int(line_, first.t_host.ns);
  line_ += ' ';
  if (first.t_device) {
    put_int(line_, first.t_device->ns);
  } else {
    line_ += '-';
  }
  if (profiles_) {
    line_ += ' ';
    put_int(line_, samples.size());
    for (const SensorSample& s : samples) {
      line_ += ' ';
      switch (s.status) {
        case SensorStatus::kOk:
          put_double(line_, s.value_mm);
          break;
        case SensorStatus::kNoTarget:
          line_ += 'N';
          break;
        case SensorStatus::kOverRange:
          line_ += 'R';
          break;
        case SensorStatus::kAlarm:  // the simulated profiler reports no alarms or error codes
        case SensorStatus::kDeviceError:
          line_ += 'N';
          break;
      }
    }
  } else {
    for (const SensorSample& s : samples) {  // one per record in practice
      line_ += ' ';
      put_double(line_, s.status == SensorStatus::kOk ? s.value_mm
                                                      : std::numeric_limits<double>::quiet_NaN());
      line_ += ' ';
      line_ += to_string(s.status);
    }
  }
  line_ += '\n';
  emit(line_);
  ++sensor_records_;
}

namespace {
template <class T>
void put_pose_record(std::string& line, char tag, const T& s) {
  line.clear();
  line += tag;
  line += ' ';
  put_int(line, s.seq);
  line += ' ';
  put_int(line, s.t.ns);
  for (const double v : {s.pose.x_mm, s.pose.y_mm, s.pose.z_mm, s.pose.a_rad}) {
    line += ' ';
    put_double(line, v);
  }
  line += '\n';
}
}  // namespace

void StreamWriter::on_stage(const StageSample& sample) {
  put_pose_record(line_, 'P', sample);
  emit(line_);
  ++stage_records_;
}

void StreamWriter::on_probe(const ProbeTrigger& trigger) {
  put_pose_record(line_, 'G', trigger);
  emit(line_);
  ++probe_records_;
}

void StreamWriter::finish() {
  line_.clear();
  line_ += "E ";
  put_int(line_, sensor_records_);
  line_ += ' ';
  put_int(line_, stage_records_);
  line_ += ' ';
  put_int(line_, probe_records_);
  line_ += ' ';
  char buf[17];
  const auto r = std::to_chars(buf, buf + 16, hash_, 16);
  line_.append(16 - static_cast<std::size_t>(r.ptr - buf), '0');
  line_.append(buf, r.ptr);
  line_ += '\n';
  out_->write(line_.data(), static_cast<std::streamsize>(line_.size()));
  out_->flush();
}

// ---------------------------------------------------------------------------------------------
// Reader

namespace {

class Parser {
 public:
  Parser(std::string_view name, std::size_t line) : name_(name), line_(line) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(std::string(name_) + ":" + std::to_string(line_) + ": " + what);
  }

  template <class Int>
  Int integer(std::string_view tok, const char* what) const {
    Int v{};
    const auto r = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    if (r.ec != std::errc() || r.ptr != tok.data() + tok.size())
      fail(std::string("bad ") + what + " '" + std::string(tok) + "'");
    return v;
  }

  double number(std::string_view tok, const char* what) const {
    double v = 0;
    const auto r = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    if (r.ec != std::errc() || r.ptr != tok.data() + tok.size())
      fail(std::string("bad ") + what + " '" + std::string(tok) + "'");
    return v;
  }

  double finite(std::string_view tok, const char* what) const {
    const double v = number(tok, what);
    if (!std::isfinite(v))
      fail(std::string(what) + " must be finite, got '" + std::string(tok) + "'");
    return v;
  }

  std::vector<double> numbers(std::string_view value, std::size_t count, const char* what) const {
    std::vector<double> out;
    std::size_t pos = 0;
    while (pos <= value.size()) {
      const std::size_t comma = value.find(',', pos);
      const std::string_view tok =
          value.substr(pos, comma == std::string_view::npos ? std::string_view::npos : comma - pos);
      out.push_back(finite(tok, what));
      if (comma == std::string_view::npos) break;
      pos = comma + 1;
    }
    if (out.size() != count)
      fail(std::string(what) + " needs " + std::to_string(count) + " comma-separated numbers");
    return out;
  }

 private:
  std::string_view name_;
  std::size_t line_;
};

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    if (i >= line.size()) break;
    std::size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t' && line[j] != '\r') ++j;
    out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

void header_entry(StreamHeader& h, std::string_view key, std::string_view value, const Parser& p) {
  SensorConfig& s = h.sensor;
  auto vec = [&](const char* what) {
    const auto v = p.numbers(value, 3, what);
    return Vec3(v[0], v[1], v[2]);
  };
  if (key == "sensor.kind") {
    try {
      s.kind = sensor_kind_from_string(value);
    } catch (const ConfigError& e) {
      p.fail(e.what());
    }
  } else if (key == "sensor.standoff_mm") {
    s.standoff_mm = p.finite(value, "sensor.standoff_mm");
  } else if (key == "sensor.range_mm") {
    s.range_mm = p.finite(value, "sensor.range_mm");
  } else if (key == "sensor.beam_dir") {
    s.beam_dir = vec("sensor.beam_dir");
  } else if (key == "sensor.baseline_dir") {
    s.baseline_dir = vec("sensor.baseline_dir");
  } else if (key == "sensor.receiver_angle_rad") {
    s.receiver_angle_rad = p.finite(value, "sensor.receiver_angle_rad");
  } else if (key == "sensor.max_incidence_rad") {
    s.max_incidence_rad = p.finite(value, "sensor.max_incidence_rad");
  } else if (key == "sensor.rate_hz") {
    s.rate_hz = p.finite(value, "sensor.rate_hz");
  } else if (key == "sensor.fan_dir") {
    s.fan_dir = vec("sensor.fan_dir");
  } else if (key == "sensor.profile_points") {
    s.profile_points = p.integer<std::uint32_t>(value, "sensor.profile_points");
  } else if (key == "sensor.fan_angle_rad") {
    s.fan_angle_rad = p.finite(value, "sensor.fan_angle_rad");
  } else if (key == "sensor.tip_radius_mm") {
    s.tip_radius_mm = p.finite(value, "sensor.tip_radius_mm");
  } else if (key == "sensor.probe_speed_mm_s") {
    s.probe_speed_mm_s = p.finite(value, "sensor.probe_speed_mm_s");
  } else if (key == "calibration.mount") {
    const auto v = p.numbers(value, 12, "calibration.mount");
    Eigen::Matrix3d r;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) r(i, j) = v[static_cast<std::size_t>(3 * i + j)];
    if (!(r.transpose() * r - Eigen::Matrix3d::Identity()).isZero(1e-9) || r.determinant() < 0)
      p.fail("calibration.mount rotation is not a rotation matrix");
    h.calibration.mount.linear() = r;
    h.calibration.mount.translation() = Vec3(v[9], v[10], v[11]);
  } else if (key == "calibration.table_center_mm") {
    h.calibration.table_center_mm = vec("calibration.table_center_mm");
  } else if (key == "stage.rate_hz") {
    h.stage_rate_hz = p.finite(value, "stage.rate_hz");
  } else if (key.starts_with("info.")) {
    h.info.emplace_back(std::string(key.substr(5)), std::string(value));
  }
  // Other keys: written by a newer minor revision; ignored.
}

Timestamp parse_time(const Parser& p, std::string_view tok, const char* what) {
  return Timestamp{p.integer<std::int64_t>(tok, what)};
}

}  // namespace

RecordedStream parse_stream(std::string_view text, std::string_view name,
                            const StreamReadOptions& options) {
  RecordedStream out;
  std::uint64_t hash = kFnvOffset;
  std::size_t line_no = 0;
  std::size_t pos = 0;
  bool in_header = true;
  bool ended = false;
  std::uint64_t sensor_records = 0;
  std::vector<std::string_view> tok;
  while (pos < text.size()) {
    std::size_t nl = text.find('\n', pos);
    const bool has_nl = nl != std::string_view::npos;
    if (!has_nl) nl = text.size();
    const std::string_view line = text.substr(pos, nl - pos);
    const std::string_view with_nl = text.substr(pos, nl - pos + (has_nl ? 1 : 0));
    pos = nl + (has_nl ? 1 : 0);
    ++line_no;
    const Parser p(name, line_no);
    if (ended) {
      if (!split(line).empty()) p.fail("data after the end record");
      continue;
    }
    if (line_no == 1) {
      if (!line.starts_with(kMagic))
        p.fail("not a scanmesh stream (first line must be '# scanmesh-stream v1')");
      const int version = p.integer<int>(line.substr(kMagic.size()), "format version");
      if (version != kVersion)
        p.fail("stream format version " + std::to_string(version) +
               " is not supported (this reader: " + std::to_string(kVersion) + ")");
      hash = fnv1a(hash, with_nl);
      continue;
    }
    if (line.starts_with("#")) {
      hash = fnv1a(hash, with_nl);
      if (!in_header) continue;  // comment
      std::string_view body = line.substr(1);
      while (!body.empty() && body.front() == ' ') body.remove_prefix(1);
      while (!body.empty() && (body.back() == '\r' || body.back() == ' ')) body.remove_suffix(1);
      const std::size_t eq = body.find('=');
      if (eq == std::string_view::npos || body.substr(0, eq).find(' ') != std::string_view::npos)
        continue;  // free comment
      header_entry(out.header, body.substr(0, eq), body.substr(eq + 1), p);
      continue;
    }
    tok = split(line);
    if (tok.empty()) {
      hash = fnv1a(hash, with_nl);
      continue;
    }
    if (in_header) {
      in_header = false;
      const auto problems = out.header.sensor.problems();
      if (!problems.empty()) p.fail("bad sensor in header: " + problems.front());
    }
    const std::string_view tag = tok[0];
    if (tag == "E") {
      if (tok.size() != 5) p.fail("end record needs 4 fields");
      const auto ns = p.integer<std::uint64_t>(tok[1], "sensor record count");
      const auto np = p.integer<std::uint64_t>(tok[2], "stage record count");
      const auto ng = p.integer<std::uint64_t>(tok[3], "probe record count");
      std::uint64_t want = 0;
      const auto r = std::from_chars(tok[4].data(), tok[4].data() + tok[4].size(), want, 16);
      if (r.ec != std::errc() || r.ptr != tok[4].data() + tok[4].size())
        p.fail("bad checksum field '" + std::string(tok[4]) + "'");
      if (ns != sensor_records || np != out.stage.size() || ng != out.probe.size())
        p.fail("record counts do not match the end record (" + std::to_string(sensor_records) +
               "/" + std::to_string(out.stage.size()) + "/" + std::to_string(out.probe.size()) +
               " read, " + std::string(tok[1]) + "/" + std::string(tok[2]) + "/" +
               std::string(tok[3]) + " written)");
      if (want != hash) p.fail("checksum mismatch: the stream is corrupt");
      ended = true;
      continue;
    }
    hash = fnv1a(hash, with_nl);
    if (tag == "S" || tag == "L") {
      const bool profile = tag == "L";
      if (tok.size() < 4) p.fail("sensor record too short");
      SensorSample s;
      s.seq = p.integer<std::uint64_t>(tok[1], "seq");
      s.t_host = parse_time(p, tok[2], "host time");
      if (tok[3] != "-") s.t_device = parse_time(p, tok[3], "device time");
      if (!profile) {
        if (tok.size() != 6) p.fail("S record needs 6 fields");
        const std::string_view st = tok[5];
        if (st == "ok") {
          s.status = SensorStatus::kOk;
          s.value_mm = p.finite(tok[4], "value");
        } else if (const auto status = drivers::sensor_status_from_string(st)) {
          s.status = *status;
          s.value_mm = std::numeric_limits<double>::quiet_NaN();
        } else {
          p.fail("unknown status '" + std::string(st) + "'");
        }
        out.sensor.push_back(s);
      } else {
        if (tok.size() < 5) p.fail("L record too short");
        const auto n = p.integer<std::uint32_t>(tok[4], "profile size");
        if (tok.size() != 5 + static_cast<std::size_t>(n))
          p.fail("L record announces " + std::to_string(n) + " values but has " +
                 std::to_string(tok.size() - 5));
        for (std::uint32_t i = 0; i < n; ++i) {
          const std::string_view v = tok[5 + i];
          s.index = i;
          if (v == "N" || v == "R") {
            s.status = v == "N" ? SensorStatus::kNoTarget : SensorStatus::kOverRange;
            s.value_mm = std::numeric_limits<double>::quiet_NaN();
          } else {
            s.status = SensorStatus::kOk;
            s.value_mm = p.finite(v, "profile value");
          }
          out.sensor.push_back(s);
        }
      }
      ++sensor_records;
    } else if (tag == "P" || tag == "G") {
      if (tok.size() != 7) p.fail(std::string(tag) + " record needs 7 fields");
      const auto seq = p.integer<std::uint64_t>(tok[1], "seq");
      const Timestamp t = parse_time(p, tok[2], "time");
      const double x = p.finite(tok[3], "x"), y = p.finite(tok[4], "y"), z = p.finite(tok[5], "z"),
                   a = p.finite(tok[6], "a");
      if (tag == "P") {
        StageSample s;
        s.seq = seq;
        s.t = t;
        s.pose = {x, y, z, a};
        out.stage.push_back(s);
      } else {
        ProbeTrigger g;
        g.seq = seq;
        g.t = t;
        g.pose = {x, y, z, a};
        out.probe.push_back(g);
      }
    } else {
      p.fail("unknown record type '" + std::string(tag) + "'");
    }
  }
  if (line_no == 0) throw InputError(std::string(name) + ": empty stream");
  if (!ended && !options.allow_truncated)
    throw InputError(std::string(name) + ": truncated stream (no end record after line " +
                     std::to_string(line_no) + ")");
  out.complete = ended;
  return out;
}

RecordedStream read_stream(const std::filesystem::path& file, const StreamReadOptions& options) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file.string() + ": cannot open: " + std::strerror(errno));
  std::ostringstream buf;
  buf << in.rdbuf();
  if (in.bad()) throw InputError(file.string() + ": read error");
  const std::string text = std::move(buf).str();
  return parse_stream(text, file.string(), options);
}

void write_stream(const std::filesystem::path& file, const RecordedStream& stream) {
  std::filesystem::path tmp = file;
  tmp += ".tmp" + std::to_string(::getpid());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw OutputError(file.string() + ": cannot create: " + std::strerror(errno));
    StreamWriter w(out, stream.header);
    // Merge the three record kinds by time (stage, probe, sensor at equal times).
    std::size_t i = 0, j = 0, k = 0;
    const auto& s = stream.sensor;
    while (i < s.size() || j < stream.stage.size() || k < stream.probe.size()) {
      const std::int64_t ts =
          i < s.size() ? s[i].t_host.ns : std::numeric_limits<std::int64_t>::max();
      const std::int64_t tp =
          j < stream.stage.size() ? stream.stage[j].t.ns : std::numeric_limits<std::int64_t>::max();
      const std::int64_t tg =
          k < stream.probe.size() ? stream.probe[k].t.ns : std::numeric_limits<std::int64_t>::max();
      if (j < stream.stage.size() && tp <= tg && tp <= ts) {
        w.on_stage(stream.stage[j++]);
      } else if (k < stream.probe.size() && tg <= ts) {
        w.on_probe(stream.probe[k++]);
      } else {
        std::size_t e = i + 1;
        while (e < s.size() && s[e].seq == s[i].seq) ++e;
        w.on_sensor(std::span<const SensorSample>(s.data() + i, e - i));
        i = e;
      }
    }
    w.finish();
    out.close();
    if (!out) {
      std::error_code ec;
      std::filesystem::remove(tmp, ec);
      throw OutputError(file.string() + ": write failed: " + std::strerror(errno));
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, file, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    throw OutputError(file.string() + ": cannot rename into place: " + ec.message());
  }
}

// ---------------------------------------------------------------------------------------------
// Samples -> points

std::vector<MeasuredPoint> points_from_samples(
    const SensorOptics& optics, const Calibration& calibration, std::span<const StageSample> stage,
    std::span<const SensorSample> sensor, std::span<const ProbeTrigger> probe, PointStats* stats) {
  acq::AccumulatorStats st;
  auto out = acq::points_from_samples(optics, calibration, stage, sensor, probe, &st);
  if (stats) *stats = PointStats{st.points, st.invalid_total(), st.no_pose()};
  return out;
}

std::vector<MeasuredPoint> points_from_stream(const RecordedStream& stream, PointStats* stats) {
  const SensorOptics optics(stream.header.sensor);
  return points_from_samples(optics, stream.header.calibration, stream.stage, stream.sensor,
                             stream.probe, stats);
}

}  // namespace scanmesh::sim
