// Touch-trigger probing through every stage driver: a sphere of known radius on the emulators'
// reference mesh, probed at 50 points over the real transports, gives back its centre and radius
// within the emulators' noise; a probe that never triggers gives "no contact", a deflected probe
// "triggered before the approach", and never a made-up point.
// SPDX-License-Identifier: MIT
#include <Eigen/Dense>
#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/grbl/device.hpp"
#include "scanmesh/drivers/ippdme/device.hpp"
#include "scanmesh/drivers/modbus_stage/device.hpp"
#include "scanmesh/drivers/probing.hpp"
#include "scanmesh/drivers/transports/tcp_stream.hpp"
#include "scanmesh/sim/emulators/grbl.hpp"
#include "scanmesh/sim/emulators/ippdme.hpp"
#include "scanmesh/sim/emulators/modbus_stage.hpp"
#include "support/stage_harness.hpp"

using namespace std::chrono_literals;
namespace drv = scanmesh::drivers;

namespace {

constexpr double kSphereRadius = 20.0;  // sim's `sphere` part, centred at the origin
constexpr double kTip = 1.0;
constexpr double kNoise = 0.003;

scanmesh::sim::StageMotionOptions sphere_motion() {
  scanmesh::sim::StageMotionOptions o;
  o.limits.linear_velocity_mm_s = 1000;
  o.limits.linear_accel_mm_s2 = 20000;
  o.probe.scene = scanmesh::test::part_scene("sphere");
  o.probe.tip_radius_mm = kTip;
  o.probe.noise_mm = kNoise;
  o.probe.seed = 7;
  o.start = {0, 0, 40, 0};
  return o;
}

struct SphereFit {
  Eigen::Vector3d centre;
  double radius = 0;
  double rms = 0;
};

/// Algebraic least-squares sphere: x^2+y^2+z^2 + D x + E y + F z + G = 0.
SphereFit fit_sphere(const std::vector<Eigen::Vector3d>& p) {
  Eigen::MatrixXd a(p.size(), 4);
  Eigen::VectorXd b(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) {
    a.row(i) << p[i].x(), p[i].y(), p[i].z(), 1.0;
    b(i) = -p[i].squaredNorm();
  }
  const Eigen::Vector4d s = a.colPivHouseholderQr().solve(b);
  SphereFit f;
  f.centre = -0.5 * s.head<3>();
  f.radius = std::sqrt(f.centre.squaredNorm() - s(3));
  double sum = 0;
  for (const auto& q : p) sum += std::pow((q - f.centre).norm() - f.radius, 2);
  f.rms = std::sqrt(sum / static_cast<double>(p.size()));
  return f;
}

/// 50 approach directions over the upper part of the sphere (a fixture holds the lower part).
std::vector<Eigen::Vector3d> directions() {
  std::vector<Eigen::Vector3d> out;
  const double golden = std::numbers::pi * (3 - std::sqrt(5.0));
  for (int i = 0; i < 50; ++i) {
    const double z = 0.95 - 1.05 * i / 49.0;  // from near the pole to just below the equator
    const double r = std::sqrt(1 - z * z);
    out.emplace_back(r * std::cos(golden * i), r * std::sin(golden * i), z);
  }
  return out;
}

void probe_sphere(drv::MotionStage& stage) {
  std::vector<Eigen::Vector3d> points;
  for (const Eigen::Vector3d& u : directions()) {
    const Eigen::Vector3d from = u * (kSphereRadius + kTip + 3.0);
    drv::ProbeRequest q;
    q.x_mm = from.x();
    q.y_mm = from.y();
    q.z_mm = from.z();
    q.i = -u.x();
    q.j = -u.y();
    q.k = -u.z();
    q.travel_mm = 6;
    q.tip_radius_mm = kTip;
    q.feed_mm_min = 3000;
    q.approach_feed_mm_min = 60000;
    // Around the sphere, not through it: up to the safe height, over, then down to the start.
    stage.move_to({std::nullopt, std::nullopt, 40.0, std::nullopt}, 60000);
    stage.move_to({from.x(), from.y(), std::nullopt, std::nullopt}, 60000);
    const drv::ProbePoint p = drv::probe_point(stage, q);
    REQUIRE(p.outcome == drv::ProbePoint::Outcome::kPoint);
    CHECK(p.travel_mm == Approx(3.0).margin(0.05));
    points.emplace_back(p.x_mm, p.y_mm, p.z_mm);
  }
  const SphereFit f = fit_sphere(points);
  INFO("centre " << f.centre.transpose() << " radius " << f.radius << " rms " << f.rms);
  // The part is a subdivided icosahedron (facets sag up to ~0.02 mm inside the radius) plus the
  // latch noise and the reports' quantisation (1 um).
  CHECK(f.centre.norm() < 0.03);
  CHECK(f.radius == Approx(kSphereRadius).margin(0.04));
  CHECK(f.rms < 0.03);
  stage.move_to({std::nullopt, std::nullopt, 40.0, std::nullopt}, 60000);
  stage.wait_idle(5s);
  // Nothing there: the probe never triggers, and says so.
  drv::ProbeRequest miss;
  miss.x_mm = 60;
  miss.y_mm = 0;
  miss.z_mm = 10;
  miss.i = 1;
  miss.j = 0;
  miss.k = 0;
  miss.travel_mm = 5;
  miss.tip_radius_mm = kTip;
  miss.feed_mm_min = 3000;
  miss.approach_feed_mm_min = 60000;
  CHECK(drv::probe_point(stage, miss).outcome == drv::ProbePoint::Outcome::kNoContact);
}

}  // namespace

