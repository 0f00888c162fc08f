// Fuzz harness: DICOM series (a directory of slice files).
//
// Input layout: the input is cut at every separator "\0NEXT\0" into the files s0, s1, … (at most
// 8) of a fresh directory, which is read as a series; then s0 alone, as a single input file is
// (recognised by its preamble, having no extension: an enhanced multi-frame image). The series
// is read again as volume 1 (a series of time points). Both the reader and volume_input_files()
// (the command's input list) are run.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text = progiso::fuzz::as_text(data, size);
  constexpr std::string_view separator("\0NEXT\0", 6);
  const std::filesystem::path dir = progiso::fuzz::scratch() / "series";
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
  std::filesystem::create_directory(dir, ec);
  std::size_t start = 0;
  for (int k = 0; k < 8; ++k) {
    const std::size_t cut = text.find(separator, start);
    const std::string_view part =
        text.substr(start, cut == std::string_view::npos ? std::string_view::npos : cut - start);
    (void)progiso::fuzz::write_file("series/s" + std::to_string(k), part);
    if (cut == std::string_view::npos) break;
    start = cut + separator.size();
  }
  progiso::fuzz::read_volume_file(dir);
  progiso::fuzz::read_volume_file(dir, {std::nullopt, 1});
  progiso::fuzz::read_volume_file(dir / "s0");
  return 0;
}
