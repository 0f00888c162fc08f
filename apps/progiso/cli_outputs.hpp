// apps/progiso/cli_outputs.hpp — the command's outputs: refused when they name an input or one
// another, created (as temporaries) before any computation, published together at the end,
// and removed if SIGINT, SIGTERM or SIGHUP arrives first.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace progiso::cli {

/// An output file or directory and the option that named it ("-o", "--stats-json" …).
struct named_output {
  std::string flag;
  std::filesystem::path path;
};

/// Throws progiso::error (one line: the output, the option, what it clashes with) when an
/// output is the same file as an input (same device and inode, whatever the name: links and
/// relative paths included) or as another output (same file, or the same normalised path when
/// it does not exist yet). Writing into a character device twice (/dev/null) is allowed.
void refuse_clashing_outputs(const std::vector<std::filesystem::path>& inputs,
                             const std::vector<named_output>& outputs);

/// Installs handlers for SIGINT, SIGTERM and SIGHUP that remove every registered temporary
/// (detail::remove_registered_temporaries) and then end the process by the same signal.
void remove_temporaries_on_signals();

}  // namespace progiso::cli
