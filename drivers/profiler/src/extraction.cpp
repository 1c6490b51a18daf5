// Laser-line extraction per column or row (see extraction.hpp): two vectorised passes over the
// frame find each column's peak, mean and brightest pixel away from the peak; a short walk
// around each peak finds its window and centre.
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/profiler/extraction.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <opencv2/core.hpp>

#include "scanmesh/common/error.hpp"

namespace scanmesh::drivers::profiler {

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
/// A second maximum inside the peak's neighbourhood counts as a second peak only when the
/// valley between them falls below this fraction of its own contrast (speckle wiggles on one
/// line do not).
constexpr float kValleyRatio = 0.7f;
/// The light beside the line may differ between its two sides by this fraction of the line's
/// contrast (and at least this many levels, for noise) before it counts as lying on an edge.
constexpr float kFloorStepRatio = 0.15f;
constexpr float kFloorStepLevels = 8.0f;

}  // namespace

std::vector<std::string> ExtractionOptions::problems() const {
  std::vector<std::string> p;
  if (min_contrast < 1 || min_contrast > 255)
    p.push_back("min_contrast must be 1..255, got " + std::to_string(min_contrast));
  if (!(edge_ratio > 0 && edge_ratio < 1))
    p.push_back("edge_ratio must be in (0, 1), got " + std::to_string(edge_ratio));
  if (max_width_px < 2 || max_width_px > 255)
    p.push_back("max_width_px must be 2..255, got " + std::to_string(max_width_px));
  if (!(second_peak_ratio > edge_ratio && second_peak_ratio <= 1))
    p.push_back("second_peak_ratio must be in (edge_ratio, 1], got " +
                std::to_string(second_peak_ratio));
  if (saturation_level < 1 || saturation_level > 255)
    p.push_back("saturation_level must be 1..255, got " + std::to_string(saturation_level));
  if (max_saturated_px < 0) p.push_back("max_saturated_px must be >= 0");
  if (trim_ends < 0 || trim_ends > 16)
    p.push_back("trim_ends must be 0..16, got " + std::to_string(trim_ends));
  return p;
}

void ExtractionOptions::validate() const {
  const auto p = problems();
  if (p.empty()) return;
  std::string msg = "line extraction options:";
  for (const auto& s : p) msg += " " + s + ";";
  msg.pop_back();
  throw ConfigError(msg);
}

LineExtractor::LineExtractor(ExtractionOptions options) : options_(options) {
  options_.validate();
}

void LineExtractor::scan_columns(const cv::Mat& img) {
  const int rows = img.rows;
  const int cols = img.cols;
  key_.assign(static_cast<std::size_t>(cols), 0);
  sum_.assign(static_cast<std::size_t>(cols), 0);
  arg_.resize(static_cast<std::size_t>(cols));
  second_.assign(static_cast<std::size_t>(cols), 0);
  std::uint32_t* __restrict key = key_.data();
  std::uint32_t* __restrict sum = sum_.data();
  // Pass 1: the peak and its first row (one 32-bit maximum of level << 16 | (0xffff - row)) and
  // the sum, per column.
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* __restrict p = img.ptr<std::uint8_t>(r);
    const std::uint32_t tag = 0xffffu - static_cast<std::uint32_t>(r);
    for (int c = 0; c < cols; ++c) {
      const std::uint32_t v = p[c];
      const std::uint32_t k = (v << 16) | tag;
      key[c] = key[c] > k ? key[c] : k;
      sum[c] += v;
    }
  }
  std::uint32_t* __restrict arg = arg_.data();
  for (int c = 0; c < cols; ++c) arg[c] = 0xffffu - (key[c] & 0xffffu);
  // Pass 2: the brightest pixel farther than max_width_px from the peak (a second line, a
  // reflection): |r - arg| > guard, as one unsigned comparison.
  const std::uint32_t guard = static_cast<std::uint32_t>(options_.max_width_px);
  std::uint32_t* __restrict second = second_.data();
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* __restrict p = img.ptr<std::uint8_t>(r);
    const std::uint32_t ur = static_cast<std::uint32_t>(r);
    for (int c = 0; c < cols; ++c) {
      const std::uint32_t d = ur - arg[c] + guard;
      const std::uint32_t v = d > 2 * guard ? p[c] : 0u;
      second[c] = second[c] > v ? second[c] : v;
    }
  }
}

