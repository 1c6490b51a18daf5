// A reconstruction job from point files to a mesh: the inputs read and merged (or registered
// through a scanalyze .conf), each point's direction towards its sensor, notes on the inputs,
// then the batch path (recon::reconstruct) or the streamed incremental path
// (recon::IncrementalReconstructor). Writing the mesh is the caller's (a file, a confined path).
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/recon/incremental.hpp"
#include "scanmesh/recon/reconstruct.hpp"

namespace scanmesh::reconstruction {

struct Request {
  /// Point files (.xyz .txt .csv .asc .ply .stl .obj), merged. With `conf`, each must be listed
  /// there (matched by file name); empty: every scan the .conf lists.
  std::vector<std::string> inputs;
  std::string conf;  ///< scanalyze registration file, or empty
  /// Where the sensor was, for every point (a single-view scan); not with `conf`, whose scans
  /// each look along -z of their own frame.
  std::optional<recon::Vec3> sensor;
  recon::ReconstructOptions options;  ///< validated by the caller
  /// 0: the batch path. N: the incremental path, each scan in turn, N points a batch in file
  /// order (a .ply range scan row by row).
  std::size_t stream = 0;
};

/// One scan as read: its points in file order, each one's direction towards its sensor (when
/// known) and, for a range scan, its rows (vertex indices a row).
struct Scan {
  std::vector<recon::Vec3> points, towards;
  std::vector<std::vector<std::uint32_t>> rows;
};

/// What the job reports as it goes (every member may be empty).
struct Observer {
  /// A warning about an input (a PLY header line skipped), as it is read.
  std::function<void(const std::string&)> warning;
  /// A note about the inputs or the result (also kept in the outcome's `notes`).
  std::function<void(const std::string&)> note;
  /// Batch path: a stage ("cube", "front", ...) or a step ("front/growth") starts; "done".
  std::function<void(std::string_view)> stage;
  /// Streamed path: after each batch, points fed so far of the total, and the core's stats.
  std::function<void(std::size_t fed, std::size_t total, const recon::IncrementalStats&)> batch;
};

/// Every scan of the request read (and registered); `notes` gets a note on each mesh input
/// whose vertices do not sample its surface as a scan does. Throws InputError / ConfigError
/// naming the file.
std::vector<Scan> load_scans(const Request& request, std::vector<std::string>& notes,
                             const Observer& observer = {});

struct BatchOutcome {
  recon::ReconstructResult result;
  std::vector<std::string> notes;
  std::map<std::string, double> seconds;       ///< "read" and each stage
  std::map<std::string, double> step_seconds;  ///< steps within a stage ("front/growth")
  std::size_t points = 0;                      ///< points read
};

struct StreamOutcome {
  recon::IncrementalResult result;  ///< with the on-request passes applied to its mesh
  recon::FillStats fill;
  recon::DenoiseStats denoise;
  recon::SharpenStats sharpen;
  std::vector<std::string> notes;
  std::size_t stream = 0, batches = 0, deltas = 0;
  double read_seconds = 0, max_batch_seconds = 0, finish_seconds = 0, take_delta_seconds = 0;
};

/// The batch path. Throws InputError when the inputs hold no point.
BatchOutcome run_batch(const Request& request, const Observer& observer = {});
/// The incremental path (request.stream > 0): a consumer takes the delta after every batch, as
/// the daemon does; fill, denoise and sharpen run on the finished mesh, as the batch path runs
/// them last.
StreamOutcome run_stream(const Request& request, const Observer& observer = {});

}  // namespace scanmesh::reconstruction
