// BatchMesher: the batch reconstruction over every point received so far.
// SPDX-License-Identifier: MIT
#include "scanmesh/acquisition/meshers.hpp"

#include <set>

namespace scanmesh::acq {

BatchMesher::BatchMesher(recon::ReconstructOptions options) : options_(std::move(options)) {}

void BatchMesher::add(std::span<const MeasuredPoint> points) {
  for (const auto& p : points) {
    points_.push_back(p.point_mm);
    towards_.push_back(p.sensor_mm - p.point_mm);
  }
  progress_.points_in += points.size();
  progress_.pending_points += points.size();
}

recon::Mesh BatchMesher::run() {
  // Fewer than a handful of distinct points cannot make a surface yet.
  if (points_.size() < 3) return {};
  last_ = recon::reconstruct(points_, options_, {}, towards_);
  progress_.kept_points = last_.reduced_points;
  progress_.vertices = last_.mesh.vertices.size();
  progress_.triangles = last_.mesh.triangles.size();
  progress_.pending_points = 0;
  ++progress_.deltas;
  return last_.mesh;
}

recon::Mesh BatchMesher::snapshot() {
  try {
    return run();
  } catch (const std::exception&) {
    return {};  // too few or degenerate points so far: no surface yet
  }
}

recon::Mesh BatchMesher::finish() { return run(); }

}  // namespace scanmesh::acq
