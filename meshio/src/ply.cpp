// PLY reader: ascii, binary_little_endian and binary_big_endian; vertex, face and tristrips
// elements are decoded, every other element and property is skipped.
// SPDX-License-Identifier: MIT
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "detail.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"

namespace scanmesh::meshio {
namespace {

using detail::fail_byte;
using detail::fail_line;

enum class Format { kAscii, kBinaryLittle, kBinaryBig };

enum class Scalar { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

std::optional<Scalar> scalar_from_name(std::string_view s) {
  if (s == "char" || s == "int8") return Scalar::kInt8;
  if (s == "uchar" || s == "uint8") return Scalar::kUint8;
  if (s == "short" || s == "int16") return Scalar::kInt16;
  if (s == "ushort" || s == "uint16") return Scalar::kUint16;
  if (s == "int" || s == "int32") return Scalar::kInt32;
  if (s == "uint" || s == "uint32") return Scalar::kUint32;
  if (s == "float" || s == "float32") return Scalar::kFloat32;
  if (s == "double" || s == "float64") return Scalar::kFloat64;
  return std::nullopt;
}

constexpr std::size_t scalar_size(Scalar t) {
  switch (t) {
    case Scalar::kInt8:
    case Scalar::kUint8:
      return 1;
    case Scalar::kInt16:
    case Scalar::kUint16:
      return 2;
    case Scalar::kInt32:
    case Scalar::kUint32:
    case Scalar::kFloat32:
      return 4;
    case Scalar::kFloat64:
      return 8;
  }
  return 1;
}

constexpr bool is_integer(Scalar t) { return t != Scalar::kFloat32 && t != Scalar::kFloat64; }

struct Property {
  std::string name;
  bool is_list = false;
  Scalar count_type = Scalar::kUint8;  ///< lists only
  Scalar type = Scalar::kFloat32;      ///< the scalar, or the list items
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;
  std::size_t header_line = 0;
  /// Smallest size of one entry: binary bytes (lists counted empty) or ascii tokens.
  [[nodiscard]] std::size_t min_binary_size() const {
    std::size_t n = 0;
    for (const Property& p : properties) n += scalar_size(p.is_list ? p.count_type : p.type);
    return n;
  }
  [[nodiscard]] int find(std::string_view prop) const {
    for (std::size_t i = 0; i < properties.size(); ++i) {
      if (properties[i].name == prop) return static_cast<int>(i);
    }
    return -1;
  }
};

struct Header {
  Format format = Format::kAscii;
  std::vector<Element> elements;
  std::size_t body_offset = 0;  ///< first byte after "end_header\n"
  std::size_t body_line = 0;    ///< line number of the first body line (ascii)
  std::int64_t num_cols = -1;   ///< `obj_info num_cols N` (range scans), -1 when absent
  /// Header lines skipped because their keyword is unknown, each named with its line.
  std::vector<std::string> warnings;
};

/// What the parser does with an element.
enum class Role { kVertex, kFace, kStrips, kRange, kSkip };

/// An empty range_grid entry (no sample at that grid position).
constexpr std::uint32_t kNoRangeVertex = 0xffffffffu;

struct ElementPlan {
  Role role = Role::kSkip;
  int x = -1, y = -1, z = -1;  ///< vertex: property indices
  int indices = -1;            ///< face/tristrips: the index list property
};

Header parse_header(std::string_view bytes, std::string_view name) {
  Header h;
  detail::LineReader lines(bytes);
  std::string_view line;
  if (!lines.next(line) || line != "ply") {
    fail_line(name, 1, "not a PLY file (first line must be 'ply')");
  }
  bool have_format = false;
  for (;;) {
    if (!lines.next(line)) fail_line(name, lines.line_number(), "header has no 'end_header' line");
    const std::size_t ln = lines.line_number();
    detail::Tokenizer tok(line);
    const std::string_view key = tok.next();
    if (key.empty() || key == "comment") continue;
    if (key == "obj_info") {
      std::int64_t cols = 0;
      if (tok.next() == "num_cols" && detail::parse_int_token(tok.next(), cols) && cols > 0)
        h.num_cols = cols;
      continue;
    }
    if (key == "format") {
      const std::string_view f = tok.next();
      if (f == "ascii") {
        h.format = Format::kAscii;
      } else if (f == "binary_little_endian") {
        h.format = Format::kBinaryLittle;
      } else if (f == "binary_big_endian") {
        h.format = Format::kBinaryBig;
      } else {
        fail_line(name, ln, "unknown PLY format " + detail::quote(f));
      }
      if (tok.next() != "1.0") fail_line(name, ln, "unsupported PLY version (expected 1.0)");
      have_format = true;
    } else if (key == "element") {
      Element e;
      e.name = std::string(tok.next());
      const std::string_view count = tok.next();
      std::int64_t n = 0;
      if (e.name.empty() || !detail::parse_int_token(count, n) || n < 0) {
        fail_line(name, ln, "expected 'element NAME COUNT'");
      }
      e.count = static_cast<std::uint64_t>(n);
      e.header_line = ln;
      h.elements.push_back(std::move(e));
    } else if (key == "property") {
      if (h.elements.empty()) fail_line(name, ln, "property before any element");
      Property p;
      std::string_view t = tok.next();
      if (t == "list") {
        p.is_list = true;
        const std::string_view ct = tok.next();
        const auto count_type = scalar_from_name(ct);
        if (!count_type) fail_line(name, ln, "unknown list count type " + detail::quote(ct));
        if (!is_integer(*count_type)) {
          fail_line(name, ln, "list count type must be an integer type, not " + detail::quote(ct));
        }
        p.count_type = *count_type;
        t = tok.next();
      }
      const auto type = scalar_from_name(t);
      if (!type) fail_line(name, ln, "unknown property type " + detail::quote(t));
      p.type = *type;
      p.name = std::string(tok.next());
      if (p.name.empty()) fail_line(name, ln, "property without a name");
      h.elements.back().properties.push_back(std::move(p));
    } else if (key == "end_header") {
      if (!have_format) fail_line(name, ln, "header has no 'format' line");
      h.body_offset = lines.offset();
      h.body_line = ln + 1;
      return h;
    } else {
      // Real raw scans bend the format (some of the Stanford range scans carry a line 'bye'
      // before their elements): a line the reader does not know is skipped, with a warning,
      // as long as the elements and properties it needs are well formed.
      h.warnings.push_back(std::string(name) + ":" + std::to_string(ln) +
                           ": unknown header line " + detail::quote(line) + " skipped");
    }
  }
}

ElementPlan plan_element(const Element& e, std::string_view name, bool have_vertex,
                         bool want_range = false) {
  ElementPlan plan;
  if (want_range && e.name == "range_grid") {
    plan.indices = e.find("vertex_indices");
    if (plan.indices >= 0) {
      const Property& p = e.properties[static_cast<std::size_t>(plan.indices)];
      if (!p.is_list || !is_integer(p.type))
        fail_line(name, e.header_line, "range_grid's vertex_indices must be a list of an integer type");
      plan.role = Role::kRange;
    }
    return plan;
  }
  if (e.name == "vertex" && !have_vertex) {
    plan.role = Role::kVertex;
    plan.x = e.find("x");
    plan.y = e.find("y");
    plan.z = e.find("z");
    for (const int i : {plan.x, plan.y, plan.z}) {
      if (i < 0) fail_line(name, e.header_line, "vertex element has no x, y and z properties");
      if (e.properties[static_cast<std::size_t>(i)].is_list) {
        fail_line(name, e.header_line, "vertex coordinate declared as a list property");
      }
    }
    return plan;
  }
  if (e.name == "face" || e.name == "tristrips") {
    plan.role = e.name == "face" ? Role::kFace : Role::kStrips;
    plan.indices = e.find("vertex_indices");
    if (plan.indices < 0 && plan.role == Role::kFace) plan.indices = e.find("vertex_index");
    if (plan.indices < 0) {
      fail_line(name, e.header_line, "element '" + e.name + "' has no vertex_indices property");
    }
    const Property& p = e.properties[static_cast<std::size_t>(plan.indices)];
    if (!p.is_list || !is_integer(p.type)) {
      fail_line(name, e.header_line, "vertex_indices must be a list of an integer type");
    }
    return plan;
  }
  return plan;
}

/// Turns index lists into triangles; validates every index against the vertex count.
class TriangleSink {
 public:
  TriangleSink(std::vector<recon::Triangle>& out, std::uint64_t vertex_count)
      : out_(out), vertex_count_(vertex_count) {}

