// progiso/io/detail/plane_window.hpp — how a chunked reader makes a plane_window
// (volume_io.hpp): the level's geometry and a function that decodes a range of its planes.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>

#include <progiso/core/base/parallel_loop.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/io/volume_io.hpp>

namespace progiso::detail {

/// Writes planes [z_begin, z_end) of the level into `out` (exactly their bytes, x fastest, host
/// byte order), through `run`; throws progiso::error naming the file at fault.
using plane_loader = std::function<void(std::int64_t z_begin, std::int64_t z_end,
                                        std::span<std::byte> out, const parallel_loop& run)>;

/// A plane_window over a level of `dims` samples of `type`, decoded `chunk_planes` planes at a
/// time (a chunk row) by `load`; `name` (the array's directory) names it in messages. Reserves the
/// level's bytes as address space only. Throws progiso::error when the geometry is refused (as
/// volume's constructor refuses it) or the address space cannot be reserved.
[[nodiscard]] plane_window make_plane_window(const std::filesystem::path& name, const index3& dims,
                                             sample_type type, std::int64_t chunk_planes,
                                             const std::array<double, 3>& spacing,
                                             const std::array<double, 3>& origin,
                                             plane_loader load);

}  // namespace progiso::detail
