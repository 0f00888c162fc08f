// progiso/core/surface/detail/cut_mesher.hpp — the indexed mesh of a cut, made from split
// records without looking surface vertices up by key.
//
// Every grid edge but the root cubes' own is made by one split: splitting the diamond centred at
// e joins e to its spine ends and ring, and e is that edge's newer end (the deeper one; ends never
// have equal depth). A surface vertex lies on one crossed edge, so it is named by (the split of
// its edge's newer end, the other end's offset code from that end), and numbered without a hash:
//
//  * the cut's split diamonds, by grid index, form a rank index (cut_index): a bitmap with a
//    count per 64-bit word when the cut is dense, a sorted array when it is sparse. A split's
//    rank is its place in canonical order (grid index order), and every per-split array of the
//    extraction is indexed by rank, so that neighbours in the grid are neighbours in memory;
//  * each record knows which of its new edges the surface crosses (split_summary::crossed, 27
//    bits by offset code). An edge of scale h ≥ 2 is in the cut until the diamond centred at its
//    midpoint (the diamond whose spine it is) splits; a finest edge stays. The crossed edges in
//    the cut whose vertex lies in the data box are the split's vertex mask;
//  * vertex ids run over the splits in canonical order (root edges first): a split's first id is
//    the sum of its predecessors' mask counts, and a vertex's id is that plus its code's rank in
//    the mask;
//  * a triangle's vertex, given by its group's edge code, is decoded by the split's shape table
//    (group_edges) into the edge's two ends; when one is the split's own centre the id is local,
//    otherwise the rank of the newer end finds it (one rank query, no record read).
//
// Root edges (both ends root-cube corners) belong to no split: they get their ids first, from
// the root triangles, in a small map (only coarse cuts use many of them). Pieces that reach past
// the data box (coarse tetrahedra of padded hierarchies) are clipped (mesh_clip.hpp) after
// the rest, with crossing points numbered after the edge vertices; vertices only such pieces used
// are then dropped.
//
// Passes run over `parts` pieces through a parallel loop: (1) the rank index, from the records in
// publication order (read in sequence); (2) each split's groups and vertex mask, written at its
// rank (its grid point is not kept: a pass over a rank range walks the rank index for it); (3)
// first ids, over rank ranges; (4) triangles, over rank ranges; (5) vertex positions, over rank
// ranges; then the ranges' triangles are joined. The two arrays of the mesh are sized
// (std::vector's resize, which writes on one thread) beside passes 4 and 5. The mesh is the same
// for every part count and thread count.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <concepts>
#include <cstdint>
#include <memory>
#include <unordered_map>
#include <utility>
#include <vector>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/detail/cut_index.hpp>
#include <progiso/core/base/detail/flat_map.hpp>
#include <progiso/core/base/detail/prefault.hpp>
#include <progiso/core/base/parallel_loop.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>
#include <progiso/core/surface/detail/mesh_clip.hpp>
#include <progiso/core/surface/marching.hpp>
#include <progiso/core/surface/mesh.hpp>
#include <progiso/core/surface/split_record.hpp>

