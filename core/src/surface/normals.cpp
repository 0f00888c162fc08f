#include <progiso/core/surface/normals.hpp>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/field/detail/subdivision.hpp>

namespace progiso {

namespace {

// Vertices per piece of the parallel loop.
constexpr std::size_t piece_vertices = 16384;

// The grid of a field in index space: sizes, strides and the map from physical positions.
struct grid_frame {
  index3 dims{};
  std::array<std::int64_t, 3> stride{};
  vec3 origin{};
  vec3 inverse_spacing{};

  explicit grid_frame(const volume& v) : dims(v.dims()), origin(v.origin()) {
    stride = {1, dims[0], dims[0] * dims[1]};
    for (std::size_t a = 0; a < 3; ++a) inverse_spacing[a] = 1.0 / v.spacing()[a];
  }
};

// The gradient of central differences at grid point g (linear index at), in index units: one
// sided on the box's faces, 0 along an axis one sample thick.
template <class Samples>
vec3 grid_gradient(const Samples& s, const grid_frame& f, const index3& g, std::int64_t at) {
  vec3 d{};
  for (std::size_t a = 0; a < 3; ++a) {
    const std::int64_t n = f.dims[a];
    if (n < 2) continue;
    const std::int64_t st = f.stride[a];
    if (g[a] == 0) {
      d[a] = static_cast<double>(s[at + st]) - static_cast<double>(s[at]);
    } else if (g[a] == n - 1) {
      d[a] = static_cast<double>(s[at]) - static_cast<double>(s[at - st]);
    } else {
      d[a] = 0.5 * (static_cast<double>(s[at + st]) - static_cast<double>(s[at - st]));
    }
  }
  return d;
}

// −(the gradient at physical position p) in physical units, unnormalised.
template <class Samples>
vec3 descent_at(const Samples& s, const grid_frame& f, const vec3& p) {
  index3 cell{};
  vec3 t{};
  for (std::size_t a = 0; a < 3; ++a) {
    const std::int64_t n = f.dims[a];
    if (n < 2) continue;  // cell 0, weight 1 on the one layer
    const double q =
        std::clamp((p[a] - f.origin[a]) * f.inverse_spacing[a], 0.0, static_cast<double>(n - 1));
    const std::int64_t c = std::min(static_cast<std::int64_t>(q), n - 2);
    cell[a] = c;
    t[a] = q - static_cast<double>(c);
  }
  vec3 g{};
  const bool interior = cell[0] >= 1 && cell[0] + 2 < f.dims[0] && cell[1] >= 1 &&
                        cell[1] + 2 < f.dims[1] && cell[2] >= 1 && cell[2] + 2 < f.dims[2];
  if (interior) {
    // Every corner's six neighbours lie in the box: central differences throughout, halved and
    // divided by the spacing once at the end.
    const std::array<double, 2> wx{1.0 - t[0], t[0]};
    const std::array<double, 2> wy{1.0 - t[1], t[1]};
    const std::array<double, 2> wz{1.0 - t[2], t[2]};
    const std::int64_t sy = f.stride[1];
    const std::int64_t sz = f.stride[2];
    const std::int64_t base = cell[0] + sy * cell[1] + sz * cell[2];
    // Corners of weight 0 (the vertex on the cell's face or edge, as every vertex of the finest
    // cut is) add only a zero: they are left out, which changes at most the sign of a zero.
    unsigned live = 0xFFu;
    if (t[0] == 0.0) live &= 0x55u;
    if (t[1] == 0.0) live &= 0x33u;
    if (t[2] == 0.0) live &= 0x0Fu;
    for (; live != 0; live &= live - 1) {
      const auto corner = static_cast<std::size_t>(std::countr_zero(live));
      const std::size_t bx = corner & 1u;
      const std::size_t by = (corner >> 1) & 1u;
      const std::size_t bz = corner >> 2;
      const double weight = wx[bx] * wy[by] * wz[bz];
      const std::int64_t at = base + static_cast<std::int64_t>(bx) +
                              sy * static_cast<std::int64_t>(by) +
                              sz * static_cast<std::int64_t>(bz);
      g[0] += weight * (static_cast<double>(s[at + 1]) - static_cast<double>(s[at - 1]));
      g[1] += weight * (static_cast<double>(s[at + sy]) - static_cast<double>(s[at - sy]));
      g[2] += weight * (static_cast<double>(s[at + sz]) - static_cast<double>(s[at - sz]));
    }
    for (std::size_t a = 0; a < 3; ++a) g[a] *= -0.5 * f.inverse_spacing[a];
    return g;
  }
  for (int corner = 0; corner < 8; ++corner) {
    double weight = 1.0;
    index3 at = cell;
    for (std::size_t a = 0; a < 3; ++a) {
      const bool high = ((corner >> a) & 1) != 0;
      if (high) {
        if (f.dims[a] < 2) weight = 0.0;
        weight *= t[a];
        ++at[a];
      } else {
        weight *= 1.0 - t[a];
      }
    }
    if (weight == 0.0) continue;
    const std::int64_t linear = at[0] + f.stride[1] * at[1] + f.stride[2] * at[2];
    const vec3 d = grid_gradient(s, f, at, linear);
    for (std::size_t a = 0; a < 3; ++a) g[a] += weight * d[a];
  }
  for (std::size_t a = 0; a < 3; ++a) g[a] = -g[a] * f.inverse_spacing[a];
  return g;
}

// v / |v|; false when v has no direction. Scaled first, so that gradients of samples near the
// double range do not overflow when squared (the pass takes the plain square first and comes
// here only when it overflows or underflows).
bool normalise(vec3& v) {
  const double m = std::max({std::fabs(v[0]), std::fabs(v[1]), std::fabs(v[2])});
  if (!(m > 0.0) || !std::isfinite(m)) return false;
  const vec3 u{v[0] / m, v[1] / m, v[2] / m};
  const double len = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
  v = {u[0] / len, u[1] / len, u[2] / len};
  return true;
}

// Normals of the vertices in `flat` (sorted) from their triangles: the sum of the area-weighted
// right-hand normals, each triangle's scaled to its largest component first; one per entry.
template <class P>
vec3 as_vec3(const P& p) {
  return {static_cast<double>(p[0]), static_cast<double>(p[1]), static_cast<double>(p[2])};
}

// Adds, in triangle order, each triangle's area-weighted normal to sum[k] of its corners in
// `flat` (slot k), and its unit normal, when it has one, to any[k].
template <class P>
void accumulate_triangles(std::span<const P> vertices,
                          std::span<const std::array<std::uint32_t, 3>> triangles,
                          const std::vector<std::uint32_t>& flat, std::vector<vec3>& sum,
                          std::vector<vec3>& any) {
  constexpr std::uint32_t none = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> slot(vertices.size(), none);
  for (std::size_t k = 0; k < flat.size(); ++k) slot[flat[k]] = static_cast<std::uint32_t>(k);
  for (const auto& tri : triangles) {
    if (slot[tri[0]] == none && slot[tri[1]] == none && slot[tri[2]] == none) continue;
    const vec3 n = area_normal(as_vec3(vertices[tri[0]]), as_vec3(vertices[tri[1]]),
                               as_vec3(vertices[tri[2]]));
    for (const std::uint32_t corner : tri) {
      const std::uint32_t k = slot[corner];
      if (k == none) continue;
      for (std::size_t i = 0; i < 3; ++i) sum[k][i] += n[i];
      vec3 unit = n;
      if (normalise(unit)) any[k] = unit;
    }
  }
}

// The unit normal of accumulated sums: the sum's direction, else the last unit normal.
vec3 finish_sum(vec3 sum, const vec3& any) { return normalise(sum) ? sum : any; }

template <class P>
std::vector<vec3> normals_from_triangles(std::span<const P> vertices,
                                         std::span<const std::array<std::uint32_t, 3>> triangles,
                                         const std::vector<std::uint32_t>& flat) {
  std::vector<vec3> sum(flat.size(), vec3{});
  std::vector<vec3> any(flat.size(), vec3{});  // one triangle's unit normal, if the sum cancels
  accumulate_triangles(vertices, triangles, flat, sum, any);
  for (std::size_t k = 0; k < flat.size(); ++k) sum[k] = finish_sum(sum[k], any[k]);
  return sum;
}

// The pass of add_vertex_normals() and vertex_normals_into(): put(i, unit normal, descent) for
// every vertex i whose gradient has a direction, then put(i, normal from its triangles, {}) for
// the others (descent: −∇f at the vertex in physical units, unnormalised).
// With `vanished`, the vertices whose gradient vanished go there (ascending) instead of being
// given their triangles' normals.
template <class P, class Put>
void normals_pass(std::span<const P> vertices,
                  std::span<const std::array<std::uint32_t, 3>> triangles, const volume& field,
                  const parallel_loop& run, const Put& put,
                  std::vector<std::uint32_t>* vanished = nullptr) {
  const std::size_t count = vertices.size();
  if (count == 0) return;
  const grid_frame frame(field);
  const std::size_t pieces = (count + piece_vertices - 1) / piece_vertices;
  std::vector<std::vector<std::uint32_t>> flat(pieces);  // per piece: gradients that vanished
  detail::visit_field(field, [&](const auto& samples) {
    run_loop(run, pieces, [&](std::size_t k) {
      const std::size_t begin = k * piece_vertices;
      const std::size_t end = std::min(count, (k + 1) * piece_vertices);
      // The gradients first, then their lengths in a loop of their own: a square root and a
      // division per vertex, independent from one vertex to the next, overlap there, where
      // behind each vertex's sample loads they took a large part of the pass. In runs of a
      // stack buffer's size: a heap buffer per piece was mapped and unmapped each time, and
      // the page faults of the threads' pieces queued on the address space's lock.
      constexpr std::size_t batch = 256;
      std::array<vec3, batch> descent;
      for (std::size_t from = begin; from < end; from += batch) {
        const std::size_t to = std::min(end, from + batch);
        for (std::size_t i = from; i < to; ++i) {
          descent[i - from] = descent_at(samples, frame, as_vec3(vertices[i]));
        }
        for (std::size_t i = from; i < to; ++i) {
          vec3 n = descent[i - from];
          const double len2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
          const bool plain = len2 >= std::numeric_limits<double>::min() &&
                             len2 <= std::numeric_limits<double>::max();
          const double inverse = plain ? 1.0 / std::sqrt(len2) : 1.0;
          n = {n[0] * inverse, n[1] * inverse, n[2] * inverse};
          if (!plain && !normalise(n)) {
            flat[k].push_back(static_cast<std::uint32_t>(i));
          } else {
            put(i, n, descent[i - from]);
          }
        }
      }
    });
  });
  std::vector<std::uint32_t> all;
  for (const auto& f : flat) all.insert(all.end(), f.begin(), f.end());
  if (vanished != nullptr) {
    *vanished = std::move(all);
    return;
  }
  if (all.empty()) return;
  const std::vector<vec3> n = normals_from_triangles(vertices, triangles, all);
  for (std::size_t k = 0; k < all.size(); ++k) put(all[k], n[k], vec3{});
}

}  // namespace

void add_vertex_normals(triangle_mesh& mesh, const volume& field, const parallel_loop& run) {
  mesh.normals.assign(mesh.vertices.size(), vec3{});
  normals_pass(std::span<const vec3>(mesh.vertices), std::span(mesh.triangles), field, run,
               [&](std::size_t i, const vec3& n, const vec3&) { mesh.normals[i] = n; });
}

std::vector<detail::normal_partial> detail::add_share_normals(
    triangle_mesh& mesh, std::span<const std::uint64_t> global, const volume& field,
    std::span<const normal_partial> carried, const std::function<bool(std::uint64_t)>& last,
    const parallel_loop& run) {
  PROGISO_ASSERT(global.size() == mesh.vertices.size());
  mesh.normals.assign(mesh.vertices.size(), vec3{});
  std::vector<std::uint32_t> flat;
  normals_pass(
      std::span<const vec3>(mesh.vertices), std::span(mesh.triangles), field, run,
      [&](std::size_t i, const vec3& n, const vec3&) { mesh.normals[i] = n; }, &flat);
  // The vanished vertices' sums start from what earlier shares' triangles gave them.
  std::vector<vec3> sum(flat.size(), vec3{}), any(flat.size(), vec3{});
  std::vector<bool> used(carried.size(), false);
  for (std::size_t k = 0; k < flat.size(); ++k) {
    const std::uint64_t id = global[flat[k]];
    const auto it =
        std::lower_bound(carried.begin(), carried.end(), id,
                         [](const normal_partial& p, std::uint64_t v) { return p.vertex < v; });
    if (it != carried.end() && it->vertex == id) {
      sum[k] = it->sum;
      any[k] = it->any;
      used[static_cast<std::size_t>(it - carried.begin())] = true;
    }
  }
  accumulate_triangles(std::span<const vec3>(mesh.vertices), std::span(mesh.triangles), flat, sum,
                       any);
  std::vector<normal_partial> out;
  for (std::size_t k = 0; k < flat.size(); ++k) {
    const std::uint64_t id = global[flat[k]];
    if (last(id)) {
      mesh.normals[flat[k]] = finish_sum(sum[k], any[k]);
    } else {
      out.push_back({id, sum[k], any[k]});
    }
  }
  for (std::size_t c = 0; c < carried.size(); ++c) {
    if (!used[c] && !last(carried[c].vertex)) out.push_back(carried[c]);
  }
  std::sort(out.begin(), out.end(),
            [](const normal_partial& a, const normal_partial& b) { return a.vertex < b.vertex; });
  return out;
}

namespace {

template <class P>
void normals_into(std::span<const P> vertices,
                  std::span<const std::array<std::uint32_t, 3>> triangles, const volume& field,
                  float* normals, float* gradient_l1, const parallel_loop& run) {
  const std::array<double, 3>& spacing = field.spacing();
  normals_pass(vertices, triangles, field, run,
               [&](std::size_t i, const vec3& n, const vec3& descent) {
                 for (std::size_t a = 0; a < 3; ++a) {
                   normals[3 * i + a] = static_cast<float>(n[a]);
                 }
                 if (gradient_l1 != nullptr) {
                   // Back to index units: the pass divided each component by its spacing.
                   gradient_l1[i] = static_cast<float>(std::fabs(descent[0]) * spacing[0] +
                                                       std::fabs(descent[1]) * spacing[1] +
                                                       std::fabs(descent[2]) * spacing[2]);
                 }
               });
}

}  // namespace

void vertex_normals_into(std::span<const vec3> vertices,
                         std::span<const std::array<std::uint32_t, 3>> triangles,
                         const volume& field, float* normals, float* gradient_l1,
                         const parallel_loop& run) {
  normals_into(vertices, triangles, field, normals, gradient_l1, run);
}

void vertex_normals_into(std::span<const std::array<float, 3>> vertices,
                         std::span<const std::array<std::uint32_t, 3>> triangles,
                         const volume& field, float* normals, float* gradient_l1,
                         const parallel_loop& run) {
  normals_into(vertices, triangles, field, normals, gradient_l1, run);
}

}  // namespace progiso
