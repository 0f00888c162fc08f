#include <progiso/core/surface/marching.hpp>

#include <utility>

namespace progiso {

namespace {

// Orients triangle (k0, k1, k2) of doubled midpoints so its normal points from `black` to
// `white` (ends of one crossed edge of the tetrahedron). Exact in 64-bit integers for grids
// below 2^16 per axis.
void orient(std::array<std::uint64_t, 3>& tri, const ipoint& black, const ipoint& white) noexcept {
  const ipoint m0 = edge_key_point(tri[0]);
  const ipoint m1 = edge_key_point(tri[1]);
  const ipoint m2 = edge_key_point(tri[2]);
  const std::int64_t u0 = m1[0] - m0[0], u1 = m1[1] - m0[1], u2 = m1[2] - m0[2];
  const std::int64_t v0 = m2[0] - m0[0], v1 = m2[1] - m0[1], v2 = m2[2] - m0[2];
  const std::int64_t n0 = u1 * v2 - u2 * v1;
  const std::int64_t n1 = u2 * v0 - u0 * v2;
  const std::int64_t n2 = u0 * v1 - u1 * v0;
  const std::int64_t dot =
      n0 * (white[0] - black[0]) + n1 * (white[1] - black[1]) + n2 * (white[2] - black[2]);
  if (dot < 0) std::swap(tri[1], tri[2]);
}

}  // namespace

tet_surface march_tet(const std::array<ipoint, 4>& p, const std::array<double, 4>& f,
                      double isovalue) noexcept {
  tet_surface s;
  int blacks[4];
  int whites[4];
  int nb = 0;
  int nw = 0;
  for (int i = 0; i < 4; ++i) {
    if (f[static_cast<std::size_t>(i)] > isovalue) {
      blacks[nb++] = i;
    } else {
      whites[nw++] = i;
    }
  }
  if (nb == 0 || nw == 0) return s;
  const auto P = [&](int i) -> const ipoint& { return p[static_cast<std::size_t>(i)]; };
  const auto key = [&](int i, int j) { return edge_key(P(i), P(j)); };
  if (nb == 1 || nw == 1) {
    const int lone = nb == 1 ? blacks[0] : whites[0];
    const int* others = nb == 1 ? whites : blacks;
    s.triangles[0] = {key(lone, others[0]), key(lone, others[1]), key(lone, others[2])};
    s.count = 1;
  } else {
    const int b1 = blacks[0], b2 = blacks[1], w1 = whites[0], w2 = whites[1];
    const std::array<std::uint64_t, 4> q{key(b1, w1), key(b1, w2), key(b2, w2), key(b2, w1)};
    int smallest = 0;
    for (int i = 1; i < 4; ++i) {
      if (q[static_cast<std::size_t>(i)] < q[static_cast<std::size_t>(smallest)]) smallest = i;
    }
    if (smallest == 0 || smallest == 2) {
      s.triangles[0] = {q[0], q[1], q[2]};
      s.triangles[1] = {q[0], q[2], q[3]};
    } else {
      s.triangles[0] = {q[1], q[2], q[3]};
      s.triangles[1] = {q[1], q[3], q[0]};
    }
    s.count = 2;
  }
  for (int t = 0; t < s.count; ++t) {
    orient(s.triangles[static_cast<std::size_t>(t)], P(blacks[0]), P(whites[0]));
  }
  return s;
}

}  // namespace progiso
