#include <progiso/core/surface/finest_surface.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <type_traits>
#include <unordered_map>
#include <vector>

#include <progiso/core/base/detail/prefault.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/detail/subdivision.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>
#include <progiso/core/surface/detail/mesh_clip.hpp>
#include <progiso/core/surface/marching.hpp>

namespace progiso {
namespace {

// How a caller (ladder_surface()) may end a call between steps that cannot be interrupted: what
// either throws leaves the call.
struct interrupts {
  // Told the surface's vertex and triangle counts once the first pass has them, before the
  // output is sized (on the calling thread).
  std::function<void(std::uint64_t vertices, std::uint64_t triangles)> sized;
  // Asked between planes of a subsampled copy (with -1), between steps of sizing the output
  // (with the fraction of that array sized so far, from any of the call's threads,
  // concurrently), and once both arrays are sized (with 2, on the calling thread).
  std::function<void(double)> poll;
  // Asked for storage to write the output into, once its size is known (detail::mesh_storage).
  detail::mesh_storage storage;
  // Capacity beyond the output's size in both arrays (a sixteenth, unmapped until used), for a
  // caller that adds to them in place (clip_to_data_box()): growing past capacity would copy
  // the arrays into fresh pages.
  bool slack = false;
  // Corner bytes a slab of z planes may hold (0: finest_slab_planes()'s default).
  std::size_t slab_bytes = 0;
  // Each slab's piece, handed over once written (its vertices follow the last piece's; its
  // triangles name vertices by their ids in the whole surface, some in the next piece): the
  // output then holds one slab at a time, and run() returns an empty mesh.
  std::function<void(triangle_mesh& piece, std::uint64_t first_vertex)> piece;
  // A share of the grid (detail::finest_share): the planes written and their first ids.
  std::int64_t z_begin = 0, z_end = -1;  // z_end −1: to the last plane
  std::uint64_t first_vertex = 0, first_triangle = 0;
  // Counts alone: the share's vertices and triangles, told here; nothing is sized or written.
  std::function<void(std::uint64_t vertices, std::uint64_t triangles)> counted;
  // A grid of more than one slab whose output is kept whole: the vertices and triangles to
  // reserve before its first slab (an estimate; 0: none), so that its output grows slab by slab
  // in place instead of being copied into larger arrays (which briefly holds both).
  std::array<std::uint64_t, 2> expected{0, 0};
};

// A grid point's owned edges, by slot: 0 +x, 1 +y, 2 +z, 3 the diagonal of its xy square,
// 4 of its xz square, 5 of its yz square, 6 of its cube. A cube corner is dx + 2 dy + 4 dz;
// an edge of a cube is (owner corner) · 8 + slot; a cube's parity class is the parity of its
// lowest corner, x + 2 y + 4 z (bits).
constexpr int slots = 7;

/// Set bits of a 7-bit mask (std::popcount compiles to a library call without -mpopcnt).
constexpr std::array<std::uint8_t, 128> bit_counts = [] {
  std::array<std::uint8_t, 128> c{};
  for (unsigned m = 0; m < 128; ++m) c[m] = static_cast<std::uint8_t>(std::popcount(m));
  return c;
}();
inline unsigned bits(unsigned m) noexcept { return bit_counts[m & 127u]; }

struct cube_case {
  std::uint8_t count = 0;
  std::array<std::array<std::uint8_t, 3>, 12> triangles{};  // cube edges
};

struct tables {
  std::array<std::array<cube_case, 256>, 8> cases{};
  /// cases[…][…].count alone: the first pass reads only these, a small fraction of `cases`.
  std::array<std::array<std::uint8_t, 256>, 8> counts{};
  /// The owned edges a point crosses, from its cube's corner colours (corners beyond the data
  /// box as white; the caller masks the slots whose ends are not there).
  std::array<std::array<std::uint8_t, 256>, 8> crossed{};
};

/// The two ends of slot `k` of a point of parity `cls`, as corner offsets of its cube.
constexpr std::array<int, 2> slot_ends(int cls, int k) noexcept {
  const int px = cls & 1, py = (cls >> 1) & 1, pz = (cls >> 2) & 1;
  switch (k) {
    case 0:
      return {0, 1};
    case 1:
      return {0, 2};
    case 2:
      return {0, 4};
    case 3:  // the square's even corner to its opposite: (0,0)-(1,1) when x + y is even
      return (px ^ py) == 0 ? std::array<int, 2>{0, 3} : std::array<int, 2>{1, 2};
    case 4:
      return (px ^ pz) == 0 ? std::array<int, 2>{0, 5} : std::array<int, 2>{1, 4};
    case 5:
      return (py ^ pz) == 0 ? std::array<int, 2>{0, 6} : std::array<int, 2>{2, 4};
    default: {  // the cube's all-even corner to the all-odd one
      const int even = px | (py << 1) | (pz << 2);
      return {even, 7 - even};
    }
  }
}

tables make_tables() {
  tables t;
  for (int cls = 0; cls < 8; ++cls) {
    const ipoint b{cls & 1, (cls >> 1) & 1, (cls >> 2) & 1};
    for (int mask = 0; mask < 256; ++mask) {
      std::uint8_t crossed = 0;
      for (int k = 0; k < slots; ++k) {
        const auto [p, q] = slot_ends(cls, k);
        if (((mask >> p) & 1) != ((mask >> q) & 1)) crossed |= static_cast<std::uint8_t>(1u << k);
      }
      t.crossed[static_cast<std::size_t>(cls)][static_cast<std::size_t>(mask)] = crossed;
      // The six tetrahedra of the unit cube, as full refinement leaves them; colours from the
      // mask (1 above the isovalue 0, −1 at or below).
      const auto value = [&](const ipoint& p) {
        const int corner = (p[0] - b[0]) + 2 * (p[1] - b[1]) + 4 * (p[2] - b[2]);
        return ((mask >> corner) & 1) != 0 ? 1.0 : -1.0;
      };
      cube_case& c = t.cases[static_cast<std::size_t>(cls)][static_cast<std::size_t>(mask)];
      std::uint8_t& count = t.counts[static_cast<std::size_t>(cls)][static_cast<std::size_t>(mask)];
      for (const std::array<ipoint, 4>& tet : cube_tetrahedra(b, 1)) {
        std::array<double, 4> f{};
        for (std::size_t k = 0; k < 4; ++k) f[k] = value(tet[k]);
        const tet_surface s = march_tet(tet, f, 0.0);
        count = static_cast<std::uint8_t>(count + s.count);
        for (int n = 0; n < s.count; ++n) {
          auto& out = c.triangles[c.count++];
          for (std::size_t v = 0; v < 3; ++v) {
            // The edge's doubled midpoint, relative to the cube: odd along the edge's axes.
            const ipoint m = edge_key_point(s.triangles[static_cast<std::size_t>(n)][v]);
            int corner = 0;
            int axes = 0;
            for (std::size_t a = 0; a < 3; ++a) {
              const int local = m[a] - 2 * b[a];  // 0, 1 or 2
              if (local == 1) axes |= 1 << a;
              if (local == 2) corner |= 1 << a;
            }
            static constexpr int slot_of_axes[8] = {-1, 0, 1, 3, 2, 4, 5, 6};
            out[v] = static_cast<std::uint8_t>((corner << 3) | slot_of_axes[axes]);
          }
        }
      }
    }
  }
  return t;
}

/// slot_ends() for every parity class and slot.
constexpr auto slot_end_table = [] {
  std::array<std::array<std::array<std::uint8_t, 2>, slots>, 8> t{};
  for (int cls = 0; cls < 8; ++cls) {
    for (int k = 0; k < slots; ++k) {
      const auto [p, q] = slot_ends(cls, k);
      t[static_cast<std::size_t>(cls)][static_cast<std::size_t>(k)] = {
          static_cast<std::uint8_t>(p), static_cast<std::uint8_t>(q)};
    }
  }
  return t;
}();

const tables& the_tables() {
  static const tables t = make_tables();
  return t;
}

/// Rows done, passed on to a finest_progress one call at a time (see finest_surface.hpp).
class progress_relay {
 public:
  static constexpr std::size_t step = 64;  // rows between reports

