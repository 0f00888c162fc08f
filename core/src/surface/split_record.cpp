#include <progiso/core/surface/split_record.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <type_traits>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/field/detail/sample_threshold.hpp>
#include <progiso/core/field/detail/subdivision.hpp>
#include <progiso/core/surface/detail/split_classify.hpp>
#include <progiso/core/surface/marching.hpp>

namespace progiso {

std::string_view to_string(tet_case c) noexcept {
  static constexpr std::string_view names[] = {"1b", "1c", "2b", "2c", "3b",
                                               "3c", "4b", "4c", "5b", "5c"};
  return names[static_cast<std::size_t>(c)];
}

std::string_view to_string(primitive p) noexcept {
  static constexpr std::string_view names[] = {"VertexMove",   "VertexSplit",       "VertexOpen",
                                               "EdgeFlip",     "NewLoop",           "NewSurf",
                                               "CylinderFlip", "ConnectivityChange"};
  return names[static_cast<std::size_t>(p)];
}

std::string_view to_string(split_configuration c) noexcept {
  static constexpr std::string_view names[] = {"spine_crossed",    "no_new_crossing",
                                               "empty_region",     "cylinder",
                                               "single_component", "multiple_components"};
  return names[static_cast<std::size_t>(c)];
}

namespace {

std::int64_t dist2(const ipoint& a, const ipoint& b) noexcept {
  std::int64_t s = 0;
  for (std::size_t q = 0; q < 3; ++q) {
    const std::int64_t d = a[q] - b[q];
    s += d * d;
  }
  return s;
}

// The diamond that owns a tetrahedron: the one centred at the midpoint of its longest edge, or
// none when that midpoint is not a grid vertex (a finest tetrahedron). The general rule; the
// split uses child_owner() and checks it against this one when asserts are on.
[[maybe_unused]] std::uint64_t owner_of(const hierarchy& hier,
                                        const std::array<ipoint, 4>& t) noexcept {
  std::int64_t best = -1;
  std::size_t bi = 0;
  std::size_t bj = 1;
  for (std::size_t i = 0; i < 4; ++i) {
    for (std::size_t j = i + 1; j < 4; ++j) {
      const std::int64_t l = dist2(t[i], t[j]);
      if (l > best) {
        best = l;
        bi = i;
        bj = j;
      }
    }
  }
  ipoint m{};
  for (std::size_t q = 0; q < 3; ++q) {
    const std::int32_t s = t[bi][q] + t[bj][q];
    if (s & 1) return no_owner;
    m[q] = s / 2;
  }
  return hier.is_diamond(m) ? hier.index(m) : no_owner;
}

// owner_of() for a child (p, e, a, b) of a split, p a spine end and e the centre: its longest
// edge is always p-a or p-b (the ring edge a-b and the half spine p-e are shorter in every
// diamond class), so two distances decide it. Ties cannot occur; the general rule would take
// p-a first, and so does this.
std::uint64_t child_owner(const hierarchy& hier, const ipoint& p, const ipoint& a,
                          const ipoint& b) noexcept {
  const ipoint& x = dist2(p, b) > dist2(p, a) ? b : a;
  ipoint m{};
  for (std::size_t q = 0; q < 3; ++q) {
    const std::int32_t s = p[q] + x[q];
    if (s & 1) return no_owner;
    m[q] = s / 2;
  }
  return hier.is_diamond(m) ? hier.index(m) : no_owner;
}

void bump(split_summary& s, primitive p, int n = 1) noexcept {
  s.primitives[static_cast<std::size_t>(p)] =
      static_cast<std::uint16_t>(s.primitives[static_cast<std::size_t>(p)] + n);
}

}  // namespace

namespace detail {

namespace {

// Bits set in a ring set (at most 8 bits). A table: the portable x86-64 baseline has no popcnt
// instruction, and std::popcount is then a library call.
int ring_count(unsigned x) noexcept {
  static constexpr auto table = [] {
    std::array<std::uint8_t, 256> t{};
    for (std::size_t i = 0; i < t.size(); ++i) {
      t[i] = static_cast<std::uint8_t>(std::popcount(static_cast<unsigned>(i)));
    }
    return t;
  }();
  return table[x & 0xFFu];
}

}  // namespace

void classify(const split_colours& k, split_summary& s) noexcept {
  const int n = k.n;
  const unsigned full = (1u << n) - 1;
  // Rotations over the ring: bit m of next(X) is X's bit m + 1, of prev(X) its bit m - 1.
  const auto next = [&](unsigned x) { return ((x >> 1) | (x << (n - 1))) & full; };
  const auto prev = [&](unsigned x) { return ((x << 1) | (x >> (n - 1))) & full; };
  const unsigned g = k.ring_in_grid & full;
  const unsigned r = k.ring & g;
  const unsigned t = g & next(g);  // tetrahedra (c, d, ring[m], ring[m + 1]) in the grid
  const unsigned rn = next(r);     // colour of ring[m + 1]
  const bool bc = k.c;
  const bool bd = k.d;
  const bool be = k.e;
  // Tetrahedra by the colours (a, b) of their ring edge.
  const int n00 = ring_count(t & ~r & ~rn & full);
  const int n11 = ring_count(t & r & rn);
  const int n_mixed = ring_count(t) - n00 - n11;
  s.tets = n00 + n11 + n_mixed;
  const unsigned cd = (bc ? 1u : 0u) | (bd ? 2u : 0u);
  s.removed_triangles = n00 * tet_triangle_count(cd) + n11 * tet_triangle_count(cd | 12u) +
                        n_mixed * tet_triangle_count(cd | 4u);
  const auto add_case = [&](tet_case c, int count) {
    s.cases[static_cast<std::size_t>(c)] =
        static_cast<std::uint8_t>(s.cases[static_cast<std::size_t>(c)] + count);
  };
  int count_3a = 0;  // a = b = c's colour
  int count_4a = 0;  // a = b, opposite to c
  if (bc != bd) {
    // 1: a = b (b when e differs from them); 2: a ≠ b (b when e has c's colour).
    add_case(be != false ? tet_case::c1b : tet_case::c1c, n00);
    add_case(be != true ? tet_case::c1b : tet_case::c1c, n11);
    add_case(be == bc ? tet_case::c2b : tet_case::c2c, n_mixed);
  } else {
    count_3a = bc ? n11 : n00;
    count_4a = bc ? n00 : n11;
    add_case(be == bc ? tet_case::c3b : tet_case::c3c, count_3a);
    add_case(be == bc ? tet_case::c4b : tet_case::c4c, count_4a);
    add_case(be == bc ? tet_case::c5b : tet_case::c5c, n_mixed);
  }

  // ---- Primitives around the spine. --------------------------------------------------------
  const unsigned interior = t & prev(t);  // ring vertices whose facet (a, c, d) is interior
  const unsigned touched = t | prev(t);   // ring vertices of some tetrahedron
  const auto ring_splits = [&] {
    // Ring vertices whose new edge a-e is crossed.
    const unsigned crossed = g & touched & (be ? ~r : r);
    bump(s, primitive::vertex_split, ring_count(crossed & interior));
    bump(s, primitive::vertex_open, ring_count(crossed & ~interior));
  };
  if (bc != bd) {
    s.configuration = split_configuration::spine_crossed;
    bump(s, primitive::vertex_move);
    ring_splits();
  } else if (be == bc) {
    s.configuration = split_configuration::no_new_crossing;
    ring_splits();
  } else if (count_3a == s.tets) {
    s.configuration = split_configuration::empty_region;
    bump(s, t == full ? primitive::new_loop : primitive::new_surf);
  } else if (count_4a == s.tets) {
    s.configuration = split_configuration::cylinder;
    bump(s, primitive::cylinder_flip);
  } else {
    // Components: maximal runs of ring vertices opposite to c in colour, along existing tets.
    const unsigned opposite = g & (bc ? ~r : r);
    int components = ring_count(opposite & ~prev(t & opposite));
    if (components == 0) components = 1;  // closed ring wholly opposite: handled as cylinder
    s.configuration = components == 1 ? split_configuration::single_component
                                      : split_configuration::multiple_components;
    bump(s, primitive::vertex_split, components);
    ring_splits();
    bump(s, primitive::edge_flip, count_4a);
    bump(s, primitive::connectivity_change, components - 1);
  }
}

}  // namespace detail

namespace {

using detail::classify;
using colours = detail::split_colours;

// The split of d by marching every child tetrahedron: the general rule, which the owned_triangle
// records use and which the tables of the packed path are built from. emit(owner, surface) for
// every child tetrahedron with surface, in a fixed order.
template <class Emit>
split_summary split_into(const hierarchy& hier, const volume& vol, double w, const diamond& d,
                         Emit&& emit) {
  split_summary s;
  // Inside the data box (the usual case) samples are read without clamping.
  const ipoint& dm = hier.data_max();
  const std::int32_t h = d.scale;
  const bool inside = d.centre[0] - h >= 0 && d.centre[1] - h >= 0 && d.centre[2] - h >= 0 &&
                      d.centre[0] + h <= dm[0] && d.centre[1] + h <= dm[1] &&
                      d.centre[2] + h <= dm[2];
  const auto value = [&](const ipoint& p) {
    return inside ? vol.at(vol.linear(p[0], p[1], p[2])) : vol.value(p[0], p[1], p[2]);
  };
  const ipoint& c = d.spine[0];
  const ipoint& dd = d.spine[1];
  const ipoint& e = d.centre;
  const double fc = value(c);
  const double fd = value(dd);
  const double fe = value(e);
  colours k;
  k.c = fc > w;
  k.d = fd > w;
  k.e = fe > w;
  k.n = d.ring_size;
  k.ring_in_grid = d.ring_in_grid;
  const int n = d.ring_size;
  std::array<double, 8> fr{};
  for (int m = 0; m < n; ++m) {
    if ((d.ring_in_grid >> m) & 1u) {
      fr[static_cast<std::size_t>(m)] = value(d.ring[static_cast<std::size_t>(m)]);
      if (fr[static_cast<std::size_t>(m)] > w) k.ring |= 1u << m;
    }
  }
  classify(k, s);
  for (int m = 0; m < n; ++m) {
    if (!k.tet_exists(m)) continue;
    const auto um = static_cast<std::size_t>(m);
    const auto um1 = static_cast<std::size_t>((m + 1 == n ? 0 : m + 1));
    const ipoint& a = d.ring[um];
    const ipoint& b = d.ring[um1];
    for (int half = 0; half < 2; ++half) {
      // A child whose four corners share one colour has no surface: skip marching it.
      const bool bp = half == 0 ? k.c : k.d;
      const bool ba = ((k.ring >> um) & 1u) != 0;
      const bool bb = ((k.ring >> um1) & 1u) != 0;
      if (bp == k.e && k.e == ba && k.e == bb) continue;
      const std::array<ipoint, 4> t =
          half == 0 ? std::array<ipoint, 4>{c, e, a, b} : std::array<ipoint, 4>{e, dd, a, b};
      const std::array<double, 4> f = half == 0 ? std::array<double, 4>{fc, fe, fr[um], fr[um1]}
                                                : std::array<double, 4>{fe, fd, fr[um], fr[um1]};
      const tet_surface ts = march_tet(t, f, w);
      if (ts.count == 0) continue;
      const std::uint64_t owner = child_owner(hier, half == 0 ? c : dd, a, b);
      PROGISO_ASSERT(owner == owner_of(hier, t));
      emit(owner, ts);
      s.added_triangles += ts.count;
    }
  }
  return s;
}

// The packed bits of one child's surface: edge keys 2·centre + h·o turned into codes of o
// (h = 2^shift).
std::uint64_t pack_surface(const tet_surface& ts, const ipoint& centre, int shift) noexcept {
  std::uint64_t bits = static_cast<std::uint64_t>(ts.count);
  for (std::size_t k = 0; k < static_cast<std::size_t>(ts.count); ++k) {
    for (std::size_t v = 0; v < 3; ++v) {
      const ipoint m = edge_key_point(ts.triangles[k][v]);
      std::array<std::int32_t, 3> o{};
      for (std::size_t q = 0; q < 3; ++q) {
        const std::int32_t rel = m[q] - 2 * centre[q];
        o[q] = rel >> shift;  // arithmetic: exact, rel is a multiple of h
        PROGISO_ASSERT((o[q] << shift) == rel && o[q] >= -2 && o[q] <= 2);
      }
      const std::uint64_t code = half_offset_code(o[0], o[1], o[2]);
      bits |= code << (8 * (1 + 3 * k + v));
    }
  }
  return bits;
}

// ---- The packed path: splits from tables. -----------------------------------------------------
//
// A diamond's points, relative to its centre in units of its scale h, depend only on its shape:
// which axes are odd at its scale (the type) and the spine's direction along them. There are 26
// shapes. Marching is invariant under that change of frame: the quad diagonal follows the order
// of edge keys, which for keys 2c + h·o is the order of o, and the orientation test is a sign of
// a product of differences. So the packed surface of every child tetrahedron, for each of its 16
// colourings, is a table entry, built once by march_tet() itself on a diamond of each shape.

using offset = std::array<std::int8_t, 3>;

struct child_table {
  std::array<std::uint64_t, 16> bits{};  // pack_surface() of each colouring; 0: no surface
  offset owner2{};                       // 2 × the owner's offset (p + x, see child_owner())
  std::uint64_t owner_code = 0;          // owner2 coded as packed_group's owner
};

struct shape_table {
  int n = 0;                            // ring size
  offset spine{};                       // spine end d; end c is its opposite
  std::array<offset, 8> ring{};         // ring points
  std::array<child_table, 16> child{};  // child 2m + half, as split_into() orders them
  // 1 << edge_offset_code() of spine end c, spine end d and each ring point.
  std::uint32_t spine_c_bit = 0;
  std::uint32_t spine_d_bit = 0;
  std::array<std::uint32_t, 8> ring_bit{};
  group_edge_table edges{};  // see group_edges()
};

// Shape index: bit q set when axis q is odd at the diamond's scale, bit 3 + q when the spine
// runs towards +q along it.
unsigned shape_of(const ipoint& c, std::int32_t h, int lg) noexcept {
  unsigned id = 0;
  for (std::size_t q = 0; q < 3; ++q) {
    if ((c[q] >> lg) & 1) {
      id |= 1u << q;
      if (((c[q] + h) & (4 * h - 1)) == 0) id |= 8u << q;
    }
  }
  return id;
}

std::array<shape_table, 64> build_shapes() {
  std::array<shape_table, 64> shapes{};
  // A diamond of every shape at scale 2 in a 17³ grid, away from the boundary.
  const hierarchy probe({17, 17, 17});
  for (unsigned odd = 1; odd < 8; ++odd) {
    for (unsigned sign = 0; sign < 8; ++sign) {
      if ((sign & ~odd) != 0) continue;
      ipoint c{};
      for (std::size_t q = 0; q < 3; ++q) {
        c[q] = ((odd >> q) & 1u) != 0 ? (((sign >> q) & 1u) != 0 ? 6 : 10) : 8;
      }
      const diamond d = probe.make_diamond(c);
      const unsigned id = shape_of(c, d.scale, 1);
      PROGISO_ASSERT(d.scale == 2 && id == (odd | sign << 3));
      shape_table& t = shapes[id];
      const auto off = [&](const ipoint& p) {
        return offset{static_cast<std::int8_t>((p[0] - c[0]) / 2),
                      static_cast<std::int8_t>((p[1] - c[1]) / 2),
                      static_cast<std::int8_t>((p[2] - c[2]) / 2)};
      };
      t.n = d.ring_size;
      t.spine = off(d.spine[1]);
      for (int m = 0; m < d.ring_size; ++m) {
        t.ring[static_cast<std::size_t>(m)] = off(d.ring[static_cast<std::size_t>(m)]);
      }
      const auto code27 = [](const offset& o) {
        return edge_offset_code({int{o[0]}, int{o[1]}, int{o[2]}});
      };
      t.spine_c_bit = 1u << code27(off(d.spine[0]));
      t.spine_d_bit = 1u << code27(t.spine);
      for (int m = 0; m < d.ring_size; ++m) {
        t.ring_bit[static_cast<std::size_t>(m)] = 1u << code27(t.ring[static_cast<std::size_t>(m)]);
      }
      for (auto& e : t.edges) e = {centre_offset_code, centre_offset_code};
      for (int m = 0; m < d.ring_size; ++m) {
        const ipoint& a = d.ring[static_cast<std::size_t>(m)];
        const ipoint& b = d.ring[static_cast<std::size_t>(m + 1 == d.ring_size ? 0 : m + 1)];
        for (int half = 0; half < 2; ++half) {
          child_table& ch = t.child[static_cast<std::size_t>(2 * m + half)];
          const ipoint& p = half == 0 ? d.spine[0] : d.spine[1];
          const std::array<ipoint, 4> tet =
              half == 0 ? std::array<ipoint, 4>{p, c, a, b} : std::array<ipoint, 4>{c, p, a, b};
          // Every edge of the child, by its code: the code of the sum of its ends' offsets.
          for (std::size_t i = 0; i < 4; ++i) {
            for (std::size_t j = i + 1; j < 4; ++j) {
              const offset u = off(tet[i]);
              const offset v = off(tet[j]);
              const std::size_t code = half_offset_code(u[0] + v[0], u[1] + v[1], u[2] + v[2]);
              std::array<std::uint8_t, 2> ends{static_cast<std::uint8_t>(code27(u)),
                                               static_cast<std::uint8_t>(code27(v))};
              if (ends[1] == centre_offset_code) std::swap(ends[0], ends[1]);
              auto& slot = t.edges[code];
              // Edge keys name edges uniquely: one edge per code.
              PROGISO_ASSERT((slot[0] == centre_offset_code && slot[1] == centre_offset_code) ||
                             slot == ends);
              slot = ends;
            }
          }
          for (unsigned mask = 0; mask < 16; ++mask) {
            std::array<double, 4> f{};
            for (std::size_t i = 0; i < 4; ++i) f[i] = ((mask >> i) & 1u) != 0 ? 1.0 : 0.0;
            ch.bits[mask] = pack_surface(march_tet(tet, f, 0.5), c, 1);
          }
          const ipoint& x = dist2(p, b) > dist2(p, a) ? b : a;
          const offset po = off(p);
          const offset xo = off(x);
          for (std::size_t q = 0; q < 3; ++q) {
            ch.owner2[q] = static_cast<std::int8_t>(po[q] + xo[q]);
          }
          ch.owner_code = half_offset_code(ch.owner2[0], ch.owner2[1], ch.owner2[2]);
        }
      }
    }
  }
  return shapes;
}

const std::array<shape_table, 64>& shapes() {
  static const std::array<shape_table, 64> all = build_shapes();
  return all;
}

}  // namespace

const group_edge_table& group_edges(const ipoint& c, std::int32_t h) noexcept {
  const int lg = std::countr_zero(static_cast<std::uint32_t>(h));
  return shapes()[shape_of(c, h, lg)].edges;
}

namespace {

// classify() of a diamond whose ring lies wholly in the grid, by table: one entry per ring size
// (4, 6, 8) and colouring of c, d, e and the ring, made by classify() itself.
std::vector<split_summary> build_interior_table() {
  std::vector<split_summary> t(interior_classification_count);
  std::size_t i = 0;
  for (int n = 4; n <= 8; n += 2) {
    for (unsigned key = 0; key < (8u << n); ++key, ++i) {
      colours c;
      c.n = n;
      c.ring_in_grid = (1u << n) - 1;
      c.c = (key & 1u) != 0;
      c.d = (key & 2u) != 0;
      c.e = (key & 4u) != 0;
      c.ring = key >> 3;
      classify(c, t[i]);
      t[i].classification = static_cast<std::int16_t>(i);
    }
  }
  return t;
}

// Small enough to inline: a split pays one initialisation check, not a call.
inline const std::vector<split_summary>& interior_table() {
  static const std::vector<split_summary> table = build_interior_table();
  return table;
}

const split_summary& interior_summary(const colours& k) noexcept {
  static constexpr std::array<unsigned, 3> first{0, 8u << 4, (8u << 4) + (8u << 6)};
  const unsigned key = (k.c ? 1u : 0u) | (k.d ? 2u : 0u) | (k.e ? 4u : 0u) | (k.ring << 3);
  return interior_table()[first[static_cast<std::size_t>(k.n / 2 - 2)] + key];
}

// Samples: a typed sample pointer, or detail::lazy_samples for a smoothed volume.
template <class Samples>
split_summary split_packed(const hierarchy& hier, const volume& vol, Samples samples,
                           const detail::sample_threshold& threshold, const ipoint& c,
                           std::int32_t h, std::vector<packed_group>& out) {
  split_summary s;
  const int lg = std::countr_zero(static_cast<std::uint32_t>(h));
  const shape_table& shape = shapes()[shape_of(c, h, lg)];
  const int n = shape.n;
  const auto point = [&](const offset& o) {
    return ipoint{c[0] + h * o[0], c[1] + h * o[1], c[2] + h * o[2]};
  };
  const ipoint& dm = hier.data_max();
  const ipoint& gm = hier.grid_max();
  bool in_data = true;
  bool in_grid = true;
  for (std::size_t q = 0; q < 3; ++q) {
    in_data = in_data && c[q] - h >= 0 && c[q] + h <= dm[q];
    in_grid = in_grid && c[q] - h >= 0 && c[q] + h <= gm[q];
  }
  colours k;
  k.n = n;
  k.ring_in_grid = (1u << n) - 1;
  if (!in_grid) {
    k.ring_in_grid = 0;
    for (int m = 0; m < n; ++m) {
      if (hier.in_grid(point(shape.ring[static_cast<std::size_t>(m)]))) k.ring_in_grid |= 1u << m;
    }
  }
  const auto above = [&threshold](auto v) { return threshold.above(v); };
  if (in_data) {
    const index3& dims = vol.dims();
    const std::int64_t sy = dims[0];
    const std::int64_t sz = dims[0] * dims[1];
    const auto base = samples + static_cast<std::int64_t>(vol.linear(c[0], c[1], c[2]));
    const auto at = [&](const offset& o) {
      return above(base[h * (o[0] + o[1] * sy + o[2] * sz)]);
    };
    const offset& sp = shape.spine;
    k.c = at({static_cast<std::int8_t>(-sp[0]), static_cast<std::int8_t>(-sp[1]),
              static_cast<std::int8_t>(-sp[2])});
    k.d = at(sp);
    k.e = above(base[0]);
    for (int m = 0; m < n; ++m) {
      if (at(shape.ring[static_cast<std::size_t>(m)])) k.ring |= 1u << m;
    }
  } else {
    // Near the data box's faces: samples at clamped coordinates (the padding takes the nearest
    // data value). Offsets are -h, 0 or h per axis, so each axis has three clamped shares of
    // the linear index.
    const index3& dims = vol.dims();
    const std::array<std::int64_t, 3> stride{1, dims[0], dims[0] * dims[1]};
    std::array<std::array<std::int64_t, 3>, 3> part{};
    for (std::size_t q = 0; q < 3; ++q) {
      for (std::size_t j = 0; j < 3; ++j) {
        const std::int64_t v = std::int64_t{c[q]} + (static_cast<std::int64_t>(j) - 1) * h;
        part[q][j] = std::clamp<std::int64_t>(v, 0, dims[q] - 1) * stride[q];
      }
    }
    const auto at = [&](const offset& o) {
      return above(samples[part[0][static_cast<std::size_t>(o[0] + 1)] +
                           part[1][static_cast<std::size_t>(o[1] + 1)] +
                           part[2][static_cast<std::size_t>(o[2] + 1)]]);
    };
    const offset& sp = shape.spine;
    k.c = at({static_cast<std::int8_t>(-sp[0]), static_cast<std::int8_t>(-sp[1]),
              static_cast<std::int8_t>(-sp[2])});
    k.d = at(sp);
    k.e = at({0, 0, 0});
    for (int m = 0; m < n; ++m) {
      if ((k.ring_in_grid >> m) & 1u) {
        if (at(shape.ring[static_cast<std::size_t>(m)])) k.ring |= 1u << m;
      }
    }
  }
  // Diamonds wholly in the grid (nearly all) take their classification from a table: it depends
  // only on n and the colours of c, d, e and the ring.
  if (k.ring_in_grid == (1u << n) - 1) {
    s = interior_summary(k);
  } else {
    classify(k, s);
  }
  if (k.c != k.e) s.crossed |= shape.spine_c_bit;
  if (k.d != k.e) s.crossed |= shape.spine_d_bit;
  const unsigned other = (k.e ? ~k.ring : k.ring) & k.ring_in_grid;
  for (unsigned todo = other; todo != 0; todo &= todo - 1) {
    s.crossed |= shape.ring_bit[static_cast<std::size_t>(std::countr_zero(todo))];
  }
  const unsigned ce = (k.c ? 1u : 0u) | (k.e ? 2u : 0u);  // colours of (c, e, ., .)
  const unsigned ed = (k.e ? 1u : 0u) | (k.d ? 2u : 0u);  // colours of (e, d, ., .)
  // Children with surface, as bit sets over ring positions: child (half, m) has corners
  // (spine end, centre, ring[m], ring[m + 1]) and holds surface unless all four agree.
  const unsigned full = (1u << n) - 1;
  const auto next = [&](unsigned x) { return ((x >> 1) | (x << (n - 1))) & full; };
  const unsigned exists = k.ring_in_grid & next(k.ring_in_grid);
  const unsigned black_pair = k.ring & next(k.ring);  // ring[m], ring[m + 1] both black
  const unsigned white_pair = ~(k.ring | next(k.ring)) & full;
  const auto mixed = [&](bool p, bool q) {  // (p, q): colours of the child's spine end, centre
    return exists & (p != q ? full : (p ? ~black_pair : ~white_pair));
  };
  const std::array<unsigned, 2> with_surface{mixed(k.c, k.e), mixed(k.e, k.d)};
  for (unsigned todo = with_surface[0] | with_surface[1]; todo != 0; todo &= todo - 1) {
    const auto um = static_cast<std::size_t>(std::countr_zero(todo));
    const auto um1 = um + 1 == static_cast<std::size_t>(n) ? std::size_t{0} : um + 1;
    const unsigned ab = (((k.ring >> um) & 1u) << 2) | (((k.ring >> um1) & 1u) << 3);
    for (std::size_t half = 0; half < 2; ++half) {
      if (((with_surface[half] >> um) & 1u) == 0) continue;
      const child_table& ch = shape.child[2 * um + half];
      const std::uint64_t bits = ch.bits[(half == 0 ? ce : ed) | ab];
      PROGISO_ASSERT(bits != 0);
      // The owner c + (h/2)·o, o = ch.owner2: at h = 1 an offset with an odd coordinate is half
      // a grid step (a finest child); otherwise the point is a child's centre, a diamond
      // whenever it is a grid vertex (children are finer than roots), which it is when the
      // whole diamond is.
      const offset& o = ch.owner2;
      std::uint64_t code = packed_group::no_owner_code;
      if (h > 1 || ((o[0] | o[1] | o[2]) & 1) == 0) {
        if (in_grid ||
            hier.in_grid(ipoint{c[0] + h * o[0] / 2, c[1] + h * o[1] / 2, c[2] + h * o[2] / 2})) {
          code = ch.owner_code;
        }
      }
      const packed_group group{bits | (code << 56)};
#if defined(PROGISO_ENABLE_ASSERTS)
      {
        const diamond d = hier.make_diamond(c);
        const ipoint& a = d.ring[um];
        const ipoint& b = d.ring[um1];
        const std::array<ipoint, 4> t = half == 0 ? std::array<ipoint, 4>{d.spine[0], c, a, b}
                                                  : std::array<ipoint, 4>{c, d.spine[1], a, b};
        PROGISO_ASSERT(group_owner(hier, hier.index(c), h, group) == owner_of(hier, t));
      }
#endif
      out.push_back(group);
      s.added_triangles += static_cast<int>(bits & 0xFFu);
    }
  }
  return s;
}

}  // namespace

const split_summary& interior_classification(std::size_t i) noexcept {
  PROGISO_ASSERT(i < interior_classification_count);
  return interior_table()[i];
}

split_summary compute_split(const hierarchy& hier, const volume& vol, double w, const diamond& d,
                            std::vector<owned_triangle>& out) {
  return split_into(hier, vol, w, d, [&](std::uint64_t owner, const tet_surface& ts) {
    for (int k = 0; k < ts.count; ++k) {
      out.push_back({owner, ts.triangles[static_cast<std::size_t>(k)]});
    }
  });
}

split_summary compute_split(const hierarchy& hier, const volume& vol, double w,
                            const ipoint& centre, std::vector<packed_group>& out) {
  return compute_split(hier, vol, w, centre, hier.scale_of(centre), out);
}

split_summary compute_split(const hierarchy& hier, const volume& vol, double w,
                            const ipoint& centre, std::int32_t scale,
                            std::vector<packed_group>& out) {
  PROGISO_ASSERT(hier.is_diamond(centre));
  PROGISO_ASSERT(hier.scale_of(centre) == scale);
  const detail::sample_threshold threshold(w);
  return detail::visit_field(vol, [&](auto samples) {
    return split_packed(hier, vol, samples, threshold, centre, scale, out);
  });
}

split_summary compute_split(const hierarchy& hier, const volume& vol, double w, const diamond& d,
                            std::vector<packed_group>& out) {
  return compute_split(hier, vol, w, d.centre, out);
}

std::optional<ipoint> compute_root(const hierarchy& hier, const volume& vol, double w,
                                   std::uint64_t r, std::vector<owned_triangle>& out) {
  std::array<std::array<ipoint, 4>, 6> tets{};
  hier.root_tets(r, tets);
  ipoint centre{};
  for (std::size_t q = 0; q < 3; ++q) centre[q] = (tets[0][0][q] + tets[0][3][q]) / 2;
  const bool has_diamond = hier.root_size() >= 2;
  const std::uint64_t owner = has_diamond ? hier.index(centre) : no_owner;
  for (const auto& t : tets) {
    std::array<double, 4> f{};
    for (std::size_t i = 0; i < 4; ++i) f[i] = vol.value(t[i][0], t[i][1], t[i][2]);
    const tet_surface s = march_tet(t, f, w);
    for (int k = 0; k < s.count; ++k) {
      out.push_back({owner, s.triangles[static_cast<std::size_t>(k)]});
    }
  }
  if (!has_diamond) return std::nullopt;
  return centre;
}

}  // namespace progiso
