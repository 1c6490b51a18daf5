// Laser-line extraction: the sub-pixel centre of a laser line in each image column (or row) of
// an 8-bit frame, with background subtraction, an adaptive threshold and rejection of blobs and
// second peaks. One value or none per column, never a point between two peaks.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace scanmesh::drivers::profiler {

/// kColumns: the line runs across the image; one position (a row) per column.
/// kRows: the line runs down the image; one position (a column) per row.
enum class LineAxis : std::uint8_t { kColumns, kRows };

/// kCentreOfGravity: centre of gravity of the peak window above its edge level.
/// kGaussian: weighted least-squares Gaussian fit (a parabola through the logarithms, weighted
/// by the squared intensities) over the window's unsaturated pixels; the centre of gravity where
/// the fit fails (fewer than 3 usable pixels, no maximum).
enum class PeakMethod : std::uint8_t { kCentreOfGravity, kGaussian };

/// Options. Levels are grey levels of the frame after background subtraction. A column's peak
/// is its brightest pixel; its contrast is its level above the floor (the light under the line:
/// the higher of the darkest pixels within max_width_px on either side of it).
struct ExtractionOptions {
  LineAxis axis = LineAxis::kColumns;
  PeakMethod method = PeakMethod::kCentreOfGravity;
  /// Least level of a peak above the column's mean and above its floor, 1..255. Default 24.
  int min_contrast = 24;
  /// The peak window is the run of pixels above floor + edge_ratio * contrast around the peak,
  /// in (0, 1). Default 0.25.
  double edge_ratio = 0.25;
  /// A window wider than this is a blob (a reflection, a saturated spot, two lines merged), not
  /// a line: no value. 2..255. Default 16.
  int max_width_px = 16;
  /// Another peak anywhere in the column reaching this fraction of the main peak's contrast
  /// (beyond the window, or inside it behind a valley) makes the column ambiguous: no value.
  /// In (edge_ratio, 1]. Default 0.5.
  double second_peak_ratio = 0.5;
  /// Pixels at or above this level are saturated, 1..255. Default 250.
  int saturation_level = 250;
  /// A window with more saturated pixels than this is a saturated blob: no value. Default 8.
  int max_saturated_px = 8;
  /// Values dropped at each end of a run of columns with values, where a gap follows (not at
  /// the image's border): there the line falls off an edge of the surface and its last
  /// columns see part of it, or mixtures of two surfaces (up to 1.5 px off). A run no longer
  /// than twice this is dropped whole. 0..16. Default 2.
  int trim_ends = 2;

  /// Every problem with the fields, one message each (empty: valid).
  std::vector<std::string> problems() const;
  /// Throws ConfigError listing every problem at once.
  void validate() const;
};

/// Why columns got no value (the counts of one extract() call).
struct ExtractionCounts {
  int found = 0;
  int weak = 0;        ///< no peak with min_contrast
  int too_wide = 0;    ///< window wider than max_width_px, or a plateau
  int saturated = 0;   ///< more than max_saturated_px saturated pixels
  int ambiguous = 0;   ///< a second peak of second_peak_ratio or more
  int edge = 0;        ///< the light on the line's two sides differs (it lies on an edge)
  int trimmed = 0;     ///< dropped at the ends of runs (trim_ends)
};

/// A column also gets no value when the light on the line's two sides differs by more than
/// 15 % of its contrast (and 8 levels): the line lies on an edge of the surface or across a
/// change of albedo, where its centre is biased.
///
/// Extracts the line from frames of any size (up to 65535 rows/columns). Keeps its scratch
/// buffers between calls: after the first frame of a size, extract() does not allocate. Not
/// thread-safe: one extractor per thread. Cost: two passes over the frame (vectorised) plus a
/// window per column.
class LineExtractor {
 public:
  explicit LineExtractor(ExtractionOptions options = {});  ///< validates

  const ExtractionOptions& options() const { return options_; }

  /// `image`: CV_8UC1. `background`: empty, or a laser-off frame of the same size and type,
  /// subtracted with saturation first. `positions` is resized to the number of columns (rows
  /// for LineAxis::kRows) and gets the sub-pixel centre, in pixel coordinates with pixel
  /// centres at integers (OpenCV's), or NaN. Throws ConfigError for another image type.
  ExtractionCounts extract(const cv::Mat& image, const cv::Mat& background,
                           std::vector<float>& positions);

 private:
  enum class Verdict : std::uint8_t { kFound, kWeak, kTooWide, kSaturated, kAmbiguous, kEdge };
  Verdict analyse(const std::uint8_t* line, std::ptrdiff_t stride, int n, int peak, int arg,
                  float mean, int second, float& position) const;
  void scan_columns(const cv::Mat& img);
  void trim(std::vector<float>& positions, ExtractionCounts& counts) const;

  ExtractionOptions options_;
  cv::Mat diff_;
  std::vector<std::uint32_t> key_;     ///< per column: peak << 16 | (0xffff - row)
  std::vector<std::uint32_t> sum_;     ///< per column: sum of levels
  std::vector<std::uint32_t> arg_;     ///< per column: row of the peak
  std::vector<std::uint32_t> second_;  ///< per column: brightest level outside the window
};

}  // namespace scanmesh::drivers::profiler