namespace progiso::detail {

/// The offset of an edge_offset_code().
[[nodiscard]] constexpr ipoint offset_of_code(unsigned code) noexcept {
  return ipoint{static_cast<std::int32_t>(code % 3) - 1,
                static_cast<std::int32_t>(code / 3 % 3) - 1,
                static_cast<std::int32_t>(code / 9) - 1};
}

/// What cut_mesher reads. `records` is the number of records; record 0 is the root surface
/// (root_triangles), records 1 … records − 1 are splits, each with the fields diamond (grid index
/// of its centre; its scale follows from it), groups, count and crossed. split(r) says whether
/// record r is in the cut (the cut is closed under parents).
template <class Source>
concept cut_source = requires(const Source& s, std::uint64_t i) {
  { s.records() } -> std::convertible_to<std::uint64_t>;
  s.record(i).diamond;
  s.record(i).groups;
  s.record(i).count;
  s.record(i).crossed;
  { s.split(i) } -> std::convertible_to<bool>;
  { s.root_triangles() } -> std::convertible_to<const std::vector<owned_triangle>&>;
};

/// What cut_mesher samples: a volume, or any field with value(x, y, z) (a double at a grid
/// vertex, clamped to the data as volume::value() clamps) and the volume's spacing() and
/// origin(). A hierarchy stream's consumer has no volume: only the samples at the cut's
/// vertices (core/surface/hierarchy_stream.hpp).
template <class Field>
concept cut_field = requires(const Field& f, std::int64_t i) {
  { f.value(i, i, i) } -> std::convertible_to<double>;
  { f.spacing() } -> std::convertible_to<std::array<double, 3>>;
  { f.origin() } -> std::convertible_to<std::array<double, 3>>;
};

template <cut_source Source, cut_field Field = volume>
class cut_mesher {
 public:
  cut_mesher(const Source& src, const hierarchy& hier, const Field& vol, double isovalue)
      : src_(src), hier_(hier), vol_(vol), w_(isovalue), records_(src.records()) {
    for (std::size_t q = 0; q < 3; ++q) box_[q] = static_cast<double>(hier.data_max()[q]);
    root_mask_ = static_cast<std::uint32_t>(hier.root_size() - 1);
  }

  /// The mesh of the cut: `parts` pieces of work through `run`.
  triangle_mesh build(const parallel_loop& run, std::size_t parts) {
    parts_ = std::max<std::size_t>(parts, 1);
    make_index(run);
    const std::uint64_t n = index_.size();
    // Not zeroed: pass 2 writes every rank's groups and mask, pass 3 every base.
    groups_ = std::make_unique_for_overwrite<const packed_group*[]>(n);
    group_counts_ = std::make_unique_for_overwrite<std::uint8_t[]>(n);
    names_ = std::make_unique_for_overwrite<naming[]>(n);
    prefault_in_parts(run, groups_.get(), n * sizeof(const packed_group*));
    prefault_in_parts(run, group_counts_.get(), n);
    prefault_in_parts(run, names_.get(), n * sizeof(naming));
    name_root_vertices();
    run_loop(run, parts_, [this](std::size_t k) { read_records(k); });
    // First ids: counts per rank range, then each range's first id.
    std::vector<std::uint64_t> first_id(parts_ + 1, root_positions_.size());
    run_loop(run, parts_, [&](std::size_t k) {
      std::uint64_t c = 0;
      for (std::uint64_t i = first(n, k); i < first(n, k + 1); ++i) c += bit_count(names_[i].mask);
      first_id[k + 1] = c;
    });
    for (std::size_t k = 0; k < parts_; ++k) first_id[k + 1] += first_id[k];
    const std::uint64_t vertices = first_id[parts_];
    PROGISO_ASSERT(vertices < clip_outside);
    mesh_.vertices.reserve(vertices);
    prefault_in_parts(run, mesh_.vertices.data(), vertices * sizeof(vec3));
    triangles_.assign(parts_, {});
    clipped_.assign(parts_, {});
    if (parts_ == 1) {
      // One part: nothing to size the arrays beside; ids and positions in one pass.
      size_vertices(vertices);
      number(0, first_id[0], true);
      triangulate(0);
      mesh_.triangles = std::move(triangles_[0]);
    } else {
      build_in_parts(run, first_id);
    }
    clip_pieces();
    drop_unused(mesh_, suspects_, run, parts_);
    return std::move(mesh_);
  }

 private:
  // Passes 3 to 5 and the join, with more than one part.
  void build_in_parts(const parallel_loop& run, const std::vector<std::uint64_t>& first_id) {
    run_loop(run, parts_, [&](std::size_t k) { number(k, first_id[k], false); });
    // std::vector's resize writes every element on one thread (on a large mesh a sizeable part
    // of a many-core extraction; bench/README.md), so it runs as one more item of the loop
    // beside a pass that does not need the array: the vertex array's beside the triangles, the
    // joined triangles' beside the vertex positions. Item 0, which the loop takes first.
    run_loop(run, parts_ + 1, [&](std::size_t k) {
      if (k == 0) {
        size_vertices(first_id[parts_]);
      } else {
        triangulate(k - 1);
      }
    });
    const std::vector<std::size_t> at = triangle_offsets();
    mesh_.triangles.reserve(at.back());
    prefault_in_parts(run, mesh_.triangles.data(), at.back() * sizeof(mesh_.triangles[0]));
    run_loop(run, parts_ + 1, [&](std::size_t k) {
      if (k == 0) {
        mesh_.triangles.resize(at.back());
      } else {
        place(k - 1);
      }
    });
    join_triangles(run, at);
  }

