// The journal tests' independent MCAP reader: node read.js (@mcap/core), installed into the
// build tree by the CTest fixture (tests/journal/mcap-reader/install.sh).
// SPDX-License-Identifier: MIT
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "support/process.hpp"
#include "support/temp_dir.hpp"

namespace scanmesh::test {

/// Runs the independent reader (node read.js, installed by the CTest fixture) on `files`; one
/// JSON object per file. Fails the test with the reader's own words when it cannot run.
inline std::vector<nlohmann::json> independent_read(const std::vector<std::filesystem::path>& files,
                                                    bool counts_only) {
  const std::filesystem::path dir = SCANMESH_MCAP_READER_DIR;
  const std::string node = SCANMESH_NODE;
  if (node.empty())
    throw std::runtime_error(
        "node was not found when the build was configured; scripts/setup.sh "
        "installs Debian's nodejs");
  if (!std::filesystem::exists(dir / "node_modules" / "@mcap" / "core"))
    throw std::runtime_error("the independent MCAP reader is not installed in " + dir.string() +
                             ": run the tests with ctest (its fixture runs " +
                             "tests/journal/mcap-reader/install.sh) or that script by hand");
  TempDir tmp;
  std::vector<std::string> args{(dir / "read.js").string()};
  if (counts_only) args.push_back("--counts");
  for (const auto& f : files) args.push_back(f.string());
  const RunResult r = run_program(node, tmp, args);
  std::vector<nlohmann::json> out;
  std::istringstream lines(r.out);
  for (std::string line; std::getline(lines, line);)
    if (!line.empty()) out.push_back(nlohmann::json::parse(line));
  if (out.size() != files.size())
    throw std::runtime_error("read.js printed " + std::to_string(out.size()) + " results for " +
                             std::to_string(files.size()) + " files (status " +
                             std::to_string(r.status) + "): " + r.err);
  return out;
}

}  // namespace scanmesh::test
