// `scanmesh scan` end to end: a simulated scan through the pipeline into a mesh file, checked
// with the independent mesh readers and analysis; usage and input errors.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/deviation.hpp"
#include "scanmesh/sim/parts.hpp"
#include "support/process.hpp"

using namespace scanmesh;

TEST_CASE("scan --sim: a simulated scan of the steps meshed while it runs", "[acq][cli]") {
  test::TempDir dir;
  const auto out = dir / "steps.ply";
  const auto png = dir / "steps.png";
  const auto r = test::run_program(SCANMESH_EXE, dir,
                                   {"scan", "--sim", "steps", "--sensor", "line", "--spacing",
                                    "0.3", "--noise", "0.01", "-o", out.string(), "--preview",
                                    png.string(), "--json"});
  INFO(r.err);
  REQUIRE(r.status == 0);
  const auto j = nlohmann::json::parse(r.out);
  CHECK(j["state"] == "completed");
  CHECK(j["mesher"] == "incremental");
  CHECK(j["samples"].get<long>() > 10000);
  CHECK(j["points"].get<long>() + j["invalid"].get<long>() + j["no_pose"].get<long>() ==
        j["samples"].get<long>());
  CHECK(j["meshing_lag"] == 0);
  // The file is what the JSON says, and lies on the part.
  const recon::Mesh mesh = meshio::read_mesh(out);
  CHECK(mesh.triangles.size() == j["mesh"]["triangles"].get<std::size_t>());
  const auto rep = recon::analyze(mesh);
  CHECK(rep.non_manifold_edges == 0);
  CHECK(rep.orientation_consistent);
  const recon::SurfaceDistance part(sim::make_part("steps"));
  double worst = 0;
  for (const auto& v : mesh.vertices) worst = std::max(worst, part.distance(v));
  CHECK(worst < 0.1);
  CHECK(std::filesystem::file_size(png) > 1000);
  CHECK(test::slurp(png).substr(1, 3) == "PNG");
}

TEST_CASE("scan: usage and input errors", "[acq][cli]") {
  test::TempDir dir;
  auto run = [&](std::vector<std::string> args) { return test::run_program(SCANMESH_EXE, dir, args); };
  auto r = run({"scan", "--sim", "steps", "-o", (dir / "x.off").string()});
  CHECK(r.status == 2);
  CHECK(r.err.find(".off") != std::string::npos);
  r = run({"scan", "--sim", "steps", "--sensor", "laser", "-o", (dir / "x.stl").string()});
  CHECK(r.status == 2);
  r = run({"scan", "--sim", (dir / "missing.stl").string(), "-o", (dir / "x.stl").string()});
  CHECK(r.status == 3);
  CHECK(r.err.find("missing.stl") != std::string::npos);
  CHECK_FALSE(std::filesystem::exists(dir / "x.stl"));
}
