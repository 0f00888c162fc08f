// progiso contour — progressive isocontours of a 2D image.
//
//   progiso contour INPUT.pgm|INPUT.png -o OUT.obj|OUT.svg --iso W[,W2,...]
//           [--full | --error E | --max-segments K | --time-ms T] [--frames DIR]
//           [--stats-json FILE]
//
// Exit status 0 on success, 2 on bad input (one line on stderr, no output file).
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <progiso/core/contour_io.hpp>
#include <progiso/core/contour_refiner.hpp>
#include <progiso/core/error.hpp>
#include <progiso/core/image_io.hpp>

#include "cli_common.hpp"

namespace {

using progiso::error;
using namespace progiso::cli;
namespace fs = std::filesystem;

struct contour_arguments {
  std::optional<std::string> input;
  std::optional<std::string> output;
  std::vector<double> isovalues;
  progiso::contour_options options;
  int modes = 0;
  std::optional<std::string> frames;
  std::optional<std::string> stats_json;
};

contour_arguments parse_contour(int argc, char** argv) {
  contour_arguments a;
  const auto value = [&](int& i, const std::string& flag) {
    return next_value(argc, argv, i, flag);
  };
  for (int i = 2; i < argc; ++i) {
    const std::string f = argv[i];
    if (f == "-o" || f == "--output") {
      a.output = value(i, f);
    } else if (f == "--iso") {
      for (const auto& part : split_list(f, value(i, f)))
        a.isovalues.push_back(parse_number(f, part));
    } else if (f == "--full") {
      a.options.mode = progiso::contour_mode::full;
      ++a.modes;
    } else if (f == "--error") {
      a.options.mode = progiso::contour_mode::error;
      a.options.max_error = parse_number(f, value(i, f));
      if (a.options.max_error < 0) throw error("--error: expected a non-negative number");
      ++a.modes;
    } else if (f == "--max-segments") {
      const std::string t = value(i, f);
      const double k = parse_number(f, t);
      if (k < 0 || k != std::floor(k)) {
        throw error("--max-segments: expected a non-negative integer, found '" + t + "'");
      }
      a.options.mode = progiso::contour_mode::segments;
      a.options.max_segments = static_cast<std::uint64_t>(k);
      ++a.modes;
    } else if (f == "--time-ms") {
      const double ms = parse_number(f, value(i, f));
      if (ms < 0) throw error("--time-ms: expected a non-negative number of milliseconds");
      a.options.mode = progiso::contour_mode::time;
      a.options.time_budget = std::chrono::duration<double>(ms / 1000.0);
      ++a.modes;
    } else if (f == "--frames") {
      a.frames = value(i, f);
    } else if (f == "--stats-json") {
      a.stats_json = value(i, f);
    } else if (!f.empty() && f[0] == '-') {
      throw error("unknown option '" + f + "'");
    } else if (!a.input) {
      a.input = f;
    } else {
      throw error("unexpected argument '" + f + "' (only one INPUT is allowed)");
    }
  }
  if (a.modes > 1) throw error("choose at most one of --full, --error, --max-segments, --time-ms");
  if (!a.input) throw error("missing INPUT.pgm|INPUT.png");
  if (!a.output) throw error("missing -o OUT.obj|OUT.svg");
  if (a.isovalues.empty()) throw error("missing --iso W[,W2,...]");
  const std::string ext = progiso::detail::lower_extension(*a.output);
  if (ext != ".obj" && ext != ".svg") {
    throw error(*a.output + ": unknown contour format (expected a .obj or .svg file name)");
  }
  if (a.stats_json) {
    const auto parent = fs::path(*a.stats_json).parent_path();
    if (!parent.empty() && !fs::is_directory(parent)) {
      throw error(*a.stats_json + ": directory does not exist");
    }
  }
  return a;
}

std::string contour_stats_json(const contour_arguments& a, const progiso::volume& img,
                               const progiso::contour_result& r) {
  const char* mode_names[] = {"full", "error", "segments", "time"};
  std::uint64_t splits = 0, visited = 0, culled = 0;
  std::array<std::uint64_t, progiso::contour_case_count> cases{};
  std::array<std::uint64_t, progiso::contour_primitive_count> prims{};
  for (const auto& s : r.stats) {
    splits += s.splits;
    visited += s.visited;
    culled += s.culled;
    for (std::size_t i = 0; i < cases.size(); ++i) cases[i] += s.cases[i];
    for (std::size_t i = 0; i < prims.size(); ++i) prims[i] += s.primitives[i];
  }
  std::size_t closed = 0;
  for (const auto& p : r.contours.polylines) closed += p.closed ? 1 : 0;
  std::ostringstream o;
  o << "{\n  \"input\": \"" << json_escape(*a.input) << "\",\n";
  o << "  \"size\": [" << img.dims()[0] << ", " << img.dims()[1] << "],\n";
  o << "  \"isovalues\": [";
  for (std::size_t i = 0; i < a.isovalues.size(); ++i) {
    o << (i ? ", " : "") << json_number(a.isovalues[i]);
  }
  o << "],\n  \"mode\": \"" << mode_names[static_cast<int>(a.options.mode)] << "\",\n";
  o << "  \"splits\": " << splits << ",\n  \"diamonds_visited\": " << visited
    << ",\n  \"diamonds_culled\": " << culled << ",\n";
  o << "  \"pixels\": " << img.voxel_count() << ",\n";
  o << "  \"segments\": " << r.contours.segment_count() << ",\n";
  o << "  \"polylines\": " << r.contours.polylines.size() << ",\n  \"closed_polylines\": " << closed
    << ",\n";
  o << "  \"time_to_first_contour_ms\": " << json_number(r.first_contour_seconds * 1e3) << ",\n";
  o << "  \"range_build_ms\": " << json_number(r.range_build_seconds * 1e3) << ",\n";
  o << "  \"refine_ms\": " << json_number(r.refine_seconds * 1e3) << ",\n";
  o << "  \"total_ms\": " << json_number(r.total_seconds * 1e3) << ",\n";
  o << "  \"range_data_bytes\": " << r.range_bytes << ",\n  \"image_bytes\": " << img.byte_size()
    << ",\n";
  o << "  \"cases\": {";
  for (std::size_t i = 0; i < cases.size(); ++i) {
    o << (i ? ", " : "") << '"' << progiso::to_string(static_cast<progiso::contour_case>(i))
      << "\": " << cases[i];
  }
  o << "},\n  \"primitives\": {";
  for (std::size_t i = 0; i < prims.size(); ++i) {
    o << (i ? ", " : "") << '"' << progiso::to_string(static_cast<progiso::contour_primitive>(i))
      << "\": " << prims[i];
  }
  o << "}\n}\n";
  return o.str();
}

}  // namespace

