// Fuzz harness: NRRD files, attached (.nrrd) and detached (.nhdr with data files).
//
// Input layout: when the input holds the separator "\0DATA\0", what comes before it is a
// detached header (v.nhdr) and what follows is written as each of the data files d.raw, d0.raw,
// d1.raw, d2.raw and d.raw.gz that seeds' headers name; otherwise the whole input is v.nrrd.
// Both the reader and volume_input_files() (the command's input list) are run, with no volume
// chosen and with volumes 1 and 2 of a 4-D series (the command's --volume; 3-D files refuse them).
#include <cstdint>
#include <string_view>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto file =
      progiso::fuzz::write_header_and_data(progiso::fuzz::as_text(data, size), "v.nrrd", "v.nhdr",
                                           {"d.raw", "d0.raw", "d1.raw", "d2.raw", "d.raw.gz"});
  progiso::fuzz::read_volume_file(file);
  for (const std::int64_t k : {1, 2}) progiso::fuzz::read_volume_file(file, {.volume = k});
  return 0;
}
