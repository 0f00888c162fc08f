// progiso/io/detail/file_output.hpp — all-or-nothing file output and small file-name helpers
// shared by the mesh, contour and image writers (and the command's statistics files).
//
// atomic_output writes a regular file through a uniquely named temporary beside it
// ("NAME.tmp-XXXXXX", in the directory of the file a symbolic link points to, so the link is
// kept and written through) and renames the temporary onto the target in publish(); until
// then the target is untouched, and if publish() is never reached the destructor removes the
// temporary. So a target is either the complete new file or what it was. A target that exists
// and is a character device or a FIFO (/dev/null, /dev/stdout, a named pipe with a reader) is
// written into directly instead: replacing a device node by a regular file would destroy it.
// Directories, block devices, sockets and FIFOs without a reader are refused.
//
// Splitting the write in finish() (everything written, flushed and closed) and publish() (the
// rename) lets a caller with several outputs create every temporary before it computes
// anything, finish them all, and only then publish them, so that a failure leaves none behind.
//
// Temporaries (and staged directories) are listed in a process-wide registry that
// remove_registered_temporaries() empties from a signal handler: the command calls it on
// SIGINT, SIGTERM and SIGHUP, so an interrupted write leaves nothing behind.
//
// Not thread-safe: one writer per object. Errors throw progiso::error naming the target.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <string_view>

namespace progiso::detail {

/// The message of an errno value.
[[nodiscard]] std::string errno_text(int code);
/// The file's extension in lower case, with its dot (".ply").
[[nodiscard]] std::string lower_extension(const std::filesystem::path& file);

/// All-or-nothing output to one file (or direct output into a device or FIFO).
class atomic_output {
 public:
  /// Creates the temporary beside `target` (or opens the device). Throws progiso::error when
  /// the name is empty, names a directory, a block device, a socket or a FIFO without a
  /// reader, or when the temporary cannot be created (missing or unwritable directory …).
  explicit atomic_output(const std::filesystem::path& target);
  atomic_output(const atomic_output&) = delete;
  atomic_output& operator=(const atomic_output&) = delete;
  ~atomic_output();

  [[nodiscard]] const std::filesystem::path& target() const noexcept { return target_; }
  /// True when writing straight into a character device or FIFO (no temporary).
  [[nodiscard]] bool direct() const noexcept { return direct_; }

  void write(const void* data, std::size_t size);
  void write(std::string_view text) { write(text.data(), text.size()); }
  /// Flushes, checks and closes the temporary; the target is still untouched.
  void finish();
  /// Renames the finished temporary onto the target (no-op for direct output).
  void publish();
  /// finish() then publish().
  void commit() {
    finish();
    publish();
  }
  /// Where scratch files for this output go (scratch_file): the directory of the file the
  /// rename replaces, whose file system takes the output; the system's temporary directory for
  /// direct output.
  [[nodiscard]] std::filesystem::path scratch_directory() const;

 private:
  [[noreturn]] void fail(const char* what, int code) const;

  std::filesystem::path target_;
  std::filesystem::path final_;  // where the rename goes: the target, or the file a link names
  std::filesystem::path temp_;
  std::FILE* file_ = nullptr;
  int slot_ = -1;  // registry slot of the temporary
  bool direct_ = false;
  bool finished_ = false;
  bool published_ = false;
};

/// An unnamed file for bytes that must wait before they go to an output (a PLY's triangles,
/// which come after all its vertices): appended to, then copied into the output from its first
/// byte. Made with O_TMPFILE in `directory` (or, where the file system lacks it, made and unlinked
/// at once), so no name of it outlives the object, nor anything of it the process. Errors throw
/// progiso::error naming `for_errors` (the output it serves). Not thread-safe.
class scratch_file {
 public:
  scratch_file(const std::filesystem::path& directory, std::string for_errors);
  scratch_file(const scratch_file&) = delete;
  scratch_file& operator=(const scratch_file&) = delete;
  ~scratch_file();

  void write(const void* data, std::size_t size);
  [[nodiscard]] std::uint64_t size() const noexcept { return size_; }
  /// Every byte written so far, in order, written into `out`.
  void copy_into(atomic_output& out);

 private:
  int fd_ = -1;
  std::string name_;
  std::uint64_t size_ = 0;
};

/// A directory that is filled in a staging directory beside it ("DIR.tmp-XXXXXX") and appears
/// only in publish(): renamed to DIR when DIR does not exist, else its files are moved into DIR
/// (replacing files of the same names). The destructor removes the staging directory and its
/// files unless published. Throws progiso::error naming DIR when DIR exists and is not a
/// directory, or when the staging directory cannot be created.
class staged_directory {
 public:
  explicit staged_directory(const std::filesystem::path& target);
  staged_directory(const staged_directory&) = delete;
  staged_directory& operator=(const staged_directory&) = delete;
  ~staged_directory();

  /// Where files go until publish().
  [[nodiscard]] const std::filesystem::path& staging() const noexcept { return staging_; }
  void publish();

 private:
  std::filesystem::path target_;
  std::filesystem::path staging_;
  int slot_ = -1;
  bool published_ = false;
};

/// Removes every registered temporary file and staged directory (with the files in it). Only
/// async-signal-safe calls: for signal handlers (the command's SIGINT/SIGTERM/SIGHUP handler).
void remove_registered_temporaries() noexcept;

/// A fresh "NAME.tmp-XXXXXX" suffix's random part (6 characters of [a-z0-9]).
[[nodiscard]] std::string temporary_suffix();

}  // namespace progiso::detail
