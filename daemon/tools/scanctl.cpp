// scanctl: the operator's command-line client for scanmeshd (daemon/README.md). Human-readable
// output by default, the daemon's JSON lines with --json; exit status 1 on an ERROR reply.
// SPDX-License-Identifier: MIT
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/daemon/client.hpp"
#include "scanmesh/daemon/protocol.hpp"

namespace {

using scanmesh::daemon::Client;
using scanmesh::daemon::Parameters;
using scanmesh::daemon::Scalar;
using scanmesh::daemon::ScanState;
namespace proto = scanmesh::daemon::proto;

constexpr int kExitOk = 0;
constexpr int kExitError = 1;  ///< the daemon answered ERROR
constexpr int kExitUsage = 2;
constexpr int kExitConnect = 3;     ///< no daemon, or the connection broke
constexpr int kExitScanFailed = 4;  ///< --wait: the scan ended without finishing

struct Options {
  std::string socket = "/run/scanmesh/control.sock";
  bool json = false;
  double timeout_s = 30;
};

std::string thousands(std::uint64_t v) {
  // Built forwards (GCC 12 warns falsely about std::string::insert here at -O3).
  const std::string digits = std::to_string(v);
  std::string s;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) s += ',';
    s += digits[i];
  }
  return s;
}

std::string rate_text(double hz) {
  char buf[32];
  if (hz >= 1e6)
    std::snprintf(buf, sizeof buf, "%.2f MHz", hz / 1e6);
  else if (hz >= 1e3)
    std::snprintf(buf, sizeof buf, "%.1f kHz", hz / 1e3);
  else
    std::snprintf(buf, sizeof buf, "%.0f Hz", hz);
  return buf;
}

Scalar parse_scalar(const std::string& text) {
  if (text == "true") return true;
  if (text == "false") return false;
  try {
    std::size_t used = 0;
    const long long i = std::stoll(text, &used);
    if (used == text.size()) return static_cast<std::int64_t>(i);
  } catch (const std::exception&) {
  }
  try {
    std::size_t used = 0;
    const double d = std::stod(text, &used);
    if (used == text.size() && std::isfinite(d)) return d;
  } catch (const std::exception&) {
  }
  return text;
}

/// Prints an ERROR (or the raw line with --json) and returns the exit status for it.
int report_error(const proto::Message& m, const std::string& raw, const Options& o) {
  if (o.json)
    std::cout << raw << "\n";
  else
    std::cerr << "scanctl: " << m.error_code << ": " << m.error_message << "\n";
  return kExitError;
}

void print_status(const proto::Message& m) {
  const auto s = proto::status_info_from(m.body);
  std::printf("daemon     %s (%s backend), up %.0f s, %s client(s)\n", s.daemon_state.c_str(),
              s.backend.c_str(), s.uptime_s, thousands(s.clients).c_str());
  for (const auto& d : s.devices)
    std::printf("device     %-14s %-7s %-6s %s%s\n", d.name.c_str(), d.role.c_str(),
                std::string(to_string(d.state)).c_str(), d.port.c_str(),
                d.detail.empty() ? "" : (" (" + d.detail + ")").c_str());
  const auto& sc = s.scan;
  if (sc.id == 0) {
    std::printf("scan       %s\n", std::string(to_string(sc.state)).c_str());
    return;
  }
  std::printf("scan       %s, scan %lld '%s'%s\n", std::string(to_string(sc.state)).c_str(),
              static_cast<long long>(sc.id), sc.name.c_str(),
              sc.reason.empty() ? "" : (" (" + sc.reason + ")").c_str());
  const auto& c = sc.counters;
  if (sc.progress >= 0)
    std::printf("progress   %.0f %%, %.1f s\n", sc.progress * 100, sc.elapsed_s);
  std::printf("samples    %s (%s)\n", thousands(c.samples).c_str(), rate_text(c.rate_hz).c_str());
  std::printf("points     %s\n", thousands(c.points).c_str());
  std::printf("triangles  %s\n", thousands(c.triangles).c_str());
  std::printf("lag        %s points (%.2f s)\n", thousands(c.meshing_lag_points).c_str(),
              c.meshing_lag_s);
  std::printf("journal    %s bytes\n", thousands(c.journal_bytes).c_str());
  std::printf("errors     %s\n", thousands(c.errors).c_str());
}

