#include "cli_options.hpp"

#include <charconv>
#include <cmath>
#include <string_view>
#include <system_error>

#include <progiso/core/base/error.hpp>
#include <progiso/core/surface/hierarchy_stream.hpp>
#include <progiso/io/detail/file_input.hpp>
#include <progiso/io/detail/file_output.hpp>

namespace progiso::cli {

const char* const usage_text =
    "usage:\n"
    "  progiso extract INPUT -o OUT.ply|OUT.obj|OUT.stl|OUT.glb|OUT.vtp --iso W\n"
    "          [--dims NX,NY,NZ --type u8|i8|u16|i16|u32|i32|f32|f64 [--big-endian]]\n"
    "          [--spacing SX,SY,SZ | --world] [--series N|UID] [--volume K] [--level L]\n"
    "          [--full | --error E | --max-triangles K | --time-ms T [--by-priority]]\n"
    "          [--stats-json FILE] [--threads N] [--normals] [--hierarchy OUT.pgh]\n"
    "          [--smooth S] [--smooth-from K] [--smooth-region X0,Y0,Z0,X1,Y1,Z1] [--alpha A]\n"
    "  progiso cut IN.pgh -o OUT.ply|OUT.obj|OUT.stl|OUT.glb|OUT.vtp\n"
    "          [--error E | --max-triangles K | --region X0,Y0,Z0,X1,Y1,Z1] [--records N]\n"
    "          [--stats-json FILE]\n"
    "  progiso extract --demo -o OUT.ply [--iso W] [--threads N] [--normals]\n"
    "  progiso contour INPUT.pgm|INPUT.png -o OUT.obj|OUT.svg --iso W[,W2,...]\n"
    "          [--full | --error E | --max-segments K | --time-ms T] [--frames DIR]\n"
    "          [--stats-json FILE]\n"
    "          [--smooth S] [--smooth-from K] [--smooth-region X0,Y0,X1,Y1] [--alpha A]\n"
    "  progiso view INPUT|--demo [--iso W] [--port P] [--bind ADDR] [--threads N]\n"
    "          [extract's input and --smooth options]: the surface refining in a browser; prints\n"
    "          the page's address (binds 127.0.0.1 and port 8080 unless told; --port 0: any)\n"
    "\n"
    "INPUT is a .nrrd/.nhdr file, a NIfTI-1/2 file (.nii, .nii.gz, or .hdr with its .img;\n"
    "scl_slope/scl_inter applied, so isovalues are in physical units), a MetaImage file\n"
    "(.mha, or .mhd with its data files), a legacy VTK file of STRUCTURED_POINTS (.vtk), VTK\n"
    "XML image data (.vti, or .pvti with its pieces: the active point scalars), a directory\n"
    "of DICOM files, one enhanced multi-frame DICOM file (Enhanced CT/MR) or an RT dose grid\n"
    "(uncompressed, lossless JPEG, RLE or JPEG 2000; rescaled, so CT isovalues are in\n"
    "Hounsfield units and doses in Gy; --series picks one of several series by the number or\n"
    "UID the error lists), a TIFF stack (a multi-page .tif/.tiff, or a directory of .tif\n"
    "slices in natural order of their names: micro-CT, microscopy, ImageJ/Fiji; one grey\n"
    "channel), an MRC or CCP4 map (.mrc, .map, .ccp4, .rec, plain or .gz: cryo-EM maps,\n"
    "tomograms, electron density; any axis order), a Zarr array or OME-Zarr image (the\n"
    "directory; blosc, zstd, zlib, gzip or raw chunks: light-sheet and electron microscopy),\n"
    "or a headerless raw file described by --dims and --type (x fastest, little-endian\n"
    "unless --big-endian).\n"
    "--volume K reads volume K (0-based) of a NIfTI time series (dim[4] > 1), a MetaImage\n"
    "series (NDims 4), a 4-D NRRD (Slicer sequences, diffusion MRI), a DICOM series of\n"
    "time points (as many frames at every position: 4-D CT, cine MR; ordered by\n"
    "TemporalPositionIndex, else InstanceNumber), an ImageJ hyperstack of frames, an MRC\n"
    "volume stack or an OME-Zarr image's time points and channels (row-major).\n"
    "--level L reads level L of an OME-Zarr image's pyramid (0, the default: the finest).\n"
    "--world writes the vertices in the coordinates the file declares (a NIfTI sform, else\n"
    "qform; NRRD space directions and origin; MetaImage TransformMatrix and Offset; .vti\n"
    "Direction; DICOM patient coordinates; an MRC map's unit cell, oblique cells skewed):\n"
    "rotations and flips applied.\n"
    "--demo uses a built-in 129^3 Marschner-Lobb volume (isovalue 0.5 unless --iso is\n"
    "given).\n"
    "--hierarchy OUT.pgh runs the engine and writes its output hierarchy as it is published:\n"
    "a versioned stream of split records (docs/formats.md) from which `progiso cut` makes\n"
    "any cut without the volume: by error, by triangle budget, or full resolution inside a\n"
    "box of grid coordinates (--region, inclusive) with the least refinement outside it;\n"
    "--records N takes the stream's first N records (a coarser cut).\n"
    "Modes: --full (default) refines everywhere the surface can be; --error E stops when\n"
    "every remaining split error is <= E; --max-triangles K keeps at most K triangles;\n"
    "--time-ms T returns the finest surface made within T milliseconds: uniform cuts of the\n"
    "hierarchy, coarse to fine (every 2^k-th sample, then every 2^(k-1)-th, ... then every\n"
    "sample; a finer cut whose memory cannot be had, under a data limit, is given up like\n"
    "one out of time); with --by-priority, the hierarchy refined by largest error first instead.\n"
    "--threads N runs the concurrent engine on N threads (default: all cores); --full gives\n"
    "the same file for every N.\n"
    "--normals gives every vertex a unit normal for smooth shading (PLY nx ny nz, OBJ vn):\n"
    "minus the field's gradient (central differences, interpolated at the vertex), so it\n"
    "points out of the region above the isovalue, as the triangles face. STL stores facet\n"
    "normals only.\n"
    "contour: INPUT is a binary PGM (8/16 bit) or a grayscale PNG; several isovalues are\n"
    "comma-separated and refined one after the other (a budget or deadline is shared);\n"
    "OBJ gets 'v x y 0' and 'l ...' polylines, SVG draws them over the image;\n"
    "--frames DIR writes one SVG per refinement stage.\n"
    "Smoothing (both commands): the values refinement inserts come from the 4-point\n"
    "subdivision rule (mask [-A, 8+A, 8+A, -A]/16, 0 < A < 2.4721, default 1) instead of\n"
    "the data. --smooth S (0..3) refines S levels below the data's resolution; --smooth-from\n"
    "K (>= 1) uses the data only on every 2^K-th sample and smooths everything finer;\n"
    "--smooth-region smooths inside a box of data index coordinates (inclusive) and keeps\n"
    "the data's values outside it. Written coordinates stay physical.\n"
    "Outputs appear only when everything succeeded; an output that names an input or\n"
    "another output is refused.\n";

namespace {

/// 'TEXT' for a message: at most 40 bytes, non-printable bytes escaped.
std::string shown(const std::string& text) {
  std::string q = detail::quoted(text);
  q.front() = '\'';
  q.back() = '\'';
  return q;
}

/// The value after option args[i] (advancing i), or a one-line error naming the option.
std::string next_value(const std::vector<std::string>& args, std::size_t& i,
                       const std::string& flag) {
  if (i + 1 >= args.size()) throw error(flag + ": missing value");
  return args[++i];
}

/// Splits "a,b,c" at commas; every part must be non-empty.
std::vector<std::string> split_list(const std::string& flag, const std::string& text) {
  std::vector<std::string> parts;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = text.find(',', start);
    parts.push_back(
        text.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (parts.back().empty()) {
      throw error(flag + ": expected comma-separated values, found " + shown(text));
    }
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return parts;
}

std::vector<std::string> split_three(const std::string& flag, const std::string& text) {
  const auto parts = text.empty() ? std::vector<std::string>{} : split_list(flag, text);
  if (parts.size() != 3) {
    throw error(flag + ": expected three comma-separated values, found " + shown(text));
  }
  return parts;
}

}  // namespace

double parse_number(const std::string& flag, const std::string& text) {
  std::string_view t = text;
  if (t.size() > 1 && t[0] == '+' && t[1] != '-' && t[1] != '+') t.remove_prefix(1);
  double v = 0.0;
  const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
  if (r.ec == std::errc::result_out_of_range && r.ptr == t.data() + t.size()) {
    throw error(flag + ": expected a finite number, found " + shown(text) +
                " (beyond the range of a double)");
  }
  if (r.ec != std::errc{} || r.ptr != t.data() + t.size() || t.empty()) {
    throw error(flag + ": expected a number, found " + shown(text));
  }
  if (!std::isfinite(v)) throw error(flag + ": expected a finite number, found " + shown(text));
  return v;
}

std::uint64_t parse_count(const std::string& flag, const std::string& text) {
  const auto bad = [&] {
    return error(flag + ": expected a non-negative integer up to 18446744073709551615, found " +
                 shown(text));
  };
  std::uint64_t n = 0;
  const auto r = std::from_chars(text.data(), text.data() + text.size(), n);
  if (r.ec == std::errc{} && r.ptr == text.data() + text.size() && !text.empty()) return n;
  if (r.ec == std::errc::result_out_of_range) throw bad();
  double v = 0.0;
  try {
    v = parse_number(flag, text);
  } catch (const error&) {
    throw bad();
  }
  // 2^64 is exactly representable; every double below it that is integral converts exactly.
  if (!(v >= 0.0) || v != std::floor(v) || v >= 18446744073709551616.0) throw bad();
  return static_cast<std::uint64_t>(v);
}

namespace {

/// The goal options shared by both commands (core/refine/goal.hpp): --full, --error E, the
/// budget flag (--max-triangles or --max-segments) K, --time-ms T. Returns false when `f` is
/// none of them; counts the goals given in `modes`. A deadline's clock starts when the input is
/// in memory: the duration waits in `time_budget` until then (start_deadline()).
template <class Arguments, class Value>
bool parse_goal(const std::string& f, const Value& value, const char* budget_flag, Arguments& a,
                int& modes) {
  refine_goal& goal = a.options.goal;
  if (f == "--full") {
    goal = refine_goal::full();
  } else if (f == "--error") {
    const double e = parse_number(f, value());
    if (e < 0) throw error("--error: expected a non-negative number");
    goal = refine_goal::error(e);
  } else if (f == budget_flag) {
    goal = refine_goal::triangles(parse_count(f, value()));
  } else if (f == "--time-ms") {
    const double ms = parse_number(f, value());
    if (ms < 0) throw error("--time-ms: expected a non-negative number of milliseconds");
    // Budgets beyond the clock's range saturate (deadline_after): no deadline at all.
    a.time_budget = std::chrono::duration<double>(ms / 1000.0);
    goal = refine_goal::until({});
  } else {
    return false;
  }
  ++modes;
  return true;
}

}  // namespace

const char* goal_name(const refine_goal& goal, const char* budget_name) noexcept {
  switch (goal.what) {
    case refine_goal::kind::full:
      return "full";
    case refine_goal::kind::error:
      return "error";
    case refine_goal::kind::budget:
      return budget_name;
    case refine_goal::kind::deadline:
      return "time";
  }
  return "full";
}

namespace {

/// What both commands do with any other argument: -h/--help (returns false: stop parsing), an
/// unknown option (throws), the one INPUT (throws for a second one).
bool take_other(const std::string& f, bool& help, std::optional<std::string>& input) {
  if (f == "-h" || f == "--help") {
    help = true;
    return false;
  }
  if (!f.empty() && f[0] == '-') throw error("unknown option " + shown(f));
  if (input) throw error("unexpected argument " + shown(f) + " (only one INPUT is allowed)");
  input = f;
  return true;
}

/// The smoothing options shared by both commands: --smooth S, --smooth-from K,
/// --smooth-region (2·axes integers: lows then highs), --alpha A. Returns false when `f` is none
/// of them. Limits that depend on the input (K against its extent, the region inside it) are
/// checked once it is read (check_smoothing()).
template <class Value>
bool parse_smoothing(const std::string& f, const Value& value, smoothing& s, std::size_t axes) {
  if (f == "--smooth") {
    const std::string t = value();
    const std::uint64_t n = parse_count(f, t);
    if (n > 3) throw error("--smooth: expected an integer from 0 to 3, found " + shown(t));
    s.levels = static_cast<int>(n);
  } else if (f == "--smooth-from") {
    const std::string t = value();
    const std::uint64_t n = parse_count(f, t);
    if (n < 1 || n > 14)
      throw error("--smooth-from: expected an integer from 1 to 14, found " + shown(t));
    s.from = static_cast<int>(n);
  } else if (f == "--smooth-region") {
    const std::string t = value();
    const char* form = axes == 3 ? "X0,Y0,Z0,X1,Y1,Z1" : "X0,Y0,X1,Y1";
    const auto parts = t.empty() ? std::vector<std::string>{} : split_list(f, t);
    if (parts.size() != 2 * axes) {
      throw error("--smooth-region: expected " + std::to_string(2 * axes) +
                  " comma-separated integers " + form + ", found " + shown(t));
    }
    std::array<std::int64_t, 6> r{0, 0, 0, 0, 0, 0};
    for (std::size_t k = 0; k < parts.size(); ++k) {
      const std::uint64_t v = parse_count(f, parts[k]);
      if (v > (std::uint64_t{1} << 31)) {
        throw error("--smooth-region: expected sample indices, found " + shown(parts[k]));
      }
      r[(k / axes) * 3 + k % axes] = static_cast<std::int64_t>(v);
    }
    for (std::size_t q = 0; q < axes; ++q) {
      if (r[q] > r[q + 3]) {
        throw error("--smooth-region: expected each low corner <= its high corner (" +
                    std::string(form) + "), found " + shown(t));
      }
    }
    s.region = r;
  } else if (f == "--alpha") {
    const std::string t = value();
    const double a = parse_number(f, t);
    if (!(a > 0.0 && a < max_smoothing_alpha)) {
      throw error("--alpha: expected a number with 0 < A < 2(sqrt 5 - 1) = 2.4721, found " +
                  shown(t));
    }
    s.alpha = a;
  } else {
    return false;
  }
  return true;
}

}  // namespace

extract_arguments parse_extract(const std::vector<std::string>& args, bool under_mpi) {
  extract_arguments a;
  if (args.empty()) {
    throw error("missing command (expected 'extract', 'cut' or 'contour'; see progiso --help)");
  }
  if (args[0] != "extract") {
    throw error("unknown command " + shown(args[0]) + " (expected 'extract', 'cut' or 'contour')");
  }
  int modes = 0;
  bool by_priority = false;
  for (std::size_t i = 1; i < args.size(); ++i) {
    const std::string& f = args[i];
    const auto value = [&] { return next_value(args, i, f); };
    if (parse_goal(f, value, "--max-triangles", a, modes) ||
        parse_smoothing(f, value, a.smooth, 3)) {
      continue;
    }
    if (f == "-o" || f == "--output") {
      a.output = value();
    } else if (f == "--iso") {
      a.iso = parse_number(f, value());
    } else if (f == "--demo") {
      a.demo = true;
    } else if (f == "--dims") {
      const auto parts = split_three(f, value());
      index3 d{};
      for (std::size_t q = 0; q < 3; ++q) {
        const std::uint64_t v = parse_count(f, parts[q]);
        if (v < 1 || v > 1000000000) {
          throw error("--dims: expected positive integers up to 1000000000, found " +
                      shown(parts[q]));
        }
        d[q] = static_cast<std::int64_t>(v);
      }
      a.dims = d;
    } else if (f == "--type") {
      const std::string t = value();
      a.type = parse_sample_type(t);
      if (!a.type) {
        throw error("--type: expected one of u8 i8 u16 i16 u32 i32 f32 f64, found " + shown(t));
      }
    } else if (f == "--big-endian") {
      a.big_endian = true;
    } else if (f == "--normals") {
      a.options.normals = true;
    } else if (f == "--by-priority") {
      a.options.deadline_ladder = false;
      by_priority = true;
    } else if (f == "--world") {
      a.world = true;
    } else if (f == "--series") {
      a.series = value();
    } else if (f == "--volume") {
      const std::string k = value();
      const std::uint64_t n = parse_count(f, k);
      if (n > 2147483647) {
        throw error("--volume: expected an index from 0 to 2147483647, found " + shown(k));
      }
      a.volume = static_cast<std::int64_t>(n);
    } else if (f == "--level") {
      const std::string k = value();
      const std::uint64_t n = parse_count(f, k);
      if (n > 31) throw error("--level: expected a level from 0 to 31, found " + shown(k));
      a.level = static_cast<std::int64_t>(n);
    } else if (f == "--spacing") {
      const auto parts = split_three(f, value());
      std::array<double, 3> s{};
      for (std::size_t q = 0; q < 3; ++q) {
        s[q] = parse_number(f, parts[q]);
        if (s[q] <= 0) throw error("--spacing: expected positive values, found " + shown(parts[q]));
      }
      a.spacing = s;
    } else if (f == "--stats-json") {
      a.stats_json = value();
    } else if (f == "--hierarchy") {
      a.hierarchy = value();
    } else if (f == "--threads") {
      const std::string t = value();
      const std::uint64_t n = parse_count(f, t);
      if (n < 1 || n > 4096) {
        throw error("--threads: expected an integer from 1 to 4096, found " + shown(t));
      }
      a.threads = static_cast<unsigned>(n);
    } else if (!take_other(f, a.help, a.input)) {
      return a;
    }
  }
  if (modes > 1) throw error("choose at most one of --full, --error, --max-triangles, --time-ms");
  if (by_priority && a.options.goal.what != refine_goal::kind::deadline) {
    throw error("--by-priority applies to --time-ms (the other modes choose their own order)");
  }
  if (a.demo && a.input) throw error("--demo takes no INPUT");
  if (!a.demo && !a.input) throw error("missing INPUT (or --demo)");
  if (!a.output) throw error("missing -o OUT.ply|OUT.obj|OUT.stl|OUT.glb|OUT.vtp");
  if (!a.demo && !a.iso) throw error("missing --iso W");
  if (a.dims.has_value() != a.type.has_value()) {
    throw error("--dims and --type must be given together for a raw volume");
  }
  if (a.big_endian && !a.dims) throw error("--big-endian applies to raw input with --dims/--type");
  if (a.world && (a.dims || a.demo)) {
    throw error(
        "--world needs an input file that declares its orientation (a NIfTI sform or qform, "
        "NRRD space directions, or a MetaImage header)");
  }
  if (a.series && (a.dims || a.demo)) {
    throw error("--series picks a series of a DICOM directory, not of a raw or demo volume");
  }
  if (a.volume && a.demo) throw error("--volume picks a volume of an input file, not of --demo");
  if (a.level && (a.demo || a.dims)) {
    throw error("--level picks a level of an OME-Zarr image, not of a raw or demo volume");
  }
  if (a.world && a.spacing) {
    throw error("--world and --spacing: the orientation the file declares sets the spacing");
  }
  const std::string ext = detail::lower_extension(*a.output);
  if (ext == ".pvtp" && !under_mpi) {
    throw error(*a.output +
                ": a .pvtp (one piece per rank) is written under mpirun only (expected a .ply, "
                ".obj, .stl, .glb or .vtp file name)");
  }
  if (ext != ".ply" && ext != ".obj" && ext != ".stl" && ext != ".glb" && ext != ".vtp" &&
      ext != ".pvtp") {
    throw error(*a.output +
                ": unknown mesh format (expected a .ply, .obj, .stl, .glb or .vtp file name, or "
                "under mpirun .pvtp)");
  }
  if (a.options.normals && ext == ".stl") {
    throw error("--normals: " + *a.output +
                " is STL, which stores one normal per facet and none per vertex (write .ply or "
                ".obj for vertex normals)");
  }
  if (a.stats_json && a.stats_json->empty()) {
    throw error("--stats-json: expected a file name, found an empty one");
  }
  if (a.hierarchy) {
    if (detail::lower_extension(*a.hierarchy) != hierarchy_stream_extension) {
      throw error("--hierarchy: " + shown(*a.hierarchy) + ": expected a " +
                  hierarchy_stream_extension + " file name");
    }
    if (a.world) {
      throw error(
          "--hierarchy with --world: a stream holds physical coordinates (origin + index x "
          "spacing); write it without --world");
    }
  }
  return a;
}

cut_arguments parse_cut(const std::vector<std::string>& args) {
  cut_arguments a;
  if (args.empty() || args[0] != "cut") throw error("expected the 'cut' command");
  int modes = 0;
  for (std::size_t i = 1; i < args.size(); ++i) {
    const std::string& f = args[i];
    const auto value = [&] { return next_value(args, i, f); };
    if (f == "-o" || f == "--output") {
      a.output = value();
    } else if (f == "--error") {
      a.max_error = parse_number(f, value());
      if (a.max_error < 0) throw error("--error: expected a non-negative number");
      a.how = cut_arguments::mode::error;
      ++modes;
    } else if (f == "--max-triangles") {
      a.max_triangles = parse_count(f, value());
      a.how = cut_arguments::mode::triangles;
      ++modes;
    } else if (f == "--region") {
      const std::string t = value();
      const auto parts = t.empty() ? std::vector<std::string>{} : split_list(f, t);
      if (parts.size() != 6) {
        throw error("--region: expected 6 numbers X0,Y0,Z0,X1,Y1,Z1, found " + shown(t));
      }
      for (std::size_t k = 0; k < 6; ++k) a.region[k] = parse_number(f, parts[k]);
      for (std::size_t q = 0; q < 3; ++q) {
        if (a.region[q] > a.region[q + 3]) {
          throw error("--region: expected each low corner <= its high corner, found " + shown(t));
        }
      }
      a.how = cut_arguments::mode::region;
      ++modes;
    } else if (f == "--records") {
      a.records = parse_count(f, value());
    } else if (f == "--stats-json") {
      a.stats_json = value();
      if (a.stats_json->empty()) {
        throw error("--stats-json: expected a file name, found an empty one");
      }
    } else if (!take_other(f, a.help, a.input)) {
      return a;
    }
  }
  if (modes > 1) throw error("choose at most one of --error, --max-triangles, --region");
  if (!a.input) throw error("missing IN.pgh");
  if (!a.output) throw error("missing -o OUT.ply|OUT.obj|OUT.stl|OUT.glb|OUT.vtp");
  const std::string ext = detail::lower_extension(*a.output);
  if (ext != ".ply" && ext != ".obj" && ext != ".stl" && ext != ".glb" && ext != ".vtp") {
    throw error(*a.output +
                ": unknown mesh format (expected a .ply, .obj, .stl, .glb or .vtp file name)");
  }
  return a;
}

contour_arguments parse_contour(const std::vector<std::string>& args) {
  contour_arguments a;
  if (args.empty() || args[0] != "contour") throw error("expected the 'contour' command");
  int modes = 0;
  for (std::size_t i = 1; i < args.size(); ++i) {
    const std::string& f = args[i];
    const auto value = [&] { return next_value(args, i, f); };
    if (parse_goal(f, value, "--max-segments", a, modes) ||
        parse_smoothing(f, value, a.smooth, 2)) {
      continue;
    }
    if (f == "-o" || f == "--output") {
      a.output = value();
    } else if (f == "--iso") {
      for (const auto& part : split_list(f, value())) a.isovalues.push_back(parse_number(f, part));
    } else if (f == "--frames") {
      a.frames = value();
      if (a.frames->empty()) throw error("--frames: expected a directory name, found an empty one");
    } else if (f == "--stats-json") {
      a.stats_json = value();
      if (a.stats_json->empty()) {
        throw error("--stats-json: expected a file name, found an empty one");
      }
    } else if (!take_other(f, a.help, a.input)) {
      return a;
    }
  }
  if (modes > 1) throw error("choose at most one of --full, --error, --max-segments, --time-ms");
  if (!a.input) throw error("missing INPUT.pgm|INPUT.png");
  if (!a.output) throw error("missing -o OUT.obj|OUT.svg");
  if (a.isovalues.empty()) throw error("missing --iso W[,W2,...]");
  const std::string ext = detail::lower_extension(*a.output);
  if (ext != ".obj" && ext != ".svg") {
    throw error(*a.output + ": unknown contour format (expected a .obj or .svg file name)");
  }
  return a;
}

}  // namespace progiso::cli
