// The scan journal written and read back: every record in order, bit for bit; chunk limits;
// acknowledgement (exactly the samples in chunks on disk); the fsync policy; check's report;
// the independent reader (@mcap/core) on the same files; bad arguments.
// SPDX-License-Identifier: MIT
#include <sys/stat.h>

#include <atomic>
#include <catch2/catch.hpp>
#include <fstream>
#include <thread>

#include "journal/independent_reader.hpp"
#include "journal/journal_support.hpp"
#include "journal/scenario.hpp"
#include "scanmesh/acquisition/journal.hpp"

using namespace scanmesh;
using namespace scanmesh::test;
using acq::ChannelKind;

TEST_CASE("A journal reads back every record in the order written, bit for bit", "[acq][journal]") {
  TempDir dir;
  const auto file = dir / "scan.mcap";
  std::vector<Item> written;
  {
    acq::JournalOptions o;
    o.metadata = {{"scan_id", "7"}, {"segment", "1"}};
    acq::JournalWriter w(file, o);
    written = write_scenario(w);
    w.close();
    CHECK(w.acknowledged_samples() == sample_count(written));
    CHECK(w.durable_samples() == sample_count(written));
  }
  Recorder rec;
  const acq::JournalReport r = acq::read_journal(file, rec);
  REQUIRE(rec.items.size() == written.size());
  std::size_t first_difference = written.size();
  for (std::size_t i = 0; i < written.size(); ++i) {
    if (!(rec.items[i] == written[i])) {
      first_difference = i;
      break;
    }
  }
  CHECK(first_difference == written.size());
  CHECK(r.scan.complete());
  CHECK(r.scan.data_section_crc_ok);
  CHECK(r.samples == sample_count(written));
  REQUIRE(rec.channels.size() == 6);
  CHECK(rec.channels[0].topic == "/sensors/lkg0");
  CHECK(rec.channels[0].kind == ChannelKind::kSensor);
  CHECK(rec.channels[0].device == "lkg0");
  CHECK(rec.channels[0].metadata.at("driver") == "keyence-lkg");
  CHECK(rec.channels[2].kind == ChannelKind::kStage);
  CHECK(rec.channels[3].kind == ChannelKind::kProbe);
  CHECK(rec.channels[4].kind == ChannelKind::kParameters);
  CHECK(rec.channels[5].kind == ChannelKind::kEvents);
  REQUIRE(r.scan.metadata.size() == 1);
  CHECK(r.scan.metadata[0].name == "scanmesh.journal");
  CHECK(r.scan.metadata[0].metadata.at("scan_id") == "7");
  // Point sensor: seq, t_host, value and status (25 bytes); the profiler adds index and device
  // time (37); the rest is message, index and chunk overhead.
  const double bytes_per_sample =
      static_cast<double>(std::filesystem::file_size(file)) / static_cast<double>(r.samples);
  CHECK(bytes_per_sample < 35.0);
}