  progress_relay(const finest_progress& to, std::uint64_t total) : to_(to), total_(total) {}

  [[nodiscard]] bool active() const noexcept { return static_cast<bool>(to_); }

  /// `rows` more rows done; tells the callback unless another thread is telling it now.
  void add(std::uint64_t rows) {
    // relaxed: a count; the mutex below orders the calls and what they are told.
    const std::uint64_t done = done_.fetch_add(rows, std::memory_order_relaxed) + rows;
    const std::unique_lock lock(mutex_, std::try_to_lock);
    if (!lock.owns_lock()) return;
    told_ = std::max(told_, done);
    to_(told_, total_);
  }

  /// The last report, on the calling thread once both passes are over.
  void finish() {
    const std::lock_guard lock(mutex_);
    told_ = total_;
    to_(total_, total_);
  }

 private:
  const finest_progress& to_;
  std::uint64_t total_;
  std::atomic<std::uint64_t> done_{0};
  std::mutex mutex_;
  std::uint64_t told_ = 0;  // under mutex_
};

/// Eight bytes from p (any alignment).
inline std::uint64_t load8(const std::uint8_t* p) noexcept {
  std::uint64_t v = 0;
  std::memcpy(&v, p, sizeof v);
  return v;
}

/// uniform_surface()'s grid in the field's: every `stride`-th sample along each axis, and the
/// last.
struct strided_grid {
  std::int64_t stride;
  index3 dims;  // the field's

  /// The field's index of grid point k along axis q.
  [[nodiscard]] std::int64_t field_index(std::size_t q, std::int64_t k) const noexcept {
    return std::min<std::int64_t>(k * stride, dims[q] - 1);
  }
  /// The field's index of the first sample of row (y, z).
  [[nodiscard]] std::int64_t row_start(std::int64_t y, std::int64_t z) const noexcept {
    return dims[0] * (field_index(1, y) + dims[1] * field_index(2, z));
  }
};

/// That grid's samples read in place: by point (x, y, z), and by rows through row(), so the
/// colour pass reads the field's samples with a stride instead of a copy of them (which took
/// 1 / stride³ of the volume's bytes beside it).
template <class T>
struct strided_samples : strided_grid {
  const T* src;

  [[nodiscard]] T at(std::int64_t x, std::int64_t y, std::int64_t z) const noexcept {
    return src[field_index(0, x) + row_start(y, z)];
  }
  [[nodiscard]] const T* row(std::int64_t y, std::int64_t z) const noexcept {
    return src + row_start(y, z);
  }
};

template <class S>
inline constexpr bool is_strided_v = false;
template <class T>
inline constexpr bool is_strided_v<strided_samples<T>> = true;

template <class S>
class finest_mesher {
 public:
  // The grid of `samples` (x fastest), placed at origin + index × spacing.
  finest_mesher(const index3& d, const std::array<double, 3>& spacing,
                const std::array<double, 3>& origin, S samples, double w)
      : spacing_(spacing), origin_(origin), s_(samples), w_(w), t_(the_tables()) {
    nx_ = d[0];
    ny_ = d[1];
    nz_ = d[2];
    rows_ = static_cast<std::size_t>(ny_ * nz_);
  }

  // Mesh: triangle_mesh (double positions), or detail::float_mesh (float positions, without
  // normals or the storage, slack and poll hooks, which serve the engine's cuts).
  //
  // In slabs of z planes (detail::finest_slab_planes()): each slab's first pass also covers the
  // plane after it (its cubes' triangles name that plane's vertices), whose counts then give the
  // next slab its first ids; so the corner bytes and row counts held are one slab's, and the ids
  // are those of a single slab over the whole grid. A grid of one slab is sized at once, with
  // every hook (size_whole()); one of more slabs grows its output slab by slab in fresh memory,
  // asking `poll` (with −1) before each slab, and tells neither `sized` nor `storage` nor makes
  // `slack` (a whole grid's corner bytes, held to size its output at once, would outweigh it).
  template <class Mesh = triangle_mesh>
  Mesh run(const parallel_loop& loop, std::size_t parts, const finest_progress& to,
           const interrupts& stop = {}) {
    const auto plane = static_cast<std::size_t>(ny_);
    const auto z_begin = static_cast<std::size_t>(stop.z_begin);
    const auto z_end = static_cast<std::size_t>(stop.z_end < 0 ? nz_ : stop.z_end);
    PROGISO_ASSERT(z_begin <= z_end && z_end <= static_cast<std::size_t>(nz_));
    const bool whole = z_begin == 0 && z_end == static_cast<std::size_t>(nz_);
    // A share's slabs are no larger than the share: what a rank or a window holds follows its
    // planes, not the grid's.
    const auto planes = static_cast<std::size_t>(std::min<std::int64_t>(
        detail::finest_slab_planes({nx_, ny_, nz_}, stop.slab_bytes),
        std::max<std::int64_t>(1, static_cast<std::int64_t>(z_end - z_begin))));
    const std::size_t slabs = (z_end - z_begin + planes - 1) / planes;
    // A slab's planes, and the one after it when there is one (the next slab's, or the next
    // share's).
    const std::size_t held =
        std::min(static_cast<std::size_t>(nz_) - z_begin,
                 planes + (z_end < static_cast<std::size_t>(nz_) || slabs > 1 ? 1 : 0));
    const std::size_t held_bytes = static_cast<std::size_t>(nx_) * plane * held;
    // Written by each first pass, every byte (not zeroed first: a byte per sample).
    corners_ = std::make_unique_for_overwrite<std::uint8_t[]>(held_bytes);
    row_vertices_.assign(plane * held + 1, 0);
    row_triangles_.assign(plane * held + 1, 0);
    parts = std::max<std::size_t>(1, std::min(parts, rows_));
    // Both passes' rows, and the plane after each slab that has one, counted twice.
    const std::size_t after = slabs - (z_end == static_cast<std::size_t>(nz_) && slabs > 0 ? 1 : 0);
    progress_relay progress(
        to, (stop.counted ? 1 : 2) * static_cast<std::uint64_t>((z_end - z_begin) * plane) +
                after * plane);
    // Rows [first, last) of the second pass, `step` rows at a time, each step reported.
    const auto in_steps = [&](std::size_t first, std::size_t last, const auto& pass) {
      if (!progress.active()) {
        pass(first, last);
        return;
      }
      for (std::size_t r = first; r < last; r += progress_relay::step) {
        const std::size_t end = std::min(last, r + progress_relay::step);
        pass(r, end);
        progress.add(end - r);
      }
    };
    // The corner bytes' pages mapped before the first pass writes them all (prefault.hpp); not
    // when the caller polls: mapping a large grid's corner bytes in one go would keep the poll
    // waiting too long.
    if (!stop.poll) detail::prefault_in_parts(loop, parts, corners_.get(), held_bytes);
    Mesh mesh{};
    // The slab's first ids.
    std::uint64_t first_vertex = stop.first_vertex, first_triangle = stop.first_triangle;
    for (std::size_t slab = 0; slab < slabs; ++slab) {
      if (slabs > 1 && stop.poll) stop.poll(-1.0);
      base_ = (z_begin + slab * planes) * plane;
      const std::size_t written = std::min(z_end * plane, base_ + planes * plane);  // pass 2's rows
      const std::size_t counted = std::min(rows_, written + plane);
      const std::size_t rows = counted - base_;
      const std::size_t pieces = std::max<std::size_t>(1, std::min(parts, rows));
      run_loop(loop, pieces, [&](std::size_t k) {
        count_rows(base_ + piece_begin(rows, pieces, k), base_ + piece_begin(rows, pieces, k + 1),
                   progress);
      });
      // Each held row's first vertex and triangle.
      std::uint64_t v = first_vertex, t = first_triangle;
      for (std::size_t r = 0; r <= rows; ++r) {
        const std::uint64_t nv = r < rows ? row_vertices_[r] : 0;
        const std::uint64_t nt = r < rows ? row_triangles_[r] : 0;
        row_vertices_[r] = v;
        row_triangles_[r] = t;
        v += nv;
        t += nt;
      }
      if (v > std::numeric_limits<std::uint32_t>::max()) {
        throw error("finest surface: " + std::to_string(v) +
                    " vertices, beyond the 2^32 a mesh's 32-bit ids can name");
      }
      const std::uint64_t next_vertex = vertex_id(written);
      const std::uint64_t next_triangle = row_triangles_[written - base_];
      if (stop.counted) {  // counts alone
        first_vertex = next_vertex;
        first_triangle = next_triangle;
        continue;
      }
      if (slabs == 1 && whole && !stop.piece) {
        size_whole(loop, parts, mesh, next_vertex, next_triangle, stop);
      } else if (stop.piece) {
        out_vertex_ = first_vertex;
        out_triangle_ = first_triangle;
        mesh.vertices.resize(static_cast<std::size_t>(next_vertex - first_vertex));
        mesh.triangles.resize(static_cast<std::size_t>(next_triangle - first_triangle));
      } else {
        if (slab == 0) {
          mesh.vertices.reserve(static_cast<std::size_t>(stop.expected[0]));
          mesh.triangles.reserve(static_cast<std::size_t>(stop.expected[1]));
        }
        mesh.vertices.resize(static_cast<std::size_t>(next_vertex));
        mesh.triangles.resize(static_cast<std::size_t>(next_triangle));
      }
      const std::size_t rows_written = written - base_;
      const std::size_t writers = std::max<std::size_t>(1, std::min(parts, rows_written));
      run_loop(loop, writers, [&](std::size_t k) {
        in_steps(base_ + piece_begin(rows_written, writers, k),
                 base_ + piece_begin(rows_written, writers, k + 1),
                 [&](std::size_t first, std::size_t last) {
                   for (std::size_t r = first; r < last; ++r) {
                     write_vertices(r, mesh);
                     write_triangles(r, mesh);
                   }
                 });
      });
      if constexpr (std::is_same_v<Mesh, triangle_mesh>) {
        if (stop.piece) {
          stop.piece(mesh, first_vertex);
          mesh.vertices.clear();
          mesh.triangles.clear();
          mesh.normals.clear();
        }
      }
      first_vertex = next_vertex;
      first_triangle = next_triangle;
    }
    if (stop.counted)
      stop.counted(first_vertex - stop.first_vertex, first_triangle - stop.first_triangle);
    // The corner bytes are read no more: their pages freed by slices over the threads, not
    // one by one on this thread by the destructor (release_in_parts()).
    detail::release_in_parts(loop, parts, corners_.get(), held_bytes);
    if (progress.active()) progress.finish();
    return mesh;
  }

