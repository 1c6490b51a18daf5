// Recovery of journals left by a crash: files cut at every kind of place, bytes flipped in the
// middle, a writer killed with SIGKILL at 100 random moments, a full disk (RLIMIT_FSIZE). After
// recovery every whole chunk (and every acknowledged sample) is there, bit for bit, and the
// independent reader opens the file.
// SPDX-License-Identifier: MIT
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <fstream>
#include <random>

#include "journal/independent_reader.hpp"
#include "journal/journal_support.hpp"
#include "journal/scenario.hpp"
#include "scanmesh/acquisition/catalog.hpp"
#include "scanmesh/acquisition/journal.hpp"

using namespace scanmesh;
using namespace scanmesh::test;

namespace {

std::string read_bytes(const std::filesystem::path& p) { return slurp(p); }

void write_bytes(const std::filesystem::path& p, std::string_view bytes) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

std::vector<Item> read_items(const std::filesystem::path& p, bool tolerate = false) {
  Recorder rec;
  acq::ReadOptions o;
  o.tolerate_damage = tolerate;
  (void)acq::read_journal(p, rec, o);
  return rec.items;
}

/// A closed journal of the scenario (`ms` milliseconds) and what was written into it.
std::vector<Item> closed_journal(const std::filesystem::path& p, int ms) {
  acq::JournalWriter w(p);
  Scenario sc;
  sc.milliseconds = ms;
  auto items = write_scenario(w, sc);
  w.close();
  return items;
}

/// `read` is `written` with one contiguous run of items missing: returns its length.
std::optional<std::size_t> missing_run(const std::vector<Item>& read,
                                       const std::vector<Item>& written) {
  std::size_t a = 0;
  while (a < read.size() && a < written.size() && read[a] == written[a]) ++a;
  if (read.size() > written.size()) return std::nullopt;
  const std::size_t gap = written.size() - read.size();
  for (std::size_t i = a; i < read.size(); ++i)
    if (!(read[i] == written[i + gap])) return std::nullopt;
  return gap;
}

/// A child process with its stdout on a pipe.
struct Child {
  pid_t pid = -1;
  FILE* out = nullptr;
};

Child spawn(const std::vector<std::string>& args) {
  int fds[2];
  REQUIRE(::pipe2(fds, O_CLOEXEC) == 0);
  std::vector<std::string> a = args;
  std::vector<char*> argv;
  for (auto& s : a) argv.push_back(s.data());
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    ::dup2(fds[1], 1);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  ::close(fds[1]);
  return {pid, ::fdopen(fds[0], "r")};
}

int reap(pid_t pid) {
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return status;
}

}  // namespace

TEST_CASE("A journal cut anywhere is recovered with every whole chunk", "[acq][journal]") {
  TempDir dir;
  const auto whole = dir / "whole.mcap";
  const std::vector<Item> written = closed_journal(whole, 400);
  const std::string bytes = read_bytes(whole);
  const auto original = acq::check_journal(whole);
  REQUIRE(original.scan.complete());
  const auto& chunks = original.scan.chunks;

  // Cut points: inside the magic, the header, a schema, chunks, message indexes, the summary,
  // the footer, and 40 random ones.
  std::vector<std::uint64_t> cuts{0, 3, 8, 20, 60};
  for (std::size_t k : {std::size_t{0}, chunks.size() / 2, chunks.size() - 1}) {
    const auto& c = chunks[k];
    cuts.push_back(c.offset);
    cuts.push_back(c.offset + 5);
    cuts.push_back(c.offset + c.length / 2);
    cuts.push_back(c.offset + c.length);      // chunk whole, its index missing
    cuts.push_back(c.offset + c.length + 7);  // inside its index
    cuts.push_back(c.offset + c.length + c.message_index_length);
  }
  cuts.push_back(*original.scan.data_end_offset);
  cuts.push_back(*original.scan.data_end_offset + 13);
  cuts.push_back(*original.scan.data_end_offset + 100);
  cuts.push_back(bytes.size() - 1);
  std::mt19937_64 rng(54);
  for (int i = 0; i < 40; ++i) cuts.push_back(rng() % bytes.size());

  std::vector<std::filesystem::path> recovered;
  for (const std::uint64_t cut : cuts) {
    INFO("cut at byte " << cut);
    const auto p = dir / ("cut" + std::to_string(cut) + ".mcap");
    write_bytes(p, std::string_view(bytes).substr(0, cut));
    const auto before = acq::check_journal(p);
    CHECK_FALSE(before.scan.complete());
    std::size_t whole_chunks = 0;
    for (const auto& c : chunks) whole_chunks += c.offset + c.length <= cut ? 1 : 0;
    CHECK(before.scan.chunks.size() == whole_chunks);

    const auto rec = acq::recover_journal(p);
    CHECK_FALSE(rec.mcap.already_complete);
    CHECK(rec.mcap.kept_chunks == whole_chunks);
    CHECK(rec.kept.samples == before.samples);
    CHECK(rec.mcap.cut_offset + rec.mcap.cut_bytes == cut);
    const auto after = acq::check_journal(p);
    CHECK(after.scan.complete());
    CHECK(after.scan.data_section_crc_ok);
    CHECK(after.samples == before.samples);
    const auto items = read_items(p);
    REQUIRE(items.size() <= written.size());
    CHECK(std::equal(items.begin(), items.end(), written.begin()));
    CHECK(sample_count(items) == before.samples);
    // Idempotent: a second recover finds nothing to do.
    CHECK(acq::recover_journal(p).mcap.already_complete);
    recovered.push_back(p);
  }

  SECTION("the independent reader opens every recovered file") {
    const auto out = independent_read(recovered, true);
    for (std::size_t i = 0; i < out.size(); ++i) {
      INFO(recovered[i].filename().string() << ": " << out[i].value("error", std::string()));
      CHECK_FALSE(out[i].contains("error"));
      CHECK(out[i]["stream"]["done"] == true);
      std::uint64_t samples = 0;
      for (const auto& [id, c] : out[i]["counts"].items())
        samples += c["samples"].get<std::uint64_t>();
      CHECK(samples == acq::check_journal(recovered[i]).samples);
    }
  }
}

