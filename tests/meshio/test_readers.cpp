// Reader tests: in-memory tables for every format (valid and malformed input), then the shared
// real scans when SCANMESH_DATA is set.
// SPDX-License-Identifier: MIT
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "support/data.hpp"

namespace fs = std::filesystem;
using scanmesh::InputError;
using scanmesh::recon::Mesh;
using scanmesh::recon::Triangle;
using scanmesh::recon::Vec3;
namespace meshio = scanmesh::meshio;

namespace {

/// The message of the InputError `f` throws (fails the test if it throws nothing).
template <typename F>
std::string input_error(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  FAIL("no InputError thrown");
  return {};
}

/// Binary data with an explicit byte order: every value is split into bytes by shifts, so the
/// result does not depend on the host's endianness.
class Bytes {
 public:
  explicit Bytes(bool big_endian = false) : big_(big_endian) {}
  Bytes& text(std::string_view s) {
    data_.append(s);
    return *this;
  }
  template <typename T>
  Bytes& put(T v) {
    using U = std::conditional_t<
        sizeof(T) == 1, std::uint8_t,
        std::conditional_t<sizeof(T) == 2, std::uint16_t,
                           std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint64_t>>>;
    const auto u = std::bit_cast<U>(v);
    for (std::size_t i = 0; i < sizeof(T); ++i) {
      const std::size_t shift = 8 * (big_ ? sizeof(T) - 1 - i : i);
      data_.push_back(static_cast<char>((static_cast<std::uint64_t>(u) >> shift) & 0xff));
    }
    return *this;
  }
  [[nodiscard]] const std::string& str() const { return data_; }
  [[nodiscard]] std::size_t size() const { return data_.size(); }

 private:
  bool big_;
  std::string data_;
};

/// A fresh empty directory under the system temp dir, removed at scope exit.
class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    path_ = fs::temp_directory_path() / ("scanmesh_meshio_readers_" + std::to_string(::getpid()) +
                                         "_" + std::to_string(counter++));
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  [[nodiscard]] fs::path file(const std::string& name, std::string_view content) const {
    const fs::path p = path_ / name;
    std::ofstream(p, std::ios::binary)
        .write(content.data(), static_cast<std::streamsize>(content.size()));
    return p;
  }
  [[nodiscard]] const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

bool near(const Vec3& a, const Vec3& b, double tol = 1e-12) { return (a - b).norm() <= tol; }

}  // namespace

// ------------------------------------------------------------------------------------------------
// Text points

TEST_CASE("xyz: accepted layouts", "[meshio]") {
  struct Case {
    const char* legend;
    std::string text;
    std::vector<Vec3> expected;
  };
  const std::vector<Case> cases = {
      {"spaces", "1 2 3\n4 5 6\n", {{1, 2, 3}, {4, 5, 6}}},
      {"no final newline", "1 2 3\n4 5 6", {{1, 2, 3}, {4, 5, 6}}},
      {"tabs, commas, semicolons",
       "1\t2\t3\n4,5,6\n7;8;9\n 10 , 11 ; 12 \n",
       {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}, {10, 11, 12}}},
      {"extra columns ignored", "1 2 3 0.5 255 255 255\n4 5 6 nx ny nz\n", {{1, 2, 3}, {4, 5, 6}}},
      {"comments and blank lines",
       "# x y z\n\n1 2 3 # trailing\n   \n\t#indented\n4 5 6#x\n",
       {{1, 2, 3}, {4, 5, 6}}},
      {"CRLF", "1 2 3\r\n4 5 6\r\n\r\n", {{1, 2, 3}, {4, 5, 6}}},
      {"signs and exponents", "+1e-3 -2.5E+2 .5\n-0 1. 3e0\n", {{1e-3, -250, 0.5}, {0, 1, 3}}},
      {"empty", "", {}},
      {"only comments", "# nothing\n\n# here\n", {}},
  };
  for (const Case& c : cases) {
    INFO(c.legend);
    const auto cloud = meshio::parse_xyz(c.text, "t.xyz");
    REQUIRE(cloud.points.size() == c.expected.size());
    for (std::size_t i = 0; i < c.expected.size(); ++i) CHECK(cloud.points[i] == c.expected[i]);
  }
}

TEST_CASE("xyz: malformed lines name file and line", "[meshio]") {
  std::string seventeen;
  for (int i = 0; i < 16; ++i) seventeen += "1 2 3\n";
  seventeen += "4 5\n";
  CHECK(input_error([&] { meshio::parse_xyz(seventeen, "bad.xyz"); }) ==
        "bad.xyz:17: expected 3 numbers (x y z), found 2");

  struct Case {
    const char* legend;
    std::string text;
    std::string expected;  // substring of the message
  };
  const std::vector<Case> cases = {
      {"one number", "1 2 3\n7\n", "bad.xyz:2: expected 3 numbers (x y z), found 1"},
      {"word in column 2", "1 abc 3\n", "bad.xyz:1: column 2: 'abc' is not a number"},
      {"number glued to text", "1 2 3x\n", "bad.xyz:1: column 3: '3x' is not a number"},
      {"double sign", "++1 2 3\n", "bad.xyz:1: column 1: '++1' is not a number"},
      {"hex", "0x10 1 2\n", "bad.xyz:1: column 1: '0x10' is not a number"},
      {"nan", "1 2 3\nnan 1 2\n", "bad.xyz:2: column 1: non-finite value 'nan'"},
      {"inf", "1 inf 2\n", "bad.xyz:1: column 2: non-finite value 'inf'"},
      {"-infinity", "1 2 -infinity\n", "bad.xyz:1: column 3: non-finite value"},
      {"out of range", "1e999 0 0\n", "bad.xyz:1: column 1: '1e999' is out of range"},
      {"CRLF keeps line numbers", "1 2 3\r\n1 2\r\n", "bad.xyz:2: expected 3 numbers"},
      {"empty csv fields collapse", "1,,2\n", "bad.xyz:1: expected 3 numbers (x y z), found 2"},
  };
  for (const Case& c : cases) {
    INFO(c.legend);
    const std::string msg = input_error([&] { meshio::parse_xyz(c.text, "bad.xyz"); });
    CHECK_THAT(msg, Catch::Contains(c.expected));
  }
}

