// The progiso command as a user runs it: success paths write a readable mesh and statistics;
// every kind of bad input prints one error line naming the problem, exits with status 2 and
// leaves no output file behind.
#include <progiso/io/mesh_io.hpp>

#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include <gtest/gtest.h>

#include "support/dicom_files.hpp"
#include "support/io_test_helpers.hpp"
#include "support/mesh_checks.hpp"
#include "support/mrc_files.hpp"
#include "support/test_data.hpp"
#include "support/tiff_files.hpp"
#include "support/vti_files.hpp"

namespace progiso {
namespace {

namespace fs = std::filesystem;

struct run_result {
  int status = -1;
  std::string out;
  std::string err;
};

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device rd;
    dir_ = fs::temp_directory_path() / ("progiso-cli-" + std::to_string(rd()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  run_result run(const std::string& args) const {
    const fs::path out = dir_ / "stdout.txt";
    const fs::path err = dir_ / "stderr.txt";
    const std::string cmd =
        std::string(PROGISO_CLI) + " " + args + " >" + out.string() + " 2>" + err.string();
    const int raw = std::system(cmd.c_str());
    run_result r;
    r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    r.out = slurp(out);
    r.err = slurp(err);
    fs::remove(out);
    fs::remove(err);
    return r;
  }

  static std::string slurp(const fs::path& p) {
    std::ifstream in(p);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }

  fs::path write_file(const std::string& name, const std::string& bytes) const {
    const fs::path p = dir_ / name;
    std::ofstream(p, std::ios::binary) << bytes;
    return p;
  }

  // The mesh of cube_bytes(9) as a raw u8 file with `spacing` ("SX,SY,SZ"), isovalue 100, full
  // refinement: the reference the format tests compare their files' meshes with.
  fs::path raw_cube_mesh(const std::string& spacing) const;
  // Extracts `in` (isovalue 100, full) and expects the same file as `want`, byte for byte.
  void expect_same_mesh(const fs::path& in, const fs::path& want) const {
    const fs::path out = dir_ / (in.filename().string() + ".obj");
    const run_result r = run("extract " + in.string() + " --iso 100 --full -o " + out.string());
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(slurp(out), slurp(want)) << in;
  }

  // Expects exit status 2, exactly one stderr line containing `needle`, and no output files.
  void expect_bad_input(const std::string& args, const std::string& needle) const {
    const run_result r = run(args + " -o " + (dir_ / "out.ply").string() + " --stats-json " +
                             (dir_ / "stats.json").string());
    EXPECT_EQ(r.status, 2) << args;
    EXPECT_NE(r.err.find(needle), std::string::npos) << "stderr: " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "stderr: " << r.err;
    EXPECT_FALSE(fs::exists(dir_ / "out.ply"));
    EXPECT_FALSE(fs::exists(dir_ / "stats.json"));
    for (const auto& e : fs::directory_iterator(dir_)) {
      EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos) << "left " << e.path();
    }
  }

  fs::path dir_;
};

std::string cube_bytes(int n) {
  std::string s(static_cast<std::size_t>(n * n * n), '\0');
  for (int i = 0; i < n * n * n; ++i) s[static_cast<std::size_t>(i)] = static_cast<char>(i % 200);
  return s;
}

fs::path Cli::raw_cube_mesh(const std::string& spacing) const {
  const fs::path raw = write_file("cube.raw", cube_bytes(9));
  const fs::path want = dir_ / "raw.obj";
  const run_result r = run("extract " + raw.string() + " --dims 9,9,9 --type u8 --spacing " +
                           spacing + " --iso 100 --full -o " + want.string());
  EXPECT_EQ(r.status, 0) << r.err;
  return want;
}

TEST_F(Cli, demo_writes_a_ply_mesh_and_statistics) {
  const fs::path out = dir_ / "demo.ply";
  const fs::path stats = dir_ / "demo.json";
  const run_result r = run("extract --demo -o " + out.string() + " --stats-json " + stats.string() +
                           " --max-triangles 20000");
  ASSERT_EQ(r.status, 0) << r.err;
  const triangle_mesh m = read_ply(out);
  EXPECT_GT(m.triangles.size(), 1000u);
  EXPECT_LE(m.triangles.size(), 20000u);
  const std::string json = slurp(stats);
  for (const char* key : {"\"splits\"", "\"diamonds_visited\"", "\"triangles\"",
                          "\"time_to_first_surface_ms\"", "\"total_ms\"", "\"range_data_bytes\"",
                          "\"cases\"", "\"primitives\"", "\"VertexSplit\"", "\"1b\""}) {
    EXPECT_NE(json.find(key), std::string::npos) << key;
  }
  EXPECT_NE(json.find("\"triangles\": " + std::to_string(m.triangles.size())), std::string::npos);
}

// The number after "key": in a stats file (NaN when the key is missing).
double json_field(const std::string& json, const std::string& key) {
  const std::size_t at = json.find("\"" + key + "\": ");
  if (at == std::string::npos) return std::nan("");
  return std::stod(json.substr(at + key.size() + 4));
}

TEST_F(Cli, pipeline_time_holds_the_phases_and_the_first_surface_comes_first) {
  const fs::path stats = dir_ / "p.json";
  ASSERT_EQ(run("extract --demo --full -o " + (dir_ / "p.ply").string() + " --stats-json " +
                stats.string())
                .status,
            0);
  const std::string json = slurp(stats);
  const double pipeline = json_field(json, "pipeline_ms");
  const double first = json_field(json, "time_to_first_surface_ms");
  const double range = json_field(json, "range_build_ms");
  const double refine = json_field(json, "refine_ms");
  const double extract = json_field(json, "extract_ms");
  ASSERT_GT(pipeline, 0.0) << json;
  // The root surface is published before the range data exists (no pass over the volume).
  EXPECT_LE(first + range, pipeline + 1e-6) << json;
  EXPECT_LE(range + refine + extract, pipeline + 1e-6) << json;
  EXPECT_LE(pipeline, json_field(json, "total_ms") + 1e-6) << json;

  const auto data = test::shared_data_dir();
  if (!data) GTEST_SKIP() << "shared data not found";
  const fs::path cstats = dir_ / "c.json";
  ASSERT_EQ(run("contour " + (*data / "camera_512x512.pgm").string() + " --iso 60,120 -o " +
                (dir_ / "c.svg").string() + " --stats-json " + cstats.string())
                .status,
            0);
  const std::string cjson = slurp(cstats);
  const double cpipe = json_field(cjson, "pipeline_ms");
  EXPECT_GT(cpipe, 0.0) << cjson;
  EXPECT_LE(cpipe, json_field(cjson, "total_ms") + 1e-6) << cjson;
  EXPECT_LE(json_field(cjson, "range_build_ms"), cpipe + 1e-6) << cjson;
}

TEST_F(Cli, raw_volume_with_spacing_gives_physical_coordinates_in_obj) {
  const auto data = test::shared_data_dir();
  if (!data) GTEST_SKIP() << "shared data not found";
  const fs::path out = dir_ / "head.obj";
  const run_result r = run(
      "extract " + (*data / "headsq_64x64x93_int16le.raw").string() +
      " --dims 64,64,93 --type i16 --spacing 3.2,3.2,1.5 --iso 500 --error 200 -o " + out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  std::ifstream in(out);
  std::string tag;
  double x = 0, y = 0, z = 0, max_x = 0, max_z = 0;
  std::size_t faces = 0;
  while (in >> tag) {
    if (tag == "v") {
      in >> x >> y >> z;
      max_x = std::max(max_x, x);
      max_z = std::max(max_z, z);
    } else {
      std::getline(in, tag);
      ++faces;
    }
  }
  EXPECT_GT(faces, 100u);
  EXPECT_GT(max_x, 63.0 * 1.5);  // x is scaled by 3.2, beyond what 1.5 could give
  EXPECT_LE(max_x, 63.0 * 3.2);
  EXPECT_LE(max_z, 92.0 * 1.5);
}

TEST_F(Cli, isovalue_outside_the_data_range_writes_an_empty_mesh_and_says_so) {
  const fs::path in = write_file("c.raw", cube_bytes(8));
  const fs::path out = dir_ / "empty.ply";
  const run_result r =
      run("extract " + in.string() + " --dims 8,8,8 --type u8 --iso 250 -o " + out.string());
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("outside the data range"), std::string::npos) << r.err;
  EXPECT_TRUE(read_ply(out).empty());
}

TEST_F(Cli, bad_inputs_exit_2_with_one_clear_line_and_no_output) {
  const fs::path good = write_file("c.raw", cube_bytes(8));
  const std::string g = good.string();
  expect_bad_input("extract " + (dir_ / "missing.raw").string() + " --dims 8,8,8 --type u8 --iso 1",
                   "missing.raw");
  expect_bad_input("extract " + g + " --dims 8,8,9 --type u8 --iso 1", "does not match");
  expect_bad_input("extract " + g + " --dims 8,8,8 --type q8 --iso 1", "--type");
  expect_bad_input("extract " + g + " --dims 8,8,8 --type u8 --iso nan", "finite");
  expect_bad_input("extract " + g + " --dims 0,8,8 --type u8 --iso 1", "--dims");
  expect_bad_input("extract " + g + " --dims 8,8 --type u8 --iso 1", "three");
  expect_bad_input("extract " + g + " --iso 1", "unknown volume format");
  expect_bad_input("extract " + g + " --dims 8,8,8 --type u8", "--iso");
  expect_bad_input("extract " + g + " --dims 8,8,8 --type u8 --iso 1 --full --error 2",
                   "at most one");
  expect_bad_input("extract " + g + " --dims 8,8,8 --type u8 --iso 1 --bogus", "--bogus");
  expect_bad_input("extract " + g + " --dims 8,8,8 --type u8 --iso 1 --threads 0", "--threads");
  expect_bad_input("extract " + g + " --dims 8,8,8 --type u8 --iso 1 --threads 1.5", "--threads");
  const fs::path bad_header = write_file("bad.nrrd", "NRRD0004\ntype: banana\ndimension: 3\n\n");
  expect_bad_input("extract " + bad_header.string() + " --iso 1", "bad.nrrd");
  const fs::path two_d = write_file("flat.nrrd",
                                    "NRRD0004\ntype: uchar\ndimension: 2\nsizes: 2 2\n"
                                    "encoding: raw\n\n" +
                                        std::string(4, '\1'));
  expect_bad_input("extract " + two_d.string() + " --iso 1", "flat.nrrd");
  const run_result r =
      run("extract " + g + " --dims 8,8,8 --type u8 --iso 1 -o " + (dir_ / "out.off").string());
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find(".ply, .obj, .stl, .glb or .vtp"), std::string::npos) << r.err;
}

TEST_F(Cli, full_output_is_identical_for_every_thread_count) {
  std::string bytes;
  for (const fs::path& out : {dir_ / "t1.ply", dir_ / "t2.ply", dir_ / "t3.ply"}) {
    const std::string n = out.stem().string().substr(1);
    const run_result r = run("extract --demo --full --threads " + n + " -o " + out.string());
    ASSERT_EQ(r.status, 0) << r.err;
    const std::string b = slurp(out);
    EXPECT_GT(b.size(), 1000000u);
    if (bytes.empty()) bytes = b;
    EXPECT_TRUE(b == bytes) << out << " differs from the 1-thread output";
  }
}

// A 17³ u8 ball: distance to the centre, scaled.
std::string ball_bytes() {
  std::string s(17 * 17 * 17, '\0');
  for (int z = 0; z < 17; ++z)
    for (int y = 0; y < 17; ++y)
      for (int x = 0; x < 17; ++x) {
        const double d =
            std::sqrt((x - 8.3) * (x - 8.3) + (y - 7.6) * (y - 7.6) + (z - 8.1) * (z - 8.1));
        s[static_cast<std::size_t>(x + 17 * (y + 17 * z))] =
            static_cast<char>(static_cast<unsigned char>(std::min(250.0, d * 20)));
      }
  return s;
}

TEST_F(Cli, hierarchy_stream_gives_every_cut_without_the_volume) {
  const fs::path in = write_file("ball.raw", ball_bytes());
  const fs::path mesh = dir_ / "full.ply";
  const fs::path stream = dir_ / "ball.pgh";
  const fs::path stats = dir_ / "run.json";
  run_result r =
      run("extract " + in.string() + " --dims 17,17,17 --type u8 --iso 111 --threads 2 -o " +
          mesh.string() + " --hierarchy " + stream.string() + " --stats-json " + stats.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("hierarchy stream of"), std::string::npos) << r.out;
  EXPECT_NE(slurp(stats).find("\"hierarchy_bytes\""), std::string::npos);
  // The full cut of the stream is the command's own mesh, byte for byte, and the volume's
  // finest surface (the direct path's).
  const fs::path cut = dir_ / "cut.ply";
  r = run("cut " + stream.string() + " -o " + cut.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("a complete stream"), std::string::npos) << r.out;
  EXPECT_TRUE(slurp(cut) == slurp(mesh));
  const fs::path direct = dir_ / "direct.ply";
  r = run("extract " + in.string() + " --dims 17,17,17 --type u8 --iso 111 -o " + direct.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(test::same_surface(read_ply(cut), read_ply(direct)));
  // Coarser cuts: by error, by budget, in a box, and of a prefix, each a valid surface.
  const auto full_triangles = read_ply(cut).triangles.size();
  const std::string budget = "--max-triangles " + std::to_string(full_triangles / 2);
  for (const std::string& how :
       {std::string("--error 20"), budget, std::string("--region 0,0,0,8,8,8"),
        std::string("--records 40")}) {
    const fs::path part = dir_ / "part.ply";
    r = run("cut " + stream.string() + " " + how + " -o " + part.string());
    ASSERT_EQ(r.status, 0) << how << ": " << r.err;
    const triangle_mesh m = read_ply(part);
    EXPECT_GT(m.triangles.size(), 0u) << how;
    EXPECT_LT(m.triangles.size(), full_triangles) << how;
    EXPECT_TRUE(test::check_valid_cut(m, {0, 0, 0}, {16, 16, 16})) << how;
    if (how == budget) {
      EXPECT_LE(m.triangles.size(), full_triangles / 2);
    }
  }
  // A truncated or corrupt stream: one line naming it, exit 2, no output.
  const std::string bytes = slurp(stream);
  const fs::path cut_short = write_file("short.pgh", bytes.substr(0, bytes.size() - 7));
  expect_bad_input("cut " + cut_short.string(), "short.pgh: hierarchy stream: byte");
  std::string flipped = bytes;
  flipped[flipped.size() / 2] = static_cast<char>(flipped[flipped.size() / 2] ^ 0x21);
  const fs::path corrupt = write_file("corrupt.pgh", flipped);
  expect_bad_input("cut " + corrupt.string(), "CRC");
  expect_bad_input("cut " + in.string(), "PROGISOH");
  expect_bad_input("cut " + stream.string() + " --error 1 --records x", "--records");
  expect_bad_input("cut " + stream.string() + " --region 1,2,3", "--region");
  expect_bad_input("extract " + in.string() + " --dims 17,17,17 --type u8 --iso 111 --hierarchy " +
                       (dir_ / "h.bin").string(),
                   ".pgh");
}

TEST_F(Cli, smoothing_options_refine_the_smoothed_field_on_every_thread_count) {
  const std::string in =
      write_file("ball.raw", ball_bytes()).string() + " --dims 17,17,17 --type u8 --iso 111";
  const auto extract = [&](const std::string& name, const std::string& extra) {
    const fs::path out = dir_ / (name + ".ply");
    const fs::path stats = dir_ / (name + ".json");
    const run_result r = run("extract " + in + " " + extra + " -o " + out.string() +
                             " --stats-json " + stats.string());
    EXPECT_EQ(r.status, 0) << r.err;
    return std::pair{slurp(out), slurp(stats)};
  };
  const auto [plain, plain_stats] = extract("plain", "--full");
  const auto [one, one_stats] = extract("s1t1", "--full --smooth 1 --threads 1");
  const auto [two, two_stats] = extract("s1t2", "--full --smooth 1 --threads 2 --alpha 1");
  EXPECT_TRUE(one == two) << "--smooth 1 --full differs between 1 and 2 threads";
  EXPECT_NE(one, plain);
  EXPECT_NE(one_stats.find("\"field_dims\": [33, 33, 33]"), std::string::npos) << one_stats;
  EXPECT_NE(one_stats.find("\"subdivision_levels\": 1"), std::string::npos) << one_stats;
  EXPECT_GT(json_field(one_stats, "subdivided_samples"), 1000.0) << one_stats;
  EXPECT_EQ(json_field(plain_stats, "subdivided_samples"), 0.0) << plain_stats;
  EXPECT_GT(json_field(one_stats, "triangles"), 3 * json_field(plain_stats, "triangles"));
  // Written coordinates stay physical: the smoothed surface spans the same box as the data's.
  const triangle_mesh a = read_ply(dir_ / "plain.ply");
  const triangle_mesh b = read_ply(dir_ / "s1t1.ply");
  for (std::size_t q = 0; q < 3; ++q) {
    const auto lo = [q](const triangle_mesh& m) {
      double v = 1e300;
      for (const vec3& p : m.vertices) v = std::min(v, p[q]);
      return v;
    };
    EXPECT_NEAR(lo(a), lo(b), 0.5) << q;
  }
  // From a coarse level, by region, with α; every mode.
  const auto [coarse, coarse_stats] =
      extract("k", "--smooth-from 2 --smooth-region 0,0,0,10,16,16 --alpha 0.5 --error 4");
  EXPECT_NE(coarse_stats.find("\"region\": [0, 0, 0, 10, 16, 16]"), std::string::npos);
  EXPECT_NE(coarse_stats.find("\"from\": 2"), std::string::npos);
  for (const std::string mode : {"--max-triangles 3000", "--time-ms 5", "--error 2"}) {
    const auto [mesh, stats] = extract("m", "--smooth 2 --threads 2 " + mode);
    EXPECT_NE(stats.find("\"field_dims\": [65, 65, 65]"), std::string::npos) << mode;
    const triangle_mesh m = read_ply(dir_ / "m.ply");
    // A deadline may end before the first split on a loaded machine: the root cut of this ball
    // is empty, and an empty surface is a valid one. The other modes must refine.
    if (mode != "--time-ms 5") {
      EXPECT_GT(m.triangles.size(), 0u) << mode;
    }
    EXPECT_TRUE(test::edge_manifold(m)) << mode;
    EXPECT_TRUE(test::consistently_oriented(m)) << mode;
  }
}

TEST_F(Cli, bad_smoothing_values_exit_2_with_one_clear_line_and_no_output) {
  const std::string g =
      write_file("b.raw", cube_bytes(8)).string() + " --dims 8,8,8 --type u8 --iso 1 ";
  expect_bad_input("extract " + g + "--smooth 4", "--smooth: expected an integer from 0 to 3");
  expect_bad_input("extract " + g + "--smooth -1", "--smooth");
  expect_bad_input("extract " + g + "--smooth 1.5", "--smooth");
  expect_bad_input("extract " + g + "--smooth-from 0", "--smooth-from");
  expect_bad_input("extract " + g + "--smooth-from 3", "K = 3");
  expect_bad_input("extract " + g + "--smooth 1 --alpha 0", "--alpha");
  expect_bad_input("extract " + g + "--smooth 1 --alpha 2.5", "--alpha");
  expect_bad_input("extract " + g + "--smooth 1 --alpha nan", "--alpha");
  expect_bad_input("extract " + g + "--smooth 1 --smooth-region 1,2,3", "--smooth-region");
  expect_bad_input("extract " + g + "--smooth 1 --smooth-region 4,0,0,3,7,7", "--smooth-region");
  expect_bad_input("extract " + g + "--smooth 1 --smooth-region 0,0,0,8,7,7", "region");
  expect_bad_input("extract " + g + "--smooth-region", "--smooth-region");
}

TEST_F(Cli, time_budget_returns_a_partial_valid_surface) {
  const fs::path out = dir_ / "t.ply";
  const run_result r = run("extract --demo --time-ms 5 --threads 2 -o " + out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const triangle_mesh m = read_ply(out);
  EXPECT_GT(m.triangles.size(), 0u);
  EXPECT_LT(m.triangles.size(), 700000u) << "the full demo surface has 764704 triangles";
  EXPECT_TRUE(test::edge_manifold(m));
  EXPECT_TRUE(test::consistently_oriented(m));
}

TEST_F(Cli, a_deadline_climbs_uniform_cuts_unless_told_to_refine_by_priority) {
  // The demo (129³, 128 cells a side) with a spent budget: the coarsest uniform cut, every 16th
  // sample (8 cells); with a budget of an hour, the finest cut (every sample, the full
  // surface); --by-priority refines the hierarchy instead and says so.
  const fs::path stats = dir_ / "d.json";
  const auto timed = [&](const std::string& extra) {
    const run_result r = run("extract --demo " + extra + " -o " + (dir_ / "d.ply").string() +
                             " --stats-json " + stats.string());
    EXPECT_EQ(r.status, 0) << r.err;
    return std::make_pair(r, slurp(stats));
  };
  const auto [spent, spent_json] = timed("--time-ms 0");
  EXPECT_NE(spent_json.find("\"path\": \"uniform\""), std::string::npos) << spent_json;
  EXPECT_EQ(json_field(spent_json, "stride"), 16.0) << spent_json;
  EXPECT_NE(spent.out.find("the uniform cut of every 16th sample by the deadline"),
            std::string::npos)
      << spent.out;
  const triangle_mesh coarse = read_ply(dir_ / "d.ply");
  EXPECT_TRUE(test::edge_manifold(coarse));
  EXPECT_TRUE(test::consistently_oriented(coarse));
  const auto [far, far_json] = timed("--time-ms 3600000");
  EXPECT_EQ(json_field(far_json, "stride"), 1.0) << far_json;
  EXPECT_EQ(json_field(far_json, "triangles"), 764704.0) << far_json;
  EXPECT_NE(far.out.find("the finest cut by the deadline"), std::string::npos) << far.out;
  const auto [priority, priority_json] = timed("--time-ms 5 --by-priority");
  EXPECT_NE(priority_json.find("\"path\": \"refinement\""), std::string::npos) << priority_json;
  EXPECT_TRUE(std::isnan(json_field(priority_json, "stride"))) << priority_json;
  expect_bad_input("extract --demo --by-priority", "--by-priority applies to --time-ms");
  expect_bad_input("extract --demo --error 1 --by-priority", "--by-priority");
}

TEST_F(Cli, nrrd_input_is_read_with_its_spacing) {
  std::string payload = cube_bytes(9);
  const fs::path in = write_file("v.nrrd",
                                 "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 9 9 9\n"
                                 "spacings: 2 2 2\nencoding: raw\n\n" +
                                     payload);
  const fs::path out = dir_ / "v.obj";
  const run_result r = run("extract " + in.string() + " --iso 100 -o " + out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  std::ifstream f(out);
  std::string tag;
  double x = 0, y = 0, z = 0, max_c = 0;
  while (f >> tag) {
    if (tag == "v") {
      f >> x >> y >> z;
      max_c = std::max({max_c, x, y, z});
    } else {
      std::getline(f, tag);
    }
  }
  EXPECT_GT(max_c, 8.0);  // spacing 2: coordinates reach beyond the index range 0..8
}

TEST_F(Cli, nifti_input_gives_the_surface_of_the_same_samples_as_raw) {
  // A CT-like volume in NIfTI-1, plain and gzip, against the same bytes as a raw file with the
  // same spacing: the same mesh file, byte for byte.
  const std::string nii = test::nifti1_file({9, 9, 9}, 2, 8, {2.0f, 1.5f, 0.5f}, cube_bytes(9));
  const fs::path plain = write_file("v.nii", nii);
  const fs::path gz = write_file("v.nii.gz", test::gzip(nii));
  const fs::path want = raw_cube_mesh("2,1.5,0.5");
  for (const fs::path& in : {plain, gz}) expect_same_mesh(in, want);
  // A NIfTI file that ends inside its data: one line naming it, exit 2, no output.
  const fs::path cut = write_file("cut.nii", nii.substr(0, nii.size() - 10));
  expect_bad_input("extract " + cut.string() + " --iso 100", "cut.nii: NIfTI data ends");
}

TEST_F(Cli, volume_picks_one_volume_of_a_nifti_metaimage_or_nrrd_series) {
  // Three volumes of 9³ bytes (dim[4] = 3), the middle one the cube: --volume 1 gives the raw
  // cube's mesh, plain and gzip; without --volume, or past the last, one line and exit 2.
  const std::string nii = test::nifti1_series(
      test::nifti1_file({9, 9, 9}, 2, 8, {2.0f, 1.5f, 0.5f},
                        std::string(729, '\0') + cube_bytes(9) + std::string(729, '\x7f')),
      3);
  const fs::path plain = write_file("t.nii", nii);
  const fs::path gz = write_file("t.nii.gz", test::gzip(nii));
  const fs::path want = raw_cube_mesh("2,1.5,0.5");
  for (const fs::path& in : {plain, gz}) {
    const fs::path out = dir_ / (in.filename().string() + ".obj");
    const fs::path stats = dir_ / (in.filename().string() + ".json");
    const run_result r = run("extract " + in.string() + " --volume 1 --iso 100 --full -o " +
                             out.string() + " --stats-json " + stats.string());
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(slurp(out), slurp(want)) << in;
    // The chosen volume is named in the report and the statistics.
    EXPECT_NE(r.err.find(in.filename().string() + " volume 1, 9x9x9 u8"), std::string::npos)
        << r.err;
    EXPECT_NE(slurp(stats).find("\"volume\": 1,"), std::string::npos) << slurp(stats);
  }
  expect_bad_input("extract " + plain.string() + " --iso 100",
                   "t.nii: a time series of 3 volumes (dim[4] = 3): choose one by its index, "
                   "0 to 2");
  expect_bad_input("extract " + gz.string() + " --iso 100 --volume 3",
                   "t.nii.gz: volume 3 was chosen, but the input is a time series of 3 volumes");
  expect_bad_input("extract " + plain.string() + " --iso 100 --volume -1", "--volume");
  expect_bad_input("extract " + plain.string() + " --iso 100 --volume x", "--volume");
  expect_bad_input("extract --demo --volume 0", "--volume picks a volume of an input file");
  // A MetaImage series (NDims 4) the same way, its volumes in one zlib data file.
  write_file("t.zraw", test::gzip(std::string(729, '\0') + cube_bytes(9) + std::string(729, '\x7f'),
                                  6, true));
  const fs::path mhd = write_file("t.mhd",
                                  "NDims = 4\nDimSize = 9 9 9 3\nElementSpacing = 2 1.5 0.5 1\n"
                                  "CompressedData = True\nElementType = MET_UCHAR\n"
                                  "ElementDataFile = t.zraw\n");
  const fs::path mesh = dir_ / "t.mhd.obj";
  const run_result m =
      run("extract " + mhd.string() + " --volume 1 --iso 100 --full -o " + mesh.string());
  ASSERT_EQ(m.status, 0) << m.err;
  EXPECT_EQ(slurp(mesh), slurp(want));
  expect_bad_input("extract " + mhd.string() + " --iso 100",
                   "t.mhd: a time series of 3 volumes (DimSize[3] = 3)");
  // A 4-D NRRD: volumes last (a Slicer sequence, gzip), and first (interleaved, as diffusion
  // MRI: the three volumes' samples alternate).
  const std::string three = std::string(729, '\0') + cube_bytes(9) + std::string(729, '\x7f');
  std::string interleaved;
  for (std::size_t i = 0; i < 729; ++i) {
    for (std::size_t k = 0; k < 3; ++k) interleaved += three[k * 729 + i];
  }
  const fs::path seq = write_file("t.seq.nrrd",
                                  "NRRD0005\ntype: uchar\ndimension: 4\nsizes: 9 9 9 3\n"
                                  "kinds: domain domain domain list\nspacings: 2 1.5 0.5 nan\n"
                                  "encoding: gzip\n\n" +
                                      test::gzip(three));
  const fs::path dwi = write_file("t.dwi.nrrd",
                                  "NRRD0005\ntype: uchar\ndimension: 4\nsizes: 3 9 9 9\n"
                                  "kinds: list domain domain domain\nspacings: nan 2 1.5 0.5\n"
                                  "encoding: raw\n\n" +
                                      interleaved);
  for (const fs::path& in : {seq, dwi}) {
    const fs::path out = dir_ / (in.filename().string() + ".obj");
    const run_result n =
        run("extract " + in.string() + " --volume 1 --iso 100 --full -o " + out.string());
    ASSERT_EQ(n.status, 0) << n.err;
    EXPECT_EQ(slurp(out), slurp(want)) << in;
  }
  expect_bad_input("extract " + dwi.string() + " --iso 100",
                   "t.dwi.nrrd: a time series of 3 volumes (sizes[0] = 3)");
  // A 3-D input holds volume 0 only.
  const fs::path raw = write_file("one.raw", cube_bytes(9));
  expect_bad_input("extract " + raw.string() + " --dims 9,9,9 --type u8 --iso 100 --volume 1",
                   "one.raw: volume 1 was chosen, but the input holds one volume (0)");
}

TEST_F(Cli, metaimage_input_gives_the_surface_of_the_same_samples_as_raw) {
  // The same bytes as a raw file, an .mha with the data after the header (big-endian 16-bit),
  // and an .mhd whose zlib-compressed data lies in another file: the same mesh, byte for byte.
  const std::string bytes = cube_bytes(9);
  const fs::path want = raw_cube_mesh("2,1.5,0.5");
  std::string wide;  // the samples as big-endian u16
  for (const char c : bytes) {
    wide += '\0';
    wide += c;
  }
  const fs::path mha = write_file("v.mha",
                                  "ObjectType = Image\nNDims = 3\nDimSize = 9 9 9\n"
                                  "ElementSpacing = 2 1.5 0.5\nElementByteOrderMSB = True\n"
                                  "ElementType = MET_USHORT\nElementDataFile = LOCAL\n" +
                                      wide);
  write_file("v.zraw", test::gzip(bytes, 6, true));
  const fs::path mhd = write_file("v.mhd",
                                  "NDims = 3\nDimSize = 9 9 9\nElementSpacing = 2 1.5 0.5\n"
                                  "CompressedData = True\nElementType = MET_UCHAR\n"
                                  "ElementDataFile = v.zraw\n");
  for (const fs::path& in : {mha, mhd}) expect_same_mesh(in, want);
  // An .mhd whose data file is one byte short: one line naming the data file, exit 2.
  write_file("short.raw", bytes.substr(0, bytes.size() - 1));
  const fs::path cut = write_file("cut.mhd",
                                  "NDims = 3\nDimSize = 9 9 9\nElementType = MET_UCHAR\n"
                                  "ElementDataFile = short.raw\n");
  expect_bad_input("extract " + cut.string() + " --iso 100", "short.raw: the 728 bytes");
}

TEST_F(Cli, legacy_vtk_input_gives_the_surface_of_the_same_samples_as_raw) {
  // The same bytes as a raw file and as binary and ASCII STRUCTURED_POINTS: the same mesh.
  const std::string bytes = cube_bytes(9);
  const fs::path want = raw_cube_mesh("2,1.5,0.5");
  const std::string head =
      "DATASET STRUCTURED_POINTS\nDIMENSIONS 9 9 9\nSPACING 2 1.5 0.5\nORIGIN 0 0 0\n"
      "POINT_DATA 729\nSCALARS density unsigned_char 1\nLOOKUP_TABLE default\n";
  std::string text;
  for (const char c : bytes) text += std::to_string(static_cast<unsigned char>(c)) + "\n";
  const fs::path binary =
      write_file("b.vtk", "# vtk DataFile Version 3.0\ncube\nBINARY\n" + head + bytes + "\n");
  const fs::path ascii =
      write_file("a.vtk", "# vtk DataFile Version 2.0\ncube\nASCII\n" + head + text);
  for (const fs::path& in : {binary, ascii}) expect_same_mesh(in, want);
  const fs::path vectors =
      write_file("vec.vtk",
                 "# vtk DataFile Version 3.0\nv\nBINARY\nDATASET STRUCTURED_POINTS\n"
                 "DIMENSIONS 9 9 9\nPOINT_DATA 729\nVECTORS v float\n");
  expect_bad_input("extract " + vectors.string() + " --iso 100", "vec.vtk: the first point");
}

TEST_F(Cli, dicom_directory_gives_the_surface_of_the_same_samples_as_raw) {
  // A CT-like series: 9 slice files of 9 × 9 unsigned bytes, spacing 1.5 (columns), 2 (rows)
  // and 0.5 (slices), named in reverse order of their positions, against the same bytes as raw.
  const std::string bytes = cube_bytes(9);
  const fs::path want = raw_cube_mesh("1.5,2,0.5");
  const fs::path series = dir_ / "series";
  fs::create_directory(series);
  for (int k = 0; k < 9; ++k) {
    test::dicom_slice_file f = test::plain_slice(k, 9, 9, 8, 0.5);
    f.pixel_spacing = {2.0, 1.5};
    const auto* p = reinterpret_cast<const std::byte*>(bytes.data()) + 81 * k;
    f.pixels.assign(p, p + 81);
    f.write(series, "IM" + std::to_string(100 - k));
  }
  expect_same_mesh(series, want);
  // An output named like one of the slices is refused, and the slice is kept.
  const fs::path slice = series / "IM100";
  const std::string before = test::read_whole_file(slice);
  fs::create_symlink(slice, dir_ / "slice.ply");
  const run_result clash =
      run("extract " + series.string() + " --iso 100 -o " + (dir_ / "slice.ply").string());
  EXPECT_EQ(clash.status, 2);
  EXPECT_NE(clash.err.find("names the input file"), std::string::npos) << clash.err;
  EXPECT_EQ(test::read_whole_file(slice), before);
  // Beside a second series (a 2-slice scout), the directory is refused with the list, and
  // --series picks the first by number or by UID; --series on a raw volume is refused.
  for (int k = 0; k < 2; ++k) {
    test::dicom_slice_file scout;
    scout.series_uid = "1.2.826.0.1.3680043.2.1125.9";
    scout.position = {0.0, 0.0, 5.0 * k};
    scout.pixels.resize(40);
    scout.write(series, "SCOUT" + std::to_string(k));
  }
  expect_bad_input("extract " + series.string() + " --iso 100", "holds 2 DICOM series (1: ");
  for (const std::string choice : {"1", "1.2.826.0.1.3680043.2.1125.1"}) {
    const fs::path chosen = dir_ / ("series_" + choice + ".obj");
    const run_result pick = run("extract " + series.string() + " --series " + choice +
                                " --iso 100 --full -o " + chosen.string());
    ASSERT_EQ(pick.status, 0) << pick.err;
    EXPECT_EQ(slurp(chosen), slurp(want)) << choice;
  }
  expect_bad_input("extract " + write_file("c.raw", bytes).string() +
                       " --dims 9,9,9 --type u8 --iso 100 --series 1",
                   "--series");
  // A single slice file is refused, naming it.
  expect_bad_input(
      "extract " + write_file("one.dcm", test::read_whole_file(slice)).string() + " --iso 100",
      "one.dcm: one DICOM file is one slice");
}

TEST_F(Cli, enhanced_dicom_file_gives_the_surface_of_the_same_samples_as_raw) {
  // An enhanced CT file: the 9 slices of 9 × 9 bytes as frames in shuffled order, each placed by
  // its per-frame Plane Position; given as the file (.dcm or no extension) or its directory.
  const std::string bytes = cube_bytes(9);
  const fs::path want = raw_cube_mesh("1.5,2,0.5");
  test::dicom_slice_file f = test::plain_slice(0, 9, 9, 8, 0.5);
  f.pixel_spacing = {2.0, 1.5};
  for (const int k : {4, 0, 8, 2, 6, 1, 3, 7, 5}) {
    f.frame_positions.push_back({0.0, 0.0, 0.5 * k});
    const auto* p = reinterpret_cast<const std::byte*>(bytes.data()) + 81 * k;
    f.pixels.insert(f.pixels.end(), p, p + 81);
  }
  const fs::path series = dir_ / "enhanced";
  fs::create_directory(series);
  const fs::path file = f.write(series, "ct.dcm");
  expect_same_mesh(file, want);
  expect_same_mesh(series, want);
  fs::copy_file(file, dir_ / "1.2.826.0.1.3680043.2.1125.1.1");
  expect_same_mesh(dir_ / "1.2.826.0.1.3680043.2.1125.1.1", want);
  // An output through a link to the file is refused and the file kept.
  const std::string before = test::read_whole_file(file);
  fs::create_symlink(file, dir_ / "ct.ply");
  const run_result clash =
      run("extract " + file.string() + " --iso 100 -o " + (dir_ / "ct.ply").string());
  EXPECT_EQ(clash.status, 2);
  EXPECT_NE(clash.err.find("names the input file"), std::string::npos) << clash.err;
  EXPECT_EQ(test::read_whole_file(file), before);
  // Two time points in one file (the cube second, a blank volume first): --volume 1 picks the
  // cube, no --volume is refused with the count, --volume 2 names the range.
  test::dicom_slice_file cine = f;
  cine.frame_positions.clear();
  cine.pixels.clear();
  for (int time = 0; time < 2; ++time) {
    for (const int k : {3, 8, 0, 5, 1, 7, 2, 6, 4}) {
      cine.frame_positions.push_back({0.0, 0.0, 0.5 * k});
      const auto* p = reinterpret_cast<const std::byte*>(bytes.data()) + 81 * k;
      if (time == 1) {
        cine.pixels.insert(cine.pixels.end(), p, p + 81);
      } else {
        cine.pixels.insert(cine.pixels.end(), 81, std::byte{0});
      }
    }
  }
  const fs::path cine_file = cine.write(dir_, "cine.dcm");
  const fs::path picked = dir_ / "cine.obj";
  const run_result one =
      run("extract " + cine_file.string() + " --volume 1 --iso 100 --full -o " + picked.string());
  ASSERT_EQ(one.status, 0) << one.err;
  EXPECT_EQ(slurp(picked), slurp(want));
  expect_bad_input("extract " + cine_file.string() + " --iso 100",
                   "a time series of 2 volumes (2 frames at each of 9 positions)");
  expect_bad_input("extract " + cine_file.string() + " --volume 2 --iso 100",
                   "volume 2 was chosen, but the input is a time series of 2 volumes (0 to 1)");
  // A multi-frame file that does not place its frames is refused, naming it.
  f.number_of_frames = "10";
  expect_bad_input("extract " + f.write(dir_, "short.dcm").string() + " --iso 100",
                   "short.dcm: a multi-frame image of 10 frames with 9 items");
}

TEST_F(Cli, rt_dose_grid_gives_the_surface_of_the_same_samples_as_raw) {
  // An RT dose grid: one file of 9 frames of 9 × 9 bytes, placed by GridFrameOffsetVector from
  // ImagePositionPatient, DoseGridScaling 1 (so the samples stay the raw file's bytes).
  const std::string bytes = cube_bytes(9);
  const fs::path want = raw_cube_mesh("1.5,2,0.5");
  test::dicom_slice_file f = test::plain_slice(0, 9, 9, 8, 0.5);
  f.pixel_spacing = {2.0, 1.5};
  for (int k = 0; k < 9; ++k) f.grid_offsets.push_back(0.5 * k);
  f.pixels.assign(reinterpret_cast<const std::byte*>(bytes.data()),
                  reinterpret_cast<const std::byte*>(bytes.data()) + bytes.size());
  expect_same_mesh(f.write(dir_, "RD.dose.dcm"), want);
  // Offsets that disagree with the frames are refused, naming the file.
  f.grid_offsets.pop_back();
  f.number_of_frames = "9";
  expect_bad_input("extract " + f.write(dir_, "RD.bad.dcm").string() + " --iso 100",
                   "RD.bad.dcm: an RT dose grid of 9 frames with 8 offsets");
}

TEST_F(Cli, stl_output_holds_the_ply_triangles_with_normals_out_of_the_solid) {
  // A ball of high values (bone in CT), 24³ u8: the STL's facets are the PLY's triangles, corner
  // for corner, and every facet's normal points out of the ball (away from its centre).
  const int n = 24;
  std::string bytes(static_cast<std::size_t>(n * n * n), '\0');
  for (int z = 0; z < n; ++z) {
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x) {
        const double r =
            std::sqrt((x - 11.5) * (x - 11.5) + (y - 11.5) * (y - 11.5) + (z - 11.5) * (z - 11.5));
        bytes[static_cast<std::size_t>(x + n * (y + n * z))] =
            static_cast<char>(static_cast<unsigned char>(std::clamp(250.0 - 20.0 * r, 0.0, 250.0)));
      }
    }
  }
  const fs::path in = write_file("ball.raw", bytes);
  const fs::path ply = dir_ / "ball.ply";
  const fs::path stl = dir_ / "ball.stl";
  for (const fs::path& out : {ply, stl}) {
    const run_result r = run("extract " + in.string() +
                             " --dims 24,24,24 --type u8 --spacing 0.5,0.5,0.5 --iso 100 --full "
                             "-o " +
                             out.string());
    ASSERT_EQ(r.status, 0) << r.err;
  }
  const triangle_mesh m = read_ply(ply);
  const std::string s = slurp(stl);
  ASSERT_GT(m.triangles.size(), 100u);
  ASSERT_EQ(s.size(), 84 + 50 * m.triangles.size());
  const auto f32 = [&s](std::size_t at) {
    float v = 0.0f;
    std::memcpy(&v, s.data() + at, sizeof v);
    return v;
  };
  const double centre = 11.5 * 0.5;
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const std::size_t at = 84 + 50 * t;
    std::array<double, 3> mid{};
    for (std::size_t k = 0; k < 3; ++k) {
      for (std::size_t a = 0; a < 3; ++a) {
        const double c = m.vertices[m.triangles[t][k]][a];
        ASSERT_EQ(f32(at + 12 + 12 * k + 4 * a), static_cast<float>(c));
        mid[a] += c / 3.0;
      }
    }
    double out = 0.0;
    for (std::size_t a = 0; a < 3; ++a)
      out += static_cast<double>(f32(at + 4 * a)) * (mid[a] - centre);
    EXPECT_GT(out, 0.0) << "facet " << t << " faces into the solid";
  }
}

/// The vertices and faces (0-based) of an OBJ file progiso wrote.
struct obj_mesh {
  std::vector<std::array<double, 3>> vertices;
  std::vector<std::array<long, 3>> faces;
};
obj_mesh read_obj_file(const fs::path& file) {
  obj_mesh m;
  std::ifstream in(file);
  std::string tag;
  while (in >> tag) {
    if (tag == "v") {
      std::array<double, 3> v{};
      in >> v[0] >> v[1] >> v[2];
      m.vertices.push_back(v);
    } else if (tag == "f") {
      std::array<long, 3> f{};
      in >> f[0] >> f[1] >> f[2];
      m.faces.push_back({f[0] - 1, f[1] - 1, f[2] - 1});
    } else {
      std::getline(in, tag);
    }
  }
  return m;
}

TEST_F(Cli, tiff_stack_gives_the_surface_of_the_same_samples_as_raw) {
  // cube_bytes(9) as 9 pages of 9 × 9 (LZW), as one multi-page file and as a directory of
  // slice files (slice1 … slice9, with a log file beside them): the raw file's mesh, byte for
  // byte. A hyperstack's frame is chosen with --volume.
  const std::string bytes = cube_bytes(9);
  const fs::path want = raw_cube_mesh("1,1,1");
  std::vector<test::tiff_page_spec> pages;
  for (std::size_t k = 0; k < 9; ++k) {
    std::vector<std::byte> s(81);
    std::memcpy(s.data(), bytes.data() + 81 * k, 81);
    test::tiff_page_spec p = test::grey_page(9, 9, sample_type::u8, std::move(s));
    p.compression = COMPRESSION_LZW;
    pages.push_back(std::move(p));
  }
  const fs::path stack = dir_ / "stack.tif";
  ASSERT_TRUE(test::write_tiff(stack, pages));
  expect_same_mesh(stack, want);
  const fs::path slices = dir_ / "slices";
  fs::create_directory(slices);
  for (std::size_t k = 0; k < 9; ++k) {
    ASSERT_TRUE(test::write_tiff(slices / ("slice" + std::to_string(k + 1) + ".tif"), {pages[k]}));
  }
  write_file("slices/scan.log", "reconstruction log");
  expect_same_mesh(slices, want);
  // Two frames of the same 9 slices, the second one's samples inverted: --volume 0 is the cube.
  std::vector<test::tiff_page_spec> frames = pages;
  for (std::size_t k = 0; k < 9; ++k) {
    test::tiff_page_spec p = pages[k];
    for (std::byte& b : p.samples) b = static_cast<std::byte>(255 - static_cast<int>(b));
    frames.push_back(std::move(p));
  }
  frames[0].description = "ImageJ=1.54f\nimages=18\nslices=9\nframes=2\nhyperstack=true\n";
  const fs::path series = dir_ / "series.tif";
  ASSERT_TRUE(test::write_tiff(series, frames));
  const fs::path out = dir_ / "series.obj";
  ASSERT_EQ(run("extract " + series.string() + " --volume 0 --iso 100 -o " + out.string()).status,
            0);
  EXPECT_EQ(slurp(out), slurp(want));
  expect_bad_input("extract " + series.string() + " --iso 100", "time series of 2 volumes");
}

TEST_F(Cli, mrc_map_gives_the_surface_of_the_same_samples_as_raw) {
  // cube_bytes(9) as an MRC map of IMOD's unsigned bytes (cell 9 Å over 9 samples: spacing 1):
  // the raw file's mesh, byte for byte, also with --world (a right-angled cell at the origin),
  // stored with its axes permuted (columns along Z, rows along X, sections along Y) in gzip, and
  // as the first volume of a volume stack whose second volume is the cube inverted.
  const std::string bytes = cube_bytes(9);
  const fs::path want = raw_cube_mesh("1,1,1");
  test::mrc_file f;
  f.mode = 0;
  f.imod_unsigned = true;
  f.item = 1;
  f.n = {9, 9, 9};
  f.m = {9, 9, 9};
  f.cell = {9.0f, 9.0f, 9.0f};
  f.samples.resize(bytes.size());
  std::memcpy(f.samples.data(), bytes.data(), bytes.size());
  const fs::path map = write_file("cube.mrc", f.bytes());
  expect_same_mesh(map, want);
  const fs::path world = dir_ / "world.obj";
  ASSERT_EQ(
      run("extract " + map.string() + " --iso 100 --full --world -o " + world.string()).status, 0);
  EXPECT_EQ(slurp(world), slurp(want));
  test::mrc_file t = f;
  t.map = {3, 1, 2};
  for (std::size_t s = 0; s < 9; ++s) {
    for (std::size_t r = 0; r < 9; ++r) {
      for (std::size_t c = 0; c < 9; ++c) {
        t.samples[c + 9 * (r + 9 * s)] = f.samples[r + 9 * (s + 9 * c)];  // x = r, y = s, z = c
      }
    }
  }
  expect_same_mesh(write_file("cube_t.map.gz", test::gzip(t.bytes())), want);
  test::mrc_file stack = f;
  stack.ispg = 401;
  stack.n[2] = 18;
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    stack.samples.push_back(static_cast<std::byte>(255 - static_cast<unsigned char>(bytes[i])));
  }
  const fs::path stack_file = write_file("stack.mrcs", stack.bytes());
  const fs::path out = dir_ / "stack.obj";
  ASSERT_EQ(
      run("extract " + stack_file.string() + " --volume 0 --iso 100 -o " + out.string()).status, 0);
  EXPECT_EQ(slurp(out), slurp(want));
  expect_bad_input("extract " + stack_file.string() + " --iso 100", "time series of 2 volumes");
}

