// progiso/core/detail/file_output.hpp — all-or-nothing file output and small file-name helpers
// shared by the mesh, contour and image writers (and the command's statistics files).
//
// atomic_output writes to a uniquely named temporary file beside the target and renames it onto
// the target in commit(); if commit() is never reached (an exception on the way), the destructor
// removes the temporary, so a target is either the complete new file or untouched. Errors throw
// progiso::error naming the target. Not thread-safe; one writer per object.
#pragma once

#include <cstddef>
#include <cstdio>
#include <filesystem>
#include <string>
#include <string_view>

namespace progiso::detail {

/// The message of an errno value.
[[nodiscard]] std::string errno_text(int code);
/// The file's extension in lower case, with its dot (".ply").
[[nodiscard]] std::string lower_extension(const std::filesystem::path& file);

/// All-or-nothing output to one file.
class atomic_output {
 public:
  /// Creates the temporary beside `target`; throws progiso::error when it cannot.
  explicit atomic_output(const std::filesystem::path& target);
  atomic_output(const atomic_output&) = delete;
  atomic_output& operator=(const atomic_output&) = delete;
  ~atomic_output();

  void write(const void* data, std::size_t size);
  void write(std::string_view text) { write(text.data(), text.size()); }
  /// Flushes, checks and closes the temporary, then renames it onto the target.
  void commit();

 private:
  [[noreturn]] void fail(const char* what, int code) const;

  std::filesystem::path target_;
  std::filesystem::path temp_;
  std::FILE* file_ = nullptr;
  bool committed_ = false;
};

}  // namespace progiso::detail
