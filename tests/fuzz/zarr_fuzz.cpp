// Fuzz harness: Zarr arrays (a directory z.zarr holding .zarray and chunk files).
//
// Input layout: what comes before the separator "\0DATA\0" is z.zarr/.zarray and what follows is
// written as each of the chunk files 0.0.0 and 0.1.0 that seeds name; otherwise the whole input
// is the .zarray and no chunk exists. volume_input_files(), the reader and a plane window over the
// level are run.
#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string_view>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace fs = std::filesystem;
  const fs::path dir = progiso::fuzz::scratch() / "z.zarr";
  std::error_code ec;
  fs::remove_all(dir, ec);
  fs::create_directories(dir, ec);
  (void)progiso::fuzz::write_header_and_data(progiso::fuzz::as_text(data, size), "z.zarr/.zarray",
                                             "z.zarr/.zarray", {"z.zarr/0.0.0", "z.zarr/0.1.0"});
  progiso::fuzz::read_volume_file(dir);
  // The same level through a window of planes (what --full and MPI ranks read): held forward
  // three planes at a time, then from the start again.
  try {
    progiso::volume_source source(dir, std::nullopt);
    if (std::optional<progiso::plane_window> w = source.window()) {
      const std::int64_t nz = w->field().dims()[2];
      for (std::int64_t z = 0; z < nz; z += 3) w->hold(z, std::min<std::int64_t>(nz, z + 3));
      w->hold(0, std::min<std::int64_t>(nz, 2));
    }
  } catch (const progiso::error&) {
  }
  return 0;
}
