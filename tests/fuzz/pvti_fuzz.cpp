// Fuzz harness: VTK XML parallel image files (.pvti) and their pieces.
//
// Input layout: when the input holds the separator "\0DATA\0", what comes before it is the .pvti
// (v.pvti) and what follows is written as each of the piece files p0.vti and p1.vti that seeds
// name; otherwise the whole input is v.pvti. Both the reader and volume_input_files() (the
// command's input list) are run.
#include <cstdint>
#include <string_view>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  progiso::fuzz::read_volume_file(progiso::fuzz::write_header_and_data(
      progiso::fuzz::as_text(data, size), "v.pvti", "v.pvti", {"p0.vti", "p1.vti"}));
  return 0;
}
