// The simulated scanner's options (shared by simulate and scan).
// SPDX-License-Identifier: MIT
#include "sim_options.hpp"

#include "commands.hpp"
#include "scanmesh/sim/parts.hpp"

namespace scanmesh::cli {

void add_sim_scan_options(CLI::App* cmd, sim::ScanSettings& a) {
  cmd->add_option("--sensor", a.sensor, "sensor model")
      ->capture_default_str()
      ->check(CLI::IsMember({"point", "line", "probe"}));
  cmd->add_option("--path", a.path, "scan path")
      ->capture_default_str()
      ->check(CLI::IsMember({"raster", "serpentine", "rotary", "views"}));
  cmd->add_option("--spacing", a.spacing_mm,
                  "sample spacing along the lines at cruise speed, mm (default 0.2; probe: "
                  "touch spacing, default 5)")
      ->check(kPositive);
  cmd->add_option("--line-spacing", a.line_spacing_mm,
                  "distance between scan lines, mm (default: 5 x spacing; line profiler: 0.8 "
                  "profile widths)")
      ->check(kPositive);
  cmd->add_option("--noise", a.noise_mm, "Gaussian range noise (sigma), mm")
      ->capture_default_str()
      ->check(kNonNegative);
  cmd->add_option("--dropout", a.dropout, "probability that a valid reading drops out")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--spike", a.spike, "probability that a valid reading is a random spike")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--missing", a.missing, "probability that a measurement never arrives")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 0.99));
  cmd->add_option("--stage-noise", a.stage_noise_mm,
                  "Gaussian noise on reported stage positions (sigma), mm")
      ->capture_default_str()
      ->check(kNonNegative);
  cmd->add_option("--latency-us", a.latency_us,
                  "sensor latency relative to the stage clock, microseconds")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e6));
  cmd->add_option("--speed", a.speed_mm_s,
                  "line speed, mm/s (sets the sample rate: speed / spacing); probe: approach "
                  "speed")
      ->capture_default_str()
      ->check(kPositive);
  cmd->add_option("--accel", a.accel_mm_s2, "axis acceleration limit, mm/s^2")
      ->capture_default_str()
      ->check(kPositive);
  cmd->add_option("--views", a.views, "number of table angles for --path views")
      ->capture_default_str()
      ->check(CLI::Range(1, 360));
  cmd->add_option("--profile-points", a.profile_points, "points per profile (line sensor)")
      ->capture_default_str()
      ->check(CLI::Range(1, 65536));
  cmd->add_option("--threads", a.threads, "ray-casting threads (0: all cores)")
      ->capture_default_str();
  cmd->add_option("--seed", a.seed, "random seed (same seed, same bytes)")->capture_default_str();
}

recon::Mesh load_scan_target(const std::string& part_or_mesh) {
  for (const auto& name : sim::part_names())
    if (name == part_or_mesh) return sim::make_part(name);
  recon::Mesh mesh = meshio::read_mesh(part_or_mesh);
  if (mesh.triangles.empty())
    throw InputError(part_or_mesh + ": no triangles to scan (a point cloud?)");
  return mesh;
}

}  // namespace scanmesh::cli