 private:
  // The whole output of a single slab sized at once, `nv` vertices and `nt` triangles, into
  // capacity whose pages are mapped first (prefault.hpp): a std::vector zeroes what it sizes,
  // and zeroing fresh pages took a fault per page, one array per thread, which made sizing a
  // large field's output a long step, slower still on two threads (bench/README.md). Mapped in
  // slices over the threads, then zeroed side by side. In steps of 1 M elements, each mapped
  // then zeroed, when the caller polls between them. Recycled storage, when the caller has
  // some (`mesh` came from stop.storage): its pages are mapped already, so sizing and writing it
  // fault nothing, and nothing was unmapped to make room for it.
  template <class Mesh>
  static void size_whole(const parallel_loop& loop, std::size_t parts, Mesh& mesh, std::uint64_t nv,
                         std::uint64_t nt, const interrupts& stop) {
    if (stop.sized) stop.sized(nv, nt);
    if constexpr (std::is_same_v<Mesh, triangle_mesh>) {
      if (stop.storage) mesh = stop.storage(nv, nt);
      mesh.vertices.clear();
      mesh.triangles.clear();
      mesh.normals.clear();
    }
    const auto size = [&stop](auto& array, std::uint64_t n) {
      using element = typename std::remove_reference_t<decltype(array)>::value_type;
      if (!stop.poll) {
        array.resize(static_cast<std::size_t>(n));
        return;
      }
      constexpr std::size_t step = std::size_t{1} << 20;
      while (array.size() < n) {
        stop.poll(static_cast<double>(array.size()) / static_cast<double>(n));
        const std::size_t next = std::min(static_cast<std::size_t>(n), array.size() + step);
        detail::prefault(array.data() + array.size(), (next - array.size()) * sizeof(element));
        array.resize(next);
      }
    };
    mesh.vertices.reserve(static_cast<std::size_t>(nv + (stop.slack ? nv / 16 + 64 : 0)));
    mesh.triangles.reserve(static_cast<std::size_t>(nt + (stop.slack ? nt / 16 + 64 : 0)));
    if (!stop.poll) {
      detail::prefault_in_parts(loop, parts, mesh.vertices.data(),
                                static_cast<std::size_t>(nv) * sizeof(mesh.vertices[0]));
      detail::prefault_in_parts(loop, parts, mesh.triangles.data(),
                                static_cast<std::size_t>(nt) * sizeof(mesh.triangles[0]));
    }
    run_loop(loop, 2, [&](std::size_t k) {
      if (k == 0) {
        size(mesh.vertices, nv);
      } else {
        size(mesh.triangles, nt);
      }
    });
    if (stop.poll) stop.poll(2.0);
  }

  // Row r's (a held row's) corner bytes, and its first vertex and triangle ids.
  [[nodiscard]] std::uint8_t* corner_row(std::size_t r) const noexcept {
    return corners_.get() + static_cast<std::size_t>(nx_) * (r - base_);
  }
  [[nodiscard]] std::uint64_t vertex_id(std::size_t r) const noexcept {
    return row_vertices_[r - base_];
  }
  [[nodiscard]] std::uint64_t triangle_id(std::size_t r) const noexcept {
    return row_triangles_[r - base_];
  }

  [[nodiscard]] bool black(std::int64_t i) const noexcept requires(!is_strided_v<S>) {
    return static_cast<double>(s_[i]) > w_;
  }

  // The sample of grid point p, at index i of the grid.
  [[nodiscard]] double value(std::int64_t i, const ipoint& p) const noexcept {
    if constexpr (is_strided_v<S>) {
      return static_cast<double>(s_.at(p[0], p[1], p[2]));
    } else {
      return static_cast<double>(s_[i]);
    }
  }