TEST_CASE("Bytes flipped in the middle: the damaged chunk is reported and skipped, the rest kept",
          "[acq][journal]") {
  TempDir dir;
  const auto whole = dir / "whole.mcap";
  const std::vector<Item> written = closed_journal(whole, 1000);
  const std::string bytes = read_bytes(whole);
  const auto original = acq::check_journal(whole);
  const auto& victim = original.scan.chunks[original.scan.chunks.size() / 2];
  const std::size_t max_chunk_items = 64 * 1024 / 25 + 64;

  struct Case {
    std::string name;
    std::uint64_t at;
    bool chunk_lost;
  };
  const std::vector<Case> cases{
      {"in the chunk's records", victim.offset + victim.length / 2, true},
      {"in the chunk's length field", victim.offset + 3, true},
      {"in the chunk's CRC", victim.offset + 33, true},
      {"in a message index record", victim.offset + victim.length + 20, false},
  };
  std::vector<std::filesystem::path> recovered;
  for (const Case& c : cases) {
    DYNAMIC_SECTION("flipped " << c.name) {
      const auto p = dir / "flipped.mcap";
      std::string damaged = bytes;
      for (std::uint64_t k = c.at; k < c.at + 4; ++k) damaged[k] = static_cast<char>(~damaged[k]);
      write_bytes(p, damaged);

      const auto r = acq::check_journal(p);
      CHECK_FALSE(r.scan.complete());
      CHECK_FALSE(r.scan.torn_tail);
      REQUIRE(r.scan.damage.size() == 1);
      const auto& d = r.scan.damage[0];
      if (c.chunk_lost) {
        CHECK(d.offset == victim.offset);
        CHECK(d.length == victim.length + victim.message_index_length);
        CHECK(r.scan.chunks.size() == original.scan.chunks.size() - 1);
      } else {
        CHECK(d.offset == victim.offset + victim.length);
        CHECK(r.scan.chunks.size() == original.scan.chunks.size());
      }
      CHECK_FALSE(r.scan.summary_ok);  // the summary indexes the chunk that is gone
      CHECK(acq::to_json(r)["damage"][0]["offset"] == d.offset);

      // Strict reading stops there, naming the file and the offset.
      CHECK_THROWS_WITH(read_items(p), Catch::Contains(p.string()) &&
                                           Catch::Contains("byte " + std::to_string(d.offset)));
      // Tolerant reading skips exactly the damaged chunk.
      const auto items = read_items(p, true);
      const auto gap = missing_run(items, written);
      REQUIRE(gap.has_value());
      if (c.chunk_lost) {
        CHECK(*gap > 0);
        CHECK(*gap <= max_chunk_items);
      } else {
        CHECK(*gap == 0);
      }

      const auto rec = acq::recover_journal(p);
      CHECK(rec.mcap.wrapped_regions == 1);
      CHECK(rec.mcap.reindexed_chunks == (c.chunk_lost ? 0 : 1));
      const auto after = acq::check_journal(p);
      CHECK(after.scan.complete());
      CHECK(after.scan.wrapped_damage.size() == 1);
      CHECK(after.samples == r.samples);
      CHECK(missing_run(read_items(p), written) == gap);
      const auto out = independent_read({p}, true).at(0);
      INFO(out.value("error", std::string()));
      CHECK_FALSE(out.contains("error"));
      CHECK(out["stream"]["done"] == true);
      CHECK(out["stream"]["records"]["Unknown"] == 1);  // the wrapped region
    }
  }
}

