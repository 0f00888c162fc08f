// progiso view: the engine's surface in a browser (apps/progiso/view/view_server.hpp).
//
//   progiso view INPUT [--iso W] [--port P] [--bind ADDR] [--threads N]
//                [--dims … --type … [--big-endian]] [--spacing …] [--series …] [--volume K]
//                [--smooth S] [--smooth-from K] [--smooth-region …] [--alpha A]
//   progiso view --demo [--iso W] [--port P] …
//
// The input options are `extract`'s (parsed by parse_extract(), with a placeholder output);
// --port (default 8080; 0: any free port) and --bind (default 127.0.0.1) are view's own. The
// command prints the page's address and serves until it is interrupted.
#include <atomic>
#include <charconv>
#include <cmath>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/field/smoothing.hpp>
#include <progiso/io/volume_io.hpp>
#include <progiso/scheduler/engine.hpp>

#include "cli_common.hpp"
#include "cli_options.hpp"
#include "view/view_assets.hpp"
#include "view/view_server.hpp"

namespace {

using progiso::error;

struct view_arguments {
  progiso::cli::extract_arguments input;
  bool iso_given = false;
  std::string bind = "127.0.0.1";
  std::uint16_t port = 8080;
};

view_arguments parse_view(const std::vector<std::string>& args) {
  view_arguments v;
  std::vector<std::string> rest{"extract"};
  for (std::size_t i = 1; i < args.size(); ++i) {
    const std::string& a = args[i];
    const auto value = [&]() -> const std::string& {
      if (i + 1 >= args.size()) throw error(a + ": missing value");
      return args[++i];
    };
    if (a == "--port") {
      const std::string& p = value();
      unsigned long n = 0;
      const auto r = std::from_chars(p.data(), p.data() + p.size(), n);
      if (r.ec != std::errc{} || r.ptr != p.data() + p.size() || n > 65535) {
        throw error("--port: expected a port number 0 to 65535, found '" + p + "'");
      }
      v.port = static_cast<std::uint16_t>(n);
    } else if (a == "--bind") {
      v.bind = value();
    } else if (a == "-o" || a == "--full" || a == "--error" || a == "--max-triangles" ||
               a == "--time-ms" || a == "--by-priority" || a == "--stats-json" ||
               a == "--hierarchy" || a == "--normals" || a == "--world") {
      throw error(a + " is an option of extract, not of view (see progiso --help)");
    } else {
      if (a == "--iso") v.iso_given = true;
      rest.push_back(a);
    }
  }
  if (!v.iso_given) {
    rest.push_back("--iso");
    rest.push_back("0");  // placeholder: the middle of the data's range replaces it
  }
  rest.push_back("-o");
  rest.push_back("view.ply");  // placeholder: view writes no file
  v.input = progiso::cli::parse_extract(rest);
  return v;
}

}  // namespace

int run_view(const std::vector<std::string>& args) {
  view_arguments a = parse_view(args);
  if (a.input.help) {
    std::cout << progiso::cli::usage_text;
    return 0;
  }
  const auto& in = a.input;
  std::shared_ptr<const progiso::volume> data;
  std::string name;
  if (in.demo) {
    data = std::make_shared<const progiso::volume>(progiso::make_demo_volume());
    name = "demo: Marschner-Lobb 129^3";
  } else {
    std::optional<progiso::raw_layout> raw;
    if (in.dims) raw = progiso::raw_layout{*in.dims, *in.type, in.big_endian};
    progiso::volume_source source(*in.input, raw,
                                  progiso::volume_choice{in.series, in.volume, in.level});
    data = std::make_shared<const progiso::volume>(source.read(in.spacing));
    name = *in.input;
  }
  const auto [lo, hi] = data->value_range();
  const double iso = a.iso_given ? *in.iso : in.demo ? progiso::demo_isovalue : 0.5 * (lo + hi);
  const std::shared_ptr<const progiso::volume> field =
      progiso::cli::smoothed_field(data, in.smooth, name);
  // Refinement split by split, largest error first: each frame a change of the surface, the
  // progressive surface the page shows (uniform cuts would arrive as whole new surfaces).
  progiso::engine_options options;
  options.threads = in.threads;
  options.uniform_cuts = false;
  auto next_error = std::make_shared<std::atomic<double>>(0.0);
  options.progress = [next_error](const progiso::engine_progress& p) {
    // Relaxed: a figure for the status line, no data hangs on it.
    next_error->store(p.next_error, std::memory_order_relaxed);
  };
  options.progress_interval = 1024;
  progiso::engine eng(field, iso, options);
  // Until a page says what it can draw (its "fit the display" budget, web/src/viewer.js), a cut
  // a software renderer still draws at interactive rates: the engine only refines, so a first
  // goal of everything would leave a slow display a surface it cannot draw.
  const progiso::refine_goal goal = progiso::refine_goal::triangles(50000);

  progiso::view::server_options so;
  so.bind = a.bind;
  so.port = a.port;
  so.assets = progiso::view::page_assets();
  so.next_error = [next_error] { return next_error->load(std::memory_order_relaxed); };
  so.spacing = field->spacing();
  so.origin = field->origin();
  progiso::view::server srv(eng, goal, so);
  eng.start(goal);
  std::ostringstream url;
  url.precision(17);
  const std::string host = a.bind == "0.0.0.0" ? "127.0.0.1" : a.bind;
  url << "http://" << host << ":" << srv.port() << "/?min=" << lo << "&max=" << hi
      << "&iso=" << iso;
  std::cerr << "progiso: " << name << ", " << data->dims()[0] << "x" << data->dims()[1] << "x"
            << data->dims()[2] << " " << progiso::to_string(data->type()) << ", isovalue " << iso
            << "\n";
  std::cout << "progiso view: " << url.str() << std::endl;
  srv.run();
  return 0;
}
