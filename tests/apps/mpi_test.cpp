// `mpirun -np N progiso extract … --full | --error E` (apps/progiso/mpi_extract.hpp): 1, 2 and 4
// ranks, over subscribed on this machine, must write the single process's mesh byte for byte (on
// a shared volume, whose surface crosses every rank's share, and on a raw file of a size that N
// does not divide), the finest surface and error-driven cuts alike, and a deadline gives the
// single process's cut of the threshold its last common round reached; an error cut's hierarchy
// stream cuts to the same mesh; a Zarr or Imaris level's ranks each decode only the chunk rows of
// their planes (and the two planes after them), to the same file; --world maps every output as one
// process does (a mirrored, sheared NRRD); a .pvtp holds one piece per rank, which VTK's reader
// (ParaView's) reads as the single process's triangles; a goal the ranks cannot share yet, and a
// missing input, give one error line and a failing status; a rank killed mid-run ends the job (no
// hang) without an output or a temporary left behind. Skipped where the command was built without
// MPI or mpiexec is missing.
#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <string>
#include <string_view>
#include <vector>

#include <gtest/gtest.h>

#include "support/bounded_run.hpp"
#include "support/io_test_helpers.hpp"
#include "support/scratch_dir.hpp"
#include "support/test_data.hpp"
#include "support/zarr_files.hpp"

namespace progiso {
namespace {

namespace fs = std::filesystem;

bool have_mpi() { return std::string_view(PROGISO_MPIEXEC).size() > 0; }

/// mpiexec's arguments for `ranks` ranks of the command with `args`.
std::vector<std::string> mpi_args(int ranks, const std::vector<std::string>& args) {
  std::vector<std::string> all{"--allow-run-as-root", "--oversubscribe", "-np",
                               std::to_string(ranks), PROGISO_CLI};
  all.insert(all.end(), args.begin(), args.end());
  return all;
}

class Mpi : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!have_mpi()) GTEST_SKIP() << "the command was built without MPI, or mpiexec is missing";
    // Containers often forbid the cross-memory attach of Open MPI's shared-memory transport.
    setenv("OMPI_MCA_btl_vader_single_copy_mechanism", "none", 1);
  }
  test::scratch_dir dir_{"progiso-mpi-"};
  test::scratch_dir runs_{"progiso-mpi-runs-"};

  /// What one process writes for the command `args(out)`.
  std::string one_process_file(
      const std::function<std::vector<std::string>(const fs::path&)>& args) {
    const fs::path single = dir_.path() / "single.ply";
    const test::bounded_result one = test::run_bounded(PROGISO_CLI, args(single), runs_.path());
    EXPECT_EQ(one.status, 0) << one.err;
    return test::read_whole(single);
  }

  /// The command `args(out)` on each of `ranks` ranks writes `want` (one process's file).
  void expect_ranks_write(const std::string& want,
                          const std::function<std::vector<std::string>(const fs::path&)>& args,
                          std::initializer_list<int> ranks) {
    for (const int n : ranks) {
      SCOPED_TRACE(std::to_string(n) + " ranks");
      const fs::path out = dir_.path() / "mpi.ply";
      const test::bounded_result r =
          test::run_bounded(PROGISO_MPIEXEC, mpi_args(n, args(out)), runs_.path());
      ASSERT_EQ(r.status, 0) << r.err;
      EXPECT_TRUE(test::read_whole(out) == want) << "another file than one process's";
    }
  }

  /// A NRRD of 31 × 29 × 37 u8 samples `f(x, y, z)` whose space directions turn, shear and mirror
  /// the grid (det < 0: windings reverse), its data in a raw file beside it.
  fs::path turned_nrrd(const std::string& name, const std::function<int(int, int, int)>& f) {
    std::string bytes;
    for (int z = 0; z < 37; ++z) {
      for (int y = 0; y < 29; ++y) {
        for (int x = 0; x < 31; ++x) bytes += static_cast<char>(f(x, y, z));
      }
    }
    test::write_file(dir_.path() / (name + ".raw"), bytes);
    const fs::path nhdr = dir_.path() / (name + ".nhdr");
    test::write_file(nhdr,
                     "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 31 29 37\n"
                     "space: left-posterior-superior\n"
                     "space directions: (0,0.9,0.1) (1.1,0,0) (0,0.2,-1.2)\n"
                     "space origin: (10,-20,30)\nencoding: raw\ndata file: " +
                         name + ".raw\n");
    return nhdr;
  }

  /// The command `args(out)` into a .vtp by one process and into a .pvtp by 3 ranks: VTK's
  /// readers give the same oriented triangles (with their normals, when written).
  void expect_pvtp_reads_as_one_process(
      const std::function<std::vector<std::string>(const fs::path&)>& args) {
    const fs::path whole = dir_.path() / "whole.vtp";
    ASSERT_EQ(test::run_bounded(PROGISO_CLI, args(whole), runs_.path()).status, 0);
    const fs::path pvtp = dir_.path() / "pieces.pvtp";
    const test::bounded_result r =
        test::run_bounded(PROGISO_MPIEXEC, mpi_args(3, args(pvtp)), runs_.path());
    ASSERT_EQ(r.status, 0) << r.err;
    const test::bounded_result check =
        test::run_bounded(PROGISO_VTK_PYTHON,
                          {std::string(PROGISO_SOURCE_DIR) + "/tests/apps/pvtp_check.py",
                           pvtp.string(), whole.string(), "3"},
                          runs_.path());
    EXPECT_EQ(check.status, 0) << check.out << check.err;
  }
};

