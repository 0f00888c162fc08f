// Fuzz harness: NIfTI files, single (.nii, plain or gzip by content) and header and data pairs
// (.hdr with .img).
//
// Input layout: when the input holds the separator "\0DATA\0", what comes before it is a header
// (v.hdr) and what follows is its data file (v.img); otherwise the whole input is v.nii. Both the
// reader and volume_input_files() (the command's input list) are run, with no volume chosen and
// with volumes 1 and 2 of a time series (the command's --volume; files of one volume refuse them).
#include <cstdint>
#include <string_view>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto file = progiso::fuzz::write_header_and_data(progiso::fuzz::as_text(data, size),
                                                         "v.nii", "v.hdr", {"v.img"});
  progiso::fuzz::read_volume_file(file);
  for (const std::int64_t k : {1, 2}) progiso::fuzz::read_volume_file(file, {.volume = k});
  return 0;
}