TEST_CASE("probing a sphere through the GRBL driver", "[drivers][probe][grbl][slow]") {
  scanmesh::test::TempDir dir;
  scanmesh::sim::GrblEmulatorOptions o;
  o.motion = sphere_motion();
  scanmesh::sim::GrblEmulator emulator((dir / "grbl").string(), o);
  emulator.start();
  drv::grbl::Device stage(scanmesh::test::fast_stage_options("grbl-probe"),
                          scanmesh::test::pty_serial_factory("grbl-probe", (dir / "grbl").string(), 115200));
  stage.open();
  stage.start({});
  probe_sphere(stage);
  SECTION("a deflected probe is refused, not measured") {
    drv::ProbeRequest q;
    q.x_mm = 0;
    q.y_mm = 0;
    q.z_mm = kSphereRadius + 0.5;  // the tip already in the surface
    q.travel_mm = 3;
    q.tip_radius_mm = kTip;
    q.approach_feed_mm_min = 60000;
    CHECK(drv::probe_point(stage, q).outcome ==
          drv::ProbePoint::Outcome::kTriggeredBeforeApproach);
  }
  SECTION("a probe that never triggers") {
    emulator.set_probe_never_triggers(true);
    drv::ProbeRequest q;
    q.x_mm = 0;
    q.y_mm = 0;
    q.z_mm = 24;
    q.travel_mm = 6;
    q.tip_radius_mm = kTip;
    q.feed_mm_min = 3000;
    q.approach_feed_mm_min = 60000;
    stage.move_to({std::nullopt, std::nullopt, 40.0, std::nullopt}, 60000);
    CHECK(drv::probe_point(stage, q).outcome == drv::ProbePoint::Outcome::kNoContact);
  }
  drv::ProbeRequest no_direction;
  no_direction.k = 0;
  CHECK_THROWS_AS(drv::probe_point(stage, no_direction), scanmesh::ConfigError);
  stage.close();
}

TEST_CASE("probing a sphere through the Modbus stage driver", "[drivers][probe][modbus_stage][slow]") {
  auto map = drv::modbus_stage::leadshine_pr_map();
  map.max_speed_units_s = 1000;
  map.default_accel_units_s2 = 20000;  // the emulated axes' own limit: quick approaches
  for (auto& a : map.axes) a.min = a.max = 0;
  auto model = std::make_shared<scanmesh::sim::ModbusStageModel>(
      scanmesh::sim::ModbusStageOptions{map, sphere_motion()});
  scanmesh::sim::ModbusTcpEmulator emulator(nullptr, {}, 1, 0);
  emulator.set_handler(model);
  emulator.start();
  drv::modbus_stage::Device stage(scanmesh::test::fast_stage_options("modbus-probe"),
                                  scanmesh::test::tcp_modbus_factory("modbus-probe", emulator.port(), 150ms),
                                  map);
  stage.open();
  stage.start({});
  probe_sphere(stage);
  stage.close();
}

TEST_CASE("probing a sphere through the I++ DME driver", "[drivers][probe][ippdme][slow]") {
  scanmesh::sim::IppDmeEmulatorOptions o;
  o.motion = sphere_motion();
  scanmesh::sim::IppDmeEmulator emulator(o);
  emulator.start();
  drv::ippdme::Device stage(scanmesh::test::fast_stage_options("cmm-probe"),
                            [port = emulator.port()] {
                              return drv::open_tcp_stream("cmm-probe", "127.0.0.1", port, 150ms);
                            });
  stage.open();
  stage.start({});
  probe_sphere(stage);
  stage.close();
}
