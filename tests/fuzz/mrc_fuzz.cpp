// Fuzz harness: MRC and CCP4 maps (plain or gzip by content; any mode, byte order, axis order,
// extended header, volume stack). Both the reader and volume_input_files() (the command's
// input list) are run, for the first volume and the second (a volume stack's).
#include <cstdint>
#include <string_view>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes = progiso::fuzz::as_text(data, size);
  const auto file = progiso::fuzz::write_file("v.mrc", bytes);
  progiso::fuzz::read_volume_file(file);
  progiso::fuzz::read_volume_file(file, {std::nullopt, 1});
  return 0;
}
