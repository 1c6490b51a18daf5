// Preview and deviation pictures: orthographic camera fitted to the mesh, software z-buffer
// rasterizer (2x supersampled), headlight Lambert shading, OpenCV for text and PNG encoding.
// SPDX-License-Identifier: MIT
#include "scanmesh/preview/render.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <png.h>
#include <stdexcept>
#include <string>
#include <system_error>

#include "scanmesh/common/error.hpp"

namespace scanmesh::preview {
namespace {

using recon::Mesh;
using recon::Vec3;

constexpr int kSupersample = 2;              ///< rasterize at 2x and downsample: anti-aliased edges
constexpr double kAmbient = 0.18;            ///< light reaching faces seen edge-on
constexpr int kTitleHeightPx = 44;           ///< band at the top kept free for the title
constexpr int kColourBarWidthPx = 150;       ///< band at the right kept free for the colour bar
const cv::Vec3b kBackground{255, 255, 255};  // OpenCV colours are BGR
const cv::Vec3b kAboveRange{255, 0, 255};    ///< magenta: value > +limit
const cv::Vec3b kBelowRange{96, 96, 96};     ///< dark grey: value < -limit
const cv::Vec3b kNoValue{200, 200, 200};     ///< light grey: NaN value

/// Orthographic camera: x = right . p, y = up . p, depth = forward . p (smaller is nearer).
/// Pixel (column, row) = (cx + scale * (x - x0), cy - scale * (y - y0)).
struct Camera {
  Vec3 right, up, forward;
  double x0 = 0, y0 = 0, scale = 1, cx = 0, cy = 0;

