// Running a pipeline from the command line and reporting its mesh.
// SPDX-License-Identifier: MIT
#include "scan_common.hpp"

#include <iostream>

#include "commands.hpp"
#include "progress_bar.hpp"
#include "scanmesh/acquisition/pipeline_json.hpp"
#include "scanmesh/preview/render.hpp"

namespace scanmesh::cli {

acq::PipelineStats run_pipeline(acq::Pipeline& pipeline, bool progress) {
  ProgressBar bar(progress);
  pipeline.start();
  while (!pipeline.wait_for(std::chrono::milliseconds(100))) bar.show(pipeline.stats());
  const acq::PipelineStats st = pipeline.stats();
  bar.done(st);
  return st;
}

int report_scan(const acq::Pipeline& pipeline, const acq::PipelineStats& st,
                const ScanOutput& out, nlohmann::json extra) {
  const recon::Mesh& mesh = pipeline.result();
  const bool have_mesh = !mesh.triangles.empty();
  if (have_mesh) write_mesh_file(mesh, out.output, false);
  const recon::MeshReport rep = recon::analyze(mesh);
  if (!out.preview.empty() && have_mesh) {
    preview::RenderOptions options;
    options.title = std::filesystem::path(out.output).filename().string() + ": " +
                    std::to_string(mesh.triangles.size()) + " triangles, " +
                    std::to_string(rep.boundary_loops) + " boundary loops, genus " +
                    std::to_string(rep.genus);
    preview::render_mesh_png(mesh, out.preview, options);
  }
  if (out.json) {
    nlohmann::json j = acq::to_json(st);
    j.update(extra);
    j["output"] = have_mesh ? nlohmann::json(out.output) : nlohmann::json(nullptr);
    if (!out.preview.empty()) j["preview"] = have_mesh ? nlohmann::json(out.preview) : nlohmann::json(nullptr);
    nlohmann::json m;
    m["vertices"] = mesh.vertices.size();
    m["triangles"] = mesh.triangles.size();
    put_topology(m, rep);
    j["mesh"] = m;
    std::cout << j.dump() << "\n";
  } else {
    std::cout << out.what << " " << acq::to_string(st.state)
              << (st.reason.empty() ? "" : " (" + st.reason + ")") << ": " << st.samples_received
              << " samples, " << st.points << " points, " << st.mesh.kept_points << " kept -> "
              << mesh.triangles.size() << " triangles, " << rep.boundary_loops
              << " boundary loops";
    if (have_mesh) std::cout << " -> " << out.output;
    if (!out.preview.empty() && have_mesh) std::cout << ", " << out.preview;
    std::cout << "\n";
  }
  switch (st.state) {
    case acq::PipelineState::kCompleted:
    case acq::PipelineState::kStopped:
      if (!have_mesh)
        throw GeometryError(out.what + ": no surface to mesh (is the part in range?)");
      return kExitOk;
    default:
      return st.reason.rfind("journal:", 0) == 0 ? kExitOutput : kExitDevice;
  }
}

}  // namespace scanmesh::cli
