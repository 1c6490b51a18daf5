// The server over a real Unix socket with the real Daemon and a scripted engine: HELLO, every
// command, errors that leave the connection open, watch and events, the device-loss policy,
// exports and previews confined to their folders, and the limits (64 KiB lines, clients, slow
// readers, disconnects mid-command).
// SPDX-License-Identifier: MIT
#include <fcntl.h>
#include <grp.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>
#include <thread>

#include "daemon/harness.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/recon/analysis.hpp"

using namespace scanmesh;
using namespace scanmesh::daemon;
using test::DaemonHarness;
using test::eventually;

namespace {

/// Reads until an event named `name` satisfying `pred` arrives; fails the test on close.
proto::Message await_event(Client& c, std::string_view name,
                           const std::function<bool(const proto::Message&)>& pred = {}) {
  for (;;) {
    auto m = c.read();
    REQUIRE(m.has_value());
    if (m->cls == proto::MessageClass::kEvent && m->event == name && (!pred || pred(*m))) return *m;
  }
}

ScanStatus scan_of(const proto::Message& m) { return proto::scan_status_from(m.body); }

}  // namespace

TEST_CASE("a client gets HELLO, then answers to version, status and devices", "[daemon]") {
  DaemonHarness h;
  auto c = h.client();
  CHECK(c->hello_line() == R"({"class":"HELLO","proto_major":1,"proto_minor":0,"daemon":"test"})");
  const proto::Message v = c->request("version");
  CHECK(v.cls == proto::MessageClass::kReply);
  CHECK(v.id == 1);
  const VersionInfo vi = proto::version_info_from(v.body);
  CHECK((vi.daemon == "test" && vi.proto_major == 1 && vi.proto_minor == 0 &&
         vi.backend == "scripted"));

  std::string raw;
  const proto::Message s = c->request("status", {}, &raw);
  const StatusInfo si = proto::status_info_from(s.body);
  CHECK(si.daemon_state == "ready");
  CHECK(si.clients == 1);
  REQUIRE(si.devices.size() == 2);
  CHECK(si.devices[0].name == "probe-sensor");
  CHECK(si.devices[0].state == DeviceState::kOk);
  CHECK(si.scan.state == ScanState::kIdle);
  // The documented fields are on the wire.
  const auto j = nlohmann::json::parse(raw);
  for (const char* k :
       {"samples", "points", "triangles", "meshing_lag_points", "journal_bytes", "errors"})
    CHECK(j["scan"].contains(k));

  const proto::Message d = c->request("devices");
  const auto list = d.body.get_objects("devices");
  REQUIRE(list.size() == 2);
  CHECK(proto::device_info_from(list[1]).role == "stage");

  const proto::Message cfg = c->request("config.get");
  CHECK(cfg.body.get_object("config")->get_object("daemon")->get_int("max_clients") == 32);
}

TEST_CASE("bad requests get an ERROR and the connection carries on", "[daemon]") {
  DaemonHarness h;
  auto c = h.client();
  struct Bad {
    std::string line;
    std::string code;
    std::optional<std::int64_t> id;
  };
  const std::vector<Bad> bad = {
      {"this is not json\n", "invalid_json", std::nullopt},
      {"[1,2]\n", "bad_request", std::nullopt},
      {"{\"id\":3}\n", "bad_request", 3},
      {"{\"cmd\":\"frobnicate\",\"id\":4}\n", "unknown_command", 4},
      {"{\"cmd\":\"scan.info\",\"id\":5,\"scan\":\"three\"}\n", "bad_argument", 5},
      {"{\"cmd\":\"scan.info\",\"id\":6}\n", "bad_argument", 6},
      {"{\"cmd\":\"scan.info\",\"id\":7,\"scan\":99}\n", "not_found", 7},
      {"{\"cmd\":\"scan.pause\",\"id\":8}\n", "bad_state", 8},
      {"{\"cmd\":\"scan.start\",\"id\":9,\"name\":\"\"}\n", "bad_argument", 9},
      {"{\"cmd\":\"scan.start\",\"id\":10,\"name\":\"x\",\"parameters\":{\"bogus\":1}}\n",
       "bad_argument", 10},
      {"{\"cmd\":\"mesh.export\",\"id\":11,\"path\":\"/tmp/x.docx\"}\n", "bad_argument", 11},
  };
  for (const auto& b : bad) {
    INFO(b.line);
    c->send_raw(b.line);
    auto m = c->read();
    REQUIRE(m.has_value());
    CHECK(m->cls == proto::MessageClass::kError);
    CHECK(m->error_code == b.code);
    CHECK(m->id == b.id);
    CHECK_FALSE(m->error_message.empty());
  }
  // Blank lines and CRLF are tolerated.
  c->send_raw("\n\r\n{\"cmd\":\"version\",\"id\":12}\r\n");
  auto v = c->read();
  REQUIRE(v.has_value());
  CHECK((v->cls == proto::MessageClass::kReply && v->id == 12));
  CHECK(proto::status_info_from(c->request("status").body).protocol_errors == bad.size());
}

