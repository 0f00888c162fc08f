// progiso — command-line front end: progressive isosurface extraction from volumes.
//
//   progiso extract INPUT -o OUT.ply|OUT.obj --iso W
//           [--dims NX,NY,NZ --type u8|i8|u16|i16|u32|i32|f32|f64 [--big-endian]]
//           [--spacing SX,SY,SZ] [--full | --error E | --max-triangles K | --time-ms T]
//           [--stats-json FILE] [--threads N]
//   progiso extract --demo -o OUT.ply [--iso W] [--threads N]
//
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
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <progiso/core/analytic.hpp>
#include <progiso/core/error.hpp>
#include <progiso/core/mesh_io.hpp>
#include <progiso/core/refiner.hpp>
#include <progiso/core/volume_io.hpp>
#include <progiso/scheduler/engine.hpp>
#include <progiso/scheduler/tbb_environment.hpp>

#include "cli_common.hpp"

int run_contour(int argc, char** argv);

namespace {

using progiso::error;
using namespace progiso::cli;

constexpr const char* usage_text =
    "usage:\n"
    "  progiso extract INPUT -o OUT.ply|OUT.obj --iso W\n"
    "          [--dims NX,NY,NZ --type u8|i8|u16|i16|u32|i32|f32|f64 [--big-endian]]\n"
    "          [--spacing SX,SY,SZ] [--full | --error E | --max-triangles K | --time-ms T]\n"
    "          [--stats-json FILE] [--threads N]\n"
    "  progiso extract --demo -o OUT.ply [--iso W] [--threads N]\n"
    "  progiso contour INPUT.pgm|INPUT.png -o OUT.obj|OUT.svg --iso W[,W2,...]\n"
    "          [--full | --error E | --max-segments K | --time-ms T] [--frames DIR]\n"
    "          [--stats-json FILE]\n"
    "\n"
    "INPUT is a .nrrd/.nhdr file, or a headerless raw file described by --dims and --type\n"
    "(x fastest, little-endian unless --big-endian). --demo uses a built-in 129^3\n"
    "Marschner-Lobb volume (isovalue 0.5 unless --iso is given).\n"
    "Modes: --full (default) refines everywhere the surface can be; --error E stops when\n"
    "every remaining split error is <= E; --max-triangles K keeps at most K triangles;\n"
    "--time-ms T refines for T milliseconds and returns the surface published by then.\n"
    "--threads N runs the concurrent engine on N threads (default: all cores); --full gives\n"
    "the same file for every N.\n"
    "contour: INPUT is a binary PGM (8/16 bit) or a grayscale PNG; several isovalues are\n"
    "comma-separated; OBJ gets 'v x y 0' and 'l ...' polylines, SVG draws them over the image;\n"
    "--frames DIR writes one SVG per refinement stage.\n";

struct arguments {
  std::optional<std::string> input;
  bool demo = false;
  std::optional<std::string> output;
  std::optional<double> iso;
  std::optional<progiso::index3> dims;
  std::optional<progiso::sample_type> type;
  bool big_endian = false;
  std::optional<std::array<double, 3>> spacing;
  progiso::extract_options options;
  int modes = 0;
  std::optional<std::string> stats_json;
  unsigned threads = 0;  // 0: all cores
};

arguments parse(int argc, char** argv) {
  arguments a;
  if (argc < 2) {
    throw error("missing command (expected 'extract' or 'contour'; see progiso --help)");
  }
  const std::string command = argv[1];
  if (command != "extract") {
    throw error("unknown command '" + command + "' (expected 'extract' or 'contour')");
  }
  const auto value = [&](int& i, const std::string& flag) {
    return next_value(argc, argv, i, flag);
  };
  for (int i = 2; i < argc; ++i) {
    const std::string f = argv[i];
    if (f == "-o" || f == "--output") {
      a.output = value(i, f);
    } else if (f == "--iso") {
      a.iso = parse_number(f, value(i, f));
    } else if (f == "--demo") {
      a.demo = true;
    } else if (f == "--dims") {
      const auto parts = split_commas(f, value(i, f));
      progiso::index3 d{};
      for (std::size_t q = 0; q < 3; ++q) {
        const double v = parse_number(f, parts[q]);
        if (v != std::floor(v) || v < 1 || v > 1e9) {
          throw error("--dims: expected positive integers, found '" + parts[q] + "'");
        }
        d[q] = static_cast<std::int64_t>(v);
      }
      a.dims = d;
    } else if (f == "--type") {
      const std::string t = value(i, f);
      a.type = progiso::parse_sample_type(t);
      if (!a.type) {
        throw error("--type: expected one of u8 i8 u16 i16 u32 i32 f32 f64, found '" + t + "'");
      }
    } else if (f == "--big-endian") {
      a.big_endian = true;
    } else if (f == "--spacing") {
      const auto parts = split_commas(f, value(i, f));
      std::array<double, 3> s{};
      for (std::size_t q = 0; q < 3; ++q) {
        s[q] = parse_number(f, parts[q]);
        if (s[q] <= 0) throw error("--spacing: expected positive values, found '" + parts[q] + "'");
      }
      a.spacing = s;
    } else if (f == "--full") {
      a.options.mode = progiso::extract_mode::full;
      ++a.modes;
    } else if (f == "--error") {
      a.options.mode = progiso::extract_mode::error;
      a.options.max_error = parse_number(f, value(i, f));
      if (a.options.max_error < 0) throw error("--error: expected a non-negative number");
      ++a.modes;
    } else if (f == "--max-triangles") {
      a.options.mode = progiso::extract_mode::triangles;
      const std::string t = value(i, f);
      const double k = parse_number(f, t);
      if (k < 0 || k != std::floor(k)) {
        throw error("--max-triangles: expected a non-negative integer, found '" + t + "'");
      }
      a.options.max_triangles = static_cast<std::uint64_t>(k);
      ++a.modes;
    } else if (f == "--time-ms") {
      a.options.mode = progiso::extract_mode::time;
      const double ms = parse_number(f, value(i, f));
      if (ms < 0) throw error("--time-ms: expected a non-negative number of milliseconds");
      a.options.time_budget = std::chrono::duration<double>(ms / 1000.0);
      ++a.modes;
    } else if (f == "--stats-json") {
      a.stats_json = value(i, f);
    } else if (f == "--threads") {
      const std::string t = value(i, f);
      const double n = parse_number(f, t);
      if (n < 1 || n > 4096 || n != std::floor(n)) {
        throw error("--threads: expected an integer from 1 to 4096, found '" + t + "'");
      }
      a.threads = static_cast<unsigned>(n);
    } else if (f == "-h" || f == "--help") {
      std::cout << usage_text;
      std::exit(0);
    } else if (!f.empty() && f[0] == '-') {
      throw error("unknown option '" + f + "'");
    } else if (!a.input) {
      a.input = f;
    } else {
      throw error("unexpected argument '" + f + "' (only one INPUT is allowed)");
    }
  }
  if (a.modes > 1) {
    throw error("choose at most one of --full, --error, --max-triangles, --time-ms");
  }
  if (a.demo && a.input) throw error("--demo takes no INPUT");
  if (!a.demo && !a.input) throw error("missing INPUT (or --demo)");
  if (!a.output) throw error("missing -o OUT.ply|OUT.obj");
  if (!a.demo && !a.iso) throw error("missing --iso W");
  if (a.dims.has_value() != a.type.has_value()) {
    throw error("--dims and --type must be given together for a raw volume");
  }
  if (a.big_endian && !a.dims) throw error("--big-endian applies to raw input with --dims/--type");
  {
    const std::string ext = progiso::detail::lower_extension(*a.output);
    if (ext != ".ply" && ext != ".obj") {
      throw error(*a.output + ": unknown mesh format (expected a .ply or .obj file name)");
    }
  }
  return a;
}

std::string stats_json(const arguments& a, const std::string& input, double iso,
                       const progiso::volume& vol, const progiso::extract_result& r) {
  const char* mode_names[] = {"full", "error", "triangles", "time"};
  std::ostringstream o;
  o << "{\n";
  o << "  \"input\": \"" << json_escape(input) << "\",\n";
  o << "  \"dims\": [" << vol.dims()[0] << ", " << vol.dims()[1] << ", " << vol.dims()[2] << "],\n";
  o << "  \"isovalue\": " << json_number(iso) << ",\n";
  o << "  \"mode\": \"" << mode_names[static_cast<int>(a.options.mode)] << "\",\n";
  const auto available = static_cast<unsigned>(progiso::scheduler::default_concurrency());
  o << "  \"threads\": " << (a.threads == 0 ? available : std::min(a.threads, available)) << ",\n";
  o << "  \"splits\": " << r.stats.splits << ",\n";
  o << "  \"diamonds_visited\": " << r.stats.visited << ",\n";
  o << "  \"diamonds_culled\": " << r.stats.culled << ",\n";
  o << "  \"voxels\": " << vol.voxel_count() << ",\n";
  o << "  \"triangles\": " << r.mesh.triangles.size() << ",\n";
  o << "  \"vertices\": " << r.mesh.vertices.size() << ",\n";
  o << "  \"time_to_first_surface_ms\": " << json_number(r.first_surface_seconds * 1e3) << ",\n";
  o << "  \"range_build_ms\": " << json_number(r.range_build_seconds * 1e3) << ",\n";
  o << "  \"refine_ms\": " << json_number(r.refine_seconds * 1e3) << ",\n";
  o << "  \"extract_ms\": " << json_number(r.extract_seconds * 1e3) << ",\n";
  o << "  \"total_ms\": " << json_number(r.total_seconds * 1e3) << ",\n";
  o << "  \"range_data_bytes\": " << r.range_bytes << ",\n";
  o << "  \"volume_bytes\": " << vol.byte_size() << ",\n";
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

// A progress bar on stderr, shown only on a terminal and only once a run has taken a second.
class progress_bar {
 public:
  progress_bar() : tty_(isatty(STDERR_FILENO) != 0), start_(std::chrono::steady_clock::now()) {}
  void update(const progiso::extract_progress& p) {
    if (!tty_) return;
    if (std::chrono::steady_clock::now() - start_ < std::chrono::seconds(1)) return;
    const double frac = p.max_depth > 0 && p.depth >= 0
                            ? std::min(1.0, static_cast<double>(p.depth) / p.max_depth)
                            : 1.0;
    const int width = 30;
    const int fill = static_cast<int>(frac * width);
    std::fprintf(stderr, "\r[%.*s%.*s] level %d/%d  %llu splits  %llu triangles ", fill,
                 "##############################", width - fill, "..............................",
                 p.depth, p.max_depth, static_cast<unsigned long long>(p.splits),
                 static_cast<unsigned long long>(p.triangles));
    shown_ = true;
  }
  void finish() {
    if (shown_) std::fprintf(stderr, "\n");
  }

 private:
  bool tty_;
  bool shown_ = false;
  std::chrono::steady_clock::time_point start_;
};

int run(int argc, char** argv) {
  arguments a = parse(argc, argv);
  if (a.stats_json) {
    const auto parent = std::filesystem::path(*a.stats_json).parent_path();
    if (!parent.empty() && !std::filesystem::is_directory(parent)) {
      throw error(*a.stats_json + ": directory does not exist");
    }
  }
  const std::string input = a.demo ? std::string("demo: Marschner-Lobb 129^3") : *a.input;
  std::optional<progiso::volume> vol;
  double iso = 0.0;
  if (a.demo) {
    vol.emplace(progiso::make_demo_volume());
    iso = a.iso.value_or(progiso::demo_isovalue);
  } else {
    std::optional<progiso::raw_layout> raw;
    if (a.dims) raw = progiso::raw_layout{*a.dims, *a.type, a.big_endian};
    vol.emplace(progiso::read_volume(*a.input, raw, a.spacing));
    iso = *a.iso;
  }
  std::cerr << "progiso: " << input << ", " << vol->dims()[0] << "x" << vol->dims()[1] << "x"
            << vol->dims()[2] << " " << progiso::to_string(vol->type()) << ", isovalue " << iso
            << "\n";
  progress_bar bar;
  a.options.progress = [&bar](const progiso::extract_progress& p) { bar.update(p); };
  const progiso::extract_result r =
      progiso::extract_isosurface_parallel(*vol, iso, a.options, a.threads);
  bar.finish();
  if (r.isovalue_outside_data) {
    const auto [lo, hi] = vol->value_range();
    std::cerr << "progiso: isovalue " << iso << " is outside the data range [" << lo << ", " << hi
              << "): the surface is empty\n";
  }
  progiso::write_mesh(*a.output, r.mesh);
  if (a.stats_json) write_text_atomically(*a.stats_json, stats_json(a, input, iso, *vol, r));
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
  try {
    const std::string first = argc >= 2 ? argv[1] : "";
    const bool help =
        first == "-h" || first == "--help" ||
        (argc >= 3 && (std::string(argv[2]) == "-h" || std::string(argv[2]) == "--help"));
    if (help) {
      std::cout << usage_text;
      return 0;
    }
    if (first == "contour") return run_contour(argc, argv);
    return run(argc, argv);
  } catch (const progiso::error& e) {
    std::cerr << "progiso: error: " << e.what() << "\n";
    return 2;
  } catch (const std::bad_alloc&) {
    std::cerr << "progiso: error: out of memory\n";
    return 2;
  }
}
