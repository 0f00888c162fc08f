// progiso — command-line front end: progressive isosurfaces of volumes, isocontours of images.
//
//   progiso extract INPUT -o OUT.ply|OUT.obj|OUT.stl|OUT.glb|OUT.vtp --iso W
//           [--dims NX,NY,NZ --type u8|i8|u16|i16|u32|i32|f32|f64 [--big-endian]]
//           [--spacing SX,SY,SZ | --world] [--series N|UID] [--volume K]
//           [--full | --error E | --max-triangles K | --time-ms T [--by-priority]]
//           [--stats-json FILE] [--threads N] [--normals]
//           [--smooth S] [--smooth-from K] [--smooth-region X0,Y0,Z0,X1,Y1,Z1] [--alpha A]
//   progiso extract --demo -o OUT.ply [--iso W] [--threads N] [--normals]
//   progiso cut IN.pgh -o OUT.ply|OUT.obj|OUT.stl|OUT.glb|OUT.vtp
//           [--error E | --max-triangles K | --region X0,Y0,Z0,X1,Y1,Z1] [--records N]
//   progiso contour INPUT.pgm|INPUT.png -o OUT.obj|OUT.svg --iso W[,W2,...]
//           [--full | --error E | --max-segments K | --time-ms T] [--frames DIR]
//           [--stats-json FILE]
//           [--smooth S] [--smooth-from K] [--smooth-region X0,Y0,X1,Y1] [--alpha A]
//
// The full text of `progiso --help` is cli_options.cpp's usage_text.
// Exit status: 0 on success, 2 on bad input or usage (one line on stderr, no output file).
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <optional>
#include <span>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/field/smoothing.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>
#include <progiso/core/refine/refiner.hpp>
#include <progiso/core/surface/finest_surface.hpp>
#include <progiso/io/detail/file_output.hpp>
#include <progiso/io/detail/writers.hpp>
#include <progiso/io/hierarchy_io.hpp>
#include <progiso/io/mesh_io.hpp>
#include <progiso/io/volume_io.hpp>
#include <progiso/scheduler/engine.hpp>
#include <progiso/scheduler/hierarchy_export.hpp>
#include <progiso/scheduler/tbb_environment.hpp>

#include "cli_common.hpp"
#include "cli_options.hpp"
#include "cli_outputs.hpp"
#include "mpi_extract.hpp"

int run_contour(const std::vector<std::string>& args);
int run_view(const std::vector<std::string>& args);

