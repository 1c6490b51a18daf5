// Preview renderer: PNGs are written atomically, decode (libpng's reader) to pictures of the
// requested size that show the mesh and the colour map; the encoder round-trips exactly; write
// failures are OutputErrors naming the file.
// SPDX-License-Identifier: MIT
#include <png.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/preview/render.hpp"

namespace {

namespace fs = std::filesystem;
using scanmesh::preview::render_deviation_png;
using scanmesh::preview::render_mesh_png;
using scanmesh::preview::RenderOptions;
using scanmesh::recon::Mesh;
using scanmesh::recon::Vec3;

/// A fresh directory under the system temp directory, removed with its contents at scope exit.
class TempDir {
 public:
  TempDir() {
    std::random_device rd;
    path_ = fs::temp_directory_path() / ("scanmesh_test_preview_" + std::to_string(rd()));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  [[nodiscard]] const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

/// Torus with its axis along +Y, outward oriented, with one quad removed (a hole).
Mesh holed_torus() {
  const std::uint32_t nu = 48, nv = 24;
  Mesh m;
  for (std::uint32_t i = 0; i < nu; ++i) {
    for (std::uint32_t j = 0; j < nv; ++j) {
      const double u = 2 * std::numbers::pi * i / nu, v = 2 * std::numbers::pi * j / nv;
      m.vertices.emplace_back((3 + std::cos(v)) * std::cos(u), std::sin(v),
                              -(3 + std::cos(v)) * std::sin(u));
    }
  }
  auto id = [&](std::uint32_t i, std::uint32_t j) { return (i % nu) * nv + (j % nv); };
  for (std::uint32_t i = 0; i < nu; ++i) {
    for (std::uint32_t j = 0; j < nv; ++j) {
      if (i == 5 && j == 3) continue;
      m.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      m.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  }
  return m;
}

std::vector<unsigned char> read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// Checks the PNG signature and that the IHDR chunk carries the expected size.
void check_png(const fs::path& p, int width, int height) {
  INFO("file " << p);
  REQUIRE(fs::is_regular_file(p));
  const std::vector<unsigned char> b = read_bytes(p);
  REQUIRE(b.size() > 33);
  const unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  CHECK(std::equal(signature, signature + 8, b.begin()));
  CHECK(std::string(b.begin() + 12, b.begin() + 16) == "IHDR");
  auto be32 = [&](std::size_t at) {
    return (std::uint32_t{b[at]} << 24) | (std::uint32_t{b[at + 1]} << 16) |
           (std::uint32_t{b[at + 2]} << 8) | std::uint32_t{b[at + 3]};
  };
  CHECK(be32(16) == static_cast<std::uint32_t>(width));
  CHECK(be32(20) == static_cast<std::uint32_t>(height));
}

struct Picture {
  int width = 0, height = 0;
  std::vector<std::uint8_t> bgr;  // rows of blue, green, red bytes, no padding
  [[nodiscard]] const std::uint8_t* at(int x, int y) const {
    return bgr.data() + 3 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                             static_cast<std::size_t>(x));
  }
};

/// Decodes PNG bytes with libpng's reader (independent of the encoder under test).
Picture decode(const std::vector<unsigned char>& bytes) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  REQUIRE(png_image_begin_read_from_memory(&image, bytes.data(), bytes.size()) != 0);
  image.format = PNG_FORMAT_BGR;
  Picture pic;
  pic.width = static_cast<int>(image.width);
  pic.height = static_cast<int>(image.height);
  pic.bgr.resize(PNG_IMAGE_SIZE(image));
  REQUIRE(png_image_finish_read(&image, nullptr, pic.bgr.data(), 0, nullptr) != 0);
  return pic;
}

/// Share of pixels that are not the white background.
double coverage(const Picture& pic) {
  std::size_t drawn = 0;
  for (int y = 0; y < pic.height; ++y)
    for (int x = 0; x < pic.width; ++x) {
      const std::uint8_t* p = pic.at(x, y);
      drawn += (p[0] != 255 || p[1] != 255 || p[2] != 255) ? 1 : 0;
    }
  return static_cast<double>(drawn) / (static_cast<double>(pic.width) * pic.height);
}

/// No temporary files left beside the target.
std::size_t files_in(const fs::path& dir) {
  std::size_t n = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    (void)entry;
    ++n;
  }
  return n;
}

}  // namespace

TEST_CASE("render_mesh_png writes a PNG of the requested size", "[preview]") {
  TempDir dir;
  const Mesh m = holed_torus();
  RenderOptions options;
  options.up = Vec3(0, 1, 0);
  options.title = "torus with a hole";
  const fs::path png = dir.path() / "torus.png";
  render_mesh_png(m, png, options);
  check_png(png, options.width_px, options.height_px);
  CHECK(files_in(dir.path()) == 1);
  {
    // The torus fills a good part of the frame in greys; the hole shows the bluish back faces.
    const Picture pic = decode(read_bytes(png));
    CHECK(pic.width == options.width_px);
    CHECK(coverage(pic) > 0.1);
    CHECK(coverage(pic) < 0.9);
    std::size_t bluish = 0;
    for (int y = 0; y < pic.height; ++y)
      for (int x = 0; x < pic.width; ++x) bluish += pic.at(x, y)[0] > pic.at(x, y)[2] + 40 ? 1 : 0;
    CHECK(bluish > 0);
  }

  // Overwriting works and other sizes are honoured.
  options.width_px = 320;
  options.height_px = 200;
  options.view_dir = Vec3(0, -1, 0);  // looking along -up: falls back to another up axis
  render_mesh_png(m, png, options);
  check_png(png, 320, 200);
  CHECK(files_in(dir.path()) == 1);
}

