// `scanmesh profiler extract|calibrate|read` run as a program on rendered images written to
// disk: outputs checked against the truth and the library, errors against their messages.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <cmath>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "profiler/calibration_scene.hpp"
#include "profiler/scene.hpp"
#include "scanmesh/drivers/profiler/calibration.hpp"
#include "scanmesh/drivers/profiler/camera.hpp"
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

TEST_CASE("profiler calibrate: from image folders to a calibration file and its report",
          "[profiler][cli]") {
  const auto& rc = test::rendered_calibration();
  const prof::Media media = prof::Media::load();
  test::TempDir dir;
  std::filesystem::create_directory(dir / "boards");
  std::filesystem::create_directory(dir / "lasers");
  for (const auto& b : rc.boards) media.write_image(dir / "boards" / b.name, b.gray);
  for (const auto& l : rc.lasers) {
    media.write_image(dir / "lasers" / l.name, l.gray);
    const std::string stem = std::filesystem::path(l.name).stem().string();
    media.write_image(dir / "lasers" / (stem + "_off.png"), l.background);
  }
  // A broken file among the boards: reported, not fatal.
  test::spit(dir / "boards" / "zz_broken.png", "not a png");
  const auto out = dir / "cal.yml";
  const auto r = scanmesh_run(dir, {"profiler", "calibrate", "--images", (dir / "boards").string(),
                                    "--pattern", "9x6", "--square", "10", "--laser-images",
                                    (dir / "lasers").string(), "-o", out.string(), "--json"});
  INFO(r.err);
  REQUIRE(r.status == 0);
  const auto j = nlohmann::json::parse(r.out);
  CHECK(j["images"] == 26);
  CHECK(j["images_used"] == 25);
  REQUIRE(j["rejected_images"].size() == 1);
  CHECK(j["rejected_images"][0]["image"] == "zz_broken.png");
  CHECK_THAT(j["rejected_images"][0]["reason"].get<std::string>(), Catch::Contains("cannot read"));
  CHECK(j["reprojection_error_px"].get<double>() < 0.1);
  CHECK(j["laser_images"] == 5);
  CHECK(j["laser_images_used"] == 5);
  CHECK(j["laser_plane_rms_mm"].get<double>() < 0.05);
  // The file holds what the library computes from the same images.
  const auto cal = prof::load_calibration(out);
  const auto plane = prof::calibrate_laser_plane(rc.lasers, rc.camera, test::calibration_spec(),
                                                 {}, "lasers");
  CHECK(cal.camera.size == cv::Size(640, 480));
  CHECK(std::abs(cal.camera.matrix(0, 0) - rc.camera.camera.matrix(0, 0)) < 1e-6);
  CHECK(std::abs(cal.plane.distance_mm - plane.plane.distance_mm) < 1e-6);
  CHECK(std::abs(j["laser_plane"]["distance_mm"].get<double>() - plane.plane.distance_mm) < 1e-9);
  CHECK(std::abs(cal.reprojection_error_px - j["reprojection_error_px"].get<double>()) < 1e-9);

  // Text report.
  const auto t = scanmesh_run(dir, {"profiler", "calibrate", "--images", (dir / "boards").string(),
                                    "--pattern", "9x6", "--square", "10", "--laser-images",
                                    (dir / "lasers").string(), "-o", (dir / "cal2.yaml").string()});
  CHECK(t.status == 0);
  CHECK_THAT(t.out, Catch::Contains("25 of 26 images used") && Catch::Contains("rejected zz_broken.png") &&
                        Catch::Contains("5 of 5 images used"));
}

TEST_CASE("profiler calibrate: errors", "[profiler][cli]") {
  const auto& rc = test::rendered_calibration();
  const prof::Media media = prof::Media::load();
  test::TempDir dir;
  std::filesystem::create_directory(dir / "boards");
  media.write_image(dir / "boards" / rc.boards[0].name, rc.boards[0].gray);
  media.write_image(dir / "boards" / "blank.png", cv::Mat(480, 640, CV_8UC1, cv::Scalar(90)));
  const auto base = [&](std::vector<std::string> extra) {
    std::vector<std::string> a{"profiler", "calibrate", "--images", (dir / "boards").string(),
                               "--square", "10", "--laser-images", (dir / "boards").string()};
    a.insert(a.end(), extra.begin(), extra.end());
    return scanmesh_run(dir, a);
  };
  // The chessboard in none of the images (a wrong pattern).
  auto r = base({"--pattern", "7x7", "-o", (dir / "c.yml").string()});
  CHECK(r.status == 3);
  CHECK_THAT(r.err, Catch::Contains((dir / "boards").string()) && Catch::Contains("7x7") &&
                        Catch::Contains("not found in any of the 2 images"));
  CHECK_FALSE(std::filesystem::exists(dir / "c.yml"));
  // An unreadable folder.
  r = scanmesh_run(dir, {"profiler", "calibrate", "--images", (dir / "none").string(), "--pattern",
                         "9x6", "--square", "10", "--laser-images", (dir / "boards").string(), "-o",
                         (dir / "c.yml").string()});
  CHECK(r.status == 3);
  CHECK_THAT(r.err, Catch::Contains((dir / "none").string()) && Catch::Contains("no such folder"));
  // Usage: a pattern that is not COLSxROWS, an output that is not YAML.
  r = base({"--pattern", "nine", "-o", (dir / "c.yml").string()});
  CHECK(r.status == 2);
  CHECK_THAT(r.err, Catch::Contains("COLSxROWS"));
  r = base({"--pattern", "9x6", "-o", (dir / "c.json").string()});
  CHECK(r.status == 2);
  CHECK_THAT(r.err, Catch::Contains(".yml or .yaml"));
}

