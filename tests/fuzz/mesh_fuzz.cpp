// Fuzz harness: the mesh and contour readers, read_ply() and read_contour_obj() (chosen by the
// build: PROGISO_FUZZ_READER is "ply" or "obj").
#include <cstdint>

#include <progiso/core/base/error.hpp>
#include <progiso/io/contour_io.hpp>
#include <progiso/io/mesh_io.hpp>

#include "fuzz_support.hpp"

#ifndef PROGISO_FUZZ_READER
#error "define PROGISO_FUZZ_READER as \"ply\" or \"obj\""
#endif

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace progiso;
  const std::string_view reader = PROGISO_FUZZ_READER;
  const auto file =
      fuzz::write_file(std::string("m.") + PROGISO_FUZZ_READER, fuzz::as_text(data, size));
  try {
    if (reader == "ply") {
      const triangle_mesh m = read_ply(file);
      for (const auto& t : m.triangles) {
        for (const std::uint32_t v : t) {
          if (v >= m.vertices.size()) __builtin_trap();  // the reader promises valid indices
        }
      }
    } else {
      const contour_set c = read_contour_obj(file);
      for (const auto& p : c.polylines) {
        for (const std::uint32_t v : p.vertices) {
          if (v >= c.vertices.size()) __builtin_trap();
        }
      }
    }
  } catch (const progiso::error&) {
  }
  return 0;
}