  // Colour pairs of row (y, z): bit 0 the colour of point x (1 above the isovalue), bit 1 that
  // of point x + 1 (0 past the end).
  void colour_row(std::int64_t y, std::int64_t z, std::vector<std::uint8_t>& out) const {
    const auto n = static_cast<std::size_t>(nx_);
    std::uint8_t* o = out.data();
    if constexpr (is_strided_v<S>) {
      const auto* p = s_.row(y, z);
      const auto stride = static_cast<std::size_t>(s_.stride);
      for (std::size_t x = 0; x + 1 < n; ++x) o[x] = static_cast<double>(p[x * stride]) > w_;
      o[n - 1] = static_cast<double>(p[s_.dims[0] - 1]) > w_;
    } else {
      const std::int64_t row = nx_ * (y + ny_ * z);
      for (std::size_t x = 0; x < n; ++x) {
        o[x] = black(row + static_cast<std::int64_t>(x)) ? 1 : 0;
      }
    }
    for (std::size_t x = 0; x + 1 < n; ++x)
      o[x] = static_cast<std::uint8_t>(o[x] | (o[x + 1] << 1));
  }

  // What a row's points cross, from their corner bytes (point_masks::at()): the table of their
  // parity and the slots whose ends exist in the row.
  struct point_masks {
    const std::uint8_t* corners;
    const std::array<std::uint8_t, 256>* crossed[2];  // for even and odd x
    unsigned valid, valid_last;
    std::size_t last;
    [[nodiscard]] unsigned at(std::size_t x) const noexcept {
      return (*crossed[x & 1])[corners[x]] & (x == last ? valid_last : valid);
    }
    /// Whether points x … x + 7 (all before the last) cross nothing: one colour each.
    [[nodiscard]] bool uniform8(std::size_t x) const noexcept {
      const std::uint64_t v = load8(corners + x);
      return v == 0 || v == ~std::uint64_t{0};
    }
  };
  [[nodiscard]] point_masks masks_of(std::size_t r) const noexcept {
    const auto n = static_cast<std::size_t>(nx_);
    const auto y = static_cast<std::int64_t>(r) % ny_;
    const auto z = static_cast<std::int64_t>(r) / ny_;
    const bool up_y = y + 1 < ny_, up_z = z + 1 < nz_;
    const auto cls_yz = static_cast<std::size_t>(((y & 1) << 1) | ((z & 1) << 2));
    point_masks m{};
    m.corners = corner_row(r);
    m.crossed[0] = &t_.crossed[cls_yz];
    m.crossed[1] = &t_.crossed[cls_yz | 1];
    // Slots whose ends exist, with and without the next point along x.
    m.valid_last =
        (up_y ? 0b0000010u : 0u) | (up_z ? 0b0000100u : 0u) | (up_y && up_z ? 0b0100000u : 0u);
    m.valid = m.valid_last | 0b0000001u | (up_y ? 0b0001000u : 0u) | (up_z ? 0b0010000u : 0u) |
              (up_y && up_z ? 0b1000000u : 0u);
    m.last = n - 1;
    return m;
  }

  // Pass 1 over rows [first, last): each point's cube corners (colours of the eight corners,
  // corner dx + 2 dy + 4 dz as bit), the owned edges it crosses, and each row's vertices and
  // the triangles of its cubes. Colour rows are made once and shared by the rows beside them.
  // Every `progress_relay::step` rows and at the end, the rows done go to `progress`.
  void count_rows(std::size_t first, std::size_t last, progress_relay& progress) {
    const auto n = static_cast<std::size_t>(nx_);
    std::size_t unreported = 0;
    // Colour pairs of the rows (y, z), (y + 1, z), (y, z + 1), (y + 1, z + 1).
    std::array<std::vector<std::uint8_t>, 4> c;
    for (auto& row : c) row.assign(n, 0);
    for (std::size_t r = first; r < last; ++r) {
      const auto y = static_cast<std::int64_t>(r) % ny_;
      const auto z = static_cast<std::int64_t>(r) / ny_;
      const bool up_y = y + 1 < ny_, up_z = z + 1 < nz_;
      if (r == first || y == 0) {
        colour_row(y, z, c[0]);
        if (up_z) colour_row(y, z + 1, c[2]);
      } else {
        std::swap(c[0], c[1]);
        std::swap(c[2], c[3]);
      }
      if (up_y) {
        colour_row(y + 1, z, c[1]);
      } else {
        std::fill(c[1].begin(), c[1].end(), std::uint8_t{0});
      }
      if (up_y && up_z) {
        colour_row(y + 1, z + 1, c[3]);
      } else {
        std::fill(c[3].begin(), c[3].end(), std::uint8_t{0});
      }
      if (!up_z) {
        std::fill(c[2].begin(), c[2].end(), std::uint8_t{0});
      }
      // Corners of the cube at each x (at the last x: the corners dx = 0 alone).
      std::uint8_t* corners = corner_row(r);
      const std::uint8_t *c0 = c[0].data(), *c1 = c[1].data(), *c2 = c[2].data(), *c3 = c[3].data();
      for (std::size_t x = 0; x < n; ++x) {
        corners[x] = static_cast<std::uint8_t>(c0[x] | (c1[x] << 2) | (c2[x] << 4) | (c3[x] << 6));
      }
      const point_masks masks = masks_of(r);
      const bool cubes = up_y && up_z;
      const std::size_t cls_yz = static_cast<std::size_t>(((y & 1) << 1) | ((z & 1) << 2));
      std::uint64_t vertices = 0, triangles = 0;
      std::size_t x = 0;
      while (x + 1 < n) {
        if (x + 9 <= n && masks.uniform8(x)) {  // eight cubes of one colour cross nothing
          x += 8;
          continue;
        }
        vertices += bits(masks.at(x));
        if (cubes) triangles += t_.counts[cls_yz | (x & 1)][corners[x]];
        ++x;
      }
      vertices += bits(masks.at(n - 1));  // no cube beyond the last point
      row_vertices_[r - base_] = vertices;
      row_triangles_[r - base_] = triangles;
      if (++unreported == progress_relay::step || r + 1 == last) {
        if (progress.active()) progress.add(unreported);
        unreported = 0;
      }
    }
  }

  // Pass 2: row r's vertex positions.
  template <class Mesh>
  void write_vertices(std::size_t r, Mesh& mesh) const {
    if (vertex_id(r + 1) == vertex_id(r)) return;
    const auto n = static_cast<std::size_t>(nx_);
    const auto y = static_cast<std::int64_t>(r) % ny_;
    const auto z = static_cast<std::int64_t>(r) / ny_;
    const std::int64_t row = nx_ * static_cast<std::int64_t>(r);
    const std::int64_t dy = nx_, dz = nx_ * ny_;
    const point_masks masks = masks_of(r);
    const std::array<std::int64_t, 8> offset{0, 1, dy, dy + 1, dz, dz + 1, dy + dz, dy + dz + 1};
    auto id = static_cast<std::size_t>(vertex_id(r) - out_vertex_);
    for (std::size_t x = 0; x < n; ++x) {
      if (x + 9 <= n && masks.uniform8(x)) {
        x += 7;
        continue;
      }
      unsigned m = masks.at(x);
      const int cls = static_cast<int>((x & 1) | static_cast<std::size_t>((y & 1) << 1) |
                                       static_cast<std::size_t>((z & 1) << 2));
      const auto xi = static_cast<std::int64_t>(x);
      while (m != 0) {
        const int k = std::countr_zero(m);
        m &= m - 1;
        const auto [p, q] =
            slot_end_table[static_cast<std::size_t>(cls)][static_cast<std::size_t>(k)];
        const ipoint a{static_cast<std::int32_t>(xi + (p & 1)),
                       static_cast<std::int32_t>(y + ((p >> 1) & 1)),
                       static_cast<std::int32_t>(z + (p >> 2))};
        const ipoint b{static_cast<std::int32_t>(xi + (q & 1)),
                       static_cast<std::int32_t>(y + ((q >> 1) & 1)),
                       static_cast<std::int32_t>(z + (q >> 2))};
        const double fa = value(row + xi + offset[static_cast<std::size_t>(p)], a);
        const double fb = value(row + xi + offset[static_cast<std::size_t>(q)], b);
        const vec3 at = interpolate(a, fa, b, fb, w_);
        const vec3 pos{origin_[0] + at[0] * spacing_[0], origin_[1] + at[1] * spacing_[1],
                       origin_[2] + at[2] * spacing_[2]};
        if constexpr (std::is_same_v<Mesh, triangle_mesh>) {
          mesh.vertices[id++] = pos;
        } else {
          mesh.vertices[id++] = {static_cast<float>(pos[0]), static_cast<float>(pos[1]),
                                 static_cast<float>(pos[2])};
        }
      }
    }
  }

