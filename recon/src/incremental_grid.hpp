// The incremental path's sparse cube grid: one kept point per occupied cube (nearest to the
// cube's centre, as the batch path's cube reduction), per-cube moments of every point for the
// projection, cubes grouped in blocks that settle, are meshed and re-open.
// SPDX-License-Identifier: MIT
#pragma once

#include <Eigen/Core>
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "scanmesh/recon/incremental.hpp"
#include "chunked.hpp"
#include "incremental_store.hpp"

namespace scanmesh::recon::detail {

enum class BlockState : std::uint8_t {
  kOpen,     ///< receiving points, or not yet settled
  kSettled,  ///< settled, waiting for its neighbours (or for its turn) to be meshed
  kMeshed,   ///< meshed; a point in one of its empty cubes re-opens it
};

enum class InsertOutcome : std::uint8_t { kNewCube, kExistingCube, kReopened, kFar };

struct BlockCounts {
  std::size_t open = 0, settled = 0, meshed = 0, unmeshed_cubes = 0;
};

/// Open-addressing map from a 63-bit key to a 32-bit value (linear probing, power-of-two
/// capacity, load at most 1/2). Look-ups only: its order never reaches an output.
class KeyTable {
 public:
  static constexpr std::uint64_t kEmpty = ~std::uint64_t{0};
  [[nodiscard]] std::uint32_t find(std::uint64_t key) const {
    if (keys_.empty()) return kNoId;
    for (std::size_t h = slot(key);; h = (h + 1) & mask_) {
      if (keys_[h] == key) return values_[h];
      if (keys_[h] == kEmpty) return kNoId;
    }
  }
  /// Inserts, or overwrites the value of a key present.
  void assign(std::uint64_t key, std::uint32_t value) {
    if (!keys_.empty())
      for (std::size_t h = slot(key);; h = (h + 1) & mask_) {
        if (keys_[h] == key) {
          values_[h] = value;
          return;
        }
        if (keys_[h] == kEmpty) break;
      }
    insert(key, value);
  }
  void insert(std::uint64_t key, std::uint32_t value) {
    if ((size_ + 1) * 2 > keys_.size()) grow();
    std::size_t h = slot(key);
    while (keys_[h] != kEmpty) h = (h + 1) & mask_;
    keys_[h] = key;
    values_[h] = value;
    ++size_;
  }
  [[nodiscard]] std::size_t heap_bytes() const { return keys_.capacity() * 12; }

 private:
  [[nodiscard]] std::size_t slot(std::uint64_t key) const {
    return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> shift_);
  }
  void grow();
  std::vector<std::uint64_t> keys_;
  std::vector<std::uint32_t> values_;
  std::size_t size_ = 0, mask_ = 0;
  int shift_ = 64;
};

/// Open-addressing index of the cubes by their packed coordinates: a slot holds the cube
/// number and a 32-bit fingerprint of its key (8 bytes; the key itself is computed from the
/// cube record, read only when the fingerprint matches), linear probing, load at most 1/2.
/// Look-ups only: its order never reaches an output.
class CubeIndex {
 public:
  /// `key_of(c)` gives cube c's key.
  template <class KeyOf>
  [[nodiscard]] std::uint32_t find(std::uint64_t key, KeyOf&& key_of) const {
    if (slots_.empty()) return kNoId;
    const std::uint32_t fp = fingerprint(key);
    for (std::size_t h = slot(key);; h = (h + 1) & mask_) {
      const std::uint64_t e = slots_[h];
      if (e == kEmpty) return kNoId;
      const auto c = static_cast<std::uint32_t>(e);
      if (static_cast<std::uint32_t>(e >> 32) == fp && key_of(c) == key) return c;
    }
  }
  /// Adds cube c (its key not present yet).
  template <class KeyOf>
  void insert(std::uint64_t key, std::uint32_t c, KeyOf&& key_of) {
    if ((size_ + 1) * 2 > slots_.size()) {
      std::vector<std::uint64_t> old(slots_.empty() ? 64 : slots_.size() * 2, kEmpty);
      old.swap(slots_);
      mask_ = slots_.size() - 1;
      shift_ = 64 - std::countr_zero(slots_.size());
      for (std::uint64_t e : old)
        if (e != kEmpty) place(key_of(static_cast<std::uint32_t>(e)), static_cast<std::uint32_t>(e));
    }
    place(key, c);
    ++size_;
  }
  [[nodiscard]] std::size_t heap_bytes() const { return slots_.capacity() * 8; }

