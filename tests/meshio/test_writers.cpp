// Writer tests: round trips through every format, STL normals, and the atomic-write guarantees
// (nothing left behind on failure, OutputError naming the file and the OS error).
// SPDX-License-Identifier: MIT
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <catch2/catch.hpp>
#include <csignal>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "support/data.hpp"

namespace fs = std::filesystem;
using scanmesh::OutputError;
using scanmesh::recon::Mesh;
using scanmesh::recon::Triangle;
using scanmesh::recon::Vec3;
namespace meshio = scanmesh::meshio;

namespace {

class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    path_ = fs::temp_directory_path() / ("scanmesh_meshio_writers_" + std::to_string(::getpid()) +
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
  [[nodiscard]] const fs::path& path() const { return path_; }
  /// Names of the entries in the directory, sorted.
  [[nodiscard]] std::vector<std::string> entries() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(path_))
      names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }

 private:
  fs::path path_;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// The OutputError message of `f` (fails the test if it throws nothing).
template <typename F>
std::string output_error(F&& f) {
  try {
    f();
  } catch (const OutputError& e) {
    return e.what();
  }
  FAIL("no OutputError thrown");
  return {};
}

/// A small closed mesh (a tetrahedron with one face split into a fan) whose vertices appear in
/// the triangles in index order, so that STL's merge gives back the same numbering.
Mesh test_mesh() {
  Mesh m;
  m.vertices = {Vec3(0, 0, 0), Vec3(0, 2.5, 0), Vec3(1.25, 0, 0), Vec3(0.1, 0.2, 3.3),
                Vec3(-1e-3, 123456.789, -7.0 / 3.0)};
  m.triangles = {{0, 1, 2}, {0, 2, 3}, {2, 1, 3}, {1, 0, 3}, {3, 4, 0}};
  return m;
}

void check_same(const Mesh& a, const Mesh& b) {
  REQUIRE(a.vertices.size() == b.vertices.size());
  // float precision: the formats store float32 or 9 significant digits
  std::size_t bad = 0;
  for (std::size_t i = 0; i < a.vertices.size(); ++i) {
    if ((a.vertices[i] - b.vertices[i]).norm() > 1e-7 * (1.0 + a.vertices[i].norm())) ++bad;
  }
  CHECK(bad == 0);
  CHECK(a.triangles == b.triangles);
}

}  // namespace

TEST_CASE("write_mesh: round trip through every format", "[meshio]") {
  TempDir dir;
  const Mesh mesh = test_mesh();
  struct Case {
    const char* file;
    bool ascii_stl;
  };
  for (const Case& c : {Case{"m.stl", false}, Case{"ma.stl", true}, Case{"m.ply", false},
                        Case{"m.obj", false}, Case{"UPPER.PLY", false}}) {
    INFO(c.file);
    const fs::path p = dir.path() / c.file;
    meshio::write_mesh(mesh, p, meshio::WriteOptions{c.ascii_stl});
    check_same(mesh, meshio::read_mesh(p));
    CHECK(meshio::read_points(p).points.size() == mesh.vertices.size());
  }
  CHECK(slurp(dir.path() / "ma.stl").rfind("solid ", 0) == 0);
  CHECK(slurp(dir.path() / "m.stl").rfind("solid", 0) == std::string::npos);
  CHECK(slurp(dir.path() / "m.stl").size() == 84 + 50 * mesh.triangles.size());
  CHECK(dir.entries() ==
        std::vector<std::string>{"UPPER.PLY", "m.obj", "m.ply", "m.stl", "ma.stl"});
}

// A part far from the origin at a fine spacing (machine coordinates): float would move its
// vertices by a good part of an edge, so PLY, OBJ and ascii STL keep double precision (near the
// origin they stay float: half the file); binary STL cannot, and says so.
TEST_CASE("write_mesh: double precision where float cannot hold the mesh", "[meshio]") {
  TempDir dir;
  Mesh far;
  const Vec3 o(2.0e5, -3.0e5, 1.0e5);
  far.vertices = {o, o + Vec3(1e-3, 0, 0), o + Vec3(0, 1e-3, 0), o + Vec3(1e-3, 1e-3, 1e-4)};
  far.triangles = {{0, 1, 2}, {1, 3, 2}};
  CHECK_FALSE(meshio::float_holds(far));
  CHECK(meshio::float_holds(test_mesh()));
  for (const char* name : {"far.ply", "far.obj", "far_ascii.stl"}) {
    INFO(name);
    const fs::path p = dir.path() / name;
    CHECK_FALSE(meshio::write_mesh(far, p, meshio::WriteOptions{true}).float_rounds_mesh);
    const Mesh back = meshio::read_mesh(p);
    REQUIRE(back.vertices.size() == far.vertices.size());
    for (std::size_t v = 0; v < far.vertices.size(); ++v) CHECK(back.vertices[v] == far.vertices[v]);
    CHECK(back.triangles == far.triangles);
  }
  CHECK(slurp(dir.path() / "far.ply").find("property double x") != std::string::npos);
  // binary STL is float32 by its format: written, and reported
  CHECK(meshio::write_mesh(far, dir.path() / "far.stl").float_rounds_mesh);
  CHECK_FALSE(meshio::write_mesh(test_mesh(), dir.path() / "near.stl").float_rounds_mesh);
  meshio::write_mesh(test_mesh(), dir.path() / "near.ply");
  CHECK(slurp(dir.path() / "near.ply").find("property float x") != std::string::npos);
}

