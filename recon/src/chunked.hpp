// Internal to recon: a growable array in fixed-size chunks (no doubling slack, no copy when it
// grows, stable element addresses), for the incremental path's per-cube and per-vertex records.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

namespace scanmesh::recon::detail {

template <class T, unsigned kShift = 12>
class Chunked {
 public:
  static constexpr std::size_t kChunk = std::size_t{1} << kShift;
  [[nodiscard]] std::size_t size() const { return size_; }
  [[nodiscard]] bool empty() const { return size_ == 0; }
  T& operator[](std::size_t i) { return chunks_[i >> kShift][i & (kChunk - 1)]; }
  const T& operator[](std::size_t i) const { return chunks_[i >> kShift][i & (kChunk - 1)]; }
  void push_back(const T& v) {
    if ((size_ & (kChunk - 1)) == 0 && (size_ >> kShift) == chunks_.size())
      chunks_.push_back(std::unique_ptr<T[]>(new T[kChunk]));
    (*this)[size_++] = v;
  }
  /// Grows to n elements set to `v` (never shrinks).
  void grow_to(std::size_t n, const T& v) {
    while (size_ < n) push_back(v);
  }
  [[nodiscard]] std::size_t heap_bytes() const {
    return chunks_.size() * kChunk * sizeof(T) + chunks_.capacity() * sizeof(void*);
  }

 private:
  std::vector<std::unique_ptr<T[]>> chunks_;
  std::size_t size_ = 0;
};

}  // namespace scanmesh::recon::detail