  // A clip job's id for a corner past the data box; every vertex id stays below it.
  static constexpr std::uint32_t clip_outside = std::uint32_t{1} << 31;
  static constexpr std::uint32_t outside = ~std::uint32_t{0};  // a vertex past the data box

  // A split's groups, as the passes after the first read them at its rank: one per child
  // tetrahedron with surface, of which a diamond of k ≤ 8 tetrahedra has 2k (split_record.hpp).
  // Its centre and scale come from its grid index (cut_index::walk), not from a copy: 17 bytes
  // per split instead of 40, paid for every split of a cut.
  static constexpr std::uint32_t max_groups = 16;

  // The grid points of a rank range's splits, in rank (grid index) order: most lie on the row of
  // the one before, so the point moves along x, and only a new row asks hierarchy::point().
  class centre_walk {
   public:
    centre_walk(const cut_index& index, std::uint64_t first_rank, const hierarchy& hier)
        : walk_(index, first_rank),
          hier_(hier),
          row_(static_cast<std::uint64_t>(hier.grid_max()[0]) + 1) {}
    // The next rank's grid index; point() is its grid point.
    std::uint64_t next() noexcept {
      const std::uint64_t v = walk_.next();
      const std::uint64_t ahead = v - index_;
      if (started_ && ahead < row_ - static_cast<std::uint64_t>(p_[0])) {
        p_[0] += static_cast<std::int32_t>(ahead);
      } else {
        p_ = hier_.point(v);
        started_ = true;
      }
      index_ = v;
      return v;
    }
    [[nodiscard]] const ipoint& point() const noexcept { return p_; }

   private:
    cut_index::walk walk_;
    const hierarchy& hier_;
    std::uint64_t row_;  // grid points per x-row
    std::uint64_t index_ = 0;
    ipoint p_{};
    bool started_ = false;
  };
  // Per split (by rank): its first vertex id and its vertex mask, read together.
  struct naming {
    std::uint32_t base;
    std::uint32_t mask;
  };
  struct clip_job {
    std::array<vec3, 3> grid;  // grid positions of the corners
    std::array<std::uint32_t, 3> ids;
  };

  // Maps the pages of a buffer about to be written everywhere, a slice per piece of work at most.
  void prefault_in_parts(const parallel_loop& run, const void* p, std::size_t bytes) const {
    detail::prefault_in_parts(run, parts_, p, bytes);
  }

  // Piece k of n items: [first(n, k), first(n, k + 1)).
  [[nodiscard]] std::uint64_t first(std::uint64_t items, std::size_t k) const noexcept {
    return piece_begin(items, parts_, k);
  }
  [[nodiscard]] bool take(std::uint64_t owner) const noexcept {
    return owner == no_owner || !index_.contains(owner);
  }
  [[nodiscard]] bool root_corner(const ipoint& p) const noexcept {
    return ((static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) |
             static_cast<std::uint32_t>(p[2])) &
            root_mask_) == 0;
  }
  // Smaller for the deeper of two vertices that are not root corners: finer scale first, and at
  // one scale edge midpoints (one axis odd at it) after face centres after cube centres.
  [[nodiscard]] static unsigned age(const ipoint& p) noexcept {
    const auto x = static_cast<std::uint32_t>(p[0]);
    const auto y = static_cast<std::uint32_t>(p[1]);
    const auto z = static_cast<std::uint32_t>(p[2]);
    const int tz = std::countr_zero(x | y | z);
    return static_cast<unsigned>(tz) * 4 + ((x >> tz) & 1u) + ((y >> tz) & 1u) + ((z >> tz) & 1u);
  }
  [[nodiscard]] vec3 on_edge(ipoint a, ipoint b) const noexcept {
    if (vertex_less(b, a)) std::swap(a, b);
    return interpolate(a, vol_.value(a[0], a[1], a[2]), b, vol_.value(b[0], b[1], b[2]), w_);
  }
  [[nodiscard]] bool in_box(const vec3& p) const noexcept {
    return p[0] <= box_[0] && p[1] <= box_[1] && p[2] <= box_[2];
  }
  [[nodiscard]] vec3 physical(const vec3& p) const noexcept { return physical_position(vol_, p); }
  [[nodiscard]] static ipoint at(const ipoint& c, std::int32_t h, unsigned code) noexcept {
    const ipoint o = offset_of_code(code);
    return ipoint{c[0] + h * o[0], c[1] + h * o[1], c[2] + h * o[2]};
  }