TEST_CASE("write_mesh: empty mesh round trips", "[meshio]") {
  TempDir dir;
  for (const char* name : {"e.stl", "e.ply", "e.obj"}) {
    INFO(name);
    meshio::write_mesh(Mesh{}, dir.path() / name);
    const Mesh back = meshio::read_mesh(dir.path() / name);
    CHECK(back.vertices.empty());
    CHECK(back.triangles.empty());
  }
}

TEST_CASE("write_mesh: binary STL facet normals", "[meshio]") {
  TempDir dir;
  Mesh m;
  m.vertices = {Vec3(0, 0, 0), Vec3(2, 0, 0), Vec3(0, 2, 0), Vec3(5, 5, 5)};
  m.triangles = {{0, 1, 2}, {0, 2, 1}, {3, 3, 0}};  // +z, -z, degenerate
  const fs::path p = dir.path() / "n.stl";
  meshio::write_mesh(m, p);
  const std::string bytes = slurp(p);
  REQUIRE(bytes.size() == 84 + 50 * 3);
  auto normal = [&](std::size_t t) {
    float n[3];
    std::memcpy(n, bytes.data() + 84 + 50 * t, 12);  // the test host is little endian
    return Vec3(n[0], n[1], n[2]);
  };
  CHECK(normal(0) == Vec3(0, 0, 1));
  CHECK(normal(1) == Vec3(0, 0, -1));
  CHECK(normal(2) == Vec3(0, 0, 0));
}

TEST_CASE("write_mesh: ascii STL and OBJ text", "[meshio]") {
  TempDir dir;
  Mesh m;
  m.vertices = {Vec3(0, 0, 0), Vec3(0.1, 0, 0), Vec3(0, 1.0 / 3.0, 0)};
  m.triangles = {{0, 1, 2}};
  meshio::write_mesh(m, dir.path() / "t.obj");
  CHECK(slurp(dir.path() / "t.obj") ==
        "# written by scanmesh\nv 0 0 0\nv 0.1 0 0\nv 0 0.333333333 0\nf 1 2 3\n");
  meshio::write_mesh(m, dir.path() / "t.stl", {.ascii_stl = true});
  CHECK(slurp(dir.path() / "t.stl") ==
        "solid scanmesh\n  facet normal 0 0 1\n    outer loop\n      vertex 0 0 0\n"
        "      vertex 0.1 0 0\n      vertex 0 0.333333333 0\n    endloop\n  endfacet\n"
        "endsolid scanmesh\n");
}

TEST_CASE("write_points_xyz: round trip and replace", "[meshio]") {
  TempDir dir;
  const std::vector<Vec3> pts = {Vec3(1, 2, 3), Vec3(-0.5, 1e-9, 6.02214076e23),
                                 Vec3(1.0 / 3.0, 2.0 / 3.0, 123456789.0)};
  const fs::path p = dir.path() / "p.xyz";
  meshio::write_points_xyz({Vec3(9, 9, 9)}, p);
  meshio::write_points_xyz(pts, p);  // replaces the previous file
  const auto back = meshio::read_points(p);
  REQUIRE(back.points.size() == pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      CHECK(back.points[i][k] == Approx(pts[i][k]).epsilon(1e-8));
    }
  }
  CHECK(slurp(p).rfind("1 2 3\n-0.5 1e-09 6.02214076e+23\n", 0) == 0);
  CHECK(dir.entries() == std::vector<std::string>{"p.xyz"});
}

