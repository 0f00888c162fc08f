#include <progiso/core/surface/detail/mesh_clip.hpp>

#include <algorithm>
#include <atomic>
#include <bit>
#include <utility>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/surface/marching.hpp>

namespace progiso::detail {

// Every vertex is used (in order of first use) unless clipping left one of its triangles' inside
// corners out (a corner on the box's face with the rest of the piece beyond it) and no other
// triangle uses it: then the unused ones are dropped.
void drop_unused(triangle_mesh& m, const std::vector<std::uint32_t>& suspects,
                 const parallel_loop& run, std::size_t parts) {
  if (suspects.empty()) return;
  const std::size_t count = m.vertices.size();
  {
    // The suspects marked, then each mark a triangle meets cleared: a byte read per corner,
    // written only at suspects (a bit vector of all vertices set for every corner cost a
    // read-modify-write per corner, and ran on one thread).
    std::vector<std::uint8_t> unused(count, 0);
    for (const std::uint32_t v : suspects) unused[v] = 1;
    const std::size_t n = m.triangles.size();
    parts = std::clamp<std::size_t>(parts, 1, std::max<std::size_t>(n, 1));
    run_loop(run, parts, [&](std::size_t k) {
      for (std::uint64_t i = piece_begin(n, parts, k); i < piece_begin(n, parts, k + 1); ++i) {
        for (const std::uint32_t v : m.triangles[i]) {
          const std::atomic_ref<std::uint8_t> mark(unused[v]);
          // relaxed: the parallel loop's join orders these stores before the check below.
          if (mark.load(std::memory_order_relaxed) != 0) mark.store(0, std::memory_order_relaxed);
        }
      }
    });
    if (std::none_of(suspects.begin(), suspects.end(),
                     [&unused](std::uint32_t v) { return unused[v] != 0; })) {
      return;
    }
  }
  std::vector<std::uint32_t> remap(count, ~std::uint32_t{0});
  std::uint32_t n = 0;
  for (auto& t : m.triangles) {
    for (auto& v : t) {
      if (remap[v] == ~std::uint32_t{0}) remap[v] = n++;
      v = remap[v];
    }
  }
  if (n != count) {
    std::vector<vec3> kept(n);
    for (std::size_t i = 0; i < count; ++i) {
      if (remap[i] != ~std::uint32_t{0}) kept[remap[i]] = m.vertices[i];
    }
    m.vertices = std::move(kept);
  } else {
    std::vector<vec3> ordered(n);
    for (std::size_t i = 0; i < count; ++i) ordered[remap[i]] = m.vertices[i];
    m.vertices = std::move(ordered);
  }
}

std::size_t position_hash::operator()(const vec3& p) const noexcept {
  std::uint64_t h = 0;
  for (const double v : p) {
    // + 0.0 makes -0.0 hash as 0.0 (they compare equal).
    h = (h ^ std::bit_cast<std::uint64_t>(v + 0.0)) * 0x9E3779B97F4A7C15ULL;
  }
  return static_cast<std::size_t>(h ^ (h >> 29));
}

}  // namespace progiso::detail
