// CDR encoders and decoders of the journal's sample messages, and the schemas that describe them
// in the file (see messages.hpp). CDR alignment is relative to the end of the 4-byte
// encapsulation header; an empty sequence has no padding before it.
// SPDX-License-Identifier: MIT
#include "messages.hpp"

#include <cstring>
#include <limits>

#include "bytes.hpp"

namespace scanmesh::acq::detail {

namespace {

constexpr std::int64_t kNoDeviceTime = std::numeric_limits<std::int64_t>::min();
constexpr std::size_t kEncapsulation = 4;
constexpr std::byte kCdrLe[kEncapsulation] = {std::byte{0}, std::byte{1}, std::byte{0},
                                              std::byte{0}};

constexpr std::size_t align(std::size_t pos, std::size_t a) { return (pos + a - 1) / a * a; }

/// Walks the columns of a SensorSamples message: where each count and each data block go.
struct SensorLayout {
  struct Column {
    std::size_t count_at = 0;  // relative to the CDR origin
    std::size_t data_at = 0;
    std::size_t count = 0;
  };
  Column seq, t_host, value, status, index, device_code, t_device;
  std::size_t end = 0;  // relative to the CDR origin

  SensorLayout(std::size_t n, SensorColumns c) {
    std::size_t pos = 0;
    auto column = [&](Column& col, std::size_t count, std::size_t elem) {
      pos = align(pos, 4);
      col.count_at = pos;
      pos += 4;
      col.count = count;
      if (count > 0) pos = align(pos, elem);
      col.data_at = pos;
      pos += count * elem;
    };
    column(seq, n, 8);
    column(t_host, n, 8);
    column(value, n, 8);
    column(status, n, 1);
    column(index, c.index ? n : 0, 4);
    column(device_code, c.device_code ? n : 0, 4);
    column(t_device, c.device_time ? n : 0, 8);
    end = pos;
  }
};

std::uint8_t status_code(drivers::SensorStatus s) {
  switch (s) {
    case drivers::SensorStatus::kOk:
      return 0;
    case drivers::SensorStatus::kNoTarget:
      return 1;
    case drivers::SensorStatus::kOverRange:
      return 2;
    case drivers::SensorStatus::kAlarm:
      return 3;
    case drivers::SensorStatus::kDeviceError:
      return 4;
  }
  return 1;
}

std::optional<drivers::SensorStatus> status_from_code(std::uint8_t c) {
  switch (c) {
    case 0:
      return drivers::SensorStatus::kOk;
    case 1:
      return drivers::SensorStatus::kNoTarget;
    case 2:
      return drivers::SensorStatus::kOverRange;
    case 3:
      return drivers::SensorStatus::kAlarm;
    case 4:
      return drivers::SensorStatus::kDeviceError;
    default:
      return std::nullopt;
  }
}

template <class T, class F>
void put_column(std::byte* cdr, const SensorLayout::Column& col,
                std::span<const drivers::SensorSample> samples, F&& get) {
  store(cdr + col.count_at, static_cast<std::uint32_t>(col.count));
  std::byte* p = cdr + col.data_at;
  for (std::size_t i = 0; i < col.count; ++i, p += sizeof(T)) store<T>(p, get(samples[i]));
}

/// The part StageSample and ProbeTrigger share: seq, t, the pose, t_device (CDR offsets 0-55).
void encode_pose(std::uint64_t seq, drivers::Timestamp t, const drivers::StagePose& pose,
                 const std::optional<drivers::Timestamp>& t_device, std::byte* out) {
  std::memcpy(out, kCdrLe, kEncapsulation);
  std::byte* p = out + kEncapsulation;
  store(p, seq);
  store(p + 8, t.ns);
  store(p + 16, pose.x_mm);
  store(p + 24, pose.y_mm);
  store(p + 32, pose.z_mm);
  store(p + 40, pose.a_rad);
  store(p + 48, t_device ? t_device->ns : kNoDeviceTime);
}

/// Journal 1 wrote seq, t and the pose only (52 bytes): `full` says whether t_device follows.
bool decode_pose(std::span<const std::byte> data, std::uint64_t& seq, drivers::Timestamp& t,
                 drivers::StagePose& pose, std::optional<drivers::Timestamp>& t_device, bool& full,
                 std::size_t full_size) {
  constexpr std::size_t kJournal1 = kEncapsulation + 8 * 6;
  if (data.size() < kJournal1 || data[0] != std::byte{0} || data[1] != std::byte{1}) return false;
  const std::byte* p = data.data() + kEncapsulation;
  seq = load<std::uint64_t>(p);
  t.ns = load<std::int64_t>(p + 8);
  pose.x_mm = load<double>(p + 16);
  pose.y_mm = load<double>(p + 24);
  pose.z_mm = load<double>(p + 32);
  pose.a_rad = load<double>(p + 40);
  full = data.size() >= full_size;
  if (full) {
    const auto td = load<std::int64_t>(p + 48);
    if (td != kNoDeviceTime) t_device = drivers::Timestamp{td};
  }
  return true;
}

std::uint8_t stage_status_code(drivers::StageStatus s) {
  switch (s) {
    case drivers::StageStatus::kIdle:
      return 0;
    case drivers::StageStatus::kMoving:
      return 1;
    case drivers::StageStatus::kHoming:
      return 2;
    case drivers::StageStatus::kAlarm:
      return 3;
    case drivers::StageStatus::kLost:
      return 4;
  }
  return 0;
}

std::optional<drivers::StageStatus> stage_status_from_code(std::uint8_t c) {
  switch (c) {
    case 0:
      return drivers::StageStatus::kIdle;
    case 1:
      return drivers::StageStatus::kMoving;
    case 2:
      return drivers::StageStatus::kHoming;
    case 3:
      return drivers::StageStatus::kAlarm;
    case 4:
      return drivers::StageStatus::kLost;
    default:
      return std::nullopt;
  }
}

}  // namespace

std::string_view sensor_schema_text() {
  return R"(# Consecutive samples of one displacement sensor as scanmesh's scan journal records them
# (drivers::SensorSample): one entry per sample in each column, except that an empty index,
# device_code or t_device_ns column means 0, 0 and "no device time" for every sample.
uint8 STATUS_OK=0
uint8 STATUS_NO_TARGET=1
uint8 STATUS_OVER_RANGE=2
uint8 STATUS_ALARM=3
uint8 STATUS_DEVICE_ERROR=4

uint64[] seq          # per sensor, +1 per measurement; the points of a line profile share one
int64[] t_host_ns     # host monotonic time the sample was received, ns
float64[] value_mm    # distance from the start of the measuring range, mm; NaN unless STATUS_OK
uint8[] status        # STATUS_*
uint32[] index        # point within the line profile (0 for a point sensor)
uint32[] device_code  # raw code the sensor sent with STATUS_ALARM or STATUS_DEVICE_ERROR
int64[] t_device_ns   # the sensor's own clock, ns; -9223372036854775808 (INT64_MIN): none
)";
}