TEST_CASE("render_mesh_png draws the triangles from highlight_from on amber", "[preview]") {
  TempDir dir;
  const Mesh m = holed_torus();
  RenderOptions options;
  options.up = Vec3(0, 1, 0);
  // Amber: red well above blue (the grey has them equal, the back faces' blue is above red).
  auto amber_pixels = [](const Picture& pic) {
    std::size_t n = 0;
    for (int y = 0; y < pic.height; ++y)
      for (int x = 0; x < pic.width; ++x) n += pic.at(x, y)[2] > pic.at(x, y)[0] + 60 ? 1 : 0;
    return n;
  };
  const fs::path png = dir.path() / "t.png";
  render_mesh_png(m, png, options);
  const std::size_t none = amber_pixels(decode(read_bytes(png)));
  options.highlight_from = m.triangles.size() / 2;
  render_mesh_png(m, png, options);
  const Picture half = decode(read_bytes(png));
  options.highlight_from = 0;
  render_mesh_png(m, png, options);
  const Picture all = decode(read_bytes(png));
  INFO("amber pixels: none " << none << ", half " << amber_pixels(half) << ", all "
                             << amber_pixels(all) << "; drawn " << coverage(all));
  CHECK(none == 0);
  CHECK(amber_pixels(half) > 0);
  CHECK(amber_pixels(all) > amber_pixels(half));
  // All front faces amber: most of what is drawn (the back faces keep their blue).
  CHECK(static_cast<double>(amber_pixels(all)) >
        0.5 * coverage(all) * static_cast<double>(all.width * all.height));
}

TEST_CASE("render_deviation_png writes a PNG with default and explicit limits", "[preview]") {
  TempDir dir;
  const Mesh m = holed_torus();
  std::vector<double> values;
  for (const Vec3& v : m.vertices) values.push_back(0.01 * v.x() + 0.002 * v.y());
  render_deviation_png(m, values, dir.path() / "dev.png");
  check_png(dir.path() / "dev.png", 1024, 768);
  {
    // Deviations of both signs: the picture holds reddish and bluish pixels (the map's ends).
    const Picture pic = decode(read_bytes(dir.path() / "dev.png"));
    std::size_t red = 0, blue = 0;
    for (int y = 0; y < pic.height; ++y)
      for (int x = 0; x < pic.width; ++x) {
        const std::uint8_t* p = pic.at(x, y);
        red += p[2] > p[0] + 80 ? 1 : 0;
        blue += p[0] > p[2] + 80 ? 1 : 0;
      }
    CHECK(red > 1000);
    CHECK(blue > 1000);
  }
  render_deviation_png(m, values, dir.path() / "dev_limit.png", {}, 0.005);
  check_png(dir.path() / "dev_limit.png", 1024, 768);
  // All zero: the range falls back to a positive value instead of dividing by zero.
  render_deviation_png(m, std::vector<double>(m.vertices.size(), 0.0), dir.path() / "zero.png");
  check_png(dir.path() / "zero.png", 1024, 768);
  CHECK(files_in(dir.path()) == 3);
}

TEST_CASE("encode_png_bgr round-trips a picture exactly, padded rows included", "[preview]") {
  const int w = 37, h = 23;
  const std::size_t stride = 3 * w + 5;  // OpenCV rows may be padded
  std::vector<std::uint8_t> src(stride * h, 0xEE);
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < 3 * w; ++x)
      src[static_cast<std::size_t>(y) * stride + x] = static_cast<std::uint8_t>(byte(rng));
  const std::vector<std::uint8_t> bytes =
      scanmesh::preview::encode_png_bgr(src.data(), w, h, stride);
  const Picture pic = decode({bytes.begin(), bytes.end()});
  REQUIRE(pic.width == w);
  REQUIRE(pic.height == h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c)
        REQUIRE(pic.at(x, y)[c] == src[static_cast<std::size_t>(y) * stride + 3 * x + c]);
  // Bad sizes are errors, not crashes.
  using scanmesh::preview::encode_png_bgr;
  CHECK_THROWS_AS(encode_png_bgr(src.data(), 0, h, stride), scanmesh::OutputError);
  CHECK_THROWS_AS(encode_png_bgr(src.data(), w, h, 3 * w - 1), scanmesh::OutputError);
  CHECK_THROWS_AS(encode_png_bgr(nullptr, w, h, stride), scanmesh::OutputError);
}

TEST_CASE("render: empty mesh still gives a picture", "[preview]") {
  TempDir dir;
  render_mesh_png(Mesh{}, dir.path() / "empty.png");
  check_png(dir.path() / "empty.png", 1024, 768);
}

TEST_CASE("render: unwritable target is an OutputError naming the file", "[preview]") {
  TempDir dir;
  const fs::path png = dir.path() / "no_such_dir" / "out.png";
  try {
    render_mesh_png(holed_torus(), png);
    FAIL("no exception");
  } catch (const scanmesh::OutputError& e) {
    CHECK_THAT(e.what(), Catch::Contains(png.string()));
  }
  CHECK(files_in(dir.path()) == 0);
}

TEST_CASE("render: bad arguments are rejected", "[preview]") {
  TempDir dir;
  const Mesh m = holed_torus();
  CHECK_THROWS_AS(render_deviation_png(m, {1.0, 2.0}, dir.path() / "x.png"), std::invalid_argument);
  RenderOptions tiny;
  tiny.width_px = 0;
  CHECK_THROWS_AS(render_mesh_png(m, dir.path() / "x.png", tiny), scanmesh::ConfigError);
  CHECK(files_in(dir.path()) == 0);
}
