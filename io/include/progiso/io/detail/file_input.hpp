// progiso/io/detail/file_input.hpp — opening untrusted input files: regular files only.
//
// Every reader of the library (raw and NRRD volumes, NRRD detached data files, PGM, PNG, PLY,
// contour OBJ) opens its input through input_file. It refuses everything that is not a
// regular file — directories, FIFOs, sockets, character devices such as /dev/zero or
// /dev/urandom, block devices — with one line naming the file and what was found, before
// reading a byte, so a reader can neither hang on a FIFO nor grow without bound on an endless
// device. The check is made on the opened descriptor (open without blocking, then fstat), so a
// file swapped for a FIFO between a check and the open cannot slip through.
//
// The size is taken when the file is opened; readers bound every allocation by it, and
// read_all() never reads more than it (a file that grows while it is read is read as it was).
//
// Not thread-safe: one reader per object. Errors throw progiso::error.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace progiso::detail {

/// A regular file opened for reading.
class input_file {
 public:
  /// Opens `file` for reading. `kind` names the file in messages ("volume", "PGM", "NRRD data"
  /// …). Throws progiso::error "FILE: cannot open KIND file (why)" when it cannot be opened,
  /// and "FILE: expected a regular KIND file, found a FIFO" (a directory, a character device,
  /// …) for anything but a regular file.
  input_file(const std::filesystem::path& file, std::string_view kind);
  input_file(const input_file&) = delete;
  input_file& operator=(const input_file&) = delete;
  ~input_file();

  [[nodiscard]] const std::filesystem::path& path() const noexcept { return path_; }
  /// The file's size in bytes when it was opened.
  [[nodiscard]] std::uint64_t size() const noexcept { return size_; }
  /// The stdio stream (binary, positioned at the start when opened).
  [[nodiscard]] std::FILE* stream() const noexcept { return file_; }

  /// Reads up to `n` bytes; returns how many were read (fewer only at the end of the file).
  /// Throws progiso::error on an I/O error.
  std::size_t read(void* data, std::size_t n);
  /// Moves to byte `offset` from the start. Throws progiso::error when it cannot.
  void seek(std::uint64_t offset);
  /// The whole file (size() bytes at most). Throws progiso::error on an I/O error.
  [[nodiscard]] std::vector<char> read_all();

 private:
  std::filesystem::path path_;
  std::string kind_;
  std::FILE* file_ = nullptr;
  std::uint64_t size_ = 0;
};

/// A byte range of a file mapped read-only in place; `keeper` unmaps it when the last copy goes.
struct mapped_bytes {
  std::span<const std::byte> bytes;
  std::shared_ptr<const void> keeper;
};
/// Inputs at least this large are mapped rather than read (map_bytes()): their samples then live
/// in the page cache, which the kernel fills as refinement reads them and may evict again, so a
/// volume larger than the memory a process may allocate still refines. Smaller ones are read: a
/// read costs less than the page faults of a mapping.
inline constexpr std::uint64_t map_min_bytes = std::uint64_t{64} << 20;
/// Bytes [offset, offset + n) of `in` mapped read-only (private: a write elsewhere to the file is
/// not promised to show, and the mapping is never written); nullopt when they cannot be mapped
/// (the caller reads them instead). The range must lie within in.size(). A file shortened by
/// another program while it is mapped ends the process at the next read of a lost page
/// (SIGBUS), as for every memory-mapped reader: inputs are not to be truncated in use.
[[nodiscard]] std::optional<mapped_bytes> map_bytes(const input_file& in, std::uint64_t offset,
                                                    std::uint64_t n) noexcept;

/// Up to `limit` bytes of `bytes` for a one-line message, in double quotes: printable ASCII as
/// is, every other byte as \xNN, "..." after the limit. Untrusted text never breaks the line.
[[nodiscard]] std::string quoted(std::string_view bytes, std::size_t limit = 40);

/// What kind of file system object a mode is ("a directory", "a FIFO", …), for messages.
[[nodiscard]] std::string_view file_type_name(unsigned mode) noexcept;

}  // namespace progiso::detail