TEST_CASE("write_mesh: failures leave nothing behind", "[meshio]") {
  TempDir dir;
  const Mesh mesh = test_mesh();

  SECTION("nonexistent directory") {
    const fs::path p = dir.path() / "no" / "such" / "dir" / "m.ply";
    CHECK(output_error([&] { meshio::write_mesh(mesh, p); }) ==
          "cannot write " + p.string() + ": No such file or directory");
    CHECK(output_error([&] {
            meshio::write_points_xyz(mesh.vertices, dir.path() / "no" / "p.xyz");
          }).find("No such file or directory") != std::string::npos);
    CHECK(dir.entries().empty());
  }
  SECTION("unknown extension") {
    const fs::path p = dir.path() / "m.off";
    CHECK_THAT(output_error([&] { meshio::write_mesh(mesh, p); }),
               Catch::StartsWith("cannot write " + p.string() + ": unknown mesh extension '.off'"));
    const fs::path q = dir.path() / "p.CSV";
    CHECK(output_error([&] { meshio::write_points_xyz(mesh.vertices, q); }) ==
          "cannot write " + q.string() + ": unknown point file extension '.csv' (use .xyz, .txt or .asc)");
    CHECK(meshio::writes_mesh_extension("a/b.ObJ"));
    CHECK(!meshio::writes_mesh_extension("a/b.xyz"));
    CHECK(meshio::writes_points_extension("a/b.TXT"));
    CHECK(!meshio::writes_points_extension("a/b"));
    CHECK(dir.entries().empty());
  }
  SECTION("triangle with a bad index") {
    Mesh bad = mesh;
    bad.triangles.push_back({0, 1, 99});
    CHECK_THAT(output_error([&] { meshio::write_mesh(bad, dir.path() / "b.stl"); }),
               Catch::Contains("triangle 5 uses vertex 99 but the mesh has 5 vertices"));
    CHECK(dir.entries().empty());
  }
  SECTION("target is a directory: the rename fails and the temp file is removed") {
    fs::create_directory(dir.path() / "taken.obj");
    fs::create_directory(dir.path() / "taken.obj" / "child");
    CHECK_THAT(output_error([&] { meshio::write_mesh(mesh, dir.path() / "taken.obj"); }),
               Catch::StartsWith("cannot write " + (dir.path() / "taken.obj").string() + ": "));
    CHECK(dir.entries() == std::vector<std::string>{"taken.obj"});
  }
  SECTION("read-only directory") {
    if (::geteuid() == 0) return;  // root ignores directory permissions
    fs::permissions(dir.path(), fs::perms::owner_read | fs::perms::owner_exec);
    const fs::path p = dir.path() / "m.stl";
    const std::string msg = output_error([&] { meshio::write_mesh(mesh, p); });
    fs::permissions(dir.path(), fs::perms::owner_all);
    CHECK(msg == "cannot write " + p.string() + ": Permission denied");
    CHECK(dir.entries().empty());
  }
  SECTION("a write fails half way (file size limit)") {
    // RLIMIT_FSIZE makes write() fail with EFBIG once the file reaches the limit (SIGXFSZ is
    // ignored so the process survives); this exercises the checked writes and the cleanup.
    Mesh big;
    for (int i = 0; i < 200000; ++i) big.vertices.emplace_back(i, i * 0.5, -i);
    for (std::uint32_t i = 0; i + 2 < 200000; i += 3) big.triangles.push_back({i, i + 1, i + 2});
    rlimit old{};
    REQUIRE(::getrlimit(RLIMIT_FSIZE, &old) == 0);
    rlimit small = old;
    small.rlim_cur = 4096;
    const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
    REQUIRE(::setrlimit(RLIMIT_FSIZE, &small) == 0);
    std::vector<std::string> messages;
    for (const char* name : {"big.stl", "big.ply", "big.obj"}) {
      messages.push_back(output_error([&] { meshio::write_mesh(big, dir.path() / name); }));
    }
    messages.push_back(
        output_error([&] { meshio::write_points_xyz(big.vertices, dir.path() / "big.xyz"); }));
    ::setrlimit(RLIMIT_FSIZE, &old);
    std::signal(SIGXFSZ, old_handler);
    for (const std::string& m : messages) CHECK_THAT(m, Catch::Contains("File too large"));
    CHECK(dir.entries().empty());
  }
}

TEST_CASE("real: bun_zipper through every writer", "[meshio][slow]") {
  const auto zipper_file = scanmesh::test::shared_file("bunny/reconstruction/bun_zipper.ply");
  if (!zipper_file) return;
  const Mesh zipper = meshio::read_mesh(*zipper_file);
  TempDir dir;
  for (const char* name : {"z.ply", "z.obj"}) {
    INFO(name);
    meshio::write_mesh(zipper, dir.path() / name);
    check_same(zipper, meshio::read_mesh(dir.path() / name));
  }
  // STL keeps only the vertices used by faces (bun_zipper has 1,113 unused ones) and renumbers
  // them; the triangles' corners must still be the same points.
  for (const bool ascii : {false, true}) {
    INFO((ascii ? "ascii STL" : "binary STL"));
    const fs::path p = dir.path() / (ascii ? "za.stl" : "z.stl");
    meshio::write_mesh(zipper, p, {.ascii_stl = ascii});
    const Mesh back = meshio::read_mesh(p);
    CHECK(back.vertices.size() == 35947 - 1113);
    REQUIRE(back.triangles.size() == zipper.triangles.size());
    double worst = 0;
    for (std::size_t t = 0; t < back.triangles.size(); ++t) {
      for (int k = 0; k < 3; ++k) {
        worst = std::max(
            worst,
            (back.vertices[back.triangles[t][k]] - zipper.vertices[zipper.triangles[t][k]]).norm());
      }
    }
    CHECK(worst < 1e-8);
  }
}
