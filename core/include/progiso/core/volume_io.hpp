// progiso/core/volume_io.hpp — reading volumes from headerless raw files and NRRD files.
//
// Two sources are supported. A headerless raw file holds nothing but the samples, x varying
// fastest, then y, then z; its layout (dims, sample type, byte order) comes from the caller,
// usually the command line's --dims and --type, and the file size must match it exactly.
// NRRD files (.nrrd with attached data, .nhdr with a detached data file) describe themselves;
// they are decoded by Teem's reference reader, so every encoding Teem supports (raw and gzip
// at least) and either byte order works. read_volume() picks the reader the way the
// command-line tool does: an explicit raw layout wins, otherwise the file extension decides.
//
// Every reader returns a volume whose samples are in host byte order. Every failure caused by
// the input — a missing file, a size that does not match the layout, a malformed or
// unsupported header — throws progiso::error with one line that names the file, what was
// expected and what was found. Nothing here aborts on malformed input.
//
// Cost: one pass over the file; the samples are copied once into the volume (a raw file in
// the other byte order is swapped in place during that pass). Memory peaks at about twice the
// data size for NRRD files (Teem's buffer plus the volume's copy).
//
// Thread safety: the functions may be called concurrently. Teem keeps its error messages in
// process-wide state, so read_nrrd() serialises its calls into Teem with an internal mutex.
#pragma once

#include <array>
#include <filesystem>
#include <optional>

#include <progiso/core/volume.hpp>

namespace progiso {

/// The layout of a headerless raw file: grid dims (x fastest), sample type and byte order.
struct raw_layout {
  index3 dims;
  sample_type type;
  bool big_endian = false;
};

/// Reads a headerless raw volume with the given layout and converts it to host byte order.
/// Throws progiso::error when the file is missing or unreadable, when a dim is < 2, or when
/// the file size differs from dims × sample_size(layout.type) (the message gives both byte
/// counts, the dims and the type), or when spacing/origin are rejected by the volume.
[[nodiscard]] volume read_raw(const std::filesystem::path& file, const raw_layout& layout,
                              std::array<double, 3> spacing = {1.0, 1.0, 1.0},
                              std::array<double, 3> origin = {0.0, 0.0, 0.0});

/// Reads a NRRD file (.nrrd, or a .nhdr header with its detached data file) through Teem.
/// The array must have exactly 3 axes of at least 2 samples each, and one of the sample types
/// u8 i8 u16 i16 u32 i32 f32 f64. Spacing per axis is the length of the axis' "space
/// directions" vector when present, else the magnitude of its "spacings" entry; an unknown,
/// zero or non-finite spacing becomes 1. The origin is the "space origin" (its first three
/// components) when present, else 0. Throws progiso::error naming the file on any failure,
/// including Teem's own message for headers or data it cannot parse.
[[nodiscard]] volume read_nrrd(const std::filesystem::path& file);

/// Reads a volume the way the command-line tool does: with a raw layout, read_raw(); else, for
/// the extensions .nrrd and .nhdr (case-insensitive), read_nrrd(). A given `spacing` replaces
/// the one from the header (or the default 1,1,1 for raw files). Throws progiso::error
/// "FILE: unknown volume format (…)" for any other file, and whatever the chosen reader
/// throws.
[[nodiscard]] volume read_volume(const std::filesystem::path& file,
                                 const std::optional<raw_layout>& raw,
                                 std::optional<std::array<double, 3>> spacing);

}  // namespace progiso
