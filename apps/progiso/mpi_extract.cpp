#include "mpi_extract.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <limits>
#include <memory>
#include <new>
#include <optional>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>
#include <progiso/core/ranges/range_data.hpp>
#include <progiso/core/refine/error_cut_share.hpp>
#include <progiso/core/surface/finest_surface.hpp>
#include <progiso/core/surface/hierarchy_stream.hpp>
#include <progiso/core/surface/normals.hpp>
#include <progiso/io/detail/file_output.hpp>
#include <progiso/io/detail/writers.hpp>
#include <progiso/io/volume_io.hpp>
#if defined(PROGISO_HAVE_MPI)
#include <progiso/mpi/detail/distributed_cut.hpp>
#include <progiso/mpi/detail/messages.hpp>
#endif
#include <progiso/scheduler/tbb_environment.hpp>

#include "cli_common.hpp"
#include "cli_options.hpp"
#include "cli_outputs.hpp"

#if defined(PROGISO_HAVE_MPI)
#include <mpi.h>
#endif

namespace progiso::cli {

namespace {

int env_int(const char* name) {
  const char* v = std::getenv(name);
  return v == nullptr ? -1 : std::atoi(v);
}

}  // namespace

bool launched_by_mpi() noexcept {
  return std::getenv("OMPI_COMM_WORLD_SIZE") != nullptr || std::getenv("PMI_SIZE") != nullptr ||
         std::getenv("PMIX_RANK") != nullptr;
}

int mpi_job_size() noexcept {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE"}) {
    if (const int n = env_int(name); n > 0) return n;
  }
  return 1;
}

#if !defined(PROGISO_HAVE_MPI)

bool have_mpi() noexcept { return false; }

int run_mpi_extract(const std::vector<std::string>&) {
  std::cerr << "progiso: error: started by mpirun with " << mpi_job_size()
            << " ranks, but this progiso was built without MPI (install libopenmpi-dev and "
               "configure again)\n";
  return 2;
}

#else

bool have_mpi() noexcept { return true; }

namespace {

/// MPI_Init and MPI_Finalize around the command.
struct mpi_session {
  mpi_session() { MPI_Init(nullptr, nullptr); }
  mpi_session(const mpi_session&) = delete;
  mpi_session& operator=(const mpi_session&) = delete;
  ~mpi_session() { MPI_Finalize(); }
};

/// Adds `by` to every vertex index of binary PLY face records (a count byte, then three
/// little-endian 32-bit indices; append_ply_records()'s): a share meshed with local ids moved to
/// the whole surface's.
void offset_ply_faces(std::vector<char>& faces, std::uint32_t by) {
  constexpr std::size_t record = 13;
  PROGISO_ASSERT(faces.size() % record == 0);
  auto* b = reinterpret_cast<unsigned char*>(faces.data());
  for (std::size_t at = 0; at < faces.size(); at += record) {
    for (std::size_t k = 0; k < 3; ++k) {
      unsigned char* p = b + at + 1 + 4 * k;
      std::uint32_t v = static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) << 8U |
                        static_cast<std::uint32_t>(p[2]) << 16U |
                        static_cast<std::uint32_t>(p[3]) << 24U;
      v += by;
      for (std::size_t q = 0; q < 4; ++q) p[q] = static_cast<unsigned char>(v >> (8 * q));
    }
  }
}

/// One line for an error, whatever it quotes.
std::string one_line(std::string s) {
  for (char& c : s) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return s;
}

/// What every rank sets up: the options, the input's samples and (rank 0) the outputs.
struct setup {
  extract_arguments a;
  std::shared_ptr<const volume> data, field;
  std::string input;
  double iso = 0.0;
  std::optional<detail::atomic_output> mesh_out, stats_out, hierarchy_out;
  bool pieces = false;  // -o X.pvtp: each rank writes its piece
  std::optional<detail::atomic_output> piece_out;
  // A chunked input's finest surface: the level in a window holding this rank's planes alone.
  std::optional<plane_window> window;
  // --world: the orientation the input declares; each rank maps its own vertices.
  std::optional<index_to_world> world;
};