TEST_F(Cli, vti_input_gives_the_surface_of_the_same_samples_as_raw) {
  // The same bytes as a raw file and as VTK XML image data, appended raw, base64 in zlib blocks
  // and ascii, on an extent that starts at 0: the same mesh, byte for byte.
  const std::string bytes = cube_bytes(9);
  const fs::path want = raw_cube_mesh("2,1.5,0.5");
  std::vector<std::byte> samples(bytes.size());
  std::memcpy(samples.data(), bytes.data(), bytes.size());
  for (int m = 0; m < 3; ++m) {
    test::vti_file f;
    f.extent = {0, 8, 0, 8, 0, 8};
    f.samples = samples;
    f.origin = "0 0 0";
    f.spacing = "2 1.5 0.5";
    f.how = m == 0 ? test::vti_file::mode::appended_raw
                   : (m == 1 ? test::vti_file::mode::binary : test::vti_file::mode::ascii);
    f.zlib = m == 1;
    f.block_bytes = 100;
    expect_same_mesh(f.write(dir_, "cube" + std::to_string(m)), want);
  }
  // The same cube as a .pvti of three pieces (sharing a layer of points, as VTK's do).
  test::vti_file whole;
  whole.extent = {0, 8, 0, 8, 0, 8};
  whole.samples = samples;
  whole.origin = "0 0 0";
  whole.spacing = "2 1.5 0.5";
  expect_same_mesh(test::write_pvti(dir_, "cube", whole,
                                    {{0, 4, 0, 8, 0, 8}, {4, 8, 0, 3, 0, 8}, {4, 8, 3, 8, 0, 8}},
                                    test::vti_file::mode::appended_raw),
                   want);
  // --world: Direction swaps x and y (a mirror), after Spacing, plus Origin; the winding of
  // every triangle is reversed.
  test::vti_file turned;
  turned.extent = {0, 8, 0, 8, 0, 8};
  turned.samples = samples;
  turned.origin = "10 20 30";
  turned.spacing = "2 1.5 0.5";
  turned.direction = "0 1 0 1 0 0 0 0 1";
  const fs::path in = turned.write(dir_, "turned");
  const fs::path plain = dir_ / "vti_plain.obj";
  const fs::path world = dir_ / "vti_world.obj";
  ASSERT_EQ(run("extract " + in.string() + " --iso 100 -o " + plain.string()).status, 0);
  ASSERT_EQ(run("extract " + in.string() + " --iso 100 --world -o " + world.string()).status, 0);
  const obj_mesh a = read_obj_file(plain);
  const obj_mesh b = read_obj_file(world);
  ASSERT_GT(a.faces.size(), 100u);
  ASSERT_EQ(a.vertices.size(), b.vertices.size());
  ASSERT_EQ(a.faces.size(), b.faces.size());
  for (std::size_t i = 0; i < a.vertices.size(); ++i) {
    // Plain (10 + 2i, 20 + 1.5j, 30 + 0.5k); world (10 + 1.5j, 20 + 2i, 30 + 0.5k).
    const double x = 10.0 + (a.vertices[i][1] - 20.0);
    const double y = 20.0 + (a.vertices[i][0] - 10.0);
    ASSERT_NEAR(b.vertices[i][0], x, 1e-9 * (1 + std::abs(x))) << "vertex " << i;
    ASSERT_NEAR(b.vertices[i][1], y, 1e-9 * (1 + std::abs(y))) << "vertex " << i;
    ASSERT_NEAR(b.vertices[i][2], a.vertices[i][2], 1e-9 * (1 + std::abs(a.vertices[i][2])));
  }
  for (std::size_t t = 0; t < a.faces.size(); ++t) {
    ASSERT_EQ(b.faces[t], (std::array<long, 3>{a.faces[t][0], a.faces[t][2], a.faces[t][1]}));
  }
  // A vector array: one line naming the file, exit 2.
  test::vti_file f;
  f.samples.resize(60);
  const fs::path vectors = write_file("vec.vti", [&] {
    std::string t = f.text();
    const std::string one = "Name=\"density\" NumberOfComponents=\"1\"";
    return t.replace(t.find(one), one.size(), "Name=\"density\" NumberOfComponents=\"3\"");
  }());
  expect_bad_input("extract " + vectors.string() + " --iso 100", "vec.vti: point array");
}

