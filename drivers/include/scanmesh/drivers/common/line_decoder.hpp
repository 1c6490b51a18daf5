// LineDecoder: the stream decoder of the line-based ASCII sensor codecs (KEYENCE LK-G / IL,
// Panasonic HL-G1): bytes -> LineFramer lines -> the codec's reply parser -> callbacks, with the
// malformed count and a resynchronisation inside a line. Pure and allocation-free per reply.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <type_traits>
#include <utility>

#include "scanmesh/drivers/common/line_framer.hpp"

namespace scanmesh::drivers {

/// Syntax: what one codec contributes, as static members:
///   using Reply = ...;                       the parsed reply (trivially reusable)
///   static constexpr std::size_t kMaxLine;   longest line accepted (LineFramer)
///   static constexpr bool kReuseReply;       parse every line into one member Reply (large
///                                            replies) instead of a fresh one per line
///   static const char* parse(std::string_view line, Reply&);   nullptr or the reason
///   static std::size_t resync(std::string_view line, std::size_t from);
///       first index >= from where a reply may start again after garbage glued to the front
///       of the line, or std::string_view::npos
template <class Syntax>
class LineDecoder {
 public:
  using Reply = typename Syntax::Reply;

  LineDecoder() : framer_(Syntax::kMaxLine) {}

  /// on_reply(const Reply&) for every reply; on_malformed(const char* reason) for every
  /// rejected line (garbage, over-long, wrong layout ...). For a reply found behind garbage in
  /// the same line, on_reply comes first, then on_malformed. Never throws on device input.
  template <class OnReply, class OnMalformed>
  void feed(std::string_view bytes, OnReply&& on_reply, OnMalformed&& on_malformed) {
    const std::uint64_t overlong = framer_.overlong_lines();
    framer_.feed(bytes, [&](std::string_view line) {
      if constexpr (Syntax::kReuseReply) {
        decode_line(line, reply_, on_reply, on_malformed);
      } else {
        Reply reply;
        decode_line(line, reply, on_reply, on_malformed);
      }
    });
    for (std::uint64_t k = overlong; k < framer_.overlong_lines(); ++k) {
      ++malformed_;
      on_malformed("line too long");
    }
  }
  template <class OnReply, class OnMalformed>
  void feed(std::span<const std::uint8_t> bytes, OnReply&& on_reply, OnMalformed&& on_malformed) {
    feed(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()),
         std::forward<OnReply>(on_reply), std::forward<OnMalformed>(on_malformed));
  }

  /// Drops a partial line (after a timeout, so a stale half reply cannot glue to the next).
  void reset() { framer_.clear(); }
  std::uint64_t malformed() const { return malformed_; }
  /// Non-printable bytes dropped by the framer (line noise).
  std::uint64_t noise_bytes() const { return framer_.noise_bytes(); }

 private:
  struct NoReply {};

  template <class OnReply, class OnMalformed>
  void decode_line(std::string_view line, Reply& reply, OnReply& on_reply,
                   OnMalformed& on_malformed) {
    const char* why = Syntax::parse(line, reply);
    if (why == nullptr) {
      on_reply(reply);
      return;
    }
    // Resynchronise inside the line: line noise that arrived just before a reply is glued to
    // its front (no terminator in between). A reply further on is still usable; the garbage
    // in front of it is reported as malformed.
    for (std::size_t i = Syntax::resync(line, 1); i != std::string_view::npos;
         i = Syntax::resync(line, i + 1)) {
      if (Syntax::parse(line.substr(i), reply) == nullptr) {
        on_reply(reply);
        ++malformed_;
        on_malformed("garbage before reply");
        return;
      }
    }
    ++malformed_;
    on_malformed(why);
  }

  LineFramer framer_;
  [[no_unique_address]] std::conditional_t<Syntax::kReuseReply, Reply, NoReply> reply_;
  std::uint64_t malformed_ = 0;
};

/// LineDecoder resync for codecs whose replies may start at any character (a 2-character header
/// at least).
inline std::size_t resync_any_header(std::string_view line, std::size_t from) {
  return from + 2 <= line.size() ? from : std::string_view::npos;
}

}  // namespace scanmesh::drivers
