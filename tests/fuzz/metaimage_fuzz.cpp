// Fuzz harness: MetaImage files, with the data after the header (.mha) or in data files (.mhd).
//
// Input layout: when the input holds the separator "\0DATA\0", what comes before it is a header
// (v.mhd) and what follows is written as each of the data files d.raw, d1.raw, d2.raw and d3.raw
// that seeds' headers name (one file, a LIST, a pattern d%d.raw); otherwise the whole input is
// v.mha. Both the reader and volume_input_files() (the command's input list) are run.
#include <cstdint>
#include <string_view>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text = progiso::fuzz::as_text(data, size);
  constexpr std::string_view separator("\0DATA\0", 6);
  const std::size_t cut = text.find(separator);
  std::filesystem::path file;
  if (cut == std::string_view::npos) {
    file = progiso::fuzz::write_file("v.mha", text);
  } else {
    const std::string_view payload = text.substr(cut + separator.size());
    for (const char* name : {"d.raw", "d1.raw", "d2.raw", "d3.raw"}) {
      progiso::fuzz::write_file(name, payload);
    }
    file = progiso::fuzz::write_file("v.mhd", text.substr(0, cut));
  }
  progiso::fuzz::read_volume_file(file);
  return 0;
}
