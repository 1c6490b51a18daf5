// The advancing front's orientation pass: one consistent orientation per component,
// towards the normals (and the context mesh's orientation where there is one).
// SPDX-License-Identifier: MIT
#include "front_builder.hpp"

namespace scanmesh::recon::front_impl {

void Builder::orient_components(detail::TriangleComponents& components) {
  const auto ncomp = static_cast<std::uint32_t>(components.count());
  // One component (the usual case): no look-ups in the passes below.
  auto comp = [&](const Triangle& t) { return ncomp == 1 ? 0u : components.of(t); };
  // Per component: whether it is open, and, for the closed ones, the signed volume. The front
  // matches the mesh here, so a component is open exactly when one of its vertices has a front
  // edge (an open fan).
  std::vector<std::uint8_t> open(ncomp, 0);
  std::uint32_t open_count = 0;
  for (const Triangle& t : tris_) {
    if (open_count == ncomp) break;  // all open (open scans: at once)
    const std::uint32_t c = comp(t);
    if (open[c]) continue;
    if (head_out_[t[0]] != kNone || head_out_[t[1]] != kNone || head_out_[t[2]] != kNone) {
      open[c] = 1;
      ++open_count;
    }
  }
#ifndef NDEBUG
  {
    // Checked against the edges: {u, v} is a boundary edge when exactly one of u's triangles
    // contains v.
    std::vector<std::uint8_t> open_edges(ncomp, 0);
    const detail::VertexTriangles adj(p_.size(), tris_);
    for (const Triangle& t : tris_)
      for (std::size_t k = 0; k < 3; ++k) {
        const std::uint32_t u = t[k], v = t[(k + 1) % 3];
        int uses = 0;
        for (std::uint32_t s = adj.start[u]; s < adj.start[u + 1]; ++s) {
          const Triangle& o = tris_[adj.list[s]];
          uses += (o[0] == v || o[1] == v || o[2] == v) ? 1 : 0;
        }
        if (uses == 1) open_edges[comp(t)] = 1;
      }
    assert(open_edges == open);
  }
#endif
  if (open_count == ncomp) return;  // the front's orientation stands
  std::vector<Vec3> centroid(ncomp, Vec3::Zero());
  std::vector<double> vol(ncomp, 0.0), count(ncomp, 0.0);
  for (const Triangle& t : tris_) {
    const std::uint32_t c = comp(t);
    centroid[c] += p_[t[0]];
    count[c] += 1;
  }
  for (const Triangle& t : tris_) {
    const std::uint32_t k = comp(t);
    const Vec3 c = centroid[k] / count[k];
    vol[k] += (p_[t[0]] - c).dot((p_[t[1]] - c).cross(p_[t[2]] - c));
  }
  std::vector<std::uint8_t> flip(ncomp, 0), fixed(ncomp, 0);
  if (ctx_ != nullptr)
    for (const Triangle& t : tris_)
      if (from_context(t)) fixed[comp(t)] = 1;
  for (std::uint32_t c = 0; c < ncomp; ++c)
    if (!open[c] && vol[c] < 0 && !fixed[c]) {
      flip[c] = 1;
      ++res_.flipped_components;
    }
  for (Triangle& t : tris_)
    if (flip[comp(t)]) std::swap(t[1], t[2]);
}

}  // namespace scanmesh::recon::front_impl
