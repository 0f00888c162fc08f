#include <progiso/core/contour/finest_contours.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/contour/contour_split.hpp>
#include <progiso/core/contour/hierarchy2d.hpp>
#include <progiso/core/field/detail/subdivision.hpp>

namespace progiso {
namespace {

// A pixel's owned edges, by slot: 0 +x, 1 +y, 2 the diagonal of its square. A square corner is
// dx + 2 dy; an edge of a square is (owner corner) · 4 + slot; a square's parity class is the
// parity of its lowest corner, x + 2 y (bits).
constexpr int slots = 3;

/// The two ends of slot k of a pixel of parity `cls`, as corner offsets of its square.
constexpr std::array<int, 2> slot_ends(int cls, int k) noexcept {
  if (k == 0) return {0, 1};
  if (k == 1) return {0, 2};
  // The square's even corner to its opposite: (0,0)-(1,1) when x + y is even.
  return ((cls & 1) ^ (cls >> 1)) == 0 ? std::array<int, 2>{0, 3} : std::array<int, 2>{1, 2};
}

struct square_case {
  std::uint8_t count = 0;
  std::array<std::array<std::uint8_t, 2>, 2> segments{};  // square edges, from → to
};

struct tables {
  std::array<std::array<square_case, 16>, 4> cases{};
  /// The owned edges a pixel crosses, from its square's corner colours (corners beyond the
  /// image as white; the caller masks the slots whose ends are not there).
  std::array<std::array<std::uint8_t, 16>, 4> crossed{};
};

tables make_tables() {
  tables t;
  for (int cls = 0; cls < 4; ++cls) {
    const ipoint2 b{cls & 1, cls >> 1};
    for (int mask = 0; mask < 16; ++mask) {
      std::uint8_t crossed = 0;
      for (int k = 0; k < slots; ++k) {
        const auto [p, q] = slot_ends(cls, k);
        if (((mask >> p) & 1) != ((mask >> q) & 1)) crossed |= static_cast<std::uint8_t>(1u << k);
      }
      t.crossed[static_cast<std::size_t>(cls)][static_cast<std::size_t>(mask)] = crossed;
      // The square's two triangles around the diagonal from its even corner e to the odd one o.
      const ipoint2 e{(b[0] & 1) != 0 ? b[0] + 1 : b[0], (b[1] & 1) != 0 ? b[1] + 1 : b[1]};
      const ipoint2 o{(b[0] & 1) != 0 ? b[0] : b[0] + 1, (b[1] & 1) != 0 ? b[1] : b[1] + 1};
      const auto value = [&](const ipoint2& p) {
        const int corner = (p[0] - b[0]) + 2 * (p[1] - b[1]);
        return ((mask >> corner) & 1) != 0 ? 1.0 : -1.0;
      };
      square_case& c = t.cases[static_cast<std::size_t>(cls)][static_cast<std::size_t>(mask)];
      for (const ipoint2& apex : {ipoint2{o[0], e[1]}, ipoint2{e[0], o[1]}}) {
        std::array<std::uint64_t, 2> keys{};
        if (!march_triangle({e, o, apex}, {value(e), value(o), value(apex)}, 0.0, keys)) continue;
        auto& seg = c.segments[c.count++];
        for (std::size_t v = 0; v < 2; ++v) {
          // The edge's doubled midpoint, relative to the square: odd along the edge's axes.
          const ipoint2 m = edge_key2_point(keys[v]);
          int corner = 0;
          int axes = 0;
          for (std::size_t a = 0; a < 2; ++a) {
            const int local = m[a] - 2 * b[a];
            if (local == 1) axes |= 1 << a;
            if (local == 2) corner |= 1 << a;
          }
          static constexpr int slot_of_axes[4] = {-1, 0, 1, 2};
          seg[v] = static_cast<std::uint8_t>((corner << 2) | slot_of_axes[axes]);
        }
      }
    }
  }
  return t;
}

const tables& the_tables() {
  static const tables t = make_tables();
  return t;
}

constexpr std::array<std::uint8_t, 8> bit_counts{0, 1, 1, 2, 1, 2, 2, 3};

template <class S>
contour_set contours_of(const volume& image, S s, double w) {
  const tables& t = the_tables();
  const std::int64_t nx = image.dims()[0], ny = image.dims()[1];
  const auto n = static_cast<std::size_t>(nx);
  const auto pixels = static_cast<std::size_t>(nx * ny);
  const auto black = [&](std::int64_t i) { return static_cast<double>(s[i]) > w ? 1u : 0u; };
  // Pass 1: each pixel's square corners and crossed owned edges, their vertices in order.
  const auto corners = std::make_unique_for_overwrite<std::uint8_t[]>(pixels);
  const auto masks = std::make_unique_for_overwrite<std::uint8_t[]>(pixels);
  std::vector<std::uint32_t> row_first(static_cast<std::size_t>(ny) + 1, 0);
  contour_set out;
  const std::array<double, 2> origin{image.origin()[0], image.origin()[1]};
  const std::array<double, 2> spacing{image.spacing()[0], image.spacing()[1]};
  std::vector<std::uint8_t> below(n), above(n);  // colour pairs: bit 0 at x, bit 1 at x + 1
  const auto colour_pairs = [&](std::int64_t y, std::vector<std::uint8_t>& row) {
    const std::int64_t base = nx * y;
    for (std::size_t x = 0; x < n; ++x) {
      row[x] = static_cast<std::uint8_t>(black(base + static_cast<std::int64_t>(x)));
    }
    for (std::size_t x = 0; x + 1 < n; ++x) {
      row[x] = static_cast<std::uint8_t>(row[x] | (row[x + 1] << 1));
    }
  };
  colour_pairs(0, below);
  for (std::int64_t y = 0; y < ny; ++y) {
    row_first[static_cast<std::size_t>(y)] = static_cast<std::uint32_t>(out.vertices.size());
    const bool up = y + 1 < ny;
    if (up) {
      colour_pairs(y + 1, above);
    } else {
      std::fill(above.begin(), above.end(), std::uint8_t{0});
    }
    const unsigned valid_last = up ? 0b010u : 0u;
    const unsigned valid = up ? 0b111u : 0b001u;
    const std::size_t cls_y = static_cast<std::size_t>((y & 1) << 1);
    std::uint8_t* c = corners.get() + n * static_cast<std::size_t>(y);
    std::uint8_t* m = masks.get() + n * static_cast<std::size_t>(y);
    const std::int64_t row = nx * y;
    for (std::size_t x = 0; x < n; ++x) {
      const unsigned k = below[x] | (static_cast<unsigned>(above[x]) << 2);
      c[x] = static_cast<std::uint8_t>(k);
      const std::size_t cls = cls_y | (x & 1);
      const unsigned crossed = t.crossed[cls][k] & (x + 1 < n ? valid : valid_last);
      m[x] = static_cast<std::uint8_t>(crossed);
      for (unsigned bits = crossed; bits != 0; bits &= bits - 1) {
        const int slot = bits & 1u ? 0 : (bits & 2u ? 1 : 2);
        const auto [p, q] = slot_ends(static_cast<int>(cls), slot);
        const auto xi = static_cast<std::int32_t>(x);
        const auto yi = static_cast<std::int32_t>(y);
        const ipoint2 a{xi + (p & 1), yi + (p >> 1)};
        const ipoint2 b{xi + (q & 1), yi + (q >> 1)};
        const double fa = static_cast<double>(s[row + (p & 1) + nx * (p >> 1) + xi]);
        const double fb = static_cast<double>(s[row + (q & 1) + nx * (q >> 1) + xi]);
        const vec2 g = interpolate2(a, fa, b, fb, w);
        out.vertices.push_back({origin[0] + g[0] * spacing[0], origin[1] + g[1] * spacing[1]});
      }
    }
    if (out.vertices.size() > std::numeric_limits<std::uint32_t>::max() - 1) {
      throw error("finest contours: " + std::to_string(out.vertices.size()) +
                  " vertices, beyond what a contour's 32-bit ids can name");
    }
    std::swap(below, above);
  }
  row_first[static_cast<std::size_t>(ny)] = static_cast<std::uint32_t>(out.vertices.size());

  // Pass 2: each crossed square's segments, as links between its edges' vertex ids.
  const std::uint32_t none = ~std::uint32_t{0};
  std::vector<std::uint32_t> next(out.vertices.size(), none);
  std::vector<std::uint8_t> has_in(out.vertices.size(), 0);
  for (std::int64_t y = 0; y + 1 < ny; ++y) {
    const auto uy = static_cast<std::size_t>(y);
    if (row_first[uy + 2] == row_first[uy]) continue;  // no vertex in either row
    const std::uint8_t* c = corners.get() + n * uy;
    const std::array<const std::uint8_t*, 2> m{masks.get() + n * uy, masks.get() + n * (uy + 1)};
    std::array<std::uint32_t, 2> first{row_first[uy], row_first[uy + 1]};
    const std::size_t cls_y = (uy & 1) << 1;
    for (std::size_t x = 0; x + 1 < n; ++x) {
      const square_case& sc = t.cases[cls_y | (x & 1)][c[x]];
      if (sc.count != 0) {
        std::array<std::uint32_t, 4> base{};
        std::array<unsigned, 4> crossed{};
        for (std::size_t j = 0; j < 2; ++j) {
          crossed[2 * j] = m[j][x];
          crossed[2 * j + 1] = m[j][x + 1];
          base[2 * j] = first[j];
          base[2 * j + 1] = first[j] + bit_counts[crossed[2 * j]];
        }
        for (std::size_t k = 0; k < sc.count; ++k) {
          std::array<std::uint32_t, 2> ids{};
          for (std::size_t v = 0; v < 2; ++v) {
            const unsigned edge = sc.segments[k][v];
            const unsigned corner = edge >> 2, slot = edge & 3u;
            ids[v] = base[corner] + bit_counts[crossed[corner] & ((1u << slot) - 1u)];
          }
          next[ids[0]] = ids[1];
          has_in[ids[1]] = 1;
        }
      }
      first[0] += bit_counts[m[0][x]];
      first[1] += bit_counts[m[1][x]];
    }
  }

  // Chaining, as the refiner's extraction chains (detail::contour_assembler::finish()).
  std::vector<std::uint8_t> used(out.vertices.size(), 0);
  const auto walk = [&](std::uint32_t start, bool closed) {
    polyline pl;
    pl.closed = closed;
    pl.isovalue = w;
    for (std::uint32_t v = start; v != none && used[v] == 0; v = next[v]) {
      used[v] = 1;
      pl.vertices.push_back(v);
    }
    if (pl.vertices.size() >= 2) out.polylines.push_back(std::move(pl));
  };
  const auto count = static_cast<std::uint32_t>(out.vertices.size());
  for (std::uint32_t v = 0; v < count; ++v) {
    if (has_in[v] == 0 && next[v] != none) walk(v, false);
  }
  for (std::uint32_t v = 0; v < count; ++v) {
    if (used[v] == 0 && next[v] != none) walk(v, true);
  }
  return out;
}

}  // namespace

contour_set finest_contours(const volume& image, double isovalue) {
  if (image.dims()[2] != 1) {
    throw error("finest contours: expected a 2D image (depth 1), found depth " +
                std::to_string(image.dims()[2]));
  }
  if (!std::isfinite(isovalue)) {
    throw error("finest contours: the isovalue must be finite, found " + std::to_string(isovalue));
  }
  return detail::visit_field(image, [&](const auto samples) {
    return contours_of<std::remove_cv_t<decltype(samples)>>(image, samples, isovalue);
  });
}

}  // namespace progiso
