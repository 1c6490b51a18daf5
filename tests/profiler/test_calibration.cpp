// Camera and laser-plane calibration against rendered chessboards of known truth, the report's
// rejections, and calibration files (round trip, and every kind of bad file).
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "profiler/calibration_scene.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/profiler/calibration.hpp"
#include "support/process.hpp"
#include "support/temp_dir.hpp"

using namespace scanmesh;
namespace prof = scanmesh::drivers::profiler;

namespace {

const test::RenderedCalibration& rendered() { return test::rendered_calibration(); }

prof::ChessboardSpec spec() { return test::calibration_spec(); }

const prof::CameraCalibrationResult& camera_result() { return rendered().camera; }

double degrees_between(cv::Vec3d a, cv::Vec3d b) {
  return std::acos(std::clamp(a.dot(b) / (cv::norm(a) * cv::norm(b)), -1.0, 1.0)) * 180 /
         std::numbers::pi;
}

}  // namespace

TEST_CASE("calibration: the camera's intrinsics from rendered chessboards", "[profiler]") {
  const auto& r = camera_result();
  const sim::CameraModel& t = rendered().truth;
  const cv::Matx33d& k = r.camera.matrix;
  const auto& d = r.camera.distortion;
  INFO("rms " << r.rms_px << " px; fx " << k(0, 0) << " fy " << k(1, 1) << " cx " << k(0, 2)
              << " cy " << k(1, 2) << "; k1 " << d[0] << " k2 " << d[1] << " p1 " << d[2]
              << " p2 " << d[3] << " k3 " << d[4]);
  CHECK(r.camera.size == cv::Size(640, 480));
  for (const auto& use : r.images) {
    INFO(use.image << ": " << use.reason);
    CHECK(use.used);
    CHECK(use.error_px < 0.2);
  }
  CHECK(r.poses.size() == 25);
  // Tolerances (about three of calibrateCamera's own standard deviations at this noise): well
  // under a pixel of reprojection error; the focal lengths within 0.2 %, the principal point
  // within 1 px, k1 within 0.01, k2 within 0.06, the tangential terms within 5e-4.
  CHECK(r.rms_px < 0.1);
  CHECK(std::abs(k(0, 0) / t.fx - 1) < 0.002);
  CHECK(std::abs(k(1, 1) / t.fy - 1) < 0.002);
  CHECK(std::abs(k(0, 2) - t.cx) < 1.0);
  CHECK(std::abs(k(1, 2) - t.cy) < 1.0);
  CHECK(std::abs(d[0] - t.k1) < 0.01);
  CHECK(std::abs(d[1] - t.k2) < 0.06);
  CHECK(std::abs(d[2] - t.p1) < 5e-4);
  CHECK(std::abs(d[3] - t.p2) < 5e-4);
  CHECK(d[4] == 0);  // k3 fixed
  // (How pixels then map to points is checked end to end with the laser plane below.)
}

TEST_CASE("calibration: the laser plane from the line on the boards", "[profiler]") {
  const auto& cam = camera_result();
  prof::ExtractionOptions extraction;
  const prof::LaserPlaneResult r =
      prof::calibrate_laser_plane(rendered().lasers, cam, spec(), extraction, "lasers/");
  const sim::LaserSheet& s = rendered().laser;
  const cv::Vec3d tn(s.normal.x(), s.normal.y(), s.normal.z());
  const double td = tn.dot(cv::Vec3d(s.origin.x(), s.origin.y(), s.origin.z()));
  const double angle = degrees_between(r.plane.normal, tn);
  // End to end where profiles are measured: true points of the laser plane 215 to 295 mm
  // away, seen through the true camera, triangulated with the calibrated camera and plane; the
  // depth must come back within 0.1 mm (the calibrated camera frame may turn by a few
  // thousandths of a degree against the true one: x and y are compared after the scan, in the
  // profile test).
  double worst_mm = 0;
  const Eigen::Vector3d along = s.normal.cross(Eigen::Vector3d::UnitX()).normalized();
  for (double x = -60; x <= 60; x += 15) {
    for (double z = 215; z <= 295; z += 20) {
      const Eigen::Vector3d p = s.origin + along * ((z - s.origin.z()) / along.z()) +
                                Eigen::Vector3d::UnitX() * x;
      const Eigen::Vector2d px = rendered().truth.project(p);
      if (px.x() < 0 || px.x() > 639 || px.y() < 0 || px.y() > 479) continue;
      const cv::Vec3d ray = prof::undistorted_ray(cam.camera, {px.x(), px.y()});
      const double depth = r.plane.distance_mm / r.plane.normal.dot(ray);
      worst_mm = std::max(worst_mm, std::abs(depth - p.z()));
    }
  }
  INFO("normal off by " << angle << " deg, distance " << r.plane.distance_mm << " (true " << td
                        << "), depth off by up to " << worst_mm
                        << " mm in the field; points " << r.points << " inliers " << r.inliers
                        << " rms " << r.rms_mm << " max " << r.max_mm);
  for (const auto& use : r.images) {
    INFO(use.image << ": " << use.reason);
    CHECK(use.used);
    CHECK(use.points > 100);
  }
  // Tolerances: under 0.1 degree and 0.1 mm (the plane's distance from the camera, and the
  // depth of its points anywhere in the measured field).
  CHECK(angle < 0.1);
  CHECK(std::abs(r.plane.distance_mm - td) < 0.1);
  CHECK(worst_mm < 0.1);
  CHECK(r.rms_mm < 0.05);
  // Points where the line crosses the edge of a square are biased (half of it on black): the
  // outlier rejection drops them.
  CHECK(r.inliers >= r.points * 0.75);
}

