// Fuzz harness: MetaImage files, with the data after the header (.mha) or in data files (.mhd).
//
// Input layout: when the input holds the separator "\0DATA\0", what comes before it is a header
// (v.mhd) and what follows is written as each of the data files d.raw, d1.raw, d2.raw and d3.raw
// that seeds' headers name (one file, a LIST, a pattern d%d.raw); otherwise the whole input is
// v.mha. Both the reader and volume_input_files() (the command's input list) are run, with no
// volume chosen and with volumes 1 and 2 of a series (NDims 4; the command's --volume).
#include <cstdint>
#include <string_view>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto file =
      progiso::fuzz::write_header_and_data(progiso::fuzz::as_text(data, size), "v.mha", "v.mhd",
                                           {"d.raw", "d1.raw", "d2.raw", "d3.raw"});
  progiso::fuzz::read_volume_file(file);
  for (const std::int64_t k : {1, 2}) progiso::fuzz::read_volume_file(file, {.volume = k});
  return 0;
}
