// Device-to-host clock mapping by the lower envelope of transit delays.
// SPDX-License-Identifier: MIT
#include "scanmesh/acquisition/clock_mapper.hpp"

#include <algorithm>
#include <cmath>

namespace scanmesh::acq {

std::vector<std::string> ClockMapperConfig::problems() const {
  std::vector<std::string> p;
  if (block_samples < 4 || block_samples > 1000000)
    p.push_back("clock.block_samples must be in 4 .. 1000000 (got " +
                std::to_string(block_samples) + ")");
  if (blocks < 2 || blocks > 4096)
    p.push_back("clock.blocks must be in 2 .. 4096 (got " + std::to_string(blocks) + ")");
  return p;
}

ClockMapper::ClockMapper(ClockMapperConfig config)
    : config_(config), min_device_(config.blocks), min_diff_(config.blocks) {}

void ClockMapper::observe(drivers::Timestamp device, drivers::Timestamp host) {
  const std::int64_t d = host.ns - device.ns;
  global_min_ = observations_ == 0 ? d : std::min(global_min_, d);
  ++observations_;
  if (in_block_ == 0 || d < block_min_) {
    block_min_ = d;
    block_min_device_ = device.ns;
  }
  if (++in_block_ < config_.block_samples) return;
  min_device_[ring_next_] = block_min_device_;
  min_diff_[ring_next_] = block_min_;
  ring_next_ = (ring_next_ + 1) % min_device_.size();
  ring_size_ = std::min(ring_size_ + 1, min_device_.size());
  in_block_ = 0;
  refit();
}

void ClockMapper::refit() {
  const std::size_t n = ring_size_;
  const std::size_t last = (ring_next_ + min_device_.size() - 1) % min_device_.size();
  ref_ = min_device_[last];
  if (n < 2) {
    slope_ = 0;
    intercept_ = static_cast<double>(min_diff_[last]);
    fitted_ = true;
    return;
  }
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const double y0 = static_cast<double>(min_diff_[last]);
  for (std::size_t i = 0; i < n; ++i) {
    const double x = static_cast<double>(min_device_[i] - ref_);
    const double y = static_cast<double>(min_diff_[i]) - y0;
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
  }
  const double den = static_cast<double>(n) * sxx - sx * sx;
  slope_ = den > 0 ? (static_cast<double>(n) * sxy - sx * sy) / den : 0.0;
  // Lower the line onto the envelope: no block minimum lies below it.
  double a = 0;
  bool first = true;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = static_cast<double>(min_device_[i] - ref_);
    const double r = static_cast<double>(min_diff_[i]) - y0 - slope_ * x;
    a = first ? r : std::min(a, r);
    first = false;
  }
  intercept_ = y0 + a;
  fitted_ = true;
}

drivers::Timestamp ClockMapper::to_host(drivers::Timestamp device) const {
  if (observations_ == 0) return device;
  if (!fitted_) return {device.ns + global_min_};
  const double diff = intercept_ + slope_ * static_cast<double>(device.ns - ref_);
  return {device.ns + static_cast<std::int64_t>(std::llround(diff))};
}

}  // namespace scanmesh::acq
