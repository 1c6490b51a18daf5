// Little-endian encoding and bounds-checked decoding of MCAP's primitive types (integers,
// uint32-length-prefixed strings and maps), and a growable byte buffer without zero-filling.
// SPDX-License-Identifier: MIT
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <string_view>

namespace scanmesh::acq::detail {

static_assert(std::endian::native == std::endian::little,
              "the MCAP and CDR encoders copy integers as they are in memory (little-endian)");

template <class T>
inline void store(std::byte* p, T v) {
  std::memcpy(p, &v, sizeof v);
}
template <class T>
inline T load(const std::byte* p) {
  T v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

/// A byte buffer that grows without initialising what it adds (the caller writes it).
class ByteBuffer {
 public:
  [[nodiscard]] std::byte* data() noexcept { return data_.get(); }
  [[nodiscard]] const std::byte* data() const noexcept { return data_.get(); }
  [[nodiscard]] std::size_t size() const noexcept { return size_; }
  [[nodiscard]] std::span<const std::byte> span() const noexcept { return {data_.get(), size_}; }
  void clear() noexcept { size_ = 0; }
  void resize(std::size_t n) {
    reserve(n);
    size_ = n;
  }
  void reserve(std::size_t n) {
    if (n <= capacity_) return;
    std::size_t cap = capacity_ == 0 ? 4096 : capacity_;
    while (cap < n) cap *= 2;
    auto bigger = std::make_unique_for_overwrite<std::byte[]>(cap);
    if (size_ > 0) std::memcpy(bigger.get(), data_.get(), size_);
    data_ = std::move(bigger);
    capacity_ = cap;
  }
  /// Appends n uninitialised bytes and returns where they start.
  std::byte* grow(std::size_t n) {
    reserve(size_ + n);
    std::byte* p = data_.get() + size_;
    size_ += n;
    return p;
  }
  void append(std::span<const std::byte> bytes) {
    if (!bytes.empty()) std::memcpy(grow(bytes.size()), bytes.data(), bytes.size());
  }
  template <class T>
  void put(T v) {
    store(grow(sizeof v), v);
  }
  void put_string(std::string_view s) {
    put(static_cast<std::uint32_t>(s.size()));
    append(std::as_bytes(std::span(s.data(), s.size())));
  }
  void put_string_map(const std::map<std::string, std::string>& m) {
    const std::size_t length_at = size_;
    put(std::uint32_t{0});
    for (const auto& [k, v] : m) {
      put_string(k);
      put_string(v);
    }
    store(data() + length_at, static_cast<std::uint32_t>(size_ - length_at - 4));
  }
  /// Starts a record: opcode and a length to be filled in by end_record(start).
  std::size_t begin_record(std::uint8_t opcode) {
    const std::size_t start = size_;
    put(opcode);
    put(std::uint64_t{0});
    return start;
  }
  void end_record(std::size_t start) {
    store(data() + start + 1, static_cast<std::uint64_t>(size_ - start - 9));
  }

 private:
  std::unique_ptr<std::byte[]> data_;
  std::size_t size_ = 0;
  std::size_t capacity_ = 0;
};

/// Reads primitives from a byte span; any read past the end sets ok() false and yields zeros.
class ByteReader {
 public:
  explicit ByteReader(std::span<const std::byte> bytes) : bytes_(bytes) {}
  [[nodiscard]] bool ok() const noexcept { return ok_; }
  [[nodiscard]] std::size_t pos() const noexcept { return pos_; }
  [[nodiscard]] std::size_t remaining() const noexcept { return bytes_.size() - pos_; }
  template <class T>
  T get() {
    if (remaining() < sizeof(T)) return fail<T>();
    T v = load<T>(bytes_.data() + pos_);
    pos_ += sizeof(T);
    return v;
  }
  std::span<const std::byte> bytes(std::size_t n) {
    if (remaining() < n) return fail<std::span<const std::byte>>();
    auto s = bytes_.subspan(pos_, n);
    pos_ += n;
    return s;
  }
  std::string string() {
    const auto n = get<std::uint32_t>();
    const auto s = bytes(n);
    return {reinterpret_cast<const char*>(s.data()), s.size()};
  }
  std::map<std::string, std::string> string_map() {
    std::map<std::string, std::string> m;
    const auto n = get<std::uint32_t>();
    ByteReader inner(bytes(n));
    while (ok_ && inner.ok() && inner.remaining() > 0) {
      std::string k = inner.string();
      std::string v = inner.string();
      if (inner.ok()) m.emplace(std::move(k), std::move(v));
    }
    if (!inner.ok()) ok_ = false;
    return m;
  }

 private:
  template <class T>
  T fail() {
    ok_ = false;
    pos_ = bytes_.size();
    return T{};
  }
  std::span<const std::byte> bytes_;
  std::size_t pos_ = 0;
  bool ok_ = true;
};

}  // namespace scanmesh::acq::detail