// Inputs whose surfaces cross every rank's share: a raw file of 37 planes (no rank count here
// divides it), a gyroid-like field, and hipip when the shared data is there.
struct mpi_input {
  fs::path file;
  std::string dims, iso, error;
};

std::vector<mpi_input> mpi_inputs(const fs::path& dir) {
  std::vector<mpi_input> inputs;
  const fs::path raw = dir / "waves.raw";
  std::string bytes;
  for (int z = 0; z < 37; ++z) {
    for (int y = 0; y < 29; ++y) {
      for (int x = 0; x < 31; ++x) {
        const int v = (x * 7 + y * 11 + z * 13 + (x * y) % 17 + (y * z) % 19) % 256;
        bytes += static_cast<char>(v);
      }
    }
  }
  test::write_file(raw, bytes);
  inputs.push_back({raw, "31,29,37", "127.5", "6"});
  if (const auto data = test::shared_data_dir()) {
    inputs.push_back({*data / "hipip_68x68x68_uint8.raw", "68,68,68", "60", "2"});
  }
  return inputs;
}

TEST_F(Mpi, one_to_four_ranks_write_the_single_process_mesh_byte_for_byte) {
  for (const mpi_input& in : mpi_inputs(dir_.path())) {
    // The finest surface, and error cuts (one that leaves most of the surface coarse).
    for (const std::string goal : {"--full", "--error"}) {
      SCOPED_TRACE(in.file.filename().string() + " " + goal);
      const auto args = [&](const std::string& out) {
        std::vector<std::string> a{"extract", in.file.string(), "--dims", in.dims, "--type",
                                   "u8",      "--iso",          in.iso,   goal};
        if (goal == "--error") a.push_back(in.error);
        a.insert(a.end(), {"-o", (dir_.path() / out).string(), "--threads", "1"});
        return a;
      };
      const test::bounded_result single =
          test::run_bounded(PROGISO_CLI, args("single.ply"), runs_.path());
      ASSERT_EQ(single.status, 0) << single.err;
      const std::string want = test::read_whole(dir_.path() / "single.ply");
      ASSERT_GT(want.size(), 1000U);
      for (const int ranks : {1, 2, 3, 4}) {  // 3: a gather tree that is not whole
        SCOPED_TRACE(std::to_string(ranks) + " ranks");
        const std::string out = "mpi" + std::to_string(ranks) + ".ply";
        const test::bounded_result r =
            test::run_bounded(PROGISO_MPIEXEC, mpi_args(ranks, args(out)), runs_.path());
        ASSERT_EQ(r.status, 0) << r.err;
        EXPECT_TRUE(test::read_whole(dir_.path() / out) == want)
            << "another file than one process's";
        EXPECT_NE(r.out.find("on " + std::to_string(ranks) + " ranks"), std::string::npos) << r.out;
        fs::remove(dir_.path() / out);
      }
    }
  }
}

