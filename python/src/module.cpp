// python/src/module.cpp — progiso's extension module, `progiso._progiso`.
//
// The Python package (python/progiso/) gives the documented API; this module does the work:
// one-shot extraction (_extract), the engine (_Engine), readers (_read_volume).
//
// The GIL. Every call that may take long releases it. A blocking run goes to a helper thread
// while the calling thread waits on it, taking the GIL back every `poll` to deliver progress to
// the Python callback and to check for signals: Ctrl-C cancels the run, waits for it to stop and
// raises KeyboardInterrupt. So Python code (a progress callback) only ever runs on the thread
// that called in, holding the GIL, never on a worker. The engine's own progress hook, which runs
// on workers, only stores the latest figures.
//
// Axis order. Arrays are indexed (axis 0, axis 1, axis 2) = progiso's (z, y, x): positions and
// normals come out in axis order, spacing goes in per axis. Reversing the axes mirrors space, so
// a triangle keeps the corner order progiso gives it and its right-hand normal then points into
// the region above the isovalue: scikit-image's winding for gradient_direction='descent'.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <exception>
#include <future>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/smoothing.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/refine/goal.hpp>
#include <progiso/core/refine/refiner.hpp>
#include <progiso/core/surface/finest_surface.hpp>
#include <progiso/core/surface/mesh.hpp>
#include <progiso/core/surface/normals.hpp>
#include <progiso/core/surface/surface_change.hpp>
#include <progiso/io/volume_io.hpp>
#include <progiso/scheduler/engine.hpp>
#include <progiso/scheduler/tbb_environment.hpp>

#include "arrays.hpp"