void print_record(const scanmesh::daemon::ScanRecord& r) {
  std::printf("%5lld  %-20s %-11s %-20s %12s %12s %12s\n", static_cast<long long>(r.id),
              r.name.c_str(), r.state.c_str(), r.started_utc.c_str(), thousands(r.samples).c_str(),
              thousands(r.points).c_str(), thousands(r.triangles).c_str());
}

/// One event as a human line.
void print_event(const proto::Message& m) {
  if (m.event == "state" || m.event == "progress") {
    const auto s = proto::scan_status_from(m.body);
    std::printf("%-8s %s scan %lld '%s' %s samples %s points %s triangles%s\n", m.event.c_str(),
                std::string(to_string(s.state)).c_str(), static_cast<long long>(s.id),
                s.name.c_str(), thousands(s.counters.samples).c_str(),
                thousands(s.counters.points).c_str(), thousands(s.counters.triangles).c_str(),
                s.reason.empty() ? "" : (" (" + s.reason + ")").c_str());
  } else if (m.event == "device") {
    const auto d = proto::device_info_from(m.body);
    std::printf("device   %s: %s%s\n", d.name.c_str(), std::string(to_string(d.state)).c_str(),
                d.detail.empty() ? "" : (" (" + d.detail + ")").c_str());
  } else if (m.event == "mesh") {
    const auto c = proto::mesh_counts_from(m.body);
    std::printf("mesh     scan %lld: %s triangles, %s vertices (+%s -%s)\n",
                static_cast<long long>(c.scan), thousands(c.triangles).c_str(),
                thousands(c.vertices).c_str(), thousands(c.added).c_str(),
                thousands(c.removed).c_str());
  } else {
    std::printf("%s\n", m.body.dump().c_str());
  }
  std::fflush(stdout);
}

/// The live progress line of `scan start --wait` on stderr.
class ProgressBar {
 public:
  ProgressBar() : tty_(::isatty(2) != 0) {}
  /// Without a terminal, a line a second at most (and the final one, `force`).
  void show(const scanmesh::daemon::ScanStatus& s, bool force = false) {
    const auto now = std::chrono::steady_clock::now();
    if (!tty_ && !force && now - last_ < std::chrono::seconds(1)) return;
    last_ = now;
    constexpr int kWidth = 24;
    const double f = s.progress < 0 ? 0 : std::min(1.0, s.progress);
    const int filled = static_cast<int>(f * kWidth);
    const auto& c = s.counters;
    std::fprintf(
        stderr, "%s[%s%s] %3.0f%%  samples %s  points %s  triangles %s  rate %s  lag %.1f s%s",
        tty_ ? "\r" : "", std::string(static_cast<std::size_t>(filled), '#').c_str(),
        std::string(static_cast<std::size_t>(kWidth - filled), '.').c_str(), f * 100,
        thousands(c.samples).c_str(), thousands(c.points).c_str(), thousands(c.triangles).c_str(),
        rate_text(c.rate_hz).c_str(), c.meshing_lag_s, tty_ ? "\033[K" : "\n");
    std::fflush(stderr);
    shown_ = true;
  }
  void done() {
    if (shown_ && tty_) std::fputc('\n', stderr);
  }

 private:
  bool tty_;
  bool shown_ = false;
  std::chrono::steady_clock::time_point last_{};
};