LineExtractor::Verdict LineExtractor::analyse(const std::uint8_t* line, std::ptrdiff_t stride,
                                              int n, int peak, int arg, float mean, int second,
                                              float& position) const {
  const auto at = [&](int i) { return static_cast<float>(line[i * stride]); };
  const float min_contrast = static_cast<float>(options_.min_contrast);
  if (static_cast<float>(peak) - mean < min_contrast) return Verdict::kWeak;
  // Levels count from the floor around the peak (the ambient light under the line), not from
  // the column's mean, which dark or bright regions elsewhere in the column pull away.
  const int max_width = options_.max_width_px;
  const int lo = std::max(0, arg - max_width);
  const int hi = std::min(n - 1, arg + max_width);
  // The floor: the higher of the darkest pixels on either side (on a step in the background,
  // the brighter side's level: the line must stand out from both).
  float left_floor = static_cast<float>(peak), right_floor = static_cast<float>(peak);
  for (int i = lo; i < arg; ++i) left_floor = std::min(left_floor, at(i));
  for (int i = arg + 1; i <= hi; ++i) right_floor = std::min(right_floor, at(i));
  const float floor = std::max(arg > lo ? left_floor : right_floor,
                               arg < hi ? right_floor : left_floor);
  const float contrast = static_cast<float>(peak) - floor;
  if (contrast < min_contrast) return Verdict::kTooWide;  // a plateau, no peak on it
  const float second_level = floor + static_cast<float>(options_.second_peak_ratio) * contrast;
  if (static_cast<float>(second) >= second_level) return Verdict::kAmbiguous;
  const float edge = floor + static_cast<float>(options_.edge_ratio) * contrast;

  // The window: the run above the edge level around the peak.
  int a = arg;
  while (a > 0 && at(a - 1) > edge) {
    if (arg - --a >= max_width) return Verdict::kTooWide;
  }
  int b = arg;
  while (b + 1 < n && at(b + 1) > edge) {
    if (++b - a + 1 > max_width) return Verdict::kTooWide;
  }
  // Second peaks near the line (pass 2 covered the rest): beyond the window any pixel at the
  // second level; inside it a second maximum behind a valley (two lines merged at the edge).
  for (int dir = -1; dir <= 1; dir += 2) {
    float valley = static_cast<float>(peak);
    for (int i = arg + dir; i >= lo && i <= hi; i += dir) {
      const float v = at(i);
      valley = std::min(valley, v);
      if (v < second_level) continue;
      const bool inside = i >= a && i <= b;
      if (!inside || valley - floor < kValleyRatio * (v - floor)) return Verdict::kAmbiguous;
    }
  }
  // A line is a peak: most of its window above half its contrast. A window mostly low is a
  // plateau with a bump on it (a sliver of light at an edge), not a line.
  int low = 0;
  const float half = floor + 0.5f * contrast;
  for (int i = a; i <= b; ++i) low += at(i) < half;
  if (2 * low > b - a + 2) return Verdict::kTooWide;
  // A line on the border of two surfaces (falling off an edge, at a silhouette, across a
  // change of albedo): the light on its two sides differs, and its centre is biased.
  if (a >= 2 && b + 2 < n) {
    const float left = 0.5f * (at(a - 1) + at(a - 2));
    const float right = 0.5f * (at(b + 1) + at(b + 2));
    if (std::abs(left - right) > std::max(kFloorStepRatio * contrast, kFloorStepLevels))
      return Verdict::kEdge;
  }
  int saturated = 0;
  for (int i = a; i <= b; ++i) saturated += at(i) >= static_cast<float>(options_.saturation_level);
  if (saturated > options_.max_saturated_px) return Verdict::kSaturated;

  // Centre of gravity above the edge level (offsets from the peak keep the sums small).
  double sw = 0;
  double sx = 0;
  for (int i = a; i <= b; ++i) {
    const double w = at(i) - edge;
    sw += w;
    sx += w * (i - arg);
  }
  double centre = sw > 0 ? arg + sx / sw : arg;

  if (options_.method == PeakMethod::kGaussian) {
    // ln(y) = A + B x + C x^2 by least squares weighted with y^2 (Guo 2011), over the window and
    // one pixel beyond each side, unsaturated pixels only.
    double s[5] = {0, 0, 0, 0, 0};
    double t[3] = {0, 0, 0};
    int used = 0;
    for (int i = std::max(0, a - 1); i <= std::min(n - 1, b + 1); ++i) {
      const double v = at(i);
      const double y = v - floor;
      if (y < 1 || v >= options_.saturation_level) continue;
      const double x = i - arg;
      const double w = y * y;
      const double ly = std::log(y);
      double xp = w;
      for (int k = 0; k < 5; ++k) {
        s[k] += xp;
        if (k < 3) t[k] += xp * ly;
        xp *= x;
      }
      ++used;
    }
    if (used >= 3) {
      // Normal equations [s0 s1 s2; s1 s2 s3; s2 s3 s4] [A B C] = [t0 t1 t2], by Cramer's rule.
      const double det = s[0] * (s[2] * s[4] - s[3] * s[3]) - s[1] * (s[1] * s[4] - s[3] * s[2]) +
                         s[2] * (s[1] * s[3] - s[2] * s[2]);
      if (std::abs(det) > 1e-12 * s[0] * s[2] * s[4]) {
        const double det_b = s[0] * (t[1] * s[4] - s[3] * t[2]) -
                             t[0] * (s[1] * s[4] - s[3] * s[2]) +
                             s[2] * (s[1] * t[2] - t[1] * s[2]);
        const double det_c = s[0] * (s[2] * t[2] - t[1] * s[3]) -
                             s[1] * (s[1] * t[2] - t[1] * s[2]) +
                             t[0] * (s[1] * s[3] - s[2] * s[2]);
        const double bb = det_b / det;
        const double cc = det_c / det;
        // A fit the noise bent away from the window keeps the centre of gravity.
        if (cc < 0) {
          const double g = arg - bb / (2 * cc);
          if (g >= a && g <= b && std::abs(g - centre) < 0.5) centre = g;
        }
      }
    }
  }
  position = static_cast<float>(centre);
  return Verdict::kFound;
}