namespace progiso::python {
namespace {

using namespace std::chrono_literals;

// How often a waiting call takes the GIL back (signals, progress).
constexpr auto poll = 20ms;

// Thrown by a progress hook to end a one-shot run that Python interrupted.
struct interrupted : std::exception {};

// Runs `work` on a helper thread with the GIL released, waiting for it on this thread. Every
// `poll`, with the GIL: `tick()` (which may raise, as a Python callback does) and a signal check.
// On either, `stop()` asks the work to end, the work is waited for, and the Python error is
// raised. Otherwise returns what `work` returns, or throws what it threw.
template <class Work, class Tick, class Stop>
auto interruptible(Work&& work, Tick&& tick, Stop&& stop) {
  std::future<decltype(work())> done;
  {
    py::gil_scoped_release release;
    done = std::async(std::launch::async, std::forward<Work>(work));
  }
  for (;;) {
    {
      py::gil_scoped_release release;
      if (done.wait_for(poll) == std::future_status::ready) break;
    }
    try {
      tick();
    } catch (py::error_already_set&) {
      // The callback's exception (held by the exception object): stop and wait, then raise it.
      stop();
      {
        py::gil_scoped_release release;
        done.wait();
      }
      throw;
    }
    if (PyErr_CheckSignals() != 0) {
      stop();
      {
        py::gil_scoped_release release;
        done.wait();
      }
      throw py::error_already_set();
    }
  }
  return done.get();
}

std::string message(const std::exception& e) { return e.what(); }

// ---------------------------------------------------------------------------------------------
// Goals and options.

// A goal from the Python keywords: kind "full", "error", "triangles" or "deadline".
refine_goal goal_of(const std::string& kind, double value) {
  if (kind == "full") return refine_goal::full();
  if (kind == "error") {
    if (!(value >= 0.0) || !std::isfinite(value)) {
      throw py::value_error("max_error: expected a finite non-negative number, found " +
                            std::to_string(value));
    }
    return refine_goal::error(value);
  }
  if (kind == "triangles") {
    if (!(value >= 0.0) || value > 1.8e19) {
      throw py::value_error("max_triangles: expected a non-negative count, found " +
                            std::to_string(value));
    }
    return refine_goal::triangles(static_cast<std::uint64_t>(value));
  }
  if (kind == "deadline") {
    if (!(value >= 0.0)) {
      throw py::value_error("deadline: expected seconds >= 0, found " + std::to_string(value));
    }
    return refine_goal::within(std::chrono::duration<double>(value));
  }
  throw py::value_error("goal: expected full, error, triangles or deadline, found " + kind);
}

smoothing smoothing_of(const py::object& spec) {
  smoothing s;
  if (spec.is_none()) return s;
  if (py::isinstance<py::int_>(spec)) {
    s.levels = spec.cast<int>();
    return s;
  }
  if (!py::isinstance<py::dict>(spec)) {
    throw py::value_error("smooth: expected None, a number of levels or a dict, found " +
                          std::string(py::str(py::type::handle_of(spec).attr("__name__"))));
  }
  const auto d = spec.cast<py::dict>();
  for (const auto& [key, value] : d) {
    const auto k = key.cast<std::string>();
    if (k == "levels") {
      s.levels = value.cast<int>();
    } else if (k == "from_level") {
      s.from = value.cast<int>();
    } else if (k == "alpha") {
      s.alpha = value.cast<double>();
    } else if (k == "region") {
      // Given per numpy axis, (a0 lo, a1 lo, a2 lo, a0 hi, a1 hi, a2 hi): progiso's x is axis 2.
      const auto r = value.cast<std::array<std::int64_t, 6>>();
      s.region = std::array<std::int64_t, 6>{r[2], r[1], r[0], r[5], r[4], r[3]};
    } else {
      throw py::value_error("smooth: unknown key " + k +
                            " (expected levels, from_level, alpha, region)");
    }
  }
  return s;
}

unsigned threads_of(const py::object& threads) {
  if (threads.is_none()) return 0;
  const long n = threads.cast<long>();
  if (n < 1 || n > 4096) {
    throw py::value_error("threads: expected 1 to 4096, found " + std::to_string(n));
  }
  return static_cast<unsigned>(n);
}

// The volume refinement reads: the data, or its smoothed field.
std::shared_ptr<const volume> field_of(volume data, const smoothing& s) {
  auto shared = std::make_shared<const volume>(std::move(data));
  if (!s.active()) return shared;
  return std::make_shared<const volume>(smooth(shared, s));
}

// ---------------------------------------------------------------------------------------------
// Meshes out.

// The triangles of `m` that `keep` accepts, then only the vertices they use, in order.
template <class Mesh, class Keep>
void keep_triangles(Mesh& m, Keep&& keep) {
  std::size_t to = 0;
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    if (keep(m.triangles[t])) m.triangles[to++] = m.triangles[t];
  }
  if (to == m.triangles.size()) return;
  m.triangles.resize(to);
  constexpr std::uint32_t unused = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> renumber(m.vertices.size(), unused);
  for (const auto& tri : m.triangles) {
    for (const std::uint32_t v : tri) renumber[v] = 0;
  }
  std::uint32_t next = 0;
  for (std::size_t v = 0; v < m.vertices.size(); ++v) {
    if (renumber[v] == unused) continue;
    renumber[v] = next;
    m.vertices[next++] = m.vertices[v];
  }
  m.vertices.resize(next);
  for (auto& tri : m.triangles) {
    for (std::uint32_t& v : tri) v = renumber[v];
  }
}

// The mesh as (verts, faces, normals, values) arrays (see the file comment), vertices in axis
// order; `ascent` reverses the winding. Normals and values on `threads` workers.
py::tuple mesh_arrays(detail::float_mesh&& m, const volume& field, bool ascent, bool values,
                      unsigned threads) {
  const std::size_t n = m.vertices.size();
  if (m.triangles.size() > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
    throw py::value_error("the surface has more triangles than int32 faces can number");
  }
  std::vector<float> normals(3 * n);
  std::vector<float> grad(values ? n : 0);
  {
    py::gil_scoped_release release;
    scheduler::run_on_threads(threads, [&](const parallel_loop& loop, std::size_t) {
      vertex_normals_into(std::span<const std::array<float, 3>>(m.vertices), m.triangles, field,
                          normals.data(), values ? grad.data() : nullptr, loop);
    });
    if (ascent) {
      for (auto& tri : m.triangles) std::swap(tri[1], tri[2]);
    }
    for (auto& p : m.vertices) std::swap(p[0], p[2]);
  }
  // The triangles' uint32 ids as int32 (scikit-image's dtype): every id < 2^31 (checked above
  // for the count; vertices number fewer than 3 per triangle).
  const auto t = static_cast<py::ssize_t>(m.triangles.size());
  auto* tri = new std::vector<std::array<std::uint32_t, 3>>(std::move(m.triangles));
  py::capsule free_tri(
      tri, [](void* p) { delete static_cast<std::vector<std::array<std::uint32_t, 3>>*>(p); });
  py::array faces = py::array_t<std::int32_t>(
      {t, py::ssize_t{3}}, reinterpret_cast<std::int32_t*>(tri->data()), free_tri);
  auto* pos = new std::vector<std::array<float, 3>>(std::move(m.vertices));
  py::capsule free_pos(pos,
                       [](void* p) { delete static_cast<std::vector<std::array<float, 3>>*>(p); });
  py::array verts = py::array_t<float>({static_cast<py::ssize_t>(n), py::ssize_t{3}},
                                       reinterpret_cast<float*>(pos->data()), free_pos);
  py::array norms = floats_as_axes(std::move(normals));
  py::object vals = values ? py::object(own(std::move(grad), {static_cast<py::ssize_t>(n)}))
                           : py::object(py::none());
  return py::make_tuple(verts, faces, norms, vals);
}

// ---------------------------------------------------------------------------------------------
// One-shot extraction.

// marching_cubes()'s work, arguments checked by the Python side: (verts, faces, normals, values,
// info).
py::tuple extract(const py::handle& data, std::optional<double> level_arg,
                  std::array<double, 3> spacing, const py::object& threads_arg,
                  const std::string& goal_kind, double goal_value, const py::object& smooth_arg,
                  const py::object& mask_arg, bool allow_degenerate, bool ascent) {
  const sample_array a = as_samples(data, 3, "volume");
  const smoothing s = smoothing_of(smooth_arg);
  const unsigned threads = threads_of(threads_arg);
  std::shared_ptr<const volume> field;
  std::array<double, 2> range{};
  const auto clock_start = std::chrono::steady_clock::now();
  try {
    py::gil_scoped_release release;  // a floating-point volume is scanned for NaN
    std::optional<volume> samples;
    scheduler::run_on_threads(threads, [&](const parallel_loop& loop, std::size_t) {
      samples.emplace(view_volume(a, spacing, loop));
    });
    range = samples->value_range();
    field = field_of(std::move(*samples), s);
  } catch (const error& e) {
    throw py::value_error(message(e));
  }
  // scikit-image's level: the middle of the data's range when not given, else within it.
  const double level = level_arg ? *level_arg : 0.5 * (range[0] + range[1]);
  if (!(level >= range[0] && level <= range[1])) {
    throw py::value_error("Surface level must be within volume data range.");
  }
  std::optional<sample_array> mask;
  if (!mask_arg.is_none()) {
    mask = as_samples(mask_arg, 3, "mask");
    for (int q = 0; q < 3; ++q) {
      if (mask->array.shape(q) != a.array.shape(q)) {
        throw py::value_error("volume and mask must have the same shape.");
      }
    }
    if (mask->type != sample_type::u8 && mask->type != sample_type::i8) {
      throw py::value_error("mask: expected a boolean array");
    }
  }
  const refine_goal goal = goal_of(goal_kind, goal_value);
  std::atomic<bool> stop_asked{false};
  // Partner: the store in the stop callback below; relaxed suffices, the run's end is joined
  // through its future.
  const auto stopping = [&stop_asked] { return stop_asked.load(std::memory_order_relaxed); };
  const auto started = std::chrono::steady_clock::now();
  detail::float_mesh m;
  double pipeline_seconds = 0.0;
  try {
    m = interruptible(
        [&] {
          if (goal.what == refine_goal::kind::full) {
            // The finest cut by the two streaming passes, its positions written as floats.
            detail::float_mesh out;
            const finest_progress progress = [&](std::uint64_t, std::uint64_t) {
              if (stopping()) throw interrupted{};
            };
            scheduler::run_on_threads(threads, [&](const parallel_loop& loop, std::size_t parts) {
              out = detail::finest_surface_floats(*field, level, loop, parts, progress);
            });
            return out;
          }
          extract_options options;
          options.goal = goal;
          options.progress = [&](const extract_progress&) {
            if (stopping()) throw interrupted{};
          };
          extract_result r = extract_isosurface_parallel(*field, level, options, threads);
          detail::float_mesh out;
          out.triangles = std::move(r.mesh.triangles);
          out.vertices.resize(r.mesh.vertices.size());
          for (std::size_t v = 0; v < out.vertices.size(); ++v) {
            const vec3& q = r.mesh.vertices[v];
            out.vertices[v] = {static_cast<float>(q[0]), static_cast<float>(q[1]),
                               static_cast<float>(q[2])};
          }
          return out;
        },
        [] {}, [&] { stop_asked.store(true, std::memory_order_relaxed); });
  } catch (const error& e) {
    throw py::value_error(message(e));
  }
  const double extract_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  pipeline_seconds = extract_seconds;
  {
    py::gil_scoped_release release;
    if (mask) {
      // scikit-image marches the cube whose upper corner the mask marks: (i, j, k) → cube of
      // corners i − 1 … i along each axis. Each of progiso's triangles lies in one unit cube
      // of the data (its tetrahedron's), found by its centroid.
      const auto* flags = static_cast<const std::uint8_t*>(mask->array.data());
      const index3 d = field->dims();
      const auto& sp = field->spacing();
      const auto& o = field->origin();
      const double fine = s.active() ? static_cast<double>(std::int64_t{1} << s.levels) : 1.0;
      keep_triangles(m, [&](const std::array<std::uint32_t, 3>& tri) {
        std::array<std::int64_t, 3> upper{};
        for (std::size_t q = 0; q < 3; ++q) {
          const double c = (static_cast<double>(m.vertices[tri[0]][q]) +
                            static_cast<double>(m.vertices[tri[1]][q]) +
                            static_cast<double>(m.vertices[tri[2]][q])) /
                           3.0;
          // In the data's index units (a smoothed field's finer grid divided back).
          const double i = (c - o[q]) / sp[q] / fine;
          const auto cell = static_cast<std::int64_t>(std::floor(i));
          const std::int64_t n = (d[q] - 1) / static_cast<std::int64_t>(fine) + 1;
          upper[q] = std::clamp<std::int64_t>(cell + 1, 1, n - 1);
        }
        const std::int64_t nx = a.array.shape(2), ny = a.array.shape(1);
        return flags[static_cast<std::size_t>(upper[0] + nx * (upper[1] + ny * upper[2]))] != 0;
      });
    }
    if (!allow_degenerate) {
      keep_triangles(m, [&](const std::array<std::uint32_t, 3>& tri) {
        const auto& p = m.vertices[tri[0]];
        const auto& q = m.vertices[tri[1]];
        const auto& r = m.vertices[tri[2]];
        return tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2] && p != q && q != r &&
               p != r;
      });
    }
  }
  py::dict info;
  info["seconds"] = extract_seconds;
  info["pipeline_seconds"] = pipeline_seconds;
  info["triangles"] = m.triangles.size();
  info["copied"] = a.copied;
  info["threads"] = threads == 0 ? scheduler::default_concurrency() : static_cast<int>(threads);
  const auto since = [](std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
  };
  info["check_seconds"] = std::chrono::duration<double>(started - clock_start).count();
  const auto arrays_start = std::chrono::steady_clock::now();
  py::tuple arrays = mesh_arrays(std::move(m), *field, ascent, true, threads);
  info["normals_seconds"] = since(arrays_start);
  info["total_seconds"] = since(clock_start);
  return py::make_tuple(arrays[0], arrays[1], arrays[2], arrays[3], info);
}

