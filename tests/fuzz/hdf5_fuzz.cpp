// Fuzz harness: Imaris and BigDataViewer HDF5 files (libhdf5 parses them; progiso checks what it
// is given). The whole input is the file; volume 0 is read at level 0 and at level 1.
#include <cstdint>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::filesystem::path file =
      progiso::fuzz::write_file("f.h5", progiso::fuzz::as_text(data, size));
  progiso::fuzz::read_volume_file(file, progiso::volume_choice{{}, 0, {}});
  progiso::fuzz::read_volume_file(file, progiso::volume_choice{{}, 0, 1});
  return 0;
}
