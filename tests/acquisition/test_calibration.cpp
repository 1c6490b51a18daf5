// Calibration helpers against the simulated scanner: the sphere fit recovers a mounting offset,
// the plane fit reports flatness, the age rule.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include "scanmesh/acquisition/accumulator.hpp"
#include "scanmesh/acquisition/calibration_fit.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/sim/parts.hpp"
#include "scanmesh/sim/rng.hpp"
#include "scanmesh/sim/simulator.hpp"

using namespace scanmesh;
using recon::Vec3;

TEST_CASE("Calibration: a scan of the calibration sphere recovers a mounting offset", "[acq]") {
  // The built-in sphere: radius 20 at the origin (a subdivided icosahedron: facets within 14 um).
  const sim::Scene scene(sim::make_part("sphere"));
  sim::SimConfig c;
  c.sensor = sim::default_sensor(sim::SensorKind::kPoint);
  c.sensor.rate_hz = 500;
  c.path.spacing_mm = 0.4;
  c.path.line_spacing_mm = 1.5;
  const double noise = 0.005;
  c.imperfections.range_noise_mm = noise;
  c.imperfections.seed = 21;
  const sim::Simulator simulator(scene, c);
  const sim::SimulatedScan scan = sim::simulate(simulator);
  // The machine believes the sensor sits 0.3, -0.2, 0.15 mm away from where it really is.
  const Vec3 error(0.3, -0.2, 0.15);
  acq::Calibration believed = simulator.calibration();
  believed.mount.pretranslate(error);
  std::vector<Vec3> pts;
  for (const auto& p :
       acq::points_from_samples(simulator.optics(), believed, scan.stage, scan.sensor))
    pts.push_back(p.point_mm);
  REQUIRE(pts.size() > 2000);
  const auto m = acq::check_mount(pts, 40.0, Vec3::Zero(), believed);
  INFO("fit centre " << m.fit.centre_mm.transpose() << ", rms " << m.fit.rms_mm);
  // The correction undoes the error within the noise and the faceting: the facets lie up to
  // 14 um inside the sphere, which moves a hemisphere's fitted centre down by about 20 um.
  CHECK(std::abs(m.mount_correction_mm.x() + error.x()) < 0.005);
  CHECK(std::abs(m.mount_correction_mm.y() + error.y()) < 0.005);
  CHECK(std::abs(m.mount_correction_mm.z() + error.z()) < 0.03);
  CHECK(m.fit.rms_mm < 0.03);
  // The corrected calibration maps the same samples onto the sphere.
  std::vector<Vec3> fixed;
  for (const auto& p :
       acq::points_from_samples(simulator.optics(), m.corrected, scan.stage, scan.sensor))
    fixed.push_back(p.point_mm);
  const auto again = acq::fit_sphere(fixed, 20.0);
  CHECK(again.centre_mm.norm() < 0.03);
  // A free-radius fit finds the diameter too.
  const auto free = acq::fit_sphere(fixed);
  CHECK(free.radius_mm == Approx(20).margin(0.03));
}

TEST_CASE("Calibration: plane fit and flatness, outliers rejected", "[acq]") {
  sim::Rng rng(4);
  std::vector<Vec3> pts;
  const Vec3 n = Vec3(0.1, -0.2, 1).normalized();
  const Vec3 u = n.unitOrthogonal(), v = n.cross(u);
  for (int i = 0; i < 5000; ++i) {
    const double a = rng.uniform() * 50 - 25, b = rng.uniform() * 50 - 25;
    pts.push_back(Vec3(3, 4, 5) + a * u + b * v + n * (0.01 * rng.gaussian()));
  }
  pts.push_back(Vec3(3, 4, 5) + n * 2.0);  // two stray readings
  pts.push_back(Vec3(3, 4, 5) - n * 3.0);
  const auto f = acq::fit_plane(pts);
  CHECK(f.normal.dot(n) == Approx(1).margin(1e-5));
  CHECK(f.rejected >= 2);
  CHECK(f.rms_mm == Approx(0.01).margin(0.001));
  CHECK(f.flatness_mm < 0.1);
  CHECK(f.flatness_mm > 0.05);
  CHECK_THROWS_AS(acq::fit_plane(std::vector<Vec3>{Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3(2, 2, 2)}),
                  GeometryError);
  CHECK_THROWS_AS(acq::fit_sphere(std::vector<Vec3>{Vec3(0, 0, 0), Vec3(1, 0, 0)}), GeometryError);
}

TEST_CASE("Calibration: a scan refuses a missing or stale calibration", "[acq]") {
  using namespace std::chrono;
  const auto now = system_clock::now();
  const hours limit = hours(24 * 30);
  CHECK(acq::calibration_problem(std::nullopt, now, limit).value().find("no calibration") == 0);
  CHECK_FALSE(acq::calibration_problem(now - hours(24 * 29), now, limit));
  const auto stale = acq::calibration_problem(now - hours(24 * 40), now, limit);
  REQUIRE(stale);
  CHECK(stale->find("40 days old") != std::string::npos);
  CHECK_FALSE(acq::calibration_problem(now - hours(24 * 400), now, hours(0)));  // no limit
}