TEST_F(Mpi, an_error_cuts_hierarchy_stream_cuts_to_the_same_mesh) {
  const mpi_input in = mpi_inputs(dir_.path()).front();
  const fs::path pgh = dir_.path() / "cut.pgh";
  const test::bounded_result r = test::run_bounded(
      PROGISO_MPIEXEC,
      mpi_args(3, {"extract", in.file.string(), "--dims", in.dims, "--type", "u8", "--iso", in.iso,
                   "--error", in.error, "-o", (dir_.path() / "mpi.ply").string(), "--hierarchy",
                   pgh.string(), "--threads", "1"}),
      runs_.path());
  ASSERT_EQ(r.status, 0) << r.err;
  const test::bounded_result c = test::run_bounded(
      PROGISO_CLI, {"cut", pgh.string(), "-o", (dir_.path() / "cut.ply").string()}, runs_.path());
  ASSERT_EQ(c.status, 0) << c.err;
  const std::string want = test::read_whole(dir_.path() / "mpi.ply");
  ASSERT_GT(want.size(), 1000U);
  EXPECT_TRUE(test::read_whole(dir_.path() / "cut.ply") == want);
}

/// The text of a JSON number field ("null" included), as the command wrote it.
std::string json_field(const std::string& json, const std::string& name) {
  const std::string key = "\"" + name + "\": ";
  const std::size_t at = json.find(key);
  if (at == std::string::npos) return "";
  const std::size_t from = at + key.size();
  return json.substr(from, json.find_first_of(",\n}", from) - from);
}

/// Runs `goal` (a deadline or a budget: rounds of thresholds) on `ranks` ranks, checks that the
/// file is one process's cut of the error goal at the threshold the statistics report (none: the
/// root surface) and returns the statistics.
std::string expect_cut_of_its_threshold(const fs::path& dir, const fs::path& runs,
                                        const mpi_input& in, const std::vector<std::string>& goal,
                                        int ranks) {
  const auto args = [&](const std::vector<std::string>& g, const std::string& out) {
    std::vector<std::string> a{"extract", in.file.string(), "--dims", in.dims, "--type",
                               "u8",      "--iso",          in.iso};
    a.insert(a.end(), g.begin(), g.end());
    a.insert(a.end(), {"-o", (dir / out).string(), "--threads", "1", "--stats-json",
                       (dir / (out + ".json")).string()});
    return a;
  };
  const test::bounded_result r =
      test::run_bounded(PROGISO_MPIEXEC, mpi_args(ranks, args(goal, "rounds.ply")), runs);
  EXPECT_EQ(r.status, 0) << r.err;
  const std::string stats = test::read_whole(dir / "rounds.ply.json");
  const std::string reached = json_field(stats, "max_error");
  EXPECT_FALSE(reached.empty()) << stats;
  // The same cut by one process: an error goal at the threshold reached (none: no split).
  const test::bounded_result one = test::run_bounded(
      PROGISO_CLI, args({"--error", reached == "null" ? "1e300" : reached}, "one.ply"), runs);
  EXPECT_EQ(one.status, 0) << one.err;
  EXPECT_TRUE(test::read_whole(dir / "rounds.ply") == test::read_whole(dir / "one.ply"))
      << "not the cut of error > " << reached;
  return stats;
}

TEST_F(Mpi, a_deadline_gives_the_single_process_cut_of_the_last_threshold_every_rank_reached) {
  for (const mpi_input& in : mpi_inputs(dir_.path())) {
    // No time (the root surface), some (whatever round it allows), ample (the error-0 cut).
    for (const char* ms : {"0", "15", "100000"}) {
      for (const int ranks : {1, 2, 4}) {
        SCOPED_TRACE(in.file.filename().string() + ", --time-ms " + ms + ", " +
                     std::to_string(ranks) + " ranks");
        const std::string stats =
            expect_cut_of_its_threshold(dir_.path(), runs_.path(), in, {"--time-ms", ms}, ranks);
        if (std::string(ms) == "100000") {
          EXPECT_NE(json_field(stats, "max_error"), "null");
          EXPECT_GT(std::stoi(json_field(stats, "rounds")), 3) << stats;
        }
      }
    }
  }
}

