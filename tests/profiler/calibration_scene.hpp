// Rendered calibration images for the profiler tests: chessboards at known poses in front of
// the true camera (scene.hpp), and the laser line across boards at poses it crosses.
// SPDX-License-Identifier: MIT
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "profiler/scene.hpp"
#include "scanmesh/drivers/profiler/calibration.hpp"
#include "scanmesh/sim/laser_frames.hpp"

namespace scanmesh::test {

inline sim::ChessboardTarget calibration_board() {
  sim::ChessboardTarget b;
  b.cols = 9;
  b.rows = 6;
  b.square_mm = 10;
  b.margin_mm = 10;
  return b;
}

/// camera_from_board with the board's centre at `centre` (camera frame, mm), turned by
/// `tilt_x_deg`, `tilt_y_deg` (about the camera's x and y) and `spin_deg` (in its plane).
inline Eigen::Isometry3d board_pose(const sim::ChessboardTarget& b, Eigen::Vector3d centre,
                                    double tilt_x_deg, double tilt_y_deg, double spin_deg) {
  const double k = std::numbers::pi / 180;
  const Eigen::Matrix3d r =
      (Eigen::AngleAxisd(tilt_x_deg * k, Eigen::Vector3d::UnitX()) *
       Eigen::AngleAxisd(tilt_y_deg * k, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(spin_deg * k, Eigen::Vector3d::UnitZ()))
          .toRotationMatrix();
  const Eigen::Vector3d mid((b.cols - 1) * b.square_mm / 2, (b.rows - 1) * b.square_mm / 2, 0);
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = r;
  t.translation() = centre - r * mid;
  return t;
}

struct NamedPose {
  std::string name;
  Eigen::Isometry3d camera_from_board;
};

/// Twenty views for the camera: the board in the middle, in the corners and at the edges of
/// the image, tilted up to 40 degrees in every direction, 220 to 340 mm away.
inline std::vector<NamedPose> camera_poses(const sim::ChessboardTarget& b) {
  struct P {
    double x, y, z, tx, ty, spin;
  };
  const P ps[] = {{0, 0, 250, 0, 0, 0},          {-52, -36, 310, -15, 20, 5},
                  {52, -36, 310, -15, -20, -5},  {-52, 36, 310, 15, 20, 10},
                  {52, 36, 310, 15, -20, -10},   {-58, 0, 320, 0, 25, 90},
                  {58, 0, 320, 0, -25, 90},      {0, -42, 320, -25, 0, 0},
                  {0, 42, 320, 25, 0, 0},        {0, 0, 250, 40, 0, 15},
                  {0, 0, 255, -40, 0, -15},      {0, 0, 260, 0, 40, 3},
                  {0, 0, 265, 0, -40, 0},        {-20, -10, 280, 30, 30, 20},
                  {20, 10, 290, -30, -30, -20},  {-20, 15, 270, 30, -30, 0},
                  {20, -15, 275, -30, 30, 8},    {0, 0, 340, 10, 10, 45},
                  {5, -5, 225, 20, -10, -30},    {-10, 8, 300, -10, 15, 60}};
  std::vector<NamedPose> poses;
  int i = 0;
  for (const P& p : ps) {
    char name[32];
    std::snprintf(name, sizeof name, "view_%02d.png", i++);
    poses.push_back({name, board_pose(b, {p.x, p.y, p.z}, p.tx, p.ty, p.spin)});
  }
  return poses;
}

/// Five poses the laser line crosses (the sheet meets the optical axis at 240 mm): the board
/// nearer and farther, tilted differently, so that the line points span the plane.
inline std::vector<NamedPose> laser_poses(const sim::ChessboardTarget& b) {
  struct P {
    double z, tx, ty, spin;
  };
  const P ps[] = {{215, 20, 10, 5}, {235, -15, -20, -5}, {255, 25, -15, 10},
                  {275, -20, 15, 0}, {295, 10, 25, -10}};
  std::vector<NamedPose> poses;
  int i = 0;
  for (const P& p : ps) {
    const double y = -100 + 100 * p.z / 240;  // the sheet's height at that depth
    char name[32];
    std::snprintf(name, sizeof name, "laser_%02d.png", i++);
    poses.push_back({name, board_pose(b, {0, y, p.z}, p.tx, p.ty, p.spin)});
  }
  return poses;
}

/// A well-lit board for the camera calibration.
inline sim::FrameLook board_look(std::uint64_t seed) {
  sim::FrameLook look;
  look.ambient = 200;
  look.background = 30;
  look.read_noise = 1.5;
  look.blur_px = 0.6;
  look.seed = seed;
  return look;
}

/// The board under dim light with the laser on it (white squares stay below saturation).
inline sim::FrameLook laser_board_look(std::uint64_t seed) {
  sim::FrameLook look;
  look.ambient = 70;
  look.background = 10;
  look.read_noise = 1.5;
  look.speckle = 0.1;
  look.blur_px = 0.6;
  look.seed = seed;
  return look;
}

inline drivers::profiler::ChessboardSpec calibration_spec() {
  return drivers::profiler::ChessboardSpec{cv::Size(9, 6), 10};
}

/// The rendered calibration images and the camera calibrated from them (made once per test
/// program).
struct RenderedCalibration {
  sim::CameraModel truth = profiler_camera();
  sim::LaserSheet laser = profiler_laser(150);
  sim::ChessboardTarget board = calibration_board();
  std::vector<drivers::profiler::NamedImage> boards;  ///< camera views, laser poses included
  std::vector<drivers::profiler::NamedImage> lasers;  ///< laser on the boards, with laser-off
                                                      ///< images
  drivers::profiler::CameraCalibrationResult camera;

  RenderedCalibration() {
    std::uint64_t seed = 100;
    auto views = camera_poses(board);
    const auto at_laser = laser_poses(board);
    views.insert(views.end(), at_laser.begin(), at_laser.end());
    for (const auto& v : views)
      boards.push_back({v.name,
                        sim::render_chessboard(truth, v.camera_from_board, board,
                                               board_look(seed++)),
                        {}});
    for (const auto& v : at_laser)
      lasers.push_back({v.name,
                        sim::render_chessboard(truth, v.camera_from_board, board,
                                               laser_board_look(seed++), &laser),
                        sim::render_chessboard(truth, v.camera_from_board, board,
                                               laser_board_look(seed++))});
    camera = drivers::profiler::calibrate_camera(boards, calibration_spec(), "boards/");
  }
};

inline const RenderedCalibration& rendered_calibration() {
  static const RenderedCalibration r;
  return r;
}

}  // namespace scanmesh::test