// ---------------------------------------------------------------------------------------------
// The engine.

// A cut's place (surface_snapshot::mark()), held by Python objects between calls.
struct mark_holder {
  cut_mark mark;
};

class py_engine {
 public:
  py_engine(const py::handle& data, double level, std::array<double, 3> spacing,
            const py::object& threads, const py::object& smooth_arg, bool uniform_cuts,
            py::object progress)
      : samples_(as_samples(data, 3, "volume")), progress_cb_(std::move(progress)) {
    engine_options options;
    options.threads = threads_of(threads);
    options.uniform_cuts = uniform_cuts;
    options.progress = [this](const engine_progress& p) {
      std::lock_guard lock(progress_mutex_);
      latest_ = p;
      // Partner: the exchange in deliver_progress(); the mutex orders the figures themselves.
      fresh_.store(true, std::memory_order_release);
    };
    if (!progress_cb_.is_none()) options.progress_interval = 1024;
    const smoothing s = smoothing_of(smooth_arg);
    try {
      py::gil_scoped_release release;
      std::optional<volume> borrowed;
      scheduler::run_on_threads(options.threads, [&](const parallel_loop& loop, std::size_t) {
        borrowed.emplace(view_volume(samples_, spacing, loop));
      });
      field_ = field_of(std::move(*borrowed), s);
      engine_ = std::make_unique<engine>(field_, level, std::move(options));
    } catch (const error& e) {
      throw py::value_error(message(e));
    }
  }

