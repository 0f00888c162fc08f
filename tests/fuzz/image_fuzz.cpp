// Fuzz harness: 2D images, PGM or PNG (chosen by the build: PROGISO_FUZZ_IMAGE_FORMAT). The
// contouring of what they hold is fuzzed by the `extract` harness (raw_fuzz.cpp).
#include <cstdint>

#include <progiso/core/base/error.hpp>
#include <progiso/io/image_io.hpp>

#include "fuzz_support.hpp"

#ifndef PROGISO_FUZZ_IMAGE_FORMAT
#error "define PROGISO_FUZZ_IMAGE_FORMAT as \"pgm\" or \"png\""
#endif

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace progiso;
  const auto file =
      fuzz::write_file(std::string("i.") + PROGISO_FUZZ_IMAGE_FORMAT, fuzz::as_text(data, size));
  try {
    const volume img = read_image(file);
    (void)img.value_range();
  } catch (const progiso::error&) {
  }
  return 0;
}
