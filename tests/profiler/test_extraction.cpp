// Laser-line extraction against rendered frames of the container part with the true line centre
// per column: clean and noisy frames, no line, saturated and doubled lines, blobs, rows.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "profiler/scene.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/profiler/extraction.hpp"

using namespace scanmesh;
using drivers::profiler::ExtractionOptions;
using drivers::profiler::LineAxis;
using drivers::profiler::LineExtractor;
using drivers::profiler::PeakMethod;

namespace {

struct Errors {
  int truth = 0;     ///< columns with a clean true centre
  int found = 0;     ///< of those, columns with a value
  int extra = 0;     ///< values where there is no clean true centre (a partly seen line)
  int garbage = 0;   ///< values off the laser's light (in a valley, on ambient light)
  double rms = 0;    ///< px, over found
  double max = 0;    ///< px
};

/// Whether the laser's own light at row `row` of column c is at least a third of its brightest
/// within 4 rows (a value on a line, perhaps a dim piece of one, not in the valley between two
/// lines nor on ambient light).
bool on_laser(const sim::LaserFrame& frame, std::size_t c, float row) {
  const int r = static_cast<int>(std::lround(row));
  const int col = static_cast<int>(c);
  if (r < 0 || r >= frame.laser.rows) return false;
  float top = 0;
  for (int i = std::max(0, r - 4); i <= std::min(frame.laser.rows - 1, r + 4); ++i)
    top = std::max(top, frame.laser.at<float>(i, col));
  return top > 0 && frame.laser.at<float>(r, col) >= top / 3;
}

Errors compare(const std::vector<float>& pos, const sim::LaserFrame& frame, std::size_t sheet = 0) {
  const std::vector<double>& truth = frame.truth[sheet];
  Errors e;
  double ss = 0;
  for (std::size_t c = 0; c < truth.size(); ++c) {
    const bool has = std::isfinite(pos[c]);
    if (has && !on_laser(frame, c, pos[c])) ++e.garbage;
    if (std::isnan(truth[c])) {
      e.extra += has;
      continue;
    }
    ++e.truth;
    if (!has) continue;
    ++e.found;
    const double d = std::abs(pos[c] - truth[c]);
    ss += d * d;
    e.max = std::max(e.max, d);
  }
  e.rms = e.found ? std::sqrt(ss / e.found) : 0;
  return e;
}

const test::PartScene& scene() {
  static const test::PartScene s;
  return s;
}

sim::LaserFrame render(const sim::FrameLook& look, std::vector<sim::LaserSheet> sheets = {test::profiler_laser()}) {
  return sim::render_laser_frame(scene().bvh, test::part_from_camera(), test::profiler_camera(),
                                 sheets, look);
}

std::size_t count_found(const std::vector<float>& pos) {
  return static_cast<std::size_t>(std::count_if(pos.begin(), pos.end(), [](float p) { return std::isfinite(p); }));
}

}  // namespace

TEST_CASE("extraction: clean frames within 0.1 px of the rendered centre", "[profiler]") {
  const sim::LaserFrame frame = render(test::clean_look());
  for (PeakMethod method : {PeakMethod::kCentreOfGravity, PeakMethod::kGaussian}) {
    ExtractionOptions o;
    o.method = method;
    o.trim_ends = 0;  // every column compared with the truth
    LineExtractor ex(o);
    std::vector<float> pos;
    const auto counts = ex.extract(frame.image, {}, pos);
    REQUIRE(pos.size() == 640);
    const Errors e = compare(pos, frame);
    INFO("method " << int(method) << ": truth " << e.truth << " found " << e.found << " extra "
                   << e.extra << " rms " << e.rms << " max " << e.max << " weak " << counts.weak
                   << " wide " << counts.too_wide << " ambiguous " << counts.ambiguous);
    CHECK(e.truth > 150);  // the line is seen whole on 189 columns of the part
    CHECK(e.found >= e.truth - 2);
    CHECK(e.max < 0.1);
    CHECK(e.rms < 0.03);
    CHECK(e.garbage == 0);  // values without a clean truth: partly seen lines at edges
  }
}

TEST_CASE("extraction: speckle, noise, uneven ambient light and blur", "[profiler]") {
  for (std::uint64_t seed : {7u, 8u, 9u}) {
    const sim::LaserFrame frame = render(test::noisy_look(seed));
    for (PeakMethod method : {PeakMethod::kCentreOfGravity, PeakMethod::kGaussian}) {
      ExtractionOptions o;
      o.method = method;
      o.trim_ends = 0;
      LineExtractor ex(o);
      std::vector<float> pos;
      ex.extract(frame.image, {}, pos);
      const Errors e = compare(pos, frame);
      INFO("seed " << seed << " method " << int(method) << ": truth " << e.truth << " found "
                   << e.found << " extra " << e.extra << " garbage " << e.garbage << " rms " << e.rms << " max " << e.max);
      CHECK(e.found >= e.truth * 0.97);
      CHECK(e.rms < 0.15);
      CHECK(e.max < 0.6);
      CHECK(e.garbage == 0);
    }
  }
}