  // Pass 1. Dense when the cut has at least one split per 64 grid vertices (then the bitmap
  // costs less than sorting), sparse otherwise (a coarse cut of a large volume: the first
  // surface reads no per-vertex array).
  void make_index(const parallel_loop& run) {
    const std::uint64_t vertices = hier_.vertex_count();
    if (vertices > 64 * records_) {
      std::vector<std::uint64_t> v;
      v.reserve(records_);
      for (std::uint64_t r = 1; r < records_; ++r) {
        if (src_.split(r)) v.push_back(src_.record(r).diamond);
      }
      index_ = cut_index::sparse(std::move(v));
      return;
    }
    index_ = cut_index::dense(vertices);
    run_loop(run, parts_, [this](std::size_t k) {
      for (std::uint64_t r = std::max<std::uint64_t>(first(records_, k), 1);
           r < first(records_, k + 1); ++r) {
        if (src_.split(r)) index_.add(src_.record(r).diamond);
      }
    });
    index_.finish(run, parts_);
  }

  // Root edges' vertices, in order of first use by the root triangles (all of them: a crossed
  // root edge in the cut is in some root tetrahedron of the cut's, whose triangles use it).
  void name_root_vertices() {
    const std::vector<owned_triangle>& tris = src_.root_triangles();
    root_ids_ = flat_map(tris.size() + 16);
    for (const owned_triangle& t : tris) {
      for (const std::uint64_t key : t.keys) {
        if (root_ids_.find(key) != nullptr) continue;
        const ipoint m2 = edge_key_point(key);
        if (((m2[0] | m2[1] | m2[2]) & 1) == 0) {
          const ipoint m{m2[0] / 2, m2[1] / 2, m2[2] / 2};
          if (index_.contains(hier_.index(m))) continue;  // split: not in the cut
        }
        const auto ends = hier_.edge_ends(key);
        const vec3 p = on_edge(ends[0], ends[1]);
        if (!in_box(p)) {
          root_ids_.try_emplace(key, outside);
          continue;
        }
        root_ids_.try_emplace(key, static_cast<std::uint32_t>(root_positions_.size()));
        root_positions_.push_back(physical(p));
      }
    }
  }

  // Pass 2, over records in publication order (read in sequence): each split's groups and vertex
  // mask, at its rank.
  void read_records(std::size_t k) {
    const ipoint& dm = hier_.data_max();
    for (std::uint64_t r = std::max<std::uint64_t>(first(records_, k), 1);
         r < first(records_, k + 1); ++r) {
      if (!src_.split(r)) continue;
      const auto& rec = src_.record(r);
      const ipoint c = hier_.point(rec.diamond);
      const std::int32_t h = hier_.scale_of(c);
      const std::uint32_t i = index_.rank(rec.diamond);
      PROGISO_ASSERT(rec.count <= max_groups);
      groups_[i] = rec.groups;
      group_counts_[i] = static_cast<std::uint8_t>(rec.count);
      std::uint32_t m = rec.crossed;
      if (h >= 2) {
        const std::int32_t g = h / 2;
        for (std::uint32_t todo = m; todo != 0; todo &= todo - 1) {
          const auto code = static_cast<unsigned>(std::countr_zero(todo));
          if (index_.contains(hier_.index(at(c, g, code)))) m &= ~(1u << code);
        }
      }
      if (c[0] + h > dm[0] || c[1] + h > dm[1] || c[2] + h > dm[2]) {
        for (std::uint32_t todo = m; todo != 0; todo &= todo - 1) {
          const auto code = static_cast<unsigned>(std::countr_zero(todo));
          if (!in_box(on_edge(c, at(c, h, code)))) m &= ~(1u << code);
        }
      }
      names_[i].mask = m;
    }
  }