  // Pass 2: the triangles of the cubes between point rows r, r + 1 (y + 1), r + ny (z + 1) and
  // r + ny + 1, each vertex's id being its owner row's first id plus the crossed edges before it
  // in that row (counted forward as the cubes advance, eight empty points at a time).
  template <class Mesh>
  void write_triangles(std::size_t r, Mesh& mesh) const {
    const auto y = static_cast<std::int64_t>(r) % ny_;
    const auto z = static_cast<std::int64_t>(r) / ny_;
    if (y + 1 >= ny_ || z + 1 >= nz_ || triangle_id(r + 1) == triangle_id(r)) return;
    const auto n = static_cast<std::size_t>(nx_);
    const std::array<std::size_t, 4> rows{r, r + 1, r + static_cast<std::size_t>(ny_),
                                          r + static_cast<std::size_t>(ny_) + 1};
    std::array<point_masks, 4> masks{};
    std::array<std::uint64_t, 4> first{};  // the first id of point pos[j] in row j
    std::array<std::size_t, 4> pos{};
    for (std::size_t j = 0; j < 4; ++j) {
      masks[j] = masks_of(rows[j]);
      first[j] = vertex_id(rows[j]);
    }
    const auto advance = [&](std::size_t j, std::size_t to) {
      std::size_t p = pos[j];
      std::uint64_t f = first[j];
      const point_masks& m = masks[j];
      while (p < to) {
        if (p + 8 <= to && m.uniform8(p)) {
          p += 8;
        } else {
          f += bits(m.at(p));
          ++p;
        }
      }
      pos[j] = p;
      first[j] = f;
    };
    const std::uint8_t* corners = corner_row(r);
    auto out = static_cast<std::size_t>(triangle_id(r) - out_triangle_);
    const std::size_t cls_yz = static_cast<std::size_t>(((y & 1) << 1) | ((z & 1) << 2));
    for (std::size_t x = 0; x + 1 < n; ++x) {
      if (x + 9 <= n) {
        const std::uint64_t v = load8(corners + x);
        if (v == 0 || v == ~std::uint64_t{0}) {
          x += 7;
          continue;
        }
      }
      const unsigned k = corners[x];
      const std::size_t cls = cls_yz | (x & 1);
      const cube_case& c = t_.cases[cls][k];
      if (c.count == 0) continue;
      for (std::size_t j = 0; j < 4; ++j) advance(j, x);
      // The first id and the crossed edges of each corner's point.
      std::array<std::uint64_t, 8> base{};
      std::array<unsigned, 8> crossed{};
      for (std::size_t j = 0; j < 4; ++j) {
        crossed[2 * j] = masks[j].at(x);
        crossed[2 * j + 1] = masks[j].at(x + 1);
        base[2 * j] = first[j];
        base[2 * j + 1] = first[j] + bits(crossed[2 * j]);
      }
      for (std::size_t t = 0; t < c.count; ++t) {
        std::array<std::uint32_t, 3>& tri = mesh.triangles[out++];
        for (std::size_t v = 0; v < 3; ++v) {
          const unsigned edge = c.triangles[t][v];
          const unsigned corner = edge >> 3, slot = edge & 7u;
          tri[v] = static_cast<std::uint32_t>(base[corner] +
                                              bits(crossed[corner] & ((1u << slot) - 1u)));
        }
      }
    }
  }