// A NIfTI-1 file of cube_bytes(9) whose sform mirrors x and rotates a little, as MRI files do;
// spacing 2, 1.5, 0.5 in pixdim.
const std::array<std::array<float, 4>, 3> oriented_srow{
    {{-1.8f, 0.2f, 0.0f, 90.5f}, {0.1f, 1.4f, -0.05f, -126.0f}, {0.0f, 0.1f, 0.5f, -72.25f}}};
std::string oriented_nifti() {
  std::string nii = test::nifti1_file({9, 9, 9}, 2, 8, {2.0f, 1.5f, 0.5f}, cube_bytes(9));
  const std::int16_t sform_code = 1;
  std::memcpy(nii.data() + 254, &sform_code, sizeof sform_code);
  for (std::size_t r = 0; r < 3; ++r) {
    std::memcpy(nii.data() + 280 + 16 * r, oriented_srow[r].data(), 16);
  }
  return nii;
}

TEST_F(Cli, world_writes_the_coordinates_a_nifti_nrrd_or_metaimage_file_declares) {
  // Without --world the vertices are at origin + index × spacing (the origin being the sform's
  // translation); with it, at sform · (index, 1), and every triangle's winding is reversed (the
  // map mirrors).
  const auto& srow = oriented_srow;
  const fs::path in = write_file("oriented.nii", oriented_nifti());
  const fs::path plain = dir_ / "plain.obj";
  const fs::path world = dir_ / "world.obj";
  ASSERT_EQ(run("extract " + in.string() + " --iso 100 -o " + plain.string()).status, 0);
  const run_result r = run("extract " + in.string() + " --iso 100 --world -o " + world.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const obj_mesh a = read_obj_file(plain);
  const obj_mesh b = read_obj_file(world);
  ASSERT_GT(a.faces.size(), 100u);
  ASSERT_EQ(a.vertices.size(), b.vertices.size());
  ASSERT_EQ(a.faces.size(), b.faces.size());
  const std::array<double, 3> spacing{2.0, 1.5, 0.5};
  for (std::size_t i = 0; i < a.vertices.size(); ++i) {
    for (std::size_t q = 0; q < 3; ++q) {
      double want = static_cast<double>(srow[q][3]);
      for (std::size_t c = 0; c < 3; ++c) {
        // Without --world the origin is the sform's translation: index = (p − origin) / spacing.
        const double index = (a.vertices[i][c] - static_cast<double>(srow[c][3])) / spacing[c];
        want += static_cast<double>(srow[q][c]) * index;
      }
      ASSERT_NEAR(b.vertices[i][q], want, 1e-9 * (1 + std::abs(want))) << "vertex " << i;
    }
  }
  for (std::size_t t = 0; t < a.faces.size(); ++t) {
    ASSERT_EQ(b.faces[t], (std::array<long, 3>{a.faces[t][0], a.faces[t][2], a.faces[t][1]}));
  }
  // A NRRD's space directions and origin: x mirrored, spacing 2, 1.5, 0.5.
  const fs::path nrrd = write_file("oriented.nrrd",
                                   "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 9 9 9\n"
                                   "space: left-posterior-superior\n"
                                   "space directions: (-2,0,0) (0,1.5,0) (0,0,0.5)\n"
                                   "space origin: (10,20,30)\nencoding: raw\n\n" +
                                       cube_bytes(9));
  const fs::path nrrd_plain = dir_ / "nrrd_plain.obj";
  const fs::path nrrd_world = dir_ / "nrrd_world.obj";
  ASSERT_EQ(run("extract " + nrrd.string() + " --iso 100 -o " + nrrd_plain.string()).status, 0);
  ASSERT_EQ(run("extract " + nrrd.string() + " --iso 100 --world -o " + nrrd_world.string()).status,
            0);
  const obj_mesh c = read_obj_file(nrrd_plain);
  const obj_mesh d = read_obj_file(nrrd_world);
  ASSERT_EQ(c.vertices.size(), d.vertices.size());
  ASSERT_EQ(c.faces.size(), d.faces.size());
  for (std::size_t i = 0; i < c.vertices.size(); ++i) {
    // Plain: origin + index × |direction|; world: origin + index × direction.
    const double x = 10.0 - (c.vertices[i][0] - 10.0);
    ASSERT_NEAR(d.vertices[i][0], x, 1e-9 * (1 + std::abs(x))) << "vertex " << i;
    ASSERT_NEAR(d.vertices[i][1], c.vertices[i][1], 1e-9 * (1 + std::abs(c.vertices[i][1])));
    ASSERT_NEAR(d.vertices[i][2], c.vertices[i][2], 1e-9 * (1 + std::abs(c.vertices[i][2])));
  }
  for (std::size_t t = 0; t < c.faces.size(); ++t) {
    ASSERT_EQ(d.faces[t], (std::array<long, 3>{c.faces[t][0], c.faces[t][2], c.faces[t][1]}));
  }
  // A MetaImage TransformMatrix: row i is index axis i's direction (x and y swapped here, a
  // mirror), scaled by ElementSpacing, plus Offset.
  const fs::path mha = write_file("oriented.mha",
                                  "NDims = 3\nDimSize = 9 9 9\nElementSpacing = 2 1.5 0.5\n"
                                  "Offset = 10 20 30\nTransformMatrix = 0 1 0 1 0 0 0 0 1\n"
                                  "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n" +
                                      cube_bytes(9));
  const fs::path mha_plain = dir_ / "mha_plain.obj";
  const fs::path mha_world = dir_ / "mha_world.obj";
  ASSERT_EQ(run("extract " + mha.string() + " --iso 100 -o " + mha_plain.string()).status, 0);
  ASSERT_EQ(run("extract " + mha.string() + " --iso 100 --world -o " + mha_world.string()).status,
            0);
  const obj_mesh e = read_obj_file(mha_plain);
  const obj_mesh g = read_obj_file(mha_world);
  ASSERT_GT(e.faces.size(), 100u);
  ASSERT_EQ(e.vertices.size(), g.vertices.size());
  for (std::size_t i = 0; i < e.vertices.size(); ++i) {
    // Plain (10 + 2i, 20 + 1.5j, 30 + 0.5k); world (10 + 1.5j, 20 + 2i, 30 + 0.5k).
    const double x = 10.0 + (e.vertices[i][1] - 20.0);
    const double y = 20.0 + (e.vertices[i][0] - 10.0);
    ASSERT_NEAR(g.vertices[i][0], x, 1e-9 * (1 + std::abs(x))) << "vertex " << i;
    ASSERT_NEAR(g.vertices[i][1], y, 1e-9 * (1 + std::abs(y))) << "vertex " << i;
    ASSERT_NEAR(g.vertices[i][2], e.vertices[i][2], 1e-9 * (1 + std::abs(e.vertices[i][2])));
  }
  for (std::size_t t = 0; t < e.faces.size(); ++t) {
    ASSERT_EQ(g.faces[t], (std::array<long, 3>{e.faces[t][0], e.faces[t][2], e.faces[t][1]}));
  }
  // Inputs without an orientation, and --spacing beside --world, are refused.
  expect_bad_input("extract " + write_file("c.raw", cube_bytes(8)).string() +
                       " --dims 8,8,8 --type u8 --iso 100 --world",
                   "--world");
  const fs::path bare =
      write_file("bare.nii", test::nifti1_file({9, 9, 9}, 2, 8, {1, 1, 1}, cube_bytes(9)));
  expect_bad_input("extract " + bare.string() + " --iso 100 --world",
                   "bare.nii: --world: the file declares no orientation");
  expect_bad_input("extract " + in.string() + " --iso 100 --world --spacing 1,1,1", "--spacing");
}

// --normals: a unit normal per vertex in PLY (nx ny nz) and OBJ (vn, faces naming them), the
// time in the statistics; refused for STL. On a linear field f = a · index the normal is known
// everywhere: −(a / spacing) normalised in the file's physical frame, and with --world, where
// index = M⁻¹ (x − t), −M⁻ᵀ a normalised (M the sform's 3 × 3 part).
TEST_F(Cli, normals_give_every_vertex_a_unit_normal_that_turns_with_world) {
  const fs::path ply = dir_ / "demo.ply";
  const fs::path stats = dir_ / "demo.json";
  run_result r = run("extract --demo --max-triangles 20000 --threads 1 --normals -o " +
                     ply.string() + " --stats-json " + stats.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const triangle_mesh m = read_ply(ply);
  ASSERT_GT(m.vertices.size(), 1000u);
  ASSERT_EQ(m.normals.size(), m.vertices.size());
  for (const auto& n : m.normals) {
    ASSERT_NEAR(std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), 1.0, 1e-6);
  }
  const std::string json = slurp(stats);
  EXPECT_NE(json.find("\"normals\": true"), std::string::npos) << json;
  EXPECT_GE(json_field(json, "normals_ms"), 0.0);

  const fs::path obj = dir_ / "demo.obj";
  r = run("extract --demo --max-triangles 20000 --threads 1 --normals -o " + obj.string());
  ASSERT_EQ(r.status, 0) << r.err;
  std::size_t v = 0;
  std::size_t vn = 0;
  std::size_t named = 0;
  std::istringstream lines(slurp(obj));
  for (std::string line; std::getline(lines, line);) {
    v += line.rfind("v ", 0) == 0 ? 1u : 0u;
    vn += line.rfind("vn ", 0) == 0 ? 1u : 0u;
    named += line.rfind("f ", 0) == 0 && line.find("//") != std::string::npos ? 1u : 0u;
  }
  EXPECT_EQ(v, m.vertices.size());
  EXPECT_EQ(vn, v);
  EXPECT_EQ(named, m.triangles.size());

  const fs::path stl = dir_ / "demo.stl";
  r = run("extract --demo --normals -o " + stl.string());
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--normals"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("facet"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(stl));

  // f = 10 i + 5 j + 2 k (u8) in the oriented NIfTI's frame.
  const std::array<double, 3> a{10.0, 5.0, 2.0};
  std::string bytes(9 * 9 * 9, '\0');
  for (int k = 0; k < 9; ++k) {
    for (int j = 0; j < 9; ++j) {
      for (int i = 0; i < 9; ++i) {
        bytes[static_cast<std::size_t>(i + 9 * (j + 9 * k))] =
            static_cast<char>(10 * i + 5 * j + 2 * k);
      }
    }
  }
  std::string nii = oriented_nifti();
  nii.replace(nii.size() - bytes.size(), bytes.size(), bytes);
  const fs::path in = write_file("linear.nii", nii);
  const fs::path plain = dir_ / "plain.ply";
  const fs::path world = dir_ / "world.ply";
  ASSERT_EQ(run("extract " + in.string() + " --iso 50 --normals -o " + plain.string()).status, 0);
  ASSERT_EQ(
      run("extract " + in.string() + " --iso 50 --normals --world -o " + world.string()).status, 0);
  const triangle_mesh p = read_ply(plain);
  const triangle_mesh q = read_ply(world);
  ASSERT_GT(p.vertices.size(), 20u);
  ASSERT_EQ(q.normals.size(), p.normals.size());
  const std::array<double, 3> spacing{2.0, 1.5, 0.5};
  std::array<double, 3> want_plain{};
  for (std::size_t c = 0; c < 3; ++c) want_plain[c] = -a[c] / spacing[c];
  // M⁻¹ by the adjugate; −M⁻ᵀ a has components −Σ_c M⁻¹[c][r] a[c].
  std::array<std::array<double, 3>, 3> mm{};
  for (std::size_t i = 0; i < 3; ++i) {
    for (std::size_t j = 0; j < 3; ++j) mm[i][j] = static_cast<double>(oriented_srow[i][j]);
  }
  const double det = mm[0][0] * (mm[1][1] * mm[2][2] - mm[1][2] * mm[2][1]) -
                     mm[0][1] * (mm[1][0] * mm[2][2] - mm[1][2] * mm[2][0]) +
                     mm[0][2] * (mm[1][0] * mm[2][1] - mm[1][1] * mm[2][0]);
  std::array<std::array<double, 3>, 3> inv{};
  inv[0][0] = (mm[1][1] * mm[2][2] - mm[1][2] * mm[2][1]) / det;
  inv[0][1] = (mm[0][2] * mm[2][1] - mm[0][1] * mm[2][2]) / det;
  inv[0][2] = (mm[0][1] * mm[1][2] - mm[0][2] * mm[1][1]) / det;
  inv[1][0] = (mm[1][2] * mm[2][0] - mm[1][0] * mm[2][2]) / det;
  inv[1][1] = (mm[0][0] * mm[2][2] - mm[0][2] * mm[2][0]) / det;
  inv[1][2] = (mm[0][2] * mm[1][0] - mm[0][0] * mm[1][2]) / det;
  inv[2][0] = (mm[1][0] * mm[2][1] - mm[1][1] * mm[2][0]) / det;
  inv[2][1] = (mm[0][1] * mm[2][0] - mm[0][0] * mm[2][1]) / det;
  inv[2][2] = (mm[0][0] * mm[1][1] - mm[0][1] * mm[1][0]) / det;
  std::array<double, 3> want_world{};
  for (std::size_t r2 = 0; r2 < 3; ++r2) {
    for (std::size_t c = 0; c < 3; ++c) want_world[r2] -= inv[c][r2] * a[c];
  }
  const auto unit = [](std::array<double, 3> x) {
    const double l = std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    return std::array<double, 3>{x[0] / l, x[1] / l, x[2] / l};
  };
  want_plain = unit(want_plain);
  want_world = unit(want_world);
  for (std::size_t i = 0; i < p.normals.size(); ++i) {
    for (std::size_t c = 0; c < 3; ++c) {
      ASSERT_NEAR(p.normals[i][c], want_plain[c], 1e-6) << "vertex " << i;
      ASSERT_NEAR(q.normals[i][c], want_world[c], 1e-6) << "vertex " << i;
    }
  }
}

}  // namespace
}  // namespace progiso

