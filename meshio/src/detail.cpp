// Internal helpers of the meshio readers: whole-file loading, locale-free number parsing and
// uniformly formatted InputError messages.
// SPDX-License-Identifier: MIT
#include "detail.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <system_error>

#include "scanmesh/common/error.hpp"

namespace scanmesh::meshio::detail {
namespace {

/// Closes a POSIX file descriptor on scope exit.
class FdGuard {
 public:
  explicit FdGuard(int fd) : fd_(fd) {}
  FdGuard(const FdGuard&) = delete;
  FdGuard& operator=(const FdGuard&) = delete;
  ~FdGuard() {
    if (fd_ >= 0) ::close(fd_);
  }

 private:
  int fd_;
};

[[noreturn]] void fail_read(const std::filesystem::path& file, int err) {
  throw InputError("cannot read " + file.string() + ": " + std::strerror(err));
}

}  // namespace

void require_readable(const std::filesystem::path& file) {
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0) fail_read(file, errno);  // no open: a FIFO would block
  if (S_ISDIR(st.st_mode)) fail_read(file, EISDIR);
}

std::string load_file(const std::filesystem::path& file) {
  const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) fail_read(file, errno);
  FdGuard guard(fd);
  struct stat st {};
  if (::fstat(fd, &st) != 0) fail_read(file, errno);
  if (S_ISDIR(st.st_mode)) fail_read(file, EISDIR);

  std::string data;
  // Regular files are read in one go into a buffer of their size; anything else (pipes, /proc)
  // grows the buffer until end of file.
  std::size_t capacity = st.st_size > 0 ? static_cast<std::size_t>(st.st_size) + 1 : 65536;
  data.resize(capacity);
  std::size_t used = 0;
  for (;;) {
    if (used == data.size()) data.resize(data.size() * 2);
    const ssize_t n = ::read(fd, data.data() + used, data.size() - used);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail_read(file, errno);
    }
    if (n == 0) break;
    used += static_cast<std::size_t>(n);
  }
  data.resize(used);
  return data;
}

std::string lower_extension(const std::filesystem::path& file) {
  std::string ext = file.extension().string();
  for (char& c : ext) {
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  }
  return ext;
}

void fail_line(std::string_view name, std::size_t line, std::string_view what) {
  std::string msg;
  msg.reserve(name.size() + what.size() + 24);
  msg.append(name).append(":").append(std::to_string(line)).append(": ").append(what);
  throw InputError(msg);
}

void fail_byte(std::string_view name, std::size_t offset, std::string_view what) {
  std::string msg;
  msg.reserve(name.size() + what.size() + 32);
  msg.append(name).append(": byte ").append(std::to_string(offset)).append(": ").append(what);
  throw InputError(msg);
}

void fail(std::string_view name, std::string_view what) {
  std::string msg;
  msg.append(name).append(": ").append(what);
  throw InputError(msg);
}

std::string quote(std::string_view token) {
  constexpr std::size_t kMax = 32;
  std::string out = "'";
  const std::size_t n = token.size() < kMax ? token.size() : kMax;
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(token[i]);
    if (c >= 0x20 && c < 0x7f) {
      out.push_back(static_cast<char>(c));
    } else {
      static constexpr char kHex[] = "0123456789abcdef";
      out.append("\\x");
      out.push_back(kHex[c >> 4]);
      out.push_back(kHex[c & 0xf]);
    }
  }
  if (token.size() > kMax) out.append("...");
  out.push_back('\'');
  return out;
}

NumberStatus parse_double(const char* first, const char* last, double& out, const char** stop) {
  const char* p = first;
  // std::from_chars rejects a leading '+', which C's strtod and many writers accept.
  if (p != last && *p == '+') {
    ++p;
    if (p != last && (*p == '+' || *p == '-')) return NumberStatus::kNotANumber;
  }
  const auto [ptr, ec] = std::from_chars(p, last, out, std::chars_format::general);
  if (ec == std::errc::result_out_of_range) {
    *stop = ptr;
    return NumberStatus::kOutOfRange;
  }
  if (ec != std::errc{}) return NumberStatus::kNotANumber;
  *stop = ptr;
  if (!std::isfinite(out)) return NumberStatus::kNotFinite;
  return NumberStatus::kOk;
}

NumberStatus parse_double_token(std::string_view token, double& out) {
  const char* stop = nullptr;
  const NumberStatus s = parse_double(token.data(), token.data() + token.size(), out, &stop);
  if (s == NumberStatus::kNotANumber) return s;
  if (stop != token.data() + token.size()) return NumberStatus::kNotANumber;
  return s;
}

bool parse_int_token(std::string_view token, std::int64_t& out) {
  const char* p = token.data();
  const char* last = p + token.size();
  if (p != last && *p == '+') {
    ++p;
    if (p != last && *p == '-') return false;
  }
  if (p == last) return false;
  const auto [ptr, ec] = std::from_chars(p, last, out);
  return ec == std::errc{} && ptr == last;
}

std::string describe(NumberStatus status, std::string_view token) {
  switch (status) {
    case NumberStatus::kOk:
      return "ok";
    case NumberStatus::kNotANumber:
      return quote(token) + " is not a number";
    case NumberStatus::kOutOfRange:
      return quote(token) + " is out of range";
    case NumberStatus::kNotFinite:
      return "non-finite value " + quote(token) + " (NaN and infinity are not valid coordinates)";
  }
  return "bad number";
}

bool LineReader::next(std::string_view& line) {
  if (pos_ >= text_.size()) return false;
  const char* begin = text_.data() + pos_;
  const std::size_t left = text_.size() - pos_;
  const void* nl = std::memchr(begin, '\n', left);
  std::size_t len =
      nl != nullptr ? static_cast<std::size_t>(static_cast<const char*>(nl) - begin) : left;
  pos_ += nl != nullptr ? len + 1 : len;
  if (len > 0 && begin[len - 1] == '\r') --len;
  line = std::string_view(begin, len);
  ++line_number_;
  return true;
}

std::string_view Tokenizer::next() {
  while (pos_ < line_.size() && is_blank(line_[pos_])) ++pos_;
  const std::size_t start = pos_;
  while (pos_ < line_.size() && !is_blank(line_[pos_])) ++pos_;
  return line_.substr(start, pos_ - start);
}

std::string_view Tokenizer::rest() {
  while (pos_ < line_.size() && is_blank(line_[pos_])) ++pos_;
  std::string_view r = line_.substr(pos_);
  while (!r.empty() && is_blank(r.back())) r.remove_suffix(1);
  return r;
}

bool iequals(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    char x = a[i];
    char y = b[i];
    if (x >= 'A' && x <= 'Z') x = static_cast<char>(x - 'A' + 'a');
    if (y >= 'A' && y <= 'Z') y = static_cast<char>(y - 'A' + 'a');
    if (x != y) return false;
  }
  return true;
}

}  // namespace scanmesh::meshio::detail