TEST_CASE(
    "a line longer than 64 KiB gets line_too_long and the connection is closed; others carry on",
    "[daemon][limits]") {
  DaemonHarness h;
  auto other = h.client();
  auto c = h.client();
  // Exactly 64 KiB is still a request (it just is not valid JSON here).
  c->send_raw(std::string(proto::kMaxLineBytes, 'x') + "\n");
  auto ok = c->read();
  REQUIRE(ok.has_value());
  CHECK(ok->error_code == "invalid_json");
  c->send_raw(std::string(proto::kMaxLineBytes + 1, 'x'));
  auto m = c->read();
  REQUIRE(m.has_value());
  CHECK(m->error_code == "line_too_long");
  CHECK_FALSE(c->read().has_value());  // closed by the daemon
  CHECK(other->request("version").cls == proto::MessageClass::kReply);
}

TEST_CASE("watchers get state, progress, mesh and device events", "[daemon]") {
  DaemonHarness h;
  auto w = h.client();
  auto ctl = h.client();
  const proto::Message r = w->request("watch");
  CHECK(r.body.get_bool("watching") == true);
  CHECK(scan_of(await_event(*w, "state")).state == ScanState::kIdle);  // the baseline

  const proto::Message started =
      ctl->request("scan.start", proto::Object()
                                     .set("name", "bracket")
                                     .set("parameters", Parameters{{"seed", std::int64_t{2}}}));
  REQUIRE(started.cls == proto::MessageClass::kReply);
  const ScanRecord rec = proto::scan_record_from(*started.body.get_object("scan"));
  CHECK(rec.name == "bracket");
  CHECK(scan_of(await_event(*w, "state")).state == ScanState::kRunning);

  h.engine().advance(5000, 4000);
  const auto p = await_event(
      *w, "progress", [](const proto::Message& m) { return scan_of(m).counters.samples == 5000; });
  CHECK(scan_of(p).counters.points == 4000);

  CHECK(ctl->request("scan.start", proto::Object().set("name", "again")).error_code == "busy");
  h.engine().finish();
  const auto mesh = proto::mesh_counts_from(await_event(*w, "mesh").body);
  CHECK(mesh.triangles == 13280);  // the container's
  const auto done = scan_of(await_event(*w, "state"));
  CHECK(done.state == ScanState::kIdle);
  CHECK(done.reason == "finished");

  // Unwatching stops events (read by hand: request() would keep earlier events for read()).
  const std::int64_t unwatch = w->send("watch", proto::Object().set("enable", false));
  for (;;) {
    auto m = w->read();
    REQUIRE(m.has_value());
    if (m->cls == proto::MessageClass::kReply && m->id == unwatch) {
      CHECK(m->body.get_bool("watching") == false);
      break;
    }
  }
  // The device report is posted to the io thread before the request is even sent, so a watcher
  // would see its event first: the next line must be the reply.
  h.engine().set_device(1, DeviceState::kOk);
  w->send("version");
  const auto after = w->read();
  REQUIRE(after.has_value());
  CHECK(after->cls == proto::MessageClass::kReply);
}