TEST_CASE("read_points: dispatch by extension and file errors", "[meshio]") {
  TempDir dir;
  CHECK(meshio::read_points(dir.file("a.xyz", "1 2 3\n")).points.size() == 1);
  CHECK(meshio::read_points(dir.file("a.CSV", "1,2,3\n4,5,6\n")).points.size() == 2);
  CHECK(meshio::read_points(dir.file("a.txt", "")).points.empty());
  CHECK(meshio::read_points(dir.file("a.asc", "1 2 3\n")).points.size() == 1);
  CHECK(meshio::read_points(dir.file("a.obj", "v 1 2 3\nv 4 5 6\nf 1 2 -1\n")).points.size() == 2);
  CHECK(meshio::read_points(dir.file("a.ply",
                                     "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                                     "property float y\nproperty float z\nend_header\n1 2 3\n"))
            .points.size() == 1);
  const std::string missing = (dir.path() / "missing.xyz").string();
  CHECK_THAT(input_error([&] { meshio::read_points(missing); }),
             Catch::StartsWith("cannot read " + missing + ": No such file"));
  CHECK_THAT(input_error([&] { meshio::read_points(dir.file("a.pts", "1 2 3\n")); }),
             Catch::Contains("unknown point file extension '.pts'"));
  CHECK_THAT(input_error([&] { meshio::read_mesh(dir.file("b.xyz", "1 2 3\n")); }),
             Catch::Contains("unknown mesh file extension '.xyz'"));
  // A folder or a missing file is named as such, whatever its extension says.
  const std::string folder = (dir.path() / "scans").string();
  std::filesystem::create_directory(folder);
  CHECK(input_error([&] { meshio::read_points(folder); }) ==
        "cannot read " + folder + ": Is a directory");
  CHECK(input_error([&] { meshio::read_mesh(folder); }) ==
        "cannot read " + folder + ": Is a directory");
  const std::string typo = (dir.path() / "scan.pst").string();
  CHECK(input_error([&] { meshio::read_points(typo); }) ==
        "cannot read " + typo + ": No such file or directory");
  CHECK(input_error([&] { meshio::read_mesh(typo); }) ==
        "cannot read " + typo + ": No such file or directory");
  const std::string bad = dir.file("bad.xyz", "1 2 3\n1 2\n").string();
  CHECK(input_error([&] { meshio::read_points(bad); }) ==
        bad + ":2: expected 3 numbers (x y z), found 2");
}

TEST_CASE("read_points_and_faces: a mesh's faces when they parse, its points always", "[meshio]") {
  TempDir dir;
  const auto mesh =
      meshio::read_points_and_faces(dir.file("m.OBJ", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"));
  CHECK(mesh.vertices.size() == 3);
  CHECK(mesh.triangles.size() == 1);
  // A face naming a missing vertex: read_mesh refuses the file, the points are still read.
  const auto bad_face = dir.file("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
  CHECK_THAT(input_error([&] { meshio::read_mesh(bad_face); }), Catch::Contains("out of range"));
  const auto points = meshio::read_points_and_faces(bad_face);
  CHECK(points.vertices.size() == 3);
  CHECK(points.triangles.empty());
  CHECK(meshio::read_points_and_faces(dir.file("p.xyz", "1 2 3\n4 5 6\n")).vertices.size() == 2);
  CHECK(meshio::read_points_and_faces(dir.file("p.xyz", "1 2 3\n4 5 6\n")).triangles.empty());
  // Faults in the points themselves are still named.
  const std::string bad = dir.file("bad.ply",
                                   "ply\nformat ascii 1.0\nelement vertex 2\n"
                                   "property float x\nproperty float y\n"
                                   "property float z\nend_header\n1 2 3\n")
                              .string();
  CHECK_THROWS_AS(meshio::read_points_and_faces(bad), scanmesh::InputError);
}

// ------------------------------------------------------------------------------------------------
// PLY

namespace {

const char* const kAsciiHeaderXyz =
    "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
    "property float z\n";

/// A binary PLY with 4 vertices carrying extra properties (double x, a list in the middle, uchar
/// colours), one quad face with an extra flags property, a range_grid element and tristrips.
std::string binary_ply(bool big) {
  Bytes b(big);
  b.text("ply\n")
      .text(big ? "format binary_big_endian 1.0\n" : "format binary_little_endian 1.0\n")
      .text("comment made by the test\nobj_info some scanner info\n")
      .text("element vertex 4\n")
      .text("property double x\nproperty float confidence\nproperty float32 y\n")
      .text("property list uint8 int16 something\nproperty int16 z\n")
      .text("property uchar red\nproperty uchar green\nproperty uchar blue\n")
      .text("element range_grid 3\nproperty list uchar int vertex_indices\n")
      .text("element face 1\nproperty uint flags\nproperty list uchar uint32 vertex_indices\n")
      .text("element tristrips 1\nproperty list int int vertex_indices\n")
      .text("end_header\n");
  const double xs[4] = {0.5, 1.5, 2.5, -3.25};
  const float ys[4] = {10.f, 11.f, 12.f, 13.f};
  const std::int16_t zs[4] = {-1, 0, 1, 300};
  for (int i = 0; i < 4; ++i) {
    b.put(xs[i]).put(0.75f).put(ys[i]);
    b.put(std::uint8_t(i % 3));
    for (int k = 0; k < i % 3; ++k) b.put(std::int16_t(1000 + k));
    b.put(zs[i]).put(std::uint8_t(255)).put(std::uint8_t(0)).put(std::uint8_t(7));
  }
  // range_grid: 1 entry with one index, 1 empty entry, 1 with one index
  b.put(std::uint8_t(1)).put(std::int32_t(0));
  b.put(std::uint8_t(0));
  b.put(std::uint8_t(1)).put(std::int32_t(3));
  // face: flags, quad 0 1 2 3
  b.put(std::uint32_t(0xdeadbeef)).put(std::uint8_t(4));
  for (std::uint32_t v : {0u, 1u, 2u, 3u}) b.put(v);
  // tristrips: 3 2 1 0 -1 0 1 2
  const std::int32_t strip[] = {3, 2, 1, 0, -1, 0, 1, 2};
  b.put(std::int32_t(8));
  for (std::int32_t v : strip) b.put(v);
  return b.str();
}

void check_binary_ply_mesh(const Mesh& m) {
  REQUIRE(m.vertices.size() == 4);
  CHECK(m.vertices[0] == Vec3(0.5, 10, -1));
  CHECK(m.vertices[1] == Vec3(1.5, 11, 0));
  CHECK(m.vertices[2] == Vec3(2.5, 12, 1));
  CHECK(m.vertices[3] == Vec3(-3.25, 13, 300));
  const std::vector<Triangle> expected = {
      {0, 1, 2}, {0, 2, 3},  // quad fan
      {3, 2, 1}, {1, 2, 0},  // strip 3 2 1 0 (second triangle flipped)
      {0, 1, 2},             // after the restart
  };
  CHECK(m.triangles == expected);
}

}  // namespace

TEST_CASE("ply: ascii with extra properties, range_grid, polygons and tristrips", "[meshio]") {
  const std::string text =
      "ply\nformat ascii 1.0\ncomment hello\nobj_info num_cols 2\n"
      "element vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
      "property float confidence\nproperty list uchar float extra\nproperty uchar red\n"
      "element range_grid 4\nproperty list uchar int vertex_indices\n"
      "element face 2\nproperty list uchar int vertex_indices\nproperty int flags\n"
      "element tristrips 1\nproperty list int int vertex_indices\n"
      "end_header\n"
      "0 0 0 0.5 2 1.0 2.0 255 \n"
      "1 0 0 0.5 0 255\n"
      "1 1 0 0.5 1 7 255\n"
      "0 1 0.25 0.5 0 255\n"
      "1 0\n0\n1 3\n0\n"
      "4 0 1 2 3 17\n"
      "3 3 2 1 0\n"
      "9 0 1 2 3 -1 0 0 1 2\n";
  const Mesh m = meshio::parse_ply(text, "t.ply");
  REQUIRE(m.vertices.size() == 4);
  CHECK(m.vertices[3] == Vec3(0, 1, 0.25));
  // faces: quad fan (0 1 2) (0 2 3), triangle (3 2 1); strip 0 1 2 3 -> (0 1 2), (2 1 3) swapped
  // at the odd position; strip 0 0 1 2 -> (0 0 1) dropped as degenerate, (0 1 2) at an odd
  // position -> (1 0 2).
  const std::vector<Triangle> expected = {{0, 1, 2}, {0, 2, 3}, {3, 2, 1},
                                          {0, 1, 2}, {2, 1, 3}, {1, 0, 2}};
  CHECK(m.triangles == expected);
}

TEST_CASE("ply: face element with vertex_index and CRLF header", "[meshio]") {
  std::string text =
      "ply\r\nformat ascii 1.0\r\nelement vertex 3\r\nproperty double x\r\nproperty double y\r\n"
      "property double z\r\nelement face 1\r\nproperty list ushort uint vertex_index\r\n"
      "end_header\r\n0 0 0\r\n1 0 0\r\n0 1 0\r\n3 0 1 2\r\n";
  const Mesh m = meshio::parse_ply(text, "crlf.ply");
  CHECK(m.vertices.size() == 3);
  CHECK(m.triangles == std::vector<Triangle>{{0, 1, 2}});
}

TEST_CASE("ply: binary little and big endian give the same mesh", "[meshio]") {
  for (const bool big : {false, true}) {
    INFO((big ? "big endian" : "little endian"));
    check_binary_ply_mesh(meshio::parse_ply(binary_ply(big), "b.ply"));
  }
  CHECK(binary_ply(false) != binary_ply(true));
}

TEST_CASE("ply: every scalar type name is accepted for coordinates", "[meshio]") {
  const std::vector<std::pair<const char*, int>> types = {
      {"char", 1},   {"int8", 1},    {"uchar", 1},  {"uint8", 1},  {"short", 2}, {"int16", 2},
      {"ushort", 2}, {"uint16", 2},  {"int", 4},    {"int32", 4},  {"uint", 4},  {"uint32", 4},
      {"float", 4},  {"float32", 4}, {"double", 8}, {"float64", 8}};
  for (const auto& [type, size] : types) {
    INFO(type);
    Bytes b;
    b.text("ply\nformat binary_little_endian 1.0\nelement vertex 1\n");
    for (const char* axis : {"x", "y", "z"}) {
      b.text("property ").text(type).text(" ").text(axis).text("\n");
    }
    b.text("end_header\n");
    const std::string t = type;
    for (int v : {1, 2, 3}) {
      if (t == "float" || t == "float32") {
        b.put(static_cast<float>(v));
      } else if (t == "double" || t == "float64") {
        b.put(static_cast<double>(v));
      } else if (size == 1) {
        b.put(static_cast<std::uint8_t>(v));
      } else if (size == 2) {
        b.put(static_cast<std::uint16_t>(v));
      } else {
        b.put(static_cast<std::uint32_t>(v));
      }
    }
    const Mesh m = meshio::parse_ply(b.str(), "types.ply");
    REQUIRE(m.vertices.size() == 1);
    CHECK(m.vertices[0] == Vec3(1, 2, 3));
  }
}

TEST_CASE("ply: malformed headers and ascii bodies", "[meshio]") {
  const std::string three = std::string(kAsciiHeaderXyz);
  struct Case {
    const char* legend;
    std::string text;
    std::string expected;
  };
  const std::vector<Case> cases = {
      {"not a ply", "plx\nformat ascii 1.0\n", "bad.ply:1: not a PLY file"},
      {"empty", "", "bad.ply:1: not a PLY file"},
      {"no end_header", "ply\nformat ascii 1.0\nelement vertex 0\n",
       "header has no 'end_header' line"},
      {"no format", "ply\nelement vertex 0\nend_header\n", "bad.ply:3: header has no 'format'"},
      {"unknown format", "ply\nformat binary_middle_endian 1.0\nend_header\n",
       "bad.ply:2: unknown PLY format 'binary_middle_endian'"},
      {"unknown type", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\n",
       "bad.ply:4: unknown property type 'float128'"},
      {"property first", "ply\nformat ascii 1.0\nproperty float x\n",
       "bad.ply:3: property before any element"},
      {"negative count", "ply\nformat ascii 1.0\nelement vertex -1\n",
       "bad.ply:3: expected 'element NAME COUNT'"},
      {"float list count",
       "ply\nformat ascii 1.0\nelement face 1\nproperty list float int vertex_indices\n",
       "bad.ply:4: list count type must be an integer type"},
      {"float indices",
       "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
       "property float z\nelement face 1\nproperty list uchar float vertex_indices\nend_header\n",
       "bad.ply:7: vertex_indices must be a list of an integer type"},
      {"vertex without z",
       "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n"
       "1 2\n",
       "bad.ply:3: vertex element has no x, y and z properties"},
      {"face without indices",
       "ply\nformat ascii 1.0\nelement face 1\nproperty int flags\nend_header\n1\n",
       "bad.ply:3: element 'face' has no vertex_indices property"},
      {"too few vertex lines", three + "end_header\n0 0 0\n1 0 0\n0 1 0\n",
       "unexpected end of file: element 'vertex' declares 4 entries, found 3"},
      {"too few values", three + "end_header\n0 0 0\n1 0\n0 1 0\n1 1 1\n",
       "bad.ply:9: too few values in vertex"},
      {"extra values", three + "end_header\n0 0 0\n1 0 0 9\n0 1 0\n1 1 1\n",
       "bad.ply:9: more values than declared in vertex"},
      {"bad number", three + "end_header\n0 0 0\n1 x 0\n0 1 0\n1 1 1\n",
       "bad.ply:9: vertex: 'x' is not a number"},
      {"nan", three + "end_header\n0 0 0\n1 nan 0\n0 1 0\n1 1 1\n",
       "bad.ply:9: vertex: non-finite value 'nan'"},
      {"absurd vertex count",
       "ply\nformat ascii 1.0\nelement vertex 999999999\nproperty float x\nproperty float y\n"
       "property float z\nend_header\n0 0 0\n",
       "bad.ply:8: element 'vertex' declares 999999999 entries, more than the rest of the file "
       "can hold"},
      {"more than 2^32 vertices",
       "ply\nformat ascii 1.0\nelement vertex 999999999999\nproperty float x\nproperty float y\n"
       "property float z\nend_header\n0 0 0\n",
       "bad.ply:3: more than 2^32-1 vertices are not supported"},
      {"count beyond int64", "ply\nformat ascii 1.0\nelement vertex 99999999999999999999999\n",
       "bad.ply:3: expected 'element NAME COUNT'"},
      {"index out of range",
       three + "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
               "0 0 0\n1 0 0\n0 1 0\n1 1 1\n3 0 1 4\n",
       "bad.ply:14: vertex index 4 out of range (4 vertices)"},
      {"negative index",
       three + "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
               "0 0 0\n1 0 0\n0 1 0\n1 1 1\n3 0 -1 2\n",
       "bad.ply:14: vertex index -1 out of range"},
      {"strip index -2",
       three + "element tristrips 1\nproperty list int int vertex_indices\nend_header\n"
               "0 0 0\n1 0 0\n0 1 0\n1 1 1\n4 0 1 -2 3\n",
       "bad.ply:14: vertex index -2 out of range"},
      {"huge list count",
       three + "element face 1\nproperty list uint int vertex_indices\nend_header\n"
               "0 0 0\n1 0 0\n0 1 0\n1 1 1\n4000000000 0 1 2\n",
       "bad.ply:14: list length 4000000000 in face is larger than the rest of the file"},
      {"face list too short",
       three + "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
               "0 0 0\n1 0 0\n0 1 0\n1 1 1\n4 0 1 2\n",
       "bad.ply:14: too few values in face"},
      {"data after last element", three + "end_header\n0 0 0\n1 0 0\n0 1 0\n1 1 1\n2 2 2\n",
       "bad.ply:12: data after the last element"},
  };
  for (const Case& c : cases) {
    INFO(c.legend);
    const std::string msg = input_error([&] { meshio::parse_ply(c.text, "bad.ply"); });
    CHECK_THAT(msg, Catch::Contains(c.expected));
  }
}

TEST_CASE("ply: malformed binary bodies report byte offsets", "[meshio]") {
  const std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n"
      "property float y\nproperty float z\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n";
  const std::size_t h = header.size();
  auto vertices = [&] {
    Bytes b;
    b.text(header);
    for (float v : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f}) b.put(v);
    return b;
  };

  SECTION("vertex data cut short") {
    Bytes b;
    b.text(header).put(1.f).put(2.f).put(3.f).put(4.f);
    CHECK(input_error([&] { meshio::parse_ply(b.str(), "b.ply"); }) ==
          "b.ply: byte " + std::to_string(h) +
              ": truncated vertex data (2 entries need at least 12 bytes each, 16 bytes left)");
  }
  SECTION("face list cut short") {
    Bytes b = vertices();
    b.put(std::uint8_t(3)).put(std::int32_t(0)).put(std::int32_t(1));
    CHECK_THAT(input_error([&] { meshio::parse_ply(b.str(), "b.ply"); }),
               Catch::StartsWith("b.ply: byte " + std::to_string(h + 24) +
                                 ": truncated face data (list of 3 items"));
  }
  SECTION("face missing entirely") {
    CHECK_THAT(
        input_error([&] { meshio::parse_ply(vertices().str(), "b.ply"); }),
        Catch::StartsWith("b.ply: byte " + std::to_string(h + 24) + ": truncated face data"));
  }
  SECTION("index out of range") {
    Bytes b = vertices();
    b.put(std::uint8_t(3)).put(std::int32_t(0)).put(std::int32_t(1)).put(std::int32_t(2));
    CHECK(input_error([&] { meshio::parse_ply(b.str(), "b.ply"); }) ==
          "b.ply: byte " + std::to_string(h + 24 + 1 + 8) +
              ": face 0: vertex index 2 out of range (2 vertices)");
  }
  SECTION("nan coordinate") {
    Bytes b;
    b.text(header).put(0.f).put(std::nanf("")).put(0.f).put(0.f).put(0.f).put(0.f);
    CHECK(input_error([&] { meshio::parse_ply(b.str(), "b.ply"); }) ==
          "b.ply: byte " + std::to_string(h) + ": vertex 0 has a non-finite coordinate");
  }
  SECTION("absurd counts never allocate") {
    const std::string absurd =
        "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\n"
        "property float y\nproperty float z\nend_header\n" +
        std::string(64, '\0');
    CHECK_THAT(input_error([&] { meshio::parse_ply(absurd, "b.ply"); }),
               Catch::Contains("truncated vertex data (4000000000 entries"));
    const std::string skipped =
        "ply\nformat binary_big_endian 1.0\nelement junk 9223372036854775807\n"
        "property list uint uchar stuff\nend_header\n\xff\xff\xff\xff";
    CHECK_THAT(input_error([&] { meshio::parse_ply(skipped, "b.ply"); }),
               Catch::Contains("truncated junk data"));
  }
  SECTION("range_grid with a huge list length") {
    Bytes b;
    b.text(
        "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n"
        "property float y\nproperty float z\nelement range_grid 2\n"
        "property list uchar int vertex_indices\nend_header\n");
    b.put(0.f).put(0.f).put(0.f).put(std::uint8_t(1)).put(std::int32_t(0)).put(std::uint8_t(200));
    CHECK_THAT(input_error([&] { meshio::parse_ply(b.str(), "b.ply"); }),
               Catch::Contains("truncated range_grid data (list of 200 items"));
  }
  SECTION("elements without properties take no bytes") {
    Bytes b;
    b.text(
        "ply\nformat binary_little_endian 1.0\nelement nothing 9000000000000000000\n"
        "element vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n");
    b.put(1.f).put(2.f).put(3.f);
    CHECK(meshio::parse_ply(b.str(), "b.ply").vertices.size() == 1);
  }
}

// ------------------------------------------------------------------------------------------------
// STL

namespace {

/// Binary STL: `header` (padded to 80 bytes), then triangles given by their corners.
std::string binary_stl(const std::vector<std::array<Vec3, 3>>& tris, std::string header = "test",
                       std::uint32_t declared = UINT32_MAX) {
  header.resize(80, ' ');
  Bytes b;
  b.text(header).put(declared == UINT32_MAX ? static_cast<std::uint32_t>(tris.size()) : declared);
  for (const auto& t : tris) {
    for (int k = 0; k < 3; ++k) b.put(0.f);
    for (const Vec3& c : t) {
      for (int k = 0; k < 3; ++k) b.put(static_cast<float>(c[k]));
    }
    b.put(std::uint16_t(0));
  }
  return b.str();
}

const std::vector<std::array<Vec3, 3>> kTwoTriangles = {
    std::array<Vec3, 3>{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0)},
    std::array<Vec3, 3>{Vec3(0, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0.5)}};

void check_two_triangles(const Mesh& m) {
  REQUIRE(m.vertices.size() == 4);
  CHECK(m.triangles == std::vector<Triangle>{{0, 1, 2}, {0, 2, 3}});
  CHECK(m.vertices[3] == Vec3(0, 1, 0.5));
}

}  // namespace

TEST_CASE("stl: binary and ascii merge coincident corners", "[meshio]") {
  SECTION("binary") { check_two_triangles(meshio::parse_stl(binary_stl(kTwoTriangles), "b.stl")); }
  SECTION("binary whose header starts with 'solid'") {
    check_two_triangles(meshio::parse_stl(binary_stl(kTwoTriangles, "solid but binary"), "b.stl"));
  }
  SECTION("-0 and +0 are the same corner") {
    auto tris = kTwoTriangles;
    tris[1][0] = Vec3(-0.0, 0, -0.0);
    check_two_triangles(meshio::parse_stl(binary_stl(tris), "b.stl"));
  }
  SECTION("ascii, CRLF, upper case, two solids") {
    const std::string text =
        "solid one\r\n"
        "  facet normal 0 0 1\r\n    outer loop\r\n      vertex 0 0 0\r\n      vertex 1 0 0\r\n"
        "      vertex 1 1 0\r\n    endloop\r\n  endfacet\r\nendsolid one\r\n"
        "SOLID two\r\n"
        "  FACET NORMAL 0 0 1\r\n    OUTER LOOP\r\n      VERTEX 0 0 0\r\n      VERTEX 1 1 0\r\n"
        "      VERTEX 0 1 0.5\r\n    ENDLOOP\r\n  ENDFACET\r\nENDSOLID two\r\n";
    check_two_triangles(meshio::parse_stl(text, "a.stl"));
  }
  SECTION("ascii empty solid") {
    const Mesh m = meshio::parse_stl("solid empty\nendsolid empty\n", "a.stl");
    CHECK(m.vertices.empty());
    CHECK(m.triangles.empty());
  }
  SECTION("binary with no triangles") {
    CHECK(meshio::parse_stl(binary_stl({}), "b.stl").triangles.empty());
  }
}

TEST_CASE("stl: malformed input", "[meshio]") {
  const std::string facet_start = "solid s\nfacet normal 0 0 1\nouter loop\n";
  struct Case {
    const char* legend;
    std::string bytes;
    std::string expected;
  };
  std::string truncated = binary_stl(kTwoTriangles);
  truncated.pop_back();
  std::string nan_stl = binary_stl(kTwoTriangles);
  const float nan = std::nanf("");
  std::memcpy(nan_stl.data() + 84 + 50 + 12 + 12 + 4, &nan, 4);  // 2nd facet, 2nd corner, y
  const std::vector<Case> cases = {
      {"truncated binary", truncated,
       "s.stl: byte 80: binary STL declares 2 triangles (184 bytes) but the file has 183 bytes"},
      {"count too large", binary_stl(kTwoTriangles, "x", 1000000), "declares 1000000 triangles"},
      {"solid header but binary bytes",
       [] {
         std::string s = binary_stl(kTwoTriangles, "solid x");
         s.push_back('\0');
         return s;
       }(),
       "s.stl: byte 80: binary STL declares 2 triangles"},
      {"too short", "abc", "s.stl: not an STL file (3 bytes"},
      {"empty", "", "s.stl: not an STL file (0 bytes"},
      {"nan in binary", nan_stl, "s.stl: byte 158: facet 1 has a non-finite coordinate"},
      {"missing endloop", facet_start + "vertex 0 0 0\nvertex 1 0 0\nvertex 1 1 0\n",
       "s.stl:6: unexpected end of file inside a facet"},
      {"bad number", facet_start + "vertex 0 x 0\n", "s.stl:4: 'x' is not a number"},
      {"two coordinates", facet_start + "vertex 0 0\n",
       "s.stl:4: expected 3 numbers after 'vertex', found 2"},
      {"two corners", facet_start + "vertex 0 0 0\nvertex 1 0 0\nendloop\n",
       "s.stl:6: facet has 2 vertices, expected 3"},
      {"garbage keyword", facet_start + "vertex 0 0 0\nvortex 1 0 0\n",
       "s.stl:5: expected 'vertex' or 'endloop', found 'vortex'"},
      {"no outer loop", "solid s\nfacet normal 0 0 1\nvertex 0 0 0\n",
       "s.stl:3: expected 'outer loop', found 'vertex'"},
      {"inf", facet_start + "vertex 0 inf 0\n", "s.stl:4: non-finite value 'inf'"},
  };
  for (const Case& c : cases) {
    INFO(c.legend);
    CHECK_THAT(input_error([&] { meshio::parse_stl(c.bytes, "s.stl"); }),
               Catch::Contains(c.expected));
  }
}

// ------------------------------------------------------------------------------------------------
// OBJ

TEST_CASE("obj: vertex and face forms", "[meshio]") {
  const std::string text =
      "# comment\nmtllib x.mtl\no thing\n"
      "v 0 0 0\nv 1 0 0 1.0\nv 1 1 0 0.5 0.5 0.5\nv 0 1 0\r\n"
      "vt 0 0\nvn 0 0 1\ng group\nusemtl m\ns off\n"
      "f 1 2 3\n"
      "f 1/1 3/1 4/1\n"
      "f 1//1 2//1 3//1\n"
      "f 1/1/1 2/1/1 3/1/1 4/1/1\n"
      "f -4 -3 -2 # relative\r\n"
      "l 1 2\n";
  const Mesh m = meshio::parse_obj(text, "t.obj");
  REQUIRE(m.vertices.size() == 4);
  CHECK(m.vertices[2] == Vec3(1, 1, 0));
  const std::vector<Triangle> expected = {{0, 1, 2}, {0, 2, 3}, {0, 1, 2},
                                          {0, 1, 2}, {0, 2, 3}, {0, 1, 2}};
  CHECK(m.triangles == expected);
}

TEST_CASE("obj: faces may refer to vertices defined later", "[meshio]") {
  const Mesh m = meshio::parse_obj("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n", "t.obj");
  CHECK(m.triangles == std::vector<Triangle>{{0, 1, 2}});
}

TEST_CASE("obj: malformed input", "[meshio]") {
  const std::string verts = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  struct Case {
    const char* legend;
    std::string text;
    std::string expected;
  };
  const std::vector<Case> cases = {
      {"index 0", verts + "f 0 1 2\n", "o.obj:4: vertex index 0 (OBJ indices start at 1)"},
      {"index too large", verts + "f 1 2 3\nf 1 2 4\nf 1 2 3\n",
       "o.obj:5: vertex index 4 out of range (3 vertices)"},
      {"relative too far", verts + "f -1 -2 -4\n",
       "o.obj:4: relative vertex index -4 reaches before the first vertex (3 defined so far)"},
      {"word", verts + "f 1 a 2\n", "o.obj:4: bad face vertex 'a'"},
      {"slash only", verts + "f 1 /2 3\n", "o.obj:4: bad face vertex '/2'"},
      {"two corners", verts + "f 1 2\n", "o.obj:4: face needs at least 3 vertices, found 2"},
      {"short vertex", "v 1 2\n", "o.obj:1: expected 3 numbers (x y z) after 'v', found 2"},
      {"bad vertex", "v 1 2 zz\n", "o.obj:1: 'zz' is not a number"},
      {"nan vertex", "v 1 nan 2\n", "o.obj:1: non-finite value 'nan'"},
      {"CRLF line numbers", "v 0 0 0\r\nv 1 0 0\r\nf 1 2 9\r\n", "o.obj:3: vertex index 9"},
  };
  for (const Case& c : cases) {
    INFO(c.legend);
    CHECK_THAT(input_error([&] { meshio::parse_obj(c.text, "o.obj"); }),
               Catch::Contains(c.expected));
  }
}

// ------------------------------------------------------------------------------------------------
// scanalyze .conf

TEST_CASE("conf: entries and the world transform", "[meshio]") {
  const std::string text =
      "camera 1 2 3 0 0 0 1\n\n"
      "bmesh a.ply 0 0 0 0 0 0 1\n"
      "bmesh /abs/b.ply 1 2 3 0 0 0.70710678118654752 0.70710678118654752\n"
      "bmesh c.ply 0 0 0 0 0 0 2\n";
  const auto entries = meshio::parse_conf(text, "t.conf", "/data/scans");
  REQUIRE(entries.size() == 3);
  CHECK(entries[0].file == fs::path("/data/scans/a.ply"));
  CHECK(entries[1].file == fs::path("/abs/b.ply"));
  CHECK(entries[0].to_world(Vec3(1, 2, 3)) == Vec3(1, 2, 3));
  // q = 90 degrees about z: R maps x to y, so R^T maps x to -y; then + t.
  CHECK(near(entries[1].to_world(Vec3(1, 0, 0)), Vec3(1, 1, 3), 1e-12));
  CHECK(near(entries[1].to_world(Vec3(0, 1, 0)), Vec3(2, 2, 3), 1e-12));
  // the quaternion is normalised before use
  CHECK(near(entries[2].to_world(Vec3(1, 2, 3)), Vec3(1, 2, 3), 1e-12));
  CHECK(entries[1].quaternion == Eigen::Vector4d(0, 0, 0.70710678118654752, 0.70710678118654752));
}

TEST_CASE("conf: malformed lines", "[meshio]") {
  struct Case {
    const char* legend;
    std::string text;
    std::string expected;
  };
  const std::vector<Case> cases = {
      {"unknown", "camera 0\nscan a.ply\n", "c.conf:2: unknown statement 'scan'"},
      {"no file", "bmesh\n", "c.conf:1: expected 'bmesh FILE tx ty tz qx qy qz qw'"},
      {"too few numbers", "bmesh a.ply 0 0 0 0 0 1\n",
       "c.conf:1: expected 7 numbers (tx ty tz qx qy qz qw) after the file name, found 6"},
      {"bad number", "bmesh a.ply 0 0 x 0 0 0 1\n", "c.conf:1: 'x' is not a number"},
      {"zero quaternion", "\nbmesh a.ply 0 0 0 0 0 0 0\n",
       "c.conf:2: rotation quaternion has zero length"},
  };
  for (const Case& c : cases) {
    INFO(c.legend);
    CHECK_THAT(input_error([&] { meshio::parse_conf(c.text, "c.conf", "."); }),
               Catch::Contains(c.expected));
  }
}

// ------------------------------------------------------------------------------------------------
// Real scans (SCANMESH_DATA)

TEST_CASE("real: Stanford bunny scans and zipper reconstruction", "[meshio]") {
  const auto bun000 = scanmesh::test::shared_file("bunny/data/bun000.ply");
  if (!bun000) return;
  const Mesh scan = meshio::read_mesh(*bun000);
  CHECK(scan.vertices.size() == 40256);
  CHECK(scan.triangles.empty());
  CHECK(meshio::read_points(*bun000).points.size() == 40256);

  const auto zipper_file = scanmesh::test::shared_file("bunny/reconstruction/bun_zipper.ply");
  const Mesh zipper = meshio::read_mesh(*zipper_file);
  CHECK(zipper.vertices.size() == 35947);
  CHECK(zipper.triangles.size() == 69451);
  // The .xyz copy has the same digits as the ascii PLY, so the parsed values are identical.
  const auto xyz = meshio::read_points(
      *scanmesh::test::shared_file("bunny/reconstruction/bun_zipper_vertices.xyz"));
  CHECK(xyz.points == zipper.vertices);

  const Mesh res4 =
      meshio::read_mesh(*scanmesh::test::shared_file("bunny/reconstruction/bun_zipper_res4.ply"));
  CHECK(res4.vertices.size() == 453);
  CHECK(res4.triangles.size() == 948);
}

TEST_CASE("real: Igea tristrips", "[meshio]") {
  const auto igea = scanmesh::test::shared_file("igea/igea.ply");
  if (!igea) return;
  const Mesh m = meshio::read_mesh(*igea);
  CHECK(m.vertices.size() == 134345);
  CHECK(m.triangles.size() == 268686);
  const auto xyz = meshio::read_points(*scanmesh::test::shared_file("igea/igea_vertices.xyz"));
  REQUIRE(xyz.points.size() == m.vertices.size());
  // %.9g round-trips float32: the text values convert back to exactly the binary floats.
  bool same = true;
  for (std::size_t i = 0; i < m.vertices.size() && same; ++i) {
    for (int k = 0; k < 3; ++k) {
      same = same && static_cast<float>(xyz.points[i][k]) == static_cast<float>(m.vertices[i][k]);
    }
  }
  CHECK(same);
  // Closed manifold: every undirected edge is used exactly twice, once in each direction.
  std::vector<std::uint64_t> directed;
  directed.reserve(3 * m.triangles.size());
  for (const Triangle& t : m.triangles) {
    for (int k = 0; k < 3; ++k) {
      directed.push_back(std::uint64_t{t[k]} << 32 | t[(k + 1) % 3]);
    }
  }
  std::sort(directed.begin(), directed.end());
  CHECK(std::adjacent_find(directed.begin(), directed.end()) == directed.end());
  std::size_t unmatched = 0;
  for (const std::uint64_t e : directed) {
    const std::uint64_t rev = (e << 32) | (e >> 32);
    if (!std::binary_search(directed.begin(), directed.end(), rev)) ++unmatched;
  }
  CHECK(unmatched == 0);
}

TEST_CASE("real: OBJ test models", "[meshio]") {
  const auto fandisk = scanmesh::test::shared_file("fandisk/fandisk.obj");
  if (!fandisk) return;
  struct Case {
    const char* obj;
    const char* xyz;
    std::size_t vertices;
    std::size_t triangles;
  };
  for (const Case& c : {Case{"fandisk/fandisk.obj", "fandisk/fandisk_vertices.xyz", 6475, 12946},
                        Case{"casting/casting.obj", "casting/casting_vertices.xyz", 5096, 10224}}) {
    INFO(c.obj);
    const Mesh m = meshio::read_mesh(*scanmesh::test::shared_file(c.obj));
    CHECK(m.vertices.size() == c.vertices);
    CHECK(m.triangles.size() == c.triangles);
    CHECK(meshio::read_points(*scanmesh::test::shared_file(c.obj)).points.size() == c.vertices);
    const auto xyz = meshio::read_points(*scanmesh::test::shared_file(c.xyz));
    CHECK(xyz.points == m.vertices);
  }
}

namespace {

/// Median distance from every `step`-th point of `points` to its nearest neighbour in `ref`.
double median_nearest(const std::vector<Vec3>& points, const std::vector<Vec3>& ref,
                      std::size_t samples) {
  std::vector<double> d;
  const std::size_t step = std::max<std::size_t>(1, points.size() / samples);
  for (std::size_t i = 0; i < points.size(); i += step) {
    double best = std::numeric_limits<double>::infinity();
    for (const Vec3& r : ref) best = std::min(best, (points[i] - r).squaredNorm());
    d.push_back(std::sqrt(best));
  }
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

}  // namespace

TEST_CASE("real: bun.conf registers the ten scans onto bun_zipper", "[meshio][slow]") {
  const auto conf = scanmesh::test::shared_file("bunny/data/bun.conf");
  if (!conf) return;
  const auto entries = meshio::read_conf(*conf);
  REQUIRE(entries.size() == 10);
  const auto zipper =
      meshio::read_points(*scanmesh::test::shared_file("bunny/reconstruction/bun_zipper.ply"));
  for (const auto& e : entries) {
    INFO(e.file.string());
    REQUIRE(fs::is_regular_file(e.file));
    const auto scan = meshio::read_points(e.file);
    REQUIRE(scan.points.size() > 30000);
    std::vector<Vec3> world;
    world.reserve(scan.points.size());
    for (const Vec3& p : scan.points) world.push_back(e.to_world(p));
    const bool is_045 = e.file.filename() == "bun045.ply";
    const double median = median_nearest(world, zipper.points, is_045 ? 500 : 150);
    CHECK(median < 1.5e-3);  // metres
    if (is_045) {
      // Without the registration (or with R instead of R^T) the scan is centimetres away.
      CHECK(median_nearest(scan.points, zipper.points, 500) > 1e-2);
    }
  }
}

TEST_CASE("ply: an unknown header line is skipped with a warning naming it", "[meshio]") {
  // As in some of the Stanford repository's raw range scans: 'bye' between obj_info and element.
  const std::string text =
      "ply\nformat ascii 1.0\nobj_info num_cols 2\nbye\nelement vertex 3\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
  CHECK(meshio::parse_ply(text, "bye.ply").vertices.size() == 3);
  meshio::PlyExtras extras;
  const Mesh m = meshio::parse_ply(text, "bye.ply", extras);
  CHECK(m.vertices.size() == 3);
  REQUIRE(extras.warnings.size() == 1);
  CHECK(extras.warnings[0] == "bye.ply:4: unknown header line 'bye' skipped");
  CHECK(extras.range_rows.empty());
  // What the reader needs must still be well formed.
  CHECK_THROWS_WITH(meshio::parse_ply("ply\nformat ascii 1.0\nbye\nelement vertex 1\nproperty "
                                      "float128 x\nend_header\n",
                                      "bad.ply"),
                    Catch::Contains("bad.ply:5: unknown property type 'float128'"));
}

TEST_CASE("ply: a range grid's rows", "[meshio]") {
  const std::string text =
      "ply\nformat ascii 1.0\nobj_info num_cols 2\n"
      "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element range_grid 6\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n0 1 0\n"
      "1 0\n1 1\n0\n0\n0\n1 2\n";
  meshio::PlyExtras extras;
  meshio::parse_ply(text, "grid.ply", extras);
  const std::vector<std::vector<std::uint32_t>> rows = {{0, 1}, {}, {2}};
  CHECK(extras.range_rows == rows);
  // Binary: the same entries as the ascii reader sees; without num_cols the rows are unknown.
  CHECK_THROWS_WITH(meshio::parse_ply(binary_ply(false), "b.ply", extras),
                    Catch::Contains("range_grid without 'obj_info num_cols N'"));
  std::string with_cols = binary_ply(true);
  with_cols.replace(with_cols.find("obj_info some scanner info"), 26, "obj_info num_cols 3       ");
  meshio::parse_ply(with_cols, "b.ply", extras);
  CHECK(extras.range_rows == std::vector<std::vector<std::uint32_t>>{{0, 3}});
  // A range entry naming a vertex that does not exist.
  std::string bad = text;
  bad.replace(bad.rfind("1 2"), 3, "1 7");
  CHECK_THROWS_WITH(meshio::parse_ply(bad, "grid.ply", extras), Catch::Contains("grid.ply:"));
}
