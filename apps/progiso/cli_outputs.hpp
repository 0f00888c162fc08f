// apps/progiso/cli_outputs.hpp — the command's outputs: refused when they name an input or one
// another, created (as temporaries) before any computation, published together at the end,
// and removed if SIGINT, SIGTERM or SIGHUP arrives first; their coordinates checked against the
// float range and mapped to scanner coordinates.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <progiso/core/field/volume.hpp>
#include <progiso/core/surface/mesh.hpp>
#include <progiso/io/volume_io.hpp>

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

/// Refuses a PLY, STL, GLB or VTP output whose float coordinates could not hold the volume's extent
/// (in the scanner coordinates of `world` when given: the box's corners mapped).
void check_float_range(const std::filesystem::path& output, const progiso::volume& vol,
                       const std::optional<progiso::index_to_world>& world);

/// With `asked` (--world), the orientation `source` declares; nullopt without. Throws
/// progiso::error naming `input` when it declares none (or there is no file: the demo).
[[nodiscard]] std::optional<progiso::index_to_world> asked_world(bool asked,
                                                                 const volume_source* source,
                                                                 const std::string& input);

/// The mesh in scanner coordinates (`world`), its winding kept facing the same side and its
/// normals mapped as gradients (see the definition).
void to_world(progiso::triangle_mesh& mesh, const progiso::volume& data,
              const progiso::index_to_world& world);

}  // namespace progiso::cli