std::string_view stage_schema_text() {
  return R"(# One position report of the motion stage (drivers::StageSample).
uint8 STATUS_IDLE=0
uint8 STATUS_MOVING=1
uint8 STATUS_HOMING=2
uint8 STATUS_ALARM=3
uint8 STATUS_LOST=4

uint64 seq          # per stage, +1 per report
int64 t_ns          # host monotonic time of the position, ns
float64 x_mm
float64 y_mm
float64 z_mm
float64 a_rad       # rotary table angle, counter-clockwise about +z seen from above
int64 t_device_ns   # the controller's own clock, ns; -9223372036854775808 (INT64_MIN): none
uint8 status        # what the stage was doing: STATUS_*
)";
}

std::string_view probe_schema_text() {
  return R"(# A touch-probe trigger: the stage position latched at the instant of contact
# (drivers::ProbeTrigger).
uint64 seq
int64 t_ns          # host monotonic time of the latch, ns
float64 x_mm        # the latched axes: the probe tip centre at contact (machine frame)
float64 y_mm
float64 z_mm
float64 a_rad       # rotary table angle, counter-clockwise about +z seen from above
int64 t_device_ns   # the controller's clock at the latch, ns; INT64_MIN: none
bool has_surface    # the controller gave its own compensated surface point (a CMM)
float64 surface_x_mm
float64 surface_y_mm
float64 surface_z_mm
float64 surface_i   # unit surface normal it compensated along
float64 surface_j
float64 surface_k
)";
}

