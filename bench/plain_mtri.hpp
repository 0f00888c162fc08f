// bench/plain_mtri.hpp — the 2D baseline: plain marching triangles on the finest mesh of an image
// (unit squares cut by the all-even → all-odd diagonal), vertices deduplicated by edge key and
// segments chained into polylines — the same output as full progressive contouring.
#pragma once

#include <progiso/core/base/detail/flat_map.hpp>
#include <progiso/core/contour/contour.hpp>
#include <progiso/core/contour/contour_split.hpp>
#include <progiso/core/field/volume.hpp>

namespace progiso::bench {

template <class T>
contour_set plain_marching_triangles(const volume& img, const T* s, double w) {
  const std::int64_t nx = img.dims()[0], ny = img.dims()[1];
  contour_set out;
  detail::flat_map ids(1 << 12);
  std::vector<std::array<std::uint32_t, 2>> segs;
  const auto id_of = [&](std::uint64_t key) {
    const auto [id, inserted] =
        ids.try_emplace(key, static_cast<std::uint32_t>(out.vertices.size()));
    if (inserted) {
      const ipoint2 m = edge_key2_point(key);
      ipoint2 a{}, b{};
      const int odd = (m[0] & 1) + (m[1] & 1);
      for (std::size_t q = 0; q < 2; ++q) {
        if (m[q] & 1) {
          const std::int32_t lo = (m[q] - 1) / 2;
          const bool lo_even = (lo & 1) == 0;
          a[q] = odd == 1 || lo_even ? lo : lo + 1;
          b[q] = odd == 1 || lo_even ? lo + 1 : lo;
        } else {
          a[q] = b[q] = m[q] / 2;
        }
      }
      out.vertices.push_back(interpolate2(a, static_cast<double>(s[a[0] + nx * a[1]]), b,
                                          static_cast<double>(s[b[0] + nx * b[1]]), w));
    }
    return id;
  };
  for (std::int32_t y = 0; y + 1 < ny; ++y) {
    const T* row = s + nx * y;
    for (std::int32_t x = 0; x + 1 < nx; ++x) {
      const double f00 = static_cast<double>(row[x]), f10 = static_cast<double>(row[x + 1]);
      const double f01 = static_cast<double>(row[x + nx]),
                   f11 = static_cast<double>(row[x + nx + 1]);
      const unsigned mask =
          (f00 > w ? 1u : 0u) | (f10 > w ? 2u : 0u) | (f01 > w ? 4u : 0u) | (f11 > w ? 8u : 0u);
      if (mask == 0 || mask == 15) continue;
      const ipoint2 e{(x & 1) ? x + 1 : x, (y & 1) ? y + 1 : y};
      const ipoint2 o{(x & 1) ? x : x + 1, (y & 1) ? y : y + 1};
      const auto f = [&](const ipoint2& p) {
        return static_cast<double>(row[(p[0] - x) + nx * (p[1] - y) + x]);
      };
      for (const ipoint2& apex : {ipoint2{o[0], e[1]}, ipoint2{e[0], o[1]}}) {
        std::array<std::uint64_t, 2> k{};
        if (march_triangle({e, o, apex}, {f(e), f(o), f(apex)}, w, k)) {
          segs.push_back({id_of(k[0]), id_of(k[1])});
        }
      }
    }
  }
  const std::uint32_t none = ~std::uint32_t{0};
  std::vector<std::uint32_t> next(out.vertices.size(), none);
  std::vector<std::uint8_t> has_in(out.vertices.size(), 0), used(out.vertices.size(), 0);
  for (const auto& sg : segs) {
    next[sg[0]] = sg[1];
    has_in[sg[1]] = 1;
  }
  const auto walk = [&](std::uint32_t v, bool closed) {
    polyline pl;
    pl.closed = closed;
    pl.isovalue = w;
    while (v != none && !used[v]) {
      used[v] = 1;
      pl.vertices.push_back(v);
      v = next[v];
    }
    out.polylines.push_back(std::move(pl));
  };
  for (std::uint32_t v = 0; v < out.vertices.size(); ++v) {
    if (!has_in[v] && next[v] != none) walk(v, false);
  }
  for (std::uint32_t v = 0; v < out.vertices.size(); ++v) {
    if (!used[v] && next[v] != none) walk(v, true);
  }
  return out;
}

inline contour_set plain_marching_triangles(const volume& img, double w) {
  return img.visit_samples([&](const auto* s) { return plain_marching_triangles(img, s, w); });
}

}  // namespace progiso::bench
