// Fuzz harness: NIfTI files, single (.nii, plain or gzip by content) and header and data pairs
// (.hdr with .img).
//
// Input layout: when the input holds the separator "\0DATA\0", what comes before it is a header
// (v.hdr) and what follows is its data file (v.img); otherwise the whole input is v.nii. Both the
// reader and volume_input_files() (the command's input list) are run.
#include <cstdint>
#include <string_view>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text = progiso::fuzz::as_text(data, size);
  constexpr std::string_view separator("\0DATA\0", 6);
  const std::size_t cut = text.find(separator);
  std::filesystem::path file;
  if (cut == std::string_view::npos) {
    file = progiso::fuzz::write_file("v.nii", text);
  } else {
    progiso::fuzz::write_file("v.img", text.substr(cut + separator.size()));
    file = progiso::fuzz::write_file("v.hdr", text.substr(0, cut));
  }
  progiso::fuzz::read_volume_file(file);
  return 0;
}