  void size_vertices(std::uint64_t vertices) {
    mesh_.vertices.resize(vertices);
    std::copy(root_positions_.begin(), root_positions_.end(), mesh_.vertices.begin());
  }

  // Pass 3, over rank range k: each split's first vertex id, from the range's first id, and with
  // `place_too` its vertices' positions (one part: the vertex array is sized already).
  void number(std::size_t k, std::uint64_t id, bool place_too) {
    const auto name = [&](std::uint64_t i) {
      naming& nm = names_[i];
      nm.base = static_cast<std::uint32_t>(id);
      id += bit_count(nm.mask);
      return nm;
    };
    if (place_too) {
      each_split(k, [&](std::uint64_t i, const ipoint& c) {
        const naming nm = name(i);
        if (nm.mask != 0) place_split(i, c, nm.base);
      });
      return;
    }
    const std::uint64_t n = index_.size();
    for (std::uint64_t i = first(n, k); i < first(n, k + 1); ++i) name(i);
  }

  // Pass 5 (after the triangles, beside the joined triangles' resize), over rank range k: the
  // positions of the splits' vertices.
  void place(std::size_t k) {
    each_split(k, [&](std::uint64_t i, const ipoint& c) {
      if (names_[i].mask != 0) place_split(i, c, names_[i].base);
    });
  }

  // f(rank, grid point) for the splits of rank range k, in order.
  template <class F>
  void each_split(std::size_t k, F&& f) const {
    const std::uint64_t n = index_.size();
    const std::uint64_t lo = first(n, k);
    const std::uint64_t hi = first(n, k + 1);
    if (lo == hi) return;
    centre_walk centres(index_, lo, hier_);
    for (std::uint64_t i = lo; i < hi; ++i) {
      centres.next();
      f(i, centres.point());
    }
  }

  // The positions of split i's vertices (its centre c), from id on.
  void place_split(std::uint64_t i, const ipoint& c, std::uint64_t id) {
    const std::int32_t h = hier_.scale_of(c);
    const double fc = vol_.value(c[0], c[1], c[2]);
    for (std::uint32_t todo = names_[i].mask; todo != 0; todo &= todo - 1) {
      const ipoint x = at(c, h, static_cast<unsigned>(std::countr_zero(todo)));
      const double fx = vol_.value(x[0], x[1], x[2]);
      const vec3 q =
          vertex_less(c, x) ? interpolate(c, fc, x, fx, w_) : interpolate(x, fx, c, fc, w_);
      mesh_.vertices[id++] = physical(q);
    }
  }

  [[nodiscard]] std::uint32_t id_in(const naming& nm, unsigned code) const noexcept {
    if (((nm.mask >> code) & 1u) == 0) return outside;
    return nm.base + bit_count(nm.mask & ((1u << code) - 1));
  }
  // The id of the vertex on the edge (a, b) of the cut, or `outside`.
  [[nodiscard]] std::uint32_t vertex_of(const ipoint& a, const ipoint& b) const noexcept {
    const bool ra = root_corner(a);
    const bool rb = root_corner(b);
    if (ra && rb) {
      const std::uint32_t* id = root_ids_.find(edge_key(a, b));
      PROGISO_ASSERT(id != nullptr);  // every root edge of the cut's triangles was named
      return id != nullptr ? *id : outside;
    }
    const bool a_newer = rb || (!ra && age(a) < age(b));
    const ipoint& n = a_newer ? a : b;
    const ipoint& x = a_newer ? b : a;
    const std::uint64_t v = hier_.index(n);
    PROGISO_ASSERT(index_.contains(v));
    const int lg = std::countr_zero(static_cast<std::uint32_t>(n[0] | n[1] | n[2]));
    return id_in(names_[index_.rank(v)],
                 edge_offset_code({(x[0] - n[0]) >> lg, (x[1] - n[1]) >> lg, (x[2] - n[2]) >> lg}));
  }

