// `scanmesh replay`: a recorded scan journal played back through the same pipeline as a live
// scan; with the recorded meshing parameters it gives the live scan's mesh exactly.
// SPDX-License-Identifier: MIT
#include <memory>
#include <string>
#include <vector>

#include "commands.hpp"
#include "scan_common.hpp"
#include "scanmesh/acquisition/journal_backend.hpp"
#include "scanmesh/acquisition/meshers.hpp"

namespace scanmesh::cli {
namespace {

struct ReplayArgs {
  std::vector<std::string> journals;
  std::string cube;
  std::string mesher;
  double pace = 0;
  ScanOutput out;
  bool progress = false;
};

int run_replay_journal(const ReplayArgs& args) {
  std::vector<std::filesystem::path> segments(args.journals.begin(), args.journals.end());
  for (const auto& s : segments) {
    std::error_code ec;
    if (!std::filesystem::exists(s, ec))
      throw InputError("cannot read " + s.string() + ": No such file or directory");
    if (std::filesystem::is_directory(s, ec))
      throw InputError("cannot read " + s.string() + ": Is a directory");
  }
  acq::ReplayOptions ro;
  ro.speed = args.pace;
  acq::ReplayBackend backend(segments, ro);
  nlohmann::json meshing = backend.parameters().value("meshing", nlohmann::json::object());
  if (!args.cube.empty()) meshing["cube"] = args.cube;
  if (!args.mesher.empty()) meshing["mesher"] = args.mesher;
  acq::Pipeline pipeline(backend, nullptr, acq::make_mesher(meshing));
  const acq::PipelineStats st = run_pipeline(pipeline, args.progress);
  ScanOutput out = args.out;
  out.what = "replay of " + args.journals.front();
  nlohmann::json journals = nlohmann::json::array();
  for (const auto& j : args.journals) journals.push_back(j);
  nlohmann::json extra{{"journals", journals}, {"meshing", meshing}};
  if (backend.parameters().contains("source")) extra["source"] = backend.parameters()["source"];
  return report_scan(pipeline, st, out, extra);
}

}  // namespace

void add_replay_command(CLI::App& app, Runner& run) {
  auto args = std::make_shared<ReplayArgs>();
  CLI::App* cmd = app.add_subcommand(
      "replay", "Mesh a recorded scan journal again through the acquisition pipeline");
  cmd->footer(
      "The journal's records go through the same accumulator and meshing as the live scan, in "
      "their recorded order; with the recorded meshing parameters (the default) the mesh is "
      "the live scan's, byte for byte. Several journals are the segments of one resumed scan, "
      "in order. A journal cut short by a crash is read up to its last whole chunk.");
  cmd->add_option("journal", args->journals, "scan journal(s) (.mcap)")->required();
  cmd->add_option("--cube", args->cube,
                  "cube reduction edge, mm, or 'auto' (default: as the scan recorded)");
  cmd->add_option("--mesher", args->mesher, "'incremental' or 'batch' (default: as recorded)")
      ->check(CLI::IsMember({"incremental", "batch"}));
  cmd->add_option("--pace", args->pace,
                  "playback speed relative to the recording (1: as recorded), 0: as fast as "
                  "possible")
      ->capture_default_str()
      ->check(kNonNegative);
  add_mesh_output_option(*cmd, args->out.output);
  cmd->add_option("--preview", args->out.preview, "also write a shaded picture of the mesh (.png)")
      ->check(png_output());
  cmd->add_flag("--json", args->out.json, "print one JSON object instead of the summary line");
  cmd->add_flag("--progress", args->progress,
                "show a live progress line on stderr: samples, points, triangles, rate, lag");
  cmd->callback([args, &run] { run = [args] { return run_replay_journal(*args); }; });
}

}  // namespace scanmesh::cli
