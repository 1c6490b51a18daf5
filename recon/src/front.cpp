// Advancing front (boundary extension) over an oriented point set.
//
// The front is a set of directed loops of edges; the mesh lies on the left of every front edge
// (seen from the side its normals point to). A new triangle on front edge a->b with apex p is
// (b, a, p): it inherits the orientation of the triangle behind a->b, so every component is
// consistently oriented by construction. A vertex's gaps (open sectors of its fan) are its
// outgoing front edges; vertices with two gaps exist only transiently and are repaired at the
// end so that the output is vertex-manifold.
// SPDX-License-Identifier: MIT
#include "front_builder.hpp"

#include <algorithm>
#include <string>
#include <vector>

namespace scanmesh::recon {
namespace front_impl {

void Builder::cap_spacing(double median) {
  // A point's spacing is capped at kMaxSparsity times the cloud's median spacing, or, for a
  // point sparser than that, at kMaxSparsity times the median spacing (by area) of the points
  // within kRegionRadius of its own spacings, where it has at least kRegionPoints of them and
  // they lie on a plane with it. Where a whole region is sampled sparsely (an overview pass
  // beside a detail pass, a part scanned at a coarser line pitch) its points keep their own
  // spacing and connect; a point much sparser than its surroundings (a stray reading near the
  // surface) or a scatter of stray readings in the air (no plane) does not pull long triangles.
  // With the cloud's median alone, a region over about 5 times sparser than it fell apart.
  // Only the points over the cloud's cap are examined (none of the bunny's points, 85 of bun000's).
  const std::size_t n = p_.size();
  sp_.resize(n);
  res_.spacing_cap = kMaxSparsity * median;
  const auto cap = static_cast<float>(res_.spacing_cap);
  max_spacing_ = 0;
  const std::vector<std::uint32_t>& order = grid_.order();
  const std::vector<float>& raw = f_.spacing;
  struct Near {
    Vec3 d;     // offset from v
    float raw;  // its spacing
  };
  std::vector<Near> near;
  std::vector<float> on;
  for (std::uint32_t v = 0; v < n; ++v) {
    sp_[v] = std::min(raw[v], cap);
    if (raw[v] <= cap) continue;
    const double r = kRegionRadius * static_cast<double>(raw[v]);
    const Vec3& pv = p_[v];
    near.clear();
    Vec3 sum = Vec3::Zero();
    Eigen::Matrix3d moment = Eigen::Matrix3d::Zero();
    grid_.for_each_range_within(pv, r, [&](std::uint32_t first, std::uint32_t last) {
      for (std::uint32_t q = first; q < last; ++q) {
        const std::uint32_t u = order[q];
        const Vec3 d = p_[u] - pv;
        if (u == v || d.squaredNorm() > r * r) continue;
        near.push_back({d, raw[u]});
        sum += d;
        moment += d * d.transpose();
      }
    });
    if (near.size() < kRegionPoints) continue;
    // On a surface: the neighbourhood fits a plane, and v lies on it.
    const double m = static_cast<double>(near.size());
    const Vec3 mean = sum / m;
    const detail::PlaneFit fit = detail::plane_normal(moment / m - mean * mean.transpose());
    const Vec3 ev = fit.eigenvalues.cwiseMax(0.0);
    const double band = kRegionBand * static_cast<double>(raw[v]);
    if (!(ev[0] <= kRegionFlatness * ev.sum()) || std::abs(mean.dot(fit.normal)) > band) continue;
    // The median by area (each point weighs its spacing squared) of the neighbours on that
    // plane: beside a seam with a denser sampling, the dense points outnumber the sparse ones
    // but cover less of the surface; stray readings off the surface do not count.
    on.clear();
    for (const Near& q : near)
      if (std::abs((q.d - mean).dot(fit.normal)) <= band) on.push_back(q.raw);
    if (on.size() < kRegionPoints) continue;
    std::sort(on.begin(), on.end());
    double total = 0;
    for (float x : on) total += static_cast<double>(x) * x;
    double acc = 0;
    float mid = on.back();
    for (float x : on) {
      acc += static_cast<double>(x) * x;
      if (2 * acc >= total) {
        mid = x;
        break;
      }
    }
    sp_[v] = std::min(raw[v], std::max(cap, static_cast<float>(kMaxSparsity * static_cast<double>(mid))));
  }
  for (float x : sp_) max_spacing_ = std::max(max_spacing_, static_cast<double>(x));
}

FrontResult Builder::run() {
  const std::size_t n = p_.size();
  if (opt_.bulk) grow_from_bulk();
  if (ctx_ != nullptr) load_context();
  step("front/growth");
  grow();  // from the bulk's border (without the bulk there is no front yet)
  // Seeds, among the points still free (states only move forward while the front grows):
  // flattest first, index breaking ties, so the order is deterministic. A stable two-pass radix
  // sort on the bits of the flatness (non-negative floats order like their bit patterns; -0 is
  // made +0), which gives the order of a comparison sort by (flatness, index).
  std::vector<std::uint32_t> order;
  {
    std::vector<std::uint32_t> tmp;  // the input of each pass, ascending index
    for (std::uint32_t i = 0; i < n; ++i)
      if (state_[i] == VertexState::kFree) tmp.push_back(i);
    order.resize(tmp.size());
    auto key = [&](std::uint32_t i) { return std::bit_cast<std::uint32_t>(f_.flatness[i] + 0.0f); };
    if (tmp.size() < 8192) {
      // Few points (the incremental path's jobs): a comparison sort by (key, index), the same
      // order, without clearing the radix sort's 256 KB of counters twice.
      order.swap(tmp);
      std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
        const std::uint32_t ka = key(a), kb = key(b);
        return ka != kb ? ka < kb : a < b;
      });
      tmp.clear();
    }
    std::vector<std::uint32_t> count(tmp.empty() ? 0 : 1u << 16);
    for (int shift = 0; shift < 32 && !tmp.empty(); shift += 16) {
      std::fill(count.begin(), count.end(), 0u);
      for (std::uint32_t i : tmp) ++count[(key(i) >> shift) & 0xffffu];
      std::uint32_t sum = 0;
      for (std::uint32_t& c : count) {
        const std::uint32_t here = c;
        c = sum;
        sum += here;
      }
      for (std::uint32_t i : tmp) order[count[(key(i) >> shift) & 0xffffu]++] = i;
      if (shift == 0) tmp.swap(order);
    }
  }
  for (std::uint32_t s : order) {
    if (state_[s] != VertexState::kFree || covered_[s] != 0) continue;
    if (try_seed(s)) grow();
  }
  std::vector<std::uint32_t>().swap(order);
  step("front/repairs");
  // Close sampling gaps, then keep vertices manifold; repairs can open small gaps again, so
  // one more round of each.
  fill_small_loops();
  // Dropping fans opens small gaps: rebuild the front from the mesh and let it close them.
  for (int round = 0; round < 2 && repair_fans() > 0; ++round) {
    if (front_stale_) rebuild_front();
    grow();
    fill_small_loops();
  }
  // The last word: every vertex keeps a single fan; gaps this opens are closed by ear clipping
  // only.
  for (int round = 0; round < 3 && repair_fans() > 0; ++round) {
    if (front_stale_) rebuild_front();
    fill_small_loops();
  }
  split_flat_triangle_holes();
  // Guarantee, checked at every vertex (two closed fans touching at one vertex leave no trace
  // in the front): no multi-fan vertex in the output. A pinch found here is cut and its gap
  // closed by ear clipping; one that survives two such rounds stays a small boundary loop. The
  // edge table is freed first: this check's vertex lists would otherwise sit on top of it at
  // the peak of the whole reconstruction.
  step("front/fan check");
  for (int round = 0; round < 3; ++round) {
    edges_map_ = EdgeMap(0);
    if (repair_fans(true) == 0) break;
    rebuild_front();
    if (round < 2) fill_small_loops();
  }
  if (check_every_step_) check_bulk_fans();
  if (front_stale_) rebuild_front();  // a slit closed above: the states and the orientation read it
  edges_map_ = EdgeMap(0);  // not needed any more
  step("front/orientation");
  {
    // Components can only cross when there are several; the orientation pass needs them too.
    detail::TriangleComponents components(n, tris_);
    if (components.count() > 1) {
      const std::size_t before = tris_.size();
      drop_crossing_components();
      if (tris_.size() != before) components = detail::TriangleComponents(n, tris_);
      if (drop_specks(components)) components = detail::TriangleComponents(n, tris_);
    }
    orient_components(components);
  }
  // Final states: vertices in no triangle are outliers; vertices with open fans are boundary.
  std::vector<std::uint8_t> used(n, 0);
  for (const Triangle& t : tris_)
    for (std::uint32_t v : t) used[v] = 1;
  for (std::uint32_t v = 0; v < n; ++v) {
    if (!used[v]) {
      state_[v] = VertexState::kOutlier;
      res_.outliers.push_back(v);
    } else if (head_out_[v] != kNone) {
      state_[v] = VertexState::kBoundary;
    } else {
      state_[v] = VertexState::kDone;
    }
  }
  res_.triangles = std::move(tris_);
  res_.state = std::move(state_);
  res_.spacing = std::move(sp_);
  return std::move(res_);
}

}  // namespace front_impl