  [[nodiscard]] cv::Point2d to_pixel(const Vec3& p) const {
    return {cx + scale * (right.dot(p) - x0), cy - scale * (up.dot(p) - y0)};
  }
};

/// Camera looking along view_dir with `up` projected to the screen's vertical, fitted so the
/// projection of the mesh's referenced vertices fills the viewport with a 4 % margin.
Camera fit_camera(const Mesh& mesh, const RenderOptions& options, const cv::Rect2d& viewport) {
  Camera cam;
  Vec3 forward = options.view_dir;
  if (!(forward.norm() > 0) || !forward.allFinite()) forward = Vec3(-1, -1, -1);
  cam.forward = forward.normalized();
  Vec3 up = options.up;
  if (!up.allFinite() || up.cross(cam.forward).norm() < 1e-9 * std::max(up.norm(), 1e-300)) {
    // Up missing or along the view direction: use the world axis least aligned with the view.
    int axis = 0;
    cam.forward.cwiseAbs().minCoeff(&axis);
    up = Vec3::Unit(axis);
  }
  cam.right = cam.forward.cross(up).normalized();
  cam.up = cam.right.cross(cam.forward);

  std::vector<char> used(mesh.vertices.size(), 0);
  for (const recon::Triangle& t : mesh.triangles) {
    for (std::uint32_t v : t) {
      if (v < used.size()) used[v] = 1;
    }
  }
  double xmin = std::numeric_limits<double>::infinity(), xmax = -xmin, ymin = xmin, ymax = -xmin;
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    if (!used[v] || !mesh.vertices[v].allFinite()) continue;
    const double x = cam.right.dot(mesh.vertices[v]), y = cam.up.dot(mesh.vertices[v]);
    xmin = std::min(xmin, x);
    xmax = std::max(xmax, x);
    ymin = std::min(ymin, y);
    ymax = std::max(ymax, y);
  }
  if (!(xmax >= xmin)) xmin = xmax = ymin = ymax = 0;
  const double w = xmax - xmin, h = ymax - ymin;
  const double sx = w > 0 ? viewport.width / w : std::numeric_limits<double>::infinity();
  const double sy = h > 0 ? viewport.height / h : std::numeric_limits<double>::infinity();
  cam.scale = std::min(sx, sy);
  if (!std::isfinite(cam.scale)) cam.scale = 1;
  cam.scale *= 0.92;
  cam.x0 = 0.5 * (xmin + xmax);
  cam.y0 = 0.5 * (ymin + ymax);
  cam.cx = viewport.x + 0.5 * viewport.width;
  cam.cy = viewport.y + 0.5 * viewport.height;
  return cam;
}

/// Result of rasterization: per pixel the nearest triangle and its barycentric coordinates.
struct Raster {
  cv::Mat depth;     ///< CV_32F, +inf where empty
  cv::Mat triangle;  ///< CV_32S, -1 where empty
  cv::Mat bary;      ///< CV_32FC2, weights of corners 1 and 2 (corner 0 is 1 - both)
};

/// z-buffer rasterization over triangles with edge functions at pixel centres. Both
/// orientations are drawn (no culling); triangles degenerate on screen are skipped.
Raster rasterize(const Mesh& mesh, const Camera& cam, cv::Size size) {
  Raster r;
  r.depth.create(size, CV_32F);
  r.depth.setTo(std::numeric_limits<float>::infinity());
  r.triangle.create(size, CV_32S);
  r.triangle.setTo(-1);
  r.bary.create(size, CV_32FC2);
  r.bary.setTo(cv::Scalar(0, 0));
  const std::size_t nv = mesh.vertices.size();
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const recon::Triangle& tri = mesh.triangles[t];
    if (tri[0] >= nv || tri[1] >= nv || tri[2] >= nv) continue;
    cv::Point2d q[3];
    double z[3];
    bool finite = true;
    for (int k = 0; k < 3; ++k) {
      const Vec3& p = mesh.vertices[tri[k]];
      finite = finite && p.allFinite();
      q[k] = cam.to_pixel(p);
      z[k] = cam.forward.dot(p);
    }
    if (!finite) continue;
    const double area =
        (q[1].x - q[0].x) * (q[2].y - q[0].y) - (q[1].y - q[0].y) * (q[2].x - q[0].x);
    if (!(std::abs(area) > 1e-12)) continue;
    const double inv_area = 1.0 / area;
    const int x_lo = std::max(0, static_cast<int>(std::floor(std::min({q[0].x, q[1].x, q[2].x}))));
    const int x_hi =
        std::min(size.width - 1, static_cast<int>(std::ceil(std::max({q[0].x, q[1].x, q[2].x}))));
    const int y_lo = std::max(0, static_cast<int>(std::floor(std::min({q[0].y, q[1].y, q[2].y}))));
    const int y_hi =
        std::min(size.height - 1, static_cast<int>(std::ceil(std::max({q[0].y, q[1].y, q[2].y}))));
    for (int y = y_lo; y <= y_hi; ++y) {
      const double py = y + 0.5;
      auto* depth_row = r.depth.ptr<float>(y);
      auto* tri_row = r.triangle.ptr<std::int32_t>(y);
      auto* bary_row = r.bary.ptr<cv::Vec2f>(y);
      for (int x = x_lo; x <= x_hi; ++x) {
        const double px = x + 0.5;
        // Barycentric weights from the signed areas of the sub-triangles, normalised by the
        // triangle's own signed area, so the test is the same for either winding.
        const double l1 =
            ((q[2].x - q[0].x) * (py - q[0].y) - (q[2].y - q[0].y) * (px - q[0].x)) * -inv_area;
        const double l2 =
            ((q[1].x - q[0].x) * (py - q[0].y) - (q[1].y - q[0].y) * (px - q[0].x)) * inv_area;
        const double l0 = 1.0 - l1 - l2;
        if (l0 < 0 || l1 < 0 || l2 < 0) continue;
        const auto d = static_cast<float>(l0 * z[0] + l1 * z[1] + l2 * z[2]);
        if (d >= depth_row[x]) continue;
        depth_row[x] = d;
        tri_row[x] = static_cast<std::int32_t>(t);
        bary_row[x] = cv::Vec2f(static_cast<float>(l1), static_cast<float>(l2));
      }
    }
  }
  return r;
}

/// Per triangle: unit normal (zero when degenerate).
std::vector<Vec3> face_normals(const Mesh& mesh) {
  std::vector<Vec3> n(mesh.triangles.size(), Vec3::Zero());
  const std::size_t nv = mesh.vertices.size();
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const recon::Triangle& tri = mesh.triangles[t];
    if (tri[0] >= nv || tri[1] >= nv || tri[2] >= nv) continue;
    const Vec3 c = (mesh.vertices[tri[1]] - mesh.vertices[tri[0]])
                       .cross(mesh.vertices[tri[2]] - mesh.vertices[tri[0]]);
    const double len = c.norm();
    if (len > 0 && std::isfinite(len)) n[t] = c / len;
  }
  return n;
}