TEST_CASE("profiler read: profiles as JSON lines from a folder and an image sequence",
          "[profiler][cli]") {
  const test::PartScene scene;
  const prof::Media media = prof::Media::load();
  test::TempDir dir;
  std::filesystem::create_directory(dir / "frames");
  std::vector<cv::Mat> images;
  for (int i = 0; i < 4; ++i) {
    images.push_back(sim::render_laser_frame(scene.bvh, test::part_from_camera(40, 14 + 4 * i),
                                             test::profiler_camera(), {test::profiler_laser()},
                                             test::noisy_look(static_cast<std::uint64_t>(50 + i)))
                         .image);
    char name[32];
    std::snprintf(name, sizeof name, "f_%02d.png", i);
    media.write_image(dir / "frames" / name, images.back());
  }
  const auto truth = test::true_calibration(test::profiler_camera(), test::profiler_laser());
  prof::save_calibration(dir / "cal.yml", truth);
  // What the library makes of the same frames.
  prof::LineExtractor ex;
  prof::Triangulator tri(truth.camera, truth.plane, prof::LineAxis::kColumns);
  for (const std::string& source :
       {(dir / "frames").string(), (dir / "frames" / "f_%02d.png").string()}) {
    const auto r = scanmesh_run(dir, {"profiler", "read", "--source", source, "--calib",
                                      (dir / "cal.yml").string(), "--frames", "4", "--json"});
    INFO(source << ": " << r.err);
    REQUIRE(r.status == 0);
    const auto lines = test::json_lines(r.out);
    REQUIRE(lines.size() == 4);
    for (std::size_t i = 0; i < 4; ++i) {
      const auto& j = lines[i];
      CHECK(j["seq"] == i);
      CHECK(j["t_host_ns"].is_number_integer());
      CHECK(j["exposure_us"].is_null());
      REQUIRE(j["points"].size() == 640);
      std::vector<float> pos;
      std::vector<drivers::ProfilePoint> pts;
      ex.extract(images[i], {}, pos);
      tri.triangulate(pos, pts);
      std::size_t valid = 0;
      for (std::size_t c = 0; c < 640; ++c) {
        const auto& p = j["points"][c];
        REQUIRE(p.is_null() == !pts[c].valid());
        if (p.is_null()) continue;
        ++valid;
        CHECK(std::abs(p[0].get<double>() - pts[c].x_mm) < 1e-4);
        CHECK(std::abs(p[2].get<double>() - pts[c].z_mm) < 1e-4);
      }
      CHECK(valid > 150);
      CHECK(j["valid"] == valid);
    }
  }
  // More profiles than the files hold: what there is, then exit 5 saying why.
  const auto r = scanmesh_run(dir, {"profiler", "read", "--source", (dir / "frames").string(),
                                    "--calib", (dir / "cal.yml").string(), "--frames", "6"});
  CHECK(r.status == 5);
  CHECK(test::json_lines("").empty());
  CHECK_THAT(r.err, Catch::Contains("end of the source after 4 frames") && Catch::Contains("4 of 6"));
}

TEST_CASE("profiler read: errors name the camera or the file", "[profiler][cli]") {
  test::TempDir dir;
  const auto truth = test::true_calibration(test::profiler_camera(), test::profiler_laser());
  prof::save_calibration(dir / "cal.yml", truth);
  // A missing camera.
  auto r = scanmesh_run(dir, {"profiler", "read", "--source", "/dev/video98", "--calib",
                              (dir / "cal.yml").string(), "--frames", "1", "--name", "cam7"});
  CHECK(r.status == 5);
  CHECK_THAT(r.err, Catch::Contains("cam7 (/dev/video98): open: no such camera"));
  // A calibration of another camera size.
  const prof::Media media = prof::Media::load();
  std::filesystem::create_directory(dir / "big");
  media.write_image(dir / "big" / "a.png", cv::Mat(600, 800, CV_8UC1, cv::Scalar(10)));
  r = scanmesh_run(dir, {"profiler", "read", "--source", (dir / "big").string(), "--calib",
                         (dir / "cal.yml").string(), "--frames", "1"});
  CHECK(r.status == 5);
  CHECK_THAT(r.err, Catch::Contains("frames are 800x600 but " + (dir / "cal.yml").string() +
                                    " is for a 640x480 camera"));
  // A missing and a broken calibration file.
  r = scanmesh_run(dir, {"profiler", "read", "--source", (dir / "big").string(), "--calib",
                         (dir / "none.yml").string(), "--frames", "1"});
  CHECK(r.status == 3);
  CHECK_THAT(r.err, Catch::Contains("none.yml") && Catch::Contains("cannot read"));
  test::spit(dir / "bad.yml", "%YAML:1.0\n---\nimage_width: 640\n");
  r = scanmesh_run(dir, {"profiler", "read", "--source", (dir / "big").string(), "--calib",
                         (dir / "bad.yml").string(), "--frames", "1"});
  CHECK(r.status == 3);
  CHECK_THAT(r.err, Catch::Contains("bad.yml: key 'image_height': missing"));
}
