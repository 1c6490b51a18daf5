// Replays fuzz_journal's seeds (fuzz/seeds/journal/: journals whole, torn, damaged, truncated in
// the header) through the fuzz target's case (fuzz/journal_case.hpp), in the normal build and
// under the sanitizers.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <filesystem>

#include "journal_case.hpp"
#include "support/process.hpp"

TEST_CASE("fuzz_journal's seeds run through the reader, check and recovery", "[acq][journal]") {
  const auto dir = std::filesystem::path(SCANMESH_SOURCE_DIR) / "fuzz/seeds/journal";
  REQUIRE(std::filesystem::is_directory(dir));
  int mcap = 0;
  int files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    const std::string bytes = scanmesh::test::slurp(e.path());
    INFO(e.path().filename().string());
    mcap += scanmesh::fuzz::run_journal_case(reinterpret_cast<const std::uint8_t*>(bytes.data()),
                                             bytes.size())
                ? 1
                : 0;
    ++files;
  }
  CHECK(files >= 5);
  CHECK(mcap == files);
}
