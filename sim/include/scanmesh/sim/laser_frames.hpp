// What a camera beside a line laser sees: 8-bit frames of laser sheets on a mesh (ray cast
// through a pinhole camera with lens distortion) with the true line centre per column, and
// frames of chessboards at given poses, so extraction and calibration are tested against truth.
// SPDX-License-Identifier: MIT
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "scanmesh/recon/mesh.hpp"
#include "scanmesh/sim/bvh.hpp"

namespace scanmesh::sim {

/// A pinhole camera with OpenCV's distortion model (k1 k2 p1 p2 k3). Camera frame as OpenCV's:
/// x right, y down, z forward, mm; pixel centres at integer coordinates.
struct CameraModel {
  int width = 640;
  int height = 480;
  double fx = 800;
  double fy = 800;
  double cx = 319.5;
  double cy = 239.5;
  double k1 = 0, k2 = 0, p1 = 0, p2 = 0, k3 = 0;

  /// Pixel of a camera-frame point with z > 0 (distortion applied).
  Eigen::Vector2d project(const recon::Vec3& p) const;
  /// The undistorted ray (x, y, 1) through pixel (u, v): the distortion inverted by fixed-point
  /// iteration to 1e-12.
  recon::Vec3 ray(double u, double v) const;
};

/// A laser sheet: the plane through `origin` with unit `normal` (camera frame), lit with a
/// Gaussian profile across it (standard deviation sigma_mm), emitted from `origin` (which casts
/// shadows). power: grey level it adds on a white (albedo 1) surface it meets head-on.
struct LaserSheet {
  recon::Vec3 origin{0, 0, 0};
  recon::Vec3 normal{0, 1, 0};
  double sigma_mm = 0.2;
  double power = 180;
};

/// How the frame looks: light, noise and optics. Grey levels on the 0..255 scale.
struct FrameLook {
  double ambient = 20;           ///< level of a white surface facing the camera in ambient light
  double ambient_gradient = 0;   ///< ambient changes by this fraction from left to right
  double background = 4;         ///< level where the ray meets nothing
  double albedo = 0.8;           ///< of the mesh
  double speckle = 0;            ///< laser speckle contrast (std / mean of a multiplicative factor)
  double read_noise = 0;         ///< additive Gaussian noise, levels
  double blur_px = 0;            ///< Gaussian blur of the optics, pixels (0: none)
  int supersample = 4;           ///< samples per pixel and axis where light changes fast
  std::uint64_t seed = 1;
};

/// A rendered laser frame and the truth: crossing[k][u] is the row where sheet k's centre plane
/// meets the surface in column u (sub-pixel, continuous), NaN where it does not, where it meets
/// it more than once or where that point is in shadow; truth[k][u] is the same where the
/// surface within four rows of it is one continuous, lit piece (a whole line is seen), NaN
/// elsewhere.
struct LaserFrame {
  cv::Mat image;  ///< CV_8UC1
  cv::Mat laser;  ///< CV_32FC1: the laser's light alone, blurred, before speckle and noise
  std::vector<std::vector<double>> truth;
  std::vector<std::vector<double>> crossing;
};

/// Renders `mesh` (its BVH; in the scene frame) seen by `camera` at `scene_from_camera`, lit by
/// ambient light and by `sheets` (given in the camera frame; none for a laser-off frame).
LaserFrame render_laser_frame(const Bvh& bvh, const Eigen::Isometry3d& scene_from_camera,
                              const CameraModel& camera, const std::vector<LaserSheet>& sheets,
                              const FrameLook& look);

/// A printed chessboard: cols x rows inner corners (OpenCV's pattern size), squares of
/// square_mm, a white margin around the squares. Board frame: origin at the first inner corner,
/// x along the cols, y along the rows, the board in z = 0 (OpenCV's object points).
struct ChessboardTarget {
  int cols = 9;
  int rows = 6;
  double square_mm = 10;
  double margin_mm = 10;
  double black = 0.06;  ///< albedos
  double white = 0.85;
};

/// Renders the chessboard at `camera_from_board`, optionally with a laser sheet on it. Its
/// edges are anti-aliased exactly for straight edges (each edge covers a pixel by the fraction
/// its distance in pixels gives), so corners carry no sampling bias. The mesh-less parts of
/// `look` apply: ambient (on white: ambient * white), gradient, background, speckle, noise,
/// blur, seed (not supersample).
cv::Mat render_chessboard(const CameraModel& camera, const Eigen::Isometry3d& camera_from_board,
                          const ChessboardTarget& board, const FrameLook& look,
                          const LaserSheet* laser = nullptr);

}  // namespace scanmesh::sim