TEST_F(Mpi, a_triangle_budget_gives_the_single_process_cut_of_the_last_round_within_it) {
  for (const mpi_input& in : mpi_inputs(dir_.path())) {
    // Below the root surface's triangles, a few rounds' worth, and more than the finest cut.
    for (const std::uint64_t budget : {1ull, 5000ull, 100000000ull}) {
      std::string first;
      for (const int ranks : {1, 2, 4}) {
        SCOPED_TRACE(in.file.filename().string() + ", --max-triangles " + std::to_string(budget) +
                     ", " + std::to_string(ranks) + " ranks");
        const std::string stats = expect_cut_of_its_threshold(
            dir_.path(), runs_.path(), in, {"--max-triangles", std::to_string(budget)}, ranks);
        EXPECT_EQ(json_field(stats, "mode"), "\"triangles\"") << stats;
        const std::uint64_t triangles = std::stoull(json_field(stats, "triangles"));
        if (json_field(stats, "max_error") != "null") {
          EXPECT_LE(triangles, budget) << stats;
        }
        if (budget == 1) {
          EXPECT_EQ(json_field(stats, "max_error"), "null") << stats;
        }
        if (budget == 100000000ull) {
          EXPECT_GT(std::stoi(json_field(stats, "rounds")), 3) << stats;
        }
        // The same file on every rank count.
        const std::string file = test::read_whole(dir_.path() / "rounds.ply");
        if (first.empty()) first = file;
        EXPECT_TRUE(file == first);
      }
    }
  }
}

/// The NumberOfPolys of a .vtp's piece (its header says it before the appended data).
std::uint64_t polys_of(const fs::path& vtp) {
  const std::string text = test::read_whole(vtp);
  const std::string key = "NumberOfPolys=\"";
  const std::size_t at = text.find(key);
  if (at == std::string::npos) return 0;
  return std::stoull(text.substr(at + key.size()));
}

TEST_F(Mpi, each_rank_decodes_only_the_chunk_rows_of_its_planes_of_a_zarr_or_imaris_level) {
  // 61 planes (no rank count here divides them) of 120 × 110 in chunks of 4 planes, two per row.
  const fs::path zarr = dir_.path() / "w.zarr";
  const fs::path raw = dir_.path() / "w.raw";
  const auto value = [](std::int64_t x, std::int64_t y, std::int64_t z) {
    return static_cast<std::uint8_t>((x * 7 + y * 11 + z * 13 + (x * y) % 17 + (y * z) % 19) % 256);
  };
  test::write_zarr_array(zarr, {120, 110, 61}, {60, 110, 4}, "|u1", 1,
                         [&](std::int64_t x, std::int64_t y, std::int64_t z, std::byte* out) {
                           *out = static_cast<std::byte>(value(x, y, z));
                         });
  std::string bytes;
  for (std::int64_t z = 0; z < 61; ++z) {
    for (std::int64_t y = 0; y < 110; ++y) {
      for (std::int64_t x = 0; x < 120; ++x) bytes += static_cast<char>(value(x, y, z));
    }
  }
  test::write_file(raw, bytes);
  const test::bounded_result single =
      test::run_bounded(PROGISO_CLI,
                        {"extract", raw.string(), "--dims", "120,110,61", "--type", "u8", "--iso",
                         "127.5", "--full", "-o", (dir_.path() / "single.ply").string()},
                        runs_.path());
  ASSERT_EQ(single.status, 0) << single.err;
  const std::string want = test::read_whole(dir_.path() / "single.ply");
  ASSERT_GT(want.size(), 1000U);
  // The same samples as an Imaris file (h5py; chunks of 4 planes, gzip), read by HDF5 children.
  std::vector<fs::path> inputs{zarr};
  if (!std::string_view(PROGISO_H5PY_PYTHON).empty()) {
    const fs::path script = dir_.path() / "ims.py";
    test::write_file(script, R"(import sys, h5py, numpy as np
def text(g, k, v): g.attrs.create(k, np.array(list(v), dtype='|S1'))
v = np.fromfile(sys.argv[1], np.uint8).reshape(61, 110, 120)
with h5py.File(sys.argv[2], 'w') as f:
    text(f, 'ImarisDataSet', 'ImarisDataSet')
    i = f.create_group('DataSetInfo/Image')
    for q, n in enumerate((120, 110, 61)):
        text(i, 'ExtMin%d' % q, '0'); text(i, 'ExtMax%d' % q, str(n))
    g = f.create_group('DataSet/ResolutionLevel 0/TimePoint 0/Channel 0')
    for a, n in zip('XYZ', (120, 110, 61)): text(g, 'ImageSize' + a, str(n))
    g.create_dataset('Data', data=v, chunks=(4, 110, 120), compression='gzip')
)");
    const fs::path ims = dir_.path() / "w.ims";
    ASSERT_EQ(test::run_bounded(PROGISO_H5PY_PYTHON, {script.string(), raw.string(), ims.string()},
                                runs_.path())
                  .status,
              0);
    inputs.push_back(ims);
  }
  const std::uint64_t plane = 120 * 110;
  for (const fs::path& input : inputs) {
    // One process's file: the raw samples' for the Zarr array (its geometry is the grid's); for
    // Imaris, whose voxel centres sit half a voxel in, the same command in one process.
    std::string one = want;
    if (input.extension() == ".ims") {
      const fs::path out = dir_.path() / "single_ims.ply";
      ASSERT_EQ(test::run_bounded(
                    PROGISO_CLI,
                    {"extract", input.string(), "--iso", "127.5", "--full", "-o", out.string()},
                    runs_.path())
                    .status,
                0);
      one = test::read_whole(out);
      ASSERT_GT(one.size(), 1000U);
    }
    for (const int ranks : {1, 2, 4}) {
      SCOPED_TRACE(input.filename().string() + ", " + std::to_string(ranks) + " ranks");
      const test::bounded_result r = test::run_bounded(
          PROGISO_MPIEXEC,
          mpi_args(ranks, {"extract", input.string(), "--iso", "127.5", "--full", "--threads", "1",
                           "-o", (dir_.path() / "mpi.ply").string(), "--stats-json",
                           (dir_.path() / "mpi.json").string()}),
          runs_.path());
      ASSERT_EQ(r.status, 0) << r.err;
      EXPECT_TRUE(test::read_whole(dir_.path() / "mpi.ply") == one)
          << "another file than one process's";
      // Rank 0 held its planes and the two after them, rounded out to chunk rows, not the level.
      const std::string stats = test::read_whole(dir_.path() / "mpi.json");
      const std::string held = json_field(stats, "rank0_window_bytes");
      ASSERT_FALSE(held.empty()) << stats;
      const auto planes = static_cast<std::uint64_t>(61 / ranks + 2 + 3 + 1);
      EXPECT_LE(std::stoull(held), planes * plane + 8192) << stats;
      if (ranks == 4) {
        EXPECT_LT(std::stoull(held), 61 * plane / 2) << stats;
      }
    }
  }
}