TEST_CASE("calibration: poses from the laser images' own boards, with and without laser-off "
          "images", "[profiler]") {
  // Laser images under names the camera calibration does not know: the pose comes from the
  // board in the laser-off image, or without one from the laser image itself (where the line
  // does not hide its corners), and then only the line on the white margin and squares counts.
  const sim::LaserSheet& s = rendered().laser;
  const cv::Vec3d tn(s.normal.x(), s.normal.y(), s.normal.z());
  for (bool with_off : {true, false}) {
    std::vector<prof::NamedImage> renamed = rendered().lasers;
    for (auto& img : renamed) {
      img.name = "own_" + img.name;
      if (!with_off) img.background = cv::Mat();
    }
    const prof::LaserPlaneResult r =
        prof::calibrate_laser_plane(renamed, camera_result(), spec(), {}, "lasers/");
    std::size_t used = 0;
    for (const auto& use : r.images) used += use.used;
    INFO("laser-off images " << with_off << ": used " << used << ", points " << r.points
                             << ", angle " << degrees_between(r.plane.normal, tn)
                             << " distance " << r.plane.distance_mm << " rms " << r.rms_mm);
    CHECK(used >= (with_off ? 5u : 2u));
    CHECK(degrees_between(r.plane.normal, tn) < (with_off ? 0.1 : 0.2));
  }
}

TEST_CASE("calibration: rejected images and why", "[profiler]") {
  std::vector<prof::NamedImage> images(rendered().boards.begin(), rendered().boards.begin() + 6);
  images.push_back({"blank.png", cv::Mat(480, 640, CV_8UC1, cv::Scalar(40)), {}});
  images.push_back({"small.png", cv::Mat(240, 320, CV_8UC1, cv::Scalar(40)), {}});
  const auto r = prof::calibrate_camera(images, spec(), "boards/");
  REQUIRE(r.images.size() == 8);
  CHECK(r.images[6].image == "blank.png");
  CHECK_FALSE(r.images[6].used);
  CHECK_THAT(r.images[6].reason, Catch::Contains("not found"));
  CHECK_FALSE(r.images[7].used);
  CHECK_THAT(r.images[7].reason, Catch::Contains("320x240"));
  CHECK(r.poses.size() == 6);

  // No board anywhere (a wrong pattern size): the folder and the pattern are named.
  try {
    const std::vector<prof::NamedImage> some{images[0], images[6]};  // a board, a blank
    prof::calibrate_camera(some, prof::ChessboardSpec{cv::Size(7, 7), 10}, "boards/");
    FAIL("calibrated without a board");
  } catch (const InputError& e) {
    CHECK_THAT(e.what(), Catch::Contains("boards/") && Catch::Contains("7x7") &&
                             Catch::Contains("not found in any"));
  }
  // One pose of the laser: no plane.
  try {
    prof::calibrate_laser_plane({rendered().lasers[0]}, camera_result(), spec(), {}, "lasers/");
    FAIL("a plane from one pose");
  } catch (const InputError& e) {
    CHECK_THAT(e.what(), Catch::Contains("lasers/") && Catch::Contains("at least 2"));
  }
}

TEST_CASE("calibration: points along one line do not make a plane", "[profiler]") {
  std::vector<cv::Vec3d> line;
  for (int i = 0; i < 100; ++i) line.emplace_back(i * 0.5, 1e-4 * (i % 3), 200);
  CHECK_THROWS_WITH(prof::fit_plane(line), Catch::Contains("along one line"));
  // A plane with 10 % gross outliers: they are rejected.
  std::vector<cv::Vec3d> pts;
  for (int i = 0; i < 400; ++i) {
    const double x = (i % 20) * 2.0, y = (i / 20) * 2.0;
    pts.emplace_back(x, y, 100 + 0.1 * x - 0.2 * y + (i % 10 == 0 ? 5.0 : 0.001 * ((i * 7) % 5 - 2)));
  }
  const auto r = prof::fit_plane(pts);
  CHECK(r.inliers == 360);
  CHECK(r.rms_mm < 0.002);
  const cv::Vec3d n = cv::normalize(cv::Vec3d(-0.1, 0.2, 1));
  CHECK(degrees_between(r.plane.normal, n) < 0.01);
}