std::vector<std::string> FrontOptions::validate() const {
  std::vector<std::string> errors;
  if (!(min_angle_deg >= 0 && min_angle_deg < 60))
    errors.push_back("min_angle_deg must be in [0, 60), got " + std::to_string(min_angle_deg));
  if (!(min_dihedral_deg >= 0 && min_dihedral_deg < 180))
    errors.push_back("min_dihedral_deg must be in [0, 180)");
  if (!(radius_factor > 0.5 && radius_factor <= 10)) errors.push_back("radius_factor must be in (0.5, 10]");
  if (!(relaxed_radius_factor >= radius_factor && relaxed_radius_factor <= 10))
    errors.push_back("relaxed_radius_factor must be in [radius_factor, 10]");
  if (!(relaxed_min_angle_deg >= 0 && relaxed_min_angle_deg <= min_angle_deg))
    errors.push_back("relaxed_min_angle_deg must be in [0, min_angle_deg]");
  if (max_valence < 6 || max_valence > 250) errors.push_back("max_valence must be in [6, 250]");
  if (!(hole_min_area >= 0 && hole_min_area <= 1e6)) errors.push_back("hole_min_area must be in [0, 1e6]");
  if (!(hole_min_width >= 0 && hole_min_width <= 1e3)) errors.push_back("hole_min_width must be in [0, 1e3]");
  if (bulk_patch_points < 3) errors.push_back("bulk_patch_points must be at least 3");
  if (!(bulk_patch_cone_deg > 0 && bulk_patch_cone_deg < 90))
    errors.push_back("bulk_patch_cone_deg must be in (0, 90) degrees");
  return errors;
}

FrontResult advance_front(std::span<const Vec3> points, const LocalFrames& frames,
                          const PointGrid& grid, const FrontOptions& options,
                          const StageObserver& observer) {
  front_impl::Builder b(points, frames, grid, options, observer);
  return b.run();
}

namespace detail {

FrontResult advance_front_from(std::span<const Vec3> points, const LocalFrames& frames,
                               const PointGrid& grid, const FrontOptions& options,
                               const FrontContext& context) {
  const StageObserver none;
  front_impl::Builder b(points, frames, grid, options, none, &context);
  return b.run();
}

}  // namespace detail

}  // namespace scanmesh::recon
