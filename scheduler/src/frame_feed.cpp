// A render thread's surface fed by a producer thread through Boost.Lockfree queues
// (frame_feed.hpp).

#include <progiso/scheduler/frame_feed.hpp>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <boost/lockfree/spsc_queue.hpp>

#include <progiso/core/base/error.hpp>

namespace progiso {

namespace {

// One frame handed over: a change to apply, or a pool holding a whole cut; and the cut it
// brings the render thread to. Back from the render thread, the same carries what is returned.
struct frame {
  surface_change* change = nullptr;
  render_slots* pool = nullptr;
  cut_mark mark;
};

[[nodiscard]] bool same_cut(const cut_mark& a, const cut_mark& b) noexcept {
  return a.owner == b.owner && a.generation == b.generation && a.records == b.records &&
         a.root == b.root;
}

}  // namespace

struct frame_feed::state {
  state(const engine& eng, frame_feed_options o)
      : e(eng),
        options(o),
        // Every change and pool ever made fits in `back` at once (depth changes in flight and
        // one being made; depth pools in flight, the shown one and one being filled), so the
        // render thread's push there never fails.
        ready(o.depth),
        back(2 * o.depth + 4) {}

  const engine& e;
  frame_feed_options options;
  // Producer → render thread, and back. Each is wait-free for its one producer and one
  // consumer; a push happens before the pop that takes the item (the queue's own release and
  // acquire), which orders the change's or pool's contents.
  boost::lockfree::spsc_queue<frame> ready;
  boost::lockfree::spsc_queue<frame> back;

  // Everything made, owned here (made by the producer, or the constructor before it starts;
  // freed after it is joined).
  std::vector<std::unique_ptr<surface_change>> changes;
  std::vector<std::unique_ptr<render_slots>> pools;

  // Producer's.
  std::vector<surface_change*> free_changes;
  std::vector<render_slots*> free_pools;
  cut_mark handed;  // the last cut handed over

  // Render thread's.
  render_slots* shown = nullptr;
  bool replaced = false;
  std::vector<std::uint32_t> written;
  cut_mark shown_mark;

  std::mutex mutex;  // quit, failure, and the producer's sleep
  std::condition_variable wake;
  bool quit = false;
  std::exception_ptr failure;  // the producer's, rethrown by the next update()
  std::thread producer;

  // Statistics: relaxed, each read alone.
  std::atomic<std::uint64_t> frames{0};
  std::atomic<std::uint64_t> pool_frames{0};
  std::atomic<std::uint64_t> taken{0};
  std::atomic<std::uint64_t> producer_ns{0};

  // An object from the producer's free list, or a new one owned by `all`.
  template <class T>
  static T* take(std::vector<T*>& free, std::vector<std::unique_ptr<T>>& all) {
    if (!free.empty()) {
      T* t = free.back();
      free.pop_back();
      return t;
    }
    all.push_back(std::make_unique<T>());
    return all.back().get();
  }

  // One look at the engine: a frame handed over when its cut is newer than the last one.
  void produce() {
    frame f;
    while (back.pop(f)) {
      if (f.change != nullptr) free_changes.push_back(f.change);
      if (f.pool != nullptr) free_pools.push_back(f.pool);
    }
    if (ready.write_available() == 0) return;  // the render thread is behind: latest wins later
    const surface_snapshot s = e.snapshot();
    const cut_mark m = s.mark();
    if (same_cut(m, handed)) return;
    const auto t0 = std::chrono::steady_clock::now();
    surface_change* c = take(free_changes, changes);
    s.change_since(handed, *c, options.normals);
    frame out;
    out.mark = m;
    if (c->rebuilt) {
      render_slots* p = take(free_pools, pools);
      p->clear();
      p->apply(*c);
      free_changes.push_back(c);
      out.pool = p;
    } else {
      // Even a change of no triangle (splits whose records add none) is handed over: mark()
      // tells the render thread which cut it holds.
      out.change = c;
    }
    const bool pushed = ready.push(out);  // room was checked above; this thread is the only writer
    (void)pushed;
    handed = m;
    // relaxed: statistics.
    frames.fetch_add(1, std::memory_order_relaxed);
    if (out.pool != nullptr) pool_frames.fetch_add(1, std::memory_order_relaxed);
    producer_ns.fetch_add(
        static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                       std::chrono::steady_clock::now() - t0)
                                       .count()),
        std::memory_order_relaxed);
  }

  void run() noexcept {
    std::unique_lock lock(mutex);
    while (!quit) {
      lock.unlock();
      try {
        produce();
      } catch (...) {
        lock.lock();
        failure = std::current_exception();
        return;
      }
      lock.lock();
      wake.wait_for(lock, options.poll, [this] { return quit; });
    }
  }
};

frame_feed::frame_feed(const engine& e, frame_feed_options options) {
  if (options.depth < 1 || options.depth > 64) {
    throw error("frame_feed: expected a depth in [1, 64], found " + std::to_string(options.depth));
  }
  s_ = std::make_unique<state>(e, options);
  s_->pools.push_back(std::make_unique<render_slots>());
  s_->shown = s_->pools.back().get();
  s_->producer = std::thread([st = s_.get()] { st->run(); });
}

frame_feed::~frame_feed() {
  {
    const std::lock_guard lock(s_->mutex);
    s_->quit = true;
  }
  s_->wake.notify_one();
  s_->producer.join();
}

std::size_t frame_feed::update() {
  state& st = *s_;
  st.written.clear();
  st.replaced = false;
  std::size_t n = 0;
  frame f;
  while (st.ready.pop(f)) {
    frame returned;
    if (f.pool != nullptr) {
      returned.pool = st.shown;
      st.shown = f.pool;
      st.replaced = true;
      st.written.clear();
    } else {
      st.shown->apply(*f.change);
      if (!st.replaced) {
        const std::span<const std::uint32_t> w = st.shown->written();
        st.written.insert(st.written.end(), w.begin(), w.end());
      }
      returned.change = f.change;
    }
    const bool pushed = st.back.push(returned);  // sized for every object: never full
    (void)pushed;
    st.shown_mark = f.mark;
    ++n;
  }
  st.taken.fetch_add(n, std::memory_order_relaxed);  // relaxed: a statistic
  if (n == 0) {
    const std::lock_guard lock(st.mutex);
    if (st.failure) std::rethrow_exception(std::exchange(st.failure, nullptr));
  }
  return n;
}

const render_slots& frame_feed::surface() const noexcept { return *s_->shown; }
bool frame_feed::replaced() const noexcept { return s_->replaced; }
std::span<const std::uint32_t> frame_feed::written() const noexcept { return s_->written; }
cut_mark frame_feed::mark() const noexcept { return s_->shown_mark; }

frame_feed_statistics frame_feed::statistics() const noexcept {
  frame_feed_statistics out;
  // relaxed: statistics.
  out.frames = s_->frames.load(std::memory_order_relaxed);
  out.pools = s_->pool_frames.load(std::memory_order_relaxed);
  out.taken = s_->taken.load(std::memory_order_relaxed);
  out.producer_seconds =
      static_cast<double>(s_->producer_ns.load(std::memory_order_relaxed)) * 1e-9;
  return out;
}

}  // namespace progiso
