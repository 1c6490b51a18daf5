// The control protocol codec: request decoding (table of good and bad lines), the exact bytes of
// HELLO / REPLY / ERROR / EVENT lines, type-checked argument access, and every message value's
// JSON form read back by an independent parser and by the codec's own decoder.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "scanmesh/daemon/protocol.hpp"

using namespace scanmesh::daemon;
namespace errc = proto::errc;

namespace {

struct DecodeCase {
  const char* legend;
  std::string line;
  std::string cmd;  ///< expected command, or "" when an error is expected
  std::optional<std::int64_t> id;
  std::string error_code;  ///< expected ProtocolError code
};

}  // namespace

TEST_CASE("requests decode or fail with the right code and keep their id", "[daemon][protocol]") {
  const std::vector<DecodeCase> cases = {
      {"plain request", R"({"cmd":"status","id":1})", "status", 1, ""},
      {"no id (allowed: the reply carries null)", R"({"cmd":"version"})", "version", std::nullopt,
       ""},
      {"negative and large ids", R"({"cmd":"status","id":-9007199254740993})", "status",
       -9007199254740993LL, ""},
      {"extra fields are arguments", R"({"cmd":"scan.info","id":7,"scan":3})", "scan.info", 7, ""},
      {"leading and trailing blanks", "  {\"cmd\":\"status\",\"id\":2}  ", "status", 2, ""},
      {"unicode escapes", R"({"cmd":"st\u0061tus","id":3})", "status", 3, ""},
      {"not JSON", "status", "", std::nullopt, std::string(errc::kInvalidJson)},
      {"truncated object", R"({"cmd":"status","id":1)", "", std::nullopt,
       std::string(errc::kInvalidJson)},
      {"two objects on one line", R"({"cmd":"a"}{"cmd":"b"})", "", std::nullopt,
       std::string(errc::kInvalidJson)},
      {"invalid UTF-8", std::string("{\"cmd\":\"st\xff\xfe\",\"id\":1}"), "", std::nullopt,
       std::string(errc::kInvalidJson)},
      {"an array", R"([1,2,3])", "", std::nullopt, std::string(errc::kBadRequest)},
      {"a string", R"("status")", "", std::nullopt, std::string(errc::kBadRequest)},
      {"no cmd, id kept", R"({"id":5})", "", 5, std::string(errc::kBadRequest)},
      {"cmd not a string, id kept", R"({"cmd":5,"id":6})", "", 6, std::string(errc::kBadRequest)},
      {"id a string", R"({"cmd":"status","id":"1"})", "", std::nullopt,
       std::string(errc::kBadRequest)},
      {"id a float", R"({"cmd":"status","id":1.5})", "", std::nullopt,
       std::string(errc::kBadRequest)},
      {"id beyond int64", R"({"cmd":"status","id":18446744073709551615})", "", std::nullopt,
       std::string(errc::kBadRequest)},
  };
  for (const auto& c : cases) {
    INFO(c.legend);
    if (c.error_code.empty()) {
      const proto::Request r = proto::decode_request(c.line);
      CHECK(r.cmd == c.cmd);
      CHECK(r.id == c.id);
    } else {
      try {
        proto::decode_request(c.line);
        FAIL("no error");
      } catch (const proto::ProtocolError& e) {
        CHECK(e.code() == c.error_code);
        CHECK(e.id() == c.id);
      }
    }
  }
}

