// Internal helpers shared by the meshio readers and writers: file loading, number parsing,
// error messages with file:line or file: byte N locations.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::meshio::detail {

/// The whole file in memory (one read, no per-line I/O). Throws InputError "cannot read FILE: ...".
std::string load_file(const std::filesystem::path& file);

/// Throws the InputError load_file would when `file` does not exist or is a directory: the
/// readers check it before naming an unknown extension, so a missing file or a folder is
/// reported as such.
void require_readable(const std::filesystem::path& file);

/// The extension in lower case with its dot (".ply"), or "" when there is none.
std::string lower_extension(const std::filesystem::path& file);

/// Throws InputError "NAME:LINE: WHAT" (text formats; LINE is 1-based).
[[noreturn]] void fail_line(std::string_view name, std::size_t line, std::string_view what);
/// Throws InputError "NAME: byte OFFSET: WHAT" (binary formats).
[[noreturn]] void fail_byte(std::string_view name, std::size_t offset, std::string_view what);
/// Throws InputError "NAME: WHAT".
[[noreturn]] void fail(std::string_view name, std::string_view what);

/// A token quoted for an error message: at most 32 characters, non-printable bytes as \xNN.
std::string quote(std::string_view token);

enum class NumberStatus { kOk, kNotANumber, kOutOfRange, kNotFinite };

/// Parses a number that starts at `first` (an optional '+' is accepted, std::from_chars is not
/// locale dependent). On success `*stop` points after the number; the caller checks that the
/// token really ends there. NaN and infinities are reported as kNotFinite.
NumberStatus parse_double(const char* first, const char* last, double& out, const char** stop);

/// Parses a whole token as a finite double.
NumberStatus parse_double_token(std::string_view token, double& out);

/// Parses a whole token as a signed 64-bit integer (optional '+').
bool parse_int_token(std::string_view token, std::int64_t& out);

/// Human-readable description of a NumberStatus for token `token`.
std::string describe(NumberStatus status, std::string_view token);

/// Byte-level whitespace test for text formats (space, \t, \r, \v, \f; not \n).
constexpr bool is_blank(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

/// Splits `text` into lines (without '\n' and a trailing '\r'), counting them from 1.
class LineReader {
 public:
  explicit LineReader(std::string_view text) : text_(text) {}
  /// Next line into `line`; false at the end of the text.
  bool next(std::string_view& line);
  [[nodiscard]] std::size_t line_number() const { return line_number_; }
  /// Byte offset of the first byte after the last line returned.
  [[nodiscard]] std::size_t offset() const { return pos_; }

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
  std::size_t line_number_ = 0;
};

/// Splits a line into whitespace-separated tokens.
class Tokenizer {
 public:
  explicit Tokenizer(std::string_view line) : line_(line) {}
  /// Next token, or an empty view at the end of the line.
  std::string_view next();
  /// The rest of the line after the current position, leading blanks removed.
  std::string_view rest();

 private:
  std::string_view line_;
  std::size_t pos_ = 0;
};

/// Case-insensitive ASCII comparison.
bool iequals(std::string_view a, std::string_view b);

/// Full PLY parser; with `vertices_only` it stops after the vertex element.
recon::Mesh parse_ply(std::string_view bytes, std::string_view name, bool vertices_only,
                      PlyExtras* extras = nullptr);

/// Full OBJ parser; with `vertices_only` 'f' statements are not parsed.
recon::Mesh parse_obj(std::string_view text, std::string_view name, bool vertices_only);

}  // namespace scanmesh::meshio::detail
