// tests/fuzz/fuzz_support.hpp — what every libFuzzer harness shares: a private scratch
// directory (in /dev/shm when it exists: memory-backed, so a file per input costs microseconds)
// and a way to write the input's bytes there under a chosen name. The readers take paths, so
// the harnesses hand them real files, as the command does.
//
// A harness calls the code under test and catches progiso::error only: that is the documented
// way to reject an input. Anything else — a crash, a sanitizer report, an uncaught exception
// (std::bad_alloc included: a bad file must never be reported by running out of memory),
// libFuzzer's RSS or malloc limit, a timeout — is a finding.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <initializer_list>
#include <string>
#include <string_view>
#include <system_error>

#include <progiso/core/base/error.hpp>
#include <progiso/io/volume_io.hpp>

namespace progiso::fuzz {

/// The process's scratch directory, created on first use and removed at exit.
inline const std::filesystem::path& scratch() {
  static const std::filesystem::path dir = [] {
    std::error_code ec;
    std::filesystem::path base = "/dev/shm";
    if (!std::filesystem::is_directory(base, ec)) base = std::filesystem::temp_directory_path();
    std::filesystem::path d = base / ("progiso-fuzz-" + std::to_string(::getpid()));
    std::filesystem::create_directories(d, ec);
    return d;
  }();
  static const struct cleanup {
    ~cleanup() {
      std::error_code ec;
      std::filesystem::remove_all(dir, ec);
    }
  } remover;
  return dir;
}

/// Writes `bytes` to scratch()/name (replacing it) and returns the path.
inline std::filesystem::path write_file(const std::string& name, std::string_view bytes) {
  const std::filesystem::path p = scratch() / name;
  std::FILE* f = std::fopen(p.c_str(), "wb");
  if (f == nullptr) std::abort();
  if (!bytes.empty() && std::fwrite(bytes.data(), 1, bytes.size(), f) != bytes.size()) std::abort();
  std::fclose(f);
  return p;
}

/// What the command does with a volume file it is given: lists its input files (a header's
/// data files) and reads it. Only progiso::error may come out.
inline void read_volume_file(const std::filesystem::path& file, const volume_choice& choice = {}) {
  try {
    (void)volume_input_files(file, std::nullopt, choice);
  } catch (const progiso::error&) {
  }
  try {
    const volume v = read_volume(file, std::nullopt, std::nullopt, choice);
    (void)v.value_range();
  } catch (const progiso::error&) {
  }
}

inline std::string_view as_text(const std::uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

/// A header file and its data files in one input: what comes before the separator "\0DATA\0" is
/// written as `header_name` and what follows as each of `data_names`; without the separator, the
/// whole input is written as `single_name`. Returns the file to read.
inline std::filesystem::path write_header_and_data(std::string_view text,
                                                   const std::string& single_name,
                                                   const std::string& header_name,
                                                   std::initializer_list<const char*> data_names) {
  constexpr std::string_view separator("\0DATA\0", 6);
  const std::size_t cut = text.find(separator);
  if (cut == std::string_view::npos) return write_file(single_name, text);
  for (const char* name : data_names) write_file(name, text.substr(cut + separator.size()));
  return write_file(header_name, text.substr(0, cut));
}

}  // namespace progiso::fuzz
