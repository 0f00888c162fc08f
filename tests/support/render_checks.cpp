#include "support/render_checks.hpp"

#include <algorithm>
#include <cstring>
#include <span>
#include <vector>

namespace progiso::test {

std::map<float_corners, int> slot_triangles(const render_slots& s, bool normals) {
  std::map<float_corners, int> out;
  const std::span<const float> src = normals ? s.normals() : s.positions();
  for (std::size_t slot = 0; slot < s.slot_count(); ++slot) {
    if (s.id_of(slot) == render_slots::free_slot) continue;
    float_corners c{};
    std::copy_n(src.data() + 9 * slot, 9, c.data());
    ++out[c];
  }
  return out;
}

std::map<float_corners, int> buffer_triangles(const render_buffers& b, bool normals) {
  std::map<float_corners, int> out;
  const std::vector<float>& src = normals ? b.normals : b.positions;
  for (std::size_t t = 0; t < b.triangle_count(); ++t) {
    float_corners c{};
    for (std::size_t v = 0; v < 3; ++v) {
      for (std::size_t k = 0; k < 3; ++k) c[3 * v + k] = src[3 * b.indices[3 * t + v] + k];
    }
    ++out[c];
  }
  return out;
}

bool same_bytes(const triangle_mesh& a, const triangle_mesh& b) {
  // memcmp is not given the null pointers of empty meshes.
  return a.vertices.size() == b.vertices.size() && a.triangles.size() == b.triangles.size() &&
         (a.vertices.empty() || std::memcmp(a.vertices.data(), b.vertices.data(),
                                            a.vertices.size() * sizeof(vec3)) == 0) &&
         (a.triangles.empty() || std::memcmp(a.triangles.data(), b.triangles.data(),
                                             a.triangles.size() * sizeof(a.triangles[0])) == 0);
}

}  // namespace progiso::test
