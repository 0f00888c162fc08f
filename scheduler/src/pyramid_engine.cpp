#include <progiso/scheduler/pyramid_engine.hpp>

#include <chrono>
#include <cmath>
#include <string>
#include <utility>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/error.hpp>

namespace progiso {
namespace {

/// How often the loader looks whether a finer level has caught up with the shown one: a switch
/// comes at most this late, and a look costs two O(1) snapshots.
constexpr std::chrono::milliseconds catch_up_poll{2};

/// Triangles of an engine's current cut.
std::uint64_t triangles_of(const engine& e) { return e.snapshot().triangle_count(); }

}  // namespace

pyramid_engine::pyramid_engine(pyramid_level_reader read, std::size_t levels, double isovalue,
                               engine_options options)
    : read_(std::move(read)), options_(std::move(options)), isovalue_(isovalue) {
  if (levels == 0) throw error("pyramid engine: the pyramid has no level");
  if (!read_) throw error("pyramid engine: no level reader");
  if (!std::isfinite(isovalue)) throw error("pyramid engine: the isovalue must be finite");
  engines_.resize(levels);
  const std::size_t coarsest = levels - 1;
  std::optional<volume> v = read_(coarsest, {});
  if (!v) throw error("pyramid engine: the coarsest level was not read");
  engines_[coarsest] = std::make_unique<engine>(std::move(*v), isovalue, options_);
  read_count_.store(1, std::memory_order_release);    // partner: levels_read()'s acquire
  shown_.store(coarsest, std::memory_order_release);  // partner: snapshot()'s acquire
}

pyramid_engine::~pyramid_engine() {
  const std::lock_guard<std::mutex> lock(control_);
  stop_loader();
  for (const std::unique_ptr<engine>& e : engines_) {
    if (e) e->cancel();
  }
}

bool pyramid_engine::stopping(const refine_goal& goal) const {
  if (stop_.load(std::memory_order_relaxed)) return true;
  return goal.what == refine_goal::kind::deadline &&
         std::chrono::steady_clock::now() >= goal.deadline;
}

void pyramid_engine::stop_loader() {
  stop_.store(true, std::memory_order_relaxed);
  if (loader_.joinable()) loader_.join();
  stop_.store(false, std::memory_order_relaxed);
}

void pyramid_engine::start(const refine_goal& goal) {
  const std::lock_guard<std::mutex> lock(control_);
  stop_loader();
  {
    const std::lock_guard<std::mutex> state(state_);
    failed_ = nullptr;
  }
  const std::size_t shown = shown_.load(std::memory_order_acquire);  // partner: load()'s release
  engines_[shown]->start(goal);
  if (shown > 0) loader_ = std::thread([this, goal] { load(goal); });
}

void pyramid_engine::load(refine_goal goal) {
  const auto stop = [this, &goal] { return stopping(goal); };
  try {
    for (;;) {
      const std::size_t shown = shown_.load(std::memory_order_relaxed);  // only this thread stores
      if (shown == 0 || stop()) return;
      const std::size_t k = shown - 1;
      engine* finer = nullptr;
      {
        const std::lock_guard<std::mutex> state(state_);
        finer = engines_[k].get();
      }
      if (finer == nullptr) {
        std::optional<volume> v = read_(k, stop);
        if (!v) return;
        const std::lock_guard<std::mutex> state(state_);
        engines_[k] = std::make_unique<engine>(std::move(*v), isovalue_, options_);
        finer = engines_[k].get();
        // partner: levels_read()'s acquire
        read_count_.fetch_add(1, std::memory_order_release);
      }
      finer->start(goal);
      engine& current = *engines_[shown];
      bool show = false;
      while (!stop()) {
        const bool ended = !finer->running();
        const bool caught_up = triangles_of(*finer) >= triangles_of(current);
        if (caught_up || (ended && goal.what != refine_goal::kind::deadline)) {
          show = true;
          break;
        }
        if (ended) break;  // a deadline ended its run short of the shown level's cut
        std::this_thread::sleep_for(catch_up_poll);
      }
      if (!show) {
        // Not shown: its run stops here (a later start() takes it up again).
        finer->cancel();
        finer->wait();
        return;
      }
      shown_.store(k, std::memory_order_release);  // partner: snapshot()'s acquire
      current.cancel();
    }
  } catch (...) {
    const std::lock_guard<std::mutex> state(state_);
    failed_ = std::current_exception();
  }
}

void pyramid_engine::cancel() {
  const std::lock_guard<std::mutex> lock(control_);
  stop_loader();
  for (const std::unique_ptr<engine>& e : engines_) {
    if (e) e->cancel();
  }
}

void pyramid_engine::wait() {
  const std::lock_guard<std::mutex> lock(control_);
  if (loader_.joinable()) loader_.join();
  engines_[shown_.load(std::memory_order_acquire)]->wait();  // partner: load()'s release
  std::exception_ptr failed;
  {
    const std::lock_guard<std::mutex> state(state_);
    failed = std::exchange(failed_, nullptr);
  }
  if (failed) std::rethrow_exception(failed);
}

void pyramid_engine::set_isovalue(double w) {
  if (!std::isfinite(w)) throw error("pyramid engine: the isovalue must be finite");
  const std::lock_guard<std::mutex> lock(control_);
  std::vector<engine*> read;
  {
    // A level the loader makes after this block starts on w; one made before is in `read`.
    const std::lock_guard<std::mutex> state(state_);
    isovalue_ = w;
    for (const std::unique_ptr<engine>& e : engines_) {
      if (e) read.push_back(e.get());
    }
  }
  // The shown level first: its new root surface is what readers see next.
  engine* shown = engines_[shown_.load(std::memory_order_acquire)].get();  // partner: load()
  shown->set_isovalue(w);
  for (engine* e : read) {
    if (e != shown) e->set_isovalue(w);
  }
}

pyramid_snapshot pyramid_engine::snapshot() const {
  // partner: the release stores of shown_ in the constructor and load(), after the slot is filled
  const std::size_t k = shown_.load(std::memory_order_acquire);
  const engine& e = *engines_[k];
  return {e.snapshot(), k, &e};
}

std::size_t pyramid_engine::level() const noexcept {
  return shown_.load(std::memory_order_acquire);  // partner: load()'s release
}

double pyramid_engine::isovalue() const {
  const std::lock_guard<std::mutex> state(state_);
  return isovalue_;
}

std::size_t pyramid_engine::levels_read() const noexcept {
  return read_count_.load(std::memory_order_acquire);  // partner: load()'s release
}

}  // namespace progiso