  // Pass 4, over rank range k: its triangles (the root surface's with range 0's).
  void triangulate(std::size_t k) {
    std::vector<std::array<std::uint32_t, 3>>& out = triangles_[k];
    const auto emit = [&](const std::array<std::uint32_t, 3>& ids,
                          const std::array<std::array<ipoint, 2>, 3>& ends) {
      if (ids[0] != outside && ids[1] != outside && ids[2] != outside) {
        out.push_back(ids);
        return;
      }
      clip_job j{};
      for (std::size_t v = 0; v < 3; ++v) {
        j.grid[v] = on_edge(ends[v][0], ends[v][1]);
        j.ids[v] = ids[v] == outside ? clip_outside : ids[v];
      }
      clipped_[k].push_back(j);
    };
    if (k == 0) {
      for (const owned_triangle& t : src_.root_triangles()) {
        if (!take(t.owner)) continue;
        // Root tetrahedra have root edges only, all named (the edges of split diamonds' spines
        // are in no taken triangle).
        std::array<std::uint32_t, 3> ids{};
        for (std::size_t v = 0; v < 3; ++v) {
          const std::uint32_t* id = root_ids_.find(t.keys[v]);
          PROGISO_ASSERT(id != nullptr);
          ids[v] = id != nullptr ? *id : outside;
        }
        if (ids[0] != outside && ids[1] != outside && ids[2] != outside) {
          out.push_back(ids);
          continue;
        }
        std::array<std::array<ipoint, 2>, 3> ends{};
        for (std::size_t v = 0; v < 3; ++v) ends[v] = hier_.edge_ends(t.keys[v]);
        emit(ids, ends);
      }
    }
    const std::uint64_t n = index_.size();
    const std::uint64_t lo = first(n, k);
    const std::uint64_t hi = first(n, k + 1);
    // About two triangles per vertex: reserving for them saves copies of a large array.
    std::uint64_t vertices = 0;
    if (hi > lo) vertices = names_[hi - 1].base + bit_count(names_[hi - 1].mask) - names_[lo].base;
    reserve_prefaulted(out, static_cast<std::size_t>(2 * vertices + 64));
    constexpr std::uint64_t ahead = 16;  // groups requested ahead: they lie in publication order
    // Per split, the ids found so far by edge code: a vertex is shared by about two triangles
    // of the same split. Stamped with the rank, so nothing is cleared between splits.
    std::array<std::uint32_t, 125> memo{};
    std::array<std::uint64_t, 125> stamp{};
    stamp.fill(~std::uint64_t{0});
    if (lo == hi) return;
    centre_walk centres(index_, lo, hier_);
    for (std::uint64_t i = lo; i < hi; ++i) {
      if (i + ahead < hi) {
        const std::uint8_t later = group_counts_[i + ahead];
        if (later != 0) {  // a split without surface may have no groups (and no pointer)
          __builtin_prefetch(groups_[i + ahead]);
          __builtin_prefetch(groups_[i + ahead] + (later - 1));
        }
      }
      const std::uint64_t centre_index = centres.next();
      const ipoint c = centres.point();
      const std::int32_t h = hier_.scale_of(c);
      const packed_group* const groups = groups_[i];
      const std::uint32_t count = group_counts_[i];
      const naming own = names_[i];
      const group_edge_table& edges = group_edges(c, h);
      const auto id_of = [&](unsigned code) {
        if (stamp[code] == i) return memo[code];
        const auto& e = edges[code];
        PROGISO_ASSERT(e[1] != centre_offset_code);
        const std::uint32_t id = e[0] == centre_offset_code
                                     ? id_in(own, e[1])
                                     : vertex_of(at(c, h, e[0]), at(c, h, e[1]));
        stamp[code] = i;
        memo[code] = id;
        return id;
      };
      for (std::uint32_t j = 0; j < count; ++j) {
        const packed_group& g = groups[j];
        if (!take(group_owner(hier_, centre_index, h, g))) continue;
        for (std::size_t t = 0; t < g.count(); ++t) {
          const std::array<std::uint32_t, 3> ids{id_of(g.edge(t, 0)), id_of(g.edge(t, 1)),
                                                 id_of(g.edge(t, 2))};
          if (ids[0] != outside && ids[1] != outside && ids[2] != outside) {
            out.push_back(ids);
            continue;
          }
          std::array<std::array<ipoint, 2>, 3> ends{};
          for (std::size_t v = 0; v < 3; ++v) {
            const auto& e = edges[g.edge(t, v)];
            ends[v] = {at(c, h, e[0]), at(c, h, e[1])};
          }
          emit(ids, ends);
        }
      }
    }
  }