  /// Validates an index; returns the reason when it is not a vertex.
  [[nodiscard]] std::optional<std::string> check(std::int64_t i) const {
    if (i < 0 || static_cast<std::uint64_t>(i) >= vertex_count_) {
      return "vertex index " + std::to_string(i) + " out of range (" +
             std::to_string(vertex_count_) + " vertices)";
    }
    return std::nullopt;
  }

  /// A polygon, triangulated as a fan around its first vertex; fewer than 3 indices are ignored.
  void polygon(const std::vector<std::uint32_t>& idx) {
    for (std::size_t i = 1; i + 1 < idx.size(); ++i) out_.push_back({idx[0], idx[i], idx[i + 1]});
  }

  /// A triangle strip with -1 restarts (already validated). Odd triangles swap their first two
  /// vertices so that all triangles keep the strip's orientation; degenerate ones are dropped
  /// (strips use them to turn corners).
  void strip(const std::vector<std::int64_t>& idx) {
    std::size_t run_start = 0;
    for (std::size_t i = 0; i < idx.size(); ++i) {
      if (idx[i] < 0) {
        run_start = i + 1;
        continue;
      }
      if (i < run_start + 2) continue;
      const auto a = static_cast<std::uint32_t>(idx[i - 2]);
      const auto b = static_cast<std::uint32_t>(idx[i - 1]);
      const auto c = static_cast<std::uint32_t>(idx[i]);
      if (a == b || b == c || a == c) continue;
      if ((i - run_start) % 2 == 0) {
        out_.push_back({a, b, c});
      } else {
        out_.push_back({b, a, c});
      }
    }
  }

