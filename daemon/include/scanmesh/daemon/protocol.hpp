// The control protocol's one codec (daemon/PROTOCOL.md): JSON lines in, JSON lines out, used by
// scanmeshd, scanctl and the tests. The JSON library stays inside this module: callers build
// objects with Object and read them through Fields.
// SPDX-License-Identifier: MIT
#pragma once

#include <concepts>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/daemon/messages.hpp"

namespace scanmesh::daemon::proto {

inline constexpr int kMajor = 1;
inline constexpr int kMinor = 0;
/// Longest request line the server reads, the '\n' not counted.
inline constexpr std::size_t kMaxLineBytes = 64 * 1024;

/// ERROR codes (PROTOCOL.md lists when each is sent).
namespace errc {
inline constexpr std::string_view kInvalidJson = "invalid_json";
inline constexpr std::string_view kBadRequest = "bad_request";
inline constexpr std::string_view kUnknownCommand = "unknown_command";
inline constexpr std::string_view kBadArgument = "bad_argument";
inline constexpr std::string_view kLineTooLong = "line_too_long";
inline constexpr std::string_view kPermissionDenied = "permission_denied";
inline constexpr std::string_view kPathRefused = "path_refused";
inline constexpr std::string_view kBusy = "busy";
inline constexpr std::string_view kBadState = "bad_state";
inline constexpr std::string_view kNotFound = "not_found";
inline constexpr std::string_view kNoMesh = "no_mesh";
inline constexpr std::string_view kIoError = "io_error";
inline constexpr std::string_view kTooManyClients = "too_many_clients";
inline constexpr std::string_view kShuttingDown = "shutting_down";
inline constexpr std::string_view kInternal = "internal";
}  // namespace errc

/// A request the server answers with an ERROR object: a snake_case code and a message.
class ProtocolError : public Error {
 public:
  ProtocolError(std::string_view code, const std::string& message,
                std::optional<std::int64_t> id = std::nullopt)
      : Error(message), code_(code), id_(id) {}
  const std::string& code() const { return code_; }
  /// The request id, when the request got as far as having a readable one.
  std::optional<std::int64_t> id() const { return id_; }

 private:
  std::string code_;
  std::optional<std::int64_t> id_;
};

/// A JSON object under construction; keys keep their insertion order on the wire.
class Object {
 public:
  Object();
  ~Object();
  Object(const Object& other);
  Object(Object&& other) noexcept;
  Object& operator=(const Object& other);
  Object& operator=(Object&& other) noexcept;

  Object& set(std::string_view key, std::string_view value);
  Object& set(std::string_view key, const char* value) { return set(key, std::string_view(value)); }
  Object& set(std::string_view key, const std::string& value) {
    return set(key, std::string_view(value));
  }
  Object& set(std::string_view key, bool value);
  Object& set(std::string_view key, double value);
  template <std::integral T>
  requires(!std::same_as<T, bool>) Object& set(std::string_view key, T value) {
    if constexpr (std::is_signed_v<T>)
      return set_int(key, static_cast<std::int64_t>(value));
    else
      return set_uint(key, static_cast<std::uint64_t>(value));
  }
  Object& set(std::string_view key, const Object& value);
  Object& set(std::string_view key, const std::vector<Object>& values);
  Object& set(std::string_view key, const std::vector<std::string>& values);
  Object& set(std::string_view key, const Parameters& values);
  Object& set_null(std::string_view key);

  /// Compact JSON text, no newline.
  std::string dump() const;

  struct Impl;

 private:
  Object& set_int(std::string_view key, std::int64_t value);
  Object& set_uint(std::string_view key, std::uint64_t value);
  std::unique_ptr<Impl> impl_;
  friend struct Codec;
};

/// A received JSON object, read with type checks: every getter returns nullopt for an absent key
/// (or null) and throws ProtocolError(bad_argument) naming the key and the expected type when the
/// value has another type. Cheap to copy (shared, immutable).
class Fields {
 public:
  Fields();  ///< the empty object
  explicit Fields(const Object& object);

  bool has(std::string_view key) const;
  std::vector<std::string> keys() const;
  std::optional<std::string> get_string(std::string_view key) const;
  std::optional<std::int64_t> get_int(std::string_view key) const;    ///< integers only
  std::optional<std::uint64_t> get_uint(std::string_view key) const;  ///< integers >= 0
  std::optional<double> get_number(std::string_view key) const;       ///< any finite number
  std::optional<bool> get_bool(std::string_view key) const;
  std::optional<Fields> get_object(std::string_view key) const;
  std::vector<Fields> get_objects(std::string_view key) const;  ///< array of objects; absent: {}
  std::vector<std::string> get_strings(std::string_view key) const;  ///< array of strings
  /// An object whose values are scalars (bool, integer, number, string).
  std::optional<Parameters> get_parameters(std::string_view key) const;
  std::string dump() const;

  struct Impl;

 private:
  explicit Fields(std::shared_ptr<const Impl> impl) : impl_(std::move(impl)) {}
  std::shared_ptr<const Impl> impl_;
  friend struct Codec;
};

/// One request: `{"cmd":NAME,"id":N,...}`; args holds every field (cmd and id included).
struct Request {
  std::string cmd;
  std::optional<std::int64_t> id;
  Fields args;
};

/// Decodes one request line (without its '\n'). Throws ProtocolError: invalid_json (not JSON,
/// or not UTF-8), bad_request (not an object, no string "cmd", an "id" that is not an integer).
/// The error carries the id whenever the line had a readable one.
Request decode_request(std::string_view line);

enum class MessageClass : std::uint8_t { kHello, kReply, kError, kEvent, kOther };

/// One line a client receives.
struct Message {
  MessageClass cls = MessageClass::kOther;
  std::string class_name;
  std::optional<std::int64_t> id;         ///< REPLY and ERROR
  std::string cmd;                        ///< REPLY: the command answered
  std::string event;                      ///< EVENT: its name
  std::string error_code, error_message;  ///< ERROR
  Fields body;                            ///< the whole object
};

/// Decodes a server line (client side). Throws ProtocolError(invalid_json) when it is not a JSON
/// object with a string "class".
Message decode_message(std::string_view line);

// Encoders: each returns one complete line, '\n' included.
std::string hello_line(std::string_view daemon_version);
std::string reply_line(std::optional<std::int64_t> id, std::string_view cmd, const Object& body);
std::string error_line(std::optional<std::int64_t> id, std::string_view code,
                       std::string_view message);
std::string event_line(std::string_view event, const Object& body);
std::string request_line(std::string_view cmd, std::int64_t id, const Object& args = {});

// The one JSON form of each message value, and its inverse (unknown fields ignored, absent
// fields left at their defaults; a field of the wrong type throws ProtocolError).
Object to_object(const DeviceInfo& v);
Object to_object(const ScanCounters& v);
Object to_object(const ScanStatus& v);  ///< the counters flattened into the same object
Object to_object(const ScanRecord& v);
Object to_object(const MeshCounts& v);
Object to_object(const VersionInfo& v);
Object to_object(const StatusInfo& v);
Object to_object(const ExportInfo& v);
Object to_object(const PreviewInfo& v);

DeviceInfo device_info_from(const Fields& f);
ScanStatus scan_status_from(const Fields& f);
ScanRecord scan_record_from(const Fields& f);
MeshCounts mesh_counts_from(const Fields& f);
VersionInfo version_info_from(const Fields& f);
StatusInfo status_info_from(const Fields& f);
ExportInfo export_info_from(const Fields& f);
PreviewInfo preview_info_from(const Fields& f);

}  // namespace scanmesh::daemon::proto
