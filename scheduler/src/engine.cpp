// The public engine: construction, control calls, statistics; and extract_isosurface_parallel.

#include "engine_impl.hpp"

#include <string>

#include <progiso/core/base/error.hpp>
#include <progiso/core/surface/finest_surface.hpp>
#include <progiso/scheduler/tbb_environment.hpp>

namespace progiso {

engine::engine(const volume& vol, double isovalue, engine_options options) {
  init(nullptr, vol, isovalue, std::move(options));
}

engine::engine(volume&& vol, double isovalue, engine_options options) {
  auto owned = std::make_shared<const volume>(std::move(vol));
  const volume& v = *owned;
  init(std::move(owned), v, isovalue, std::move(options));
}

engine::engine(std::shared_ptr<const volume> vol, double isovalue, engine_options options) {
  if (!vol) throw error("engine: expected a volume, found a null pointer");
  const volume& v = *vol;
  init(std::move(vol), v, isovalue, std::move(options));
}

void engine::init(std::shared_ptr<const volume> owned, const volume& vol, double isovalue,
                  engine_options options) {
  detail::require_finite_isovalue(isovalue);
  if (options.smooth.active()) {
    // The engine refines the smoothed field; it keeps the data alive through it when it owns
    // the data, and borrows it (as for any volume given by reference) otherwise.
    std::shared_ptr<const volume> data =
        owned ? std::move(owned) : std::shared_ptr<const volume>(std::shared_ptr<void>(), &vol);
    auto field = std::make_shared<const volume>(smooth(std::move(data), options.smooth));
    const volume& f = *field;
    impl_ = std::make_unique<detail::engine_impl>(std::move(field), f, std::move(options));
  } else {
    impl_ = std::make_unique<detail::engine_impl>(std::move(owned), vol, std::move(options));
  }
  // release: pairs with the acquire in epoch_guard::protect() (snapshot()).
  impl_->root.store(impl_->make_root(isovalue, 0), std::memory_order_release);
}

engine::~engine() {
  {
    std::unique_lock lock(impl_->control);
    impl_->stop_and_join(lock);
  }
  if (impl_->graph) impl_->arena.execute([this] { impl_->graph->wait_for_all(); });
  detail::engine_root* r = impl_->current();
  impl_->root.store(nullptr, std::memory_order_relaxed);  // relaxed: no reader is left
  impl_->stop_reclaimer();                                // destroys the roots it was handed
  impl_->recycle = false;
  impl_->spare.reset();
  detail::engine_impl::destroy_root(r);
  // Participants, then the domain (which drains the retired roots), go with impl_.
  impl_->readers.clear();
}

void engine::set_isovalue(double w) {
  detail::engine_impl& e = *impl_;
  detail::swap_root(e, w, [&e](detail::engine_root& old) { e.count_retired(old); });
}

void engine::start(const refine_goal& goal) { detail::start_run(*impl_, goal); }

void engine::cancel() { impl_->cancel(); }

void engine::wait() { impl_->wait(); }

bool engine::refine(const refine_goal& goal) { return detail::refine_blocking(*impl_, goal); }

surface_snapshot engine::snapshot() const {
  surface_snapshot s;
  s.guard_ = impl_->readers.reader().pin();
  s.owner_ = this;
  s.root_ = s.guard_.protect(impl_->root);
  s.published_ = s.root_->records.published();
  return s;
}

double engine::isovalue() const {
  epoch_guard g = impl_->readers.reader().pin();
  return g.protect(impl_->root)->isovalue;
}

bool engine::running() const noexcept { return impl_->running(); }

bool engine::done() const {
  epoch_guard g = impl_->readers.reader().pin();
  return g.protect(impl_->root)->remaining.get() == 0;
}

engine_statistics engine::statistics() const {
  engine_statistics s;
  {
    epoch_guard g = impl_->readers.reader().pin();
    const detail::engine_root* r = g.protect(impl_->root);
    s.refine.splits = r->splits.get();
    s.refine.visited = r->visited.get();
    s.refine.culled = r->culled.get();
    s.refine.triangles = r->triangles.get();
    s.refine.record_triangles = r->record_triangles.get();
    for (std::size_t k = 0; k < tet_case_count; ++k) s.refine.cases[k] = r->cases[k].get();
    for (std::size_t k = 0; k < primitive_count; ++k) {
      s.refine.primitives[k] = r->primitives[k].get();
    }
    for (std::size_t k = 0; k < split_configuration_count; ++k) {
      s.refine.configurations[k] = r->configurations[k].get();
    }
    s.published = r->records.published();
    s.discarded = r->discarded.get();
    s.batches = r->batches.get();
    s.generation = r->generation;
    s.surface_published_at = r->published_at;
  }
  s.retired_bytes = impl_->retired_bytes.load(std::memory_order_relaxed);  // relaxed: a statistic
  s.peak_retired_bytes = impl_->peak_retired_bytes.get();
  s.recycled_roots = impl_->recycled_roots.get();
  // relaxed: a statistic (roots are made by the control thread and the driver).
  s.roots = impl_->next_serial.load(std::memory_order_relaxed);
  s.root_bytes = impl_->root_bytes.get();
  s.runs = impl_->runs.get();
  s.cancelled_runs = impl_->cancelled_runs.get();
  s.reclamation = impl_->domain.statistics();
  s.snapshot_retries = impl_->readers.snapshot_retries();
  return s;
}

const volume& engine::field() const noexcept { return impl_->vol; }
const hierarchy& engine::hierarchy_of() const noexcept { return impl_->hier; }
const range_data& engine::ranges() const { return impl_->ranges(); }
unsigned engine::threads() const noexcept { return impl_->threads; }
double engine::range_build_seconds() const noexcept {
  // relaxed: a statistic, added to by each step of the build.
  return impl_->range_seconds.load(std::memory_order_relaxed);
}

bool engine::errors_built() const noexcept {
  // acquire: see ranges_built(); ranges_ is then made and never replaced.
  return impl_->ranges_ready.load(std::memory_order_acquire) && impl_->ranges_->errors_exact();
}

std::size_t engine::range_bytes() const {
  const std::lock_guard lock(impl_->build_mutex);
  return impl_->ranges_ ? impl_->ranges_->byte_size() : 0;
}

bool engine::ranges_built() const noexcept {
  // acquire: pairs with the release in build_ranges() (a caller may then read ranges()).
  return impl_->ranges_ready.load(std::memory_order_acquire);
}

extract_result extract_isosurface_parallel(const volume& vol, double isovalue,
                                           const extract_options& options, unsigned threads) {
  return detail::extract_isosurface_parallel(vol, isovalue, options, threads, {});
}

extract_result detail::extract_isosurface_parallel(const volume& vol, double isovalue,
                                                   const extract_options& options, unsigned threads,
                                                   path_choice path) {
  // detail::clock (run_control.hpp) is steady_clock.
  const auto seconds = [](clock::duration d) { return std::chrono::duration<double>(d).count(); };
  check_extract_inputs(isovalue, options);
  extract_result res;
  engine_options eo;
  eo.threads = threads;
  // The direct paths below are chosen here; what runs through the engine asks for its records
  // (the hierarchy's path of a full run, refinement by priority).
  eo.uniform_cuts = false;
  int max_depth = 0;
  if (options.progress) {
    eo.progress = [&options, &max_depth](const engine_progress& p) {
      options.progress({p.splits, p.triangles, p.depth, max_depth});
    };
  }
  const auto t0 = clock::now();  // the volume is in memory
  engine eng(vol, isovalue, std::move(eo));
  max_depth = eng.hierarchy_of().max_depth();
  {
    // The root surface: no range data, no pass over the volume.
    const surface_snapshot first = eng.snapshot();
    const triangle_mesh m = first.mesh();
    res.first_surface_seconds = seconds(clock::now() - t0);
  }
  const auto t1 = clock::now();
  // The direct paths run pieces of rows on the engine's thread count, in a fresh arena (as the
  // snapshots' meshes), or on this thread alone.
  const auto direct = [&eng](const auto& f) { scheduler::run_on_threads(eng.threads(), f); };
  // A 2D field has no coarser uniform cut than its finest: it refines by priority.
  using kind = refine_goal::kind;
  const bool ladder =
      options.goal.what == kind::deadline && options.deadline_ladder && vol.dims()[2] >= 2;
  if ((options.goal.what == kind::full && path.finest_direct) || ladder) {
    // The finest cut is all a full run returns: two streaming passes over the samples give it
    // (finest_surface()), without range data, splits or records. A deadline run on the ladder
    // makes uniform cuts the same way, coarse to fine, until the deadline (ladder_surface()).
    if (ladder) {
      const ladder_progress progress = ladder_direct_progress(options, max_depth);
      direct([&](const parallel_loop& loop, std::size_t parts) {
        ladder_result l =
            ladder_surface(vol, isovalue, options.goal.deadline, loop, parts, progress);
        res.mesh = std::move(l.mesh);
        res.ladder_stride = l.stride;
        res.ladder_out_of_memory = l.out_of_memory;
      });
    } else {
      const finest_progress progress = direct_progress(options, max_depth);
      direct([&](const parallel_loop& loop, std::size_t parts) {
        res.mesh = finest_surface(vol, isovalue, loop, parts, progress);
      });
      res.finest_direct = true;
    }
    const auto t2 = clock::now();
    res.extract_seconds = seconds(t2 - t1);
    res.total_seconds = seconds(t2 - t0);
    res.pipeline_seconds = res.total_seconds;
    res.stats.triangles = res.mesh.triangles.size();
    if (options.normals) {
      eng.add_normals(res.mesh);
      res.normals_seconds = seconds(clock::now() - t2);
    }
    const auto [lo, hi] = vol.value_range();
    res.isovalue_outside_data = !(lo <= isovalue && isovalue < hi);
    return res;
  }
  // Nothing reads the cuts on the way: an error target's split set by plane, sooner. A
  // deadline's range data is built inside it.
  refine_goal goal = options.goal;
  if (goal.what == kind::error) goal.any_order = true;
  eng.refine(goal);
  const auto t2 = clock::now();
  // The first run built the range data (in parallel); refinement is the rest of the run.
  res.range_build_seconds = eng.range_build_seconds();
  // What is built so far (completing the data here would put a build after the deadline into
  // the pipeline).
  res.range_bytes = eng.range_bytes();
  res.refine_seconds = std::max(0.0, seconds(t2 - t1) - res.range_build_seconds);
  {
    const surface_snapshot s = eng.snapshot();
    res.mesh = s.mesh();
  }
  const auto t3 = clock::now();
  res.extract_seconds = seconds(t3 - t2);
  res.total_seconds = seconds(t3 - t0);
  res.pipeline_seconds = res.total_seconds;
  if (options.normals) {
    eng.add_normals(res.mesh);
    res.normals_seconds = seconds(clock::now() - t3);
  }
  res.stats = eng.statistics().refine;
  // A scan of every sample: after the timings, not inside "first surface".
  const auto [lo, hi] = vol.value_range();
  res.isovalue_outside_data = !(lo <= isovalue && isovalue < hi);
  return res;
}

}  // namespace progiso