TEST_CASE("lines have the documented bytes", "[daemon][protocol]") {
  CHECK(proto::hello_line("1.2.3") ==
        "{\"class\":\"HELLO\",\"proto_major\":1,\"proto_minor\":0,\"daemon\":\"1.2.3\"}\n");
  CHECK(proto::error_line(4, errc::kUnknownCommand, "unknown command 'x'") ==
        "{\"class\":\"ERROR\",\"id\":4,\"code\":\"unknown_command\",\"message\":\"unknown command "
        "'x'\"}\n");
  CHECK(proto::error_line(std::nullopt, errc::kInvalidJson, "bad") ==
        "{\"class\":\"ERROR\",\"id\":null,\"code\":\"invalid_json\",\"message\":\"bad\"}\n");
  proto::Object body;
  body.set("watching", true).set("n", 3u).set("x", -1.5);
  CHECK(proto::reply_line(9, "watch", body) ==
        "{\"class\":\"REPLY\",\"id\":9,\"cmd\":\"watch\",\"watching\":true,\"n\":3,\"x\":-1.5}\n");
  // A body cannot override the envelope.
  proto::Object sneaky;
  sneaky.set("class", "EVENT").set("id", 99);
  CHECK(proto::reply_line(1, "status", sneaky) ==
        "{\"class\":\"REPLY\",\"id\":1,\"cmd\":\"status\"}\n");
  CHECK(proto::event_line("mesh", proto::to_object(MeshCounts{2, 10, 20, 5, 1})) ==
        "{\"class\":\"EVENT\",\"event\":\"mesh\",\"scan\":2,\"vertices\":10,\"triangles\":20,"
        "\"added\":5,\"removed\":1}\n");
  CHECK(proto::request_line("scan.info", 3, proto::Object().set("scan", 12)) ==
        "{\"cmd\":\"scan.info\",\"id\":3,\"scan\":12}\n");
  // NaN and infinity have no JSON form: null.
  CHECK(proto::Object().set("v", std::nan("")).dump() == "{\"v\":null}");
  // Bytes that are not UTF-8 (a path) are replaced, never thrown on.
  const std::string dumped = proto::Object().set("path", std::string("/tmp/\xff.stl")).dump();
  CHECK(nlohmann::json::parse(dumped)["path"].get<std::string>() == "/tmp/\xEF\xBF\xBD.stl");
}

TEST_CASE("arguments are read with type checks naming the key", "[daemon][protocol]") {
  const proto::Request r = proto::decode_request(
      R"({"cmd":"x","id":1,"s":"a","i":-4,"u":7,"f":2.5,"b":true,"o":{"k":1},"n":null,)"
      R"("p":{"part":"sphere","spacing_mm":0.5,"seed":3,"fast":false},"bad":{"x":[1]}})");
  const proto::Fields& a = r.args;
  CHECK(a.get_string("s") == "a");
  CHECK(a.get_int("i") == -4);
  CHECK(a.get_uint("u") == 7u);
  CHECK(a.get_number("f") == 2.5);
  CHECK(a.get_number("i") == -4.0);
  CHECK(a.get_bool("b") == true);
  CHECK(a.get_object("o")->get_int("k") == 1);
  CHECK_FALSE(a.get_string("n").has_value());  // null is absent
  CHECK_FALSE(a.get_string("missing").has_value());
  const Parameters p = *a.get_parameters("p");
  CHECK(std::get<std::string>(p.at("part")) == "sphere");
  CHECK(std::get<double>(p.at("spacing_mm")) == 0.5);
  CHECK(std::get<std::int64_t>(p.at("seed")) == 3);
  CHECK(std::get<bool>(p.at("fast")) == false);
  auto code_of = [](auto&& f) {
    try {
      f();
    } catch (const proto::ProtocolError& e) {
      return e.code() + ": " + e.what();
    }
    return std::string("no error");
  };
  CHECK(code_of([&] { a.get_int("s"); }) == "bad_argument: 's' must be an integer, got a string");
  CHECK(code_of([&] { a.get_int("f"); }) == "bad_argument: 'f' must be an integer, got a number");
  CHECK(code_of([&] { a.get_uint("i"); }) ==
        "bad_argument: 'i' must be an integer >= 0, got an integer");
  CHECK(code_of([&] { a.get_string("b"); }) == "bad_argument: 'b' must be a string, got a boolean");
  CHECK(code_of([&] { a.get_bool("i"); }) ==
        "bad_argument: 'i' must be true or false, got an integer");
  CHECK(code_of([&] { a.get_parameters("bad"); }) ==
        "bad_argument: 'bad.x' must be a string, number or boolean, got an array");
}