TEST_CASE(
    "a lost device pauses the scan, which resumes when the device is back; nothing is "
    "counted while paused",
    "[daemon][faults]") {
  DaemonHarness h;
  auto w = h.client();
  w->request("watch");
  await_event(*w, "state");
  REQUIRE(w->request("scan.start", proto::Object().set("name", "s")).cls ==
          proto::MessageClass::kReply);
  h.engine().advance(100, 90);
  h.engine().set_device(0, DeviceState::kLost, "no reply for 1500 ms");
  const auto dev = proto::device_info_from(await_event(*w, "device").body);
  CHECK((dev.name == "probe-sensor" && dev.state == DeviceState::kLost &&
         dev.detail == "no reply for 1500 ms"));
  const auto paused = scan_of(await_event(*w, "state", [](const proto::Message& m) {
    return scan_of(m).state != ScanState::kRunning || !scan_of(m).reason.empty();
  }));
  CHECK(paused.state == ScanState::kPaused);
  CHECK(paused.reason == "device_lost: probe-sensor");
  const StatusInfo st = proto::status_info_from(w->request("status").body);
  CHECK(st.devices[0].state == DeviceState::kLost);
  CHECK(st.scan.state == ScanState::kPaused);
  h.engine().advance(50, 50);  // a paused engine records nothing
  h.engine().set_device(0, DeviceState::kOk);
  CHECK(scan_of(await_event(*w, "state")).state == ScanState::kRunning);  // after the pause
  h.engine().advance(10, 10);
  CHECK(proto::status_info_from(w->request("status").body).scan.counters.samples == 110);
  CHECK_THAT(h.log(), Catch::Contains("<4>device probe-sensor: lost: no reply for 1500 ms"));
  // An operator's pause is not undone by a device coming back.
  REQUIRE(w->request("scan.pause").cls == proto::MessageClass::kReply);
  h.engine().set_device(1, DeviceState::kOk);
  await_event(*w, "device");
  CHECK(proto::status_info_from(w->request("status").body).scan.state == ScanState::kPaused);
}

TEST_CASE("mesh.export writes STL, PLY and OBJ in an export folder; mesh.preview a PNG",
          "[daemon][export]") {
  DaemonHarness h;
  auto c = h.client();
  CHECK(c->request("mesh.export",
                   proto::Object().set("path", (h.dir() / "exports/none.stl").string()))
            .error_code == "no_mesh");
  REQUIRE(c->request("scan.start", proto::Object().set("name", "s")).cls ==
          proto::MessageClass::kReply);
  h.engine().finish();
  REQUIRE(eventually([&] {
    return proto::status_info_from(c->request("status").body).scan.state == ScanState::kIdle;
  }));
  const recon::Mesh part = sim::make_part("container");
  for (const char* ext : {"stl", "ply", "obj"}) {
    const auto path = h.dir() / "exports" / (std::string("part.") + ext);
    const proto::Message m = c->request("mesh.export", proto::Object().set("path", path.string()));
    INFO(m.body.dump());
    REQUIRE(m.cls == proto::MessageClass::kReply);
    const ExportInfo e = proto::export_info_from(m.body);
    CHECK(e.path == path.string());
    CHECK(e.format == ext);
    CHECK(e.triangles == part.triangles.size());
    CHECK(e.bytes == std::filesystem::file_size(path));
    const recon::Mesh back = meshio::read_mesh(path);
    CHECK(back.triangles.size() == part.triangles.size());
    const recon::MeshReport rep = recon::analyze(back);
    CHECK(rep.boundary_loops == 0);
    CHECK(rep.genus == 2);
  }
  // Binary STL, checked byte by byte against its format: 80-byte header, count, 50 bytes each.
  const std::string stl = test::slurp(h.dir() / "exports/part.stl");
  REQUIRE(stl.size() == 84 + 50 * part.triangles.size());
  std::uint32_t count = 0;
  std::memcpy(&count, stl.data() + 80, 4);
  CHECK(count == part.triangles.size());

  const auto png = h.dir() / "exports/part.png";
  const proto::Message pm = c->request(
      "mesh.preview",
      proto::Object().set("path", png.string()).set("width_px", 320).set("height_px", 200));
  REQUIRE(pm.cls == proto::MessageClass::kReply);
  const std::string bytes = test::slurp(png);
  REQUIRE(bytes.size() > 33);
  CHECK(bytes.substr(0, 8) == "\x89PNG\r\n\x1a\n");
  auto be32 = [&](std::size_t at) {
    return (std::uint32_t(std::uint8_t(bytes[at])) << 24) |
           (std::uint32_t(std::uint8_t(bytes[at + 1])) << 16) |
           (std::uint32_t(std::uint8_t(bytes[at + 2])) << 8) |
           std::uint32_t(std::uint8_t(bytes[at + 3]));
  };
  CHECK(bytes.substr(12, 4) == "IHDR");
  CHECK(be32(16) == 320);
  CHECK(be32(20) == 200);
  CHECK(
      c->request("mesh.export",
                 proto::Object().set("path", (h.dir() / "exports/x.stl").string()).set("scan", 77))
          .error_code == "not_found");
}

