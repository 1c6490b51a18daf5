// The incremental path's published mesh: chunked copy-on-write storage of vertices and
// triangles with stable ids, the pending delta, and per-stage seconds.
// SPDX-License-Identifier: MIT
#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "scanmesh/recon/incremental.hpp"

namespace scanmesh::recon::detail {

inline constexpr std::uint32_t kNoId = 0xffffffffu;

/// Seconds per stage name, in first-use order (filled only when the caller gave a clock).
class StageTimes {
 public:
  void add(const std::string& name, double seconds) {
    for (auto& [n, s] : times_)
      if (n == name) {
        s += seconds;
        return;
      }
    times_.emplace_back(name, seconds);
  }
  [[nodiscard]] double get(const std::string& name) const {
    for (const auto& [n, s] : times_)
      if (n == name) return s;
    return 0.0;
  }
  [[nodiscard]] const std::vector<std::pair<std::string, double>>& all() const { return times_; }

 private:
  std::vector<std::pair<std::string, double>> times_;
};

/// Chunks of T shared with snapshots: a chunk a snapshot holds is copied before it changes.
template <class T>
class CowChunks {
 public:
  static constexpr std::size_t kChunk = MeshSnapshot::kChunk;
  [[nodiscard]] std::size_t size() const { return size_; }
  [[nodiscard]] const T& operator[](std::size_t i) const { return (*chunks_[i / kChunk])[i % kChunk]; }
  void push_back(const T& v) {
    if (size_ % kChunk == 0) {
      chunks_.push_back(std::make_shared<std::vector<T>>());
      chunks_.back()->reserve(kChunk);
    }
    writable(size_ / kChunk).push_back(v);
    ++size_;
  }
  void set(std::size_t i, const T& v) { writable(i / kChunk)[i % kChunk] = v; }
  /// The chunks as a snapshot holds them.
  [[nodiscard]] std::vector<std::shared_ptr<const std::vector<T>>> share() const {
    return {chunks_.begin(), chunks_.end()};
  }
  [[nodiscard]] std::size_t heap_bytes() const {
    return chunks_.size() * (kChunk * sizeof(T) + sizeof(std::shared_ptr<std::vector<T>>) + 64);
  }

 private:
  std::vector<T>& writable(std::size_t chunk) {
    std::shared_ptr<std::vector<T>>& c = chunks_[chunk];
    if (c.use_count() > 1) {  // a snapshot holds it: copy before writing
      auto copy = std::make_shared<std::vector<T>>();
      copy->reserve(kChunk);
      copy->assign(c->begin(), c->end());
      c = std::move(copy);
    }
    return *c;
  }
  std::vector<std::shared_ptr<std::vector<T>>> chunks_;
  std::size_t size_ = 0;
};

/// The published mesh and the delta pending since the last take_delta().
class PublishedMesh {
 public:
  [[nodiscard]] std::size_t vertex_count() const { return vertices_.size(); }
  [[nodiscard]] const Vec3& vertex(std::uint32_t id) const { return vertices_[id]; }
  [[nodiscard]] std::size_t triangle_slots() const { return triangles_.size(); }
  [[nodiscard]] const Triangle& triangle(std::uint32_t id) const { return triangles_[id]; }
  [[nodiscard]] bool alive(std::uint32_t id) const { return triangles_[id][0] != kNoId; }
  [[nodiscard]] std::size_t triangle_count() const { return live_; }

  std::uint32_t add_vertex(const Vec3& p) {
    vertices_.push_back(p);
    return static_cast<std::uint32_t>(vertices_.size() - 1);
  }
  std::uint32_t add_triangle(const Triangle& t) {
    const auto id = static_cast<std::uint32_t>(triangles_.size());
    triangles_.push_back(t);
    ++live_;
    return id;
  }
  void remove_triangle(std::uint32_t id) {
    if (!alive(id)) return;
    for (std::uint32_t v : triangles_[id]) touched_.push_back(v);
    triangles_.set(id, Triangle{kNoId, kNoId, kNoId});
    --live_;
    if (id < delta_first_triangle_) removed_.push_back(id);
  }
  void remove_all_triangles() {
    for (std::uint32_t id = 0; id < triangles_.size(); ++id) remove_triangle(id);
  }

  MeshSnapshot snapshot() const {
    MeshSnapshot s;
    s.vertices_ = vertices_.share();
    s.triangles_ = triangles_.share();
    s.vertex_count_ = vertices_.size();
    s.triangle_slots_ = triangles_.size();
    s.triangle_count_ = live_;
    return s;
  }

  /// The delta since the last call; `loops(touched)` gives the boundary loops through the
  /// vertices of the triangles added and removed (ascending, unique).
  template <class Loops>
  MeshDelta take_delta(Loops&& loops) {
    MeshDelta d;
    d.first_vertex = delta_first_vertex_;
    for (std::size_t v = delta_first_vertex_; v < vertices_.size(); ++v) d.vertices.push_back(vertices_[v]);
    for (std::uint32_t id = delta_first_triangle_; id < triangles_.size(); ++id) {
      if (!alive(id)) continue;
      d.added_ids.push_back(id);
      d.added.push_back(triangles_[id]);
      for (std::uint32_t v : triangles_[id]) touched_.push_back(v);
    }
    std::sort(removed_.begin(), removed_.end());
    d.removed = std::move(removed_);
    removed_.clear();
    std::sort(touched_.begin(), touched_.end());
    touched_.erase(std::unique(touched_.begin(), touched_.end()), touched_.end());
    if (!touched_.empty()) d.boundary_loops = loops(std::span<const std::uint32_t>(touched_));
    touched_.clear();
    delta_first_vertex_ = static_cast<std::uint32_t>(vertices_.size());
    delta_first_triangle_ = static_cast<std::uint32_t>(triangles_.size());
    return d;
  }

  [[nodiscard]] std::size_t heap_bytes() const {
    return vertices_.heap_bytes() + triangles_.heap_bytes() +
           (removed_.capacity() + touched_.capacity()) * 4;
  }

 private:
  CowChunks<Vec3> vertices_;
  CowChunks<Triangle> triangles_;
  std::size_t live_ = 0;
  std::uint32_t delta_first_vertex_ = 0, delta_first_triangle_ = 0;
  std::vector<std::uint32_t> removed_;  // published ids removed since the last delta
  std::vector<std::uint32_t> touched_;  // vertices of removed triangles since the last delta
};

}  // namespace scanmesh::recon::detail
