#include "cli_outputs.hpp"

#include <sys/stat.h>

#include <csignal>
#include <optional>
#include <system_error>

#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/file_output.hpp>

namespace progiso::cli {

namespace fs = std::filesystem;

namespace {

struct identity {
  dev_t device = 0;
  ino_t inode = 0;
  bool character_device = false;
  bool operator==(const identity& o) const noexcept {
    return device == o.device && inode == o.inode;
  }
};

/// The file's identity when it exists (symbolic links followed).
std::optional<identity> identify(const fs::path& p) {
  struct stat st {};
  if (::stat(p.c_str(), &st) != 0) return std::nullopt;
  return identity{st.st_dev, st.st_ino, S_ISCHR(st.st_mode)};
}

/// An absolute path with symbolic links resolved as far as the path exists, for comparing
/// outputs that do not exist yet.
fs::path normalised(const fs::path& p) {
  std::error_code ec;
  fs::path n = fs::weakly_canonical(fs::absolute(p, ec), ec);
  if (ec) n = fs::absolute(p, ec).lexically_normal();
  // "dir/" and "dir" name the same thing.
  while (!n.empty() && n.filename().empty() && n != n.root_path()) n = n.parent_path();
  return n;
}

void on_fatal_signal(int sig) {
  detail::remove_registered_temporaries();
  // SA_RESETHAND has restored the default action: end the process by the same signal.
  std::raise(sig);
}

}  // namespace

void refuse_clashing_outputs(const std::vector<fs::path>& inputs,
                             const std::vector<named_output>& outputs) {
  for (std::size_t i = 0; i < outputs.size(); ++i) {
    const named_output& out = outputs[i];
    const std::optional<identity> id = identify(out.path);
    if (id) {
      for (const fs::path& in : inputs) {
        const std::optional<identity> in_id = identify(in);
        if (in_id && *in_id == *id) {
          throw error(out.path.string() + ": " + out.flag + " names the input file " + in.string() +
                      " (refusing to overwrite an input)");
        }
      }
    }
    for (std::size_t j = 0; j < i; ++j) {
      const named_output& other = outputs[j];
      const std::optional<identity> other_id = identify(other.path);
      const bool same = id && other_id
                            ? *id == *other_id && !id->character_device
                            : !id && !other_id && normalised(out.path) == normalised(other.path);
      if (same) {
        throw error(out.path.string() + ": " + out.flag + " names the same file as " + other.flag +
                    " (each output needs its own file)");
      }
    }
  }
}

void remove_temporaries_on_signals() {
  struct sigaction action {};
  action.sa_handler = on_fatal_signal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = static_cast<int>(SA_RESETHAND);
  for (const int sig : {SIGINT, SIGTERM, SIGHUP}) sigaction(sig, &action, nullptr);
}

}  // namespace progiso::cli