/// Rank r's piece of a .pvtp: X_r.vtp beside X.pvtp (the index names it relative to itself).
std::filesystem::path piece_path(const std::filesystem::path& pvtp, int r) {
  return pvtp.parent_path() / (pvtp.stem().string() + "_" + std::to_string(r) + ".vtp");
}

void set_up(setup& s, const std::vector<std::string>& args, int rank, int size) {
  s.a = parse_extract(args, true);
  extract_arguments& a = s.a;
  using kind = refine_goal::kind;
  // Error goals and deadlines are both cuts by error thresholds across ranks (docs/MPI.md).
  // A triangle budget too: the last round whose cut holds at most the budget.
  const bool error_goal = a.options.goal.what == kind::error ||
                          a.options.goal.what == kind::deadline ||
                          a.options.goal.what == kind::budget;
  if (!a.options.deadline_ladder) {
    throw error(
        "--by-priority: under MPI a deadline refines by rounds of falling error thresholds, the "
        "same on every rank");
  }
  if (a.hierarchy && (!error_goal || a.options.goal.what == kind::budget)) {
    throw error("under MPI, --hierarchy goes only with --error or --time-ms");
  }
  if (error_goal && a.smooth.active()) {
    throw error(
        "under MPI, --error and --time-ms refine the data as read: --smooth is not built across "
        "ranks");
  }
  const std::string ext = detail::lower_extension(*a.output);
  s.pieces = ext == ".pvtp";
  if (error_goal && s.pieces) {
    throw error(std::string(*a.output) +
                ": under MPI, an error cut is meshed whole on rank 0 (write .ply, .obj, .stl, .glb "
                "or .vtp); a .pvtp of one piece per rank is written for --full");
  }
  if (!error_goal && ext != ".ply" && !s.pieces) {
    throw error(std::string(*a.output) +
                ": under MPI, the finest surface is written as .ply, or as .pvtp with one piece "
                "per rank (found another extension)");
  }
  std::optional<raw_layout> raw;
  if (a.dims) raw = raw_layout{*a.dims, *a.type, a.big_endian};
  std::optional<volume_source> source;
  if (!a.demo) source.emplace(*a.input, raw, volume_choice{a.series, a.volume, a.level});
  s.world = asked_world(a.world, source ? &*source : nullptr, a.demo ? "demo" : *a.input);
  if (rank == 0) {
    std::vector<std::filesystem::path> inputs;
    if (source) inputs = source->files();
    std::vector<named_output> outputs{{"-o", *a.output}};
    if (a.stats_json) outputs.push_back({"--stats-json", *a.stats_json});
    if (a.hierarchy) outputs.push_back({"--hierarchy", *a.hierarchy});
    if (s.pieces) {
      for (int r = 0; r < size; ++r) outputs.push_back({"-o (a piece)", piece_path(*a.output, r)});
    }
    refuse_clashing_outputs(inputs, outputs);
    s.mesh_out.emplace(*a.output);
    if (a.stats_json) s.stats_out.emplace(*a.stats_json);
    if (a.hierarchy) s.hierarchy_out.emplace(*a.hierarchy);
  }
  if (s.pieces) s.piece_out.emplace(piece_path(*a.output, rank));
  s.input = a.demo ? std::string("demo: Marschner-Lobb 129^3") : *a.input;
  if (a.demo) {
    s.data = std::make_shared<const volume>(make_demo_volume());
    s.iso = a.iso.value_or(demo_isovalue);
  } else {
    // A mapped input is read only where this rank's share lies (the pages it touches); a chunked
    // one's finest surface decodes only the chunk rows of the rank's planes and the two after
    // them (finest_share's reads).
    if (!error_goal && !a.smooth.active()) s.window = source->window(a.spacing);
    if (s.window) {
      s.data = std::make_shared<const volume>(s.window->field());
    } else {
      s.data = std::make_shared<const volume>(source->read(a.spacing));
    }
    s.iso = *a.iso;
  }
  s.field = smoothed_field(s.data, a.smooth, s.input);
  if (rank == 0) check_float_range(*a.output, *s.data, s.world);
}

