// progiso/io/hierarchy_io.hpp — hierarchy stream files (.pgh; core/surface/hierarchy_stream.hpp,
// layout in docs/formats.md): read as an untrusted input.
#pragma once

#include <cstdint>
#include <filesystem>

#include <progiso/core/base/error.hpp>
#include <progiso/core/surface/hierarchy_stream.hpp>

namespace progiso {

/// Reads and validates a hierarchy stream file, keeping at most `max_records` records (a prefix).
/// Throws progiso::error "FILE: hierarchy stream: byte N: expected …, found …" for a file that is
/// not a regular file, is truncated inside a chunk, or is corrupt.
[[nodiscard]] hierarchy_stream read_hierarchy_stream(
    const std::filesystem::path& file, std::uint64_t max_records = hierarchy_stream::all_records);

}  // namespace progiso