 private:
  std::vector<recon::Triangle>& out_;
  std::uint64_t vertex_count_;
};

// ---------------------------------------------------------------------------------------------
// Binary body

class BinaryReader {
 public:
  BinaryReader(std::string_view bytes, std::size_t offset, bool big_endian, std::string_view name)
      : data_(reinterpret_cast<const unsigned char*>(bytes.data())),
        size_(bytes.size()),
        pos_(offset),
        swap_(big_endian != (std::endian::native == std::endian::big)),
        name_(name) {}

  [[nodiscard]] std::size_t pos() const { return pos_; }
  [[nodiscard]] std::size_t remaining() const { return size_ - pos_; }

  /// Throws "truncated WHAT" unless `n` more bytes are available.
  void need(std::size_t n, std::string_view what) const {
    if (n > size_ - pos_) fail_byte(name_, pos_, "truncated " + std::string(what));
  }
  void skip(std::size_t n) { pos_ += n; }

  /// Reads one scalar of type t as R (bounds already checked with need()). As an integer R,
  /// t must be an integer type (the header check makes list counts and face indices so): a
  /// float type reads nothing and gives 0.
  template <class R>
  R read_scalar(Scalar t) {
    switch (t) {
      case Scalar::kInt8:
        return static_cast<std::int8_t>(read_raw<std::uint8_t>());
      case Scalar::kUint8:
        return read_raw<std::uint8_t>();
      case Scalar::kInt16:
        return static_cast<std::int16_t>(read_raw<std::uint16_t>());
      case Scalar::kUint16:
        return read_raw<std::uint16_t>();
      case Scalar::kInt32:
        return static_cast<std::int32_t>(read_raw<std::uint32_t>());
      case Scalar::kUint32:
        return read_raw<std::uint32_t>();
      case Scalar::kFloat32:
        if constexpr (std::is_floating_point_v<R>)
          return std::bit_cast<float>(read_raw<std::uint32_t>());
        break;
      case Scalar::kFloat64:
        if constexpr (std::is_floating_point_v<R>)
          return std::bit_cast<double>(read_raw<std::uint64_t>());
        break;
    }
    return 0;
  }
  double read_double(Scalar t) { return read_scalar<double>(t); }
  std::int64_t read_int(Scalar t) { return read_scalar<std::int64_t>(t); }