/// Headlight Lambert term of a face: both sides lit; `front` tells which side is seen.
double lambert(const Vec3& normal, const Camera& cam, bool* front) {
  const double c = -normal.dot(cam.forward);
  *front = c >= 0;
  return kAmbient + (1.0 - kAmbient) * std::abs(c);
}

cv::Vec3b scaled(const cv::Vec3b& colour, double k) {
  return cv::Vec3b(cv::saturate_cast<uchar>(colour[0] * k), cv::saturate_cast<uchar>(colour[1] * k),
                   cv::saturate_cast<uchar>(colour[2] * k));
}

/// Diverging map over t in [-1, 1]: blue, cyan, green (0), yellow, red. Out of range: the
/// distinct over/under colours.
cv::Vec3b colour_map(double t) {
  if (std::isnan(t)) return kNoValue;
  if (t > 1.0) return kAboveRange;
  if (t < -1.0) return kBelowRange;
  // Stops in RGB, converted to BGR on return.
  static constexpr double kStops[5][3] = {
      {0, 0, 255}, {0, 255, 255}, {0, 200, 0}, {255, 255, 0}, {255, 0, 0}};
  const double s = (t + 1.0) * 2.0;  // 0..4
  const int i = std::min(3, static_cast<int>(std::floor(s)));
  const double f = s - i;
  double rgb[3];
  for (int k = 0; k < 3; ++k) rgb[k] = kStops[i][k] * (1 - f) + kStops[i + 1][k] * f;
  return cv::Vec3b(cv::saturate_cast<uchar>(rgb[2]), cv::saturate_cast<uchar>(rgb[1]),
                   cv::saturate_cast<uchar>(rgb[0]));
}

void put_text(cv::Mat& img, const std::string& text, cv::Point at, double scale,
              const cv::Scalar& colour = cv::Scalar(0, 0, 0)) {
  cv::putText(img, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, colour, 1, cv::LINE_AA);
}

/// Three significant digits, with an explicit + on positive values.
std::string tick_label(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, v > 0 ? "+%.3g" : "%.3g", v);
  return buf;
}

void draw_colour_bar(cv::Mat& img, double limit) {
  const int bar_w = 24;
  const int x0 = img.cols - kColourBarWidthPx + 16;
  const int top = kTitleHeightPx + 50, bottom = img.rows - 50;
  const int box = 18;  // out-of-range swatches above and below the bar
  const int y0 = top + box + 14, y1 = bottom - box - 14;
  if (y1 - y0 < 20) return;
  put_text(img, "deviation", cv::Point(x0 - 6, top - 16), 0.5);
  for (int y = y0; y <= y1; ++y) {
    const double t = 1.0 - 2.0 * (y - y0) / static_cast<double>(y1 - y0);  // +1 at the top
    const cv::Vec3b c = colour_map(t);
    cv::line(img, cv::Point(x0, y), cv::Point(x0 + bar_w - 1, y), cv::Scalar(c[0], c[1], c[2]));
  }
  cv::rectangle(img, cv::Rect(x0, y0, bar_w, y1 - y0 + 1), cv::Scalar(0, 0, 0));
  cv::rectangle(img, cv::Rect(x0, top, bar_w, box),
                cv::Scalar(kAboveRange[0], kAboveRange[1], kAboveRange[2]), cv::FILLED);
  cv::rectangle(img, cv::Rect(x0, top, bar_w, box), cv::Scalar(0, 0, 0));
  put_text(img, "> " + tick_label(limit), cv::Point(x0 + bar_w + 6, top + box - 4), 0.42);
  cv::rectangle(img, cv::Rect(x0, bottom - box, bar_w, box),
                cv::Scalar(kBelowRange[0], kBelowRange[1], kBelowRange[2]), cv::FILLED);
  cv::rectangle(img, cv::Rect(x0, bottom - box, bar_w, box), cv::Scalar(0, 0, 0));
  put_text(img, "< " + tick_label(-limit), cv::Point(x0 + bar_w + 6, bottom - 4), 0.42);
  for (int i = 0; i <= 4; ++i) {
    const double frac = i / 4.0;
    const int y = y0 + static_cast<int>(std::lround(frac * (y1 - y0)));
    const double v = limit * (1.0 - 2.0 * frac);
    cv::line(img, cv::Point(x0 + bar_w, y), cv::Point(x0 + bar_w + 5, y), cv::Scalar(0, 0, 0));
    put_text(img, i == 2 ? std::string("0") : tick_label(v), cv::Point(x0 + bar_w + 9, y + 5),
             0.45);
  }
}

