// IncrementalMesher: the pipeline's meshing stage over recon::IncrementalReconstructor.
// SPDX-License-Identifier: MIT
#include "scanmesh/acquisition/meshers.hpp"

namespace scanmesh::acq {

IncrementalMesher::IncrementalMesher(recon::IncrementalOptions options)
    : core_(options) {}

void IncrementalMesher::add(std::span<const MeasuredPoint> points) {
  points_.clear();
  sensors_.clear();
  for (const auto& p : points) {
    points_.push_back(p.point_mm);
    sensors_.push_back(p.sensor_mm);
  }
  core_.add(points_, sensors_, recon::SensorData::kPosition);
  progress_.points_in += points.size();
  take_delta();
}

void IncrementalMesher::take_delta() {
  const recon::MeshDelta d = core_.take_delta();
  const recon::IncrementalStats st = core_.stats();
  progress_.kept_points = st.cubes_kept;
  progress_.vertices = st.vertices;
  progress_.triangles = st.triangles;
  progress_.pending_points = st.unmeshed_cubes + st.pending_points;
  progress_.deltas = st.deltas;
  progress_.reopened_blocks = st.reopened_blocks;
  (void)d;
}

recon::Mesh IncrementalMesher::snapshot() { return core_.snapshot().to_mesh(); }

recon::Mesh IncrementalMesher::finish() {
  result_ = core_.finish();
  take_delta();
  progress_.pending_points = 0;
  return result_.mesh;
}

}  // namespace scanmesh::acq