TEST_CASE("extraction: a frame without a laser line gives an empty profile", "[profiler]") {
  for (std::uint64_t seed : {3u, 4u}) {
    const sim::LaserFrame frame = render(test::noisy_look(seed), {});
    LineExtractor ex;
    std::vector<float> pos;
    const auto counts = ex.extract(frame.image, {}, pos);
    INFO("weak " << counts.weak << " wide " << counts.too_wide << " ambiguous " << counts.ambiguous);
    CHECK(pos.size() == 640);
    CHECK(count_found(pos) == 0);
    CHECK(counts.found == 0);
  }
}

TEST_CASE("extraction: a saturated line gives its centre or nothing", "[profiler]") {
  sim::FrameLook look = test::noisy_look(11);
  const sim::LaserFrame frame = render(look, {test::profiler_laser(1500)});
  REQUIRE(cv::countNonZero(frame.image == 255) > 600);  // really saturated
  LineExtractor ex;
  std::vector<float> pos;
  ex.extract(frame.image, {}, pos);
  const Errors e = compare(pos, frame);
  INFO("truth " << e.truth << " found " << e.found << " rms " << e.rms << " max " << e.max);
  CHECK(e.found >= e.truth * 0.9);  // a flat top is symmetric: its centre is still found
  CHECK(e.max < 0.5);
  CHECK(e.garbage == 0);
}

TEST_CASE("extraction: a saturated blob gives nothing in its columns", "[profiler]") {
  sim::LaserFrame frame = render(test::clean_look());
  // A specular reflection beside the line: a saturated disc of 20 px radius, 10 px from it.
  const double row = frame.truth[0][300];
  REQUIRE(std::isfinite(row));
  cv::circle(frame.image, cv::Point(300, static_cast<int>(row) - 30), 20, cv::Scalar(255),
             cv::FILLED, cv::LINE_AA);
  LineExtractor ex;
  std::vector<float> pos;
  const auto counts = ex.extract(frame.image, {}, pos);
  for (int c = 282; c <= 318; ++c) CHECK(std::isnan(pos[static_cast<std::size_t>(c)]));
  CHECK(counts.too_wide + counts.saturated + counts.ambiguous >= 37);
  const Errors e = compare(pos, frame);
  CHECK(e.garbage == 0);
  CHECK(e.max < 0.1);
}

TEST_CASE("extraction: a doubled line gives the right peak or nothing, never one between",
          "[profiler]") {
  // A second, parallel sheet 2.5 mm away (a reflection of the laser off a shiny wall): its line
  // runs about 9 px from the first.
  for (double ratio : {0.3, 0.9, 1.0}) {
    sim::LaserSheet main = test::profiler_laser();
    sim::LaserSheet ghost = main;
    ghost.origin += ghost.normal.normalized() * 2.5;
    ghost.power = main.power * ratio;
    for (const sim::FrameLook& look : {test::clean_look(), test::noisy_look(5)}) {
      const sim::LaserFrame frame = render(look, {main, ghost});
      for (PeakMethod method : {PeakMethod::kCentreOfGravity, PeakMethod::kGaussian}) {
        ExtractionOptions o;
        o.method = method;
        o.trim_ends = 0;
        LineExtractor ex(o);
        std::vector<float> pos;
        ex.extract(frame.image, {}, pos);
        int right = 0, between = 0, found = 0, both = 0;
        for (std::size_t c = 0; c < pos.size(); ++c) {
          const double t0 = frame.truth[0][c], t1 = frame.truth[1][c];
          if (std::isnan(t0) || std::isnan(t1)) continue;
          ++both;
          if (!std::isfinite(pos[c])) continue;
          ++found;
          const double d = std::min(std::abs(pos[c] - t0), std::abs(pos[c] - t1));
          if (std::abs(pos[c] - t0) < 0.6) ++right;
          if (d > 0.6) ++between;
        }
        INFO("ratio " << ratio << " method " << int(method) << " ambient " << look.ambient
                      << ": columns with both " << both << " found " << found << " right "
                      << right << " between " << between);
        CHECK(both > 120);
        CHECK(between == 0);
        if (ratio < 0.5) CHECK(right >= both * 0.95);  // a weak ghost: the main line is kept
      }
    }
  }
}

