// Fuzz harness: headerless raw volumes, through read_volume() with a raw layout. Built twice:
// as `raw` (reading only: millions of inputs per run) and, with PROGISO_FUZZ_EXTRACT, as
// `extract`, which also refines and extracts tiny volumes fully, by error and by budget (3D),
// or contours them (volumes one sample thick) at an isovalue taken from the input.
//
// Input layout: bytes 0..2 dims (1..24 each), byte 3 type (low 3 bits), byte order (bit 3), "make
// the size fit" (bit 4), byte 4 spacing selector, byte 5 isovalue selector, the rest the file.
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/contour/contour_refiner.hpp>
#include <progiso/core/refine/refiner.hpp>
#include <progiso/io/volume_io.hpp>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace progiso;
  if (size < 6) return 0;
  raw_layout layout;
  for (std::size_t a = 0; a < 3; ++a) layout.dims[a] = 1 + data[a] % 24;
  layout.type = static_cast<sample_type>(data[3] & 7u);
  layout.big_endian = (data[3] & 8u) != 0;
  std::string body(fuzz::as_text(data + 6, size - 6));
  if ((data[3] & 16u) != 0) {
    const auto want = static_cast<std::size_t>(layout.dims[0] * layout.dims[1] * layout.dims[2]) *
                      sample_size(layout.type);
    body.resize(want, '\x5a');
  }
  std::array<double, 3> spacing{1.0, 1.0, 1.0};
  if (data[4] >= 200 && body.size() >= 8) {
    double s = 0.0;
    std::memcpy(&s, body.data(), 8);  // any bit pattern: NaN, inf, subnormal, negative
    spacing[data[4] % 3] = s;
  } else {
    spacing[0] = 0.5 + data[4];
  }
#if defined(PROGISO_FUZZ_EXTRACT)
  if (layout.dims[2] == 1) {
    // Images (one sample thick; the raw reader wants 2 per axis): built directly, contoured.
    const auto want =
        static_cast<std::size_t>(layout.dims[0] * layout.dims[1]) * sample_size(layout.type);
    body.resize(want, '\x5a');
    std::vector<std::byte> bytes(want);
    std::memcpy(bytes.data(), body.data(), want);
    try {
      const volume img(layout.dims, layout.type, std::move(bytes));
      const auto [lo, hi] = img.value_range();
      const double w = lo + (hi - lo) * (data[5] / 255.0);
      contour_options o;
      // full, error, segments
      const refine_goal goals[] = {refine_goal::full(), refine_goal::error(data[5] * 0.5),
                                   refine_goal::segments(data[5])};
      o.goal = goals[data[5] % 3];
      (void)extract_contours(img, {w, w + 1.0}, o);
    } catch (const progiso::error&) {
    }
    return 0;
  }
#endif
  const auto file = fuzz::write_file("v.raw", body);
  try {
    const volume v = read_volume(file, layout, spacing);
#if defined(PROGISO_FUZZ_EXTRACT)
    const auto [lo, hi] = v.value_range();
    const double w = lo + (hi - lo) * (data[5] / 255.0);
    if (v.dims()[2] >= 2 && v.voxel_count() <= 4096) {
      extract_options o;
      // full, error, triangles
      const refine_goal goals[] = {refine_goal::full(), refine_goal::error(data[5] * 0.01),
                                   refine_goal::triangles(data[5])};
      o.goal = goals[data[5] % 3];
      const extract_result r = extract_isosurface(v, w, o);
      for (const auto& t : r.mesh.triangles) {
        for (const std::uint32_t i : t) {
          if (i >= r.mesh.vertices.size()) __builtin_trap();
        }
      }
    }
#else
    (void)v.value_range();
#endif
  } catch (const progiso::error&) {
  }
  return 0;
}