TEST_CASE("calibration files: round trip through OpenCV YAML", "[profiler]") {
  test::TempDir dir;
  prof::ProfilerCalibration c;
  c.camera.size = cv::Size(1280, 1024);
  c.camera.matrix = cv::Matx33d(1800.5, 0, 645.25, 0, 1801.75, 500.5, 0, 0, 1);
  c.camera.distortion = {-0.12, 0.08, 0.0006, -0.0004, 0.001};
  c.plane = prof::LaserPlane{cv::normalize(cv::Vec3d(0, -0.9, 0.4)), 92.25};
  c.reprojection_error_px = 0.05;
  c.plane_rms_mm = 0.012;
  const auto file = dir / "cal.yml";
  prof::save_calibration(file, c);
  const std::string text = test::slurp(file);
  CHECK_THAT(text, Catch::StartsWith("%YAML:1.0") && Catch::Contains("camera_matrix: !!opencv-matrix"));
  const auto back = prof::load_calibration(file);
  CHECK(back.camera.size == c.camera.size);
  CHECK(cv::norm(cv::Mat(back.camera.matrix), cv::Mat(c.camera.matrix)) < 1e-9);
  REQUIRE(back.camera.distortion.size() == 5);
  for (int i = 0; i < 5; ++i) CHECK(back.camera.distortion[i] == c.camera.distortion[i]);
  CHECK(cv::norm(back.plane.normal - c.plane.normal) < 1e-12);
  CHECK(back.plane.distance_mm == c.plane.distance_mm);
  CHECK(back.reprojection_error_px == 0.05);
  CHECK(back.source == file.string());
}

TEST_CASE("calibration files: bad files are named with the key and the reason", "[profiler]") {
  const std::string head = "%YAML:1.0\n---\n";
  const std::string size = "image_width: 640\nimage_height: 480\n";
  const std::string k =
      "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 900., 0., "
      "320., 0., 900., 240., 0., 0., 1. ]\n";
  const std::string d =
      "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: [ "
      "-0.1, 0.05, 0., 0., 0. ]\n";
  const std::string n =
      "laser_plane_normal: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n   data: [ 0., "
      "-0.9, 0.4 ]\n";
  const std::string dist = "laser_plane_distance_mm: 90.\n";
  // The good file, with the normal not quite unit: normalised with its distance.
  const auto good = prof::parse_calibration(head + size + k + d + n + dist, "cal.yml");
  CHECK(std::abs(cv::norm(good.plane.normal) - 1) < 1e-12);
  CHECK(std::abs(good.plane.distance_mm - 90 / std::hypot(0.9, 0.4)) < 1e-9);

  const struct {
    std::string text;
    std::string expect;
  } cases[] = {
      {"", "empty file"},
      {"just some words\n", "cal.yml"},
      {head + "image_width: [1, 2\n", "cal.yml"},
      {head + size + k + d + n, "key 'laser_plane_distance_mm': missing"},
      {head + "image_width: 640.5\nimage_height: 480\n" + k + d + n + dist,
       "key 'image_width': not an integer"},
      {head + "image_width: 0\nimage_height: 480\n" + k + d + n + dist,
       "key 'image_width': 0 out of 2..65535"},
      {head + size + "camera_matrix: 5\n" + d + n + dist, "key 'camera_matrix': not an OpenCV matrix"},
      {head + size +
           "camera_matrix: !!opencv-matrix\n   rows: 2\n   cols: 2\n   dt: d\n   data: [ 1., 0., "
           "0., 1. ]\n" + d + n + dist,
       "key 'camera_matrix': must be 3 x 3"},
      {head + size +
           "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1., 0. ]\n" +
           d + n + dist,
       "key 'camera_matrix'"},
      {head + size +
           "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ -900., "
           "0., 320., 0., 900., 240., 0., 0., 1. ]\n" + d + n + dist,
       "focal lengths"},
      {head + size + k +
           "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 3\n   dt: d\n   data: [ "
           "0., 0., 0. ]\n" + n + dist,
       "0, 4, 5, 8, 12 or 14 coefficients, got 3"},
      {head + size + k + d +
           "laser_plane_normal: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n   data: [ 0., "
           "0., 0. ]\n" + dist,
       "key 'laser_plane_normal': is zero"},
      {head + size + k + d + n + "laser_plane_distance_mm: .nan\n",
       "key 'laser_plane_distance_mm'"},
      {head + size + k + d + n + "laser_plane_distance_mm: 0\n",
       "passes through the camera's centre"},
  };
  for (const auto& c : cases) {
    INFO(c.text);
    try {
      prof::parse_calibration(c.text, "cal.yml");
      FAIL("accepted");
    } catch (const InputError& e) {
      CHECK_THAT(e.what(), Catch::StartsWith("cal.yml: ") && Catch::Contains(c.expect));
    }
  }
  test::TempDir dir;
  CHECK_THROWS_WITH(prof::load_calibration(dir / "none.yml"),
                    Catch::Contains("none.yml") && Catch::Contains("cannot read"));
}

TEST_CASE("calibration files: inputs the fuzzer once failed on are refused cleanly",
          "[profiler]") {
  const auto dir =
      std::filesystem::path(SCANMESH_SOURCE_DIR) / "fuzz" / "regressions" / "profiler_calibration";
  int n = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    INFO(entry.path());
    CHECK_THROWS_AS(prof::load_calibration(entry.path()), InputError);
    ++n;
  }
  CHECK(n >= 2);
}
