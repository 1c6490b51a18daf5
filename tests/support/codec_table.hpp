// Table-driven codec tests (../shared/STYLE.md §8.2): decodes byte strings in any chunking with a
// driver's Decoder and compares the replies, described as text, with the expected ones.
// SPDX-License-Identifier: MIT
#pragma once

#include <catch2/catch.hpp>
#include <cstddef>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::test {

/// What a decoder made of some bytes: each reply as describe(reply), each malformed reason.
struct Decoded {
  std::vector<std::string> replies;
  std::vector<std::string> malformed;
};

/// One row of a codec table.
struct CodecCase {
  const char* legend;
  std::string input;
  std::vector<std::string> replies;  ///< expected, as describe(reply)
  std::size_t malformed;             ///< expected count of malformed reports
};

/// A decoded reading (status + value) as text: "ok:<value>", otherwise the status name.
template <class Reading>
std::string describe_reading(const Reading& r) {
  if (r.status != drivers::SensorStatus::kOk) return std::string(drivers::to_string(r.status));
  std::ostringstream o;
  o << "ok:" << r.value;
  return o.str();
}

/// Feeds the chunks in order to one fresh Decoder.
template <class Decoder, class Describe>
Decoded decode_chunks(const std::vector<std::string>& chunks, Describe describe) {
  Decoder decoder;
  Decoded out;
  for (const auto& c : chunks)
    decoder.feed(
        std::string_view(c), [&](const auto& r) { out.replies.push_back(describe(r)); },
        [&](const char* why) { out.malformed.emplace_back(why); });
  return out;
}

/// Checks every row, decoded as one chunk.
template <class Decoder, class Describe>
void check_codec_table(const std::vector<CodecCase>& cases, Describe describe) {
  for (const auto& c : cases) {
    INFO(c.legend);
    const Decoded d = decode_chunks<Decoder>({c.input}, describe);
    CHECK(d.replies == c.replies);
    CHECK(d.malformed.size() == c.malformed);
  }
}

/// stream holds `replies` well-formed replies: split in two at every byte boundary, and fed
/// byte by byte, it must decode to the same replies with nothing malformed.
template <class Decoder, class Describe>
void check_split_at_every_byte(const std::string& stream, std::size_t replies, Describe describe) {
  const Decoded whole = decode_chunks<Decoder>({stream}, describe);
  REQUIRE(whole.replies.size() == replies);
  REQUIRE(whole.malformed.empty());
  for (std::size_t a = 0; a <= stream.size(); ++a) {
    INFO("split at " << a);
    const Decoded d = decode_chunks<Decoder>({stream.substr(0, a), stream.substr(a)}, describe);
    CHECK(d.replies == whole.replies);
    CHECK(d.malformed.empty());
  }
  std::vector<std::string> bytes;
  for (char c : stream) bytes.emplace_back(1, c);
  CHECK(decode_chunks<Decoder>(bytes, describe).replies == whole.replies);
}

}  // namespace scanmesh::test
