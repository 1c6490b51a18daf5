// `scanmesh inspect`: read a mesh and print its topology and quality report (text or JSON).
// SPDX-License-Identifier: MIT
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "commands.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/intersections.hpp"

namespace scanmesh::cli {
namespace {

struct InspectArgs {
  std::string mesh;
  bool json = false;
};

/// Six significant digits, as %g.
std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

std::string percent(double fraction) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.2f %%", 100.0 * fraction);
  return buf;
}

/// Each boundary loop's width (recon::loop_width: its largest vertex-to-vertex distance, what
/// `fill --max-width` compares), in the report's order of the loops (most edges first).
std::vector<double> loop_widths(const recon::Mesh& mesh, const recon::MeshReport& r) {
  std::vector<double> widths;
  for (const std::size_t li : recon::loop_report_order(r.loops))
    widths.push_back(recon::loop_width(mesh, r.loops[li].vertices));
  return widths;
}

nlohmann::json to_json(const recon::MeshReport& r, const std::vector<double>& widths,
                       const recon::SelfIntersections& x) {
  nlohmann::json j;
  j["vertices"] = r.vertices;
  j["referenced_vertices"] = r.referenced_vertices;
  j["triangles"] = r.triangles;
  j["degenerate_triangles"] = r.degenerate_triangles;
  j["duplicate_triangles"] = r.duplicate_triangles;
  j["edges"] = r.edges;
  j["boundary_edges"] = r.boundary_edges;
  j["non_manifold_edges"] = r.non_manifold_edges;
  j["non_manifold_vertices"] = r.non_manifold_vertices;
  j["inconsistent_edges"] = r.inconsistent_edges;
  j["orientation_consistent"] = r.orientation_consistent;
  j["boundary_loops"] = r.boundary_loops;
  j["boundary_loop_lengths"] = r.boundary_loop_lengths;
  j["boundary_loop_perimeters"] = r.boundary_loop_perimeters;
  j["boundary_loop_widths"] = widths;
  j["components"] = r.components;
  j["euler_characteristic"] = r.euler_characteristic;
  j["genus"] = r.genus;
  // chi = 2c - 2g - b holds for manifold surfaces only: elsewhere the number means nothing.
  j["genus_defined"] = r.non_manifold_edges == 0 && r.non_manifold_vertices == 0;
  j["angle_min_deg"] = r.min_angle_deg;
  j["angle_max_deg"] = r.max_angle_deg;
  j["angle_mean_deg"] = r.mean_angle_deg;
  j["frac_min_angle_below_10"] = r.frac_min_angle_below_10;
  j["frac_min_angle_below_20"] = r.frac_min_angle_below_20;
  j["mean_edge_length"] = r.mean_edge_length;
  j["max_edge_length"] = r.max_edge_length;
  j["signed_volume"] = r.signed_volume;
  j["scan_like_vertices"] = recon::scan_like_vertices(r);
  j["self_intersections"] = x.pairs;
  j["self_intersecting_triangles"] = x.triangles;
  nlohmann::json pairs = nlohmann::json::array();
  for (const auto& [a, b] : x.examples) pairs.push_back({a, b});
  j["self_intersection_examples"] = pairs;
  return j;
}

void print_text(const std::string& file, const recon::MeshReport& r,
                const std::vector<double>& widths, const recon::SelfIntersections& x) {
  auto line = [](const char* label, const std::string& value) {
    std::cout << std::left << std::setw(25) << label << value << "\n";
  };
  auto count = [](std::size_t n) { return std::to_string(n); };
  line("mesh", file);
  line("vertices", count(r.vertices) + " (" + count(r.referenced_vertices) + " referenced)");
  line("triangles", count(r.triangles) + " (" + count(r.degenerate_triangles) + " degenerate, " +
                        count(r.duplicate_triangles) + " duplicate)");
  line("edges", count(r.edges) + " (" + count(r.boundary_edges) + " boundary)");
  line("non-manifold edges", count(r.non_manifold_edges));
  line("non-manifold vertices", count(r.non_manifold_vertices));
  line("orientation", std::string(r.orientation_consistent ? "consistent" : "INCONSISTENT") + " (" +
                          count(r.inconsistent_edges) + " inconsistent edges)");
  std::string loops = count(r.boundary_loops);
  if (!r.boundary_loop_lengths.empty()) {
    constexpr std::size_t kShown = 12;
    loops += " (edges:";
    for (std::size_t i = 0; i < r.boundary_loop_lengths.size() && i < kShown; ++i) {
      loops += " " + count(r.boundary_loop_lengths[i]);
    }
    if (r.boundary_loop_lengths.size() > kShown) loops += " ...";
    loops += ")";
  }
  line("boundary loops", loops);
  if (!r.boundary_loop_perimeters.empty()) {
    constexpr std::size_t kShown = 12;
    std::string perimeters;
    for (std::size_t i = 0; i < r.boundary_loop_perimeters.size() && i < kShown; ++i)
      perimeters += (i > 0 ? " " : "") + num(r.boundary_loop_perimeters[i]);
    if (r.boundary_loop_perimeters.size() > kShown) perimeters += " ...";
    line("loop perimeters", perimeters);
    std::string across;
    for (std::size_t i = 0; i < widths.size() && i < kShown; ++i)
      across += (i > 0 ? " " : "") + num(widths[i]);
    if (widths.size() > kShown) across += " ...";
    line("loop widths", across);
  }
  line("components", count(r.components));
  line("euler characteristic", std::to_string(r.euler_characteristic));
  line("genus", r.non_manifold_edges == 0 && r.non_manifold_vertices == 0
                    ? std::to_string(r.genus)
                    : std::to_string(r.genus) + " (not defined: the mesh is not manifold)");
  line("interior angles", "min " + num(r.min_angle_deg) + " deg, max " + num(r.max_angle_deg) +
                              " deg, mean " + num(r.mean_angle_deg) + " deg");
  line("min angle < 10 / 20 deg", percent(r.frac_min_angle_below_10) + " / " +
                                      percent(r.frac_min_angle_below_20) + " of triangles");
  line("edge length", "mean " + num(r.mean_edge_length) + ", max " + num(r.max_edge_length));
  line("signed volume", num(r.signed_volume));
  line("vertices as points", recon::scan_like_vertices(r)
                                 ? "scan-like (evenly spread: `scanmesh reconstruct` can use them)"
                                 : "too few or uneven (a CAD export?): sample the surface with "
                                   "`scanmesh generate --mesh-in` to reconstruct it");
  std::string crossing = count(x.pairs) + " triangle pairs";
  if (x.pairs > 0) {
    crossing += " (" + count(x.triangles) + " triangles; first:";
    for (const auto& [a, b] : x.examples) crossing += " " + count(a) + "/" + count(b);
    crossing += x.examples.size() < x.pairs ? " ...)" : ")";
  }
  line("self-intersections", crossing);
}

int run_inspect(const InspectArgs& args) {
  const recon::Mesh mesh = meshio::read_mesh(args.mesh);
  const recon::MeshReport report = recon::analyze(mesh, true);
  const std::vector<double> widths = loop_widths(mesh, report);
  const recon::SelfIntersections crossing = recon::find_self_intersections(mesh, 8);
  if (args.json) {
    std::cout << to_json(report, widths, crossing).dump() << "\n";
  } else {
    print_text(args.mesh, report, widths, crossing);
  }
  return kExitOk;
}

}  // namespace

void add_inspect_command(CLI::App& app, Runner& run) {
  auto args = std::make_shared<InspectArgs>();
  CLI::App* cmd = app.add_subcommand(
      "inspect", "Print a mesh's topology (manifoldness, orientation, holes, genus, self-intersections) and quality");
  cmd->add_option("MESH", args->mesh, "mesh file: .ply .stl .obj")->required();
  cmd->add_flag("--json", args->json, "print one JSON object instead of the text summary");
  cmd->callback([args, &run] { run = [args] { return run_inspect(*args); }; });
}

}  // namespace scanmesh::cli
