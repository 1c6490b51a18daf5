// `scanmesh device read --driver microepsilon-ild1420` end to end: the real binary reads the
// binary stream of an ILD1420 emulator on a pty, scaled by the measuring range GETINFO reports.
// SPDX-License-Identifier: MIT
#ifdef SCANMESH_EXE
#include <catch2/catch.hpp>
#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>

#include "scanmesh/sim/emulators/microepsilon_ild1420.hpp"
#include "support/json_lines.hpp"
#include "support/process.hpp"
#include "support/temp_dir.hpp"

using nlohmann::json;
using scanmesh::test::run_program;
using scanmesh::test::TempDir;

TEST_CASE("device read: an ILD1420 stream through the real binary", "[drivers][cli]") {
  TempDir dir;
  scanmesh::sim::Ild1420EmulatorOptions options;
  options.measuring_range_mm = 25;
  scanmesh::sim::MicroEpsilonIld1420Emulator emu(
      (dir / "rs422").string(), scanmesh::sim::scripted_values({3.0, 12.5, std::nan("")}),
      options);
  emu.start();
  const auto r = run_program(SCANMESH_EXE, dir,
                             {"device", "read", "--driver", "microepsilon-ild1420", "--port",
                              emu.port(), "--samples", "30", "--json"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  int n = 0, ok = 0, no_target = 0;
  std::uint64_t last_seq = 0;
  for (const json& j : scanmesh::test::json_lines(r.out)) {
    const auto seq = j.at("seq").get<std::uint64_t>();
    if (n > 0) CHECK(seq > last_seq);
    last_seq = seq;
    ++n;
    if (j.at("status") == "ok") {
      ++ok;
      // 16-bit raw values over a 25 mm range: one step is 1.02 * 25 / 65520 = 0.39 um
      const double v = j.at("value_mm").get<double>();
      CHECK((std::abs(v - 3.0) < 1e-3 || std::abs(v - 12.5) < 1e-3));
    } else {
      CHECK(j.at("status") == "no_target");
      CHECK(j.at("value_mm").is_null());
      ++no_target;
    }
  }
  CHECK(n == 30);
  CHECK(ok >= 18);
  CHECK(no_target >= 8);
}
#endif
