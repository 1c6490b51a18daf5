// `scanmesh profiler extract|calibrate|read` run as a program on rendered images written to
// disk: outputs checked against the truth and the library, errors against their messages.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <cmath>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "profiler/scene.hpp"
#include "scanmesh/drivers/profiler/extraction.hpp"
#include "scanmesh/drivers/profiler/media.hpp"
#include "support/json_lines.hpp"
#include "support/process.hpp"
#include "support/temp_dir.hpp"

using namespace scanmesh;
namespace prof = scanmesh::drivers::profiler;

namespace {

test::RunResult scanmesh_run(const test::TempDir& dir, const std::vector<std::string>& args) {
  return test::run_program(SCANMESH_EXE, dir, args);
}

}  // namespace

TEST_CASE("profiler extract: JSON per image in name order, within 0.1 px of the truth",
          "[profiler][cli]") {
  const test::PartScene scene;
  const prof::Media media = prof::Media::load();
  test::TempDir dir;
  std::filesystem::create_directory(dir / "frames");
  std::vector<sim::LaserFrame> frames;
  // Written out of name order; three camera positions along the part.
  const std::vector<std::pair<std::string, double>> shots{{"b.png", 30}, {"a.png", 20}, {"c.png", 10}};
  for (const auto& [name, y] : shots) {
    frames.push_back(sim::render_laser_frame(scene.bvh, test::part_from_camera(40, y),
                                             test::profiler_camera(), {test::profiler_laser()},
                                             test::clean_look()));
    media.write_image(dir / "frames" / name, frames.back().image);
  }
  const auto r = scanmesh_run(dir, {"profiler", "extract", "--images", (dir / "frames").string(),
                                    "--trim-ends", "0", "--json"});
  INFO(r.err);
  REQUIRE(r.status == 0);
  const auto lines = test::json_lines(r.out);
  REQUIRE(lines.size() == 3);
  const std::vector<std::size_t> order{1, 0, 2};  // a, b, c
  for (std::size_t i = 0; i < 3; ++i) {
    const auto& j = lines[i];
    const sim::LaserFrame& frame = frames[order[i]];
    CHECK(j["image"] == shots[order[i]].first);
    REQUIRE(j["positions"].size() == 640);
    int compared = 0;
    for (std::size_t c = 0; c < 640; ++c) {
      const double t = frame.truth[0][c];
      if (std::isnan(t)) continue;
      REQUIRE(j["positions"][c].is_number());
      CHECK(std::abs(j["positions"][c].get<double>() - t) < 0.1);
      ++compared;
    }
    CHECK(compared > 150);
    CHECK(j["found"].get<int>() >= compared);
  }

  // --rows on the transposed images: the same positions, a value per row.
  std::filesystem::create_directory(dir / "rows");
  media.write_image(dir / "rows" / "a.png", frames[1].image.t());
  const auto rr = scanmesh_run(dir, {"profiler", "extract", "--images", (dir / "rows").string(),
                                     "--rows", "--trim-ends", "0", "--json"});
  REQUIRE(rr.status == 0);
  const auto rows = test::json_lines(rr.out);
  REQUIRE(rows.size() == 1);
  CHECK(rows[0]["positions"] == lines[0]["positions"]);
}

TEST_CASE("profiler extract: folders and images that cannot be read", "[profiler][cli]") {
  test::TempDir dir;
  auto r = scanmesh_run(dir, {"profiler", "extract", "--images", (dir / "nowhere").string()});
  CHECK(r.status == 3);
  CHECK_THAT(r.err, Catch::Contains((dir / "nowhere").string()) && Catch::Contains("no such folder"));

  std::filesystem::create_directory(dir / "empty");
  test::spit(dir / "empty" / "notes.txt", "not an image");
  r = scanmesh_run(dir, {"profiler", "extract", "--images", (dir / "empty").string()});
  CHECK(r.status == 3);
  CHECK_THAT(r.err, Catch::Contains("empty") && Catch::Contains("no images"));

  std::filesystem::create_directory(dir / "broken");
  test::spit(dir / "broken" / "frame.png", "\x89PNG but not really");
  r = scanmesh_run(dir, {"profiler", "extract", "--images", (dir / "broken").string()});
  CHECK(r.status == 3);
  CHECK_THAT(r.err, Catch::Contains("frame.png") && Catch::Contains("cannot read the image"));
}
