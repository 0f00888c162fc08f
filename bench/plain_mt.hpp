// bench/plain_mt.hpp — the baseline: plain (non-progressive) marching tetrahedra on the finest
// mesh, written for speed: typed samples, a uniform-cell early exit, vertices deduplicated by
// edge key. It produces the same surface as the progressive full-resolution extraction and is
// what the benchmarks compare against, in the same binary.
#pragma once

#include <progiso/core/base/detail/flat_map.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>
#include <progiso/core/surface/marching.hpp>
#include <progiso/core/surface/mesh.hpp>

namespace progiso::bench {

template <class T>
triangle_mesh plain_marching_tetrahedra(const volume& v, const T* s, double w) {
  const auto d = v.dims();
  triangle_mesh mesh;
  detail::flat_map ids(1 << 16);
  const auto id_of = [&](std::uint64_t key) {
    const auto [id, inserted] =
        ids.try_emplace(key, static_cast<std::uint32_t>(mesh.vertices.size()));
    if (inserted) {
      const ipoint m = edge_key_point(key);
      // Ends of a finest edge from its doubled midpoint (the all-even/all-odd diagonal rule).
      ipoint a{}, b{};
      int odd = 0;
      for (std::size_t q = 0; q < 3; ++q) odd += m[q] & 1;
      for (std::size_t q = 0; q < 3; ++q) {
        if (m[q] & 1) {
          const std::int32_t lo = (m[q] - 1) / 2;
          const bool lo_even = (lo & 1) == 0;
          a[q] = odd == 1 || lo_even ? lo : lo + 1;
          b[q] = odd == 1 || lo_even ? lo + 1 : lo;
        } else {
          a[q] = b[q] = m[q] / 2;
        }
      }
      const vec3 p = interpolate(a, v.value(a[0], a[1], a[2]), b, v.value(b[0], b[1], b[2]), w);
      const auto& sp = v.spacing();
      const auto& o = v.origin();
      mesh.vertices.push_back({o[0] + p[0] * sp[0], o[1] + p[1] * sp[1], o[2] + p[2] * sp[2]});
    }
    return id;
  };
  const std::int64_t sx = 1, sy = d[0], sz = d[0] * d[1];
  for (std::int32_t z = 0; z + 1 < d[2]; ++z) {
    for (std::int32_t y = 0; y + 1 < d[1]; ++y) {
      const T* row = s + y * sy + z * sz;
      for (std::int32_t x = 0; x + 1 < d[0]; ++x) {
        const T* c = row + x;
        const std::array<double, 8> f{
            static_cast<double>(c[0]),       static_cast<double>(c[sx]),
            static_cast<double>(c[sy]),      static_cast<double>(c[sx + sy]),
            static_cast<double>(c[sz]),      static_cast<double>(c[sx + sz]),
            static_cast<double>(c[sy + sz]), static_cast<double>(c[sx + sy + sz])};
        unsigned mask = 0;
        for (unsigned i = 0; i < 8; ++i) mask |= (f[i] > w ? 1u : 0u) << i;
        if (mask == 0 || mask == 0xFF) continue;
        const auto corner = [&](const ipoint& p) {
          return f[static_cast<std::size_t>((p[0] - x) + 2 * (p[1] - y) + 4 * (p[2] - z))];
        };
        for (const std::array<ipoint, 4>& t : cube_tetrahedra({x, y, z}, 1)) {
          std::array<double, 4> tf{};
          for (std::size_t k = 0; k < 4; ++k) tf[k] = corner(t[k]);
          const tet_surface ts = march_tet(t, tf, w);
          for (int k = 0; k < ts.count; ++k) {
            const auto& tri = ts.triangles[static_cast<std::size_t>(k)];
            mesh.triangles.push_back({id_of(tri[0]), id_of(tri[1]), id_of(tri[2])});
          }
        }
      }
    }
  }
  return mesh;
}

inline triangle_mesh plain_marching_tetrahedra(const volume& v, double w) {
  return v.visit_samples([&](const auto* s) { return plain_marching_tetrahedra(v, s, w); });
}

}  // namespace progiso::bench
