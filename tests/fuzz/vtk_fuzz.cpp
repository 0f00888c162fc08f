// Fuzz harness: legacy VTK files (.vtk, STRUCTURED_POINTS with binary or ASCII point data). Both
// the reader and volume_input_files() (the command's input list) are run.
#include <cstdint>
#include <string_view>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text = progiso::fuzz::as_text(data, size);
  progiso::fuzz::read_volume_file(progiso::fuzz::write_file("v.vtk", text));
  return 0;
}