/// A threshold as the command reads it back exactly (JSON null for none).
std::string exact_number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

/// Text for an XML attribute value.
std::string xml_attribute(const std::string& text) {
  std::string out;
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

/// Where each rank's vertices begin (ascending: rank r owns [firsts[r], firsts[r + 1])).
std::vector<std::uint64_t> vertex_firsts(std::uint64_t first, int size) {
  std::vector<std::uint64_t> firsts(static_cast<std::size_t>(size));
  MPI_Allgather(&first, 1, MPI_UINT64_T, firsts.data(), 1, MPI_UINT64_T, MPI_COMM_WORLD);
  return firsts;
}

/// For each of `ids` (ascending global vertex ids of later ranks), what its owner has at it:
/// `values(id)` on the owner, 3 doubles (MPI_Alltoallv of ids, then of values). Collective.
std::vector<vec3> ask_owners(const std::vector<std::uint64_t>& ids,
                             const std::vector<std::uint64_t>& firsts,
                             const std::function<vec3(std::uint64_t)>& values) {
  const std::size_t n = firsts.size();
  std::vector<int> ask(n, 0), asked(n, 0), ask_at(n, 0), asked_at(n, 0);
  for (const std::uint64_t id : ids) {
    const auto owner = static_cast<std::size_t>(std::upper_bound(firsts.begin(), firsts.end(), id) -
                                                firsts.begin() - 1);
    ++ask[owner];
  }
  MPI_Alltoall(ask.data(), 1, MPI_INT, asked.data(), 1, MPI_INT, MPI_COMM_WORLD);
  for (std::size_t r = 1; r < n; ++r) {
    ask_at[r] = ask_at[r - 1] + ask[r - 1];
    asked_at[r] = asked_at[r - 1] + asked[r - 1];
  }
  std::vector<std::uint64_t> wanted(static_cast<std::size_t>(asked_at[n - 1] + asked[n - 1]));
  MPI_Alltoallv(ids.data(), ask.data(), ask_at.data(), MPI_UINT64_T, wanted.data(), asked.data(),
                asked_at.data(), MPI_UINT64_T, MPI_COMM_WORLD);
  std::vector<double> answer;
  answer.reserve(3 * wanted.size());
  for (const std::uint64_t id : wanted) {
    const vec3 v = values(id);
    answer.insert(answer.end(), v.begin(), v.end());
  }
  const auto times3 = [](std::vector<int> v) {
    for (int& x : v) x *= 3;
    return v;
  };
  std::vector<double> got(3 * ids.size());
  MPI_Alltoallv(answer.data(), times3(asked).data(), times3(asked_at).data(), MPI_DOUBLE,
                got.data(), times3(ask).data(), times3(ask_at).data(), MPI_DOUBLE, MPI_COMM_WORLD);
  std::vector<vec3> out(ids.size());
  for (std::size_t i = 0; i < ids.size(); ++i)
    out[i] = {got[3 * i], got[3 * i + 1], got[3 * i + 2]};
  return out;
}

/// A rank's share with the ghosts its last cubes name (the next ranks' vertices, asked of their
/// owners), ids local to the piece: the share's vertices [0, own), then the ghosts, whose global
/// ids go into `ghosts` (ascending). `mine` holds the share's mesh with global ids, its own
/// vertices being [first, first + own).
triangle_mesh piece_with_ghosts(triangle_mesh&& mine, std::uint64_t first, std::uint64_t own,
                                const std::vector<std::uint64_t>& firsts,
                                std::vector<std::uint64_t>& ghosts) {
  const std::uint64_t end = first + own;
  ghosts.clear();
  for (const auto& t : mine.triangles) {
    for (const std::uint32_t id : t) {
      if (id < first) throw error("a piece names a vertex of an earlier rank");
      if (id >= end) ghosts.push_back(id);
    }
  }
  std::sort(ghosts.begin(), ghosts.end());
  ghosts.erase(std::unique(ghosts.begin(), ghosts.end()), ghosts.end());
  const std::vector<vec3> got = ask_owners(ghosts, firsts, [&](std::uint64_t id) {
    if (id < first || id >= end) throw error("a rank asked for a vertex not here");
    return mine.vertices[static_cast<std::size_t>(id - first)];
  });
  triangle_mesh piece;
  piece.vertices = std::move(mine.vertices);
  piece.vertices.insert(piece.vertices.end(), got.begin(), got.end());
  piece.triangles = std::move(mine.triangles);
  for (auto& t : piece.triangles) {
    for (std::uint32_t& id : t) {
      id =
          id < end
              ? static_cast<std::uint32_t>(id - first)
              : static_cast<std::uint32_t>(
                    own + static_cast<std::uint64_t>(
                              std::lower_bound(ghosts.begin(), ghosts.end(), id) - ghosts.begin()));
    }
  }
  return piece;
}

/// Vertex normals of a piece (piece_with_ghosts()) as one process computes them for the whole
/// surface: the gradient's where it has a direction; where it vanishes, the sum of the normals of
/// the triangles around the vertex in the whole surface's order, which ranks before this one
/// began (their last cubes name this rank's first vertices). Those sums go from rank to rank in
/// order (small: the vertices whose gradient vanishes), so each is added to in the one process's
/// order, bit for bit. Then the ghosts' normals are asked of their owners. Collective.
void add_piece_normals(triangle_mesh& piece, std::uint64_t first, std::uint64_t own,
                       const std::vector<std::uint64_t>& ghosts,
                       const std::vector<std::uint64_t>& firsts, const volume& field,
                       const parallel_loop& loop, int rank, int size) {
  std::vector<std::uint64_t> global(piece.vertices.size());
  for (std::uint64_t k = 0; k < own; ++k) global[static_cast<std::size_t>(k)] = first + k;
  for (std::size_t i = 0; i < ghosts.size(); ++i) {
    global[static_cast<std::size_t>(own) + i] = ghosts[i];
  }
  constexpr int tag_carry = 5;
  std::vector<detail::normal_partial> carried;
  if (rank > 0) detail::receive_records(MPI_COMM_WORLD, carried, rank - 1, tag_carry);
  carried = detail::add_share_normals(
      piece, global, field, carried,
      [first, own](std::uint64_t id) { return id >= first && id < first + own; }, loop);
  if (rank + 1 < size) {
    detail::send_records(MPI_COMM_WORLD, carried, 0, carried.size(), rank + 1, tag_carry);
  } else if (!carried.empty()) {
    throw error("vertex normals were carried past the last rank");
  }
  const std::vector<vec3> theirs = ask_owners(ghosts, firsts, [&](std::uint64_t id) {
    if (id < first || id >= first + own) throw error("a rank asked for a normal not here");
    return piece.normals[static_cast<std::size_t>(id - first)];
  });
  std::copy(theirs.begin(), theirs.end(), piece.normals.begin() + static_cast<std::ptrdiff_t>(own));
}

/// The .pvtp index of `size` pieces (X_r.vtp beside it): positions, and normals when asked.
std::string pvtp_index(const std::filesystem::path& pvtp, int size, bool normals) {
  std::string xml =
      "<?xml version=\"1.0\"?>\n<VTKFile type=\"PPolyData\" version=\"0.1\" "
      "byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<PPolyData GhostLevel=\"0\">\n";
  if (normals) {
    xml +=
        "<PPointData Normals=\"Normals\">\n<PDataArray type=\"Float32\" Name=\"Normals\" "
        "NumberOfComponents=\"3\"/>\n</PPointData>\n";
  }
  xml +=
      "<PPoints>\n<PDataArray type=\"Float32\" Name=\"Points\" NumberOfComponents=\"3\"/>\n"
      "</PPoints>\n";
  for (int r = 0; r < size; ++r) {
    xml += "<Piece Source=\"" + xml_attribute(piece_path(pvtp, r).filename().string()) + "\"/>\n";
  }
  xml += "</PPolyData>\n</VTKFile>\n";
  return xml;
}

/// An error-driven cut across ranks (docs/MPI.md): each rank builds the range data's pieces of
/// its planes, the ranks copy them to each other (every rank then holds the one process's range
/// data), each rank finds and computes the splits centred in its planes, and rank 0 meshes them
/// and writes the mesh. A deadline (--time-ms) takes rounds of falling thresholds, each half the
/// largest error still waiting on any rank, until the deadline or the error-0 cut; the cut is the
/// last round that every rank finished.
int run_error_cut(setup& s, int rank, int size, unsigned threads,
                  std::chrono::steady_clock::time_point t0) {
  using clock = std::chrono::steady_clock;
  const auto ms_since = [](clock::time_point t) {
    return std::chrono::duration<double, std::milli>(clock::now() - t).count();
  };
  const bool timed = s.a.options.goal.what == refine_goal::kind::deadline;
  // The budget starts with the samples mapped and the outputs made, as in one process.
  const clock::time_point until = deadline_after(clock::now(), s.a.time_budget);
  const auto passed = [timed, until] { return timed && clock::now() >= until; };
  const volume& field = *s.field;
  detail::distributed_cut cut(MPI_COMM_WORLD, 0, field, s.iso);
  // A deadline may end the build: then every rank gives the root surface.
  const bool built = cut.build_ranges(threads, timed ? std::function<bool()>(passed) : nullptr);
  const double ranges_ms = ms_since(t0);
  // A fault for the tests: this rank dies here, after the others have its pieces.
  if (env_int("PROGISO_MPI_FAULT_RANK") == rank) std::raise(SIGKILL);
  const bool budget = s.a.options.goal.what == refine_goal::kind::budget;
  const bool in_rounds = timed || budget;
  if (built && !in_rounds) cut.round(s.a.options.goal.max_error, threads);
  // Rounds until the error-0 cut, until some rank is out of time, or until a round's cut passes
  // the budget; the cut is the last round every rank finished (and within the budget). A budget
  // gathers each round on rank 0, which meshes it, keeps the mesh and says whether it passed.
  triangle_mesh kept;
  double kept_error = std::numeric_limits<double>::infinity();
  int kept_rounds = 0;
  std::uint64_t kept_splits = 0;
  if (budget && rank == 0) kept = cut.mesh(threads);  // the root surface
  while (in_rounds) {
    const std::optional<double> next = cut.next_threshold(0.0, passed());
    if (!next || !cut.round(*next, threads, passed)) break;
    if (!budget) continue;
    cut.gather();
    int over = 0;
    if (rank == 0) {
      triangle_mesh m = cut.mesh(threads);
      over = m.triangles.size() > s.a.options.goal.max_elements ? 1 : 0;
      if (over == 0) kept = std::move(m);
    }
    MPI_Bcast(&over, 1, MPI_INT, 0, MPI_COMM_WORLD);
    if (over != 0) break;
    kept_error = cut.threshold();
    kept_rounds = cut.rounds();
    kept_splits = cut.gathered_splits();
  }
  cut.gather();
  const double max_error = budget ? kept_error : cut.threshold();
  const int rounds = budget ? kept_rounds : timed ? cut.rounds() : 0;
  const double splits_ms = ms_since(t0);
  if (rank != 0) return 0;
  const hierarchy& hier = cut.hier();
  // A budget's cut may be a round short of what was gathered.
  const std::uint64_t splits = budget ? kept_splits : cut.gathered_splits();
  std::vector<const detail::share_splits*> pieces;
  for (const auto& p : cut.pieces()) pieces.push_back(p.get());
  // The stream only when asked for: the mesh is made from the records as they came.
  if (s.hierarchy_out) {
    detail::write_cut_stream(
        [&s](std::span<const std::byte> b) { s.hierarchy_out->write(b.data(), b.size()); }, hier,
        field, s.iso, pieces);
  }
  triangle_mesh mesh = budget ? std::move(kept) : cut.mesh(threads);
  if (s.a.options.normals) {
    scheduler::run_on_threads(threads, [&](const parallel_loop& loop, std::size_t) {
      add_vertex_normals(mesh, field, loop);
    });
  }
  if (s.world) to_world(mesh, *s.data, *s.world);
  detail::write_mesh_to(*s.mesh_out, mesh);
  const double total_ms = ms_since(t0);
  if (s.stats_out) {
    std::ostringstream o;
    o << "{\n  \"input\": \"" << json_escape(s.input) << "\",\n  \"dims\": [" << field.dims()[0]
      << ", " << field.dims()[1] << ", " << field.dims()[2]
      << "],\n  \"isovalue\": " << json_number(s.iso) << ",\n  \"mode\": \""
      << (timed    ? "time"
          : budget ? "triangles"
                   : "error")
      << "\",\n  \"max_error\": " << exact_number(max_error) << ",\n  \"rounds\": " << rounds
      << ",\n  \"path\": \"shares\",\n  \"ranks\": " << size
      << ",\n  \"threads_per_rank\": " << threads << ",\n  \"splits\": " << splits
      << ",\n  \"triangles\": " << mesh.triangles.size()
      << ",\n  \"vertices\": " << mesh.vertices.size()
      << ",\n  \"rank0_ranges_ms\": " << json_number(ranges_ms)
      << ",\n  \"rank0_splits_ms\": " << json_number(splits_ms)
      << ",\n  \"total_ms\": " << json_number(total_ms) << "\n}\n";
    s.stats_out->write(o.str());
  }
  s.mesh_out->finish();
  if (s.stats_out) s.stats_out->finish();
  if (s.hierarchy_out) s.hierarchy_out->finish();
  s.mesh_out->publish();
  if (s.stats_out) s.stats_out->publish();
  if (s.hierarchy_out) s.hierarchy_out->publish();
  const std::string which = std::isinf(max_error) ? std::string("the root surface")
                                                  : "the cut of error > " + exact_number(max_error);
  std::printf(
      "progiso: %zu triangles, %zu vertices; %llu splits, %s%s on %d ranks (%zu voxels); range "
      "data %.1f ms, splits %.1f ms, total %.1f ms; wrote %s\n",
      mesh.triangles.size(), mesh.vertices.size(), static_cast<unsigned long long>(splits),
      which.c_str(),
      in_rounds ? (" after " + std::to_string(rounds) + " rounds" +
                   (timed ? " by the deadline" : " within the budget"))
                      .c_str()
                : "",
      size, field.voxel_count(), ranges_ms, splits_ms, total_ms, s.a.output->c_str());
  return 0;
}

}  // namespace