  /// Reads a list length and checks that its items fit in the rest of the data.
  std::size_t read_list_count(const Property& p, std::string_view what) {
    need(scalar_size(p.count_type), what);
    const std::size_t at = pos_;
    const std::int64_t n = read_int(p.count_type);
    if (n < 0) fail_byte(name_, at, "negative list length in " + std::string(what));
    const auto un = static_cast<std::uint64_t>(n);
    if (un > remaining() / scalar_size(p.type)) {
      fail_byte(name_, at,
                "truncated " + std::string(what) + " (list of " + std::to_string(un) +
                    " items runs past the end of the file)");
    }
    return static_cast<std::size_t>(un);
  }

  /// Skips one property value (scalar or list).
  void skip_property(const Property& p, std::string_view what) {
    if (p.is_list) {
      const std::size_t n = read_list_count(p, what);
      skip(n * scalar_size(p.type));
    } else {
      need(scalar_size(p.type), what);
      skip(scalar_size(p.type));
    }
  }

 private:
  template <typename U>
  U read_raw() {
    U v;
    std::memcpy(&v, data_ + pos_, sizeof(U));
    pos_ += sizeof(U);
    if (swap_) v = byteswap(v);
    return v;
  }
  template <typename U>
  static U byteswap(U v) {
    if constexpr (sizeof(U) == 1) {
      return v;
    } else if constexpr (sizeof(U) == 2) {
      return static_cast<U>(__builtin_bswap16(v));
    } else if constexpr (sizeof(U) == 4) {
      return static_cast<U>(__builtin_bswap32(v));
    } else {
      return static_cast<U>(__builtin_bswap64(v));
    }
  }

