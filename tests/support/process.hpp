// Runs a program (the real scanmesh binary) with stdout/stderr captured, for tests that check
// a command's output and exit status.
// SPDX-License-Identifier: MIT
#pragma once

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "support/temp_dir.hpp"

namespace scanmesh::test {

struct RunResult {
  int status = -1;  ///< exit status, or 128 + signal number when killed by a signal
  std::string out;
  std::string err;
};

inline std::string slurp(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline void spit(const std::filesystem::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
}

/// Runs `exe` with `args`, stdout and stderr captured through files in `dir`. With
/// `max_file_bytes` the child gets RLIMIT_FSIZE (and ignores SIGXFSZ), so every write past that
/// size fails with EFBIG: a disk-full failure that works even when the tests run as root.
inline RunResult run_program(const std::string& exe, const TempDir& dir,
                             const std::vector<std::string>& args,
                             std::optional<rlim_t> max_file_bytes = std::nullopt) {
  static std::atomic<int> counter{0};
  const int n = counter++;
  const std::filesystem::path out_file = dir / (".stdout." + std::to_string(n));
  const std::filesystem::path err_file = dir / (".stderr." + std::to_string(n));
  std::vector<std::string> argv_s{exe};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);

  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    const int fo = ::open(out_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int fe = ::open(err_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fo < 0 || fe < 0 || ::dup2(fo, 1) < 0 || ::dup2(fe, 2) < 0) ::_exit(126);
    if (max_file_bytes) {
      ::signal(SIGXFSZ, SIG_IGN);  // stays ignored across exec
      const rlimit lim{*max_file_bytes, *max_file_bytes};
      if (::setrlimit(RLIMIT_FSIZE, &lim) != 0) ::_exit(126);
    }
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  int wstatus = 0;
  while (::waitpid(pid, &wstatus, 0) < 0) {
    if (errno != EINTR) throw std::runtime_error("waitpid failed");
  }
  RunResult r;
  r.status = WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : 128 + WTERMSIG(wstatus);
  r.out = slurp(out_file);
  r.err = slurp(err_file);
  std::filesystem::remove(out_file);
  std::filesystem::remove(err_file);
  return r;
}

}  // namespace scanmesh::test
