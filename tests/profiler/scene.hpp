// The rendered profiler scene shared by the profiler tests and bench_profiler: a camera looking
// down on the built-in container part, a line laser beside it, and their true calibration.
// SPDX-License-Identifier: MIT
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <vector>

#include "scanmesh/drivers/profiler/camera.hpp"
#include "scanmesh/sim/bvh.hpp"
#include "scanmesh/sim/laser_frames.hpp"
#include "scanmesh/sim/parts.hpp"

namespace scanmesh::test {

/// The true camera: 640 x 480 (or any size, same field of view), with moderate distortion.
inline sim::CameraModel profiler_camera(int width = 640, int height = 480) {
  sim::CameraModel c;
  const double s = width / 640.0;
  c.width = width;
  c.height = height;
  c.fx = 900 * s;
  c.fy = 902 * s;
  c.cx = (width - 1) / 2.0 + 6.5 * s;
  c.cy = (height - 1) / 2.0 - 4.25 * s;
  c.k1 = -0.12;
  c.k2 = 0.08;
  c.p1 = 0.0006;
  c.p2 = -0.0004;
  c.k3 = 0;
  return c;
}

/// The laser emitter 100 mm beside the camera (towards image -y), its sheet through the camera's
/// x axis direction and the optical axis at 240 mm: the line runs across the image columns.
inline sim::LaserSheet profiler_laser(double power = 180, double sigma_mm = 0.35) {
  sim::LaserSheet s;
  s.origin = {0, -100, 0};
  const Eigen::Vector3d towards = Eigen::Vector3d(0, 100, 240).normalized();
  s.normal = Eigen::Vector3d::UnitX().cross(towards).normalized();
  s.sigma_mm = sigma_mm;
  s.power = power;
  return s;
}

/// Part (scene) frame from camera frame with the camera `height_mm` above the table, looking
/// down at (x_mm, y_mm): camera x along part +x, camera y along part -y, optical axis along -z.
inline Eigen::Isometry3d part_from_camera(double x_mm = 40, double y_mm = 20,
                                          double height_mm = 250) {
  Eigen::Matrix3d r;
  r.col(0) = Eigen::Vector3d(1, 0, 0);
  r.col(1) = Eigen::Vector3d(0, -1, 0);
  r.col(2) = Eigen::Vector3d(0, 0, -1);
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = r;
  t.translation() = Eigen::Vector3d(x_mm, y_mm, height_mm);
  return t;
}

/// The built-in container part and its BVH.
struct PartScene {
  recon::Mesh mesh = sim::make_part("container");
  sim::Bvh bvh{mesh};
};

/// A clean look: faint ambient light, a little blur, no noise.
inline sim::FrameLook clean_look() {
  sim::FrameLook look;
  look.ambient = 20;
  look.blur_px = 0.5;
  return look;
}

/// Speckle, read noise, a strong uneven ambient light and blur.
inline sim::FrameLook noisy_look(std::uint64_t seed = 7) {
  sim::FrameLook look;
  look.ambient = 60;
  look.ambient_gradient = 0.6;
  look.speckle = 0.25;
  look.read_noise = 2.0;
  look.blur_px = 0.7;
  look.seed = seed;
  return look;
}

/// The true calibration of the rendered profiler (camera and sheet) in the profiler's terms.
inline drivers::profiler::ProfilerCalibration true_calibration(const sim::CameraModel& c,
                                                               const sim::LaserSheet& s) {
  drivers::profiler::ProfilerCalibration cal;
  cal.camera.size = cv::Size(c.width, c.height);
  cal.camera.matrix = cv::Matx33d(c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
  cal.camera.distortion = {c.k1, c.k2, c.p1, c.p2, c.k3};
  const Eigen::Vector3d n = s.normal.normalized();
  double d = n.dot(s.origin);
  cv::Vec3d normal(n.x(), n.y(), n.z());
  if (d < 0) {
    normal = -normal;
    d = -d;
  }
  cal.plane = drivers::profiler::LaserPlane{normal, d};
  return cal;
}

}  // namespace scanmesh::test
