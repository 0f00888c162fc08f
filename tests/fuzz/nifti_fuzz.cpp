// Fuzz harness: NIfTI files, single (.nii, plain or gzip by content) and header and data pairs
// (.hdr with .img).
//
// Input layout: when the input holds the separator "\0DATA\0", what comes before it is a header
// (v.hdr) and what follows is its data file (v.img); otherwise the whole input is v.nii. Both the
// reader and volume_input_files() (the command's input list) are run.
#include <cstdint>
#include <string_view>

#include <progiso/core/base/error.hpp>
#include <progiso/core/io/volume_io.hpp>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace progiso;
  const std::string_view text = fuzz::as_text(data, size);
  constexpr std::string_view separator("\0DATA\0", 6);
  const std::size_t cut = text.find(separator);
  std::filesystem::path file;
  if (cut == std::string_view::npos) {
    file = fuzz::write_file("v.nii", text);
  } else {
    fuzz::write_file("v.img", text.substr(cut + separator.size()));
    file = fuzz::write_file("v.hdr", text.substr(0, cut));
  }
  try {
    (void)volume_input_files(file, std::nullopt);
  } catch (const progiso::error&) {
  }
  try {
    const volume v = read_volume(file, std::nullopt, std::nullopt);
    (void)v.value_range();
  } catch (const progiso::error&) {
  }
  return 0;
}