  // Where each range's triangles start in the joined array, and their total.
  [[nodiscard]] std::vector<std::size_t> triangle_offsets() const {
    std::vector<std::size_t> at(triangles_.size() + 1, 0);
    for (std::size_t k = 0; k < triangles_.size(); ++k) at[k + 1] = at[k] + triangles_[k].size();
    return at;
  }

  // The ranges' triangles into the mesh's array (already of its full size), in parallel; the
  // per-rank arrays, no longer needed, are freed beside them.
  void join_triangles(const parallel_loop& run, const std::vector<std::size_t>& at) {
    const std::size_t n = triangles_.size();
    run_loop(run, n + 2, [&](std::size_t k) {
      if (k == n) {
        groups_.reset();
        group_counts_.reset();
      } else if (k == n + 1) {
        names_.reset();
      } else {
        std::copy(triangles_[k].begin(), triangles_[k].end(),
                  mesh_.triangles.begin() + static_cast<std::ptrdiff_t>(at[k]));
        triangles_[k] = {};
      }
    });
  }

  // Pieces past the data box, in canonical order: crossing points numbered after every edge
  // vertex, one id per position.
  void clip_pieces() {
    std::unordered_map<vec3, std::uint32_t, position_hash> crossings;
    const auto crossing = [&](const vec3& x) {
      const auto [it, inserted] =
          crossings.try_emplace(x, static_cast<std::uint32_t>(mesh_.vertices.size()));
      if (inserted) mesh_.vertices.push_back(physical(x));
      return it->second;
    };
    const auto emit = [&](const std::array<std::uint32_t, 3>& t) { mesh_.triangles.push_back(t); };
    for (std::vector<clip_job>& jobs : clipped_) {
      for (const clip_job& j : jobs) {
        const std::array<bool, 3> used = clip_to_box(j.grid, j.ids, box_, crossing, emit);
        for (std::size_t v = 0; v < 3; ++v) {
          if (j.ids[v] != clip_outside && !used[v]) suspects_.push_back(j.ids[v]);
        }
      }
      jobs = {};
    }
  }

  const Source& src_;
  const hierarchy& hier_;
  const Field& vol_;
  double w_;
  std::uint64_t records_;
  std::size_t parts_ = 1;
  vec3 box_{};
  std::uint32_t root_mask_ = 0;
  cut_index index_;
  std::unique_ptr<const packed_group*[]> groups_;  // by rank
  std::unique_ptr<std::uint8_t[]> group_counts_;   // by rank
  std::unique_ptr<naming[]> names_;                // by rank
  flat_map root_ids_;
  std::vector<vec3> root_positions_;
  std::vector<std::vector<std::array<std::uint32_t, 3>>> triangles_;  // per rank range
  std::vector<std::vector<clip_job>> clipped_;                        // per rank range
  std::vector<std::uint32_t> suspects_;
  triangle_mesh mesh_;
};

}  // namespace progiso::detail
