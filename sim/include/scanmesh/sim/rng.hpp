// Seeded random numbers whose values the library fixes itself: the std::mt19937_64 sequence
// (fixed by the standard) mapped to doubles here, never by <random> distributions.
// SPDX-License-Identifier: MIT
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numbers>

namespace scanmesh::sim {

/// The 64-bit Mersenne Twister: the same sequence as std::mt19937_64 (which the standard fixes;
/// a test checks they agree), with a branch-free state refill (the library's refill branches on
/// a random bit, and those mispredictions showed up in the simulator's profile).
class Mt19937_64 {
 public:
  explicit Mt19937_64(std::uint64_t seed) {
    x_[0] = seed;
    for (std::size_t i = 1; i < kN; ++i)
      x_[i] = 6364136223846793005ULL * (x_[i - 1] ^ (x_[i - 1] >> 62)) + i;
    i_ = kN;
  }
  std::uint64_t operator()() {
    if (i_ >= kN) refill();
    std::uint64_t z = x_[i_++];
    z ^= (z >> 29) & 0x5555555555555555ULL;
    z ^= (z << 17) & 0x71D67FFFEDA60000ULL;
    z ^= (z << 37) & 0xFFF7EEE000000000ULL;
    return z ^ (z >> 43);
  }

 private:
  static constexpr std::size_t kN = 312;
  static constexpr std::size_t kM = 156;
  static constexpr std::uint64_t kA = 0xB5026F5AA96619E9ULL;
  static constexpr std::uint64_t kUpper = ~0ULL << 31;
  static constexpr std::uint64_t kLower = ~kUpper;
  static std::uint64_t twist(std::uint64_t a, std::uint64_t b, std::uint64_t m) {
    const std::uint64_t y = (a & kUpper) | (b & kLower);
    return m ^ (y >> 1) ^ ((0 - (y & 1)) & kA);
  }
  void refill() {
    for (std::size_t k = 0; k < kN - kM; ++k) x_[k] = twist(x_[k], x_[k + 1], x_[k + kM]);
    for (std::size_t k = kN - kM; k < kN - 1; ++k) x_[k] = twist(x_[k], x_[k + 1], x_[k + kM - kN]);
    x_[kN - 1] = twist(x_[kN - 1], x_[0], x_[kM - 1]);
    i_ = 0;
  }
  std::uint64_t x_[kN];
  std::size_t i_;
};

/// One random stream. The same seed gives the same doubles with every standard library (IEEE
/// doubles and a correctly rounded log/cos assumed). Not thread-safe: one per user.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : gen_(seed) {}
  /// Uniform on [0, 1): the top 53 bits as a fraction.
  double uniform() { return static_cast<double>(gen_() >> 11) * 0x1.0p-53; }
  /// Uniform on (0, 1]: safe for log().
  double uniform_open_low() { return static_cast<double>((gen_() >> 11) + 1) * 0x1.0p-53; }
  /// Standard normal by Box-Muller (the cosine branch; one normal per two draws).
  double gaussian() {
    const double u1 = uniform_open_low();
    const double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
  }

 private:
  Mt19937_64 gen_;
};

/// The seed of an independent sub-stream `stream` of `seed` (SplitMix64 finaliser of both), so
/// every imperfection draws from its own stream and changing one never moves another.
constexpr std::uint64_t substream_seed(std::uint64_t seed, std::uint64_t stream) {
  std::uint64_t z = seed + 0x9E3779B97F4A7C15ULL * (stream + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

}  // namespace scanmesh::sim