TEST_F(Mpi, a_pvtp_holds_one_piece_per_rank_that_vtk_reads_as_the_single_process_surface) {
  for (const mpi_input& in : mpi_inputs(dir_.path())) {
    SCOPED_TRACE(in.file.filename().string());
    const auto args = [&](const fs::path& out) {
      return std::vector<std::string>{"extract",    in.file.string(), "--dims", in.dims,  "--type",
                                      "u8",         "--iso",          in.iso,   "--full", "-o",
                                      out.string(), "--threads",      "1"};
    };
    const fs::path whole = dir_.path() / "whole.vtp";
    const test::bounded_result single = test::run_bounded(PROGISO_CLI, args(whole), runs_.path());
    ASSERT_EQ(single.status, 0) << single.err;
    const std::uint64_t triangles = polys_of(whole);
    ASSERT_GT(triangles, 100U);
    for (const int ranks : {1, 2, 4}) {
      SCOPED_TRACE(std::to_string(ranks) + " ranks");
      const fs::path pvtp = dir_.path() / ("pieces" + std::to_string(ranks) + ".pvtp");
      const test::bounded_result r =
          test::run_bounded(PROGISO_MPIEXEC, mpi_args(ranks, args(pvtp)), runs_.path());
      ASSERT_EQ(r.status, 0) << r.err;
      const std::string index = test::read_whole(pvtp);
      std::uint64_t sum = 0;
      for (int k = 0; k < ranks; ++k) {
        const std::string piece = pvtp.stem().string() + "_" + std::to_string(k) + ".vtp";
        EXPECT_NE(index.find("<Piece Source=\"" + piece + "\"/>"), std::string::npos) << index;
        ASSERT_TRUE(fs::exists(dir_.path() / piece)) << piece;
        sum += polys_of(dir_.path() / piece);
      }
      EXPECT_EQ(sum, triangles) << "the pieces' triangles are not the surface's";
      if (std::string_view(PROGISO_VTK_PYTHON).empty()) continue;
      const test::bounded_result check =
          test::run_bounded(PROGISO_VTK_PYTHON,
                            {std::string(PROGISO_SOURCE_DIR) + "/tests/apps/pvtp_check.py",
                             pvtp.string(), whole.string(), std::to_string(ranks)},
                            runs_.path());
      EXPECT_EQ(check.status, 0) << check.out << check.err;
    }
  }
  if (std::string_view(PROGISO_VTK_PYTHON).empty()) {
    GTEST_SKIP() << "the pieces' counts checked; python3 with vtk (python3-vtk9) not found to read "
                    "them as ParaView does";
  }
}