/// Waits for scan `id` to end, showing progress; returns the exit status.
int wait_for_scan(Client& client, std::int64_t id, const Options& o) {
  client.set_timeout(std::chrono::milliseconds(0));
  ProgressBar bar;
  std::string raw;
  while (auto m = client.read(&raw)) {
    if (o.json) std::cout << raw << "\n" << std::flush;
    if (m->cls != proto::MessageClass::kEvent) continue;
    if (m->event != "state" && m->event != "progress") continue;
    const auto s = proto::scan_status_from(m->body);
    if (s.id != id) continue;
    const bool over = m->event == "state" && s.state == ScanState::kIdle;
    if (!o.json) bar.show(s, over);
    if (over) {
      if (!o.json) {
        bar.done();
        std::printf("scan %lld '%s': %s, %s samples, %s points, %s triangles in %.1f s\n",
                    static_cast<long long>(s.id), s.name.c_str(), s.reason.c_str(),
                    thousands(s.counters.samples).c_str(), thousands(s.counters.points).c_str(),
                    thousands(s.counters.triangles).c_str(), s.elapsed_s);
      }
      return s.reason == "finished" ? kExitOk : kExitScanFailed;
    }
  }
  if (!o.json) bar.done();
  std::cerr << "scanctl: the daemon closed the connection before the scan ended\n";
  return kExitConnect;
}

int run(const std::function<int(Client&)>& body, const Options& o) {
  try {
    Client client(o.socket, std::chrono::milliseconds(static_cast<long long>(o.timeout_s * 1000)));
    return body(client);
  } catch (const proto::ProtocolError& e) {
    std::cerr << "scanctl: " << e.what() << "\n";
    return kExitConnect;
  } catch (const scanmesh::Error& e) {
    std::cerr << "scanctl: " << e.what() << "\n";
    return kExitConnect;
  }
}

/// A request whose reply is printed by `human` (or as the raw line with --json).
int simple(Client& client, const std::string& cmd, const proto::Object& args, const Options& o,
           const std::function<void(const proto::Message&)>& human) {
  std::string raw;
  const proto::Message m = client.request(cmd, args, &raw);
  if (m.cls == proto::MessageClass::kError) return report_error(m, raw, o);
  if (o.json)
    std::cout << raw << "\n";
  else
    human(m);
  return kExitOk;
}

