// Fuzz harness: the hierarchy stream reader (read_hierarchy_stream()) and every cut of what it
// accepts: a stream it accepts must give valid meshes (indices in range) by every selection.
#include <cstdint>

#include <progiso/core/base/error.hpp>
#include <progiso/io/hierarchy_io.hpp>

#include "fuzz_support.hpp"

namespace {

void check(const progiso::triangle_mesh& m) {
  for (const auto& t : m.triangles) {
    for (const std::uint32_t v : t) {
      if (v >= m.vertices.size()) __builtin_trap();  // a cut's indices are in range
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace progiso;
  const auto file = fuzz::write_file("h.pgh", fuzz::as_text(data, size));
  try {
    const hierarchy_stream h = read_hierarchy_stream(file);
    check(h.mesh(h.all()));
    check(h.mesh(h.by_error(h.records() > 0 ? h.error_of(1) / 2 : 0.0)));
    check(h.mesh(h.by_triangles(h.triangle_count(h.all()) / 2)));
    const ipoint& g = h.grid().grid_max();
    check(h.mesh(h.in_box({0, 0, 0}, {g[0] / 3.0, g[1] / 2.0, g[2] / 3.0})));
    if (h.records() > 2) {
      const hierarchy_stream p = read_hierarchy_stream(file, h.records() / 2);
      check(p.mesh(p.all()));
    }
  } catch (const progiso::error&) {
  }
  return 0;
}
