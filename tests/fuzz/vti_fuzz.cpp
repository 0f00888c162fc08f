// Fuzz harness: VTK XML image data files (.vti: ascii, base64 or appended point data, plain or in
// zlib blocks). Both the reader and volume_input_files() (the command's input list) are run.
#include <cstdint>
#include <string_view>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text = progiso::fuzz::as_text(data, size);
  progiso::fuzz::read_volume_file(progiso::fuzz::write_file("v.vti", text));
  return 0;
}
