#include <progiso/scheduler/tbb_environment.hpp>

#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

namespace progiso::scheduler {

int default_concurrency() noexcept { return tbb::info::default_concurrency(); }

void run_on_threads(unsigned threads,
                    const std::function<void(const parallel_loop& loop, std::size_t parts)>& f) {
  const unsigned n = threads == 0 ? static_cast<unsigned>(default_concurrency()) : threads;
  if (n <= 1) {
    f(parallel_loop{}, std::size_t{1});
    return;
  }
  const parallel_loop loop = [](std::size_t count, const std::function<void(std::size_t)>& body) {
    tbb::parallel_for(std::size_t{0}, count, [&body](std::size_t i) { body(i); });
  };
  // The calling thread's arena when it has the threads asked for (its workers are warm: a fresh
  // arena's must first be woken and join it, which a short pass may not wait for).
  if (tbb::this_task_arena::max_concurrency() == static_cast<int>(n)) {
    f(loop, 16 * std::size_t{n});
    return;
  }
  tbb::task_arena arena(static_cast<int>(n));
  arena.execute([&] { f(loop, 16 * std::size_t{n}); });
}

}  // namespace progiso::scheduler
