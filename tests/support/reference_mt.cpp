#include <support/reference_mt.hpp>

#include <array>
#include <cmath>
#include <tuple>
#include <unordered_map>
#include <utility>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/error.hpp>

namespace progiso::test {
namespace {

using point = std::array<std::int64_t, 3>;
using tet = std::array<point, 4>;

// The 6 orders in which a path from the all-even corner to the all-odd corner of a unit cube
// can take its three axis steps; each order is one tetrahedron of the finest mesh.
constexpr std::array<std::array<std::size_t, 3>, 6> axis_orders{
    {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}}};

// The 6 tetrahedra of the unit cube with min corner b: e is the corner whose coordinates are
// all even, s the step from e toward the opposite (all-odd) corner on each axis.
std::array<tet, 6> cell_tetrahedra(const point& b) {
  point e{};
  point s{};
  for (std::size_t q = 0; q < 3; ++q) {
    e[q] = b[q] % 2 == 0 ? b[q] : b[q] + 1;
    s[q] = e[q] == b[q] ? 1 : -1;
  }
  std::array<tet, 6> tets{};
  for (std::size_t t = 0; t < 6; ++t) {
    tets[t][0] = e;
    for (std::size_t step = 0; step < 3; ++step) {
      const std::size_t axis = axis_orders[t][step];
      tets[t][step + 1] = tets[t][step];
      tets[t][step + 1][axis] += s[axis];
    }
  }
  return tets;
}

// Calls f(tetrahedron) for every tetrahedron of every unit cell inside the data box.
template <class F>
void for_each_tetrahedron(const volume& v, F&& f) {
  const index3& n = v.dims();
  for (std::int64_t k = 0; k + 1 < n[2]; ++k) {
    for (std::int64_t j = 0; j + 1 < n[1]; ++j) {
      for (std::int64_t i = 0; i + 1 < n[0]; ++i) {
        for (const tet& t : cell_tetrahedra({i, j, k})) f(t);
      }
    }
  }
}

double sample(const volume& v, const point& p) { return v.at(v.linear(p[0], p[1], p[2])); }

std::uint64_t key_of(const point& a, const point& b) {
  return static_cast<std::uint64_t>(a[0] + b[0]) | static_cast<std::uint64_t>(a[1] + b[1]) << 21 |
         static_cast<std::uint64_t>(a[2] + b[2]) << 42;
}

point sub(const point& a, const point& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }

class extractor {
 public:
  // A crossed edge of the tetrahedron, as a pair of corner indices (in either order).
  using edge = std::array<std::size_t, 2>;

  extractor(const volume& v, double isovalue) : v_(v), w_(isovalue) {}

  void march(const tet& t) {
    std::array<double, 4> f{};
    std::array<bool, 4> black{};
    int blacks = 0;
    for (std::size_t c = 0; c < 4; ++c) {
      f[c] = sample(v_, t[c]);
      black[c] = f[c] > w_;
      blacks += black[c] ? 1 : 0;
    }
    if (blacks == 0 || blacks == 4) return;

    if (blacks == 1 || blacks == 3) {
      // The lone corner (the one black, or the one white) is joined to each of the others.
      const bool lone_colour = blacks == 1;
      std::size_t lone = 0;
      while (black[lone] != lone_colour) ++lone;
      std::array<edge, 3> tri{};
      std::size_t m = 0;
      for (std::size_t c = 0; c < 4; ++c) {
        if (c != lone) tri[m++] = {lone, c};
      }
      emit(t, f, black, tri);
      return;
    }

    std::array<std::size_t, 2> b{};
    std::array<std::size_t, 2> w{};
    std::size_t nb = 0;
    std::size_t nw = 0;
    for (std::size_t c = 0; c < 4; ++c) (black[c] ? b[nb++] : w[nw++]) = c;
    // The quad cycle b1w1, b1w2, b2w2, b2w1, cut along the diagonal through its vertex with
    // the smallest edge key.
    const std::array<edge, 4> quad{{{b[0], w[0]}, {b[0], w[1]}, {b[1], w[1]}, {b[1], w[0]}}};
    std::size_t smallest = 0;
    for (std::size_t q = 1; q < 4; ++q) {
      if (key_of(t[quad[q][0]], t[quad[q][1]]) <
          key_of(t[quad[smallest][0]], t[quad[smallest][1]])) {
        smallest = q;
      }
    }
    if (smallest == 0 || smallest == 2) {
      emit(t, f, black, {quad[0], quad[1], quad[2]});
      emit(t, f, black, {quad[0], quad[2], quad[3]});
    } else {
      emit(t, f, black, {quad[1], quad[2], quad[3]});
      emit(t, f, black, {quad[1], quad[3], quad[0]});
    }
  }

