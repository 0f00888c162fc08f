#include <progiso/core/refine/error_cut_share.hpp>

#include <algorithm>
#include <optional>

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

// What one piece of a depth's candidates gives: its splits (groups numbered from 0) and the
// children to test at the next depth.
struct piece_out {
  std::vector<share_split> splits;
  std::vector<packed_group> groups;
  std::vector<std::uint64_t> next;
};

}  // namespace

share_splits error_cut_splits(const hierarchy& hier, const volume& vol, const range_data& ranges,
                              double isovalue, double max_error, std::int32_t z_begin,
                              std::int32_t z_end, const parallel_loop& run) {
  share_splits out;
  if (z_begin >= z_end) return out;
  // Whether the subtree of the diamond centred at c (scale h) can hold a centre in the planes.
  const auto reaches = [z_begin, z_end](const ipoint& c, std::int32_t h) {
    return c[2] + h >= z_begin && c[2] - h < z_end;
  };
  std::vector<std::uint64_t> level;
  {
    std::vector<owned_triangle> scratch;
    for (std::uint64_t r = 0; r < hier.root_count(); ++r) {
      scratch.clear();
      const std::optional<ipoint> c = compute_root(hier, vol, isovalue, r, scratch);
      if (c && reaches(*c, hier.scale_of(*c))) level.push_back(hier.index(*c));
    }
  }
  std::sort(level.begin(), level.end());
  constexpr std::size_t piece_items = 2048;
  while (!level.empty()) {
    const std::size_t n = (level.size() + piece_items - 1) / piece_items;
    std::vector<piece_out> pieces(n);
    run_loop(run, n, [&](std::size_t k) {
      piece_out& p = pieces[k];
      const std::size_t end = std::min(level.size(), (k + 1) * piece_items);
      for (std::size_t i = k * piece_items; i < end; ++i) {
        const ipoint c = hier.point(level[i]);
        const std::int32_t h = hier.scale_of(c);
        const diamond_range r = ranges.get(c, h);
        if (!r.straddles(isovalue) || !(r.error > max_error)) continue;
        if (c[2] >= z_begin && c[2] < z_end) {
          share_split s;
          s.diamond = level[i];
          s.first_group = p.groups.size();
          const split_summary sum = compute_split(hier, vol, isovalue, c, h, p.groups);
          s.groups = static_cast<std::uint32_t>(p.groups.size() - s.first_group);
          s.crossed = sum.crossed;
          s.value = vol.value(c[0], c[1], c[2]);
          s.error = r.error;
          s.depth = hier.depth_of(c);
          p.splits.push_back(s);
        }
        const child_list ch = hier.children_of(c, h, hierarchy::type_of(c, h));
        for (int j = 0; j < ch.count; ++j) {
          const ipoint& cc = ch.centre[static_cast<std::size_t>(j)];
          if (reaches(cc, ch.scale)) p.next.push_back(hier.index(cc));
        }
      }
    });
    level.clear();
    for (piece_out& p : pieces) {
      const std::uint64_t base = out.groups.size();
      for (share_split s : p.splits) {
        s.first_group += base;
        out.splits.push_back(s);
      }
      out.groups.insert(out.groups.end(), p.groups.begin(), p.groups.end());
      level.insert(level.end(), p.next.begin(), p.next.end());
      p = piece_out{};
    }
    // A child of several parents is listed once for each that split.
    std::sort(level.begin(), level.end());
    level.erase(std::unique(level.begin(), level.end()), level.end());
  }
  return out;
}

void write_cut_stream(const hierarchy_stream_writer::sink& out, const hierarchy& hier,
                      const volume& vol, double isovalue, std::span<const share_splits> shares) {
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
  // Merge: the next split of every share, smallest (depth, diamond) first. Shares are few.
  std::vector<std::size_t> at(shares.size(), 0);
  for (;;) {
    std::size_t best = shares.size();
    for (std::size_t k = 0; k < shares.size(); ++k) {
      if (at[k] == shares[k].splits.size()) continue;
      if (best == shares.size()) {
        best = k;
        continue;
      }
      const share_split& a = shares[k].splits[at[k]];
      const share_split& b = shares[best].splits[at[best]];
      if (a.depth < b.depth || (a.depth == b.depth && a.diamond < b.diamond)) best = k;
    }
    if (best == shares.size()) break;
    const share_split& s = shares[best].splits[at[best]++];
    hierarchy_stream_record r;
    r.diamond = s.diamond;
    r.crossed = s.crossed;
    r.value = s.value;
    r.error = s.error;
    r.groups = std::span<const packed_group>(shares[best].groups).subspan(s.first_group, s.groups);
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
                             std::span<const share_splits> shares, const parallel_loop& run,
                             std::size_t parts) {
  std::uint64_t splits = 0;
  for (const share_splits& s : shares) splits += s.splits.size();
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
  for (const share_splits& s : shares) {
    for (const share_split& sp : s.splits) {
      cut.recs.push_back({sp.diamond, s.groups.data() + sp.first_group, sp.groups,
                          hier.scale_of(hier.point(sp.diamond)), sp.crossed});
      field.slot.try_emplace(sp.diamond, static_cast<std::uint32_t>(field.values.size()));
      field.values.push_back(sp.value);
    }
  }
  cut_mesher mesher(cut, hier, field, isovalue);
  return mesher.build(run, parts);
}

}  // namespace progiso::detail
