// The control protocol codec over nlohmann-json (ordered objects, so keys go out in the order
// they were set: "class" first). The only file of the daemon that sees the JSON library.
// SPDX-License-Identifier: MIT
#include "scanmesh/daemon/protocol.hpp"

#include <cmath>
#include <nlohmann/json.hpp>
#include <utility>

namespace scanmesh::daemon {

namespace {
constexpr std::string_view kDeviceStates[] = {"closed", "opening", "ok", "lost", "failed"};
constexpr std::string_view kScanStates[] = {"idle", "running", "paused", "stopping"};
}  // namespace

std::string_view to_string(DeviceState state) {
  return kDeviceStates[static_cast<std::size_t>(state)];
}
std::optional<DeviceState> device_state_from_string(std::string_view word) {
  for (std::size_t i = 0; i < std::size(kDeviceStates); ++i)
    if (kDeviceStates[i] == word) return static_cast<DeviceState>(i);
  return std::nullopt;
}
std::string_view to_string(ScanState state) { return kScanStates[static_cast<std::size_t>(state)]; }
std::optional<ScanState> scan_state_from_string(std::string_view word) {
  for (std::size_t i = 0; i < std::size(kScanStates); ++i)
    if (kScanStates[i] == word) return static_cast<ScanState>(i);
  return std::nullopt;
}

namespace proto {

using Json = nlohmann::ordered_json;

struct Object::Impl {
  Json j = Json::object();
};
struct Fields::Impl {
  Json j = Json::object();
};

/// Access to the JSON inside Object and Fields for this file.
struct Codec {
  static Json& json(Object& o) { return o.impl_->j; }
  static const Json& json(const Object& o) { return o.impl_->j; }
  static const Json& json(const Fields& f) { return f.impl_->j; }
  static Fields wrap(Json j) {
    auto impl = std::make_shared<Fields::Impl>();
    impl->j = std::move(j);
    return Fields(std::shared_ptr<const Fields::Impl>(std::move(impl)));
  }
};

namespace {

/// Text of any string we did not make (paths, device details) may not be UTF-8: replace bad bytes
/// instead of throwing.
std::string dump_json(const Json& j) {
  return j.dump(-1, ' ', false, Json::error_handler_t::replace);
}

const char* type_word(const Json& v) {
  switch (v.type()) {
    case Json::value_t::null:
      return "null";
    case Json::value_t::object:
      return "an object";
    case Json::value_t::array:
      return "an array";
    case Json::value_t::string:
      return "a string";
    case Json::value_t::boolean:
      return "a boolean";
    case Json::value_t::number_integer:
    case Json::value_t::number_unsigned:
      return "an integer";
    case Json::value_t::number_float:
      return "a number";
    default:
      return "something else";
  }
}

[[noreturn]] void wrong_type(std::string_view key, const char* want, const Json& got) {
  throw ProtocolError(errc::kBadArgument,
                      "'" + std::string(key) + "' must be " + want + ", got " + type_word(got));
}

/// The value under key, or nullptr when absent or null.
const Json* find(const Json& j, std::string_view key) {
  const auto it = j.find(key);
  if (it == j.end() || it->is_null()) return nullptr;
  return &*it;
}

Json scalar_json(const Scalar& s) {
  return std::visit([](const auto& v) { return Json(v); }, s);
}

std::optional<Scalar> json_scalar(const Json& v) {
  if (v.is_boolean()) return Scalar(v.get<bool>());
  if (v.is_number_integer()) {
    if (v.is_number_unsigned() && v.get<std::uint64_t>() > static_cast<std::uint64_t>(INT64_MAX))
      return Scalar(static_cast<double>(v.get<std::uint64_t>()));
    return Scalar(v.get<std::int64_t>());
  }
  if (v.is_number_float()) return Scalar(v.get<double>());
  if (v.is_string()) return Scalar(v.get<std::string>());
  return std::nullopt;
}

/// The id of a request object: an integer, or absent. Anything else is a bad request.
std::optional<std::int64_t> read_id(const Json& j) {
  const Json* v = find(j, "id");
  if (v == nullptr) return std::nullopt;
  if (v->is_number_integer() &&
      !(v->is_number_unsigned() && v->get<std::uint64_t>() > static_cast<std::uint64_t>(INT64_MAX)))
    return v->get<std::int64_t>();
  throw ProtocolError(errc::kBadRequest,
                      std::string("'id' must be an integer, got ") + type_word(*v));
}

Json parse_object(std::string_view line) {
  Json j = Json::parse(line, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded())
    throw ProtocolError(errc::kInvalidJson, "the line is not valid JSON (UTF-8, one object)");
  if (!j.is_object())
    throw ProtocolError(errc::kBadRequest,
                        std::string("a request must be a JSON object, got ") + type_word(j));
  return j;
}

std::string with_class(std::string_view cls, std::optional<std::int64_t> id, bool with_id,
                       std::string_view cmd, const Json& body) {
  Json out = Json::object();
  out["class"] = cls;
  if (with_id) out["id"] = id ? Json(*id) : Json(nullptr);
  if (!cmd.empty()) out["cmd"] = cmd;
  for (const auto& [k, v] : body.items())
    if (!out.contains(k)) out[k] = v;
  return dump_json(out) + "\n";
}

}  // namespace

// ---- Object

Object::Object() : impl_(std::make_unique<Impl>()) {}
Object::~Object() = default;
Object::Object(const Object& other) : impl_(std::make_unique<Impl>(*other.impl_)) {}
Object::Object(Object&& other) noexcept : impl_(std::move(other.impl_)) {}
Object& Object::operator=(const Object& other) {
  if (this != &other) impl_ = std::make_unique<Impl>(*other.impl_);
  return *this;
}
Object& Object::operator=(Object&& other) noexcept {
  impl_ = std::move(other.impl_);
  return *this;
}
Object& Object::set(std::string_view key, std::string_view value) {
  impl_->j[std::string(key)] = std::string(value);
  return *this;
}
Object& Object::set(std::string_view key, bool value) {
  impl_->j[std::string(key)] = value;
  return *this;
}
Object& Object::set(std::string_view key, double value) {
  // JSON has no NaN or infinity: they go out as null.
  impl_->j[std::string(key)] = std::isfinite(value) ? Json(value) : Json(nullptr);
  return *this;
}
Object& Object::set_int(std::string_view key, std::int64_t value) {
  impl_->j[std::string(key)] = value;
  return *this;
}
Object& Object::set_uint(std::string_view key, std::uint64_t value) {
  impl_->j[std::string(key)] = value;
  return *this;
}
Object& Object::set(std::string_view key, const Object& value) {
  impl_->j[std::string(key)] = value.impl_->j;
  return *this;
}
Object& Object::set(std::string_view key, const std::vector<Object>& values) {
  Json a = Json::array();
  for (const auto& v : values) a.push_back(v.impl_->j);
  impl_->j[std::string(key)] = std::move(a);
  return *this;
}
Object& Object::set(std::string_view key, const std::vector<std::string>& values) {
  impl_->j[std::string(key)] = values;
  return *this;
}
Object& Object::set(std::string_view key, const Parameters& values) {
  Json o = Json::object();
  for (const auto& [k, v] : values) o[k] = scalar_json(v);
  impl_->j[std::string(key)] = std::move(o);
  return *this;
}
Object& Object::set_null(std::string_view key) {
  impl_->j[std::string(key)] = nullptr;
  return *this;
}
std::string Object::dump() const { return dump_json(impl_->j); }

// ---- Fields

Fields::Fields() : impl_(std::make_shared<const Impl>()) {}
Fields::Fields(const Object& object) : Fields(Codec::wrap(Codec::json(object))) {}

bool Fields::has(std::string_view key) const { return find(impl_->j, key) != nullptr; }

std::vector<std::string> Fields::keys() const {
  std::vector<std::string> out;
  for (const auto& [k, v] : impl_->j.items()) out.push_back(k);
  return out;
}

std::optional<std::string> Fields::get_string(std::string_view key) const {
  const Json* v = find(impl_->j, key);
  if (v == nullptr) return std::nullopt;
  if (!v->is_string()) wrong_type(key, "a string", *v);
  return v->get<std::string>();
}

std::optional<std::int64_t> Fields::get_int(std::string_view key) const {
  const Json* v = find(impl_->j, key);
  if (v == nullptr) return std::nullopt;
  if (!v->is_number_integer() ||
      (v->is_number_unsigned() && v->get<std::uint64_t>() > static_cast<std::uint64_t>(INT64_MAX)))
    wrong_type(key, "an integer", *v);
  return v->get<std::int64_t>();
}

std::optional<std::uint64_t> Fields::get_uint(std::string_view key) const {
  const Json* v = find(impl_->j, key);
  if (v == nullptr) return std::nullopt;
  if (v->is_number_unsigned()) return v->get<std::uint64_t>();
  if (v->is_number_integer() && v->get<std::int64_t>() >= 0)
    return static_cast<std::uint64_t>(v->get<std::int64_t>());
  wrong_type(key, "an integer >= 0", *v);
}

std::optional<double> Fields::get_number(std::string_view key) const {
  const Json* v = find(impl_->j, key);
  if (v == nullptr) return std::nullopt;
  if (!v->is_number()) wrong_type(key, "a number", *v);
  return v->get<double>();
}

std::optional<bool> Fields::get_bool(std::string_view key) const {
  const Json* v = find(impl_->j, key);
  if (v == nullptr) return std::nullopt;
  if (!v->is_boolean()) wrong_type(key, "true or false", *v);
  return v->get<bool>();
}

std::optional<Fields> Fields::get_object(std::string_view key) const {
  const Json* v = find(impl_->j, key);
  if (v == nullptr) return std::nullopt;
  if (!v->is_object()) wrong_type(key, "an object", *v);
  return Codec::wrap(*v);
}

std::vector<Fields> Fields::get_objects(std::string_view key) const {
  const Json* v = find(impl_->j, key);
  std::vector<Fields> out;
  if (v == nullptr) return out;
  if (!v->is_array()) wrong_type(key, "an array of objects", *v);
  for (const auto& e : *v) {
    if (!e.is_object()) wrong_type(key, "an array of objects", e);
    out.push_back(Codec::wrap(e));
  }
  return out;
}

std::vector<std::string> Fields::get_strings(std::string_view key) const {
  const Json* v = find(impl_->j, key);
  std::vector<std::string> out;
  if (v == nullptr) return out;
  if (!v->is_array()) wrong_type(key, "an array of strings", *v);
  for (const auto& e : *v) {
    if (!e.is_string()) wrong_type(key, "an array of strings", e);
    out.push_back(e.get<std::string>());
  }
  return out;
}

std::optional<Parameters> Fields::get_parameters(std::string_view key) const {
  const Json* v = find(impl_->j, key);
  if (v == nullptr) return std::nullopt;
  if (!v->is_object()) wrong_type(key, "an object", *v);
  Parameters out;
  for (const auto& [k, e] : v->items()) {
    auto s = json_scalar(e);
    if (!s) wrong_type(std::string(key) + "." + k, "a string, number or boolean", e);
    out.emplace(k, std::move(*s));
  }
  return out;
}

std::string Fields::dump() const { return dump_json(impl_->j); }

// ---- lines

Request decode_request(std::string_view line) {
  Json j = parse_object(line);
  std::optional<std::int64_t> id = read_id(j);
  const Json* cmd = find(j, "cmd");
  if (cmd == nullptr)
    throw ProtocolError(errc::kBadRequest, "a request needs a \"cmd\" (a command name)", id);
  if (!cmd->is_string())
    throw ProtocolError(errc::kBadRequest,
                        std::string("'cmd' must be a string, got ") + type_word(*cmd), id);
  Request r;
  r.cmd = cmd->get<std::string>();
  r.id = id;
  r.args = Codec::wrap(std::move(j));
  return r;
}

Message decode_message(std::string_view line) {
  Json j = Json::parse(line, nullptr, false);
  if (j.is_discarded() || !j.is_object() || !j.contains("class") || !j["class"].is_string())
    throw ProtocolError(errc::kInvalidJson,
                        "not a protocol object: " + std::string(line.substr(0, 200)));
  Message m;
  m.class_name = j["class"].get<std::string>();
  if (m.class_name == "HELLO")
    m.cls = MessageClass::kHello;
  else if (m.class_name == "REPLY")
    m.cls = MessageClass::kReply;
  else if (m.class_name == "ERROR")
    m.cls = MessageClass::kError;
  else if (m.class_name == "EVENT")
    m.cls = MessageClass::kEvent;
  m.body = Codec::wrap(std::move(j));
  if (const Json* id = find(Codec::json(m.body), "id"); id && id->is_number_integer())
    m.id = id->get<std::int64_t>();
  m.cmd = m.body.get_string("cmd").value_or("");
  m.event = m.body.get_string("event").value_or("");
  if (m.cls == MessageClass::kError) {
    m.error_code = m.body.get_string("code").value_or("");
    m.error_message = m.body.get_string("message").value_or("");
  }
  return m;
}

std::string hello_line(std::string_view daemon_version) {
  Json b = Json::object();
  b["proto_major"] = kMajor;
  b["proto_minor"] = kMinor;
  b["daemon"] = daemon_version;
  return with_class("HELLO", std::nullopt, false, "", b);
}

std::string reply_line(std::optional<std::int64_t> id, std::string_view cmd, const Object& body) {
  return with_class("REPLY", id, true, cmd, Codec::json(body));
}

std::string error_line(std::optional<std::int64_t> id, std::string_view code,
                       std::string_view message) {
  Json b = Json::object();
  b["code"] = code;
  b["message"] = message;
  return with_class("ERROR", id, true, "", b);
}

std::string event_line(std::string_view event, const Object& body) {
  Json b = Json::object();
  b["event"] = event;
  for (const auto& [k, v] : Codec::json(body).items())
    if (!b.contains(k)) b[k] = v;
  return with_class("EVENT", std::nullopt, false, "", b);
}

std::string request_line(std::string_view cmd, std::int64_t id, const Object& args) {
  Json out = Json::object();
  out["cmd"] = cmd;
  out["id"] = id;
  for (const auto& [k, v] : Codec::json(args).items())
    if (!out.contains(k)) out[k] = v;
  return dump_json(out) + "\n";
}

// ---- message values

Object to_object(const DeviceInfo& v) {
  Object o;
  o.set("name", v.name).set("role", v.role).set("driver", v.driver).set("port", v.port);
  o.set("state", to_string(v.state)).set("detail", v.detail);
  o.set("samples", v.samples).set("errors", v.errors);
  return o;
}

Object to_object(const ScanCounters& v) {
  Object o;
  o.set("samples", v.samples).set("points", v.points).set("triangles", v.triangles);
  o.set("vertices", v.vertices).set("meshing_lag_points", v.meshing_lag_points);
  o.set("meshing_lag_s", v.meshing_lag_s).set("journal_bytes", v.journal_bytes);
  o.set("rate_hz", v.rate_hz).set("errors", v.errors);
  return o;
}

Object to_object(const ScanStatus& v) {
  Object o;
  o.set("state", to_string(v.state)).set("reason", v.reason).set("id", v.id).set("name", v.name);
  o.set("elapsed_s", v.elapsed_s).set("progress", v.progress);
  const Object counters = to_object(v.counters);
  for (const auto& [k, e] : Codec::json(counters).items()) Codec::json(o)[k] = e;
  return o;
}

Object to_object(const ScanRecord& v) {
  Object o;
  o.set("id", v.id).set("name", v.name).set("state", v.state);
  o.set("started_utc", v.started_utc).set("stopped_utc", v.stopped_utc).set("reason", v.reason);
  o.set("samples", v.samples).set("points", v.points).set("triangles", v.triangles);
  o.set("journal_bytes", v.journal_bytes).set("journal", v.journal);
  o.set("parameters", v.parameters);
  return o;
}

Object to_object(const MeshCounts& v) {
  Object o;
  o.set("scan", v.scan).set("vertices", v.vertices).set("triangles", v.triangles);
  o.set("added", v.added).set("removed", v.removed);
  return o;
}

Object to_object(const VersionInfo& v) {
  Object o;
  o.set("daemon", v.daemon).set("proto_major", v.proto_major).set("proto_minor", v.proto_minor);
  o.set("backend", v.backend);
  return o;
}

Object to_object(const StatusInfo& v) {
  Object o;
  o.set("daemon_state", v.daemon_state).set("backend", v.backend).set("uptime_s", v.uptime_s);
  o.set("clients", v.clients).set("protocol_errors", v.protocol_errors);
  std::vector<Object> devices;
  for (const auto& d : v.devices) devices.push_back(to_object(d));
  o.set("devices", devices).set("scan", to_object(v.scan));
  return o;
}

Object to_object(const ExportInfo& v) {
  Object o;
  o.set("scan", v.scan).set("path", v.path).set("format", v.format);
  o.set("vertices", v.vertices).set("triangles", v.triangles).set("bytes", v.bytes);
  return o;
}

Object to_object(const PreviewInfo& v) {
  Object o;
  o.set("scan", v.scan).set("path", v.path).set("width_px", v.width_px);
  o.set("height_px", v.height_px).set("bytes", v.bytes);
  return o;
}

DeviceInfo device_info_from(const Fields& f) {
  DeviceInfo d;
  d.name = f.get_string("name").value_or("");
  d.role = f.get_string("role").value_or("");
  d.driver = f.get_string("driver").value_or("");
  d.port = f.get_string("port").value_or("");
  d.state =
      device_state_from_string(f.get_string("state").value_or("")).value_or(DeviceState::kClosed);
  d.detail = f.get_string("detail").value_or("");
  d.samples = f.get_uint("samples").value_or(0);
  d.errors = f.get_uint("errors").value_or(0);
  return d;
}

ScanStatus scan_status_from(const Fields& f) {
  ScanStatus s;
  s.state = scan_state_from_string(f.get_string("state").value_or("")).value_or(ScanState::kIdle);
  s.reason = f.get_string("reason").value_or("");
  s.id = f.get_int("id").value_or(0);
  s.name = f.get_string("name").value_or("");
  s.elapsed_s = f.get_number("elapsed_s").value_or(0);
  s.progress = f.get_number("progress").value_or(-1);
  auto& c = s.counters;
  c.samples = f.get_uint("samples").value_or(0);
  c.points = f.get_uint("points").value_or(0);
  c.triangles = f.get_uint("triangles").value_or(0);
  c.vertices = f.get_uint("vertices").value_or(0);
  c.meshing_lag_points = f.get_uint("meshing_lag_points").value_or(0);
  c.meshing_lag_s = f.get_number("meshing_lag_s").value_or(0);
  c.journal_bytes = f.get_uint("journal_bytes").value_or(0);
  c.rate_hz = f.get_number("rate_hz").value_or(0);
  c.errors = f.get_uint("errors").value_or(0);
  return s;
}

ScanRecord scan_record_from(const Fields& f) {
  ScanRecord r;
  r.id = f.get_int("id").value_or(0);
  r.name = f.get_string("name").value_or("");
  r.state = f.get_string("state").value_or("");
  r.started_utc = f.get_string("started_utc").value_or("");
  r.stopped_utc = f.get_string("stopped_utc").value_or("");
  r.reason = f.get_string("reason").value_or("");
  r.samples = f.get_uint("samples").value_or(0);
  r.points = f.get_uint("points").value_or(0);
  r.triangles = f.get_uint("triangles").value_or(0);
  r.journal_bytes = f.get_uint("journal_bytes").value_or(0);
  r.journal = f.get_string("journal").value_or("");
  r.parameters = f.get_parameters("parameters").value_or(Parameters{});
  return r;
}

MeshCounts mesh_counts_from(const Fields& f) {
  MeshCounts m;
  m.scan = f.get_int("scan").value_or(0);
  m.vertices = f.get_uint("vertices").value_or(0);
  m.triangles = f.get_uint("triangles").value_or(0);
  m.added = f.get_uint("added").value_or(0);
  m.removed = f.get_uint("removed").value_or(0);
  return m;
}

VersionInfo version_info_from(const Fields& f) {
  VersionInfo v;
  v.daemon = f.get_string("daemon").value_or("");
  v.proto_major = static_cast<int>(f.get_int("proto_major").value_or(0));
  v.proto_minor = static_cast<int>(f.get_int("proto_minor").value_or(0));
  v.backend = f.get_string("backend").value_or("");
  return v;
}

StatusInfo status_info_from(const Fields& f) {
  StatusInfo s;
  s.daemon_state = f.get_string("daemon_state").value_or("");
  s.backend = f.get_string("backend").value_or("");
  s.uptime_s = f.get_number("uptime_s").value_or(0);
  s.clients = f.get_uint("clients").value_or(0);
  s.protocol_errors = f.get_uint("protocol_errors").value_or(0);
  for (const auto& d : f.get_objects("devices")) s.devices.push_back(device_info_from(d));
  if (auto scan = f.get_object("scan")) s.scan = scan_status_from(*scan);
  return s;
}

ExportInfo export_info_from(const Fields& f) {
  ExportInfo e;
  e.scan = f.get_int("scan").value_or(0);
  e.path = f.get_string("path").value_or("");
  e.format = f.get_string("format").value_or("");
  e.vertices = f.get_uint("vertices").value_or(0);
  e.triangles = f.get_uint("triangles").value_or(0);
  e.bytes = f.get_uint("bytes").value_or(0);
  return e;
}

PreviewInfo preview_info_from(const Fields& f) {
  PreviewInfo p;
  p.scan = f.get_int("scan").value_or(0);
  p.path = f.get_string("path").value_or("");
  p.width_px = static_cast<int>(f.get_int("width_px").value_or(0));
  p.height_px = static_cast<int>(f.get_int("height_px").value_or(0));
  p.bytes = f.get_uint("bytes").value_or(0);
  return p;
}

}  // namespace proto
}  // namespace scanmesh::daemon