int run_contour(int argc, char** argv) {
  contour_arguments a = parse_contour(argc, argv);
  const progiso::volume img = progiso::read_image(*a.input);
  std::cerr << "progiso: " << *a.input << ", " << img.dims()[0] << "x" << img.dims()[1] << " "
            << progiso::to_string(img.type()) << ", " << a.isovalues.size() << " isovalue(s)\n";
  if (a.frames) {
    std::error_code ec;
    fs::create_directories(*a.frames, ec);
    if (ec || !fs::is_directory(*a.frames)) {
      throw error(*a.frames + ": cannot create the frames directory");
    }
    a.options.frame = [&](const progiso::contour_set& c, int stage) {
      char name[32];
      std::snprintf(name, sizeof name, "frame_%04d.svg", stage);
      progiso::write_contour_svg(fs::path(*a.frames) / name, c, &img);
    };
  }
  const progiso::contour_result r = progiso::extract_contours(img, a.isovalues, a.options);
  const auto [lo, hi] = img.value_range();
  for (const double w : a.isovalues) {
    if (!(lo <= w && w < hi)) {
      std::cerr << "progiso: isovalue " << w << " is outside the data range [" << lo << ", " << hi
                << "): its contour is empty\n";
    }
  }
  progiso::write_contours(*a.output, r.contours, &img);
  if (a.stats_json) write_text_atomically(*a.stats_json, contour_stats_json(a, img, r));
  std::uint64_t splits = 0;
  for (const auto& s : r.stats) splits += s.splits;
  std::printf(
      "progiso: %zu polylines, %zu segments; %llu splits; first contour %.3f ms, range data "
      "%.1f ms (%zu bytes), refinement %.1f ms; wrote %s\n",
      r.contours.polylines.size(), r.contours.segment_count(),
      static_cast<unsigned long long>(splits), r.first_contour_seconds * 1e3,
      r.range_build_seconds * 1e3, r.range_bytes, r.refine_seconds * 1e3, a.output->c_str());
  return 0;
}