/// Encodes as PNG (libpng) and writes it under a temporary name beside the target, then renames
/// it into place, so no partial file is ever left under the final name.
void write_png(const cv::Mat& img, const std::filesystem::path& png) {
  std::vector<std::uint8_t> bytes;
  try {
    bytes = encode_png_bgr(img.ptr<std::uint8_t>(), img.cols, img.rows, img.step[0]);
  } catch (const OutputError& e) {
    throw OutputError("cannot write '" + png.string() + "': " + e.what());
  }
  std::filesystem::path tmp = png;
  tmp += ".tmp";
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (f == nullptr) {
    throw OutputError("cannot write '" + png.string() + "': " + std::strerror(errno));
  }
  const bool written = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  const int write_errno = errno;
  const bool closed = std::fclose(f) == 0;
  if (!written || !closed) {
    const int err = !written ? write_errno : errno;
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw OutputError("cannot write '" + png.string() + "': " + std::strerror(err));
  }
  std::error_code ec;
  std::filesystem::rename(tmp, png, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw OutputError("cannot write '" + png.string() + "': " + ec.message());
  }
}

/// What a pixel shows: a function of (triangle, barycentric weights, Lambert term, front side).
template <typename Shade>
cv::Mat render(const Mesh& mesh, const RenderOptions& options, bool colour_bar, Shade&& shade) {
  if (options.width_px < 16 || options.height_px < 16 || options.width_px > 16384 ||
      options.height_px > 16384) {
    throw ConfigError("render: picture size " + std::to_string(options.width_px) + "x" +
                      std::to_string(options.height_px) + " px is outside 16..16384");
  }
  const cv::Size size(options.width_px * kSupersample, options.height_px * kSupersample);
  const int top = options.title.empty() ? 8 : kTitleHeightPx;
  const int right = colour_bar ? kColourBarWidthPx : 8;
  cv::Rect2d viewport(8.0 * kSupersample, top * kSupersample,
                      (options.width_px - 8 - right) * kSupersample,
                      (options.height_px - top - 8) * kSupersample);
  viewport.width = std::max(viewport.width, 1.0);
  viewport.height = std::max(viewport.height, 1.0);
  const Camera cam = fit_camera(mesh, options, viewport);
  const Raster raster = rasterize(mesh, cam, size);
  const std::vector<Vec3> normals = face_normals(mesh);

  cv::Mat big(size, CV_8UC3, cv::Scalar(kBackground[0], kBackground[1], kBackground[2]));
  for (int y = 0; y < size.height; ++y) {
    const auto* tri_row = raster.triangle.ptr<std::int32_t>(y);
    const auto* bary_row = raster.bary.ptr<cv::Vec2f>(y);
    auto* out = big.ptr<cv::Vec3b>(y);
    for (int x = 0; x < size.width; ++x) {
      const std::int32_t t = tri_row[x];
      if (t < 0) continue;
      bool front = true;
      const double light = lambert(normals[static_cast<std::size_t>(t)], cam, &front);
      out[x] = shade(static_cast<std::size_t>(t), bary_row[x], light, front);
    }
  }
  cv::Mat img;
  cv::resize(big, img, cv::Size(options.width_px, options.height_px), 0, 0, cv::INTER_AREA);
  if (!options.title.empty()) put_text(img, options.title, cv::Point(10, 28), 0.7);
  if (mesh.triangles.empty()) {
    put_text(img, "(no triangles)", cv::Point(options.width_px / 2 - 70, options.height_px / 2),
             0.7, cv::Scalar(90, 90, 90));
  }
  return img;
}

}  // namespace