namespace progiso {
namespace {

std::string pgm_bytes(int w, int h) {
  std::string s = "P5\n# test image\n" + std::to_string(w) + " " + std::to_string(h) + "\n255\n";
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) s += static_cast<char>((x * 13 + y * 7) % 250);
  return s;
}

TEST_F(Cli, contour_writes_svg_obj_frames_and_statistics) {
  const fs::path in = write_file("img.pgm", pgm_bytes(40, 30));
  const fs::path svg = dir_ / "c.svg";
  const fs::path frames = dir_ / "frames";
  const fs::path stats = dir_ / "c.json";
  const run_result r = run("contour " + in.string() + " -o " + svg.string() + " --iso 60,120 " +
                           "--frames " + frames.string() + " --stats-json " + stats.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(slurp(svg).find("<svg"), std::string::npos);
  std::size_t n = 0;
  for (const auto& e : fs::directory_iterator(frames))
    n += e.path().extension() == ".svg" ? 1u : 0u;
  EXPECT_GE(n, 3u);
  const std::string json = slurp(stats);
  for (const char* key : {"\"splits\"", "\"segments\"", "\"polylines\"", "\"cases\"",
                          "\"EdgeFlip\"", "\"time_to_first_contour_ms\""}) {
    EXPECT_NE(json.find(key), std::string::npos) << key;
  }
  const fs::path obj = dir_ / "c.obj";
  ASSERT_EQ(run("contour " + in.string() + " -o " + obj.string() + " --iso 60 --error 5").status,
            0);
  const std::string text = slurp(obj);
  EXPECT_NE(text.find("\nl "), std::string::npos);
  EXPECT_NE(text.find(" 0\n"), std::string::npos);  // v x y 0
}

TEST_F(Cli, contour_smoothing_grows_stage_by_stage_into_frames) {
  const fs::path in = write_file("img.pgm", pgm_bytes(40, 30));
  const fs::path frames = dir_ / "frames";
  const fs::path stats = dir_ / "c.json";
  const fs::path obj = dir_ / "c.obj";
  const run_result r =
      run("contour " + in.string() + " -o " + (dir_ / "c.svg").string() +
          " --iso 100 --smooth 1 --frames " + frames.string() + " --stats-json " + stats.string());
  ASSERT_EQ(r.status, 0) << r.err;
  std::size_t n = 0;
  for (const auto& e : fs::directory_iterator(frames))
    n += e.path().extension() == ".svg" ? 1u : 0u;
  EXPECT_GE(n, 3u);
  const std::string json = slurp(stats);
  EXPECT_NE(json.find("\"field_dims\": [79, 59, 1]"), std::string::npos) << json;
  EXPECT_GT(json_field(json, "subdivided_samples"), 100.0) << json;
  ASSERT_EQ(run("contour " + in.string() + " -o " + obj.string() +
                " --iso 100 --smooth-from 1 --smooth-region 0,0,20,29 --alpha 1.5")
                .status,
            0);
  EXPECT_NE(slurp(obj).find("\nl "), std::string::npos);
}

TEST_F(Cli, contour_bad_inputs_exit_2_with_one_clear_line_and_no_output) {
  const fs::path good = write_file("img.pgm", pgm_bytes(20, 20));
  const std::string g = good.string();
  const auto bad = [&](const std::string& args, const std::string& needle) {
    const run_result r = run("contour " + args + " -o " + (dir_ / "out.svg").string());
    EXPECT_EQ(r.status, 2) << args;
    EXPECT_NE(r.err.find(needle), std::string::npos) << "stderr: " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "stderr: " << r.err;
    EXPECT_FALSE(fs::exists(dir_ / "out.svg"));
  };
  bad((dir_ / "missing.pgm").string() + " --iso 10", "missing.pgm");
  bad(write_file("bad.pgm", "P2\n2 2\n255\n1 2 3 4\n").string() + " --iso 10", "bad.pgm");
  bad(write_file("short.pgm", "P5\n20 20\n255\nabc").string() + " --iso 10", "short.pgm");
  bad(write_file("x.tif", "II*").string() + " --iso 10", "x.tif");
  bad(g + " --iso nan", "finite");
  bad(g + " --iso 10,", "--iso");
  bad(g, "--iso");
  bad(g + " --iso 10 --full --max-segments 5", "at most one");
  bad(g + " --iso 10 --smooth 9", "--smooth");
  bad(g + " --iso 10 --smooth-from 5", "K = 5");
  bad(g + " --iso 10 --smooth 1 --alpha -1", "--alpha");
  bad(g + " --iso 10 --smooth 1 --smooth-region 0,0,0,5,5,5", "--smooth-region");
  bad(g + " --iso 10 --smooth 1 --smooth-region 0,0,20,5", "region");
  const run_result r = run("contour " + g + " --iso 10 -o " + (dir_ / "c.ply").string());
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find(".obj or .svg"), std::string::npos) << r.err;
}

TEST_F(Cli, extract_reads_an_ome_zarr_level_and_refuses_a_level_it_lacks) {
  // Two levels of cube_bytes(9), raw chunks: level 0 the cube, level 1 every second sample.
  const std::string cube = cube_bytes(9);
  std::string half;
  for (int z = 0; z < 9; z += 2) {
    for (int y = 0; y < 9; y += 2) {
      for (int x = 0; x < 9; x += 2) half += cube[static_cast<std::size_t>((z * 9 + y) * 9 + x)];
    }
  }
  const fs::path img = dir_ / "img.zarr";
  fs::create_directories(img / "0");
  fs::create_directories(img / "1");
  const auto zarray = [](int n) {
    const std::string s = std::to_string(n);
    return "{\"zarr_format\": 2, \"shape\": [" + s + ", " + s + ", " + s + "], \"chunks\": [" + s +
           ", " + s + ", " + s +
           "], \"dtype\": \"|u1\", \"compressor\": null, \"fill_value\": 0, \"order\": "
           "\"C\", \"filters\": null}";
  };
  write_file("img.zarr/.zattrs",
             "{\"multiscales\": [{\"version\": \"0.4\", \"axes\": [{\"name\": \"z\", "
             "\"type\": \"space\"}, {\"name\": \"y\", \"type\": \"space\"}, {\"name\": \"x\", "
             "\"type\": \"space\"}], \"datasets\": [{\"path\": \"0\"}, {\"path\": \"1\", "
             "\"coordinateTransformations\": [{\"type\": \"scale\", \"scale\": [2, 2, 2]}]}]}]}");
  write_file("img.zarr/0/.zarray", zarray(9));
  write_file("img.zarr/0/0.0.0", cube);
  write_file("img.zarr/1/.zarray", zarray(5));
  write_file("img.zarr/1/0.0.0", half);
  // Level 0 is the raw cube: the same mesh.
  expect_same_mesh(img, raw_cube_mesh("1,1,1"));
  // Level 1: its grid and spacing, named in the report and the statistics.
  const fs::path coarse = dir_ / "coarse.ply";
  const fs::path stats = dir_ / "coarse.json";
  const run_result r = run("extract " + img.string() + " --level 1 --iso 100 --full -o " +
                           coarse.string() + " --stats-json " + stats.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("img.zarr level 1, 5x5x5 u8"), std::string::npos) << r.err;
  EXPECT_NE(slurp(stats).find("\"level\": 1,"), std::string::npos) << slurp(stats);
  expect_bad_input("extract " + img.string() + " --iso 100 --level 2",
                   "img.zarr: level 2 was chosen, but the image has 2 levels (0 to 1)");
  expect_bad_input("extract " + img.string() + " --iso 100 --level x", "--level");
  expect_bad_input("extract " + (dir_ / "c.raw").string() +
                       " --dims 9,9,9 --type u8 --iso 100 "
                       "--level 1",
                   "--level picks a level of an OME-Zarr image");
  fs::remove(img / "1" / "0.0.0");
  expect_bad_input("extract " + img.string() + " --iso 100 --level 1",
                   "0 of the 1 chunks of the array are present");
}

TEST_F(Cli, a_deadline_on_an_ome_zarr_pyramid_reads_and_meshes_coarse_first) {
  // Three levels of a ball, each sampled at its own cells' centres: level k is not every 2^k-th
  // sample of level 0, but a field of its own (as averaging writers make them).
  const fs::path img = dir_ / "ball.zarr";
  std::string datasets;
  for (int k = 0; k < 3; ++k) {
    const int n = (32 >> k) + 1;
    const double step = static_cast<double>(1 << k);
    std::string samples;
    for (int z = 0; z < n; ++z) {
      for (int y = 0; y < n; ++y) {
        for (int x = 0; x < n; ++x) {
          const double cx = (x + 0.25 * k) * step - 16.3, cy = (y + 0.25 * k) * step - 15.8,
                       cz = (z + 0.25 * k) * step - 16.1;
          samples += static_cast<char>(static_cast<unsigned char>(
              std::min(255.0, 8.0 * std::sqrt(cx * cx + cy * cy + cz * cz))));
        }
      }
    }
    const std::string d = std::to_string(k), ns = std::to_string(n);
    fs::create_directories(img / d);
    write_file("ball.zarr/" + d + "/.zarray",
               "{\"zarr_format\": 2, \"shape\": [" + ns + ", " + ns + ", " + ns +
                   "], \"chunks\": [8, 8, 8], \"dtype\": \"|u1\", \"compressor\": null, "
                   "\"fill_value\": 0, \"order\": \"C\", \"filters\": null}");
    const int chunks = (n + 7) / 8;
    for (int cz = 0; cz < chunks; ++cz) {
      for (int cy = 0; cy < chunks; ++cy) {
        for (int cx = 0; cx < chunks; ++cx) {
          std::string chunk(512, '\0');
          for (int z = 0; z < 8; ++z) {
            for (int y = 0; y < 8; ++y) {
              for (int x = 0; x < 8; ++x) {
                const int gz = cz * 8 + z, gy = cy * 8 + y, gx = cx * 8 + x;
                if (gz < n && gy < n && gx < n) {
                  chunk[static_cast<std::size_t>((z * 8 + y) * 8 + x)] =
                      samples[static_cast<std::size_t>((gz * n + gy) * n + gx)];
                }
              }
            }
          }
          write_file("ball.zarr/" + d + "/" + std::to_string(cz) + "." + std::to_string(cy) + "." +
                         std::to_string(cx),
                     chunk);
        }
      }
    }
    datasets += std::string(k > 0 ? ", " : "") + "{\"path\": \"" + d +
                "\", \"coordinateTransformations\": [{\"type\": \"scale\", \"scale\": [" +
                std::to_string(step) + ", " + std::to_string(step) + ", " + std::to_string(step) +
                "]}]}";
  }
  write_file("ball.zarr/.zattrs",
             "{\"multiscales\": [{\"version\": \"0.4\", \"axes\": [\"z\", "
             "\"y\", \"x\"], \"datasets\": [" +
                 datasets + "]}]}");
  const auto extract = [&](const std::string& how, const std::string& name) {
    const run_result r = run("extract " + img.string() + " --iso 120 " + how + " -o " +
                             (dir_ / (name + ".ply")).string() + " --stats-json " +
                             (dir_ / (name + ".json")).string());
    EXPECT_EQ(r.status, 0) << how << ": " << r.err;
    return std::make_pair(slurp(dir_ / (name + ".ply")), slurp(dir_ / (name + ".json")));
  };
  const auto level2 = extract("--level 2 --full", "level2");
  const auto level0 = extract("--level 0 --full", "level0");
  ASSERT_NE(level2.first, level0.first);
  // A deadline already passed: the coarsest level, read and meshed whole, nothing else read.
  const auto passed = extract("--time-ms 0", "passed");
  EXPECT_EQ(passed.first, level2.first);
  EXPECT_NE(passed.second.find("\"level\": 2,"), std::string::npos) << passed.second;
  EXPECT_NE(passed.second.find("\"levels_read\": 1,"), std::string::npos) << passed.second;
  // Time enough: every level read, coarsest first, and the finest level's finest surface.
  const auto ample = extract("--time-ms 60000", "ample");
  EXPECT_EQ(ample.first, level0.first);
  EXPECT_NE(ample.second.find("\"level\": 0,"), std::string::npos) << ample.second;
  EXPECT_NE(ample.second.find("\"levels_read\": 3,"), std::string::npos) << ample.second;
  EXPECT_NE(ample.second.find("\"coarse_first\": true,"), std::string::npos) << ample.second;
}

TEST_F(Cli, an_imaris_pyramid_takes_level_and_volume_and_reads_coarse_first_by_a_deadline) {
  if (std::string_view(PROGISO_H5PY_PYTHON).empty()) {
    GTEST_SKIP() << "python3 with h5py (python3-h5py) not found";
  }
  // Two channels, three levels of a ball, each level sampled at its own cells' centres (a field
  // of its own, as Imaris's block means are); channel 1 is the ball shifted by 3.
  const fs::path ims = dir_ / "ball.ims";
  const fs::path script = dir_ / "write.py";
  write_file("write.py", R"(
import sys, numpy as np, h5py
def text(o, k, v): o.attrs.create(k, np.array(list(v), dtype='|S1'))
with h5py.File(sys.argv[1], 'w') as f:
    text(f, 'ImarisDataSet', 'ImarisDataSet')
    for k in range(3):
        n, step = (32 >> k) + 1, float(1 << k)
        i = (np.arange(n) + 0.25 * k) * step
        z, y, x = np.meshgrid(i - 16.1, i - 15.8, i - 16.3, indexing='ij')
        for c in range(2):
            g = f.create_group('DataSet/ResolutionLevel %d/TimePoint 0/Channel %d' % (k, c))
            for a in 'XYZ': text(g, 'ImageSize' + a, str(n))
            v = np.minimum(255, 8 * np.sqrt(x * x + y * y + z * z) + 3 * c).astype(np.uint8)
            g.create_dataset('Data', data=v, chunks=(8, 8, 8), compression='gzip')
)");
  ASSERT_EQ(
      std::system(
          (std::string(PROGISO_H5PY_PYTHON) + " " + script.string() + " " + ims.string()).c_str()),
      0);
  const auto extract = [&](const std::string& how, const std::string& name) {
    const run_result r = run("extract " + ims.string() + " --iso 120 " + how + " -o " +
                             (dir_ / (name + ".ply")).string() + " --stats-json " +
                             (dir_ / (name + ".json")).string());
    EXPECT_EQ(r.status, 0) << how << ": " << r.err;
    return std::make_pair(slurp(dir_ / (name + ".ply")), slurp(dir_ / (name + ".json")));
  };
  const auto level2 = extract("--volume 1 --level 2 --full", "level2");
  const auto level0 = extract("--volume 1 --level 0 --full", "level0");
  ASSERT_NE(level2.first, level0.first);
  ASSERT_NE(level0.first, extract("--volume 0 --level 0 --full", "other").first)
      << "channel 0 and channel 1 gave the same surface";
  const run_result named = run("extract " + ims.string() + " --volume 1 --level 2 --iso 120 " +
                               "--full -o " + (dir_ / "named.ply").string());
  EXPECT_NE(named.err.find("ball.ims volume 1 level 2, 9x9x9 u8"), std::string::npos) << named.err;
  // A passed deadline: the coarsest level alone; time enough: the finest level's surface.
  const auto passed = extract("--volume 1 --time-ms 0", "passed");
  EXPECT_EQ(passed.first, level2.first);
  EXPECT_NE(passed.second.find("\"levels_read\": 1,"), std::string::npos) << passed.second;
  const auto ample = extract("--volume 1 --time-ms 60000", "ample");
  EXPECT_EQ(ample.first, level0.first);
  EXPECT_NE(ample.second.find("\"levels_read\": 3,"), std::string::npos) << ample.second;
  expect_bad_input("extract " + ims.string() + " --iso 120 --volume 1 --level 3",
                   "ball.ims: level 3 was chosen, but the image has 3 levels (0 to 2)");
  expect_bad_input("extract " + ims.string() + " --iso 120 --level 0",
                   "ball.ims: a time series of 2 volumes (timepoints x channels = 2)");
}

}  // namespace
}  // namespace progiso
