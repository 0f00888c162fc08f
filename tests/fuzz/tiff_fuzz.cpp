// Fuzz harness: TIFF stacks (.tif: pages of one grey channel in strips or tiles, uncompressed,
// LZW, Deflate or PackBits; ImageJ descriptions), through libtiff and progiso's checks around it.
// Both the reader and volume_input_files() (the command's input list) are run, for the first
// volume and the second (a hyperstack's frames).
#include <cstdint>
#include <string_view>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes = progiso::fuzz::as_text(data, size);
  const auto file = progiso::fuzz::write_file("v.tif", bytes);
  progiso::fuzz::read_volume_file(file);
  progiso::fuzz::read_volume_file(file, {std::nullopt, 1});
  return 0;
}