TEST_CASE("export paths outside the allowed folders are refused: '..', symlinks, relative paths",
          "[daemon][security]") {
  DaemonHarness h;
  auto c = h.client();
  REQUIRE(c->request("scan.start", proto::Object().set("name", "s")).cls ==
          proto::MessageClass::kReply);
  h.engine().finish();
  REQUIRE(eventually([&] {
    return proto::status_info_from(c->request("status").body).scan.state == ScanState::kIdle;
  }));
  const auto exports = h.dir() / "exports";
  std::filesystem::create_directories(h.dir() / "elsewhere");
  std::filesystem::create_directory_symlink(h.dir() / "elsewhere", exports / "link");
  std::filesystem::create_symlink(h.dir() / "elsewhere/target.stl", exports / "file-link.stl");
  std::filesystem::create_directories(exports / "sub");
  struct Case {
    std::string path;
    std::string why;
  };
  const std::vector<Case> refused = {
      {(h.dir() / "elsewhere/x.stl").string(), "is outside the folders"},
      {(exports / "../elsewhere/x.stl").string(), "must not contain '..'"},
      {(exports / "sub/../../x.stl").string(), "must not contain '..'"},
      {(exports / "link/x.stl").string(),
       "its folder resolves to " + (h.dir() / "elsewhere").string()},
      {(exports / "file-link.stl").string(), "is a symbolic link"},
      {"relative/x.stl", "must be an absolute path"},
      {(exports / "missing-dir/x.stl").string(), "cannot open its folder"},
      {"/etc/passwd.stl", "is outside the folders"},
  };
  for (const auto& r : refused) {
    INFO(r.path);
    const proto::Message m = c->request("mesh.export", proto::Object().set("path", r.path));
    CHECK(m.error_code == "path_refused");
    CHECK_THAT(m.error_message, Catch::Contains(r.why));
  }
  CHECK_FALSE(std::filesystem::exists(h.dir() / "elsewhere/x.stl"));
  CHECK_FALSE(std::filesystem::exists(h.dir() / "elsewhere/target.stl"));
  CHECK(c->request("mesh.export", proto::Object().set("path", (exports / "sub/ok.stl").string()))
            .cls == proto::MessageClass::kReply);
  CHECK(std::filesystem::is_regular_file(exports / "sub/ok.stl"));
}

TEST_CASE("100 clients at once are all served", "[daemon][limits]") {
  DaemonHarness h([](DaemonConfig& c) { c.max_clients = 128; });
  std::vector<std::unique_ptr<Client>> clients;
  for (int i = 0; i < 100; ++i) clients.push_back(h.client());
  for (auto& c : clients) c->send("status");
  for (auto& c : clients) {
    auto m = c->read();
    REQUIRE(m.has_value());
    CHECK(m->cls == proto::MessageClass::kReply);
    CHECK(proto::status_info_from(m->body).clients == 100);
  }
}

TEST_CASE("clients beyond max_clients get too_many_clients; a freed slot is reused",
          "[daemon][limits]") {
  DaemonHarness h([](DaemonConfig& c) { c.max_clients = 4; });
  std::vector<std::unique_ptr<Client>> clients;
  for (int i = 0; i < 4; ++i) clients.push_back(h.client());
  try {
    h.client();
    FAIL("a fifth client was accepted");
  } catch (const Error& e) {
    CHECK_THAT(e.what(), Catch::Contains("too_many_clients"));
  }
  clients.pop_back();
  REQUIRE(eventually(
      [&] { return proto::status_info_from(clients[0]->request("status").body).clients == 3; }));
  CHECK_NOTHROW(h.client());
}

TEST_CASE("a client that never reads is dropped at its output limit; the others are served",
          "[daemon][limits]") {
  DaemonHarness h([](DaemonConfig& c) { c.client_output_limit_bytes = 64 * 1024; });
  auto slow = h.client();
  auto fast = h.client();
  slow->request("watch");
  fast->request("watch");
  // Far more than the socket buffers and the limit hold (4 MB of device events), in bursts the
  // fast client reads as they come; the slow one never reads.
  for (int burst = 0; burst < 100; ++burst) {
    h.engine().flood_device_events(40, 1000);
    std::size_t events = 0;
    while (events < 40) {
      auto m = fast->read();
      if (!m) FAIL(h.log().substr(h.log().size() > 3000 ? h.log().size() - 3000 : 0));
      if (m->event == "device") ++events;
    }
  }
  REQUIRE(eventually([&] { return h.log().find("is not reading") != std::string::npos; }));
  CHECK(fast->request("version").cls == proto::MessageClass::kReply);
  // The slow one finds its stream cut short: it was disconnected, not allowed to grow.
  std::size_t got = 0;
  slow->set_timeout(std::chrono::seconds(5));
  while (auto m = slow->read()) got += m->event == "device" ? 1 : 0;
  CHECK(got < 4000);
  CHECK(proto::status_info_from(fast->request("status").body).clients == 1);
}