std::string absolute(const std::string& p) {
  return std::filesystem::absolute(p).lexically_normal().string();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"scanctl: control scanmeshd over its socket"};
  app.require_subcommand(1);
  Options o;
  app.add_option("--socket", o.socket, "control socket of scanmeshd")->capture_default_str();
  app.add_flag("--json", o.json, "print the daemon's JSON lines instead of text");
  app.add_option("--timeout", o.timeout_s, "seconds to wait for a reply")->capture_default_str();
  std::function<int(Client&)> body;

  auto* version = app.add_subcommand("version", "daemon and protocol version");
  version->callback([&] {
    body = [&](Client& c) {
      return simple(c, "version", {}, o, [](const proto::Message& m) {
        const auto v = proto::version_info_from(m.body);
        std::printf("scanmeshd %s, protocol %d.%d, backend %s\n", v.daemon.c_str(), v.proto_major,
                    v.proto_minor, v.backend.c_str());
      });
    };
  });
  app.add_subcommand("status", "devices, scan state and counters")->callback([&] {
    body = [&](Client& c) { return simple(c, "status", {}, o, print_status); };
  });
  app.add_subcommand("devices", "the configured devices and their states")->callback([&] {
    body = [&](Client& c) {
      return simple(c, "devices", {}, o, [](const proto::Message& m) {
        for (const auto& f : m.body.get_objects("devices")) {
          const auto d = proto::device_info_from(f);
          std::printf("%-14s %-7s %-8s %-6s %-20s %12s samples %6s errors%s\n", d.name.c_str(),
                      d.role.c_str(), d.driver.c_str(), std::string(to_string(d.state)).c_str(),
                      d.port.c_str(), thousands(d.samples).c_str(), thousands(d.errors).c_str(),
                      d.detail.empty() ? "" : ("  " + d.detail).c_str());
        }
      });
    };
  });
  app.add_subcommand("config", "the daemon's running configuration (JSON)")->callback([&] {
    body = [&](Client& c) {
      return simple(c, "config.get", {}, o, [](const proto::Message& m) {
        std::printf("%s\n", m.body.get_object("config").value_or(proto::Fields()).dump().c_str());
      });
    };
  });
  app.add_subcommand("watch", "print events until interrupted")->callback([&] {
    body = [&](Client& c) {
      std::string raw;
      proto::Message m = c.request("watch", proto::Object().set("enable", true), &raw);
      if (m.cls == proto::MessageClass::kError) return report_error(m, raw, o);
      c.set_timeout(std::chrono::milliseconds(0));
      while (auto e = c.read(&raw)) {
        if (o.json)
          std::cout << raw << "\n" << std::flush;
        else if (e->cls == proto::MessageClass::kEvent)
          print_event(*e);
      }
      return kExitOk;
    };
  });

  auto* scan = app.add_subcommand("scan", "start, pause, resume, stop and list scans");
  scan->require_subcommand(1);
  std::string name;
  std::vector<std::string> params;
  bool wait = false;
  auto* start = scan->add_subcommand("start", "start a scan");
  start->add_option("--name", name, "scan name")->required();
  start->add_option("--param", params, "scan parameter KEY=VALUE (repeatable), e.g. part=sphere");
  start->add_flag("--wait", wait, "show progress until the scan ends (exit 4 unless it finished)");
  start->callback([&] {
    body = [&](Client& c) {
      Parameters p;
      for (const auto& kv : params) {
        const auto eq = kv.find('=');
        if (eq == std::string::npos || eq == 0) {
          std::cerr << "scanctl: --param wants KEY=VALUE, got '" << kv << "'\n";
          return kExitUsage;
        }
        p[kv.substr(0, eq)] = parse_scalar(kv.substr(eq + 1));
      }
      std::string raw;
      if (wait) {
        const proto::Message w = c.request("watch", proto::Object().set("enable", true), &raw);
        if (w.cls == proto::MessageClass::kError) return report_error(w, raw, o);
      }
      const proto::Message m =
          c.request("scan.start", proto::Object().set("name", name).set("parameters", p), &raw);
      if (m.cls == proto::MessageClass::kError) return report_error(m, raw, o);
      const auto rec = proto::scan_record_from(m.body.get_object("scan").value_or(proto::Fields()));
      if (o.json)
        std::cout << raw << "\n" << std::flush;
      else
        std::printf("scan %lld '%s' started\n", static_cast<long long>(rec.id), rec.name.c_str());
      std::fflush(stdout);
      return wait ? wait_for_scan(c, rec.id, o) : kExitOk;
    };
  });
  for (const auto& [sub, cmd, help] :
       std::vector<std::tuple<std::string, std::string, std::string>>{
           {"pause", "scan.pause", "pause the running scan"},
           {"resume", "scan.resume", "resume the paused scan"},
           {"stop", "scan.stop", "stop the running scan (its journal and mesh are kept)"}}) {
    scan->add_subcommand(sub, help)->callback([&, cmd = cmd] {
      body = [&, cmd](Client& c) {
        return simple(c, cmd, {}, o, [](const proto::Message& m) {
          const auto s =
              proto::scan_status_from(m.body.get_object("scan").value_or(proto::Fields()));
          std::printf("scan %lld '%s': %s\n", static_cast<long long>(s.id), s.name.c_str(),
                      std::string(to_string(s.state)).c_str());
        });
      };
    });
  }
  scan->add_subcommand("list", "the scan catalog")->callback([&] {
    body = [&](Client& c) {
      return simple(c, "scan.list", {}, o, [](const proto::Message& m) {
        std::printf("%5s  %-20s %-11s %-20s %12s %12s %12s\n", "id", "name", "state", "started",
                    "samples", "points", "triangles");
        for (const auto& f : m.body.get_objects("scans")) print_record(proto::scan_record_from(f));
      });
    };
  });
  std::int64_t scan_id = 0;
  for (const auto& [sub, cmd, help] :
       std::vector<std::tuple<std::string, std::string, std::string>>{
           {"info", "scan.info", "one scan of the catalog"},
           {"resume-interrupted", "scan.resume_interrupted", "continue a scan a crash interrupted"},
           {"close-interrupted", "scan.close_interrupted", "close a scan a crash interrupted"}}) {
    auto* s = scan->add_subcommand(sub, help);
    s->add_option("ID", scan_id, "scan id")->required();
    s->callback([&, cmd = cmd] {
      body = [&, cmd](Client& c) {
        return simple(c, cmd, proto::Object().set("scan", scan_id), o, [](const proto::Message& m) {
          const auto r =
              proto::scan_record_from(m.body.get_object("scan").value_or(proto::Fields()));
          print_record(r);
          if (!r.reason.empty()) std::printf("       %s\n", r.reason.c_str());
          std::printf("       journal %s (%s bytes)\n", r.journal.c_str(),
                      thousands(r.journal_bytes).c_str());
        });
      };
    });
  }

  auto* mesh = app.add_subcommand("mesh", "export or preview the mesh");
  mesh->require_subcommand(1);
  std::string path;
  std::optional<std::int64_t> mesh_scan;
  bool ascii = false;
  int width = 1024, height = 768;
  auto* exp = mesh->add_subcommand("export", "write the mesh as STL, PLY or OBJ (by extension)");
  exp->add_option("--path", path, "file to write (in a folder the daemon may write)")->required();
  exp->add_option("--scan", mesh_scan, "a past scan's id (default: the current or last scan)");
  exp->add_flag("--ascii", ascii, "ASCII STL instead of binary");
  exp->callback([&] {
    body = [&](Client& c) {
      proto::Object args;
      args.set("path", absolute(path));
      if (mesh_scan) args.set("scan", *mesh_scan);
      if (ascii) args.set("ascii", true);
      return simple(c, "mesh.export", args, o, [](const proto::Message& m) {
        const auto e = proto::export_info_from(m.body);
        std::printf("wrote %s (%s, scan %lld: %s triangles, %s vertices, %s bytes)\n",
                    e.path.c_str(), e.format.c_str(), static_cast<long long>(e.scan),
                    thousands(e.triangles).c_str(), thousands(e.vertices).c_str(),
                    thousands(e.bytes).c_str());
      });
    };
  });
  auto* prev =
      mesh->add_subcommand("preview", "render a shaded PNG of the mesh with the scan's progress");
  prev->add_option("--path", path, "PNG file to write")->required();
  prev->add_option("--scan", mesh_scan, "a past scan's id (default: the current or last scan)");
  prev->add_option("--width", width, "pixels")->capture_default_str();
  prev->add_option("--height", height, "pixels")->capture_default_str();
  prev->callback([&] {
    body = [&](Client& c) {
      proto::Object args;
      args.set("path", absolute(path)).set("width_px", width).set("height_px", height);
      if (mesh_scan) args.set("scan", *mesh_scan);
      return simple(c, "mesh.preview", args, o, [](const proto::Message& m) {
        const auto p = proto::preview_info_from(m.body);
        std::printf("wrote %s (%dx%d, scan %lld, %s bytes)\n", p.path.c_str(), p.width_px,
                    p.height_px, static_cast<long long>(p.scan), thousands(p.bytes).c_str());
      });
    };
  });

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? kExitOk : kExitUsage;
  }
  if (!body) return kExitUsage;
  return run(body, o);
}