ExtractionCounts LineExtractor::extract(const cv::Mat& image, const cv::Mat& background,
                                        std::vector<float>& positions) {
  if (image.type() != CV_8UC1 || image.empty())
    throw ConfigError("line extraction: the frame must be a non-empty 8-bit single-channel image");
  if (image.rows > 0xffff || image.cols > 0xffff)
    throw ConfigError("line extraction: frames of at most 65535 x 65535 pixels");
  const cv::Mat* img = &image;
  if (!background.empty()) {
    if (background.size() != image.size() || background.type() != image.type())
      throw ConfigError("line extraction: the background frame is " +
                        std::to_string(background.cols) + "x" + std::to_string(background.rows) +
                        ", the frame " + std::to_string(image.cols) + "x" +
                        std::to_string(image.rows));
    cv::subtract(image, background, diff_);  // saturating: negative differences become 0
    img = &diff_;
  }
  ExtractionCounts counts;
  const auto tally = [&](Verdict v) {
    switch (v) {
      case Verdict::kFound:
        ++counts.found;
        break;
      case Verdict::kWeak:
        ++counts.weak;
        break;
      case Verdict::kTooWide:
        ++counts.too_wide;
        break;
      case Verdict::kSaturated:
        ++counts.saturated;
        break;
      case Verdict::kAmbiguous:
        ++counts.ambiguous;
        break;
      case Verdict::kEdge:
        ++counts.edge;
        break;
    }
  };
  if (options_.axis == LineAxis::kColumns) {
    scan_columns(*img);
    positions.assign(static_cast<std::size_t>(img->cols), kNaN);
    const float inv_rows = 1.0f / static_cast<float>(img->rows);
    const std::ptrdiff_t stride = static_cast<std::ptrdiff_t>(img->step[0]);
    for (int c = 0; c < img->cols; ++c) {
      const auto uc = static_cast<std::size_t>(c);
      float pos = kNaN;
      const Verdict v = analyse(img->ptr<std::uint8_t>(0) + c, stride, img->rows,
                                static_cast<int>(key_[uc] >> 16), static_cast<int>(arg_[uc]),
                                static_cast<float>(sum_[uc]) * inv_rows,
                                static_cast<int>(second_[uc]), pos);
      tally(v);
      if (v == Verdict::kFound) positions[uc] = pos;
    }
    trim(positions, counts);
    return counts;
  }
  // One position per row: each row is contiguous, so the peak, sum and second peak are plain
  // reductions over it.
  positions.assign(static_cast<std::size_t>(img->rows), kNaN);
  const int n = img->cols;
  const int guard = options_.max_width_px;
  for (int r = 0; r < img->rows; ++r) {
    const std::uint8_t* __restrict p = img->ptr<std::uint8_t>(r);
    std::uint32_t peak = 0;
    std::uint32_t sum = 0;
    for (int c = 0; c < n; ++c) {
      peak = std::max<std::uint32_t>(peak, p[c]);
      sum += p[c];
    }
    const auto* first = static_cast<const std::uint8_t*>(std::memchr(p, static_cast<int>(peak), static_cast<std::size_t>(n)));
    const int arg = static_cast<int>(first - p);
    std::uint32_t second = 0;
    for (int c = 0; c < arg - guard; ++c) second = std::max<std::uint32_t>(second, p[c]);
    for (int c = arg + guard + 1; c < n; ++c) second = std::max<std::uint32_t>(second, p[c]);
    float pos = kNaN;
    const Verdict v = analyse(p, 1, n, static_cast<int>(peak), arg,
                              static_cast<float>(sum) / static_cast<float>(n),
                              static_cast<int>(second), pos);
    tally(v);
    if (v == Verdict::kFound) positions[static_cast<std::size_t>(r)] = pos;
  }
  trim(positions, counts);
  return counts;
}

void LineExtractor::trim(std::vector<float>& positions, ExtractionCounts& counts) const {
  const std::size_t k = static_cast<std::size_t>(options_.trim_ends);
  if (k == 0) return;
  const std::size_t n = positions.size();
  std::size_t i = 0;
  while (i < n) {
    if (!std::isfinite(positions[i])) {
      ++i;
      continue;
    }
    std::size_t end = i;  // one past the run
    while (end < n && std::isfinite(positions[end])) ++end;
    const std::size_t len = end - i;
    // Ends at a gap are trimmed; ends at the image's border are not.
    const std::size_t head = i > 0 ? std::min(k, len) : 0;
    const std::size_t tail = end < n ? std::min(k, len - head) : 0;
    for (std::size_t j = i; j < i + head; ++j) positions[j] = kNaN;
    for (std::size_t j = end - tail; j < end; ++j) positions[j] = kNaN;
    counts.trimmed += static_cast<int>(head + tail);
    counts.found -= static_cast<int>(head + tail);
    i = end;
  }
}

}  // namespace scanmesh::drivers::profiler
