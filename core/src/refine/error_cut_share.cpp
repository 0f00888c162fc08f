#include <progiso/core/refine/error_cut_share.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/detail/flat_map.hpp>
#include <progiso/core/surface/detail/cut_mesher.hpp>

namespace progiso::detail {

cut_share error_cut_share(const hierarchy& hier, std::size_t pieces, std::size_t k,
                          std::size_t shares) noexcept {
  PROGISO_ASSERT(shares > 0 && k < shares);
  cut_share s;
  s.piece_begin = piece_begin(pieces, shares, k);
  s.piece_end = piece_begin(pieces, shares, k + 1);
  const std::int32_t planes = hier.grid_max()[2] + 1;
  const auto plane_of = [planes](std::size_t piece) {
    return std::clamp(4 * static_cast<std::int32_t>(piece) - 4, 0, planes);
  };
  s.z_begin = k == 0 ? 0 : plane_of(s.piece_begin);
  s.z_end = k + 1 == shares ? planes : plane_of(s.piece_end);
  s.z_begin = std::min(s.z_begin, s.z_end);
  return s;
}

namespace {

// What one piece of a depth's work gives: its splits (groups numbered from 0), the diamonds it
// kept waiting, and the children to test at the next depth.
struct piece_out {
  std::vector<share_split> splits;
  std::vector<packed_group> groups;
  std::vector<std::uint64_t> next;
  std::vector<std::pair<std::uint64_t, double>> kept;
};

// One diamond of a depth's work: tested already (waiting, its error known) or to test.
struct work_item {
  std::uint64_t diamond;
  double error;  // NaN: not tested yet
};

}  // namespace

error_cut_walk::error_cut_walk(const hierarchy& hier, const volume& vol, const range_data& ranges,
                               double isovalue, std::int32_t z_begin, std::int32_t z_end)
    : hier_(hier),
      vol_(vol),
      ranges_(ranges),
      isovalue_(isovalue),
      z_begin_(z_begin),
      z_end_(z_end),
      waiting_(static_cast<std::size_t>(hier.max_depth()) + 2) {
  if (z_begin >= z_end) return;
  std::vector<owned_triangle> scratch;
  std::vector<std::uint64_t> roots;  // the roots that reach the planes
  for (std::uint64_t r = 0; r < hier.root_count(); ++r) {
    scratch.clear();
    const std::optional<ipoint> c = compute_root(hier, vol, isovalue, r, scratch);
    if (c && c->at(2) + hier.scale_of(*c) >= z_begin && c->at(2) - hier.scale_of(*c) < z_end) {
      roots.push_back(hier.index(*c));
    }
  }
  std::sort(roots.begin(), roots.end());
  // Tested now, so that the first round's threshold can be told from their errors.
  for (const std::uint64_t r : roots) {
    const ipoint c = hier.point(r);
    const diamond_range d = ranges.get(c, hier.scale_of(c));
    if (d.straddles(isovalue)) waiting_[0].push_back({r, d.error});
  }
}

double error_cut_walk::largest_waiting_error() const noexcept {
  double m = 0.0;
  for (const auto& depth : waiting_) {
    for (const waiting& w : depth) m = std::max(m, w.error);
  }
  return m;
}

bool error_cut_walk::extend(double max_error, const parallel_loop& run,
                            const std::function<bool()>& stop) {
  PROGISO_ASSERT(!broken_);
  // Whether the subtree of the diamond centred at c (scale h) can hold a centre in the planes.
  const auto reaches = [this](const ipoint& c, std::int32_t h) {
    return c[2] + h >= z_begin_ && c[2] - h < z_end_;
  };
  constexpr double untested = std::numeric_limits<double>::quiet_NaN();
  // Children of this round's splits at the previous depth, to test.
  std::vector<std::uint64_t> fresh;
  constexpr std::size_t piece_items = 2048;
  for (std::size_t depth = 0; depth < waiting_.size(); ++depth) {
    // The depth's work: its waiting diamonds (known errors) and the fresh children not among
    // them (a diamond waits at most once; a split one is never a later split's child).
    std::vector<waiting>& wait = waiting_[depth];
    if (wait.empty() && fresh.empty()) continue;
    std::vector<work_item> work;
    work.reserve(wait.size() + fresh.size());
    {
      std::size_t a = 0, b = 0;
      while (a < wait.size() || b < fresh.size()) {
        if (b == fresh.size() || (a < wait.size() && wait[a].diamond <= fresh[b])) {
          if (b < fresh.size() && wait[a].diamond == fresh[b]) ++b;
          work.push_back({wait[a].diamond, wait[a].error});
          ++a;
        } else {
          work.push_back({fresh[b++], untested});
        }
      }
    }
    const std::size_t n = (work.size() + piece_items - 1) / piece_items;
    std::vector<piece_out> pieces(n);
    std::atomic<bool> stopped{false};
    run_loop(run, n, [&](std::size_t k) {
      // relaxed: only whether to skip the rest; the round's result is read after run_loop.
      if (stopped.load(std::memory_order_relaxed)) return;
      if (stop && stop()) {
        stopped.store(true, std::memory_order_relaxed);
        return;
      }
      piece_out& p = pieces[k];
      const std::size_t end = std::min(work.size(), (k + 1) * piece_items);
      for (std::size_t i = k * piece_items; i < end; ++i) {
        const ipoint c = hier_.point(work[i].diamond);
        const std::int32_t h = hier_.scale_of(c);
        double error = work[i].error;
        if (std::isnan(error)) {
          const diamond_range r = ranges_.get(c, h);
          if (!r.straddles(isovalue_)) continue;  // culled for every threshold
          error = r.error;
        }
        if (!(error > max_error)) {
          p.kept.emplace_back(work[i].diamond, error);
          continue;
        }
        if (c[2] >= z_begin_ && c[2] < z_end_) {
          share_split s;
          s.diamond = work[i].diamond;
          s.first_group = p.groups.size();
          const split_summary sum = compute_split(hier_, vol_, isovalue_, c, h, p.groups);
          s.groups = static_cast<std::uint32_t>(p.groups.size() - s.first_group);
          s.crossed = sum.crossed;
          s.value = vol_.value(c[0], c[1], c[2]);
          s.error = error;
          s.depth = static_cast<int>(depth);
          p.splits.push_back(s);
        }
        const child_list ch = hier_.children_of(c, h, hierarchy::type_of(c, h));
        for (int j = 0; j < ch.count; ++j) {
          const ipoint& cc = ch.centre[static_cast<std::size_t>(j)];
          if (reaches(cc, ch.scale)) p.next.push_back(hier_.index(cc));
        }
      }
    });
    if (stopped.load(std::memory_order_relaxed)) {
      broken_ = true;
      return false;
    }
    wait.clear();
    fresh.clear();
    for (piece_out& p : pieces) {
      const std::uint64_t base = out_.groups.size();
      for (share_split s : p.splits) {
        s.first_group += base;
        out_.splits.push_back(s);
      }
      out_.groups.insert(out_.groups.end(), p.groups.begin(), p.groups.end());
      fresh.insert(fresh.end(), p.next.begin(), p.next.end());
      for (const auto& [d, e] : p.kept) wait.push_back({d, e});  // ascending: work was
      p = piece_out{};
    }
    // A child of several parents is listed once for each that split.
    std::sort(fresh.begin(), fresh.end());
    fresh.erase(std::unique(fresh.begin(), fresh.end()), fresh.end());
  }
  round_end_ = out_.splits.size();
  return true;
}

share_splits error_cut_splits(const hierarchy& hier, const volume& vol, const range_data& ranges,
                              double isovalue, double max_error, std::int32_t z_begin,
                              std::int32_t z_end, const parallel_loop& run) {
  error_cut_walk walk(hier, vol, ranges, isovalue, z_begin, z_end);
  walk.extend(max_error, run);
  return walk.splits();
}

void write_cut_stream(const hierarchy_stream_writer::sink& out, const hierarchy& hier,
                      const volume& vol, double isovalue,
                      std::span<const share_splits* const> shares) {
  hierarchy_stream_header header;
  header.dims = vol.dims();
  // A smoothed field's samples are computed doubles; a volume's are of its type.
  header.type = vol.subdivided() != nullptr ? sample_type::f64 : vol.type();
  header.spacing = vol.spacing();
  header.origin = vol.origin();
  header.isovalue = isovalue;
  std::vector<double> corners(root_corner_count(hier));
  for (std::uint64_t i = 0; i < corners.size(); ++i) {
    const ipoint p = root_corner(hier, i);
    corners[i] = vol.value(p[0], p[1], p[2]);
  }
  std::vector<owned_triangle> root;
  for (std::uint64_t r = 0; r < hier.root_count(); ++r) {
    (void)compute_root(hier, vol, isovalue, r, root);
  }
  hierarchy_stream_writer writer(out, header, corners, root);
  // Parents first: every share's splits by depth, then grid index.
  std::vector<std::pair<std::size_t, std::size_t>> order;
  for (std::size_t k = 0; k < shares.size(); ++k) {
    for (std::size_t i = 0; i < shares[k]->splits.size(); ++i) order.emplace_back(k, i);
  }
  const auto key = [&shares](const std::pair<std::size_t, std::size_t>& at) {
    const share_split& s = shares[at.first]->splits[at.second];
    return std::pair<int, std::uint64_t>(s.depth, s.diamond);
  };
  std::sort(order.begin(), order.end(),
            [&key](const auto& a, const auto& b) { return key(a) < key(b); });
  for (const auto& [k, i] : order) {
    const share_split& s = shares[k]->splits[i];
    hierarchy_stream_record r;
    r.diamond = s.diamond;
    r.crossed = s.crossed;
    r.value = s.value;
    r.error = s.error;
    r.groups = std::span<const packed_group>(shares[k]->groups).subspan(s.first_group, s.groups);
    writer.add(r);
  }
  writer.finish();
}

namespace {

// The shares' splits as cut_mesher reads records: record 0 the root surface, then every share's
// splits in turn (the mesh does not depend on the records' order), all of them split.
struct shares_cut {
  struct record {
    std::uint64_t diamond;
    const packed_group* groups;
    std::uint32_t count;
    std::int32_t scale;
    std::uint32_t crossed;
  };
  std::vector<record> recs;
  std::vector<owned_triangle> roots;
  [[nodiscard]] std::uint64_t records() const noexcept { return recs.size(); }
  [[nodiscard]] const record& record(std::uint64_t r) const noexcept { return recs[r]; }
  [[nodiscard]] bool split(std::uint64_t r) const noexcept { return r != 0; }
  [[nodiscard]] const std::vector<owned_triangle>& root_triangles() const noexcept { return roots; }
};

// The samples a cut of the shares reads: root corners (from the volume) and split centres (from
// their records), by grid index.
struct shares_field {
  const hierarchy& hier;
  const volume& vol;
  flat_map slot;
  std::vector<double> values;
  [[nodiscard]] double value(std::int64_t x, std::int64_t y, std::int64_t z) const noexcept {
    const std::uint32_t* s =
        slot.find(hier.index({static_cast<std::int32_t>(x), static_cast<std::int32_t>(y),
                              static_cast<std::int32_t>(z)}));
    // Every vertex of the cut lies between split centres and root corners, all of them here.
    return s != nullptr ? values[*s] : 0.0;
  }
  [[nodiscard]] std::array<double, 3> spacing() const noexcept { return vol.spacing(); }
  [[nodiscard]] std::array<double, 3> origin() const noexcept { return vol.origin(); }
};

}  // namespace

triangle_mesh mesh_of_shares(const hierarchy& hier, const volume& vol, double isovalue,
                             std::span<const share_splits* const> shares, const parallel_loop& run,
                             std::size_t parts) {
  std::uint64_t splits = 0;
  for (const share_splits* s : shares) splits += s->splits.size();
  shares_cut cut;
  cut.recs.reserve(splits + 1);
  cut.recs.push_back({no_owner, nullptr, 0, 0, 0});
  for (std::uint64_t r = 0; r < hier.root_count(); ++r) {
    (void)compute_root(hier, vol, isovalue, r, cut.roots);
  }
  const std::uint64_t corners = root_corner_count(hier);
  shares_field field{hier, vol, flat_map(static_cast<std::size_t>(corners + splits + 16)), {}};
  field.values.reserve(static_cast<std::size_t>(corners + splits));
  for (std::uint64_t i = 0; i < corners; ++i) {
    const ipoint p = root_corner(hier, i);
    field.slot.try_emplace(hier.index(p), static_cast<std::uint32_t>(field.values.size()));
    field.values.push_back(vol.value(p[0], p[1], p[2]));
  }
  for (const share_splits* s : shares) {
    for (const share_split& sp : s->splits) {
      cut.recs.push_back({sp.diamond, s->groups.data() + sp.first_group, sp.groups,
                          hier.scale_of(hier.point(sp.diamond)), sp.crossed});
      field.slot.try_emplace(sp.diamond, static_cast<std::uint32_t>(field.values.size()));
      field.values.push_back(sp.value);
    }
  }
  cut_mesher mesher(cut, hier, field, isovalue);
  return mesher.build(run, parts);
}

}  // namespace progiso::detail