TEST_CASE("Recovery refuses a journal that a writer still holds", "[acq][journal]") {
  TempDir dir;
  const auto p = dir / "open.mcap";
  acq::JournalWriter w(p);
  const auto s = w.add_stage("xyz");
  w.write_stage(s, stage_sample(0));
  w.flush();
  CHECK_THROWS_WITH(acq::recover_journal(p), Catch::Contains("another process is writing it"));
  CHECK(acq::check_journal(p).being_written);
}

TEST_CASE("SIGKILL at 100 random moments: after recovery every acknowledged sample is there",
          "[acq][journal][slow]") {
  TempDir dir;
  std::mt19937_64 rng(20260514);
  std::vector<std::filesystem::path> files;
  std::uint64_t total_acked = 0;
  int before_any_ack = 0;
  for (int round = 0; round < 100; ++round) {
    const auto p = dir / ("kill" + std::to_string(round) + ".mcap");
    // Up to ~150k samples (about 5 MB, 0.9 s of sample time); one round in ten right after
    // the file exists.
    const std::uint64_t target = round % 10 == 0 ? 0 : rng() % 150'000;
    Child c = spawn({JOURNAL_CRASH_WRITER, p.string()});
    std::uint64_t acked = 0;
    bool open = false;
    char line[128];
    while (std::fgets(line, sizeof line, c.out) != nullptr) {
      const std::string s(line);
      if (s == "open\n") open = true;
      if (s.rfind("acked ", 0) == 0) acked = std::stoull(s.substr(6));
      if (open && acked >= target) break;
    }
    ::kill(c.pid, SIGKILL);
    const int status = reap(c.pid);
    std::fclose(c.out);
    INFO("round " << round << ": killed after " << acked << " acknowledged samples");
    REQUIRE(open);
    REQUIRE(WIFSIGNALED(status));
    before_any_ack += acked == 0 ? 1 : 0;
    total_acked += acked;

    const auto rec = acq::recover_journal(p);
    CHECK(rec.kept.samples >= acked);
    CHECK(rec.mcap.before.damage.empty());
    // Strict read of the recovered file: complete, every sample the scenario's, in order.
    ScenarioChecker checker;
    const auto after = acq::read_journal(p, checker);
    CHECK(after.scan.complete());
    CHECK(checker.problem.empty());
    CHECK(checker.samples == rec.kept.samples);
    CHECK(checker.samples >= acked);
    files.push_back(p);
  }
  CHECK(before_any_ack >= 10);
  CHECK(total_acked > 100 * 50'000);
  const auto out = independent_read(files, true);
  for (std::size_t i = 0; i < out.size(); ++i) {
    INFO(files[i].filename().string() << ": " << out[i].value("error", std::string()));
    CHECK_FALSE(out[i].contains("error"));
  }
}

TEST_CASE("A full disk (RLIMIT_FSIZE) stops the journal with an error naming it; nothing is lost",
          "[acq][journal]") {
  TempDir dir;
  const auto p = dir / "full.mcap";
  constexpr rlim_t kLimit = 3'000'000;
  const auto db = dir / "catalog.sqlite";
  const RunResult r = run_program(JOURNAL_CRASH_WRITER, dir,
                                  {p.string(), "--quiet", "--catalog", db.string()}, kLimit);
  CHECK(r.status == 3);
  CHECK_THAT(r.err, Catch::Contains("journal " + p.string()) && Catch::Contains("File too large") &&
                        Catch::Contains("samples recorded"));
  REQUIRE(r.out.rfind("acked ") != std::string::npos);
  const std::uint64_t acked = std::stoull(r.out.substr(r.out.rfind("acked ") + 6));
  CHECK(acked > 50'000);
  // The file ends on a whole chunk: no torn tail, no damage; only the summary is missing.
  CHECK(std::filesystem::file_size(p) <= kLimit);
  const auto before = acq::check_journal(p);
  CHECK_FALSE(before.scan.torn_tail);
  CHECK(before.scan.damage.empty());
  CHECK_FALSE(before.scan.data_end_offset.has_value());
  CHECK(before.samples == acked);
  const auto rec = acq::recover_journal(p);
  CHECK(rec.mcap.cut_bytes == 0);
  CHECK(acq::check_journal(p).scan.complete());
  ScenarioChecker checker;
  (void)acq::read_journal(p, checker);
  CHECK(checker.problem.empty());
  CHECK(checker.samples == acked);
  // The catalog says why the scan stopped.
  const auto scans = acq::Catalog::open_read_only(db).scans();
  REQUIRE(scans.size() == 1);
  CHECK(scans[0].state == acq::ScanState::kFailed);
  CHECK_THAT(scans[0].stop_reason,
             Catch::Contains(p.string()) && Catch::Contains("File too large"));
  CHECK(scans[0].samples == acked);
  REQUIRE(scans[0].segments.size() == 1);
  CHECK(scans[0].segments[0].state == "closed");
  CHECK(scans[0].segments[0].samples == acked);
}