TEST_CASE("Chunks hold at most 64 KiB of records and 100 ms of sample time", "[acq][journal]") {
  TempDir dir;
  const auto file = dir / "scan.mcap";
  {
    acq::JournalWriter w(file);
    (void)write_scenario(w);
  }  // the destructor closes
  const auto r = acq::check_journal(file);
  REQUIRE(r.scan.complete());
  REQUIRE(r.scan.chunks.size() > 50);
  std::size_t full = 0;
  for (const auto& c : r.scan.chunks) {
    CHECK(c.records_bytes <= 64 * 1024);
    CHECK(c.message_end_time - c.message_start_time < 100'000'000);
    full += c.records_bytes > 60 * 1024 ? 1 : 0;
  }
  // The sensors fill chunks by size (the batches are split to fill them).
  CHECK(full * 10 > r.scan.chunks.size() * 8);

  SECTION("a slow stream closes chunks by time") {
    const auto slow = dir / "slow.mcap";
    acq::JournalWriter w(slow);
    const auto stage = w.add_stage("xyz");
    for (std::uint64_t i = 0; i < 50; ++i)
      w.write_stage(stage, stage_sample(i, 1'000'000'000, 30'000'000));  // 33 Hz
    w.close();
    const auto s = acq::check_journal(slow);
    // 50 samples over 1.5 s: a chunk per 100 ms (4 samples each, the last one short).
    CHECK(s.scan.chunks.size() == 13);
    for (const auto& c : s.scan.chunks)
      CHECK(c.message_end_time - c.message_start_time < 100'000'000);
  }
}

TEST_CASE("Acknowledged samples are exactly those in chunks written to the file",
          "[acq][journal]") {
  TempDir dir;
  const auto file = dir / "scan.mcap";
  acq::JournalWriter w(file);
  int looks = 0;
  Scenario sc;
  sc.milliseconds = 600;
  (void)write_scenario(w, sc, [&](int ms) {
    if (ms % 97 != 0) return;
    // The writer's file as another process sees it now: whole chunks only, no torn tail.
    const auto seen = acq::check_journal(file);
    CHECK(seen.being_written);
    CHECK_FALSE(seen.scan.torn_tail);
    CHECK(seen.scan.damage.empty());
    CHECK(seen.samples == w.acknowledged_samples());
    CHECK(w.acknowledged_samples() <= w.written_samples());
    // At most one chunk's worth waits in memory (64 KiB at 25 bytes a sample).
    CHECK(w.written_samples() - w.acknowledged_samples() < 64 * 1024 / 25);
    ++looks;
  });
  CHECK(looks == 7);
  w.flush();
  CHECK(w.acknowledged_samples() == w.written_samples());
  CHECK(acq::check_journal(file).samples == w.written_samples());

  SECTION("tick writes a chunk once it is chunk_duration old") {
    const auto stage = w.add_stage("late");
    const auto before = w.acknowledged_samples();
    const drivers::Timestamp t{5'000'000'000};
    drivers::StageSample late;
    late.t = t;
    w.write_stage(stage, late);
    CHECK(w.acknowledged_samples() == before);
    w.tick(t + std::chrono::milliseconds(99));
    CHECK(w.acknowledged_samples() == before);
    w.tick(t + std::chrono::milliseconds(100));
    CHECK(w.acknowledged_samples() == before + 1);
  }
}

TEST_CASE("The acknowledged count is read from another thread while the journal is written",
          "[acq][journal]") {
  TempDir dir;
  acq::JournalWriter w(dir / "scan.mcap");
  std::atomic<bool> done{false};
  std::uint64_t reads = 0;
  bool monotonic = true;
  std::thread status([&] {
    std::uint64_t last = 0;
    while (!done.load(std::memory_order_acquire)) {
      const std::uint64_t now = w.acknowledged_samples();
      monotonic = monotonic && now >= last;
      last = now;
      ++reads;
    }
  });
  Scenario sc;
  sc.milliseconds = 500;
  const auto items = write_scenario(w, sc);
  w.flush();
  done.store(true, std::memory_order_release);
  status.join();
  CHECK(monotonic);
  CHECK(reads > 0);
  CHECK(w.acknowledged_samples() == sample_count(items));
}

TEST_CASE("The fsync policy: by bytes and by sample time", "[acq][journal]") {
  TempDir dir;
  SECTION("by bytes") {
    acq::JournalOptions o;
    o.fsync_bytes = 1 << 20;
    o.fsync_interval = std::chrono::nanoseconds(0);
    acq::JournalWriter w(dir / "a.mcap", o);
    Scenario sc;
    sc.milliseconds = 1000;
    (void)write_scenario(w, sc,
                         [&](int) { CHECK(w.durable_samples() <= w.acknowledged_samples()); });
    const auto st = w.stats();
    // ~8 MB written: one fdatasync per MiB (each once a chunk passes the next MiB).
    CHECK(st.fsyncs <= st.bytes / (1 << 20));
    CHECK(st.fsyncs * ((1 << 20) + 70 * 1024) >= st.bytes - (1 << 20));
    CHECK(w.durable_samples() > 0);
  }
  SECTION("by interval (default: 1 s of sample time)") {
    acq::JournalOptions o;
    o.fsync_bytes = 0;
    acq::JournalWriter w(dir / "b.mcap", o);
    Scenario sc;
    sc.milliseconds = 2500;
    (void)write_scenario(w, sc);
    CHECK(w.stats().fsyncs == 2);
    w.close();
    CHECK(w.durable_samples() == w.acknowledged_samples());
  }
}

TEST_CASE("check reports a complete journal: chunks, channels, samples, time span",
          "[acq][journal]") {
  TempDir dir;
  const auto file = dir / "scan.mcap";
  std::vector<Item> written;
  {
    acq::JournalWriter w(file);
    written = write_scenario(w);
  }
  const auto r = acq::check_journal(file);
  CHECK(r.scan.complete());
  CHECK_FALSE(r.being_written);
  CHECK(r.scan.crc_failures == 0);
  CHECK(r.scan.summary_ok);
  CHECK(r.samples == sample_count(written));
  CHECK(samples_of(r, ChannelKind::kSensor) == 200'000 + 2000 * 64);
  CHECK(samples_of(r, ChannelKind::kStage) == 2000);
  CHECK(samples_of(r, ChannelKind::kProbe) == 10);
  CHECK(r.first_sample_ns == 1'000'000'000);
  CHECK(r.last_sample_ns == std::int64_t{1'000'000'000} + std::int64_t{199'999} * 10'000);
  CHECK(r.scan.message_start_time == 1'000'000'000);
  CHECK(r.scan.message_end_time == 3'000'000'000);
  const auto j = acq::to_json(r);
  CHECK(j["complete"] == true);
  CHECK(j["chunks"] == r.scan.chunks.size());
  CHECK(j["samples"] == r.samples);
  CHECK(j["torn_tail"].is_null());
  CHECK(j["crc_failures"] == 0);
  CHECK(j["time_span"]["seconds"] == Approx(2.0));
  CHECK(j["channels"].size() == 6);
  CHECK(j["channels"][1]["topic"] == "/sensors/line0");
  CHECK(j["channels"][1]["samples"] == 2000 * 64);
  CHECK(j["metadata"]["scanmesh.journal"].is_object());
}

TEST_CASE("The independent reader (@mcap/core) opens a journal and decodes what was written",
          "[acq][journal][mcap-reader]") {
  TempDir dir;
  const auto file = dir / "scan.mcap";
  std::vector<Item> written;
  Scenario sc;
  sc.milliseconds = 300;
  {
    acq::JournalOptions o;
    o.metadata = {{"scan_id", "42"}};
    acq::JournalWriter w(file, o);
    written = write_scenario(w, sc);
  }
  const auto out = independent_read({file}, false).at(0);
  INFO(out.value("error", std::string()));
  REQUIRE_FALSE(out.contains("error"));
  CHECK(out["profile"] == "x-scanmesh");
  CHECK(out["stream"]["done"] == true);
  CHECK(out["stream"]["records"]["Footer"] == 1);
  CHECK(out["data_section_crc"]["stored"] == out["data_section_crc"]["computed"]);
  CHECK(out["data_section_crc"]["stored"] != 0);
  CHECK(out["out_of_order"] == 0);
  REQUIRE(out["metadata"].size() == 1);
  CHECK(out["metadata"][0]["name"] == "scanmesh.journal");
  CHECK(out["metadata"][0]["metadata"]["scan_id"] == "42");
  REQUIRE(out["channels"].size() == 6);
  std::map<int, std::string> topic;
  for (const auto& c : out["channels"]) {
    topic[c["id"].get<int>()] = c["topic"];
    if (c["topic"].get<std::string>().rfind("/sensors/", 0) == 0) {
      CHECK(c["message_encoding"] == "cdr");
      CHECK(c["schema_encoding"] == "ros2msg");
      CHECK(c["schema_name"] == "scanmesh_msgs/msg/SensorSamples");
      CHECK(c["metadata"]["kind"] == "sensor");
    }
  }
  // Rebuild the items from what node decoded (with the schema text from the file) and compare.
  std::vector<Item> decoded;
  auto num = [](const nlohmann::json& v) { return std::stoll(v.get<std::string>()); };
  auto unum = [](const nlohmann::json& v) { return std::stoull(v.get<std::string>()); };
  for (const auto& m : out["messages"]) {
    const std::string t = topic.at(m["channel"].get<int>());
    const auto& d = m["data"];
    if (t.rfind("/sensors/", 0) == 0) {
      const std::size_t n = d["seq"].size();
      for (std::size_t i = 0; i < n; ++i) {
        drivers::SensorSample s;
        s.seq = unum(d["seq"][i]);
        s.t_host.ns = num(d["t_host_ns"][i]);
        s.value_mm = d["value_mm"][i].is_null() ? std::numeric_limits<double>::quiet_NaN()
                                                : d["value_mm"][i].get<double>();
        s.status = static_cast<drivers::SensorStatus>(d["status"][i].get<int>());
        s.index = d["index"].empty() ? 0 : d["index"][i].get<std::uint32_t>();
        s.device_code = d["device_code"].empty() ? 0 : d["device_code"][i].get<std::uint32_t>();
        if (!d["t_device_ns"].empty() &&
            num(d["t_device_ns"][i]) != std::numeric_limits<std::int64_t>::min())
          s.t_device = drivers::Timestamp{num(d["t_device_ns"][i])};
        decoded.push_back(sensor_item(t.substr(9), s));
      }
    } else if (t.rfind("/stages/", 0) == 0) {
      drivers::StageSample s;
      s.seq = unum(d["seq"]);
      s.t.ns = num(d["t_ns"]);
      s.pose = {d["x_mm"].get<double>(), d["y_mm"].get<double>(), d["z_mm"].get<double>(),
                d["a_rad"].get<double>()};
      if (num(d["t_device_ns"]) != std::numeric_limits<std::int64_t>::min())
        s.t_device = drivers::Timestamp{num(d["t_device_ns"])};
      s.status = static_cast<drivers::StageStatus>(d["status"].get<int>());
      decoded.push_back(stage_item(t, s));
    } else if (t.rfind("/probes/", 0) == 0) {
      drivers::ProbeTrigger p;
      p.seq = unum(d["seq"]);
      p.t.ns = num(d["t_ns"]);
      p.pose = {d["x_mm"].get<double>(), d["y_mm"].get<double>(), d["z_mm"].get<double>(),
                d["a_rad"].get<double>()};
      if (num(d["t_device_ns"]) != std::numeric_limits<std::int64_t>::min())
        p.t_device = drivers::Timestamp{num(d["t_device_ns"])};
      if (d["has_surface"].get<bool>())
        p.surface =
            drivers::SurfacePoint{d["surface_x_mm"].get<double>(), d["surface_y_mm"].get<double>(),
                                  d["surface_z_mm"].get<double>(), d["surface_i"].get<double>(),
                                  d["surface_j"].get<double>(),    d["surface_k"].get<double>()};
      decoded.push_back(probe_item(t, p));
    } else {
      decoded.push_back(json_item(t, d, num(m["publish_time"])));
    }
  }
  REQUIRE(decoded.size() == written.size());
  std::size_t mismatches = 0;
  for (std::size_t i = 0; i < written.size(); ++i) {
    Item a = decoded[i];
    Item b = written[i];
    // NaN travels as null and comes back as the quiet NaN; every other double is exact.
    if (std::isnan(a.sensor.value_mm) && std::isnan(b.sensor.value_mm))
      a.sensor.value_mm = b.sensor.value_mm;
    // JSON has no negative zero (-0.0 comes back as 0): poses compare by value.
    if (a.stage.pose == b.stage.pose) a.stage.pose = b.stage.pose;
    if (a.probe.pose == b.probe.pose) a.probe.pose = b.probe.pose;
    if (a.probe.surface && b.probe.surface && a.probe.surface->x_mm == b.probe.surface->x_mm &&
        a.probe.surface->y_mm == b.probe.surface->y_mm &&
        a.probe.surface->z_mm == b.probe.surface->z_mm && a.probe.surface->i == b.probe.surface->i &&
        a.probe.surface->j == b.probe.surface->j && a.probe.surface->k == b.probe.surface->k)
      a.probe.surface = b.probe.surface;
    if (!(a == b)) {
      ++mismatches;
      UNSCOPED_INFO("item " << i << " on " << b.topic << ": node '" << a.json << "' t " << a.t_ns
                            << " seq " << a.stage.seq << ", written '" << b.json << "' t " << b.t_ns
                            << " seq " << b.stage.seq);
    }
  }
  CHECK(mismatches == 0);
}

TEST_CASE("Bad arguments are refused with the file's name", "[acq][journal]") {
  TempDir dir;
  const auto file = dir / "scan.mcap";
  {
    acq::JournalWriter w(file);
    const auto s = w.add_sensor("a");
    CHECK_THROWS_WITH(w.add_sensor("a"), Catch::Contains("/sensors/a exists already"));
    CHECK_THROWS_AS(w.add_stage(""), ConfigError);
    CHECK_THROWS_WITH(w.write_event({0}, nlohmann::json{{"what", 1}}),
                      Catch::Contains("string \"event\""));
    CHECK_THROWS_WITH(w.write_parameters({0}, nlohmann::json::array()),
                      Catch::Contains("string \"kind\""));
    CHECK_THROWS_WITH(w.write_event({0}, std::string_view("{\"event\": ")),
                      Catch::Contains("not JSON"));
    w.write_event({0}, std::string_view(R"({"event": "started"})"));
    CHECK_THROWS_WITH(w.write_stage(acq::StageChannel{s.id}, drivers::StageSample()),
                      Catch::Contains("not one of this journal's stage channels"));
  }
  // A journal is never overwritten.
  CHECK_THROWS_WITH(acq::JournalWriter(file),
                    Catch::Contains(file.string()) && Catch::Contains("File exists"));
  acq::JournalOptions bad;
  bad.chunk_bytes = 10;
  CHECK_THROWS_WITH(acq::JournalWriter(dir / "b.mcap", bad), Catch::Contains("chunk_bytes"));
  // Not an MCAP file.
  spit(dir / "x.mcap", "solid cube\nfacet normal 0 0 1\n");
  CHECK_THROWS_WITH(acq::check_journal(dir / "x.mcap"),
                    Catch::Contains("not an MCAP file") && Catch::Contains("x.mcap"));
  CHECK_THROWS_WITH(acq::check_journal(dir / "missing.mcap"),
                    Catch::Contains("missing.mcap") && Catch::Contains("No such file"));
}