std::string_view event_schema_text() {
  return R"({"$schema":"https://json-schema.org/draft/2020-12/schema","title":"scanmesh scan event",)"
         R"("description":"Something that happened to the scan (started, paused, resumed, stopped, )"
         R"(a device lost or back, an error), with whatever fields describe it.",)"
         R"("type":"object","properties":{"event":{"type":"string"}},"required":["event"]})";
}

std::string_view parameters_schema_text() {
  return R"({"$schema":"https://json-schema.org/draft/2020-12/schema","title":"scanmesh parameters",)"
         R"("description":"Parameters in force from this message on: a sensor's configuration, )"
         R"(the calibration, the reduction or meshing parameters; 'kind' says which.",)"
         R"("type":"object","properties":{"kind":{"type":"string"}},"required":["kind"]})";
}

SensorColumns sensor_columns(std::span<const drivers::SensorSample> samples) {
  SensorColumns c;
  for (const auto& s : samples) {
    c.index |= s.index != 0;
    c.device_code |= s.device_code != 0;
    c.device_time |= s.t_device.has_value();
  }
  return c;
}

std::size_t sensor_message_bytes(std::size_t n, SensorColumns c) {
  return kEncapsulation + SensorLayout(n, c).end;
}

void encode_sensor(std::span<const drivers::SensorSample> samples, SensorColumns c,
                   std::byte* out) {
  const SensorLayout l(samples.size(), c);
  std::memcpy(out, kCdrLe, kEncapsulation);
  std::byte* cdr = out + kEncapsulation;
  std::memset(cdr, 0, l.end);  // padding bytes are zero (the file is deterministic)
  using S = drivers::SensorSample;
  put_column<std::uint64_t>(cdr, l.seq, samples, [](const S& s) { return s.seq; });
  put_column<std::int64_t>(cdr, l.t_host, samples, [](const S& s) { return s.t_host.ns; });
  put_column<double>(cdr, l.value, samples, [](const S& s) { return s.value_mm; });
  put_column<std::uint8_t>(cdr, l.status, samples,
                           [](const S& s) { return status_code(s.status); });
  put_column<std::uint32_t>(cdr, l.index, samples, [](const S& s) { return s.index; });
  put_column<std::uint32_t>(cdr, l.device_code, samples, [](const S& s) { return s.device_code; });
  put_column<std::int64_t>(cdr, l.t_device, samples,
                           [](const S& s) { return s.t_device ? s.t_device->ns : kNoDeviceTime; });
}

std::optional<std::uint32_t> sensor_message_count(std::span<const std::byte> data) {
  if (data.size() < kEncapsulation + 4) return std::nullopt;
  return load<std::uint32_t>(data.data() + kEncapsulation);
}

