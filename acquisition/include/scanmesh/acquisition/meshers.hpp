// The pipeline's meshing stages over the geometry core.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <memory>
#include <nlohmann/json.hpp>
#include <vector>

#include "scanmesh/acquisition/pipeline.hpp"
#include "scanmesh/recon/incremental.hpp"
#include "scanmesh/recon/reconstruct.hpp"

namespace scanmesh::acq {

/// Keeps every point and runs the batch reconstruction over all of them on snapshot() and
/// finish(): O(n) per snapshot, so previews cost a whole reconstruction each. The final mesh is
/// the batch path's, with each point's direction towards its sensor. Memory: the raw points.
class BatchMesher final : public Mesher {
 public:
  explicit BatchMesher(recon::ReconstructOptions options = {});
  void add(std::span<const MeasuredPoint> points) override;
  MeshProgress progress() const override { return progress_; }
  recon::Mesh snapshot() override;
  recon::Mesh finish() override;
  /// The last reconstruction's details (cube, outliers...).
  const recon::ReconstructResult& last() const { return last_; }

 private:
  recon::Mesh run();
  recon::ReconstructOptions options_;
  std::vector<recon::Vec3> points_;
  std::vector<recon::Vec3> towards_;
  recon::ReconstructResult last_;
  MeshProgress progress_;
};

/// Meshes while the scan runs (recon::IncrementalReconstructor): regions the scan has left are
/// meshed and published; snapshot() copies the published mesh (O(mesh), no re-meshing). Each
/// point's sensor position orients the surface. Settling follows the point sequence, not the
/// batch cuts, so a replay in the recorded order gives the live mesh exactly.
class IncrementalMesher final : public Mesher {
 public:
  explicit IncrementalMesher(recon::IncrementalOptions options = {});
  void add(std::span<const MeasuredPoint> points) override;
  MeshProgress progress() const override { return progress_; }
  recon::Mesh snapshot() override;
  recon::Mesh finish() override;
  /// The final result's details (outliers, stats), after finish().
  const recon::IncrementalResult& result() const { return result_; }

 private:
  void take_delta();
  recon::IncrementalReconstructor core_;
  std::vector<recon::Vec3> points_, sensors_;  // one batch, reused
  recon::IncrementalResult result_;
  MeshProgress progress_;
};

/// The meshing stage a scan's "meshing" parameters ask for (recorded in its journal):
/// {"mesher": "incremental" (default) or "batch", "cube": "auto" (default) or a size in mm as a
/// number or a string}. Throws ConfigError for anything else.
std::unique_ptr<Mesher> make_mesher(const nlohmann::json& meshing);

}  // namespace scanmesh::acq