namespace {

using progiso::error;
using namespace progiso::cli;
namespace fs = std::filesystem;
using arguments = extract_arguments;

/// Every argument after the program name.
std::vector<std::string> argument_list(int argc, char** argv) {
  std::vector<std::string> args;
  for (int i = 1; i < argc; ++i) args.emplace_back(argv[i]);
  return args;
}

/// The finest surface written piece by piece (run_finest_in_pieces()): its counts, since the
/// result then holds no mesh.
struct pieces_written {
  std::uint64_t triangles = 0, vertices = 0;
  /// A chunked level read in windows of planes (plane_window): the most sample bytes held at
  /// once; 0 when the volume was read whole or mapped.
  std::uint64_t window_peak_bytes = 0;
};

std::string stats_json(const arguments& a, const std::string& input, double iso,
                       const progiso::volume& data, const progiso::volume& vol,
                       const progiso::extract_result& r,
                       const std::optional<pieces_written>& pieces = std::nullopt,
                       std::size_t levels_read = 0) {
  std::ostringstream o;
  o << "{\n";
  o << "  \"input\": \"" << json_escape(input) << "\",\n";
  if (a.volume) o << "  \"volume\": " << *a.volume << ",\n";
  if (a.level) o << "  \"level\": " << *a.level << ",\n";
  // Coarse first (run_coarse_first()): the pyramid levels read by the deadline, coarsest first.
  if (levels_read > 0)
    o << "  \"coarse_first\": true,\n  \"levels_read\": " << levels_read << ",\n";
  o << "  \"dims\": [" << vol.dims()[0] << ", " << vol.dims()[1] << ", " << vol.dims()[2] << "],\n";
  o << "  \"isovalue\": " << json_number(iso) << ",\n";
  o << "  \"mode\": \"" << goal_name(a.options.goal, "triangles") << "\",\n";
  const auto available = static_cast<unsigned>(progiso::scheduler::default_concurrency());
  o << "  \"threads\": " << (a.threads == 0 ? available : std::min(a.threads, available)) << ",\n";
  // "finest": the full surface came from two passes over the samples, not from refinement;
  // "uniform": a deadline's uniform cut, from the same passes over every stride-th sample.
  o << "  \"path\": \""
    << (r.finest_direct ? "finest" : (r.ladder_stride > 0 ? "uniform" : "refinement")) << "\",\n";
  if (r.ladder_stride > 0) {
    o << "  \"stride\": " << r.ladder_stride << ",\n";
    o << "  \"out_of_memory\": " << (r.ladder_out_of_memory ? "true" : "false") << ",\n";
  }
  o << "  \"splits\": " << r.stats.splits << ",\n";
  o << "  \"diamonds_visited\": " << r.stats.visited << ",\n";
  o << "  \"diamonds_culled\": " << r.stats.culled << ",\n";
  o << "  \"voxels\": " << vol.voxel_count() << ",\n";
  // "streamed": written slab by slab through scratch files, never whole in memory.
  o << "  \"streamed\": " << (pieces ? "true" : "false") << ",\n";
  o << "  \"triangles\": " << (pieces ? pieces->triangles : r.mesh.triangles.size()) << ",\n";
  o << "  \"vertices\": " << (pieces ? pieces->vertices : r.mesh.vertices.size()) << ",\n";
  o << "  \"time_to_first_surface_ms\": " << json_number(r.first_surface_seconds * 1e3) << ",\n";
  o << "  \"range_build_ms\": " << json_number(r.range_build_seconds * 1e3) << ",\n";
  o << "  \"refine_ms\": " << json_number(r.refine_seconds * 1e3) << ",\n";
  o << "  \"extract_ms\": " << json_number(r.extract_seconds * 1e3) << ",\n";
  o << "  \"total_ms\": " << json_number(r.total_seconds * 1e3) << ",\n";
  o << "  \"pipeline_ms\": " << json_number(r.pipeline_seconds * 1e3) << ",\n";
  o << "  \"normals\": " << (a.options.normals ? "true" : "false") << ",\n";
  o << "  \"normals_ms\": " << json_number(r.normals_seconds * 1e3) << ",\n";
  o << "  \"range_data_bytes\": " << r.range_bytes << ",\n";
  o << "  \"volume_bytes\": " << data.byte_size() << ",\n";
  if (pieces && pieces->window_peak_bytes > 0) {
    o << "  \"windowed\": true,\n  \"window_peak_bytes\": " << pieces->window_peak_bytes << ",\n";
  }
  o << "  \"smoothing\": " << smoothing_json(a.smooth, data, vol) << ",\n";
  o << "  \"isovalue_outside_data\": " << (r.isovalue_outside_data ? "true" : "false") << ",\n";
  o << "  \"cases\": {";
  for (std::size_t i = 0; i < progiso::tet_case_count; ++i) {
    o << (i ? ", " : "") << '"' << progiso::to_string(static_cast<progiso::tet_case>(i))
      << "\": " << r.stats.cases[i];
  }
  o << "},\n  \"primitives\": {";
  for (std::size_t i = 0; i < progiso::primitive_count; ++i) {
    o << (i ? ", " : "") << '"' << progiso::to_string(static_cast<progiso::primitive>(i))
      << "\": " << r.stats.primitives[i];
  }
  o << "},\n  \"configurations\": {";
  for (std::size_t i = 0; i < progiso::split_configuration_count; ++i) {
    o << (i ? ", " : "") << '"' << progiso::to_string(static_cast<progiso::split_configuration>(i))
      << "\": " << r.stats.configurations[i];
  }
  o << "}\n}\n";
  return o.str();
}

// A progress bar on stderr, shown only on a terminal and only once a run has taken a second;
// redrawn at most ten times a second, and once more when the finest surface's passes end.
class progress_bar {
 public:
  progress_bar() : tty_(isatty(STDERR_FILENO) != 0), start_(std::chrono::steady_clock::now()) {}
  void update(const progiso::extract_progress& p) {
    if (!tty_) return;
    const auto now = std::chrono::steady_clock::now();
    if (now - start_ < std::chrono::seconds(1)) return;
    const bool last = p.rows_total > 0 && p.rows_done == p.rows_total;
    if (shown_ && !last && now - drawn_ < std::chrono::milliseconds(100)) return;
    drawn_ = now;
    if (p.rows_total > 0) {  // the finest surface's two passes
      const std::uint64_t per_pass = p.rows_total / 2;
      const bool second = p.rows_done >= per_pass;
      draw(static_cast<double>(p.rows_done) / static_cast<double>(p.rows_total));
      // Rows as wide as their total, so that a shorter count leaves nothing of a longer one.
      const int digits = static_cast<int>(std::to_string(per_pass).size());
      if (p.stride > 1) {
        std::fprintf(stderr, "uniform cut, every %d%s sample: ", p.stride,
                     p.stride == 2 ? "nd" : "th");
      } else {
        std::fprintf(stderr, "finest surface: ");
      }
      std::fprintf(stderr, "pass %d of 2, %*llu of %llu rows ", second ? 2 : 1, digits,
                   static_cast<unsigned long long>(second ? p.rows_done - per_pass : p.rows_done),
                   static_cast<unsigned long long>(per_pass));
      return;
    }
    const double frac = p.max_depth > 0 && p.depth >= 0
                            ? std::min(1.0, static_cast<double>(p.depth) / p.max_depth)
                            : 1.0;
    draw(frac);
    std::fprintf(stderr, "level %d/%d  %llu splits  %llu triangles ", p.depth, p.max_depth,
                 static_cast<unsigned long long>(p.splits),
                 static_cast<unsigned long long>(p.triangles));
  }
  void finish() {
    if (shown_) std::fprintf(stderr, "\n");
  }

