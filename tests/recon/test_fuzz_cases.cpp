// Replays fuzz_reconstruct's seeds and every input it once failed on (fuzz/regressions/
// reconstruct/: add each crash file there when fixing it) through the same case and checks
// (fuzz/reconstruct_case.hpp), in the normal build and under the sanitizers.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

#include "reconstruct_case.hpp"

namespace {

std::vector<std::filesystem::path> files_in(const std::filesystem::path& dir) {
  std::vector<std::filesystem::path> out;
  if (std::filesystem::is_directory(dir))
    for (const auto& e : std::filesystem::directory_iterator(dir))
      if (e.is_regular_file() && e.path().filename().string().front() != '.') out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<std::uint8_t> bytes_of(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

TEST_CASE("the reconstruction fuzz target's seeds make valid meshes", "[recon][fuzz]") {
  const auto seeds = files_in(std::filesystem::path(SCANMESH_SOURCE_DIR) / "fuzz/seeds/reconstruct");
  REQUIRE(seeds.size() >= 7);  // one per shape, and the option bits
  for (const auto& f : seeds) {
    const std::vector<std::uint8_t> b = bytes_of(f);
    std::size_t triangles = 0;
    INFO(f.filename().string());
    CHECK(scanmesh::fuzz::run_reconstruct_case(b.data(), b.size(), &triangles).empty());
    CHECK(triangles > 0);  // a surface, not a rejected cloud
  }
}

TEST_CASE("inputs the reconstruction fuzz target once failed on keep the promises", "[recon][fuzz]") {
  const auto cases = files_in(std::filesystem::path(SCANMESH_SOURCE_DIR) / "fuzz/regressions/reconstruct");
  for (const auto& f : cases) {
    const std::vector<std::uint8_t> b = bytes_of(f);
    INFO(f.filename().string());
    CHECK(scanmesh::fuzz::run_reconstruct_case(b.data(), b.size()).empty());
  }
}