  std::array<double, 3> spacing_;
  std::array<double, 3> origin_;
  S s_;
  double w_;
  const tables& t_;
  std::int64_t nx_ = 0, ny_ = 0, nz_ = 0;
  std::size_t rows_ = 0;
  // Of the held rows, from row base_ (the slab's first): the corner colours of the cube at each
  // point, and each row's vertex and triangle counts, then (after the prefix sums) first ids.
  std::size_t base_ = 0;
  std::unique_ptr<std::uint8_t[]> corners_;
  std::vector<std::uint64_t> row_vertices_;
  std::vector<std::uint64_t> row_triangles_;
  // The ids of the output's first vertex and triangle (a piece's, in the whole surface).
  std::uint64_t out_vertex_ = 0, out_triangle_ = 0;
};

}  // namespace

namespace {

// Mesh: triangle_mesh, or detail::float_mesh (finest_mesher::run()).
template <class Mesh = triangle_mesh>
Mesh finest_surface_hooked(const volume& field, double isovalue, const parallel_loop& run,
                           std::size_t parts, const finest_progress& progress,
                           const interrupts& stop) {
  if (!std::isfinite(isovalue)) {
    throw error("finest surface: the isovalue must be finite, found " + std::to_string(isovalue));
  }
  return detail::visit_field(field, [&](const auto samples) {
    finest_mesher<std::remove_cv_t<decltype(samples)>> m(field.dims(), field.spacing(),
                                                         field.origin(), samples, isovalue);
    return m.template run<Mesh>(run, parts, progress, stop);
  });
}

}  // namespace

triangle_mesh finest_surface(const volume& field, double isovalue, const parallel_loop& run,
                             std::size_t parts, const finest_progress& progress) {
  return finest_surface_hooked(field, isovalue, run, parts, progress, {});
}

triangle_mesh detail::finest_surface(const volume& field, double isovalue, const parallel_loop& run,
                                     std::size_t parts, const finest_progress& progress,
                                     const mesh_storage& storage) {
  interrupts hooks;
  hooks.storage = storage;
  return finest_surface_hooked(field, isovalue, run, parts, progress, hooks);
}

detail::float_mesh detail::finest_surface_floats(const volume& field, double isovalue,
                                                 const parallel_loop& run, std::size_t parts,
                                                 const finest_progress& progress,
                                                 std::size_t slab_bytes) {
  interrupts hooks;
  hooks.slab_bytes = slab_bytes;
  return finest_surface_hooked<float_mesh>(field, isovalue, run, parts, progress, hooks);
}

std::int64_t detail::finest_slab_planes(const index3& dims, std::size_t slab_bytes) noexcept {
  const std::uint64_t plane = static_cast<std::uint64_t>(std::max<std::int64_t>(1, dims[0])) *
                              static_cast<std::uint64_t>(std::max<std::int64_t>(1, dims[1]));
  const auto nz = std::max<std::int64_t>(1, dims[2]);
  if (slab_bytes == 0) {
    if (plane * static_cast<std::uint64_t>(nz) <= finest_whole_grid_bytes) return nz;
    slab_bytes = finest_slab_bytes;
  }
  return std::clamp<std::int64_t>(static_cast<std::int64_t>(slab_bytes / plane), 1, nz);
}

namespace {

// The share's planes, checked.
void check_share(const volume& field, const detail::finest_share& share) {
  const std::int64_t nz = field.dims()[2];
  const std::int64_t end = share.z_end < 0 ? nz : share.z_end;
  if (share.z_begin < 0 || share.z_begin > end || end > nz) {
    throw error("finest surface: planes [" + std::to_string(share.z_begin) + ", " +
                std::to_string(end) + ") are not a share of the " + std::to_string(nz) +
                " planes of the grid");
  }
}

}  // namespace

std::array<std::uint64_t, 2> detail::finest_share_counts(const volume& field, double isovalue,
                                                         const parallel_loop& run,
                                                         std::size_t parts,
                                                         const finest_share& share,
                                                         std::size_t slab_bytes) {
  check_share(field, share);
  std::array<std::uint64_t, 2> counts{};
  interrupts hooks;
  hooks.slab_bytes = slab_bytes;
  hooks.z_begin = share.z_begin;
  hooks.z_end = share.z_end;
  hooks.counted = [&counts](std::uint64_t v, std::uint64_t t) { counts = {v, t}; };
  (void)finest_surface_hooked(field, isovalue, run, parts, {}, hooks);
  return counts;
}

void detail::finest_surface_pieces(const volume& field, double isovalue, const parallel_loop& run,
                                   std::size_t parts, const finest_progress& progress,
                                   const finest_piece& piece, std::size_t slab_bytes,
                                   const finest_share& share) {
  PROGISO_ASSERT(piece);
  check_share(field, share);
  interrupts hooks;
  hooks.slab_bytes = slab_bytes;
  const bool all = share.z_begin == 0 && (share.z_end < 0 || share.z_end == field.dims()[2]) &&
                   share.first_vertex == 0 && share.first_triangle == 0;
  // One slab of the whole grid: its piece is the whole surface.
  if (all && finest_slab_planes(field.dims(), slab_bytes) >= field.dims()[2]) {
    triangle_mesh whole = finest_surface_hooked(field, isovalue, run, parts, progress, hooks);
    piece(whole, 0);
    return;
  }
  hooks.piece = piece;
  hooks.z_begin = share.z_begin;
  hooks.z_end = share.z_end;
  hooks.first_vertex = share.first_vertex;
  hooks.first_triangle = share.first_triangle;
  (void)finest_surface_hooked(field, isovalue, run, parts, progress, hooks);
}

index3 uniform_grid_dims(const index3& dims, std::int32_t stride) noexcept {
  index3 sub{};
  for (std::size_t q = 0; q < 3; ++q) sub[q] = dims[q] < 2 ? dims[q] : (dims[q] - 2) / stride + 2;
  return sub;
}

namespace {

// Grid index along one axis of the subsampled grid → index of the field's grid, for a vertex
// position p of the subsampled grid (in its index frame). Cells before the last are `stride`
// wide, so p × stride (exact: a power of two), the ends of a vertex's edge scaled exactly as
// refinement has them; the last cell runs from (k − 1) × stride to the last index, so a
// position there is mapped linearly, and a position on a grid plane (an integer) to its index.
double field_index(double p, std::int64_t sub_n, std::int64_t n, std::int32_t stride) noexcept {
  const auto last_cell = static_cast<double>(sub_n - 2);
  if ((sub_n - 1) * stride == n - 1 || p <= last_cell) return p * stride;
  if (p == std::floor(p)) return static_cast<double>(n - 1);
  const double from = last_cell * stride;
  return from + (p - last_cell) * (static_cast<double>(n - 1) - from);
}

// A mesh in the field's grid frame clipped to the data box [0, dims − 1], as cut_mesher clips a
// cut's pieces (clip_to_box(): a crossing point computed from the segment's ordered ends, one
// vertex per position), in place: only the last layer of cells along an axis reaches past the
// box, so the whole mesh is read once in parallel parts (its corners marked outside or not, its
// triangles tested by those marks) and written only where it changes. A clipped triangle's slot
// takes its first piece, or, when it has none, a further piece of another or else the last
// triangle;
// vertices no triangle uses any more — every one outside the box, and a clipped triangle's
// corner on the box that no piece kept, when nothing else uses it — are dropped by one renaming
// pass, the rest keeping their order. The same result for every part count.
void clip_to_data_box(triangle_mesh& mesh, const index3& dims, const parallel_loop& run,
                      std::size_t parts) {
  using tri = std::array<std::uint32_t, 3>;
  const vec3 box{static_cast<double>(dims[0] - 1), static_cast<double>(dims[1] - 1),
                 static_cast<double>(dims[2] - 1)};
  parts = std::max<std::size_t>(parts, 1);
  const std::size_t nv = mesh.vertices.size();
  // 1 for a vertex outside the box (then 2 for one that stays unused), 0 inside.
  std::vector<std::uint8_t> mark(nv);
  run_loop(run, parts, [&](std::size_t k) {
    for (std::size_t v = piece_begin(nv, parts, k); v < piece_begin(nv, parts, k + 1); ++v) {
      const vec3& p = mesh.vertices[v];
      mark[v] = p[0] <= box[0] && p[1] <= box[1] && p[2] <= box[2] ? 0 : 1;
    }
  });
  const std::size_t nt = mesh.triangles.size();
  std::vector<std::vector<std::uint32_t>> found(parts);
  run_loop(run, parts, [&](std::size_t k) {
    for (std::size_t t = piece_begin(nt, parts, k); t < piece_begin(nt, parts, k + 1); ++t) {
      const tri& c = mesh.triangles[t];
      if ((mark[c[0]] | mark[c[1]] | mark[c[2]]) != 0) {
        found[k].push_back(static_cast<std::uint32_t>(t));
      }
    }
  });
  std::vector<std::uint32_t> clipped;
  for (const auto& f : found) clipped.insert(clipped.end(), f.begin(), f.end());
  if (clipped.empty()) return;
  std::unordered_map<vec3, std::uint32_t, detail::position_hash> crossings;
  std::vector<tri> extra;
  std::vector<std::uint32_t> holes;
  std::vector<std::uint32_t> on_box;  // corners inside the box that a clipped triangle lost
  const auto crossing = [&](const vec3& x) {
    const auto [it, inserted] =
        crossings.try_emplace(x, static_cast<std::uint32_t>(mesh.vertices.size()));
    if (inserted) mesh.vertices.push_back(x);
    return it->second;
  };
  for (const std::uint32_t t : clipped) {
    const tri c = mesh.triangles[t];
    const std::array<vec3, 3> p{mesh.vertices[c[0]], mesh.vertices[c[1]], mesh.vertices[c[2]]};
    bool first = true;
    const std::array<bool, 3> used = detail::clip_to_box(p, c, box, crossing, [&](const tri& e) {
      if (first) {
        mesh.triangles[t] = e;
        first = false;
      } else {
        extra.push_back(e);
      }
    });
    if (first) holes.push_back(t);
    for (std::size_t v = 0; v < 3; ++v) {
      if (!used[v] && mark[c[v]] == 0) on_box.push_back(c[v]);
    }
  }
  // Holes take the further pieces first; those left are filled from the end, largest first (a
  // hole at the end is dropped); pieces left over go to the end.
  const std::size_t filled = std::min(holes.size(), extra.size());
  for (std::size_t i = 0; i < filled; ++i) mesh.triangles[holes[i]] = extra[i];
  for (std::size_t i = holes.size(); i > filled; --i) {
    const std::uint32_t h = holes[i - 1];
    if (h + 1 != mesh.triangles.size()) mesh.triangles[h] = mesh.triangles.back();
    mesh.triangles.pop_back();
  }
  mesh.triangles.insert(mesh.triangles.end(), extra.begin() + static_cast<std::ptrdiff_t>(filled),
                        extra.end());
  mark.resize(mesh.vertices.size(), 0);  // crossing points are inside
  if (!on_box.empty()) {
    // Rare (a corner on the box whose triangle kept nothing there): dropped only if unused.
    for (const std::uint32_t v : on_box) mark[v] = 2;
    for (const tri& c : mesh.triangles) {
      for (const std::uint32_t v : c) {
        if (mark[v] == 2) mark[v] = 0;
      }
    }
  }
  // Renaming: each kept vertex's new id is its old one less the dropped before it.
  const std::size_t nv2 = mesh.vertices.size();
  std::vector<std::uint32_t> before(parts + 1, 0);
  run_loop(run, parts, [&](std::size_t k) {
    std::uint32_t n = 0;
    for (std::size_t v = piece_begin(nv2, parts, k); v < piece_begin(nv2, parts, k + 1); ++v) {
      n += mark[v] != 0 ? 1u : 0u;
    }
    before[k + 1] = n;
  });
  for (std::size_t k = 0; k < parts; ++k) before[k + 1] += before[k];
  if (before[parts] == 0) return;
  std::vector<std::uint32_t> rename(nv2);
  run_loop(run, parts, [&](std::size_t k) {
    std::uint32_t dropped = before[k];
    for (std::size_t v = piece_begin(nv2, parts, k); v < piece_begin(nv2, parts, k + 1); ++v) {
      if (mark[v] != 0) {
        ++dropped;
      } else {
        rename[v] = static_cast<std::uint32_t>(v) - dropped;
      }
    }
  });
  const std::size_t nt2 = mesh.triangles.size();
  run_loop(run, parts, [&](std::size_t k) {
    for (std::size_t t = piece_begin(nt2, parts, k); t < piece_begin(nt2, parts, k + 1); ++t) {
      for (std::uint32_t& v : mesh.triangles[t]) v = rename[v];
    }
  });
  // Kept vertices move down in order; a part's targets lie at or below its sources and above
  // the earlier parts' targets, so the parts run one after another.
  std::size_t to = 0;
  for (std::size_t v = 0; v < nv2; ++v) {
    if (mark[v] == 0) mesh.vertices[to++] = mesh.vertices[v];
  }
  mesh.vertices.resize(to);
}

triangle_mesh uniform_surface_hooked(const volume& field, double isovalue, std::int32_t stride,
                                     const parallel_loop& run, std::size_t parts,
                                     const finest_progress& progress, const interrupts& stop,
                                     bool hierarchy_cut = false) {
  if (stride < 1 || stride > (1 << 14) ||
      !std::has_single_bit(static_cast<std::uint32_t>(stride))) {
    throw error("uniform surface: the stride must be a power of two in [1, 16384], found " +
                std::to_string(stride));
  }
  if (stride == 1) return finest_surface_hooked(field, isovalue, run, parts, progress, stop);
  const index3 dims = field.dims();
  if (dims[2] < 2) throw error("uniform surface: a 2D field has no stride above 1");
  if (!std::isfinite(isovalue)) {
    throw error("uniform surface: the isovalue must be finite, found " + std::to_string(isovalue));
  }
  const index3 sub = uniform_grid_dims(dims, stride);
  const strided_grid grid{stride, dims};
  const auto mesh_of = [&](auto samples) {
    finest_mesher<decltype(samples)> m(sub, {1.0, 1.0, 1.0}, {0.0, 0.0, 0.0}, samples, isovalue);
    if (!hierarchy_cut) return m.run(run, parts, progress, stop);
    interrupts with_slack = stop;
    with_slack.slack = true;  // clip_to_data_box() adds crossing points and pieces in place
    return m.run(run, parts, progress, with_slack);
  };
  triangle_mesh mesh = detail::visit_field(field, [&](const auto src) -> triangle_mesh {
    using S = std::remove_cv_t<decltype(src)>;
    if constexpr (std::is_pointer_v<S>) {
      // Stored samples: read in place, every colour and crossing from the field's own values.
      using T = std::remove_cv_t<std::remove_pointer_t<S>>;
      if (stop.poll) stop.poll(-1.0);
      return mesh_of(strided_samples<T>{grid, src});
    } else {
      // A computed field (a smoothed one's doubles): its subsampled values made once, so that
      // a crossing reads the value its colour came from; written by the copy, every one.
      const auto points = static_cast<std::size_t>(sub[0] * sub[1] * sub[2]);
      const std::unique_ptr<double[]> samples = std::make_unique_for_overwrite<double[]>(points);
      double* const out = samples.get();
      const std::int64_t nx = sub[0];
      const std::int64_t last_x = dims[0] - 1;
      const auto plane = [&](std::size_t k) {
        if (stop.poll) stop.poll(-1.0);
        for (std::int64_t j = 0; j < sub[1]; ++j) {
          const std::int64_t row = grid.row_start(j, static_cast<std::int64_t>(k));
          double* o = out + nx * (j + sub[1] * static_cast<std::int64_t>(k));
          // Every stride-th sample of the row, then its last.
          for (std::int64_t i = 0; i + 1 < nx; ++i)
            o[i] = static_cast<double>(src[row + i * stride]);
          o[nx - 1] = static_cast<double>(src[row + last_x]);
        }
      };
      run_loop(run, static_cast<std::size_t>(sub[2]), plane);
      return mesh_of(static_cast<const double*>(out));
    }
  });
  const auto& sp = field.spacing();
  const auto& org = field.origin();
  if (hierarchy_cut) {
    // The subsampled grid's cells are all `stride` wide (its last samples are the box's last,
    // as the hierarchy's padding repeats the nearest sample): grid frame, clipped, physical.
    bool past_box = false;
    for (std::size_t q = 0; q < 3; ++q) past_box = past_box || (sub[q] - 1) * stride > dims[q] - 1;
    const auto scale = [&](std::size_t part) {
      const std::size_t n = mesh.vertices.size();
      const std::size_t count = std::max<std::size_t>(parts, 1);
      for (std::size_t v = n * part / count; v < n * (part + 1) / count; ++v) {
        for (double& x : mesh.vertices[v]) x *= stride;  // exact: a power of two
      }
    };
    run_loop(run, std::max<std::size_t>(parts, 1), scale);
    if (past_box) clip_to_data_box(mesh, dims, run, parts);
    const auto to_physical = [&](std::size_t part) {
      const std::size_t n = mesh.vertices.size();
      const std::size_t count = std::max<std::size_t>(parts, 1);
      for (std::size_t v = n * part / count; v < n * (part + 1) / count; ++v) {
        mesh.vertices[v] = detail::physical_position(field, mesh.vertices[v]);
      }
    };
    run_loop(run, std::max<std::size_t>(parts, 1), to_physical);
    return mesh;
  }
  // Index frame of the subsampled grid → the field's physical frame.
  const auto place = [&](std::size_t part) {
    const std::size_t n = mesh.vertices.size();
    const std::size_t count = std::max<std::size_t>(parts, 1);
    for (std::size_t v = n * part / count; v < n * (part + 1) / count; ++v) {
      vec3& p = mesh.vertices[v];
      for (std::size_t q = 0; q < 3; ++q) {
        p[q] = org[q] + field_index(p[q], sub[q], dims[q], stride) * sp[q];
      }
    }
  };
  run_loop(run, std::max<std::size_t>(parts, 1), place);
  return mesh;
}

}  // namespace

triangle_mesh uniform_surface(const volume& field, double isovalue, std::int32_t stride,
                              const parallel_loop& run, std::size_t parts,
                              const finest_progress& progress) {
  return uniform_surface_hooked(field, isovalue, stride, run, parts, progress, {});
}

triangle_mesh uniform_cut(const volume& field, double isovalue, std::int32_t stride,
                          const parallel_loop& run, std::size_t parts,
                          const finest_progress& progress) {
  return uniform_surface_hooked(field, isovalue, stride, run, parts, progress, {}, true);
}

namespace {

// Thrown through finest_surface() by ladder_surface()'s progress when the deadline has passed.
struct deadline_passed {};

}  // namespace

ladder_result ladder_surface(const volume& field, double isovalue,
                             std::chrono::steady_clock::time_point deadline,
                             const parallel_loop& run, std::size_t parts,
                             const ladder_progress& progress) {
  return detail::ladder_surface(field, isovalue, deadline, run, parts, progress, {});
}

ladder_result detail::ladder_surface(const volume& field, double isovalue,
                                     std::chrono::steady_clock::time_point deadline,
                                     const parallel_loop& run, std::size_t parts,
                                     const ladder_progress& progress, const ladder_hooks& hooks) {
  using clock = std::chrono::steady_clock;
  const auto since = [](clock::time_point t) {
    return std::chrono::duration<double>(clock::now() - t).count();
  };
  const index3 dims = field.dims();
  std::int32_t stride = 1;
  if (dims[2] >= 2) {
    const std::int64_t longest = std::max({dims[0], dims[1], dims[2]}) - 1;
    while (longest / (2 * stride) >= 8 && stride < (1 << 14)) stride *= 2;
  }
  // A caller that shows a cut already begins below it, and need not make a first cut at all.
  const bool shown = hooks.shown_stride > 0;
  if (shown) stride = std::min(stride, hooks.shown_stride / 2);
  ladder_result res;
  const auto called = clock::now();
  // A cut's time: its first pass (and the copy of its samples) in proportion to its grid
  // points, the rest (sizing the output, the second pass) to its vertices and triangles, each
  // rate that of the last cut done. A finer cut's output is four times the last one's where the
  // surface is a smooth sheet (its area in cells of half the side) and up to eight where it
  // fills the volume (noise): the last two cuts' ratio, within [4, 8], says which. Its exact
  // size is known after its first pass; the rest is then begun only if half as long again
  // would still end in time, because giving it up is not free: the output sized so far is
  // returned to the system before the call returns (a large cut's rest can run well past its
  // prediction, and dropping it takes time of its own; bench/README.md). While the
  // output is sized, its own rate so far and the last cut's second pass per output element
  // say when the cut would end; it is dropped as soon as that is past the deadline, with
  // little of the output touched (fresh pages cost what the machine's memory makes them).
  constexpr double rest_margin = 1.5;
  constexpr double sizing_seen = 0.1;  // projected from a tenth of an array sized
  double pass2_per_output = 0.0;
  double per_point = 0.0;
  double per_output = 0.0;
  double last_output = 0.0;
  double growth = 4.0;
  std::array<double, 2> last_counts{0.0, 0.0};  // the last cut's vertices and triangles
  for (; stride >= 1; stride /= 2) {
    const index3 sub = uniform_grid_dims(dims, stride);
    const double points =
        static_cast<double>(sub[0]) * static_cast<double>(sub[1]) * static_cast<double>(sub[2]);
    const bool must = res.levels_done == 0 && !shown;
    const auto give_up = [&] {
      return (!must && clock::now() >= deadline) || (hooks.stopping && hooks.stopping());
    };
    const auto left = [&deadline] {
      return std::chrono::duration<double>(deadline - clock::now()).count();
    };
    if (!must && (hooks.begin_when_time_is_left
                      ? left() <= 0.0
                      : per_point * points + per_output * growth * last_output > left())) {
      break;
    }
    const auto start = clock::now();
    double first_pass = 0.0;
    double output = 0.0;
    double sizing = 0.0;
    clock::time_point sized_at{};
    interrupts stop;
    stop.storage = hooks.storage;
    stop.slab_bytes = hooks.slab_bytes;
    // A cut of more than one slab is not sized at once: room for what the model expects (and a
    // sixteenth), so that its arrays grow in place.
    for (std::size_t k = 0; k < 2; ++k) {
      stop.expected[k] = static_cast<std::uint64_t>(growth * last_counts[k] * 17.0 / 16.0);
    }
    stop.sized = [&](std::uint64_t v, std::uint64_t t) {
      sized_at = clock::now();
      first_pass = std::chrono::duration<double>(sized_at - start).count();
      output = static_cast<double>(v + t);
      if (!must && !hooks.begin_when_time_is_left && rest_margin * per_output * output > left()) {
        throw deadline_passed{};
      }
    };
    stop.poll = [&](double fraction) {
      const auto now = clock::now();
      const double so_far = std::chrono::duration<double>(now - sized_at).count();
      if (fraction > 1.0) sizing = so_far;  // both arrays sized (the calling thread)
      if (give_up()) throw deadline_passed{};
      if (must || hooks.begin_when_time_is_left) return;
      double ends = -1.0;  // projected seconds from sizing's start to the cut's end
      if (fraction > 1.0) {
        ends = so_far + pass2_per_output * output;
      } else if (fraction >= sizing_seen) {
        ends = so_far / fraction + pass2_per_output * output;
      }
      if (ends > 0.0 && sized_at + std::chrono::duration_cast<clock::duration>(
                                       std::chrono::duration<double>(ends)) >
                            deadline) {
        throw deadline_passed{};
      }
    };
    const finest_progress watch = [&](std::uint64_t done, std::uint64_t total) {
      if (progress) progress(stride, done, total);
      // The last call says all is done: nothing left to give up.
      if (done < total && give_up()) throw deadline_passed{};
    };
    try {
      triangle_mesh m = uniform_surface_hooked(field, isovalue, stride, run, parts, watch, stop,
                                               hooks.hierarchy_cuts);
      res.triangles = m.triangles.size();
      // A grid of more than one slab is not sized at once (`sized` is not told): its output,
      // counted now, takes the whole cut's time in the model.
      if (output == 0.0) output = static_cast<double>(m.vertices.size() + m.triangles.size());
      last_counts = {static_cast<double>(m.vertices.size()),
                     static_cast<double>(m.triangles.size())};
      if (hooks.on_cut) {
        hooks.on_cut(std::move(m), stride);
      } else {
        res.mesh = std::move(m);
      }
    } catch (const deadline_passed&) {
      res.abandoned = true;
      break;
    } catch (const std::bad_alloc&) {
      // Under a data limit (or past the machine) a finer cut may not fit where a coarser one
      // did: the time-critical answer is the finest cut that fit, not no surface. Its work is
      // freed by the unwinding; the first cut has nothing to fall back on.
      if (must) throw;
      res.abandoned = true;
      res.out_of_memory = true;
      break;
    }
    const double took = since(start);
    if (res.levels_done == 0) res.first_seconds = since(called);
    res.stride = stride;
    ++res.levels_done;
    per_point = first_pass / points;
    per_output = output > 0 ? (took - first_pass) / output : per_output;
    if (output > 0) pass2_per_output = std::max(0.0, took - first_pass - sizing) / output;
    if (last_output > 0 && output > 0) growth = std::clamp(output / last_output, 4.0, 8.0);
    last_output = output;
  }
  return res;
}

}  // namespace progiso