  reference_surface take() { return std::move(out_); }

 private:
  // Appends the triangle on three crossed edges of t, oriented so that its right-hand normal
  // points from black to white. The test uses the doubled edge midpoints: integers, so it is
  // exact, and their plane separates the black corners from the white ones, so it is never 0.
  void emit(const tet& t, const std::array<double, 4>& f, const std::array<bool, 4>& black,
            std::array<edge, 3> tri) {
    std::array<point, 3> m{};
    for (std::size_t i = 0; i < 3; ++i) {
      for (std::size_t q = 0; q < 3; ++q) m[i][q] = t[tri[i][0]][q] + t[tri[i][1]][q];
    }
    const point u = sub(m[1], m[0]);
    const point v = sub(m[2], m[0]);
    const point normal{u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                       u[0] * v[1] - u[1] * v[0]};
    const std::size_t black_end = black[tri[0][0]] ? tri[0][0] : tri[0][1];
    const std::size_t white_end = black[tri[0][0]] ? tri[0][1] : tri[0][0];
    const point d = sub(t[white_end], t[black_end]);
    const std::int64_t dot = normal[0] * d[0] + normal[1] * d[1] + normal[2] * d[2];
    PROGISO_ASSERT(dot != 0);
    if (dot < 0) std::swap(tri[1], tri[2]);

    std::array<std::uint32_t, 3> indices{};
    for (std::size_t i = 0; i < 3; ++i) {
      indices[i] = vertex(t[tri[i][0]], f[tri[i][0]], t[tri[i][1]], f[tri[i][1]]);
    }
    out_.mesh.triangles.push_back(indices);
  }

  // The vertex on crossed edge (p, fp)–(r, fr), created on first use: interpolated from the
  // canonically ordered ends (lower (z, y, x) first), clamped strictly inside the edge.
  std::uint32_t vertex(const point& p, double fp, const point& r, double fr) {
    const std::uint64_t key = key_of(p, r);
    const auto [it, inserted] =
        index_.try_emplace(key, static_cast<std::uint32_t>(out_.mesh.vertices.size()));
    if (!inserted) return it->second;

    const bool p_first = std::tie(p[2], p[1], p[0]) < std::tie(r[2], r[1], r[0]);
    const point& a = p_first ? p : r;
    const point& b = p_first ? r : p;
    const double fa = p_first ? fp : fr;
    const double fb = p_first ? fr : fp;
    constexpr double margin = 1.0 / 4096.0;
    double t = (w_ - fa) / (fb - fa);
    t = t < margin ? margin : (t > 1.0 - margin ? 1.0 - margin : t);
    vec3 position{};
    for (std::size_t q = 0; q < 3; ++q) {
      const double grid = static_cast<double>(a[q]) + t * static_cast<double>(b[q] - a[q]);
      position[q] = v_.origin()[q] + grid * v_.spacing()[q];
    }
    out_.mesh.vertices.push_back(position);
    out_.vertex_keys.push_back(key);
    return it->second;
  }

  const volume& v_;
  double w_;
  reference_surface out_;
  std::unordered_map<std::uint64_t, std::uint32_t> index_;
};

void check_isovalue(double isovalue) {
  if (std::isnan(isovalue)) throw error("reference_marching_tetrahedra: isovalue is NaN");
}

}  // namespace

reference_surface reference_marching_tetrahedra(const volume& v, double isovalue) {
  check_isovalue(isovalue);
  extractor x(v, isovalue);
  for_each_tetrahedron(v, [&](const tet& t) { x.march(t); });
  return x.take();
}

std::size_t reference_triangle_count(const volume& v, double isovalue) {
  check_isovalue(isovalue);
  std::size_t count = 0;
  for_each_tetrahedron(v, [&](const tet& t) {
    int blacks = 0;
    for (const point& p : t) blacks += sample(v, p) > isovalue ? 1 : 0;
    count += blacks == 2 ? 2 : (blacks == 0 || blacks == 4 ? 0 : 1);
  });
  return count;
}

}  // namespace progiso::test