TEST_CASE("every message value round-trips through its one JSON form", "[daemon][protocol]") {
  StatusInfo s;
  s.daemon_state = "ready";
  s.backend = "sim";
  s.uptime_s = 12.5;
  s.clients = 3;
  s.protocol_errors = 2;
  s.devices.push_back(
      {"lkg", "sensor", "keyence-lkg", "/dev/ttyUSB0", DeviceState::kLost, "timeout", 100, 4});
  s.devices.push_back({"stage", "stage", "grbl", "", DeviceState::kOk, "", 5, 0});
  s.scan.state = ScanState::kPaused;
  s.scan.reason = "device_lost: lkg";
  s.scan.id = 42;
  s.scan.name = "bracket";
  s.scan.elapsed_s = 3.25;
  s.scan.progress = 0.5;
  s.scan.counters = {1000, 900, 1700, 880, 20, 0.05, 65536, 400.5, 3};
  const std::string line = proto::reply_line(1, "status", proto::to_object(s));

  // An independent reader sees the documented field names.
  const auto j = nlohmann::json::parse(line);
  CHECK(j["class"] == "REPLY");
  CHECK(j["devices"][0]["state"] == "lost");
  CHECK(j["scan"]["state"] == "paused");
  CHECK(j["scan"]["meshing_lag_points"] == 20);
  CHECK(j["scan"]["journal_bytes"] == 65536);
  for (const char* key : {"samples", "points", "triangles", "vertices", "meshing_lag_points",
                          "meshing_lag_s", "journal_bytes", "rate_hz", "errors", "progress",
                          "elapsed_s", "reason", "id", "name", "state"})
    CHECK(j["scan"].contains(key));

  // And the codec's own decoder gives the values back.
  const proto::Message m = proto::decode_message(line.substr(0, line.size() - 1));
  CHECK(m.cls == proto::MessageClass::kReply);
  CHECK(m.id == 1);
  CHECK(m.cmd == "status");
  const StatusInfo back = proto::status_info_from(m.body);
  CHECK(back.devices.size() == 2);
  CHECK(back.devices[0].state == DeviceState::kLost);
  CHECK(back.devices[0].detail == "timeout");
  CHECK(back.devices[0].errors == 4);
  CHECK(back.scan.state == ScanState::kPaused);
  CHECK(back.scan.id == 42);
  CHECK(back.scan.counters.points == 900);
  CHECK(back.scan.counters.rate_hz == 400.5);
  CHECK(back.uptime_s == 12.5);

  ScanRecord r;
  r.id = 7;
  r.name = "n";
  r.state = "interrupted";
  r.started_utc = "2024-01-01T00:00:00Z";
  r.samples = 5;
  r.parameters = {
      {"part", std::string("sphere")}, {"seed", std::int64_t{4}}, {"x", 0.25}, {"b", true}};
  const ScanRecord r2 = proto::scan_record_from(proto::Fields(proto::to_object(r)));
  CHECK(r2.id == 7);
  CHECK(r2.state == "interrupted");
  CHECK(r2.parameters == r.parameters);

  const ExportInfo e{3, "/x/y.stl", "stl", 10, 20, 1084};
  const ExportInfo e2 = proto::export_info_from(proto::Fields(proto::to_object(e)));
  CHECK((e2.scan == 3 && e2.path == e.path && e2.triangles == 20 && e2.bytes == 1084));
  const PreviewInfo p{3, "/x/y.png", 640, 480, 999};
  const PreviewInfo p2 = proto::preview_info_from(proto::Fields(proto::to_object(p)));
  CHECK((p2.width_px == 640 && p2.height_px == 480 && p2.bytes == 999));
  const VersionInfo v{"0.1.0", 1, 0, "sim"};
  const VersionInfo v2 = proto::version_info_from(proto::Fields(proto::to_object(v)));
  CHECK((v2.daemon == "0.1.0" && v2.proto_major == 1 && v2.backend == "sim"));
}

TEST_CASE("clients ignore fields they do not know and reject lines that are not objects",
          "[daemon][protocol]") {
  const proto::Message m = proto::decode_message(
      R"({"class":"EVENT","event":"device","name":"x","state":"ok","future":[1,{"a":2}]})");
  CHECK(m.cls == proto::MessageClass::kEvent);
  CHECK(m.event == "device");
  CHECK(proto::device_info_from(m.body).state == DeviceState::kOk);
  const proto::Message other = proto::decode_message(R"({"class":"NEWCLASS","x":1})");
  CHECK(other.cls == proto::MessageClass::kOther);
  CHECK(other.class_name == "NEWCLASS");
  CHECK_THROWS_AS(proto::decode_message("not json"), proto::ProtocolError);
  CHECK_THROWS_AS(proto::decode_message(R"({"no_class":1})"), proto::ProtocolError);
}
