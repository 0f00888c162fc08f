// tests/support/bounded_run.hpp — runs a program (the progiso command) as a hostile input's
// victim: without a shell, with an address-space limit (setrlimit in the child; skipped in
// sanitizer builds, whose shadow memory needs terabytes of address space), a wall-clock limit
// after which it is killed, and its peak resident memory read back through wait4().
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace progiso::test {

struct bounded_result {
  int status = -1;         ///< exit status, or -1 when killed by a signal
  int signal = 0;          ///< the signal that ended it, if any
  bool timed_out = false;  ///< killed at the wall-clock limit
  std::string out;
  std::string err;
  std::int64_t max_rss_kib = 0;
  double seconds = 0.0;
};

/// Options of one bounded run.
struct bounds {
  std::chrono::milliseconds wall{std::chrono::seconds(60)};
  std::uint64_t address_space_bytes = 0;  ///< 0: no limit
  /// RLIMIT_DATA: the heap and private writable mappings, which is what a process allocates;
  /// read-only file mappings (a mapped input) and the page cache are not counted. 0: no limit.
  std::uint64_t data_bytes = 0;
  /// Called with the child's pid while it runs, every 5 ms (to send it signals); return false
  /// to stop calling.
  std::function<bool(pid_t)> while_running;
};

/// Bounds with a wall-clock limit and, optionally, an address-space limit.
inline bounds limited(std::chrono::milliseconds wall, std::uint64_t address_space_bytes = 0) {
  bounds b;
  b.wall = wall;
  b.address_space_bytes = address_space_bytes;
  return b;
}

inline std::string read_whole(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// Runs `program` with `args` (argv[1…]); stdout and stderr go to files in `scratch`.
inline bounded_result run_bounded(const std::string& program, const std::vector<std::string>& args,
                                  const std::filesystem::path& scratch, const bounds& b = {}) {
  const std::filesystem::path out = scratch / "bounded.stdout";
  const std::filesystem::path err = scratch / "bounded.stderr";
  std::vector<std::string> all{program};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);

  const auto start = std::chrono::steady_clock::now();
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int o = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int e = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(o, 1);
    ::dup2(e, 2);
    const int in = ::open("/dev/null", O_RDONLY);
    ::dup2(in, 0);
#if !defined(PROGISO_SANITIZER_BUILD)
    if (b.address_space_bytes != 0) {
      const rlimit lim{b.address_space_bytes, b.address_space_bytes};
      ::setrlimit(RLIMIT_AS, &lim);
    }
    if (b.data_bytes != 0) {
      const rlimit lim{b.data_bytes, b.data_bytes};
      ::setrlimit(RLIMIT_DATA, &lim);
    }
#endif
    ::execv(program.c_str(), argv.data());
    ::_exit(127);
  }
  bounded_result r;
  int raw = 0;
  rusage usage{};
  bool calling = static_cast<bool>(b.while_running);
  for (;;) {
    const pid_t done = ::wait4(pid, &raw, WNOHANG, &usage);
    if (done == pid) break;
    if (std::chrono::steady_clock::now() - start > b.wall) {
      r.timed_out = true;
      ::kill(pid, SIGKILL);
      ::wait4(pid, &raw, 0, &usage);
      break;
    }
    if (calling) calling = b.while_running(pid);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (WIFEXITED(raw)) r.status = WEXITSTATUS(raw);
  if (WIFSIGNALED(raw)) r.signal = WTERMSIG(raw);
  r.max_rss_kib = usage.ru_maxrss;
  r.out = read_whole(out);
  r.err = read_whole(err);
  std::filesystem::remove(out);
  std::filesystem::remove(err);
  return r;
}

}  // namespace progiso::test
