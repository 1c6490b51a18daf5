// Device-to-host clock mapping: a sensor that timestamps its samples on its own clock is mapped
// onto the host monotonic clock by the lower envelope of (host receive time - device time), with
// the drift between the two clocks estimated by a line through recent block minima.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::acq {

struct ClockMapperConfig {
  /// Samples per block; each block contributes its smallest host-minus-device difference (the
  /// sample that waited least in transit). 4 .. 1e6. Default 256.
  std::uint32_t block_samples = 256;
  /// Block minima the drift line is fitted through. 2 .. 4096. Default 64.
  std::uint32_t blocks = 64;
  std::vector<std::string> problems() const;
};

/// Host-clock estimate of device timestamps. Deterministic in the sequence of observations.
/// O(1) per sample (the fit is redone once per block over at most `blocks` points).
class ClockMapper {
 public:
  explicit ClockMapper(ClockMapperConfig config = {});

  /// Records one sample's device time and host receive time.
  void observe(drivers::Timestamp device, drivers::Timestamp host);
  /// The host time at which the device clock showed `device`, plus the smallest transit delay
  /// seen (so a sample's mapped time is never later than its receive time by construction of
  /// the envelope). Before any observation: `device` unchanged.
  drivers::Timestamp to_host(drivers::Timestamp device) const;
  /// Estimated rate difference (host - device) / device, in parts per million.
  double drift_ppm() const { return slope_ * 1e6; }
  std::uint64_t observations() const { return observations_; }

 private:
  void refit();

  ClockMapperConfig config_;
  std::uint64_t observations_ = 0;
  // Current block.
  std::uint32_t in_block_ = 0;
  std::int64_t block_min_ = 0;
  std::int64_t block_min_device_ = 0;
  // Ring of block minima (device time, host - device).
  std::vector<std::int64_t> min_device_, min_diff_;
  std::size_t ring_next_ = 0, ring_size_ = 0;
  // Fit: diff(device) = intercept_ + slope_ * (device - ref_), anchored so the line lies on the
  // lower envelope.
  std::int64_t ref_ = 0;
  double intercept_ = 0;
  double slope_ = 0;
  bool fitted_ = false;
  std::int64_t global_min_ = 0;
};

}  // namespace scanmesh::acq
