// The scanmesh sample stream file (format v1, documented in sim/README.md): writing it as a
// sink, reading it back, and turning sensor samples plus stage positions into 3D points the way
// acquisition does (pose interpolation + calibration).
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "scanmesh/acquisition/accumulator.hpp"
#include "scanmesh/sim/samples.hpp"
#include "scanmesh/sim/sensor.hpp"
#include "scanmesh/sim/simulator.hpp"

namespace scanmesh::sim {

/// What a stream file says about the sensor and machine it was recorded with.
struct StreamHeader {
  SensorConfig sensor;
  Calibration calibration;
  double stage_rate_hz = 0;
  /// Free `info.KEY=VALUE` lines (source, seed, recorder...), in order. Keys: no spaces or '='.
  std::vector<std::pair<std::string, std::string>> info;
};

/// The header describing a simulator's sensor, calibration and stage rate.
StreamHeader stream_header(const Simulator& simulator,
                           std::vector<std::pair<std::string, std::string>> info = {});

/// Writes the stream to `out` as the samples arrive. finish() appends the end record with the
/// record counts and checksum; a stream without it is reported as truncated by the reader.
class StreamWriter : public SampleSink {
 public:
  StreamWriter(std::ostream& out, const StreamHeader& header);
  void on_sensor(std::span<const SensorSample> samples) override;
  void on_stage(const StageSample& sample) override;
  void on_probe(const ProbeTrigger& trigger) override;
  void finish();

 private:
  void emit(std::string_view line);
  std::ostream* out_;
  std::uint64_t hash_;
  std::uint64_t sensor_records_ = 0;
  std::uint64_t stage_records_ = 0;
  std::uint64_t probe_records_ = 0;
  std::string line_;
  bool profiles_;
};

/// A stream read back: header and the records, each kind in file order.
struct RecordedStream {
  StreamHeader header;
  std::vector<SensorSample> sensor;  ///< a profile is a run of samples with one seq
  std::vector<StageSample> stage;
  std::vector<ProbeTrigger> probe;
  bool complete = false;  ///< the end record was present and matched
};

struct StreamReadOptions {
  /// Accept a stream cut short (no end record), e.g. after a crash: the records read so far are
  /// returned with complete = false. A wrong checksum or count is always an error.
  bool allow_truncated = false;
};

/// Parses a stream. Throws InputError naming `name`, the line and the problem.
RecordedStream parse_stream(std::string_view text, std::string_view name,
                            const StreamReadOptions& options = {});
RecordedStream read_stream(const std::filesystem::path& file,
                           const StreamReadOptions& options = {});
/// Writes a whole recorded stream (header, records in time order, end record) to a file,
/// atomically (temporary file + rename). Throws OutputError.
void write_stream(const std::filesystem::path& file, const RecordedStream& stream);

using acq::MeasuredPoint;

struct PointStats {
  std::uint64_t points = 0;
  std::uint64_t invalid = 0;  ///< samples with no value (no target, over range)
  std::uint64_t no_pose = 0;  ///< valid samples outside the stage's time span
};

/// acq::points_from_samples with the simulation's summary counts: for every kOk sensor sample
/// and every probe trigger, the stage pose interpolated at its host time, mapped through the
/// calibration. Points come in sample order, triggers after.
std::vector<MeasuredPoint> points_from_samples(const SensorOptics& optics,
                                               const Calibration& calibration,
                                               std::span<const StageSample> stage,
                                               std::span<const SensorSample> sensor,
                                               std::span<const ProbeTrigger> probe = {},
                                               PointStats* stats = nullptr);

/// points_from_samples over a recorded stream with its own header's sensor and calibration.
std::vector<MeasuredPoint> points_from_stream(const RecordedStream& stream,
                                              PointStats* stats = nullptr);

}  // namespace scanmesh::sim
