// progiso/io/detail/hdf5_reader.hpp — the HDF5 resolution pyramids of Imaris (.ims) and
// BigDataViewer (.h5), read through libhdf5 (Debian's libhdf5-dev, its serial build), behind
// read_hdf5().
//
// Imaris 5.5 (`ImarisDataSet`): `/DataSet/ResolutionLevel R/TimePoint T/Channel C/Data`, a
// (z, y, x) dataset padded to its blocks, whose image size is the channel group's ImageSizeX/Y/Z
// attributes (text, as Imaris writes every attribute); the extent from `/DataSetInfo/Image`'s
// ExtMin0..2 and ExtMax0..2 (the box's corners: spacing (max − min) / size per level, origin the
// first voxel's centre). Volumes are timepoints × channels (volume_choice::volume = t × channels
// + c), the same at every level.
//
// BigDataViewer: `/sSS/resolutions` (levels × 3 downsampling factors, x first) and
// `/tTTTTT/sSS/L/cells`, a (z, y, x) dataset. BigDataViewer stores 16-bit data as int16 and reads
// it as unsigned: so does progiso. The voxel size lives in the XML beside the file, which is not
// read: spacing 1 at level 0 (--spacing sets it), a level's spacing its factors times level 0's,
// its origin where BigDataViewer places it ((factor − 1) / 2 of level 0's voxels). Volumes are
// timepoints × setups (volume = t × setups + s).
//
// Levels are finest first (volume_choice::level). Each level is its own field: a coarser level is
// not a subsampling of the finer one (Imaris and BigDataViewer average blocks), so a cut of one
// level is never mixed with another's (docs/formats.md).
//
// Bounds: the file is opened read-only with libhdf5's error printing off and every call checked;
// a level's size is checked (2 to 32769 samples per axis; the dataset at least as large) and its
// stored bytes against its size (a level more than 1100 times larger than its stored chunks, the
// deflate limit, is refused unread: a decompression bomb); only filters libhdf5 decodes here are
// accepted (a dataset of the LZ4 plugin filter is refused by name); types are 1, 2 or 4 byte
// integers and 4 or 8 byte floats. Reads run in slabs of whole chunk layers.
// Every failure throws progiso::error naming the file, the object, what was expected and what
// was found.
//
// Isolation: libhdf5 is not memory-safe on every corrupt file (fuzzing finds use after free in
// its object-header code), so every call into it runs in a child process (fork): a file that
// crashes it gives one error naming the file and how the child ended, one on which it falls
// silent for 120 s is killed with an error, and the samples come back through memory shared
// with the child. The child is single-threaded, which is also what libhdf5's serial build needs:
// different files may be read from several threads at once.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <progiso/core/field/volume.hpp>
#include <progiso/io/detail/file_input.hpp>

namespace progiso::detail {

/// Which pyramid a file holds.
enum class hdf5_layout { imaris, bdv };

/// One level of a pyramid, checked.
struct hdf5_level {
  index3 dims{};                                 ///< the image's samples, x fastest
  std::array<double, 3> spacing{1.0, 1.0, 1.0};  ///< x, y, z
  std::array<double, 3> origin{0.0, 0.0, 0.0};   ///< x, y, z
};

/// A pyramid: its levels, finest first, its volumes and their sample type.
struct hdf5_image {
  std::filesystem::path file;
  hdf5_layout layout = hdf5_layout::imaris;
  sample_type type = sample_type::u8;
  std::vector<hdf5_level> levels;
  std::int64_t timepoints = 1;
  std::int64_t channels = 1;  ///< Imaris channels, or BigDataViewer setups
  [[nodiscard]] std::int64_t volumes() const noexcept { return timepoints * channels; }
  /// The dataset of `volume` at `level`.
  [[nodiscard]] std::string dataset(std::size_t level, std::int64_t volume) const;
};

/// Whether `file` starts with the HDF5 signature (at byte 0, or after a user block of 512,
/// 1024, … bytes, as the format allows).
[[nodiscard]] bool has_hdf5_signature(const std::filesystem::path& file);
/// Whether the name asks for HDF5: .ims, .h5, .hdf5, .hdf (any case).
[[nodiscard]] bool has_hdf5_name(const std::filesystem::path& file);

/// Reads and checks the pyramid of an Imaris or BigDataViewer file (see the file comment).
[[nodiscard]] hdf5_image read_hdf5_header(const std::filesystem::path& file);

/// The samples of `volume` at `level`, x fastest, in host byte order, in memory shared with the
/// child that read them (the keeper unmaps it); nullopt when `stop` (asked while the child reads,
/// when not empty) answers true, which ends the child.
[[nodiscard]] std::optional<mapped_bytes> read_hdf5_samples(const hdf5_image& image,
                                                            std::size_t level, std::int64_t volume,
                                                            const std::function<bool()>& stop = {});

/// Checks the dataset of `volume` at `level` as read_hdf5_samples() does before it reads (in a
/// child: its type, its size, its stored bytes); returns the planes of one chunk layer (1 when the
/// dataset is not chunked), the unit a plane window reads by. Throws as read_hdf5_samples().
[[nodiscard]] std::int64_t check_hdf5_samples(const hdf5_image& image, std::size_t level,
                                              std::int64_t volume);
/// Planes [z_begin, z_end) of `volume` at `level` into `out` (exactly their bytes, x fastest,
/// host byte order): read by a child into memory shared with it, then copied. Throws as
/// read_hdf5_samples(); check_hdf5_samples() first.
void read_hdf5_planes(const hdf5_image& image, std::size_t level, std::int64_t volume,
                      std::int64_t z_begin, std::int64_t z_end, std::span<std::byte> out);

}  // namespace progiso::detail
