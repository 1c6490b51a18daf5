// `scanmesh journal check JOURNAL [--json]`: what a scan journal holds and whether it is sound
// (read-only). `scanmesh journal recover JOURNAL [--json]`: after a crash, keeps every good chunk,
// cuts the torn tail and writes the summary and footer. `scanmesh scans [--catalog FILE]
// [--json]`: the scan catalog.
// SPDX-License-Identifier: MIT
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>

#include "commands.hpp"
#include "scanmesh/acquisition/catalog.hpp"
#include "scanmesh/acquisition/journal.hpp"

namespace scanmesh::cli {

namespace {

std::string span_text(const acq::JournalReport& r) {
  const auto& s = r.scan;
  if (s.messages == 0) return "empty";
  char b[96];
  std::snprintf(b, sizeof b, "%.3f s (log time %llu .. %llu ns)",
                static_cast<double>(s.message_end_time - s.message_start_time) * 1e-9,
                static_cast<unsigned long long>(s.message_start_time),
                static_cast<unsigned long long>(s.message_end_time));
  return b;
}

void print_channels(const acq::JournalReport& r) {
  std::printf("%-28s %-10s %10s %12s\n", "channel", "kind", "messages", "samples");
  for (const auto& c : r.channels) {
    std::printf(
        "%-28s %-10s %10llu %12llu%s\n", c.channel.topic.c_str(),
        std::string(acq::to_string(c.channel.kind)).c_str(),
        static_cast<unsigned long long>(c.messages), static_cast<unsigned long long>(c.samples),
        c.undecodable > 0 ? ("  (" + std::to_string(c.undecodable) + " undecodable)").c_str() : "");
  }
}

void print_damage_list(const acq::mcap::ScanReport& s) {
  if (s.damage.empty()) {
    std::printf("damage        none\n");
    return;
  }
  std::printf("damage        %zu region(s), %llu CRC failure(s)\n", s.damage.size(),
              static_cast<unsigned long long>(s.crc_failures));
  for (const auto& d : s.damage)
    std::printf("              byte %llu (%llu bytes): %s\n",
                static_cast<unsigned long long>(d.offset),
                static_cast<unsigned long long>(d.length), d.what.c_str());
}

/// Whether the report says the file is sound: complete, nothing damaged or undecodable.
bool sound(const acq::JournalReport& r) {
  return r.scan.complete() && r.undecodable_messages == 0 && r.scan.unknown_channel_messages == 0;
}

int run_check(const std::string& file, bool as_json) {
  const acq::JournalReport r = acq::check_journal(file);
  if (as_json) {
    std::cout << acq::to_json(r).dump() << "\n";
    return sound(r) ? kExitOk : kExitInput;
  }
  const auto& s = r.scan;
  std::printf("journal       %s (%llu bytes)\n", file.c_str(),
              static_cast<unsigned long long>(s.file_bytes));
  if (r.being_written) {
    std::printf("state         being written by another process (a scan is running)\n");
  } else if (s.complete()) {
    std::printf("state         complete\n");
  } else if (s.torn_tail) {
    std::printf(
        "state         not finished: a torn tail of %llu bytes at byte %llu (a write cut "
        "short); `scanmesh journal recover` finishes it\n",
        static_cast<unsigned long long>(s.torn_bytes),
        static_cast<unsigned long long>(s.torn_offset));
  } else if (!s.data_end_offset) {
    std::printf(
        "state         not finished: no summary (the writer stopped after a whole chunk); "
        "`scanmesh journal recover` finishes it\n");
  } else {
    std::printf(
        "state         not sound (see below); `scanmesh journal recover` rewrites its "
        "summary around the damage\n");
  }
  std::printf("chunks        %zu good\n", s.chunks.size());
  print_damage_list(s);
  if (!s.wrapped_damage.empty())
    std::printf("skipped       %zu damaged region(s) an earlier recover marked\n",
                s.wrapped_damage.size());
  if (s.data_end_offset) {
    std::printf("summary       %s\n", s.summary_ok ? "ok" : "does not match the data");
    for (const auto& p : s.summary_problems) std::printf("              %s\n", p.c_str());
  }
  std::printf("time span     %s\n", span_text(r).c_str());
  std::printf("messages      %llu\n", static_cast<unsigned long long>(s.messages));
  std::printf("samples       %llu\n", static_cast<unsigned long long>(r.samples));
  print_channels(r);
  return sound(r) ? kExitOk : kExitInput;
}

int run_recover(const std::string& file, bool as_json) {
  const acq::JournalRecovery rec = acq::recover_journal(file);
  if (as_json) {
    std::cout << acq::to_json(rec).dump() << "\n";
    return kExitOk;
  }
  const auto& m = rec.mcap;
  std::printf("journal       %s\n", file.c_str());
  if (m.already_complete) {
    std::printf("result        complete already: nothing changed\n");
  } else {
    std::printf("result        recovered: any MCAP reader opens it now\n");
  }
  std::printf("kept          %llu chunks, %llu messages, %llu samples, %s\n",
              static_cast<unsigned long long>(m.kept_chunks),
              static_cast<unsigned long long>(m.kept_messages),
              static_cast<unsigned long long>(rec.kept.samples), span_text(rec.kept).c_str());
  if (!m.already_complete) {
    std::printf("cut           %llu bytes at byte %llu%s\n",
                static_cast<unsigned long long>(m.cut_bytes),
                static_cast<unsigned long long>(m.cut_offset),
                m.before.torn_tail ? " (the torn tail)"
                : m.cut_bytes > 0  ? " (the old summary)"
                                   : "");
    if (m.wrapped_regions > 0)
      std::printf(
          "skipped       %llu damaged region(s) (%llu CRC failures), left in place and "
          "marked so readers step over them\n",
          static_cast<unsigned long long>(m.wrapped_regions),
          static_cast<unsigned long long>(m.before.crc_failures));
    if (m.reindexed_chunks > 0)
      std::printf("reindexed     %llu chunk(s) whose message indexes were missing or damaged\n",
                  static_cast<unsigned long long>(m.reindexed_chunks));
    std::printf("file          %llu -> %llu bytes\n",
                static_cast<unsigned long long>(m.before.file_bytes),
                static_cast<unsigned long long>(m.file_bytes_after));
  }
  print_channels(rec.kept);
  return kExitOk;
}

int run_scans(const std::string& catalog, bool as_json) {
  std::vector<acq::ScanRecord> scans;
  try {
    scans = acq::Catalog::open_read_only(catalog).scans();
  } catch (const acq::CatalogError& e) {
    throw InputError(e.what());  // the catalog is this command's input
  }
  if (as_json) {
    nlohmann::json j{{"catalog", catalog}, {"scans", nlohmann::json::array()}};
    for (const auto& s : scans) j["scans"].push_back(acq::to_json(s));
    std::cout << j.dump() << "\n";
    return kExitOk;
  }
  std::printf("%-5s %-20s %-12s %-24s %-24s %12s %12s %4s  %s\n", "id", "name", "state", "started",
              "stopped", "samples", "points", "seg", "reason");
  for (const auto& s : scans) {
    std::printf(
        "%-5lld %-20s %-12s %-24s %-24s %12llu %12llu %4zu  %s\n", static_cast<long long>(s.id),
        s.name.c_str(), std::string(acq::to_string(s.state)).c_str(), s.started_at.c_str(),
        s.stopped_at.empty() ? "-" : s.stopped_at.c_str(),
        static_cast<unsigned long long>(s.samples), static_cast<unsigned long long>(s.points),
        s.segments.size(), s.stop_reason.c_str());
  }
  if (scans.empty()) std::printf("(no scans in %s)\n", catalog.c_str());
  return kExitOk;
}

}  // namespace

void add_journal_commands(CLI::App& app, Runner& run) {
  auto* journal = app.add_subcommand("journal", "check or recover a scan journal (MCAP)");
  journal->require_subcommand(1);

  struct Args {
    std::string file;
    bool json = false;
  };
  auto check_args = std::make_shared<Args>();
  auto* check = journal->add_subcommand(
      "check",
      "what a journal holds: chunks, records per channel, samples, time span, CRC "
      "failures, torn tail (read-only; exit 3 unless it is complete and sound)");
  check->add_option("JOURNAL", check_args->file, "journal file (.mcap)")->required();
  check->add_flag("--json", check_args->json, "print one JSON object");
  check->callback([&run, check_args] {
    run = [check_args] { return run_check(check_args->file, check_args->json); };
  });

  auto recover_args = std::make_shared<Args>();
  auto* recover = journal->add_subcommand(
      "recover",
      "after a crash: keep every good chunk, cut the torn tail, write the summary and "
      "footer so any MCAP reader opens the file; reports what it kept and cut");
  recover->add_option("JOURNAL", recover_args->file, "journal file (.mcap)")->required();
  recover->add_flag("--json", recover_args->json, "print one JSON object");
  recover->callback([&run, recover_args] {
    run = [recover_args] { return run_recover(recover_args->file, recover_args->json); };
  });

  auto scans_args = std::make_shared<Args>();
  scans_args->file = std::string(acq::kDefaultCatalogPath);
  auto* scans = app.add_subcommand("scans",
                                   "the scan catalog: every scan with its state, times, "
                                   "counts, journal files and why it stopped");
  scans->add_option("--catalog", scans_args->file, "catalog file (SQLite)")->capture_default_str();
  scans->add_flag("--json", scans_args->json, "print one JSON object");
  scans->callback([&run, scans_args] {
    run = [scans_args] { return run_scans(scans_args->file, scans_args->json); };
  });
}

}  // namespace scanmesh::cli