  // The engine stops its workers before the array reference goes (members in reverse order).
  ~py_engine() {
    py::gil_scoped_release release;
    engine_.reset();
  }
  py_engine(const py_engine&) = delete;
  py_engine& operator=(const py_engine&) = delete;

  void start(const std::string& kind, double value) {
    const refine_goal goal = goal_of(kind, value);
    py::gil_scoped_release release;
    engine_->start(goal);
  }

  bool refine(const std::string& kind, double value) {
    const refine_goal goal = goal_of(kind, value);
    bool reached = false;
    try {
      reached = interruptible([&] { return engine_->refine(goal); }, [&] { deliver_progress(); },
                              [&] { engine_->cancel(); });
    } catch (const error& e) {
      throw py::value_error(message(e));
    }
    deliver_progress();  // the run's last figures
    return reached;
  }

  void wait() {
    try {
      interruptible(
          [&] {
            engine_->wait();
            return 0;
          },
          [&] { deliver_progress(); }, [&] { engine_->cancel(); });
    } catch (const error& e) {
      throw py::value_error(message(e));
    }
    deliver_progress();
  }

  void cancel() {
    py::gil_scoped_release release;
    engine_->cancel();
  }

  void set_isovalue(double w) {
    try {
      py::gil_scoped_release release;
      engine_->set_isovalue(w);
    } catch (const error& e) {
      throw py::value_error(message(e));
    }
  }

