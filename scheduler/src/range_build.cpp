// The pruning data of a run: the range data built in slices with the engine's threads.

#include "engine_impl.hpp"

namespace progiso::detail {

const range_data& engine_impl::ranges() const {
  // acquire: pairs with the release in build_ranges(); the data is then complete.
  if (ranges_ready.load(std::memory_order_acquire) && ranges_->errors_exact()) return *ranges_;
  if (in_own_callback()) {
    throw error(
        "engine: ranges() cannot build the range data from the engine's progress callback "
        "(it would wait for the run that calls it); call it outside the callback");
  }
  const std::lock_guard lock(build_mutex);
  build_ranges(clock::time_point::max(), false, true);
  return *ranges_;
}

bool engine_impl::build_ranges(clock::time_point until, bool stop_requests, bool errors) const {
  const auto t0 = clock::now();
  if (!ranges_) ranges_.emplace(vol, hier, range_data::staged);
  range_data& rd = *ranges_;
  const std::size_t n = rd.piece_count();
  const std::size_t m = rd.error_piece_count();
  const bool fuse = errors && m == n;
  // No step that is expected to end past `until` (the first has no estimate yet).
  const auto fits = [&](std::size_t step) {
    const auto expected = std::chrono::duration<double>(
        seconds_per_work() *
        static_cast<double>(rd.piece_work(pieces_built, std::min(n, pieces_built + step))));
    return clock::now() + std::chrono::duration_cast<clock::duration>(expected) < until &&
           !(stop_requests && stopping());
  };
  // isolate: while it waits for its slabs, the building thread runs only slab tasks, never
  // another caller's delegated work. Steps of one slab per thread, the clock between them.
  arena.execute([&] {
    tbb::this_task_arena::isolate([&] {
      // Without a time limit, one parallel loop over everything left (no step barriers).
      const bool unlimited = until == clock::time_point::max() && !stop_requests;
      while (pieces_built < n) {
        const std::size_t step =
            unlimited ? n - pieces_built : std::min<std::size_t>(n - pieces_built, threads);
        if (!fits(step)) break;
        const auto p0 = clock::now();
        if (fuse && error_pieces_built == pieces_built) {
          rd.build_pieces_with_errors(pieces_built, pieces_built + step, tbb_loop);
          error_pieces_built += step;
        } else {
          rd.build_pieces(pieces_built, pieces_built + step, tbb_loop);
          piece_seconds += std::chrono::duration<double>(clock::now() - p0).count();
          min_max_work += rd.piece_work(pieces_built, pieces_built + step);
        }
        pieces_built += step;
      }
      if (pieces_built == n && !rd.complete()) rd.finish(tbb_loop);
      if (!errors || !rd.complete()) return;
      while (error_pieces_built < m) {
        const std::size_t step = unlimited ? m - error_pieces_built
                                           : std::min<std::size_t>(m - error_pieces_built, threads);
        if (!fits(0)) break;
        rd.build_error_pieces(error_pieces_built, error_pieces_built + step, tbb_loop);
        error_pieces_built += step;
      }
      if (error_pieces_built == m && !rd.errors_exact()) rd.finish_errors(tbb_loop);
    });
  });
  const double spent = std::chrono::duration<double>(clock::now() - t0).count();
  // relaxed: a statistic; writers hold build_mutex, readers take any value.
  range_seconds.store(range_seconds.load(std::memory_order_relaxed) + spent,
                      std::memory_order_relaxed);
  // relaxed: this thread holds build_mutex, and only holders of it store the flag.
  if (rd.complete() && !ranges_ready.load(std::memory_order_relaxed)) {
    // release: pairs with the acquire loads in ranges(), built_ranges(), the driver and
    // engine::ranges_built() / errors_built().
    ranges_ready.store(true, std::memory_order_release);
  }
  return rd.complete() && (!errors || rd.errors_exact());
}

}  // namespace progiso::detail