 private:
  static constexpr std::uint64_t kEmpty = ~std::uint64_t{0};
  [[nodiscard]] std::size_t slot(std::uint64_t key) const {
    return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> shift_);
  }
  static std::uint32_t fingerprint(std::uint64_t key) {
    return static_cast<std::uint32_t>(((key ^ (key >> 29)) * 0xBF58476D1CE4E5B9ull) >> 32);
  }
  void place(std::uint64_t key, std::uint32_t c) {
    std::size_t h = slot(key);
    while (slots_[h] != kEmpty) h = (h + 1) & mask_;
    slots_[h] = (std::uint64_t{fingerprint(key)} << 32) | c;
  }
  std::vector<std::uint64_t> slots_;
  std::size_t size_ = 0, mask_ = 0;
  int shift_ = 64;
};

class CubeGrid {
 public:
  [[nodiscard]] bool ready() const { return cube_ > 0; }
  /// Fixes the cube size and the grid origin (the cube holding `first` has coordinates 0).
  void start(const Vec3& first, double cube, int block_cubes);
  [[nodiscard]] double cube() const { return cube_; }
  [[nodiscard]] int block_cubes() const { return block_cubes_; }

  /// Takes one point (index: its position in the sequence). A point in a new cube of a meshed
  /// block re-opens the block; one in a kept cube only updates the cube's moments, and its kept
  /// point when nearer to the centre and not yet a vertex.
  InsertOutcome insert(const Vec3& p, const Vec3* towards, std::size_t index);

  /// A decision point at sequence position `seq`: every unmeshed block settles when the
  /// footprint is farther than its radius plus `margin_cubes` cubes from it (with a footprint),
  /// or when no point has landed in it for `delay` points (without). Returns the blocks ready to
  /// mesh (settled, and every neighbour settled or meshed), ascending by id (creation order).
  std::vector<std::uint32_t> settle(std::size_t seq, const std::optional<Footprint>& footprint,
                                    std::size_t delay, double margin_cubes, double now);
  /// Blocks meeting `box` (all when null) settle now, until a point lands in them.
  void force_settle(const Eigen::AlignedBox3d* box, double now);
  void mark_meshed(std::uint32_t block);
  [[nodiscard]] std::vector<std::uint32_t> unmeshed_blocks() const;
  [[nodiscard]] double settled_at(std::uint32_t block) const { return blocks_[block].settled_at; }

  [[nodiscard]] std::uint32_t vertex_of(std::uint32_t c) const { return cubes_[c].vertex; }
  void set_vertex(std::uint32_t c, std::uint32_t id) { cubes_[c].vertex = id; }
  [[nodiscard]] const Vec3& rep(std::uint32_t c) const { return cubes_[c].rep; }
  [[nodiscard]] Vec3 towards(std::uint32_t c) const { return cubes_[c].towards.cast<double>(); }
  /// The kept point moved onto the least-squares plane of the points of the 27 cubes around
  /// it (from their moments), by at most half a cube; unmoved with fewer than 6 points.
  [[nodiscard]] Vec3 projected(std::uint32_t c) const;

