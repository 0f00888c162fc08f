#include <progiso/core/contour/contour_refiner.hpp>

#include <progiso/core/contour/finest_contours.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <type_traits>

#include <progiso/core/base/detail/cut_index.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/refine/deadline.hpp>
#include <progiso/core/refine/detail/path_choice.hpp>
#include <progiso/core/refine/detail/ready_queue.hpp>

namespace progiso {

using detail::no_owner2;

namespace {
// Below one split per this many grid vertices a cut's splits are kept sorted rather than in a
// bitmap: a binary search per segment owner then costs less than clearing a bit per vertex (a
// bitmap costs up to 512 bytes per split here, a sorted array 8 and a search of ~20 steps).
constexpr std::uint64_t sparse_cut_vertices = 4096;
// The cut of every record (extract()).
struct whole_cut {
  bool operator()(std::uint64_t, double) const noexcept { return true; }
};
}  // namespace

struct contour_refiner::queue : detail::ready_queue<detail::contour_ready> {
  using detail::ready_queue<detail::contour_ready>::ready_queue;
};

contour_refiner::contour_refiner(const volume& image, const hierarchy2d& hier,
                                 const range_data2d& ranges, double isovalue, contour_order order)
    : image_(image),
      hier_(hier),
      ranges_(ranges),
      isovalue_(isovalue),
      frontier_(hier),
      segments_(detail::chunked_store<detail::placed_segment>::bits_for(hier.vertex_count())),
      records_(detail::chunked_store<record>::bits_for(hier.vertex_count())),
      queue_(std::make_unique<queue>(order == contour_order::breadth_first
                                         ? detail::queue_discipline::fifo
                                         : detail::queue_discipline::largest_error)) {
  if (!std::isfinite(isovalue)) {
    throw error("isovalue: expected a finite number, found " + std::to_string(isovalue));
  }
  origin_ = {image.origin()[0], image.origin()[1]};
  spacing_ = {image.spacing()[0], image.spacing()[1]};
  std::vector<ipoint2> roots;
  detail::root_contour(hier_, image_, isovalue_, root_segments_, roots);
  records_.push_back({no_owner2, root_segments_.data(), 0, 0.0});
  for (const ipoint2& c : roots) {
    ++stats_.visited;
    if (const auto r = detail::ready_contour_diamond(ranges_, isovalue_, c, hier_.scale_of(c))) {
      queue_->push(*r);
    } else {
      ++stats_.culled;
    }
  }
  records_[0].count = static_cast<std::uint32_t>(root_segments_.size());
  stats_.segments = root_segments_.size();
  stats_.record_segments = root_segments_.size();
}

contour_refiner::~contour_refiner() = default;

bool contour_refiner::done() const noexcept { return queue_->empty(); }
double contour_refiner::next_error() const noexcept { return done() ? 0.0 : queue_->top().error; }
int contour_refiner::next_depth() const noexcept {
  return done() ? -1 : hier_.make_diamond(queue_->top().centre).depth;
}

bool contour_refiner::is_split(const ipoint2& c) const noexcept {
  return hier_.in_grid(c) && frontier_.is_split(hier_.index(c));
}

bool contour_refiner::split_next(std::uint64_t max_segments) {
  if (queue_->empty()) return false;
  const detail::contour_ready next = queue_->top();
  const diamond2 d = hier_.make_diamond(next.centre);
  const std::uint64_t index = hier_.index(next.centre);
  // Written in place: room for the most a split adds, the rest given back.
  detail::placed_segment* at = segments_.reserve_contiguous(detail::max_split_segments);
  const contour_split_summary s =
      detail::compute_placed_contour_split(hier_, image_, isovalue_, d, at);
  const auto count = static_cast<std::uint32_t>(s.added_segments);
  segments_.trim(detail::max_split_segments - count);
  const std::uint64_t after = stats_.segments + static_cast<std::uint64_t>(s.added_segments) -
                              static_cast<std::uint64_t>(s.removed_segments);
  if (after > max_segments) {
    segments_.trim(count);
    return false;
  }
  queue_->pop();
  if (count == 0) at = nullptr;
  records_.push_back({index, at, count, next.error});
  stats_.segments = after;
  stats_.record_segments += count;
  ++stats_.splits;
  ++class_counts_[s.split_class];
  counts_pending_ = true;
  last_index_ = index;
  frontier_.split(d, index, [&](const ipoint2& c, std::int32_t h) {
    ++stats_.visited;
    if (const auto r = detail::ready_contour_diamond(ranges_, isovalue_, c, h)) {
      queue_->push(*r);
    } else {
      ++stats_.culled;
    }
  });
  return true;
}

const contour_statistics& contour_refiner::statistics() const noexcept {
  if (counts_pending_) {
    for (std::size_t k = 0; k < contour_split_classes; ++k) {
      const std::uint64_t n = class_counts_[k];
      if (n == 0) continue;
      const contour_split_class& c = contour_split_class_info(k);
      stats_.cases[static_cast<std::size_t>(c.kind)] += n;
      for (std::size_t i = 0; i < c.op_count; ++i) {
        stats_.primitives[static_cast<std::size_t>(c.ops[i])] += n;
      }
      class_counts_[k] = 0;
    }
    counts_pending_ = false;
  }
  return stats_;
}

contour_split_summary contour_refiner::last_split() const {
  if (last_index_ == no_owner2) return {};
  // Made again from the image: a split's sequence with its keys is wanted rarely, and making it
  // for every split cost a noticeable part of the split.
  const ipoint2 c = hier_.point(last_index_);
  std::vector<owned_segment> unused;
  return compute_contour_split(hier_, image_, isovalue_, hier_.make_diamond(c), unused);
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
  // in_cut(diamond, error) selects the split records of the cut (a parent-closed set; the root
  // record is always in). "Is this segment's owner split in the cut" is asked of the selected
  // diamonds: a bitmap (a bit per grid vertex) unless the refiner has fewer splits than one per
  // sparse_cut_vertices grid vertices, then their sorted grid indices, so that a coarse
  // refinement of a large image touches no per-vertex array. The refiner keeps no per-vertex
  // record index: it has no reader to serve.
  if constexpr (std::is_same_v<std::decay_t<InCut>, whole_cut>) {
    // Every record: the owner is split in the cut when the frontier says so.
    detail::contour_assembler out(hier_, isovalue_, static_cast<std::size_t>(stats_.segments));
    for (std::size_t i = 0; i < records_.size(); ++i) {
      const record& r = records_[i];
      out.begin_record(r.diamond);
      for (const detail::placed_segment* p = r.segments; p != r.segments + r.count; ++p) {
        const std::uint64_t owner = p->seg.owner;
        if (owner == no_owner2 || !frontier_.is_split(owner)) out.add(*p);
      }
    }
    return out.finish(origin_, spacing_);
  }
  const std::uint64_t vertices = hier_.vertex_count();
  const bool dense = records_.size() - 1 > vertices / sparse_cut_vertices;
  std::vector<std::uint8_t> taken(records_.size(), 0);  // record 0, the root's, always in
  detail::cut_index cut = dense ? detail::cut_index::dense(vertices) : detail::cut_index{};
  std::vector<std::uint64_t> selected;  // sparse: the selected grid indices
  for (std::size_t i = 1; i < records_.size(); ++i) {
    const record& r = records_[i];
    if (!in_cut(r.diamond, r.error)) continue;
    taken[i] = 1;
    if (dense) {
      cut.add_on_one_thread(r.diamond);
    } else {
      selected.push_back(r.diamond);
    }
  }
  if (!dense) cut = detail::cut_index::sparse(std::move(selected));
  detail::contour_assembler out(hier_, isovalue_, static_cast<std::size_t>(stats_.segments));
  for (std::size_t i = 0; i < records_.size(); ++i) {
    const record& r = records_[i];
    if (i != 0 && !taken[i]) continue;
    out.begin_record(r.diamond);
    for (const detail::placed_segment* p = r.segments; p != r.segments + r.count; ++p) {
      const std::uint64_t owner = p->seg.owner;
      if (owner == no_owner2 || !cut.contains(owner)) out.add(*p);
    }
  }
  return out.finish(origin_, spacing_);
}

contour_set contour_refiner::extract() const { return build(whole_cut{}); }

contour_set contour_refiner::extract_cut(double max_error) const {
  // A split is in the cut when its own record's error exceeds max_error (nested errors: the
  // selection is parent-closed): records only, no image and no range data.
  return build([max_error](std::uint64_t, double err) { return err > max_error; });
}

contour_set contour_refiner::extract_region(double x0, double y0, double x1, double y1) const {
  // The subtree of a diamond of scale h reaches 3h (square centre) or 2h (edge midpoint) per
  // axis; these boxes nest from parent to child, so the selection is parent-closed.
  return build([&](std::uint64_t diamond, double) {
    const ipoint2 c = hier_.point(diamond);
    const diamond2 d = hier_.make_diamond(c);
    const double reach = (d.type == 0 ? 3.0 : 2.0) * d.scale;
    return c[0] + reach >= x0 && c[0] - reach <= x1 && c[1] + reach >= y0 && c[1] - reach <= y1;
  });
}

// ---------------------------------------------------------------------------------------------

contour_result extract_contours(const volume& image, const std::vector<double>& isovalues,
                                const contour_options& options) {
  return detail::extract_contours(image, isovalues, options, {});
}

contour_result detail::extract_contours(const volume& image, const std::vector<double>& isovalues,
                                        const contour_options& options, path_choice path) {
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
  using kind = refine_goal::kind;
  const refine_goal& goal = options.goal;
  check_goal(goal);
  contour_result res;
  const auto t0 = clock::now();
  if (goal.what == kind::full && !options.frame && path.finest_direct) {
    // Only the finest cut is asked for: two passes over the pixels give it (finest_contours()),
    // without range data or splits. The first contour is the first isovalue's finest one.
    clock::duration in_sink{};
    for (std::size_t k = 0; k < isovalues.size(); ++k) {
      contour_set c = finest_contours(image, isovalues[k]);
      if (k == 0) res.first_contour_seconds = seconds(clock::now() - t0);
      contour_statistics st;
      st.segments = c.segment_count();
      res.stats.push_back(st);
      if (options.sink) {
        const auto c0 = clock::now();
        options.sink(c, k);
        in_sink += clock::now() - c0;
      } else if (res.contours.vertices.empty() && res.contours.polylines.empty()) {
        res.contours = std::move(c);
      } else {
        const auto base = static_cast<std::uint32_t>(res.contours.vertices.size());
        res.contours.vertices.insert(res.contours.vertices.end(), c.vertices.begin(),
                                     c.vertices.end());
        for (polyline& pl : c.polylines) {
          for (auto& v : pl.vertices) v += base;
          res.contours.polylines.push_back(std::move(pl));
        }
      }
    }
    res.finest_direct = true;
    res.total_seconds = seconds(clock::now() - t0);
    res.refine_seconds = res.total_seconds;
    res.pipeline_seconds = res.total_seconds - seconds(in_sink);
    return res;
  }
  const hierarchy2d hier(image.dims()[0], image.dims()[1]);
  const range_data2d ranges(image, hier);
  const auto t1 = clock::now();
  res.range_build_seconds = seconds(t1 - t0);
  res.range_bytes = ranges.byte_size();
  const contour_order order =
      goal.what == kind::full ? contour_order::breadth_first : contour_order::largest_error_first;
  const clock::time_point deadline =
      goal.what == kind::deadline ? goal.deadline : clock::time_point::max();

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
  std::uint64_t segments_left = goal.max_elements;
  const std::size_t n = isovalues.size();
  for (std::size_t k = 0; k < n; ++k) {
    contour_refiner r(image, hier, ranges, isovalues[k], order);
    if (goal.what == kind::error) r.aim_at_error(goal.max_error);
    if (k == 0) res.first_contour_seconds = seconds(clock::now() - t1);
    if (k == 0) frame(&r, false);
    const std::uint64_t share = segments_left / (n - k);
    const clock::time_point now = clock::now();
    const clock::time_point my_deadline = deadline == clock::time_point::max() || deadline <= now
                                              ? deadline
                                              : now + (deadline - now) / static_cast<long>(n - k);
    for (;;) {
      if (r.done()) break;
      if (goal.what == kind::error && !(r.next_error() > goal.max_error)) break;
      if (goal.what == kind::deadline && clock::now() >= my_deadline) break;
      if (goal.what == kind::budget) {
        if (!r.split_next(share)) break;
      } else {
        r.split_next();
      }
      ++splits;
      frame(&r, false);
    }
    if (goal.what == kind::budget) segments_left -= std::min(segments_left, r.segment_count());
    contour_set c = r.extract();
    res.stats.push_back(r.statistics());
    if (options.frame) finished.push_back(c);
    if (options.sink) {
      timed([&] { options.sink(c, k); });
    } else if (res.contours.vertices.empty() && res.contours.polylines.empty()) {
      res.contours = std::move(c);  // the first isovalue's: no copy of every polyline
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
