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
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/contour/contour_refiner.hpp>
#include <progiso/core/field/smoothing.hpp>
#include <progiso/io/contour_io.hpp>
#include <progiso/io/detail/file_output.hpp>
#include <progiso/io/image_io.hpp>

#include "cli_common.hpp"
#include "cli_options.hpp"
#include "cli_outputs.hpp"

namespace {

using progiso::error;
using namespace progiso::cli;
namespace fs = std::filesystem;

std::string contour_stats_json(const contour_arguments& a, const progiso::volume& img,
                               const progiso::volume& field, const progiso::contour_result& r,
                               std::size_t polylines, std::size_t segments, std::size_t closed) {
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
  std::ostringstream o;
  o << "{\n  \"input\": \"" << json_escape(*a.input) << "\",\n";
  o << "  \"size\": [" << img.dims()[0] << ", " << img.dims()[1] << "],\n";
  o << "  \"isovalues\": [";
  for (std::size_t i = 0; i < a.isovalues.size(); ++i) {
    o << (i ? ", " : "") << json_number(a.isovalues[i]);
  }
  o << "],\n  \"mode\": \"" << goal_name(a.options.goal, "segments") << "\",\n";
  // "finest": full contours from two passes over the pixels, not from refinement.
  o << "  \"path\": \"" << (r.finest_direct ? "finest" : "refinement") << "\",\n";
  o << "  \"splits\": " << splits << ",\n  \"diamonds_visited\": " << visited
    << ",\n  \"diamonds_culled\": " << culled << ",\n";
  o << "  \"pixels\": " << img.voxel_count() << ",\n";
  o << "  \"segments\": " << segments << ",\n";
  o << "  \"polylines\": " << polylines << ",\n  \"closed_polylines\": " << closed << ",\n";
  o << "  \"time_to_first_contour_ms\": " << json_number(r.first_contour_seconds * 1e3) << ",\n";
  o << "  \"range_build_ms\": " << json_number(r.range_build_seconds * 1e3) << ",\n";
  o << "  \"refine_ms\": " << json_number(r.refine_seconds * 1e3) << ",\n";
  o << "  \"total_ms\": " << json_number(r.total_seconds * 1e3) << ",\n";
  o << "  \"pipeline_ms\": " << json_number(r.pipeline_seconds * 1e3) << ",\n";
  o << "  \"range_data_bytes\": " << r.range_bytes << ",\n  \"image_bytes\": " << img.byte_size()
    << ",\n";
  o << "  \"smoothing\": " << smoothing_json(a.smooth, img, field) << ",\n";
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

int run_contour(const std::vector<std::string>& args) {
  contour_arguments a = parse_contour(args);
  if (a.help) {
    std::cout << usage_text;
    return 0;
  }
  // ---- Outputs: checked against the input and each other, then created (as temporaries, the
  // frames in a staging directory) before anything is read or computed.
  {
    std::vector<named_output> outputs{{"-o", *a.output}};
    if (a.stats_json) outputs.push_back({"--stats-json", *a.stats_json});
    if (a.frames) outputs.push_back({"--frames", *a.frames});
    refuse_clashing_outputs({fs::path(*a.input)}, outputs);
  }
  progiso::detail::atomic_output out(*a.output);
  std::optional<progiso::detail::atomic_output> stats_out;
  if (a.stats_json) stats_out.emplace(*a.stats_json);
  std::optional<progiso::detail::staged_directory> frames;
  if (a.frames) frames.emplace(*a.frames);

  const auto data = std::make_shared<const progiso::volume>(progiso::read_image(*a.input));
  const progiso::volume& img = *data;
  // The field contoured: the image, or its smoothed field (samples computed on demand). SVG
  // backgrounds show the image itself; coordinates are physical either way.
  std::shared_ptr<const progiso::volume> field = data;
  if (a.smooth.active()) {
    try {
      progiso::check_smoothing(img.dims(), a.smooth);
    } catch (const progiso::error& e) {
      throw error(*a.input + ": " + e.what());
    }
    field = std::make_shared<const progiso::volume>(progiso::smooth(data, a.smooth));
  }
  std::cerr << "progiso: " << *a.input << ", " << img.dims()[0] << "x" << img.dims()[1] << " "
            << progiso::to_string(img.type()) << ", " << a.isovalues.size() << " isovalue(s)";
  if (a.smooth.active()) {
    std::cerr << ", smoothed to " << field->dims()[0] << "x" << field->dims()[1] << " (S "
              << a.smooth.levels << ", K " << a.smooth.from << ", alpha " << a.smooth.alpha
              << (a.smooth.region ? ", in a region" : "") << ")";
  }
  std::cerr << "\n";
  if (frames) {
    a.options.frame = [&](const progiso::contour_set& c, int stage) {
      char name[32];
      std::snprintf(name, sizeof name, "frame_%04d.svg", stage);
      progiso::write_contour_svg(frames->staging() / name, c, &img);
    };
  }
  // Each isovalue's contours go to the file as soon as they are finished: memory holds one
  // isovalue's refinement, however many isovalues are asked for.
  progiso::contour_writer writer(out, a.isovalues, &img);
  std::size_t polylines = 0;
  std::size_t segments = 0;
  std::size_t closed = 0;
  a.options.sink = [&](const progiso::contour_set& c, std::size_t) {
    writer.add(c);
    polylines += c.polylines.size();
    segments += c.segment_count();
    for (const auto& p : c.polylines) closed += p.closed ? 1 : 0;
  };
  start_deadline(a);  // the image is in memory
  const progiso::contour_result r = progiso::extract_contours(*field, a.isovalues, a.options);
  const auto [lo, hi] = field->value_range();
  for (const double w : a.isovalues) {
    if (!(lo <= w && w < hi)) {
      std::cerr << "progiso: isovalue " << w << " is outside the data range [" << lo << ", " << hi
                << "): its contour is empty\n";
    }
  }
  writer.finish();
  if (stats_out) {
    stats_out->write(contour_stats_json(a, img, *field, r, polylines, segments, closed));
    stats_out->finish();
  }
  // Everything is written: publish the outputs together.
  out.publish();
  if (stats_out) stats_out->publish();
  if (frames) frames->publish();
  std::uint64_t splits = 0;
  for (const auto& s : r.stats) splits += s.splits;
  if (r.finest_direct) {
    std::printf(
        "progiso: %zu polylines, %zu segments; finest contours %.1f ms (two passes over "
        "the pixels); wrote %s\n",
        polylines, segments, r.refine_seconds * 1e3, a.output->c_str());
    return 0;
  }
  std::printf(
      "progiso: %zu polylines, %zu segments; %llu splits; first contour %.3f ms, range data "
      "%.1f ms (%zu bytes), refinement %.1f ms; wrote %s\n",
      polylines, segments, static_cast<unsigned long long>(splits), r.first_contour_seconds * 1e3,
      r.range_build_seconds * 1e3, r.range_bytes, r.refine_seconds * 1e3, a.output->c_str());
  return 0;
}
