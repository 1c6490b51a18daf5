// Replays fuzz_reconstruct's seeds and every input it once failed on (fuzz/regressions/
// reconstruct/: add each crash file there when fixing it) through the same case and checks
// (fuzz/reconstruct_case.hpp), in the normal build and under the sanitizers.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "reconstruct_case.hpp"
#include "support/process.hpp"

namespace {

std::vector<std::filesystem::path> files_in(const std::filesystem::path& dir) {
  std::vector<std::filesystem::path> out;
  if (std::filesystem::is_directory(dir))
    for (const auto& e : std::filesystem::directory_iterator(dir))
      if (e.is_regular_file() && e.path().filename().string().front() != '.') out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

/// Runs the case in file f; `triangles` as in run_reconstruct_case.
std::string run_file(const std::filesystem::path& f, std::size_t* triangles = nullptr) {
  const std::string b = scanmesh::test::slurp(f);
  return scanmesh::fuzz::run_reconstruct_case(reinterpret_cast<const std::uint8_t*>(b.data()),
                                              b.size(), triangles);
}

}  // namespace

TEST_CASE("the reconstruction fuzz target's seeds make valid meshes", "[recon][fuzz]") {
  const auto seeds = files_in(std::filesystem::path(SCANMESH_SOURCE_DIR) / "fuzz/seeds/reconstruct");
  REQUIRE(seeds.size() >= 7);  // one per shape, and the option bits
  for (const auto& f : seeds) {
    std::size_t triangles = 0;
    INFO(f.filename().string());
    CHECK(run_file(f, &triangles).empty());
    CHECK(triangles > 0);  // a surface, not a rejected cloud
  }
}

TEST_CASE("inputs the reconstruction fuzz target once failed on keep the promises", "[recon][fuzz]") {
  const auto cases = files_in(std::filesystem::path(SCANMESH_SOURCE_DIR) / "fuzz/regressions/reconstruct");
  REQUIRE_FALSE(cases.empty());
  for (const auto& f : cases) {
    INFO(f.filename().string());
    CHECK(run_file(f).empty());
  }
}
