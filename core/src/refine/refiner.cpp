#include <progiso/core/refine/refiner.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <string>

#include <progiso/core/base/error.hpp>
#include <progiso/core/refine/deadline.hpp>
#include <progiso/core/refine/detail/path_choice.hpp>
#include <progiso/core/refine/detail/prefetch.hpp>
#include <progiso/core/refine/detail/readiness.hpp>
#include <progiso/core/refine/detail/ready_queue.hpp>
#include <progiso/core/surface/detail/cut_mesher.hpp>
#include <progiso/core/surface/marching.hpp>
#include <progiso/core/surface/normals.hpp>

namespace progiso {
namespace {

// Per-diamond state, one byte per grid vertex (in bricks made when first written).
constexpr std::uint8_t split_bit = 0x80;
// Set on a diamond when one of its tetrahedra holds surface (it owns a group of a split
// record): its range then straddles the isovalue. Kept in breadth- and depth-first order only.
constexpr std::uint8_t surface_bit = 0x40;
constexpr std::uint8_t parent_count_mask = 0x07;

}  // namespace

namespace {

detail::queue_discipline discipline_of(refine_order order) noexcept {
  switch (order) {
    case refine_order::breadth_first:
      return detail::queue_discipline::fifo;
    case refine_order::depth_first:
      return detail::queue_discipline::lifo;
    case refine_order::largest_error_first:
      break;
  }
  return detail::queue_discipline::largest_error;
}

}  // namespace

struct refiner::queue : detail::ready_queue<refiner::ready> {
  using detail::ready_queue<refiner::ready>::ready_queue;
};

refiner::refiner(const volume& vol, const hierarchy& hier, const range_data& ranges,
                 double isovalue, refine_order order)
    : vol_(vol),
      hier_(hier),
      ranges_(ranges),
      isovalue_(isovalue),
      state_(hier),
      groups_(detail::chunked_store<packed_group>::bits_for(vol.voxel_count())),
      records_(detail::chunked_store<record>::bits_for(vol.voxel_count())),
      queue_(std::make_unique<queue>(discipline_of(order))),
      prefetch_(vol.byte_size() > detail::prefetch_min_bytes),
      errors_needed_(order == refine_order::largest_error_first),
      threshold_(isovalue) {
  if (!std::isfinite(isovalue)) {
    throw error("isovalue: expected a finite number, found " + std::to_string(isovalue));
  }
  // As many ready diamonds as one chunk of records before the queue first grows (its growth
  // by doubling copied the queue a dozen times per refinement of a small volume).
  queue_->reserve(std::size_t{1} << detail::chunked_store<record>::bits_for(vol.voxel_count()));
  // Root record: the surface in the root tetrahedra, owned by the root diamonds.
  records_.push_back({no_owner, nullptr, 0.0, 0, 0, 0});
  for (std::uint64_t r = 0; r < hier_.root_count(); ++r) {
    const std::optional<ipoint> centre = compute_root(hier_, vol_, isovalue_, r, root_triangles_);
    if (centre) {
      const diamond d = hier_.make_diamond(*centre);
      ++stats_.visited;
      const diamond_range rr = ranges_.get(d);
      if (rr.straddles(isovalue_)) {
        queue_->push({rr.error, hier_.index(*centre), *centre, d.scale,
                      static_cast<std::int16_t>(d.type), static_cast<std::int16_t>(d.depth)});
      } else {
        ++stats_.culled;
      }
    }
  }
  stats_.triangles = root_triangles_.size();
  stats_.record_triangles = root_triangles_.size();
}

refiner::~refiner() = default;

bool refiner::done() const noexcept { return queue_->empty(); }
double refiner::next_error() const noexcept {
  if (done()) return 0.0;
  const ready& top = queue_->top();
  return std::isnan(top.error) ? ranges_.get(top.centre, top.scale).error : top.error;
}

void refiner::add_classification(const split_summary& s, std::uint64_t times) const noexcept {
  for (std::size_t i = 0; i < tet_case_count; ++i) stats_.cases[i] += times * s.cases[i];
  for (std::size_t i = 0; i < primitive_count; ++i) {
    stats_.primitives[i] += times * s.primitives[i];
  }
  stats_.configurations[static_cast<std::size_t>(s.configuration)] += times;
}

const refine_statistics& refiner::statistics() const noexcept {
  if (any_pending_) {
    for (std::size_t i = 0; i < interior_classification_count; ++i) {
      if (pending_[i] == 0) continue;
      add_classification(interior_classification(i), pending_[i]);
      pending_[i] = 0;
    }
    any_pending_ = false;
  }
  return stats_;
}

int refiner::next_depth() const noexcept { return done() ? -1 : queue_->top().depth; }

bool refiner::is_split(const ipoint& centre) const noexcept {
  if (!hier_.in_grid(centre)) return false;
  const std::uint8_t* word = state_.find(centre);
  return word != nullptr && (*word & split_bit) != 0;
}

bool refiner::split_next() { return split(~std::uint64_t{0}); }
bool refiner::split_next_within(std::uint64_t max_triangles) { return split(max_triangles); }

bool refiner::split(std::uint64_t max_triangles) {
  if (queue_->empty()) return false;
  const ready next = queue_->top();
  if (prefetch_) {
    if (const ready* ahead = queue_->peek(prefetch_distance)) {
      detail::prefetch_diamond_samples(vol_, ahead->centre, ahead->scale);
    }
  }
  scratch_.clear();
  const split_summary s = compute_split(hier_, vol_, isovalue_, next.centre, next.scale, scratch_);
  const std::uint64_t after = stats_.triangles + static_cast<std::uint64_t>(s.added_triangles) -
                              static_cast<std::uint64_t>(s.removed_triangles);
  if (after > max_triangles) return false;
  const packed_group* groups =
      scratch_.empty() ? nullptr : groups_.append_contiguous(scratch_.data(), scratch_.size());
  queue_->pop();
  std::uint8_t& split_word = state_.at(next.centre);
  split_word = static_cast<std::uint8_t>(split_word | split_bit);
  for (const packed_group& g : scratch_) {
    const std::uint64_t owner = group_owner(hier_, next.index, next.scale, g);
    if (owner == no_owner) continue;
    std::uint8_t& word = state_.at(owner);
    word = static_cast<std::uint8_t>(word | surface_bit);
  }
  records_.push_back({next.index, groups, next.error, static_cast<std::uint32_t>(scratch_.size()),
                      s.crossed, next.scale});
  stats_.triangles = after;
  stats_.record_triangles += static_cast<std::uint64_t>(s.added_triangles);
  ++stats_.splits;
  if (s.classification >= 0) {
    // Counted by classification, added up when the statistics are read.
    ++pending_[static_cast<std::size_t>(s.classification)];
    any_pending_ = true;
  } else {
    add_classification(s, 1);
  }

  // Children whose parents are now all split become ready.
  const child_list children = hier_.children_of(next.centre, next.scale, next.type);
  const auto depth = static_cast<std::int16_t>(next.depth + 1);
  const auto type = static_cast<std::int16_t>(children.type);
  for (int i = 0; i < children.count; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    const ipoint& c = children.centre[ui];
    const std::uint64_t ci = hier_.index(c);
    std::uint8_t& word = state_.at(c);
    // The count is the low bits and never exceeds the parent count: the add carries into
    // nothing else.
    const auto count =
        static_cast<std::uint8_t>(add_in_place(word, std::uint8_t{1}) & parent_count_mask);
    if (count != children.parents[ui]) continue;
    ++stats_.visited;
    // The rule the engine applies too (refine/detail/readiness.hpp). In breadth- and depth-first
    // order the error is left unknown and computed if asked for: next_error(), extract_cut().
    const detail::readiness rule =
        detail::ready_rule(ranges_, c, children.scale, (word & surface_bit) != 0, errors_needed_,
                           isovalue_, threshold_);
    if (!rule.keep) {
      ++stats_.culled;
      continue;
    }
    queue_->push({rule.error, ci, c, children.scale, type, depth});
  }
  return true;
}

void refiner::refine_full() {
  while (split_next()) {
  }
}

void refiner::aim_at_error(double max_error) { queue_->aim_at(max_error); }

void refiner::refine_to_error(double max_error) {
  aim_at_error(max_error);
  while (!done() && next_error() > max_error) split_next();
}

void refiner::refine_to_triangles(std::uint64_t max_triangles) {
  while (split_next_within(max_triangles)) {
  }
}

void refiner::refine_until(std::chrono::steady_clock::time_point deadline) {
  while (!done() && std::chrono::steady_clock::now() < deadline) split_next();
}

void refiner::refine_set(const std::function<bool(std::uint64_t)>& in_set) {
  while (!queue_->empty()) {
    if (in_set(queue_->top().index)) {
      split_next();
    } else {
      queue_->pop();
    }
  }
}

template <class InCut>
triangle_mesh refiner::build_mesh(const InCut& in_cut) const {
  // The cut as cut_mesher reads it: the records, of which in_cut(r) are split in the cut.
  struct cut {
    const detail::chunked_store<refiner::record>& recs;
    const std::vector<owned_triangle>& roots;
    const InCut& in;
    [[nodiscard]] std::uint64_t records() const noexcept { return recs.size(); }
    [[nodiscard]] const refiner::record& record(std::uint64_t r) const noexcept { return recs[r]; }
    [[nodiscard]] bool split(std::uint64_t r) const noexcept { return in(recs[r]); }
    [[nodiscard]] const std::vector<owned_triangle>& root_triangles() const noexcept {
      return roots;
    }
  };
  const cut c{records_, root_triangles_, in_cut};
  detail::cut_mesher<cut> mesher(c, hier_, vol_, isovalue_);
  return mesher.build({}, 1);
}

triangle_mesh refiner::extract() const {
  return build_mesh([](const record&) { return true; });
}

triangle_mesh refiner::extract_cut(double max_error) const {
  // A split is in the cut when its nested error exceeds max_error (the range data's where the
  // refinement did not need it); errors shrink from parent to child, so the cut is closed under
  // parents.
  return build_mesh([this, max_error](const record& r) {
    if (r.diamond == no_owner) return true;  // the root record
    const double e =
        std::isnan(r.error) ? ranges_.get(hier_.point(r.diamond), r.scale).error : r.error;
    return e > max_error;
  });
}

// ---------------------------------------------------------------------------------------------

void check_extract_inputs(double isovalue, const extract_options& options) {
  if (!std::isfinite(isovalue)) {
    throw error("isovalue: expected a finite number, found " + std::to_string(isovalue));
  }
  check_goal(options.goal);
}

ladder_progress ladder_direct_progress(const extract_options& options, int max_depth) {
  if (!options.progress) return {};
  return [&options, max_depth](std::int32_t stride, std::uint64_t done, std::uint64_t total) {
    extract_progress p;
    p.depth = max_depth;
    p.max_depth = max_depth;
    p.rows_done = done;
    p.rows_total = total;
    p.stride = stride;
    options.progress(p);
  };
}

finest_progress direct_progress(const extract_options& options, int max_depth) {
  ladder_progress each = ladder_direct_progress(options, max_depth);
  if (!each) return {};
  return
      [each = std::move(each)](std::uint64_t done, std::uint64_t total) { each(1, done, total); };
}

extract_result extract_isosurface(const volume& vol, double isovalue,
                                  const extract_options& options) {
  return detail::extract_isosurface(vol, isovalue, options, {});
}

extract_result detail::extract_isosurface(const volume& vol, double isovalue,
                                          const extract_options& options, path_choice path) {
  using clock = std::chrono::steady_clock;
  const auto seconds = [](clock::duration d) { return std::chrono::duration<double>(d).count(); };
  check_extract_inputs(isovalue, options);
  extract_result res;
  const auto t0 = clock::now();
  using kind = refine_goal::kind;
  const refine_goal& goal = options.goal;
  const bool finest = goal.what == kind::full && path.finest_direct;
  // Uniform cuts, coarse to fine, until the deadline (the engine's entry does the same after
  // its root surface); the first is always made, so it is the first surface.
  const bool ladder = goal.what == kind::deadline && options.deadline_ladder && vol.dims()[2] >= 2;
  if (finest || ladder) {
    // No range data or splits: the finest cut alone by two passes over the samples, or the
    // ladder's uniform cuts by the same passes (the engine's entry does the same after its
    // root surface).
    const int max_depth = hierarchy(vol.dims()).max_depth();
    if (finest) {
      res.mesh = finest_surface(vol, isovalue, {}, 1, direct_progress(options, max_depth));
      res.finest_direct = true;
    } else {
      ladder_result l = ladder_surface(vol, isovalue, goal.deadline, {}, 1,
                                       ladder_direct_progress(options, max_depth));
      res.mesh = std::move(l.mesh);
      res.ladder_stride = l.stride;
      res.ladder_out_of_memory = l.out_of_memory;
      res.first_surface_seconds = l.first_seconds;
    }
    const auto t1 = clock::now();
    res.extract_seconds = seconds(t1 - t0);
    if (finest) res.first_surface_seconds = res.extract_seconds;
    res.total_seconds = res.extract_seconds;
    res.pipeline_seconds = res.extract_seconds;
    res.stats.triangles = res.mesh.triangles.size();
    if (options.normals) {
      add_vertex_normals(res.mesh, vol);
      res.normals_seconds = seconds(clock::now() - t1);
    }
    const auto [lo, hi] = vol.value_range();
    res.isovalue_outside_data = !(lo <= isovalue && isovalue < hi);
    return res;
  }
  const hierarchy hier(vol.dims());
  const range_data ranges(vol, hier);
  const auto t1 = clock::now();
  res.range_build_seconds = seconds(t1 - t0);
  res.range_bytes = ranges.byte_size();

  const refine_order order =
      goal.what == kind::full ? refine_order::breadth_first : refine_order::largest_error_first;
  refiner ref(vol, hier, ranges, isovalue, order);
  {
    const triangle_mesh first = ref.extract();
    res.first_surface_seconds = seconds(clock::now() - t1);
  }
  extract_progress prog;
  prog.max_depth = hier.max_depth();
  std::uint64_t since = 0;
  const auto report = [&] {
    if (!options.progress || ++since < 4096) return;
    since = 0;
    prog.splits = ref.statistics().splits;
    prog.triangles = ref.triangle_count();
    prog.depth = ref.next_depth();
    options.progress(prog);
  };
  switch (goal.what) {
    case kind::full:
      while (ref.split_next()) report();
      break;
    case kind::error:
      ref.aim_at_error(goal.max_error);
      while (!ref.done() && ref.next_error() > goal.max_error) {
        ref.split_next();
        report();
      }
      break;
    case kind::budget:
      while (ref.split_next_within(goal.max_elements)) report();
      break;
    case kind::deadline:
      while (!ref.done() && clock::now() < goal.deadline) {
        ref.split_next();
        report();
      }
      break;
  }
  const auto t2 = clock::now();
  res.refine_seconds = seconds(t2 - t1);
  res.mesh = ref.extract();
  const auto t3 = clock::now();
  res.extract_seconds = seconds(t3 - t2);
  res.total_seconds = seconds(t3 - t0);
  res.pipeline_seconds = res.total_seconds;
  if (options.normals) {
    add_vertex_normals(res.mesh, vol);
    res.normals_seconds = seconds(clock::now() - t3);
  }
  res.stats = ref.statistics();
  // A scan of every sample: after the timings, not inside "first surface".
  const auto [lo, hi] = vol.value_range();
  res.isovalue_outside_data = !(lo <= isovalue && isovalue < hi);
  return res;
}

}  // namespace progiso
