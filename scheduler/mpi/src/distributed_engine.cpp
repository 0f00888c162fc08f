#include <progiso/mpi/distributed_engine.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include <progiso/core/base/error.hpp>
#include <progiso/mpi/detail/distributed_cut.hpp>
#include <progiso/mpi/detail/messages.hpp>

namespace progiso {

namespace {

using clock = std::chrono::steady_clock;

// The control block the root broadcasts before each round, as doubles.
enum control_slot : std::size_t {
  c_quit,      // 1: end the engine
  c_start,     // 1: a goal was started
  c_isovalue,  // 1: a new isovalue, in c_w
  c_w,
  c_go,        // 1: run a round
  c_floor,     // the goal's error threshold (0 for deadline, budget, full)
  c_duration,  // ms a deadline gives each run (infinity: none)
  c_slots
};

}  // namespace

distributed_engine::distributed_engine(MPI_Comm comm, const volume& vol, double isovalue,
                                       options opt)
    : threads_(opt.threads), on_snapshot_(std::move(opt.on_snapshot)), vol_(vol) {
  int level = MPI_THREAD_SINGLE;
  MPI_Query_thread(&level);
  if (level < MPI_THREAD_MULTIPLE) {
    throw error(
        "distributed_engine needs MPI initialised with MPI_THREAD_MULTIPLE (MPI_Init_thread): its "
        "thread on each rank calls MPI while the host's threads may too");
  }
  if (!std::isfinite(isovalue)) throw error("the isovalue is not a finite number");
  MPI_Comm_dup(comm, &comm_);
  MPI_Comm_rank(comm_, &rank_);
  root_ = opt.root;
  try {
    cut_ = std::make_unique<detail::distributed_cut>(comm_, root_, vol, isovalue);
    hier_ = std::make_shared<const hierarchy>(vol.dims());
  } catch (...) {
    MPI_Comm_free(&comm_);
    throw;
  }
  if (is_root()) publish(0, nullptr, false);  // on_snapshot hears it from the engine's thread
  thread_ = std::thread([this] { serve(); });
}

distributed_engine::~distributed_engine() {
  if (is_root()) {
    const std::lock_guard lock(mutex_);
    pending_.quit = true;
    interrupt_.store(true, std::memory_order_relaxed);
    changed_.notify_all();
  }
  thread_.join();
  cut_.reset();
  MPI_Comm_free(&comm_);
}

void distributed_engine::start(const refine_goal& goal) {
  if (!is_root()) throw error("distributed_engine::start: only the root rank takes commands");
  if (goal.focus) throw error("distributed_engine: a focused goal is not supported across ranks");
  check_goal(goal);
  const std::lock_guard lock(mutex_);
  pending_.start = true;
  pending_.goal = goal;
  pending_.cancel = false;
  busy_ = true;
  changed_.notify_all();
}

void distributed_engine::set_isovalue(double w) {
  if (!is_root())
    throw error("distributed_engine::set_isovalue: only the root rank takes commands");
  if (!std::isfinite(w)) throw error("the isovalue is not a finite number");
  const std::lock_guard lock(mutex_);
  pending_.isovalue = true;
  pending_.w = w;
  busy_ = true;
  interrupt_.store(true, std::memory_order_relaxed);
  changed_.notify_all();
}

void distributed_engine::cancel() {
  if (!is_root()) throw error("distributed_engine::cancel: only the root rank takes commands");
  const std::lock_guard lock(mutex_);
  pending_.cancel = true;
  pending_.start = false;
  busy_ = true;
  interrupt_.store(true, std::memory_order_relaxed);
  changed_.notify_all();
}

std::shared_ptr<const distributed_snapshot> distributed_engine::snapshot() const {
  const std::lock_guard lock(mutex_);
  return latest_;
}

void distributed_engine::wait() {
  std::unique_lock lock(mutex_);
  changed_.wait(lock, [this] { return ended_ || (is_root() && !busy_); });
}

std::shared_ptr<const triangle_mesh> distributed_snapshot::mesh() const {
  std::call_once(cut->once, [this] {
    cut->mesh = std::make_shared<const triangle_mesh>(
        detail::mesh_of_pieces(*cut->hier, *cut->vol, cut->isovalue, cut->pieces, cut->threads));
  });
  return cut->mesh;
}

void distributed_engine::publish(std::uint64_t changes, std::shared_ptr<const triangle_mesh> mesh,
                                 bool tell) {
  auto c = std::make_shared<detail::snapshot_cut>();
  c->hier = hier_;
  c->vol = &vol_;
  c->isovalue = cut_->isovalue();
  c->pieces = cut_->pieces();
  c->threads = threads_;
  if (mesh) std::call_once(c->once, [&] { c->mesh = std::move(mesh); });
  auto s = std::make_shared<distributed_snapshot>();
  s->isovalue = cut_->isovalue();
  s->max_error = cut_->threshold();
  s->splits = cut_->gathered_splits();
  s->round = cut_->rounds();
  s->isovalue_changes = changes;
  s->cut = std::move(c);
  {
    const std::lock_guard lock(mutex_);
    latest_ = s;
  }
  if (tell && on_snapshot_) on_snapshot_(s);
}

void distributed_engine::serve() {
  try {
    if (is_root() && on_snapshot_) on_snapshot_(snapshot());  // the root surface
    cut_->build_ranges(threads_);
    // The run, on every rank (the root decides it, the control block carries it).
    bool running = false;
    double floor = 0.0;
    double duration_ms = std::numeric_limits<double>::infinity();
    std::uint64_t budget = 0;  // root only: triangles, 0 for none
    bool have_goal = false;    // root only
    std::uint64_t changes = 0;
    double shown =
        std::numeric_limits<double>::infinity();  // root: the latest snapshot's threshold
    clock::time_point until = clock::time_point::max();
    const auto out_of_time = [&until] { return clock::now() >= until; };
    // On the root: the cut gathered so far as the next snapshot, unless it passes the budget
    // (then the run ends, and the previous snapshot is the last within it).
    // A budget needs the round's triangles, so the root meshes each round then (the snapshot
    // keeps that mesh); otherwise a snapshot is meshed only when a reader asks.
    const auto show = [&]() -> bool {
      std::shared_ptr<const triangle_mesh> mesh;
      if (budget != 0) {
        mesh = std::make_shared<const triangle_mesh>(cut_->mesh(threads_));
        if (mesh->triangles.size() > budget) {
          running = false;
          return false;
        }
      }
      shown = cut_->threshold();
      publish(changes, std::move(mesh));
      return true;
    };
    for (;;) {
      double c[c_slots] = {};
      if (is_root()) {
        std::unique_lock lock(mutex_);
        const auto pending = [this] {
          return pending_.quit || pending_.start || pending_.isovalue || pending_.cancel;
        };
        if (!running && !pending()) {
          busy_ = false;
          changed_.notify_all();
          changed_.wait(lock, pending);
        }
        const pending_command p = pending_;
        pending_ = {};
        interrupt_.store(false, std::memory_order_relaxed);
        lock.unlock();
        if (p.start) {
          have_goal = true;
          const refine_goal& g = p.goal;
          floor = g.what == refine_goal::kind::error ? g.max_error : 0.0;
          budget =
              g.what == refine_goal::kind::budget ? std::max<std::uint64_t>(g.max_elements, 1) : 0;
          duration_ms = g.what == refine_goal::kind::deadline
                            ? std::max(0.0, std::chrono::duration<double, std::milli>(g.deadline -
                                                                                      clock::now())
                                                .count())
                            : std::numeric_limits<double>::infinity();
          running = true;
        }
        if (p.cancel) have_goal = running = false;
        if (p.isovalue && have_goal) running = true;
        c[c_quit] = p.quit ? 1 : 0;
        c[c_start] = p.start ? 1 : 0;
        c[c_isovalue] = p.isovalue ? 1 : 0;
        c[c_w] = p.w;
        c[c_go] = running ? 1 : 0;
        c[c_floor] = floor;
        c[c_duration] = duration_ms;
      }
      MPI_Request request = MPI_REQUEST_NULL;
      MPI_Ibcast(c, c_slots, MPI_DOUBLE, root_, comm_, &request);
      detail::wait_politely(request);
      if (c[c_quit] != 0) break;
      running = c[c_go] != 0;
      floor = c[c_floor];
      if (c[c_isovalue] != 0) {
        cut_->restart(c[c_w]);
        ++changes;
        shown = std::numeric_limits<double>::infinity();
        if (is_root()) publish(changes, nullptr);
      } else if (c[c_start] != 0 && cut_->broken()) {
        cut_->restart(cut_->isovalue());  // an abandoned round: the same cut again, not shown
      }
      if (c[c_start] != 0 || c[c_isovalue] != 0) {
        until = std::isinf(c[c_duration])
                    ? clock::time_point::max()
                    : clock::now() + std::chrono::duration_cast<clock::duration>(
                                         std::chrono::duration<double, std::milli>(c[c_duration]));
      }
      if (!running) continue;
      // A round kept past a budget: a larger budget may show it now, or end the run at once
      // (the root still takes part in the agreement, as a rank that stops).
      const bool over = is_root() && c[c_start] != 0 && cut_->threshold() < shown && !show();
      const std::optional<double> next = cut_->next_threshold(floor, out_of_time() || over);
      if (!next) {
        running = false;  // agreed by every rank
        continue;
      }
      const bool root = is_root();
      const bool finished = cut_->round(*next, threads_, [this, root, &out_of_time] {
        return out_of_time() || (root && interrupt_.load(std::memory_order_relaxed));
      });
      if (!finished) continue;  // the next control block or agreement ends or restarts it
      cut_->gather();
      if (is_root() && *next < shown) show();
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "progiso: distributed_engine on rank %d: %s\n", rank_, e.what());
    MPI_Abort(comm_, 1);
  }
  const std::lock_guard lock(mutex_);
  ended_ = true;
  busy_ = false;
  changed_.notify_all();
}

}  // namespace progiso
