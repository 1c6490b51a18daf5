// libFuzzer target for the control protocol's decoder: the bytes a client sends, split into
// lines as the server splits them (at most 64 KiB each), decoded as requests and read through
// every typed getter; and decoded as server lines as a client does. Anything but ProtocolError
// escaping, or a sanitizer report, is a bug.
// SPDX-License-Identifier: MIT
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "scanmesh/daemon/protocol.hpp"

using namespace scanmesh::daemon;

namespace {

void read_everything(const proto::Fields& f, int depth) {
  if (depth > 4) return;
  for (const auto& key : f.keys()) {
    auto guarded = [&](auto&& get) {
      try {
        get();
      } catch (const proto::ProtocolError&) {
      }
    };
    guarded([&] { (void)f.get_string(key); });
    guarded([&] { (void)f.get_int(key); });
    guarded([&] { (void)f.get_uint(key); });
    guarded([&] { (void)f.get_number(key); });
    guarded([&] { (void)f.get_bool(key); });
    guarded([&] { (void)f.get_parameters(key); });
    guarded([&] { (void)f.get_strings(key); });
    guarded([&] {
      if (auto o = f.get_object(key)) read_everything(*o, depth + 1);
    });
    guarded([&] {
      for (const auto& o : f.get_objects(key)) read_everything(o, depth + 1);
    });
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string_view bytes(reinterpret_cast<const char*>(data), size);
  while (!bytes.empty()) {
    const std::size_t nl = bytes.find('\n');
    std::string_view line = bytes.substr(0, nl);
    bytes = nl == std::string_view::npos ? std::string_view() : bytes.substr(nl + 1);
    if (line.size() > proto::kMaxLineBytes) continue;  // the server refuses it unread
    try {
      const proto::Request r = proto::decode_request(line);
      read_everything(r.args, 0);
      // What the server sends back quotes parts of the request: it must always serialise.
      (void)proto::error_line(r.id, proto::errc::kUnknownCommand,
                              "unknown command '" + r.cmd + "'");
    } catch (const proto::ProtocolError&) {
    }
    try {
      const proto::Message m = proto::decode_message(line);
      (void)proto::status_info_from(m.body);
      (void)proto::scan_record_from(m.body);
      (void)m.body.dump();
    } catch (const proto::ProtocolError&) {
    }
  }
  return 0;
}