int run_mpi_extract(const std::vector<std::string>& args) {
  const mpi_session mpi;
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();

  // ---- Set-up, agreed on: the lowest rank that failed says why, every rank returns 2.
  setup s;
  std::string failure;
  bool help = false;
  try {
    set_up(s, args, rank, size);
    help = s.a.help;
  } catch (const error& e) {
    failure = e.what();
  } catch (const std::bad_alloc&) {
    failure = "out of memory";
  }
  int first_failed = failure.empty() ? size : rank;
  MPI_Allreduce(MPI_IN_PLACE, &first_failed, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  if (first_failed < size) {
    if (rank == first_failed) std::cerr << "progiso: error: " << one_line(failure) << "\n";
    return 2;
  }
  if (help) {
    if (rank == 0) std::cout << usage_text;
    return 0;
  }

  try {
    const unsigned threads =
        s.a.threads != 0 ? s.a.threads
                         : std::max(1u, static_cast<unsigned>(scheduler::default_concurrency()) /
                                            static_cast<unsigned>(size));
    if (s.a.options.goal.what != refine_goal::kind::full) {
      return run_error_cut(s, rank, size, threads, t0);
    }
    const volume& field = *s.field;
    const std::int64_t nz = field.dims()[2];
    const std::int64_t z_begin = nz * rank / size, z_end = nz * (rank + 1) / size;
    // The share meshed once, its ids local (from 0): the counts are known after, and the ids
    // moved by the ranks before this one's counts once MPI_Exscan has them. A triangle of the
    // share's last cubes names the next rank's first vertices as local ids past this share's
    // own, which the same move makes theirs.
    const bool pvtp = s.pieces;
    triangle_mesh mine;                 // .pvtp: the share's vertices and triangles
    std::vector<char> vertices, faces;  // .ply: the share's records
    std::uint64_t counts[2] = {0, 0}, first[2] = {0, 0}, totals[2] = {0, 0};
    const std::string name = *s.a.output;
    // With normals the share is held whole: they need the ghosts' positions, and are mapped to
    // the world with the positions after.
    const bool normals = s.a.options.normals;
    const bool hold = pvtp || normals;
    const detail::finest_piece add = [&](triangle_mesh& piece, std::uint64_t) {
      if (s.world && !normals) to_world(piece, *s.data, *s.world);
      counts[0] += piece.vertices.size();
      counts[1] += piece.triangles.size();
      if (hold) {
        mine.vertices.insert(mine.vertices.end(), piece.vertices.begin(), piece.vertices.end());
        mine.triangles.insert(mine.triangles.end(), piece.triangles.begin(), piece.triangles.end());
      } else {
        detail::append_ply_records(name, piece, vertices, faces);
      }
    };
    scheduler::run_on_threads(threads, [&](const parallel_loop& loop, std::size_t parts) {
      if (s.window) {
        // A chunked level: the share a window of planes at a time.
        finest_in_windows(
            *s.window, s.iso, loop, parts, add,
            [&counts] {
              return std::array<std::uint64_t, 2>{counts[0], counts[1]};
            },
            z_begin, z_end);
      } else {
        detail::finest_surface_pieces(field, s.iso, loop, parts, {}, add, 0,
                                      {z_begin, z_end, 0, 0});
      }
    });
    MPI_Exscan(counts, first, 2, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
    if (rank == 0) first[0] = first[1] = 0;  // MPI_Exscan leaves rank 0's undefined
    MPI_Allreduce(counts, totals, 2, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
    if (totals[0] > 2147483647u) {
      // Every rank knows the totals: one says it, all end alike.
      if (rank == 0) {
        std::cerr << "progiso: error: " << *s.a.output
                  << ": PLY int indices allow at most 2147483647 vertices, the surface has "
                  << totals[0] << "\n";
      }
      return 2;
    }
    // A fault for the tests: this rank dies here, after the others have its counts.
    if (env_int("PROGISO_MPI_FAULT_RANK") == rank) std::raise(SIGKILL);
    const double meshed = std::chrono::duration<double>(clock::now() - t0).count();
    triangle_mesh piece;
    std::vector<std::uint64_t> ghosts;
    if (hold) {
      for (auto& t : mine.triangles) {
        for (std::uint32_t& id : t) id += static_cast<std::uint32_t>(first[0]);
      }
      const std::vector<std::uint64_t> firsts = vertex_firsts(first[0], size);
      piece = piece_with_ghosts(std::move(mine), first[0], counts[0], firsts, ghosts);
      if (normals) {
        scheduler::run_on_threads(threads, [&](const parallel_loop& loop, std::size_t) {
          add_piece_normals(piece, first[0], counts[0], ghosts, firsts, field, loop, rank, size);
        });
        if (s.world) to_world(piece, *s.data, *s.world);
      }
    }
    if (pvtp) {
      detail::write_vtp_to(*s.piece_out, piece);
      s.piece_out->finish();
      // Every piece is written before any is published, and every one published before the
      // index that names them.
      MPI_Barrier(MPI_COMM_WORLD);
      s.piece_out->publish();
      MPI_Barrier(MPI_COMM_WORLD);
      if (rank != 0) return 0;
      s.mesh_out->write(pvtp_index(name, size, normals));
    } else {
      if (hold) {
        // The share's own vertices and its triangles, their ids global again.
        const auto own = static_cast<std::size_t>(counts[0]);
        triangle_mesh records;
        records.vertices.assign(piece.vertices.begin(),
                                piece.vertices.begin() + static_cast<std::ptrdiff_t>(own));
        records.normals.assign(piece.normals.begin(),
                               piece.normals.begin() + static_cast<std::ptrdiff_t>(own));
        records.triangles = std::move(piece.triangles);
        for (auto& t : records.triangles) {
          for (std::uint32_t& id : t) {
            id = static_cast<std::uint32_t>(id < own ? first[0] + id : ghosts[id - own]);
          }
        }
        detail::append_ply_records(name, records, vertices, faces);
      } else {
        offset_ply_faces(faces, static_cast<std::uint32_t>(first[0]));
      }
      if (rank != 0) {
        detail::send_bytes(MPI_COMM_WORLD, vertices.data(), vertices.size(), 0, 1);
        detail::send_bytes(MPI_COMM_WORLD, faces.data(), faces.size(), 0, 2);
        return 0;
      }
      // Rank 0: the header, every rank's vertices, then every rank's faces.
      detail::atomic_output& out = *s.mesh_out;
      out.write(detail::ply_header_text(totals[0], totals[1], normals));
      const auto write = [&out](const char* p, std::size_t n) { out.write(p, n); };
      out.write(vertices.data(), vertices.size());
      for (int r = 1; r < size; ++r) detail::receive_bytes(MPI_COMM_WORLD, r, 1, write);
      out.write(faces.data(), faces.size());
      for (int r = 1; r < size; ++r) detail::receive_bytes(MPI_COMM_WORLD, r, 2, write);
    }
    detail::atomic_output& out = *s.mesh_out;
    const double seconds = std::chrono::duration<double>(clock::now() - t0).count();
    if (s.stats_out) {
      std::ostringstream o;
      o << "{\n  \"input\": \"" << json_escape(s.input) << "\",\n  \"dims\": [" << field.dims()[0]
        << ", " << field.dims()[1] << ", " << field.dims()[2]
        << "],\n  \"isovalue\": " << json_number(s.iso)
        << ",\n  \"mode\": \"full\",\n  \"path\": \"finest\",\n  \"pieces\": "
        << (s.pieces ? "true" : "false") << ",\n  \"ranks\": " << size
        << ",\n  \"threads_per_rank\": " << threads << ",\n  \"triangles\": " << totals[1]
        << ",\n  \"vertices\": " << totals[0]
        << ",\n  \"rank0_mesh_ms\": " << json_number(meshed * 1e3);
      // A chunked input: the sample bytes rank 0 held (its planes' chunk rows, not the level).
      if (s.window) o << ",\n  \"rank0_window_bytes\": " << s.window->peak_bytes();
      o << ",\n  \"total_ms\": " << json_number(seconds * 1e3) << "\n}\n";
      s.stats_out->write(o.str());
    }
    out.finish();
    if (s.stats_out) s.stats_out->finish();
    out.publish();
    if (s.stats_out) s.stats_out->publish();
    std::printf(
        "progiso: %llu triangles, %llu vertices (%zu voxels); finest surface on %d ranks, %.1f "
        "ms; wrote %s\n",
        static_cast<unsigned long long>(totals[1]), static_cast<unsigned long long>(totals[0]),
        field.voxel_count(), size, seconds * 1e3, name.c_str());
    return 0;
  } catch (const error& e) {
    std::cerr << "progiso: error: rank " << rank << ": " << one_line(e.what()) << "\n";
  } catch (const std::bad_alloc&) {
    std::cerr << "progiso: error: rank " << rank << ": out of memory\n";
  }
  // One rank's failure mid-run: the others may wait on it, so the job ends here.
  std::cerr.flush();
  MPI_Abort(MPI_COMM_WORLD, 2);
  return 2;
}

#endif

}  // namespace progiso::cli