  const unsigned char* data_;
  std::size_t size_;
  std::size_t pos_;
  bool swap_;
  std::string_view name_;
};

void read_binary_body(std::string_view bytes, std::string_view name, const Header& h,
                      std::vector<std::uint32_t>* range,
                      bool vertices_only, recon::Mesh& mesh) {
  BinaryReader in(bytes, h.body_offset, h.format == Format::kBinaryBig, name);
  const Element* vertex_element = nullptr;
  for (const Element& e : h.elements) {
    if (e.name == "vertex") {
      vertex_element = &e;
      break;
    }
  }
  const std::uint64_t vertex_count = vertex_element != nullptr ? vertex_element->count : 0;
  TriangleSink sink(mesh.triangles, vertex_count);
  std::vector<std::uint32_t> poly;
  std::vector<std::int64_t> strip;
  bool have_vertex = false;

  for (const Element& e : h.elements) {
    const ElementPlan plan = plan_element(e, name, have_vertex, range != nullptr);
    const std::size_t min_size = e.min_binary_size();
    if (min_size == 0 || e.count == 0) continue;  // an element without properties has no bytes
    if (e.count > in.remaining() / min_size) {
      fail_byte(name, in.pos(),
                "truncated " + e.name + " data (" + std::to_string(e.count) +
                    " entries need at least " + std::to_string(min_size) + " bytes each, " +
                    std::to_string(in.remaining()) + " bytes left)");
    }
    const std::string what = e.name + " data";
    const auto count = static_cast<std::size_t>(e.count);

    if (plan.role == Role::kVertex) {
      have_vertex = true;
      mesh.vertices.reserve(count);
      for (std::size_t k = 0; k < count; ++k) {
        const std::size_t entry_at = in.pos();
        double xyz[3] = {0, 0, 0};
        for (std::size_t pi = 0; pi < e.properties.size(); ++pi) {
          const Property& p = e.properties[pi];
          const int ip = static_cast<int>(pi);
          const int axis = ip == plan.x ? 0 : ip == plan.y ? 1 : ip == plan.z ? 2 : -1;
          if (axis >= 0) {
            in.need(scalar_size(p.type), what);
            xyz[axis] = in.read_double(p.type);
          } else {
            in.skip_property(p, what);
          }
        }
        if (!std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) || !std::isfinite(xyz[2])) {
          fail_byte(name, entry_at, "vertex " + std::to_string(k) + " has a non-finite coordinate");
        }
        mesh.vertices.emplace_back(xyz[0], xyz[1], xyz[2]);
      }
      if (vertices_only) return;
      continue;
    }

    if (plan.role == Role::kRange) {
      range->reserve(count);
      for (std::size_t k = 0; k < count; ++k) {
        std::uint32_t entry = kNoRangeVertex;
        for (std::size_t pi = 0; pi < e.properties.size(); ++pi) {
          const Property& p = e.properties[pi];
          if (static_cast<int>(pi) != plan.indices) {
            in.skip_property(p, what);
            continue;
          }
          const std::size_t n = in.read_list_count(p, what);
          for (std::size_t j = 0; j < n; ++j) {
            const std::size_t at = in.pos();
            const std::int64_t v = in.read_int(p.type);
            if (auto bad = sink.check(v)) fail_byte(name, at, "range_grid " + std::to_string(k) + ": " + *bad);
            if (j == 0) entry = static_cast<std::uint32_t>(v);
          }
        }
        range->push_back(entry);
      }
      continue;
    }

    if (plan.role == Role::kFace || plan.role == Role::kStrips) {
      if (plan.role == Role::kFace) mesh.triangles.reserve(mesh.triangles.size() + count);
      for (std::size_t k = 0; k < count; ++k) {
        for (std::size_t pi = 0; pi < e.properties.size(); ++pi) {
          const Property& p = e.properties[pi];
          if (static_cast<int>(pi) != plan.indices) {
            in.skip_property(p, what);
            continue;
          }
          const std::size_t n = in.read_list_count(p, what);
          if (plan.role == Role::kFace) {
            poly.clear();
            for (std::size_t j = 0; j < n; ++j) {
              const std::size_t at = in.pos();
              const std::int64_t v = in.read_int(p.type);
              if (auto bad = sink.check(v))
                fail_byte(name, at, "face " + std::to_string(k) + ": " + *bad);
              poly.push_back(static_cast<std::uint32_t>(v));
            }
            sink.polygon(poly);
          } else {
            strip.clear();
            strip.reserve(n);
            for (std::size_t j = 0; j < n; ++j) {
              const std::size_t at = in.pos();
              const std::int64_t v = in.read_int(p.type);
              if (v != -1) {
                if (auto bad = sink.check(v)) {
                  fail_byte(name, at, "tristrip " + std::to_string(k) + ": " + *bad);
                }
              }
              strip.push_back(v);
            }
            sink.strip(strip);
          }
        }
      }
      continue;
    }

    // Skipped element: fixed-size entries are skipped at once, others entry by entry.
    bool fixed = true;
    for (const Property& p : e.properties) fixed = fixed && !p.is_list;
    if (fixed) {
      in.skip(count * min_size);  // fits: checked against remaining() above
    } else {
      for (std::size_t k = 0; k < count; ++k) {
        for (const Property& p : e.properties) in.skip_property(p, what);
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// ASCII body: one element entry per line, whitespace-separated values.

class AsciiReader {
 public:
  AsciiReader(std::string_view bytes, std::size_t offset, std::size_t first_line,
              std::string_view name)
      : p_(bytes.data() + offset),
        end_(bytes.data() + bytes.size()),
        line_(first_line),
        name_(name) {}

  /// Moves to the start of the next non-blank line; false at end of file.
  bool begin_entry() {
    for (;;) {
      while (p_ < end_ && detail::is_blank(*p_)) ++p_;
      if (p_ == end_) return false;
      if (*p_ != '\n') return true;
      ++p_;
      ++line_;
    }
  }

  /// The next value of the current line; throws when the line has ended.
  std::string_view token(std::string_view what) {
    while (p_ < end_ && detail::is_blank(*p_)) ++p_;
    if (p_ == end_ || *p_ == '\n')
      fail_line(name_, line_, "too few values in " + std::string(what));
    const char* s = p_;
    while (p_ < end_ && *p_ != '\n' && !detail::is_blank(*p_)) ++p_;
    return {s, static_cast<std::size_t>(p_ - s)};
  }

  double number(std::string_view what) {
    const std::string_view t = token(what);
    double v = 0;
    const detail::NumberStatus s = detail::parse_double_token(t, v);
    if (s != detail::NumberStatus::kOk) {
      fail_line(name_, line_, std::string(what) + ": " + detail::describe(s, t));
    }
    return v;
  }

  std::int64_t integer(std::string_view what) {
    const std::string_view t = token(what);
    std::int64_t v = 0;
    if (!detail::parse_int_token(t, v)) {
      fail_line(name_, line_, std::string(what) + ": " + detail::quote(t) + " is not an integer");
    }
    return v;
  }

  /// A list length; it cannot exceed the bytes left (each value takes at least one byte).
  std::size_t list_count(std::string_view what) {
    const std::int64_t n = integer(what);
    if (n < 0) fail_line(name_, line_, "negative list length in " + std::string(what));
    if (static_cast<std::uint64_t>(n) > static_cast<std::uint64_t>(end_ - p_)) {
      fail_line(name_, line_,
                "list length " + std::to_string(n) + " in " + std::string(what) +
                    " is larger than the rest of the file");
    }
    return static_cast<std::size_t>(n);
  }

  void skip_property(const Property& p, std::string_view what) {
    if (p.is_list) {
      const std::size_t n = list_count(what);
      for (std::size_t i = 0; i < n; ++i) token(what);
    } else {
      token(what);
    }
  }

  /// The line must end after the entry's values.
  void end_entry(std::string_view what) {
    while (p_ < end_ && detail::is_blank(*p_)) ++p_;
    if (p_ < end_ && *p_ != '\n') {
      fail_line(name_, line_, "more values than declared in " + std::string(what));
    }
  }

  [[nodiscard]] std::size_t line() const { return line_; }
  [[nodiscard]] std::size_t remaining() const { return static_cast<std::size_t>(end_ - p_); }

 private:
  const char* p_;
  const char* end_;
  std::size_t line_;
  std::string_view name_;
};

void read_ascii_body(std::string_view bytes, std::string_view name, const Header& h,
                     std::vector<std::uint32_t>* range,
                     bool vertices_only, recon::Mesh& mesh) {
  AsciiReader in(bytes, h.body_offset, h.body_line, name);
  const Element* vertex_element = nullptr;
  for (const Element& e : h.elements) {
    if (e.name == "vertex") {
      vertex_element = &e;
      break;
    }
  }
  TriangleSink sink(mesh.triangles, vertex_element != nullptr ? vertex_element->count : 0);
  std::vector<std::uint32_t> poly;
  std::vector<std::int64_t> strip;
  bool have_vertex = false;

  for (const Element& e : h.elements) {
    const ElementPlan plan = plan_element(e, name, have_vertex, range != nullptr);
    if (e.properties.empty() || e.count == 0) continue;
    // Every entry is at least one value and a line break: two bytes.
    if (e.count > in.remaining() / 2 + 1) {
      fail_line(name, in.line(),
                "element '" + e.name + "' declares " + std::to_string(e.count) +
                    " entries, more than the rest of the file can hold");
    }
    const auto count = static_cast<std::size_t>(e.count);
    const std::string what = e.name;
    if (plan.role == Role::kVertex) {
      have_vertex = true;
      mesh.vertices.reserve(count);
    } else if (plan.role == Role::kFace) {
      mesh.triangles.reserve(mesh.triangles.size() + count);
    } else if (plan.role == Role::kRange) {
      range->reserve(count);
    }
    for (std::size_t k = 0; k < count; ++k) {
      if (!in.begin_entry()) {
        fail_line(name, in.line(),
                  "unexpected end of file: element '" + e.name + "' declares " +
                      std::to_string(e.count) + " entries, found " + std::to_string(k));
      }
      if (plan.role == Role::kVertex) {
        double xyz[3] = {0, 0, 0};
        for (std::size_t pi = 0; pi < e.properties.size(); ++pi) {
          const int ip = static_cast<int>(pi);
          const int axis = ip == plan.x ? 0 : ip == plan.y ? 1 : ip == plan.z ? 2 : -1;
          if (axis >= 0) {
            xyz[axis] = in.number(what);
          } else {
            in.skip_property(e.properties[pi], what);
          }
        }
        mesh.vertices.emplace_back(xyz[0], xyz[1], xyz[2]);
      } else if (plan.role == Role::kRange) {
        std::uint32_t entry = kNoRangeVertex;
        for (std::size_t pi = 0; pi < e.properties.size(); ++pi) {
          if (static_cast<int>(pi) != plan.indices) {
            in.skip_property(e.properties[pi], what);
            continue;
          }
          const std::size_t n = in.list_count(what);
          for (std::size_t j = 0; j < n; ++j) {
            const std::int64_t v = in.integer(what);
            if (auto bad = sink.check(v)) fail_line(name, in.line(), *bad);
            if (j == 0) entry = static_cast<std::uint32_t>(v);
          }
        }
        range->push_back(entry);
      } else if (plan.role == Role::kFace || plan.role == Role::kStrips) {
        for (std::size_t pi = 0; pi < e.properties.size(); ++pi) {
          if (static_cast<int>(pi) != plan.indices) {
            in.skip_property(e.properties[pi], what);
            continue;
          }
          const std::size_t n = in.list_count(what);
          if (plan.role == Role::kFace) {
            poly.clear();
            for (std::size_t j = 0; j < n; ++j) {
              const std::int64_t v = in.integer(what);
              if (auto bad = sink.check(v)) fail_line(name, in.line(), *bad);
              poly.push_back(static_cast<std::uint32_t>(v));
            }
            sink.polygon(poly);
          } else {
            strip.clear();
            for (std::size_t j = 0; j < n; ++j) {
              const std::int64_t v = in.integer(what);
              if (v != -1) {
                if (auto bad = sink.check(v)) fail_line(name, in.line(), *bad);
              }
              strip.push_back(v);
            }
            sink.strip(strip);
          }
        }
      } else {
        for (const Property& p : e.properties) in.skip_property(p, what);
      }
      in.end_entry(what);
    }
    if (plan.role == Role::kVertex && vertices_only) return;
  }
  if (in.begin_entry()) {
    fail_line(name, in.line(), "data after the last element (declared counts too small?)");
  }
}

}  // namespace

namespace detail {

recon::Mesh parse_ply(std::string_view bytes, std::string_view name, bool vertices_only,
                      PlyExtras* extras) {
  const Header h = parse_header(bytes, name);
  std::vector<std::uint32_t> range;
  std::vector<std::uint32_t>* range_sink = extras != nullptr ? &range : nullptr;
  recon::Mesh mesh;
  for (const Element& e : h.elements) {
    if (e.name == "vertex" && e.count > std::numeric_limits<std::uint32_t>::max()) {
      fail_line(name, e.header_line, "more than 2^32-1 vertices are not supported");
    }
  }
  if (h.format == Format::kAscii) {
    read_ascii_body(bytes, name, h, range_sink, vertices_only, mesh);
  } else {
    read_binary_body(bytes, name, h, range_sink, vertices_only, mesh);
  }
  if (extras != nullptr) {
    extras->warnings = h.warnings;
    extras->range_rows.clear();
    if (!range.empty()) {
      if (h.num_cols <= 0)
        fail_line(name, 1, "range_grid without 'obj_info num_cols N': its rows are unknown");
      const auto cols = static_cast<std::size_t>(h.num_cols);
      if (range.size() % cols != 0)
        fail_line(name, 1, "range_grid has " + std::to_string(range.size()) +
                               " entries, not a whole number of rows of num_cols " +
                               std::to_string(cols));
      for (std::size_t r = 0; r < range.size(); r += cols) {
        std::vector<std::uint32_t> row;
        for (std::size_t c = r; c < r + cols; ++c)
          if (range[c] != kNoRangeVertex) row.push_back(range[c]);
        extras->range_rows.push_back(std::move(row));
      }
    }
  }
  return mesh;
}

}  // namespace detail

recon::Mesh parse_ply(std::string_view bytes, std::string_view name) {
  return detail::parse_ply(bytes, name, false);
}

recon::Mesh parse_ply(std::string_view bytes, std::string_view name, PlyExtras& extras) {
  return detail::parse_ply(bytes, name, false, &extras);
}

recon::Mesh read_ply(const std::filesystem::path& file, PlyExtras& extras) {
  detail::require_readable(file);
  return parse_ply(detail::load_file(file), file.string(), extras);
}

}  // namespace scanmesh::meshio