TEST_CASE("extraction: per row on the transposed frame gives the same positions", "[profiler]") {
  const sim::LaserFrame frame = render(test::noisy_look(2));
  LineExtractor by_column;
  std::vector<float> a, b;
  by_column.extract(frame.image, {}, a);
  ExtractionOptions o;
  o.axis = LineAxis::kRows;
  LineExtractor by_row(o);
  const cv::Mat transposed = frame.image.t();
  by_row.extract(transposed, {}, b);
  REQUIRE(a.size() == b.size());
  int found = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    CHECK(std::isnan(a[i]) == std::isnan(b[i]));
    if (std::isfinite(a[i])) {
      CHECK(a[i] == b[i]);
      ++found;
    }
  }
  CHECK(found > 150);
}

TEST_CASE("extraction: a laser-off frame removes a bright background", "[profiler]") {
  // Bright, uneven ambient light, and a lamp in view above the part (brighter than the line).
  sim::FrameLook look = test::noisy_look(21);
  look.ambient = 150;
  look.speckle = 0.1;
  sim::FrameLook off = look;
  off.seed = 22;  // another frame: its own noise
  sim::LaserFrame on_frame = render(look);
  sim::LaserFrame off_frame = render(off, {});
  for (cv::Mat* img : {&on_frame.image, &off_frame.image})
    cv::rectangle(*img, cv::Rect(0, 60, 640, 50), cv::Scalar(235), cv::FILLED);
  LineExtractor ex;
  std::vector<float> plain, subtracted;
  ex.extract(on_frame.image, {}, plain);
  ex.extract(on_frame.image, off_frame.image, subtracted);
  const Errors without = compare(plain, on_frame);
  const Errors with = compare(subtracted, on_frame);
  INFO("without: found " << without.found << " of " << without.truth << " garbage "
                         << without.garbage << "; with: found " << with.found << " rms "
                         << with.rms << " max " << with.max << " garbage " << with.garbage);
  CHECK(without.found < without.truth * 0.1);
  CHECK(without.garbage == 0);
  CHECK(with.found >= with.truth * 0.97);
  CHECK(with.rms < 0.15);
  CHECK(with.max < 0.6);
  CHECK(with.garbage == 0);
}

TEST_CASE("extraction: bad options and frames are refused with the reason", "[profiler]") {
  ExtractionOptions o;
  o.edge_ratio = 0.7;
  o.second_peak_ratio = 0.5;
  o.max_width_px = 1;
  try {
    LineExtractor ex(o);
    FAIL("accepted");
  } catch (const ConfigError& e) {
    CHECK_THAT(e.what(), Catch::Contains("second_peak_ratio") && Catch::Contains("max_width_px"));
  }
  LineExtractor ex;
  std::vector<float> pos;
  CHECK_THROWS_AS(ex.extract(cv::Mat(10, 10, CV_16UC1), {}, pos), ConfigError);
  CHECK_THROWS_WITH(ex.extract(cv::Mat(10, 10, CV_8UC1), cv::Mat(10, 11, CV_8UC1), pos),
                    Catch::Contains("background"));
}

TEST_CASE("extraction: the ends of runs at gaps are trimmed, not those at the border",
          "[profiler]") {
  // A synthetic frame: a clean line (Gaussian, sigma 1.5 px) across columns 0..99, with a gap
  // at 40..49 (the line falls into a hole).
  cv::Mat img(60, 100, CV_8UC1, cv::Scalar(10));
  for (int c = 0; c < 100; ++c) {
    if (c >= 40 && c < 50) continue;
    for (int r = 0; r < 60; ++r)
      img.at<std::uint8_t>(r, c) =
          cv::saturate_cast<std::uint8_t>(10 + 150 * std::exp(-0.5 * std::pow((r - 30.3) / 1.5, 2)));
  }
  for (int k : {0, 2, 3}) {
    ExtractionOptions o;
    o.trim_ends = k;
    LineExtractor ex(o);
    std::vector<float> pos;
    const auto counts = ex.extract(img, {}, pos);
    INFO("trim_ends " << k);
    CHECK(counts.trimmed == 2 * k);
    CHECK(counts.found == 90 - 2 * k);
    CHECK(std::isfinite(pos[0]));   // the border's end is kept
    CHECK(std::isfinite(pos[99]));
    for (int c = 40 - k; c < 40; ++c) CHECK(std::isnan(pos[static_cast<std::size_t>(c)]));
    for (int c = 50; c < 50 + k; ++c) CHECK(std::isnan(pos[static_cast<std::size_t>(c)]));
    CHECK(std::isfinite(pos[static_cast<std::size_t>(39 - k)]));
    CHECK(std::abs(pos[10] - 30.3) < 0.05);
  }
}