  // (vertices, faces, normals, info, mark) of the current cut.
  py::tuple snapshot(bool normals) {
    render_buffers b;
    py::dict info;
    mark_holder mark;
    double isovalue = 0.0;
    std::uint64_t generation = 0, splits = 0;
    std::int32_t stride = 0;
    {
      py::gil_scoped_release release;
      const surface_snapshot s = engine_->snapshot();
      s.mesh_into(b, normals ? vertex_normals::gradient : vertex_normals::none);
      mark.mark = s.mark();
      isovalue = s.isovalue();
      generation = s.generation();
      splits = s.split_count();
      stride = s.uniform_stride();
    }
    info["isovalue"] = isovalue;
    info["generation"] = generation;
    info["splits"] = splits;
    info["uniform_stride"] = stride;
    const auto t = static_cast<py::ssize_t>(b.indices.size() / 3);
    py::array faces = own(std::move(b.indices), {t, 3});
    faces = faces.attr("view")("int32");
    py::array verts = floats_as_axes(std::move(b.positions));
    py::object norms =
        normals ? py::object(floats_as_axes(std::move(b.normals))) : py::object(py::none());
    return py::make_tuple(verts, faces, norms, info, mark);
  }

  // (rebuilt, gone, added, hidden, positions, normals, mark) since `earlier`.
  py::tuple changes(const std::optional<mark_holder>& earlier, bool normals) {
    surface_change c;
    mark_holder now;
    {
      py::gil_scoped_release release;
      const surface_snapshot s = engine_->snapshot();
      s.change_since(earlier ? earlier->mark : cut_mark{}, c,
                     normals ? vertex_normals::gradient : vertex_normals::none);
      now.mark = s.mark();
    }
    const bool rebuilt = c.rebuilt;
    py::array gone = own(std::move(c.gone), {static_cast<py::ssize_t>(c.gone.size())});
    py::array added = own(std::move(c.added), {static_cast<py::ssize_t>(c.added.size())});
    py::array hidden = own(std::move(c.hidden), {static_cast<py::ssize_t>(c.hidden.size())});
    py::array positions = floats_as_axes(std::move(c.positions), true);
    py::object norms =
        normals ? py::object(floats_as_axes(std::move(c.normals), true)) : py::object(py::none());
    return py::make_tuple(rebuilt, gone, added, hidden, positions, norms, now);
  }

  mark_holder mark() const {
    const surface_snapshot s = engine_->snapshot();
    return {s.mark()};
  }

