// apps/progiso/cli_outputs.hpp — the command's outputs: refused when they name an input or one
// another, created (as temporaries) before any computation, published together at the end,
// and removed if SIGINT, SIGTERM or SIGHUP arrives first; their coordinates checked against the
// float range and mapped to scanner coordinates.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <progiso/core/field/volume.hpp>
#include <progiso/core/surface/finest_surface.hpp>
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

/// The planes a window holds for the finest surface made share by share (whole chunk rows, at
/// least one): samples of a quarter of detail::finest_slab_bytes, since a share's passes also
/// hold a corner byte per point of its planes and its piece of the output. PROGISO_WINDOW_BYTES
/// sets the sample bytes, so that the tests take small levels through several windows.
[[nodiscard]] std::int64_t window_planes(const progiso::plane_window& w);

/// The finest surface of planes [z_begin, z_end) of a windowed level (z_end = dims[2]: to the
/// last plane), sub-share by sub-share in z order (detail::finest_share): each one's planes and
/// the two after them that its last cubes and edges read held while it is made, its ids
/// continuing from `counted()` (the vertices and triangles handed to `add` so far, plus those of
/// the shares before). The pieces, in order, are those one share of [z_begin, z_end) gives.
void finest_in_windows(progiso::plane_window& w, double iso, const progiso::parallel_loop& loop,
                       std::size_t parts, const progiso::detail::finest_piece& add,
                       const std::function<std::array<std::uint64_t, 2>()>& counted,
                       std::int64_t z_begin, std::int64_t z_end);

/// The mesh in scanner coordinates (`world`), its winding kept facing the same side and its
/// normals mapped as gradients (see the definition).
void to_world(progiso::triangle_mesh& mesh, const progiso::volume& data,
              const progiso::index_to_world& world);

}  // namespace progiso::cli