TEST_F(Mpi, world_coordinates_are_the_single_process_ones_in_every_output) {
  const fs::path nhdr = turned_nrrd("w", [](int x, int y, int z) {
    return (x * 7 + y * 11 + z * 13 + (x * y) % 17 + (y * z) % 19) % 256;
  });
  for (const std::vector<std::string>& goal :
       {std::vector<std::string>{"--full"}, std::vector<std::string>{"--error", "6"}}) {
    SCOPED_TRACE(goal[0]);
    const auto args = [&](const fs::path& out) {
      std::vector<std::string> a{"extract", nhdr.string(), "--iso", "127.5", "--world"};
      a.insert(a.end(), goal.begin(), goal.end());
      a.insert(a.end(), {"-o", out.string(), "--threads", "1"});
      return a;
    };
    const std::string want = one_process_file(args);
    ASSERT_GT(want.size(), 1000U);
    // Not the grid's physical coordinates: the map is applied.
    std::vector<std::string> plain = args(dir_.path() / "plain.ply");
    plain.erase(std::find(plain.begin(), plain.end(), "--world"));
    ASSERT_EQ(test::run_bounded(PROGISO_CLI, plain, runs_.path()).status, 0);
    EXPECT_FALSE(test::read_whole(dir_.path() / "plain.ply") == want);
    expect_ranks_write(want, args, {1, 2, 4});
  }
  // Pieces: VTK reads the same oriented triangles as the single process's .vtp.
  if (std::string_view(PROGISO_VTK_PYTHON).empty()) return;
  const auto full = [&](const fs::path& out) {
    return std::vector<std::string>{"extract", nhdr.string(), "--iso",      "127.5",     "--world",
                                    "--full",  "-o",          out.string(), "--threads", "1"};
  };
  expect_pvtp_reads_as_one_process(full);
}

TEST_F(Mpi, vertex_normals_are_the_single_process_ones_bit_for_bit) {
  // A checkerboard in the lower planes (every central difference 0: those vertices take the
  // normals of the triangles around them, some on the rank before) and waves above; in a NRRD
  // whose directions turn, shear and mirror the grid, with and without --world.
  const fs::path nhdr = turned_nrrd("n", [](int x, int y, int z) {
    const int wave = (x * 7 + y * 11 + z * 13 + (x * y) % 17 + (y * z) % 19) % 256;
    return z < 20 ? ((x + y + z) % 2) * 200 + 20 : wave;
  });
  for (const bool world : {false, true}) {
    for (const std::vector<std::string>& goal :
         {std::vector<std::string>{"--full"}, std::vector<std::string>{"--error", "6"},
          std::vector<std::string>{"--error", "0"}}) {
      SCOPED_TRACE(goal[0] + (goal.size() > 1 ? " " + goal[1] : "") + (world ? ", --world" : ""));
      const auto args = [&](const fs::path& out) {
        std::vector<std::string> a{"extract", nhdr.string(), "--iso", "110.5", "--normals"};
        if (world) a.push_back("--world");
        a.insert(a.end(), goal.begin(), goal.end());
        a.insert(a.end(), {"-o", out.string(), "--threads", "1"});
        return a;
      };
      const std::string want = one_process_file(args);
      ASSERT_NE(want.find("property float nx"), std::string::npos);
      expect_ranks_write(want, args, {1, 2, 3, 4});
    }
  }
  // Pieces with normals: VTK reads the single process's corners and normals.
  if (std::string_view(PROGISO_VTK_PYTHON).empty()) return;
  const auto full = [&](const fs::path& out) {
    return std::vector<std::string>{"extract",    nhdr.string(), "--iso",     "110.5",
                                    "--world",    "--full",      "--normals", "-o",
                                    out.string(), "--threads",   "1"};
  };
  expect_pvtp_reads_as_one_process(full);
}