  py::dict statistics() const {
    const engine_statistics s = engine_->statistics();
    py::dict d;
    d["splits"] = s.refine.splits;
    d["triangles"] = s.refine.triangles;
    d["published"] = s.published;
    d["generation"] = s.generation;
    d["runs"] = s.runs;
    d["cancelled_runs"] = s.cancelled_runs;
    d["roots"] = s.roots;
    d["root_bytes"] = s.root_bytes;
    d["retired_bytes"] = s.retired_bytes;
    d["range_build_seconds"] = engine_->range_build_seconds();
    return d;
  }

  [[nodiscard]] double isovalue() const { return engine_->isovalue(); }
  [[nodiscard]] bool running() const { return engine_->running(); }
  [[nodiscard]] bool done() const { return engine_->done(); }
  [[nodiscard]] unsigned threads() const { return engine_->threads(); }
  [[nodiscard]] bool copied() const { return samples_.copied; }
  [[nodiscard]] const py::array& array() const { return samples_.array; }

  // The latest progress to the Python callback, on this thread (it holds the GIL).
  void deliver_progress() {
    if (progress_cb_.is_none()) return;
    // Partner: the release store in the engine's progress hook.
    if (!fresh_.exchange(false, std::memory_order_acquire)) return;
    engine_progress p;
    {
      std::lock_guard lock(progress_mutex_);
      p = latest_;
    }
    py::dict d;
    d["splits"] = p.splits;
    d["triangles"] = p.triangles;
    d["next_error"] = p.next_error;
    d["depth"] = p.depth;
    progress_cb_(d);
  }

 private:
  sample_array samples_;  // first: outlives the engine that reads it
  py::object progress_cb_;
  std::shared_ptr<const volume> field_;
  std::mutex progress_mutex_;
  engine_progress latest_;
  std::atomic<bool> fresh_{false};
  std::unique_ptr<engine> engine_;
};

// ---------------------------------------------------------------------------------------------
// Readers.

// (array, spacing, origin, world 4×4 or None), all in axis order.
py::tuple read_file(const std::string& path, const py::object& raw, const py::object& spacing_arg,
                    const py::object& series, const py::object& volume_index,
                    const py::object& level) {
  std::optional<raw_layout> layout;
  if (!raw.is_none()) {
    const auto d = raw.cast<py::dict>();
    if (!d.contains("shape") || !d.contains("dtype")) {
      throw py::value_error("raw: expected a dict with shape (axis order) and dtype");
    }
    const auto shape = d["shape"].cast<std::array<std::int64_t, 3>>();
    const auto type_name = d["dtype"].cast<std::string>();
    const auto type = parse_sample_type(type_name);
    if (!type) {
      throw py::value_error("raw dtype: expected u8 i8 u16 i16 u32 i32 f32 f64, found " +
                            type_name);
    }
    layout = raw_layout{{shape[2], shape[1], shape[0]},
                        *type,
                        d.contains("big_endian") && d["big_endian"].cast<bool>()};
  }
  std::optional<std::array<double, 3>> spacing;
  if (!spacing_arg.is_none()) {
    const auto s = spacing_arg.cast<std::array<double, 3>>();
    spacing = std::array<double, 3>{s[2], s[1], s[0]};
  }
  volume_choice choice;
  if (!series.is_none()) choice.series = py::str(series).cast<std::string>();
  if (!volume_index.is_none()) choice.volume = volume_index.cast<std::int64_t>();
  if (!level.is_none()) choice.level = level.cast<std::int64_t>();
  std::shared_ptr<const volume> vol;
  std::optional<index_to_world> world;
  try {
    py::gil_scoped_release release;
    volume_source source(path, layout, choice);
    world = source.world();
    vol = std::make_shared<const volume>(source.read(spacing));
  } catch (const error& e) {
    PyErr_SetString(PyExc_OSError, e.what());
    throw py::error_already_set();
  }
  const index3& d = vol->dims();
  const char* dtype = "uint8";
  switch (vol->type()) {
    case sample_type::u8:
      dtype = "uint8";
      break;
    case sample_type::i8:
      dtype = "int8";
      break;
    case sample_type::u16:
      dtype = "uint16";
      break;
    case sample_type::i16:
      dtype = "int16";
      break;
    case sample_type::u32:
      dtype = "uint32";
      break;
    case sample_type::i32:
      dtype = "int32";
      break;
    case sample_type::f32:
      dtype = "float32";
      break;
    case sample_type::f64:
      dtype = "float64";
      break;
  }
  // The array owns a reference to the volume, whose samples it shows in place.
  auto* held = new std::shared_ptr<const volume>(vol);
  py::capsule free_it(held, [](void* p) { delete static_cast<std::shared_ptr<const volume>*>(p); });
  // The samples are the volume's own heap vector, made for this array: written only through it.
  auto* bytes =
      const_cast<std::byte*>(vol->bytes());  // NOLINT(cppcoreguidelines-pro-type-const-cast)
  py::array array(py::dtype(dtype), std::vector<py::ssize_t>{d[2], d[1], d[0]}, bytes, free_it);
  const auto& sp = vol->spacing();
  const auto& o = vol->origin();
  py::tuple spacing_axes = py::make_tuple(sp[2], sp[1], sp[0]);
  py::tuple origin_axes = py::make_tuple(o[2], o[1], o[0]);
  py::object world_axes = py::none();
  if (world) {
    // Columns for axis 0, 1, 2 (progiso's z, y, x index), then the translation.
    std::vector<double> m(16, 0.0);
    for (std::size_t r = 0; r < 3; ++r) {
      m[4 * r + 0] = world->m[r][2];
      m[4 * r + 1] = world->m[r][1];
      m[4 * r + 2] = world->m[r][0];
      m[4 * r + 3] = world->m[r][3];
    }
    m[15] = 1.0;
    world_axes = own(std::move(m), {4, 4});
  }
  return py::make_tuple(array, spacing_axes, origin_axes, world_axes);
}

}  // namespace
}  // namespace progiso::python