  /// The kept points of `job` (blocks, ascending) that remain after thinning to 0.65 cube:
  /// vertices first (by id), then by distance to their cube's centre (as cube_reduce_thin);
  /// a point clashes with a kept one of the job or with a vertex around the job.
  [[nodiscard]] std::vector<std::uint32_t> thinned_cubes_of(std::span<const std::uint32_t> job) const;
  /// The blocks around `block` (itself included) that exist, ascending.
  [[nodiscard]] std::vector<std::uint32_t> neighbour_blocks(std::uint32_t block) const;
  [[nodiscard]] const std::vector<std::uint32_t>& cubes_of(std::uint32_t block) const {
    return blocks_[block].cubes;
  }
  [[nodiscard]] std::uint32_t block_of(std::uint32_t c) const { return cubes_[c].block; }
  /// Whether cube c lies within `cubes` cubes of one of the blocks `job` (per axis).
  [[nodiscard]] bool near_blocks(std::uint32_t c, std::span<const std::uint32_t> job, int cubes) const;
  [[nodiscard]] std::size_t block_count() const { return blocks_.size(); }
  [[nodiscard]] BlockState state(std::uint32_t block) const { return blocks_[block].state; }
  /// The cubes of the blocks `ring` within `cubes` cubes of a block of `job` (both ascending).
  [[nodiscard]] std::vector<std::uint32_t> cubes_near(std::span<const std::uint32_t> job,
                                                      std::span<const std::uint32_t> ring,
                                                      int cubes) const;
  [[nodiscard]] std::size_t cube_count() const { return cubes_.size(); }
  [[nodiscard]] BlockCounts block_counts() const;
  [[nodiscard]] std::size_t heap_bytes() const;

 private:
  struct Cube {
    Vec3 rep;                   // kept point: the nearest to the centre so far
    Eigen::Vector3f towards{0, 0, 0};  // from the kept point towards its sensor (0: unknown)
    float d2 = 0;               // its squared distance to the centre, in cube units
    std::uint32_t block = 0;
    std::uint32_t vertex = kNoId;  // published vertex id (frozen from then on)
    std::uint32_t count = 0;       // points landed
    std::int32_t x = 0, y = 0, z = 0;
    std::array<float, 3> sum{};    // moments of the points about the centre, in cube units
    std::array<float, 6> outer{};  // xx xy xz yy yz zz
  };
  struct Block {
    std::int32_t x = 0, y = 0, z = 0;
    BlockState state = BlockState::kOpen;
    bool forced = false;  // settled by settle() / settle_all()
    std::size_t last_index = 0;  // sequence position of the last point landed
    double settled_at = 0;
    std::vector<std::uint32_t> cubes;
  };
  static std::uint64_t key(std::int64_t x, std::int64_t y, std::int64_t z) {
    constexpr std::int64_t kOff = std::int64_t{1} << 20;
    return (static_cast<std::uint64_t>(z + kOff) << 42) | (static_cast<std::uint64_t>(y + kOff) << 21) |
           static_cast<std::uint64_t>(x + kOff);
  }
  [[nodiscard]] Vec3 centre(const Cube& c) const {
    return origin_ + cube_ * Vec3(c.x + 0.5, c.y + 0.5, c.z + 0.5);
  }
  [[nodiscard]] std::uint32_t block_at(std::int64_t x, std::int64_t y, std::int64_t z) const {
    return block_table_.find(key(x, y, z));
  }
  [[nodiscard]] bool settled_now(const Block& b, std::size_t seq,
                                 const std::optional<Footprint>& footprint, std::size_t delay,
                                 double margin_cubes) const;

  double cube_ = 0, inv_cube_ = 0;
  int block_cubes_ = 16;
  Vec3 origin_ = Vec3::Zero();  // corner of cube (0, 0, 0)
  Chunked<Cube, 10> cubes_;  // no doubling slack: the largest record of the path
  CubeIndex cube_table_;
  [[nodiscard]] std::uint32_t find_cube(std::uint64_t k) const {
    return cube_table_.find(k, [this](std::uint32_t c) { return cube_key(c); });
  }
  [[nodiscard]] std::uint64_t cube_key(std::uint32_t c) const {
    const Cube& cc = cubes_[c];
    return key(cc.x, cc.y, cc.z);
  }
  std::vector<Block> blocks_;
  KeyTable block_table_;
  std::vector<std::uint32_t> unmeshed_;  // blocks not meshed (meshed ones dropped lazily)
  mutable std::vector<std::uint8_t> cube_mark_, block_mark_;  // scratch, all zero between calls
};

}  // namespace scanmesh::recon::detail
