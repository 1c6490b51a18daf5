// The incremental path's sparse cube grid (incremental_grid.hpp) and the walk of boundary loops
// for deltas (incremental_store.hpp).
// SPDX-License-Identifier: MIT
#include "incremental_grid.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

#include "scanmesh/recon/normals.hpp"

namespace scanmesh::recon::detail {

void KeyTable::grow() {
  const std::size_t cap = keys_.empty() ? 64 : keys_.size() * 2;
  std::vector<std::uint64_t> old_keys(cap, kEmpty);
  std::vector<std::uint32_t> old_values(cap, 0);
  old_keys.swap(keys_);
  old_values.swap(values_);
  mask_ = cap - 1;
  shift_ = 64 - std::countr_zero(cap);
  size_ = 0;
  for (std::size_t i = 0; i < old_keys.size(); ++i)
    if (old_keys[i] != kEmpty) insert(old_keys[i], old_values[i]);
}

void CubeGrid::start(const Vec3& first, double cube, int block_cubes) {
  cube_ = cube;
  inv_cube_ = 1.0 / cube;
  block_cubes_ = block_cubes;
  // The first point's cube is (0, 0, 0), and the first point its centre: the grid is anchored
  // to the sequence, not to a box known in advance.
  origin_ = first - Vec3::Constant(0.5 * cube);
}

namespace {

std::int64_t floor_div(std::int64_t a, std::int64_t b) {
  return a >= 0 ? a / b : -((-a + b - 1) / b);
}

}  // namespace

InsertOutcome CubeGrid::insert(const Vec3& p, const Vec3* towards, std::size_t index) {
  // Cube coordinates within +-2^20 less two blocks (keys are 21 bits an axis, and neighbour
  // look-ups step a block out).
  const double lim = static_cast<double>((std::int64_t{1} << 20) - 2 * block_cubes_ - 2);
  const Vec3 u = (p - origin_) * inv_cube_;
  if (!(std::abs(u.x()) < lim && std::abs(u.y()) < lim && std::abs(u.z()) < lim))
    return InsertOutcome::kFar;
  const auto cx = static_cast<std::int64_t>(std::floor(u.x())),
             cy = static_cast<std::int64_t>(std::floor(u.y())),
             cz = static_cast<std::int64_t>(std::floor(u.z()));
  const Vec3 d(u.x() - static_cast<double>(cx) - 0.5, u.y() - static_cast<double>(cy) - 0.5,
               u.z() - static_cast<double>(cz) - 0.5);
  const auto d2 = static_cast<float>(d.squaredNorm());
  const std::uint64_t k = key(cx, cy, cz);
  std::uint32_t c = find_cube(k);
  InsertOutcome out = InsertOutcome::kExistingCube;
  if (c == kNoId) {
    const std::int64_t bx = floor_div(cx, block_cubes_), by = floor_div(cy, block_cubes_),
                       bz = floor_div(cz, block_cubes_);
    std::uint32_t b = block_at(bx, by, bz);
    if (b == kNoId) {
      b = static_cast<std::uint32_t>(blocks_.size());
      Block nb;
      nb.x = static_cast<std::int32_t>(bx);
      nb.y = static_cast<std::int32_t>(by);
      nb.z = static_cast<std::int32_t>(bz);
      blocks_.push_back(std::move(nb));
      block_table_.insert(key(bx, by, bz), b);
      unmeshed_.push_back(b);
    }
    c = static_cast<std::uint32_t>(cubes_.size());
    Cube nc;
    nc.rep = p;
    nc.d2 = d2;
    nc.block = b;
    nc.x = static_cast<std::int32_t>(cx);
    nc.y = static_cast<std::int32_t>(cy);
    nc.z = static_cast<std::int32_t>(cz);
    if (towards != nullptr) nc.towards = towards->cast<float>();
    cubes_.push_back(nc);
    cube_table_.insert(k, c, [this](std::uint32_t o) { return cube_key(o); });
    Block& blk = blocks_[b];
    blk.cubes.push_back(c);
    out = InsertOutcome::kNewCube;
    if (blk.state == BlockState::kMeshed) {
      out = InsertOutcome::kReopened;
      unmeshed_.push_back(b);
    }
    blk.state = BlockState::kOpen;
    blk.forced = false;
  } else {
    Cube& cb = cubes_[c];
    // Nearer to the centre replaces the kept point (ties keep the earlier), unless it is a
    // published vertex already.
    if (cb.vertex == kNoId && d2 < cb.d2) {
      cb.rep = p;
      cb.d2 = d2;
      cb.towards = towards != nullptr ? Eigen::Vector3f(towards->cast<float>()) : Eigen::Vector3f::Zero();
    }
    Block& blk = blocks_[cb.block];
    if (blk.state != BlockState::kMeshed) {
      blk.state = BlockState::kOpen;
      blk.forced = false;
    }
  }
  Cube& cb = cubes_[c];
  ++cb.count;
  const auto fx = static_cast<float>(d.x()), fy = static_cast<float>(d.y()),
             fz = static_cast<float>(d.z());
  cb.sum[0] += fx;
  cb.sum[1] += fy;
  cb.sum[2] += fz;
  cb.outer[0] += fx * fx;
  cb.outer[1] += fx * fy;
  cb.outer[2] += fx * fz;
  cb.outer[3] += fy * fy;
  cb.outer[4] += fy * fz;
  cb.outer[5] += fz * fz;
  blocks_[cb.block].last_index = index;
  return out;
}

bool CubeGrid::settled_now(const Block& b, std::size_t seq,
                           const std::optional<Footprint>& footprint, std::size_t delay,
                           double margin_cubes) const {
  if (b.state != BlockState::kOpen || b.forced) return true;
  if (footprint) {
    const double edge = cube_ * block_cubes_;
    const Vec3 lo = origin_ + edge * Vec3(b.x, b.y, b.z);
    const Eigen::AlignedBox3d box(lo, lo + Vec3::Constant(edge));
    const double reach = footprint->radius_mm + margin_cubes * cube_;
    return box.squaredExteriorDistance(footprint->centre) > reach * reach;
  }
  return seq - b.last_index > delay;
}

std::vector<std::uint32_t> CubeGrid::settle(std::size_t seq,
                                            const std::optional<Footprint>& footprint,
                                            std::size_t delay, double margin_cubes, double now) {
  // Only the unmeshed blocks (the scan's frontier) are looked at: the list drops the meshed.
  std::erase_if(unmeshed_, [&](std::uint32_t i) { return blocks_[i].state == BlockState::kMeshed; });
  std::sort(unmeshed_.begin(), unmeshed_.end());  // a block re-opened twice is listed once
  unmeshed_.erase(std::unique(unmeshed_.begin(), unmeshed_.end()), unmeshed_.end());
  for (std::uint32_t i : unmeshed_) {
    Block& b = blocks_[i];
    if (b.state == BlockState::kOpen && settled_now(b, seq, footprint, delay, margin_cubes)) {
      b.state = BlockState::kSettled;
      b.settled_at = now;
    }
  }
  std::vector<std::uint32_t> ready;
  for (std::uint32_t i : unmeshed_) {
    const Block& b = blocks_[i];
    if (b.state != BlockState::kSettled) continue;
    bool all = true;
    for (int dz = -1; dz <= 1 && all; ++dz)
      for (int dy = -1; dy <= 1 && all; ++dy)
        for (int dx = -1; dx <= 1 && all; ++dx) {
          const std::uint32_t n = block_at(b.x + dx, b.y + dy, b.z + dz);
          all = n == kNoId || blocks_[n].state != BlockState::kOpen;
        }
    if (all) ready.push_back(i);
  }
  std::sort(ready.begin(), ready.end());
  return ready;
}

void CubeGrid::force_settle(const Eigen::AlignedBox3d* box, double now) {
  const double edge = cube_ * block_cubes_;
  for (const std::uint32_t i : unmeshed_) {
    Block& b = blocks_[i];
    if (b.state == BlockState::kMeshed) continue;
    if (box != nullptr) {
      const Vec3 lo = origin_ + edge * Vec3(b.x, b.y, b.z);
      if (!box->intersects(Eigen::AlignedBox3d(lo, lo + Vec3::Constant(edge)))) continue;
    }
    b.forced = true;
    if (b.state == BlockState::kOpen) {
      b.state = BlockState::kSettled;
      b.settled_at = now;
    }
  }
}

void CubeGrid::mark_meshed(std::uint32_t block) { blocks_[block].state = BlockState::kMeshed; }

std::vector<std::uint32_t> CubeGrid::unmeshed_blocks() const {
  std::vector<std::uint32_t> out;
  for (std::uint32_t i : unmeshed_)
    if (blocks_[i].state != BlockState::kMeshed) out.push_back(i);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

std::vector<std::uint32_t> CubeGrid::thinned_cubes_of(std::span<const std::uint32_t> job) const {
  std::vector<std::uint32_t> cand;
  for (std::uint32_t b : job) cand.insert(cand.end(), blocks_[b].cubes.begin(), blocks_[b].cubes.end());
  std::sort(cand.begin(), cand.end(), [&](std::uint32_t a, std::uint32_t b) {
    const Cube &ca = cubes_[a], &cb = cubes_[b];
    if (ca.vertex != cb.vertex) return ca.vertex < cb.vertex;
    if (ca.d2 != cb.d2) return ca.d2 < cb.d2;
    return a < b;
  });
  // Scratch flags (sized to the grid, cleared after use): O(job), not O(grid), a call.
  std::vector<std::uint8_t>& in_job = block_mark_;
  std::vector<std::uint8_t>& kept = cube_mark_;
  in_job.resize(blocks_.size(), 0);
  kept.resize(cubes_.size(), 0);
  for (std::uint32_t b : job) in_job[b] = 1;
  const double r2 = 0.65 * 0.65 * cube_ * cube_;
  std::vector<std::uint32_t> out;
  out.reserve(cand.size());
  // A neighbour cube whose box lies 0.65 cube or more from the kept point cannot hold a
  // clashing one: it is not looked up (a kept point near its cube's centre has only its six
  // face neighbours within reach). The margin covers the rounding of the cube assignment.
  const double skip2 = r2 * (1 + 1e-9);
  for (std::uint32_t c : cand) {
    const Cube& cc = cubes_[c];
    const Vec3 r = cc.rep - centre(cc);
    // Per axis and side (-1, 0, +1): the squared gap from the kept point to that slab.
    double gap2[3][3];
    for (int k = 0; k < 3; ++k) {
      const double lo = std::max(0.0, 0.5 * cube_ + r[k]), hi = std::max(0.0, 0.5 * cube_ - r[k]);
      gap2[k][0] = lo * lo;
      gap2[k][1] = 0;
      gap2[k][2] = hi * hi;
    }
    bool clash = false;
    for (int dz = -1; dz <= 1 && !clash; ++dz)
      for (int dy = -1; dy <= 1 && !clash; ++dy)
        for (int dx = -1; dx <= 1 && !clash; ++dx) {
          if (dx == 0 && dy == 0 && dz == 0) continue;
          if (gap2[0][dx + 1] + gap2[1][dy + 1] + gap2[2][dz + 1] >= skip2) continue;
          const std::uint32_t n = find_cube(key(cc.x + dx, cc.y + dy, cc.z + dz));
          if (n == kNoId) continue;
          const bool other = in_job[cubes_[n].block] ? kept[n] != 0 : cubes_[n].vertex != kNoId;
          clash = other && (cubes_[n].rep - cc.rep).squaredNorm() < r2;
        }
    if (clash) continue;
    kept[c] = 1;
    out.push_back(c);
  }
  for (std::uint32_t c : out) kept[c] = 0;
  for (std::uint32_t b : job) in_job[b] = 0;
  return out;
}

std::vector<std::uint32_t> CubeGrid::neighbour_blocks(std::uint32_t block) const {
  const Block& b = blocks_[block];
  std::vector<std::uint32_t> out;
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const std::uint32_t n = block_at(b.x + dx, b.y + dy, b.z + dz);
        if (n != kNoId) out.push_back(n);
      }
  std::sort(out.begin(), out.end());
  return out;
}

bool CubeGrid::near_blocks(std::uint32_t c, std::span<const std::uint32_t> job, int cubes) const {
  const Cube& cc = cubes_[c];
  for (std::uint32_t j : job) {
    const Block& b = blocks_[j];
    const std::int64_t lo[3] = {std::int64_t{b.x} * block_cubes_, std::int64_t{b.y} * block_cubes_,
                                std::int64_t{b.z} * block_cubes_};
    const std::int64_t at[3] = {cc.x, cc.y, cc.z};
    bool in = true;
    for (int k = 0; k < 3 && in; ++k) in = at[k] >= lo[k] - cubes && at[k] < lo[k] + block_cubes_ + cubes;
    if (in) return true;
  }
  return false;
}

std::vector<std::uint32_t> CubeGrid::cubes_near(std::span<const std::uint32_t> job,
                                                std::span<const std::uint32_t> ring,
                                                int cubes) const {
  std::vector<std::uint32_t> out;
  for (std::uint32_t r : ring)
    for (std::uint32_t c : blocks_[r].cubes) {
      const Cube& cc = cubes_[c];
      bool near = false;
      for (std::uint32_t j : job) {
        const Block& b = blocks_[j];
        const std::int64_t lo[3] = {std::int64_t{b.x} * block_cubes_, std::int64_t{b.y} * block_cubes_,
                                    std::int64_t{b.z} * block_cubes_};
        const std::int64_t at[3] = {cc.x, cc.y, cc.z};
        bool in = true;
        for (int k = 0; k < 3 && in; ++k)
          in = at[k] >= lo[k] - cubes && at[k] < lo[k] + block_cubes_ + cubes;
        if (in) {
          near = true;
          break;
        }
      }
      if (near) out.push_back(c);
    }
  return out;
}

Vec3 CubeGrid::projected(std::uint32_t c) const {
  const Cube& cc = cubes_[c];
  double n = 0;
  Eigen::Vector3d s = Eigen::Vector3d::Zero();
  Eigen::Matrix3d o = Eigen::Matrix3d::Zero();
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const std::uint32_t q = find_cube(key(cc.x + dx, cc.y + dy, cc.z + dz));
        if (q == kNoId) continue;
        const Cube& cq = cubes_[q];
        const double m = cq.count;
        const Eigen::Vector3d k(dx, dy, dz);
        const Eigen::Vector3d sq(cq.sum[0], cq.sum[1], cq.sum[2]);
        Eigen::Matrix3d oq;
        oq << cq.outer[0], cq.outer[1], cq.outer[2], cq.outer[1], cq.outer[3], cq.outer[4],
            cq.outer[2], cq.outer[4], cq.outer[5];
        // About this cube's centre: d' = d + k.
        n += m;
        s += sq + m * k;
        o += oq + sq * k.transpose() + k * sq.transpose() + m * k * k.transpose();
      }
  if (n < 6) return cc.rep;
  const Eigen::Vector3d mean = s / n;
  const Eigen::Matrix3d cov = o / n - mean * mean.transpose();
  const PlaneFit fit = plane_normal(cov);
  const Eigen::Vector3d r = (cc.rep - centre(cc)) * inv_cube_;
  double h = (mean - r).dot(fit.normal);
  h = std::clamp(h, -0.5, 0.5);
  return cc.rep + (h * cube_) * fit.normal;
}

BlockCounts CubeGrid::block_counts() const {
  BlockCounts bc;
  for (const Block& b : blocks_) {
    if (b.state == BlockState::kOpen) ++bc.open;
    if (b.state == BlockState::kSettled) ++bc.settled;
    if (b.state == BlockState::kMeshed) ++bc.meshed;
    if (b.state != BlockState::kMeshed) bc.unmeshed_cubes += b.cubes.size();
  }
  return bc;
}

std::size_t CubeGrid::heap_bytes() const {
  std::size_t n = cubes_.heap_bytes() + blocks_.capacity() * sizeof(Block) +
                  cube_table_.heap_bytes() + block_table_.heap_bytes();
  for (const Block& b : blocks_) n += b.cubes.capacity() * 4;
  return n;
}

}  // namespace scanmesh::recon::detail