void render_mesh_png(const recon::Mesh& mesh, const std::filesystem::path& png,
                     const RenderOptions& options) {
  const cv::Vec3b front_colour{205, 205, 205};  // light grey
  const cv::Vec3b back_colour{215, 140, 95};    // BGR: bluish, so holes and flips stand out
  const cv::Vec3b filled_colour{70, 175, 240};   // BGR: amber, surface no sensor measured
  cv::Mat img =
      render(mesh, options, false, [&](std::size_t t, const cv::Vec2f&, double light, bool front) {
        if (!front) return scaled(back_colour, light);
        return scaled(t >= options.highlight_from ? filled_colour : front_colour, light);
      });
  write_png(img, png);
}

void render_deviation_png(const recon::Mesh& mesh, const std::vector<double>& vertex_values,
                          const std::filesystem::path& png, const RenderOptions& options,
                          std::optional<double> limit) {
  if (vertex_values.size() != mesh.vertices.size()) {
    throw std::invalid_argument("render_deviation_png: " + std::to_string(vertex_values.size()) +
                                " values for " + std::to_string(mesh.vertices.size()) +
                                " vertices");
  }
  double lim = limit.value_or(0.0);
  if (!(lim > 0) || !std::isfinite(lim)) {
    // Default: the 95th percentile of |value| over the vertices the triangles use, so a few
    // outliers do not wash out the picture; never zero.
    std::vector<char> used(mesh.vertices.size(), 0);
    for (const recon::Triangle& t : mesh.triangles) {
      for (std::uint32_t v : t) {
        if (v < used.size()) used[v] = 1;
      }
    }
    std::vector<double> mags;
    for (std::size_t v = 0; v < vertex_values.size(); ++v) {
      if (used[v] && std::isfinite(vertex_values[v])) mags.push_back(std::abs(vertex_values[v]));
    }
    lim = 0;
    if (!mags.empty()) {
      const auto rank =
          static_cast<std::size_t>(std::ceil(0.95 * static_cast<double>(mags.size())));
      auto nth = mags.begin() + static_cast<std::ptrdiff_t>(std::max<std::size_t>(rank, 1) - 1);
      std::nth_element(mags.begin(), nth, mags.end());
      lim = *nth;
      if (!(lim > 0)) lim = *std::max_element(mags.begin(), mags.end());
    }
    if (!(lim > 0)) lim = 1.0;  // all zero: any positive range shows them as the centre colour
  }
  cv::Mat img = render(
      mesh, options, true, [&](std::size_t t, const cv::Vec2f& bary, double light, bool front) {
        const recon::Triangle& tri = mesh.triangles[t];
        const double v = (1.0 - bary[0] - bary[1]) * vertex_values[tri[0]] +
                         bary[0] * vertex_values[tri[1]] + bary[1] * vertex_values[tri[2]];
        // Keep the shape readable under the colours; back faces darker still.
        return scaled(colour_map(v / lim), (0.45 + 0.55 * light) * (front ? 1.0 : 0.6));
      });
  draw_colour_bar(img, lim);
  write_png(img, png);
}

std::vector<std::uint8_t> encode_png_bgr(const std::uint8_t* bgr, int width, int height,
                                         std::size_t stride) {
  if (bgr == nullptr || width <= 0 || height <= 0 || stride < 3 * static_cast<std::size_t>(width) ||
      stride > static_cast<std::size_t>(std::numeric_limits<png_int_32>::max()))
    throw OutputError("PNG encoding: no picture or a bad size");
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(width);
  image.height = static_cast<png_uint_32>(height);
  image.format = PNG_FORMAT_BGR;
  image.flags = PNG_IMAGE_FLAG_FAST;  // previews: speed over the last per cent of size
  // One pass into a buffer of the worst-case size (stored blocks), then trimmed.
  std::vector<std::uint8_t> bytes(PNG_IMAGE_PNG_SIZE_MAX(image));
  png_alloc_size_t size = bytes.size();
  // row_stride counts components, which for 8-bit samples are bytes.
  if (png_image_write_to_memory(&image, bytes.data(), &size, 0, bgr,
                                static_cast<png_int_32>(stride), nullptr) == 0) {
    const std::string why = image.message;
    png_image_free(&image);
    throw OutputError("PNG encoding failed: " + why);
  }
  bytes.resize(size);
  return bytes;
}

}  // namespace scanmesh::preview