PYBIND11_MODULE(_progiso, m) {
  namespace py = pybind11;
  using namespace progiso::python;
  m.doc() = "progiso's extension module: use the progiso package instead.";
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const progiso::error& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });
  m.def("_extract", &extract, py::arg("volume"), py::arg("level"), py::arg("spacing"),
        py::arg("threads"), py::arg("goal"), py::arg("goal_value"), py::arg("smooth"),
        py::arg("mask"), py::arg("allow_degenerate"), py::arg("ascent"));
  m.def("_read_volume", &read_file, py::arg("path"), py::arg("raw"), py::arg("spacing"),
        py::arg("series"), py::arg("volume"), py::arg("level"));
  m.def("_default_threads", [] { return progiso::scheduler::default_concurrency(); });
  m.def("_view_address", [](const py::handle& data) {
    const sample_array a = as_samples(data, 3, "volume");
    return py::make_tuple(reinterpret_cast<std::uintptr_t>(a.array.data()), a.copied);
  });
  py::class_<mark_holder>(m, "_Mark")
      .def_property_readonly("generation", [](const mark_holder& h) { return h.mark.generation; })
      .def_property_readonly("records", [](const mark_holder& h) { return h.mark.records; })
      .def_property_readonly("root", [](const mark_holder& h) { return h.mark.root; })
      .def("__eq__", [](const mark_holder& a, const mark_holder& b) {
        return a.mark.owner == b.mark.owner && a.mark.generation == b.mark.generation &&
               a.mark.records == b.mark.records && a.mark.root == b.mark.root;
      });
  py::class_<py_engine>(m, "_Engine")
      .def(py::init<const py::handle&, double, std::array<double, 3>, const py::object&,
                    const py::object&, bool, py::object>(),
           py::arg("volume"), py::arg("level"), py::arg("spacing"), py::arg("threads"),
           py::arg("smooth"), py::arg("uniform_cuts"), py::arg("progress"))
      .def("start", &py_engine::start)
      .def("refine", &py_engine::refine)
      .def("wait", &py_engine::wait)
      .def("cancel", &py_engine::cancel)
      .def("set_isovalue", &py_engine::set_isovalue)
      .def("snapshot", &py_engine::snapshot, py::arg("normals"))
      .def("changes", &py_engine::changes, py::arg("since"), py::arg("normals"))
      .def("mark", &py_engine::mark, py::call_guard<py::gil_scoped_release>())
      .def("statistics", &py_engine::statistics)
      .def("deliver_progress", &py_engine::deliver_progress)
      .def_property_readonly("isovalue", &py_engine::isovalue)
      .def_property_readonly("running", &py_engine::running)
      .def_property_readonly("done", &py_engine::done)
      .def_property_readonly("threads", &py_engine::threads)
      .def_property_readonly("copied", &py_engine::copied)
      .def_property_readonly("array", &py_engine::array);
}