 private:
  // The bar, from the start of the line, filled to `frac` (0 to 1).
  void draw(double frac) {
    const int width = 30;
    const int fill = static_cast<int>(std::clamp(frac, 0.0, 1.0) * width);
    std::fprintf(stderr, "\r[%.*s%.*s] ", fill, "##############################", width - fill,
                 "..............................");
    shown_ = true;
  }

  bool tty_;
  bool shown_ = false;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point drawn_;  // the last redraw
};

/// Everything is written: the mesh and the statistics finished, then published together.
void publish_outputs(progiso::detail::atomic_output& mesh_out,
                     std::optional<progiso::detail::atomic_output>& stats_out) {
  mesh_out.finish();
  if (stats_out) stats_out->finish();
  mesh_out.publish();
  if (stats_out) stats_out->publish();
}

/// extract --hierarchy: the engine refines towards the goal while this thread writes the records
/// it publishes, a chunk every few milliseconds, so that the stream grows with the run (into a
/// FIFO or device it is readable while the run goes on; a file appears, complete, at the end).
/// The mesh written to -o is the engine's final cut (at full resolution, marching tetrahedra's
/// surface, as the direct path's).
int run_with_hierarchy(arguments& a, const std::shared_ptr<const progiso::volume>& vol, double iso,
                       progiso::detail::atomic_output& mesh_out,
                       std::optional<progiso::detail::atomic_output>& stats_out,
                       progiso::detail::atomic_output& hierarchy_out) {
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  progiso::engine_options eo;
  eo.threads = a.threads;
  eo.uniform_cuts = false;  // a stream carries split records: every split makes one
  progiso::engine e(vol, iso, eo);
  progiso::hierarchy_exporter out(e, [&hierarchy_out](std::span<const std::byte> b) {
    hierarchy_out.write(b.data(), b.size());
  });
  start_deadline(a);
  e.start(a.options.goal);
  while (e.running()) {
    {
      const progiso::surface_snapshot s = e.snapshot();
      out.write(s);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  e.wait();
  progiso::triangle_mesh mesh;
  std::uint64_t splits = 0;
  {
    const progiso::surface_snapshot s = e.snapshot();
    out.write(s);
    mesh = s.mesh();
    splits = s.split_count();
  }
  out.finish();
  if (a.options.normals) e.add_normals(mesh);
  const double seconds = std::chrono::duration<double>(clock::now() - t0).count();
  progiso::detail::write_mesh_to(mesh_out, mesh);
  if (stats_out) {
    std::ostringstream o;
    o << "{\n  \"isovalue\": " << json_number(iso) << ",\n  \"mode\": \""
      << goal_name(a.options.goal, "triangles") << "\",\n  \"path\": \"engine\",\n"
      << "  \"splits\": " << splits << ",\n  \"triangles\": " << mesh.triangles.size()
      << ",\n  \"vertices\": " << mesh.vertices.size()
      << ",\n  \"hierarchy_records\": " << out.records()
      << ",\n  \"hierarchy_bytes\": " << out.bytes()
      << ",\n  \"total_ms\": " << json_number(seconds * 1e3) << "\n}\n";
    stats_out->write(o.str());
  }
  mesh_out.finish();
  if (stats_out) stats_out->finish();
  hierarchy_out.finish();
  mesh_out.publish();
  if (stats_out) stats_out->publish();
  hierarchy_out.publish();
  std::printf(
      "progiso: %zu triangles, %zu vertices; %llu splits in %.1f ms; hierarchy stream of %llu "
      "records, %llu bytes (%.1f per triangle); wrote %s and %s\n",
      mesh.triangles.size(), mesh.vertices.size(), static_cast<unsigned long long>(splits),
      seconds * 1e3, static_cast<unsigned long long>(out.records()),
      static_cast<unsigned long long>(out.bytes()),
      mesh.triangles.empty()
          ? 0.0
          : static_cast<double>(out.bytes()) / static_cast<double>(mesh.triangles.size()),
      a.output->c_str(), a.hierarchy->c_str());
  return 0;
}

/// Whether the run writes the finest surface slab by slab (run_finest_in_pieces()): a full goal
/// into a PLY, on a grid that the finest surface's passes take in more than one slab (larger than
/// detail::finest_whole_grid_bytes points), so that neither the passes nor the output hold more
/// than a slab. Normals need their neighbours' triangles where the gradient vanishes, some in
/// another slab: with --normals the surface is held whole (its passes still slab by slab).
bool writes_in_pieces(const arguments& a, const progiso::volume& vol) {
  return a.options.goal.what == progiso::refine_goal::kind::full && !a.options.normals &&
         progiso::detail::lower_extension(*a.output) == ".ply" &&
         progiso::detail::finest_slab_planes(vol.dims()) < vol.dims()[2];
}

/// Whether a chunked input's level is read in windows of planes (run_finest_in_pieces() with a
/// plane_window) rather than whole: a full goal into a PLY, without normals (held whole) or
/// smoothing (whose field reads beyond a window).
bool writes_in_windows(const arguments& a) {
  return a.options.goal.what == progiso::refine_goal::kind::full && !a.options.normals &&
         !a.smooth.active() && progiso::detail::lower_extension(*a.output) == ".ply";
}

/// A full goal's finest surface (finest_surface(), the direct path) made slab by slab and
/// written to the PLY as it is made (ply_pieces_writer), each piece mapped to scanner
/// coordinates when asked: the same file as the whole surface's. With `window`, `data` and
/// `vol` are its field, made share by share (finest_in_windows()).
int run_finest_in_pieces(arguments& a, const std::string& input, const progiso::volume& data,
                         const progiso::volume& vol, double iso,
                         const std::optional<progiso::index_to_world>& world,
                         progiso::detail::atomic_output& mesh_out,
                         std::optional<progiso::detail::atomic_output>& stats_out,
                         progiso::plane_window* window = nullptr) {
  using clock = std::chrono::steady_clock;
  progress_bar bar;
  a.options.progress = [&bar](const progiso::extract_progress& p) { bar.update(p); };
  const progiso::finest_progress progress =
      progiso::direct_progress(a.options, progiso::hierarchy(vol.dims()).max_depth());
  progiso::detail::ply_pieces_writer ply(mesh_out, false);
  const auto t0 = clock::now();
  progiso::scheduler::run_on_threads(
      a.threads, [&](const progiso::parallel_loop& loop, std::size_t parts) {
        const auto add = [&](progiso::triangle_mesh& piece, std::uint64_t) {
          if (world) to_world(piece, data, *world);
          ply.add(piece);
        };
        if (window == nullptr) {
          progiso::detail::finest_surface_pieces(vol, iso, loop, parts, progress, add);
        } else {
          finest_in_windows(
              *window, iso, loop, parts, add,
              [&ply] {
                return std::array<std::uint64_t, 2>{ply.vertices(), ply.triangles()};
              },
              0, window->field().dims()[2]);
        }
      });
  const double made = std::chrono::duration<double>(clock::now() - t0).count();
  bar.finish();
  ply.write_into(mesh_out);
  const double seconds = std::chrono::duration<double>(clock::now() - t0).count();
  progiso::extract_result r;
  r.finest_direct = true;
  r.stats.triangles = ply.triangles();
  r.extract_seconds = made;
  r.total_seconds = seconds;
  r.pipeline_seconds = seconds;
  const auto [lo, hi] = window != nullptr ? window->range_seen() : vol.value_range();
  r.isovalue_outside_data = !(lo <= iso && iso < hi);
  if (r.isovalue_outside_data) {
    std::cerr << "progiso: isovalue " << iso << " is outside the data range [" << lo << ", " << hi
              << "): the surface is empty\n";
  }
  const pieces_written counts{ply.triangles(), ply.vertices(),
                              window != nullptr ? window->peak_bytes() : 0};
  if (stats_out) stats_out->write(stats_json(a, input, iso, data, vol, r, counts));
  publish_outputs(mesh_out, stats_out);
  std::printf(
      "progiso: %llu triangles, %llu vertices (%zu voxels); finest surface %.1f ms (two passes "
      "over the samples, slab by slab), written in %.1f ms in all; wrote %s\n",
      static_cast<unsigned long long>(counts.triangles),
      static_cast<unsigned long long>(counts.vertices), vol.voxel_count(), made * 1e3,
      seconds * 1e3, a.output->c_str());
  return 0;
}

/// A deadline on a multiscale input (an OME-Zarr pyramid) without --level: coarse first. The
/// budget starts before any read. The coarsest level is read and its finest surface made
/// whatever the deadline (a surface is always given); then each finer level, read while time is
/// left (a read stops between chunks at the deadline), gets the deadline's ladder of uniform cuts
/// for the time that remains, and replaces the surface when its cut has more triangles. Each
/// level is a field of its own (a pyramid level need not subsample the finer one: writers
/// average), so the result is one level's surface, a valid cut of that field, never a mix.
int run_coarse_first(arguments& a, progiso::volume_source& source, const std::string& input,
                     double iso, progiso::detail::atomic_output& mesh_out,
                     std::optional<progiso::detail::atomic_output>& stats_out) {
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  start_deadline(a);
  const clock::time_point deadline = a.options.goal.deadline;
  const auto passed = [deadline] { return clock::now() >= deadline; };
  const std::size_t levels = source.levels();
  std::optional<progiso::extract_result> best;
  std::shared_ptr<const progiso::volume> best_data, best_field;
  std::size_t best_level = levels - 1, read = 0;
  for (std::size_t k = levels; k-- > 0;) {
    const bool first = !best;
    if (!first && passed()) break;
    std::optional<progiso::volume> v =
        source.read_level(k, a.spacing, first ? std::function<bool()>{} : passed);
    if (!v) break;
    ++read;
    auto data = std::make_shared<const progiso::volume>(std::move(*v));
    const std::shared_ptr<const progiso::volume> field = smoothed_field(data, a.smooth, input);
    progiso::extract_options o = a.options;
    if (first) o.goal = progiso::refine_goal::full();  // always made: the coarsest surface
    o.progress = {};
    progiso::extract_result r = progiso::extract_isosurface_parallel(*field, iso, o, a.threads);
    const bool finest = first || r.ladder_stride == 1;
    if (!best || r.mesh.triangles.size() > best->mesh.triangles.size()) {
      best = std::move(r);
      best_data = data;
      best_field = field;
      best_level = k;
    }
    if (!finest) break;  // the deadline came inside this level's ladder
  }
  best->total_seconds = std::chrono::duration<double>(clock::now() - t0).count();
  a.level = static_cast<std::int64_t>(best_level);
  check_float_range(*a.output, *best_data, std::nullopt);
  progiso::detail::write_mesh_to(mesh_out, best->mesh);
  if (stats_out) {
    stats_out->write(stats_json(a, input, iso, *best_data, *best_field, *best, std::nullopt, read));
  }
  publish_outputs(mesh_out, stats_out);
  std::printf(
      "progiso: %zu triangles, %zu vertices; level %zu of %zu (coarse first: %zu levels read, "
      "coarsest first) by the deadline, in %.1f ms; wrote %s\n",
      best->mesh.triangles.size(), best->mesh.vertices.size(), best_level, levels, read,
      best->total_seconds * 1e3, a.output->c_str());
  return 0;
}

/// progiso cut: a cut of a hierarchy stream, without the volume.
int run_cut(const std::vector<std::string>& args) {
  const progiso::cli::cut_arguments a = progiso::cli::parse_cut(args);
  if (a.help) {
    std::cout << usage_text;
    return 0;
  }
  using clock = std::chrono::steady_clock;
  // Built step by step: gcc 12 at -O3 reports a string of a braced list inside a conditional
  // as maybe uninitialized (a false -Wmaybe-uninitialized).
  std::vector<named_output> outputs;
  outputs.push_back({"-o", *a.output});
  if (a.stats_json) outputs.push_back({"--stats-json", *a.stats_json});
  refuse_clashing_outputs({fs::path(*a.input)}, outputs);
  progiso::detail::atomic_output mesh_out(*a.output);
  std::optional<progiso::detail::atomic_output> stats_out;
  if (a.stats_json) stats_out.emplace(*a.stats_json);
  const auto t0 = clock::now();
  const progiso::hierarchy_stream h = progiso::read_hierarchy_stream(*a.input, a.records);
  const auto t1 = clock::now();
  progiso::hierarchy_stream::split_set split;
  double threshold = -1.0;
  using mode = progiso::cli::cut_arguments::mode;
  switch (a.how) {
    case mode::all:
      split = h.all();
      break;
    case mode::error:
      split = h.by_error(a.max_error);
      break;
    case mode::triangles:
      split = h.by_triangles(a.max_triangles, &threshold);
      break;
    case mode::region:
      split = h.in_box({a.region[0], a.region[1], a.region[2]},
                       {a.region[3], a.region[4], a.region[5]});
      break;
  }
  const progiso::triangle_mesh mesh = h.mesh(split);
  const auto t2 = clock::now();
  std::uint64_t taken = 0;
  for (std::size_t r = 1; r < split.size(); ++r) taken += split[r];
  const double read_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  const double cut_ms = std::chrono::duration<double, std::milli>(t2 - t1).count();
  progiso::detail::write_mesh_to(mesh_out, mesh);
  if (stats_out) {
    std::ostringstream o;
    o << "{\n  \"input\": \"" << json_escape(*a.input) << "\",\n  \"records\": " << h.records()
      << ",\n  \"complete\": " << (h.complete() ? "true" : "false") << ",\n  \"split\": " << taken
      << ",\n  \"error_threshold\": " << json_number(threshold)
      << ",\n  \"triangles\": " << mesh.triangles.size()
      << ",\n  \"vertices\": " << mesh.vertices.size()
      << ",\n  \"read_ms\": " << json_number(read_ms) << ",\n  \"cut_ms\": " << json_number(cut_ms)
      << "\n}\n";
    stats_out->write(o.str());
  }
  publish_outputs(mesh_out, stats_out);
  std::printf(
      "progiso: cut of %llu of %llu records (%s), %zu triangles, %zu vertices; read %.1f ms, "
      "cut %.1f ms; wrote %s\n",
      static_cast<unsigned long long>(taken), static_cast<unsigned long long>(h.records()),
      h.complete() ? "a complete stream" : "a prefix", mesh.triangles.size(), mesh.vertices.size(),
      read_ms, cut_ms, a.output->c_str());
  return 0;
}

int run(const std::vector<std::string>& args) {
  arguments a = parse_extract(args);
  if (a.help) {
    std::cout << usage_text;
    return 0;
  }
  std::optional<progiso::raw_layout> raw;
  if (a.dims) raw = progiso::raw_layout{*a.dims, *a.type, a.big_endian};

  // The input's headers are parsed once, here; its files, orientation and data come from them.
  std::optional<progiso::volume_source> source;
  if (!a.demo) {
    source.emplace(*a.input, raw, progiso::volume_choice{a.series, a.volume, a.level});
  }

  // ---- Outputs: checked against the inputs and each other, then created (as temporaries)
  // before anything is read or computed.
  {
    std::vector<fs::path> inputs;
    if (source) inputs = source->files();
    std::vector<named_output> outputs{{"-o", *a.output}};
    if (a.stats_json) outputs.push_back({"--stats-json", *a.stats_json});
    if (a.hierarchy) outputs.push_back({"--hierarchy", *a.hierarchy});
    refuse_clashing_outputs(inputs, outputs);
  }
  const std::optional<progiso::index_to_world> world =
      asked_world(a.world, source ? &*source : nullptr, a.demo ? "demo" : *a.input);
  progiso::detail::atomic_output mesh_out(*a.output);
  std::optional<progiso::detail::atomic_output> stats_out;
  if (a.stats_json) stats_out.emplace(*a.stats_json);
  std::optional<progiso::detail::atomic_output> hierarchy_out;
  if (a.hierarchy) hierarchy_out.emplace(*a.hierarchy);

  const std::string input = a.demo ? std::string("demo: Marschner-Lobb 129^3") : *a.input;
  if (source && source->levels() > 1 && !a.level && !a.hierarchy && !a.world &&
      a.options.goal.what == progiso::refine_goal::kind::deadline) {
    std::cerr << "progiso: " << input << ", " << source->levels()
              << " levels, coarse first, isovalue " << *a.iso << "\n";
    return run_coarse_first(a, *source, input, *a.iso, mesh_out, stats_out);
  }
  std::shared_ptr<const progiso::volume> data;
  double iso = 0.0;
  if (a.demo) {
    data = std::make_shared<const progiso::volume>(progiso::make_demo_volume());
    iso = a.iso.value_or(progiso::demo_isovalue);
  } else {
    // A chunked level's finest surface is made a window of planes at a time: what is held is a
    // window, not the level.
    std::optional<progiso::plane_window> window;
    if (writes_in_windows(a)) window = source->window(a.spacing);
    if (window) {
      const progiso::volume& level = window->field();
      check_float_range(*a.output, level, world);
      std::cerr << "progiso: " << input;
      if (a.volume) std::cerr << " volume " << *a.volume;
      if (a.level) std::cerr << " level " << *a.level;
      std::cerr << ", " << level.dims()[0] << "x" << level.dims()[1] << "x" << level.dims()[2]
                << " " << progiso::to_string(level.type()) << ", isovalue " << *a.iso
                << ", read in windows of " << std::min(window_planes(*window), level.dims()[2])
                << " planes\n";
      return run_finest_in_pieces(a, input, level, level, *a.iso, world, mesh_out, stats_out,
                                  &*window);
    }
    data = std::make_shared<const progiso::volume>(source->read(a.spacing));
    iso = *a.iso;
  }
  // The field refined: the data, or its smoothed field (samples computed on demand).
  const std::shared_ptr<const progiso::volume> vol = smoothed_field(data, a.smooth, input);
  check_float_range(*a.output, *data, world);
  std::cerr << "progiso: " << input;
  if (a.volume) std::cerr << " volume " << *a.volume;
  if (a.level) std::cerr << " level " << *a.level;
  std::cerr << ", " << data->dims()[0] << "x" << data->dims()[1] << "x" << data->dims()[2] << " "
            << progiso::to_string(data->type()) << ", isovalue " << iso;
  if (a.smooth.active()) {
    std::cerr << ", smoothed to " << vol->dims()[0] << "x" << vol->dims()[1] << "x"
              << vol->dims()[2] << " (S " << a.smooth.levels << ", K " << a.smooth.from
              << ", alpha " << a.smooth.alpha << (a.smooth.region ? ", in a region" : "") << ")";
  }
  std::cerr << "\n";
  if (hierarchy_out) {
    return run_with_hierarchy(a, vol, iso, mesh_out, stats_out, *hierarchy_out);
  }
  if (writes_in_pieces(a, *vol)) {
    return run_finest_in_pieces(a, input, *data, *vol, iso, world, mesh_out, stats_out);
  }
  progress_bar bar;
  a.options.progress = [&bar](const progiso::extract_progress& p) { bar.update(p); };
  start_deadline(a);  // the volume is in memory
  progiso::extract_result r = progiso::extract_isosurface_parallel(*vol, iso, a.options, a.threads);
  bar.finish();
  if (r.isovalue_outside_data) {
    const auto [lo, hi] = vol->value_range();
    std::cerr << "progiso: isovalue " << iso << " is outside the data range [" << lo << ", " << hi
              << "): the surface is empty\n";
  }
  if (world) to_world(r.mesh, *data, *world);
  progiso::detail::write_mesh_to(mesh_out, r.mesh);
  if (stats_out) stats_out->write(stats_json(a, input, iso, *data, *vol, r));
  // Everything is written: publish the outputs together.
  publish_outputs(mesh_out, stats_out);
  if (r.finest_direct) {
    std::printf(
        "progiso: %zu triangles, %zu vertices (%zu voxels); first surface %.3f ms, finest "
        "surface %.1f ms (two passes over the samples); wrote %s\n",
        r.mesh.triangles.size(), r.mesh.vertices.size(), vol->voxel_count(),
        r.first_surface_seconds * 1e3, r.extract_seconds * 1e3, a.output->c_str());
    return 0;
  }
  if (r.ladder_stride > 0) {
    const std::string cut = r.ladder_stride == 1
                                ? std::string("the finest cut")
                                : "the uniform cut of every " + std::to_string(r.ladder_stride) +
                                      (r.ladder_stride == 2 ? "nd" : "th") + " sample";
    std::printf(
        "progiso: %zu triangles, %zu vertices (%zu voxels); %s by the deadline%s, in %.1f ms "
        "(first surface %.3f ms); wrote %s\n",
        r.mesh.triangles.size(), r.mesh.vertices.size(), vol->voxel_count(), cut.c_str(),
        r.ladder_out_of_memory ? " (the next finer cut did not fit in memory)" : "",
        r.extract_seconds * 1e3, r.first_surface_seconds * 1e3, a.output->c_str());
    return 0;
  }
  std::printf(
      "progiso: %zu triangles, %zu vertices; %llu splits, %llu diamonds visited (%zu voxels); "
      "first surface %.3f ms, range data %.1f ms (%zu bytes), refinement %.1f ms, extraction "
      "%.1f ms; wrote %s\n",
      r.mesh.triangles.size(), r.mesh.vertices.size(),
      static_cast<unsigned long long>(r.stats.splits),
      static_cast<unsigned long long>(r.stats.visited), vol->voxel_count(),
      r.first_surface_seconds * 1e3, r.range_build_seconds * 1e3, r.range_bytes,
      r.refine_seconds * 1e3, r.extract_seconds * 1e3, a.output->c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  progiso::cli::remove_temporaries_on_signals();
  try {
    const std::vector<std::string> args = argument_list(argc, argv);
    const std::string first = args.empty() ? "" : args[0];
    if (first == "-h" || first == "--help") {
      std::cout << usage_text;
      return 0;
    }
    if (first == "contour") return run_contour(args);
    if (first == "cut") return run_cut(args);
    if (first == "view") return run_view(args);
    // Started by mpirun: one rank of an MPI job (mpi_extract.hpp). A build without MPI refuses a
    // job of several ranks (each would write the same output alone).
    if (progiso::cli::launched_by_mpi() &&
        (progiso::cli::have_mpi() || progiso::cli::mpi_job_size() > 1)) {
      return progiso::cli::run_mpi_extract(args);
    }
    return run(args);
  } catch (const progiso::error& e) {
    // One line whatever the message quotes (file names and arguments are the user's text).
    std::string line = e.what();
    for (char& c : line) {
      if (c == '\n' || c == '\r') c = ' ';
    }
    std::cerr << "progiso: error: " << line << "\n";
    return 2;
  } catch (const std::bad_alloc&) {
    std::cerr << "progiso: error: out of memory\n";
    return 2;
  }
}