TEST_F(Mpi, refusals_give_one_error_line_and_a_failing_status) {
  const fs::path raw = dir_.path() / "small.raw";
  test::write_file(raw, std::string(8 * 8 * 8, '\x10'));
  const auto refused = [&](const std::vector<std::string>& args, const std::string& says) {
    const test::bounded_result r =
        test::run_bounded(PROGISO_MPIEXEC, mpi_args(2, args), runs_.path());
    EXPECT_NE(r.status, 0);
    std::size_t lines = 0;
    for (std::size_t at = r.err.find("progiso: error:"); at != std::string::npos;
         at = r.err.find("progiso: error:", at + 1)) {
      ++lines;
    }
    EXPECT_EQ(lines, 1U) << r.err;
    EXPECT_NE(r.err.find(says), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir_.path() / "out.ply"));
  };
  refused({"extract", raw.string(), "--dims", "8,8,8", "--type", "u8", "--iso", "3",
           "--max-triangles", "100", "--hierarchy", (dir_.path() / "out.pgh").string(), "-o",
           (dir_.path() / "out.ply").string()},
          "under MPI, --hierarchy goes only with --error or --time-ms");
  refused({"extract", raw.string(), "--dims", "8,8,8", "--type", "u8", "--iso", "3", "--error", "1",
           "--smooth", "1", "-o", (dir_.path() / "out.ply").string()},
          "--smooth is not built across ranks");
  refused({"extract", raw.string(), "--dims", "8,8,8", "--type", "u8", "--iso", "3", "--time-ms",
           "10", "--by-priority", "-o", (dir_.path() / "out.ply").string()},
          "under MPI a deadline refines by rounds of falling error thresholds");
  refused({"extract", raw.string(), "--dims", "8,8,8", "--type", "u8", "--iso", "3", "--error", "1",
           "-o", (dir_.path() / "out.pvtp").string()},
          "a .pvtp of one piece per rank is written for --full");
  refused(
      {"extract", raw.string(), "--dims", "8,8,8", "--type", "u8", "--iso", "3", "--full",
       "--hierarchy", (dir_.path() / "out.pgh").string(), "-o", (dir_.path() / "out.ply").string()},
      "under MPI, --hierarchy goes only with --error");
  refused({"extract", (dir_.path() / "missing.raw").string(), "--dims", "8,8,8", "--type", "u8",
           "--iso", "3", "--full", "-o", (dir_.path() / "out.ply").string()},
          "missing.raw: cannot open");
}

TEST_F(Mpi, a_rank_killed_mid_run_ends_the_job_without_an_output) {
  const fs::path raw = dir_.path() / "ramp.raw";
  std::string bytes;
  for (int i = 0; i < 40 * 40 * 40; ++i) bytes += static_cast<char>((i * 7) % 251);
  test::write_file(raw, bytes);
  // After the counts (finest surface), after the range data's exchange (error cut).
  for (const std::vector<std::string>& goal :
       {std::vector<std::string>{"--full"}, std::vector<std::string>{"--error", "3"}}) {
    SCOPED_TRACE(goal[0]);
    std::vector<std::string> args{
        "extract", raw.string(), "--dims", "40,40,40", "--type",
        "u8",      "--iso",      "100",    "-o",       (dir_.path() / "out.ply").string()};
    args.insert(args.end(), goal.begin(), goal.end());
    setenv("PROGISO_MPI_FAULT_RANK", "1", 1);
    test::bounds b;
    b.wall = std::chrono::seconds(120);
    const test::bounded_result r =
        test::run_bounded(PROGISO_MPIEXEC, mpi_args(2, args), runs_.path(), b);
    unsetenv("PROGISO_MPI_FAULT_RANK");
    EXPECT_FALSE(r.timed_out) << "the job hung after a rank died";
    EXPECT_NE(r.status, 0);
    for (const auto& e : fs::directory_iterator(dir_.path())) {
      EXPECT_EQ(e.path().filename().string().find("out.ply"), std::string::npos)
          << "left " << e.path();
    }
  }
}

}  // namespace
}  // namespace progiso
