// progiso/io/detail/gzip_input.hpp — reading gzip (or zlib) data from an untrusted file,
// shared by the NRRD reader (gzip encoding), the NIfTI reader (.nii.gz, .img.gz) and the MRC
// reader (.map.gz, as EMDB distributes maps). sequential_input reads a file front to back,
// inflating it when it starts with the gzip magic, whatever its name.
//
// gzip_input inflates from the file's current position, one or more concatenated gzip members
// (as gzip and pigz write them), into buffers the caller owns: nothing is allocated beyond a
// 64 KiB input buffer and, while skipping, a scratch buffer of at most that size. Corrupt data
// throws progiso::error "FILE: corrupt LABEL (zlib: …)"; data that ends early is not an error
// here, read() returns fewer bytes and the caller names what was expected.
//
// Bounds: a reader that allocates for declared contents checks first that the compressed size
// can hold them: deflate expands at most about 1032:1, so a file of n bytes yields at most
// gzip_max_ratio × n + gzip_slack_bytes (gzip_can_hold()).
//
// Not thread-safe: one reader per object, on one input_file.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>

#include <progiso/io/detail/file_input.hpp>

namespace progiso::detail {

inline constexpr std::uint64_t gzip_max_ratio = 1032;
inline constexpr std::uint64_t gzip_slack_bytes = 64 * 1024;

/// Whether `compressed` bytes of gzip data can inflate to `bytes` bytes (gzip_max_ratio).
[[nodiscard]] bool gzip_can_hold(std::uint64_t compressed, std::uint64_t bytes) noexcept;

/// Whether the file starts with the gzip magic (0x1f 0x8b); leaves the position at the start.
[[nodiscard]] bool starts_with_gzip_magic(input_file& in);

class gzip_input {
 public:
  /// Inflates `in` from its current position. `label` names the data in messages ("NRRD gzip
  /// data"). Throws progiso::error when zlib cannot start.
  gzip_input(input_file& in, std::string label);
  gzip_input(const gzip_input&) = delete;
  gzip_input& operator=(const gzip_input&) = delete;
  ~gzip_input();

  /// Fills `out` with the next decompressed bytes; returns how many (fewer only when the data
  /// ends). Throws progiso::error for corrupt data, std::bad_alloc when zlib runs out.
  std::size_t read(std::span<std::byte> out);
  /// Drops the next `n` decompressed bytes; returns how many were dropped (fewer only when the
  /// data ends).
  std::uint64_t skip(std::uint64_t n);

 private:
  struct state;
  input_file& in_;
  std::string label_;
  std::unique_ptr<state> state_;
};

/// A file read front to back, plain or gzip (told by its first two bytes, not its name).
class sequential_input {
 public:
  /// Opens `file` (input_file's `kind`); gzip data is named `gzip_label` in messages.
  sequential_input(const std::filesystem::path& file, std::string_view kind,
                   std::string gzip_label);
  [[nodiscard]] bool gzipped() const noexcept { return gz_ != nullptr; }
  [[nodiscard]] const std::filesystem::path& path() const noexcept { return in_.path(); }
  /// The file itself when its data is not gzip (a caller may map it), else null.
  [[nodiscard]] const input_file* plain() const noexcept { return gz_ ? nullptr : &in_; }
  /// The file's size (compressed, for gzip).
  [[nodiscard]] std::uint64_t size() const noexcept { return in_.size(); }
  /// Reads up to out.size() bytes; fewer only at the end.
  std::size_t read(std::span<std::byte> out);
  /// From the start (nothing read yet), moves to byte `to` of the (inflated) data; false when
  /// the data ends first.
  bool skip_to(std::uint64_t to);

 private:
  input_file in_;
  std::unique_ptr<gzip_input> gz_;
};

}  // namespace progiso::detail
