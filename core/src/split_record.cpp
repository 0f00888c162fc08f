#include <progiso/core/split_record.hpp>

#include <bit>

#include <progiso/core/assert.hpp>
#include <progiso/core/marching.hpp>

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

namespace {

// The split of d; emit(owner, surface) for every child
// tetrahedron with surface, in a fixed order.
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
  const bool bc = fc > w;
  const bool bd = fd > w;
  const bool be = fe > w;
  const int n = d.ring_size;
  std::array<double, 8> fr{};
  std::array<bool, 8> br{};
  for (int m = 0; m < n; ++m) {
    if ((d.ring_in_grid >> m) & 1u) {
      fr[static_cast<std::size_t>(m)] = value(d.ring[static_cast<std::size_t>(m)]);
      br[static_cast<std::size_t>(m)] = fr[static_cast<std::size_t>(m)] > w;
    }
  }
  const auto tet_exists = [&](int m) {
    const int m1 = (m + 1 == n ? 0 : m + 1);
    return ((d.ring_in_grid >> m) & 1u) && ((d.ring_in_grid >> m1) & 1u);
  };

  // ---- The children tetrahedra and their surface pieces, per tetrahedron's case. ----------
  int count_3a = 0;
  int count_4a = 0;
  for (int m = 0; m < n; ++m) {
    if (!tet_exists(m)) continue;
    const auto um = static_cast<std::size_t>(m);
    const auto um1 = static_cast<std::size_t>((m + 1 == n ? 0 : m + 1));
    const ipoint& a = d.ring[um];
    const ipoint& b = d.ring[um1];
    ++s.tets;
    const unsigned mask =
        (bc ? 1u : 0u) | (bd ? 2u : 0u) | (br[um] ? 4u : 0u) | (br[um1] ? 8u : 0u);
    s.removed_triangles += tet_triangle_count(mask);
    tet_case tc;
    if (bc != bd) {
      if (br[um] == br[um1]) {
        tc = be != br[um] ? tet_case::c1b : tet_case::c1c;
      } else {
        tc = be == bc ? tet_case::c2b : tet_case::c2c;
      }
    } else if (br[um] == br[um1]) {
      if (br[um] == bc) {
        tc = be == bc ? tet_case::c3b : tet_case::c3c;
        ++count_3a;
      } else {
        tc = be == bc ? tet_case::c4b : tet_case::c4c;
        ++count_4a;
      }
    } else {
      tc = be == bc ? tet_case::c5b : tet_case::c5c;
    }
    ++s.cases[static_cast<std::size_t>(tc)];
    for (int half = 0; half < 2; ++half) {
      // A child whose four corners share one colour has no surface: skip marching it.
      const bool bp = half == 0 ? bc : bd;
      if (bp == be && be == br[um] && be == br[um1]) continue;
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

  // ---- Primitives around the spine. --------------------------------------------------------
  const auto facet_interior = [&](int m) {
    return tet_exists(m) && tet_exists((m == 0 ? n - 1 : m - 1));
  };
  const auto ring_splits = [&](bool want_colour_ne_e) {
    for (int m = 0; m < n; ++m) {
      if (!((d.ring_in_grid >> m) & 1u)) continue;
      if (!tet_exists(m) && !tet_exists((m == 0 ? n - 1 : m - 1))) continue;
      if ((br[static_cast<std::size_t>(m)] != be) != want_colour_ne_e) continue;
      bump(s, facet_interior(m) ? primitive::vertex_split : primitive::vertex_open);
    }
  };
  if (bc != bd) {
    s.configuration = split_configuration::spine_crossed;
    bump(s, primitive::vertex_move);
    ring_splits(true);
  } else if (be == bc) {
    s.configuration = split_configuration::no_new_crossing;
    ring_splits(true);
  } else if (count_3a == s.tets) {
    s.configuration = split_configuration::empty_region;
    bool closed = true;
    for (int m = 0; m < n; ++m) closed = closed && tet_exists(m);
    bump(s, closed ? primitive::new_loop : primitive::new_surf);
  } else if (count_4a == s.tets) {
    s.configuration = split_configuration::cylinder;
    bump(s, primitive::cylinder_flip);
  } else {
    // Components: maximal runs of ring vertices opposite to c in colour, along existing tets.
    int components = 0;
    for (int m = 0; m < n; ++m) {
      const auto um = static_cast<std::size_t>(m);
      if (!((d.ring_in_grid >> m) & 1u) || br[um] == bc) continue;
      const int prev = (m == 0 ? n - 1 : m - 1);
      const bool continues = tet_exists(prev) && br[static_cast<std::size_t>(prev)] != bc;
      if (!continues) ++components;
    }
    if (components == 0) components = 1;  // closed ring wholly opposite: handled as cylinder
    s.configuration = components == 1 ? split_configuration::single_component
                                      : split_configuration::multiple_components;
    bump(s, primitive::vertex_split, components);
    ring_splits(true);
    bump(s, primitive::edge_flip, count_4a);
    bump(s, primitive::connectivity_change, components - 1);
  }
  return s;
}

}  // namespace

split_summary compute_split(const hierarchy& hier, const volume& vol, double w, const diamond& d,
                            std::vector<owned_triangle>& out) {
  return split_into(hier, vol, w, d, [&](std::uint64_t owner, const tet_surface& ts) {
    for (int k = 0; k < ts.count; ++k) {
      out.push_back({owner, ts.triangles[static_cast<std::size_t>(k)]});
    }
  });
}

split_summary compute_split(const hierarchy& hier, const volume& vol, double w, const diamond& d,
                            std::vector<packed_group>& out) {
  return split_into(hier, vol, w, d, [&](std::uint64_t owner, const tet_surface& ts) {
    std::uint64_t bits = static_cast<std::uint64_t>(ts.count);
    const int shift = std::countr_zero(static_cast<std::uint32_t>(d.scale));  // h = 2^shift
    for (std::size_t k = 0; k < static_cast<std::size_t>(ts.count); ++k) {
      for (std::size_t v = 0; v < 3; ++v) {
        const ipoint m = edge_key_point(ts.triangles[k][v]);
        std::uint64_t code = 0;
        for (std::size_t q = 3; q-- > 0;) {
          const std::int32_t rel = m[q] - 2 * d.centre[q];
          const std::int32_t o = rel >> shift;  // arithmetic: exact, rel is a multiple of h
          PROGISO_ASSERT((o << shift) == rel && o >= -2 && o <= 2);
          code = code * 5 + static_cast<std::uint64_t>(o + 2);
        }
        bits |= code << (8 * (1 + 3 * k + v));
      }
    }
    out.push_back({owner, bits});
  });
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
