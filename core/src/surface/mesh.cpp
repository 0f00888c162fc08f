#include <progiso/core/surface/mesh.hpp>

#include <cstring>

namespace progiso {

void fill_render_buffers(const triangle_mesh& m, render_buffers& out) {
  // resize() within capacity keeps the storage: no allocation once the buffers are large enough.
  out.positions.resize(3 * m.vertices.size());
  float* p = out.positions.data();
  for (const vec3& v : m.vertices) {
    *p++ = static_cast<float>(v[0]);
    *p++ = static_cast<float>(v[1]);
    *p++ = static_cast<float>(v[2]);
  }
  out.normals.resize(3 * m.normals.size());
  float* n = out.normals.data();
  for (const vec3& v : m.normals) {
    *n++ = static_cast<float>(v[0]);
    *n++ = static_cast<float>(v[1]);
    *n++ = static_cast<float>(v[2]);
  }
  static_assert(sizeof(std::array<std::uint32_t, 3>) == 3 * sizeof(std::uint32_t));
  out.indices.resize(3 * m.triangles.size());
  if (!m.triangles.empty()) {
    std::memcpy(out.indices.data(), m.triangles.data(),
                m.triangles.size() * sizeof(std::array<std::uint32_t, 3>));
  }
}

}  // namespace progiso
