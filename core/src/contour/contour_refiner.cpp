#include <progiso/core/contour/contour_refiner.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <string>

#include <progiso/core/base/detail/flat_map.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/refine/deadline.hpp>
#include <progiso/core/refine/detail/ready_queue.hpp>

namespace progiso {
namespace {

constexpr std::uint8_t split_bit = 0x80;
constexpr std::uint8_t parent_count_mask = 0x07;
constexpr std::uint64_t no_owner2 = ~std::uint64_t{0};

}  // namespace

struct contour_refiner::queue : detail::ready_queue<contour_refiner::ready> {
  using detail::ready_queue<contour_refiner::ready>::ready_queue;
};

contour_refiner::contour_refiner(const volume& image, const hierarchy2d& hier,
                                 const range_data2d& ranges, double isovalue, contour_order order)
    : image_(image),
      hier_(hier),
      ranges_(ranges),
      isovalue_(isovalue),
      state_(hier.vertex_count()),
      record_of_(hier.vertex_count()),
      queue_(std::make_unique<queue>(order == contour_order::breadth_first
                                         ? detail::queue_discipline::fifo
                                         : detail::queue_discipline::largest_error)) {
  if (!std::isfinite(isovalue)) {
    throw error("isovalue: expected a finite number, found " + std::to_string(isovalue));
  }
  origin_ = {image.origin()[0], image.origin()[1]};
  spacing_ = {image.spacing()[0], image.spacing()[1]};
  records_.push_back({no_owner2, {0, 0}, 0, 0, 0.0});
  std::array<std::array<ipoint2, 3>, 2> tris{};
  for (std::uint64_t r = 0; r < hier_.root_count(); ++r) {
    hier_.root_triangles(r, tris);
    const ipoint2 centre = hier_.root_centre(r);
    const bool has_diamond = hier_.root_size() >= 2;
    const std::uint64_t owner = has_diamond ? hier_.index(centre) : no_owner2;
    for (const auto& t : tris) {
      std::array<double, 3> f{};
      for (std::size_t i = 0; i < 3; ++i) f[i] = image_.value(t[i][0], t[i][1], 0);
      std::array<std::uint64_t, 2> k{};
      if (march_triangle(t, f, isovalue_, k)) {
        segments_.push_back({{owner, k}, {place(k[0]), place(k[1])}});
      }
    }
    if (has_diamond) {
      ++stats_.visited;
      const diamond_range rr = ranges_.get(centre);
      if (rr.straddles(isovalue_)) {
        queue_->push({rr.error, 0, owner, centre});
      } else {
        ++stats_.culled;
      }
    }
  }
  records_[0].count = static_cast<std::uint32_t>(segments_.size());
  stats_.segments = segments_.size();
  stats_.record_segments = segments_.size();
}

contour_refiner::~contour_refiner() = default;

bool contour_refiner::done() const noexcept { return queue_->empty(); }
double contour_refiner::next_error() const noexcept { return done() ? 0.0 : queue_->top().error; }
int contour_refiner::next_depth() const noexcept { return done() ? -1 : queue_->top().depth; }

bool contour_refiner::is_split(const ipoint2& c) const noexcept {
  return hier_.in_grid(c) && (state_.get()[hier_.index(c)] & split_bit) != 0;
}

vec2 contour_refiner::place(std::uint64_t key) const noexcept {
  const auto e = hier_.edge_ends(key);
  return interpolate2(e[0], image_.value(e[0][0], e[0][1], 0), e[1],
                      image_.value(e[1][0], e[1][1], 0), isovalue_);
}

bool contour_refiner::split_next(std::uint64_t max_segments) {
  if (queue_->empty()) return false;
  const ready next = queue_->top();
  const diamond2 d = hier_.make_diamond(next.centre);
  scratch_.clear();
  const contour_split_summary s = compute_contour_split(hier_, image_, isovalue_, d, scratch_);
  const std::uint64_t after = stats_.segments + static_cast<std::uint64_t>(s.added_segments) -
                              static_cast<std::uint64_t>(s.removed_segments);
  if (after > max_segments) return false;
  queue_->pop();
  const std::uint64_t first = segments_.size();
  for (const owned_segment& seg : scratch_) {
    segments_.push_back({seg, {place(seg.keys[0]), place(seg.keys[1])}});
  }
  std::uint8_t* state = state_.get();
  state[next.index] = static_cast<std::uint8_t>(state[next.index] | split_bit);
  record_of_.get()[next.index] = static_cast<std::uint32_t>(records_.size());
  records_.push_back(
      {next.index, next.centre, first, static_cast<std::uint32_t>(scratch_.size()), next.error});
  stats_.segments = after;
  stats_.record_segments += scratch_.size();
  ++stats_.splits;
  ++stats_.cases[static_cast<std::size_t>(s.kind)];
  for (int i = 0; i < s.op_count; ++i) {
    ++stats_.primitives[static_cast<std::size_t>(s.ops[static_cast<std::size_t>(i)].kind)];
  }
  last_ = s;
  std::array<ipoint2, 4> children{};
  const int nc = hier_.children(d, children);
  for (int i = 0; i < nc; ++i) {
    const ipoint2& c = children[static_cast<std::size_t>(i)];
    const std::uint64_t ci = hier_.index(c);
    const auto count = static_cast<std::uint8_t>((state[ci] & parent_count_mask) + 1);
    state[ci] = static_cast<std::uint8_t>((state[ci] & ~parent_count_mask) | count);
    if (count != hier_.parent_count(c)) continue;
    ++stats_.visited;
    const diamond_range r = ranges_.get(c);
    if (r.straddles(isovalue_)) {
      queue_->push({r.error, d.depth + 1, ci, c});
    } else {
      ++stats_.culled;
    }
  }
  return true;
}

void contour_refiner::refine_full() {
  while (split_next()) {
  }
}

void contour_refiner::aim_at_error(double max_error) { queue_->aim_at(max_error); }

void contour_refiner::refine_to_error(double max_error) {
  aim_at_error(max_error);
  while (!done() && next_error() > max_error) split_next();
}

void contour_refiner::refine_until(std::chrono::steady_clock::time_point deadline) {
  while (!done() && std::chrono::steady_clock::now() < deadline) split_next();
}

// ---------------------------------------------------------------------------------------------
// Extraction: live segments of the cut, clipped to the image, chained into polylines.

template <class InCut>
contour_set contour_refiner::build(InCut&& in_cut) const {
  const double bx = static_cast<double>(hier_.data_max()[0]);
  const double by = static_cast<double>(hier_.data_max()[1]);
  contour_set out;
  detail::flat_map ids(static_cast<std::size_t>(stats_.segments + 16));
  std::map<vec2, std::uint32_t> clipped;
  const auto key_id = [&](std::uint64_t key, const vec2& p) {
    const auto [id, inserted] =
        ids.try_emplace(key, static_cast<std::uint32_t>(out.vertices.size()));
    if (inserted) out.vertices.push_back(p);
    return id;
  };
  const auto point_id = [&](const vec2& p) {
    const auto [it, inserted] =
        clipped.try_emplace(p, static_cast<std::uint32_t>(out.vertices.size()));
    if (inserted) out.vertices.push_back(p);
    return it->second;
  };
  std::vector<std::array<std::uint32_t, 2>> segs;
  const std::uint8_t* state = state_.get();
  for (const record& r : records_) {
    if (!in_cut(r.diamond, r.centre, r.error, true)) continue;
    for (std::uint64_t i = r.first; i < r.first + r.count; ++i) {
      const owned_segment& s = segments_[i].seg;
      if (s.owner != no_owner2 && (state[s.owner] & split_bit) != 0 &&
          in_cut(s.owner, ipoint2{}, 0.0, false)) {
        continue;
      }
      const vec2 p = segments_[i].pos[0];
      const vec2 q = segments_[i].pos[1];
      if (p[0] <= bx && p[1] <= by && q[0] <= bx && q[1] <= by) {
        segs.push_back({key_id(s.keys[0], p), key_id(s.keys[1], q)});
        continue;
      }
      // Clip against x ≤ bx and y ≤ by; crossings computed from the lexicographically ordered
      // ends so that neighbours agree exactly. The direction of the segment is kept. When the
      // inside end lies on the border line, what remains is that point: the segment is dropped.
      vec2 a = p, b = q;
      bool a_orig = true, b_orig = true, keep = true;
      for (std::size_t axis = 0; axis < 2 && keep; ++axis) {
        const double lim = axis == 0 ? bx : by;
        const bool ain = a[axis] <= lim;
        const bool bin = b[axis] <= lim;
        if (ain && bin) continue;
        if ((!ain && !bin) || (ain && a[axis] == lim) || (bin && b[axis] == lim)) {
          keep = false;
          break;
        }
        vec2 u = a, v = b;
        if (v < u) std::swap(u, v);
        const double t = (lim - u[axis]) / (v[axis] - u[axis]);
        vec2 x{u[0] + t * (v[0] - u[0]), u[1] + t * (v[1] - u[1])};
        x[axis] = lim;
        if (!ain) {
          a = x;
          a_orig = false;
        } else {
          b = x;
          b_orig = false;
        }
      }
      if (!keep || a == b) continue;
      const std::uint32_t ia = a_orig ? key_id(s.keys[0], p) : point_id(a);
      const std::uint32_t ib = b_orig ? key_id(s.keys[1], q) : point_id(b);
      if (ia != ib) segs.push_back({ia, ib});
    }
  }
  // Chain: every vertex has at most one outgoing and one incoming segment.
  const std::uint32_t none = ~std::uint32_t{0};
  std::vector<std::uint32_t> next(out.vertices.size(), none);
  std::vector<std::uint8_t> has_in(out.vertices.size(), 0);
  for (const auto& s : segs) {
    next[s[0]] = s[1];
    has_in[s[1]] = 1;
  }
  std::vector<std::uint8_t> used(out.vertices.size(), 0);
  const auto walk = [&](std::uint32_t start, bool closed) {
    polyline pl;
    pl.closed = closed;
    pl.isovalue = isovalue_;
    std::uint32_t v = start;
    while (v != none && !used[v]) {
      used[v] = 1;
      pl.vertices.push_back(v);
      v = next[v];
    }
    if (pl.vertices.size() >= 2) out.polylines.push_back(std::move(pl));
  };
  for (std::uint32_t v = 0; v < out.vertices.size(); ++v) {
    if (!has_in[v] && next[v] != none) walk(v, false);
  }
  for (std::uint32_t v = 0; v < out.vertices.size(); ++v) {
    if (!used[v] && next[v] != none) walk(v, true);
  }
  // Physical coordinates: origin + grid position × spacing, as for volumes.
  for (vec2& p : out.vertices) {
    p = {origin_[0] + p[0] * spacing_[0], origin_[1] + p[1] * spacing_[1]};
  }
  return out;
}

contour_set contour_refiner::extract() const {
  return build([](std::uint64_t, const ipoint2&, double, bool) { return true; });
}

contour_set contour_refiner::extract_cut(double max_error) const {
  // A split owner is in the cut when its own record's error exceeds max_error: records only,
  // no image and no range data.
  return build([&](std::uint64_t diamond, const ipoint2&, double err, bool is_record) {
    if (diamond == no_owner2) return true;
    if (is_record) return err > max_error;
    return records_[record_of_.get()[diamond]].error > max_error;
  });
}

contour_set contour_refiner::extract_region(double x0, double y0, double x1, double y1) const {
  const auto stride = static_cast<std::uint64_t>(hier_.grid_max()[0]) + 1;
  // The subtree of a diamond of scale h reaches 3h (square centre) or 2h (edge midpoint) per
  // axis; these boxes nest from parent to child, so the selection is parent-closed.
  return build([&](std::uint64_t diamond, const ipoint2&, double, bool) {
    if (diamond == no_owner2) return true;
    const ipoint2 c{static_cast<std::int32_t>(diamond % stride),
                    static_cast<std::int32_t>(diamond / stride)};
    const diamond2 d = hier_.make_diamond(c);
    const double reach = (d.type == 0 ? 3.0 : 2.0) * d.scale;
    return c[0] + reach >= x0 && c[0] - reach <= x1 && c[1] + reach >= y0 && c[1] - reach <= y1;
  });
}

// ---------------------------------------------------------------------------------------------

contour_result extract_contours(const volume& image, const std::vector<double>& isovalues,
                                const contour_options& options) {
  using clock = std::chrono::steady_clock;
  const auto seconds = [](clock::duration d) { return std::chrono::duration<double>(d).count(); };
  if (image.dims()[2] != 1) {
    throw error("contour: expected a 2D image (depth 1), found depth " +
                std::to_string(image.dims()[2]));
  }
  if (isovalues.empty()) throw error("isovalues: expected at least one");
  for (const double w : isovalues) {
    if (!std::isfinite(w)) throw error("isovalues: expected finite numbers");
  }
  if (options.mode == contour_mode::error && !(options.max_error >= 0.0)) {
    throw error("error threshold: expected a non-negative number");
  }
  if (options.mode == contour_mode::time && !(options.time_budget.count() >= 0.0)) {
    throw error("time budget: expected a non-negative duration");
  }
  contour_result res;
  const auto t0 = clock::now();
  const hierarchy2d hier(image.dims()[0], image.dims()[1]);
  const range_data2d ranges(image, hier);
  const auto t1 = clock::now();
  res.range_build_seconds = seconds(t1 - t0);
  res.range_bytes = ranges.byte_size();
  const contour_order order = options.mode == contour_mode::full
                                  ? contour_order::breadth_first
                                  : contour_order::largest_error_first;
  const clock::time_point deadline = deadline_after(t1, options.time_budget);

  // Isovalues are refined one at a time, in the order given, and each one's contours go to the
  // sink (or into the result) before the next starts: memory holds one refiner, whatever the
  // number of isovalues. A segment budget or a deadline is shared fairly: each isovalue gets
  // an equal part of what the ones before it left.
  std::vector<contour_set> finished;  // kept for the frames only
  const auto append = [](contour_set& all, const contour_set& c) {
    const auto base = static_cast<std::uint32_t>(all.vertices.size());
    all.vertices.insert(all.vertices.end(), c.vertices.begin(), c.vertices.end());
    for (polyline p : c.polylines) {
      for (auto& v : p.vertices) v += base;
      all.polylines.push_back(std::move(p));
    }
  };
  int stage = 0;
  std::uint64_t splits = 0;
  clock::duration in_callbacks{};  // frames and sinks: not part of the pipeline
  const auto timed = [&in_callbacks](auto&& call) {
    const auto c0 = clock::now();
    call();
    in_callbacks += clock::now() - c0;
  };
  std::uint64_t next_frame = 1;
  const auto frame = [&](const contour_refiner* current, bool last) {
    if (!options.frame) return;
    if (last || splits >= next_frame || stage == 0) {
      contour_set all;
      for (const contour_set& c : finished) append(all, c);
      if (current != nullptr) append(all, current->extract());
      timed([&] { options.frame(all, stage++); });
      while (next_frame <= splits) next_frame *= 2;
    }
  };
  std::uint64_t segments_left = options.max_segments;
  const std::size_t n = isovalues.size();
  for (std::size_t k = 0; k < n; ++k) {
    contour_refiner r(image, hier, ranges, isovalues[k], order);
    if (options.mode == contour_mode::error) r.aim_at_error(options.max_error);
    if (k == 0) res.first_contour_seconds = seconds(clock::now() - t1);
    if (k == 0) frame(&r, false);
    const std::uint64_t share = segments_left / (n - k);
    const clock::time_point now = clock::now();
    const clock::time_point my_deadline = deadline == clock::time_point::max() || deadline <= now
                                              ? deadline
                                              : now + (deadline - now) / static_cast<long>(n - k);
    for (;;) {
      if (r.done()) break;
      if (options.mode == contour_mode::error && !(r.next_error() > options.max_error)) break;
      if (options.mode == contour_mode::time && clock::now() >= my_deadline) break;
      if (options.mode == contour_mode::segments) {
        if (!r.split_next(share)) break;
      } else {
        r.split_next();
      }
      ++splits;
      frame(&r, false);
    }
    if (options.mode == contour_mode::segments)
      segments_left -= std::min(segments_left, r.segment_count());
    contour_set c = r.extract();
    res.stats.push_back(r.statistics());
    if (options.frame) finished.push_back(c);
    if (options.sink) {
      timed([&] { options.sink(c, k); });
    } else {
      append(res.contours, c);
    }
  }
  res.refine_seconds = seconds(clock::now() - t1);
  frame(nullptr, true);
  res.total_seconds = seconds(clock::now() - t0);
  res.pipeline_seconds = res.total_seconds - seconds(in_callbacks);
  return res;
}

}  // namespace progiso