TEST_CASE("clients disconnecting mid-line or mid-command do not disturb the daemon",
          "[daemon][faults]") {
  DaemonHarness h;
  {
    auto c = h.client();
    c->send_raw("{\"cmd\":\"sta");  // half a line, then gone
  }
  {
    auto c = h.client();
    REQUIRE(c->request("scan.start", proto::Object().set("name", "s")).cls ==
            proto::MessageClass::kReply);
    h.engine().finish();
  }
  {
    // A slow job (an export) whose client is gone before the reply: the work completes.
    auto c = h.client();
    REQUIRE(eventually([&] {
      return proto::status_info_from(c->request("status").body).scan.state == ScanState::kIdle;
    }));
    c->send("mesh.export", proto::Object().set("path", (h.dir() / "exports/gone.stl").string()));
    ::shutdown(c->native_handle(), SHUT_RDWR);
  }
  auto c = h.client();
  REQUIRE(eventually([&] { return std::filesystem::exists(h.dir() / "exports/gone.stl"); }));
  REQUIRE(
      eventually([&] { return proto::status_info_from(c->request("status").body).clients == 1; }));
  CHECK(c->request("version").cls == proto::MessageClass::kReply);
}

TEST_CASE("shutting down stops the running scan through the engine and removes the socket",
          "[daemon]") {
  DaemonHarness h;
  auto w = h.client();
  w->request("watch");
  await_event(*w, "state");
  REQUIRE(w->request("scan.start", proto::Object().set("name", "s")).cls ==
          proto::MessageClass::kReply);
  await_event(*w, "state");
  CHECK(h.stop() == 0);
  CHECK(h.engine().shutdowns() == 1);
  // The watcher saw the scan stop before the connection closed.
  const auto last = scan_of(await_event(*w, "state"));
  CHECK(last.state == ScanState::kIdle);
  CHECK(last.reason == "stopped: daemon stopping");
  CHECK_FALSE(w->read().has_value());
  CHECK_FALSE(std::filesystem::exists(h.socket()));
}

TEST_CASE("state-changing commands are refused to peers that are not control users",
          "[daemon][security]") {
  if (::geteuid() != 0) {
    WARN("not root: cannot run a client as another user; skipped");
    return;
  }
  // nobody (65534) reaches the socket through its group (nogroup), as an operator in the
  // scanmesh group would, but is not a control user.
  DaemonHarness h([](DaemonConfig& c) { c.socket_group = "nogroup"; });
  ::chmod(h.dir().path().c_str(), 0755);
  struct stat st {};
  REQUIRE(::stat(h.socket().c_str(), &st) == 0);
  CHECK((st.st_mode & 0777) == 0660);
  // The real client, run as nobody: only async-signal-safe calls between fork and exec.
  auto run_as_nobody = [&](std::vector<std::string> args) {
    const auto out_file = h.dir() / "nobody.out";
    args.insert(args.begin(), {SCANCTL_EXE, "--json", "--socket", h.socket().string()});
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    const pid_t pid = ::fork();
    REQUIRE(pid >= 0);
    if (pid == 0) {
      const int fd = ::open(out_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0666);
      if (fd < 0 || ::dup2(fd, 1) < 0 || ::dup2(fd, 2) < 0) ::_exit(126);
      if (::setgroups(0, nullptr) != 0 || ::setgid(65534) != 0 || ::setuid(65534) != 0)
        ::_exit(125);
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
    int status = 0;
    ::waitpid(pid, &status, 0);
    return std::make_pair(WIFEXITED(status) ? WEXITSTATUS(status) : -1, test::slurp(out_file));
  };
  const auto [status_rc, status_out] = run_as_nobody({"status"});
  INFO(status_out);
  CHECK(status_rc == 0);
  CHECK_THAT(status_out, Catch::Contains("\"class\":\"REPLY\""));
  for (std::vector<std::string> cmd :
       {std::vector<std::string>{"scan", "start", "--name", "x"},
        std::vector<std::string>{"scan", "stop"},
        std::vector<std::string>{"mesh", "export", "--path", "/tmp/x.stl"}}) {
    const auto [rc, out] = run_as_nobody(cmd);
    INFO(out);
    CHECK(rc == 1);
    CHECK_THAT(out, Catch::Contains("\"code\":\"permission_denied\""));
  }
  CHECK(proto::status_info_from(h.client()->request("status").body).scan.state == ScanState::kIdle);
  CHECK_THAT(h.log(), Catch::Contains("uid 65534) refused scan.start: not a control user"));
}