bool decode_sensor(std::span<const std::byte> data, std::vector<drivers::SensorSample>& out) {
  out.clear();
  if (data.size() < kEncapsulation || data[0] != std::byte{0} || data[1] != std::byte{1})
    return false;
  const std::byte* cdr = data.data() + kEncapsulation;
  const std::size_t size = data.size() - kEncapsulation;
  std::size_t pos = 0;
  std::size_t n = 0;
  bool first = true;
  // Reads one column's count and returns where its data starts (nullopt: malformed). The first
  // column sets n; the others must hold n entries, or 0 where `optional`.
  auto column = [&](std::size_t elem, bool optional) -> std::optional<std::size_t> {
    pos = align(pos, 4);
    if (pos + 4 > size) return std::nullopt;
    const std::size_t count = load<std::uint32_t>(cdr + pos);
    pos += 4;
    if (first) {
      n = count;
      first = false;
    } else if (count != n && !(optional && count == 0)) {
      return std::nullopt;
    }
    if (count > 0) pos = align(pos, elem);
    if (count > (size - std::min(pos, size)) / elem) return std::nullopt;
    const std::size_t at = pos;
    pos += count * elem;
    return count == 0 ? std::optional<std::size_t>(std::numeric_limits<std::size_t>::max()) : at;
  };
  const auto seq = column(8, false);
  if (!seq) return false;
  const auto t_host = column(8, false);
  const auto value = column(8, false);
  const auto status = column(1, false);
  const auto index = column(4, true);
  const auto code = column(4, true);
  const auto t_device = column(8, true);
  if (!t_host || !value || !status || !index || !code || !t_device) return false;
  constexpr std::size_t kEmpty = std::numeric_limits<std::size_t>::max();
  out.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    drivers::SensorSample& s = out[i];
    s.seq = load<std::uint64_t>(cdr + *seq + 8 * i);
    s.t_host.ns = load<std::int64_t>(cdr + *t_host + 8 * i);
    s.value_mm = load<double>(cdr + *value + 8 * i);
    const auto st = status_from_code(load<std::uint8_t>(cdr + *status + i));
    if (!st) {
      out.clear();
      return false;
    }
    s.status = *st;
    s.index = *index == kEmpty ? 0 : load<std::uint32_t>(cdr + *index + 4 * i);
    s.device_code = *code == kEmpty ? 0 : load<std::uint32_t>(cdr + *code + 4 * i);
    if (*t_device != kEmpty) {
      const auto td = load<std::int64_t>(cdr + *t_device + 8 * i);
      if (td != kNoDeviceTime)
        s.t_device = drivers::Timestamp{td};
      else
        s.t_device.reset();
    } else {
      s.t_device.reset();
    }
  }
  return true;
}

void encode_stage(const drivers::StageSample& s, std::byte* out) {
  encode_pose(s.seq, s.t, s.pose, s.t_device, out);
  store(out + kEncapsulation + 56, stage_status_code(s.status));
}

void encode_probe(const drivers::ProbeTrigger& p, std::byte* out) {
  encode_pose(p.seq, p.t, p.pose, p.t_device, out);
  std::byte* c = out + kEncapsulation;
  std::memset(c + 56, 0, 8);  // has_surface and the padding before the next float64
  store(c + 56, static_cast<std::uint8_t>(p.surface ? 1 : 0));
  const drivers::SurfacePoint s = p.surface.value_or(drivers::SurfacePoint{});
  store(c + 64, s.x_mm);
  store(c + 72, s.y_mm);
  store(c + 80, s.z_mm);
  store(c + 88, s.i);
  store(c + 96, s.j);
  store(c + 104, s.k);
}

std::optional<drivers::StageSample> decode_stage(std::span<const std::byte> data) {
  drivers::StageSample s;
  bool full = false;
  if (!decode_pose(data, s.seq, s.t, s.pose, s.t_device, full, kStageMessageBytes))
    return std::nullopt;
  if (full) {
    const auto st = stage_status_from_code(load<std::uint8_t>(data.data() + kEncapsulation + 56));
    if (!st) return std::nullopt;
    s.status = *st;
  }
  return s;
}

std::optional<drivers::ProbeTrigger> decode_probe(std::span<const std::byte> data) {
  drivers::ProbeTrigger p;
  bool full = false;
  if (!decode_pose(data, p.seq, p.t, p.pose, p.t_device, full, kProbeMessageBytes))
    return std::nullopt;
  if (full) {
    const std::byte* c = data.data() + kEncapsulation;
    const auto has = load<std::uint8_t>(c + 56);
    if (has > 1) return std::nullopt;
    if (has == 1) {
      p.surface =
          drivers::SurfacePoint{load<double>(c + 64), load<double>(c + 72), load<double>(c + 80),
                                load<double>(c + 88), load<double>(c + 96), load<double>(c + 104)};
    }
  }
  return p;
}

}  // namespace scanmesh::acq::detail
