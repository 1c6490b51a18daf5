// The journal's message encodings: CDR (little-endian, XCDR1 as ROS 2 writes it) for the sample
// channels with their ros2msg schemas, JSON with JSON Schemas for events and parameters.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::acq::detail {

inline constexpr std::string_view kSensorSchemaName = "scanmesh_msgs/msg/SensorSamples";
inline constexpr std::string_view kStageSchemaName = "scanmesh_msgs/msg/StageSample";
inline constexpr std::string_view kProbeSchemaName = "scanmesh_msgs/msg/ProbeTrigger";
inline constexpr std::string_view kEventSchemaName = "scanmesh.ScanEvent";
inline constexpr std::string_view kParametersSchemaName = "scanmesh.Parameters";

std::string_view sensor_schema_text();
std::string_view stage_schema_text();
std::string_view probe_schema_text();
std::string_view event_schema_text();
std::string_view parameters_schema_text();

/// The optional columns of a SensorSamples message (an absent column is empty in the message).
struct SensorColumns {
  bool index = false;        ///< some sample has index != 0
  bool device_code = false;  ///< some sample has device_code != 0
  bool device_time = false;  ///< some sample has t_device
};

SensorColumns sensor_columns(std::span<const drivers::SensorSample> samples);
/// Bytes of the CDR message holding n samples with these columns (encapsulation included).
std::size_t sensor_message_bytes(std::size_t n, SensorColumns c);
/// Writes the message into out (exactly sensor_message_bytes(samples.size(), c) bytes).
void encode_sensor(std::span<const drivers::SensorSample> samples, SensorColumns c, std::byte* out);
/// Decodes a message into `out` (cleared first); false when it is malformed.
bool decode_sensor(std::span<const std::byte> data, std::vector<drivers::SensorSample>& out);
/// The number of samples a message claims (its first column's length), without decoding.
std::optional<std::uint32_t> sensor_message_count(std::span<const std::byte> data);

/// StageSample: seq, t, the pose, t_device, status (journal 1 wrote the first six fields only).
inline constexpr std::size_t kStageMessageBytes = 4 + 8 * 7 + 1;
/// ProbeTrigger: seq, t, the pose, t_device, has_surface, the surface point and normal.
inline constexpr std::size_t kProbeMessageBytes = 4 + 8 * 7 + 8 + 8 * 6;
void encode_stage(const drivers::StageSample& s, std::byte* out);
void encode_probe(const drivers::ProbeTrigger& p, std::byte* out);
std::optional<drivers::StageSample> decode_stage(std::span<const std::byte> data);
std::optional<drivers::ProbeTrigger> decode_probe(std::span<const std::byte> data);

}  // namespace scanmesh::acq::detail
