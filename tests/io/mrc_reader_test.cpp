// Tests for progiso's MRC and CCP4 map reader (io/detail/mrc_reader.hpp, through
// read_mrc(), read_volume(), read_volume_world() and volume_input_files()).
//
// Differential: mrcfile (the CCP-EM project's MRC2014 library, Debian's python3-mrcfile, a
// test-only dependency found at configure time) writes maps of every mode it writes, in both
// byte orders, plain and gzip, and a volume stack; numpy gives the samples it stored, which
// progiso's must equal. Where mrcfile is absent those tests skip with a message.
//
// Own files (tests/support/mrc_files.hpp): axes stored in each of the six orders, the origin
// from ORIGIN or from the start indices, oblique cells, IMOD's unsigned bytes, files without a
// machine stamp, extended headers; hostile headers and short, truncated and corrupt data, each
// refused with one line naming the file.
#include <progiso/io/volume_io.hpp>

#include <gtest/gtest.h>

#include "support/io_test_helpers.hpp"
#include "support/mrc_files.hpp"
#include "support/scratch_dir.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <numeric>
#include <string>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/io/detail/mrc_reader.hpp>

namespace {

namespace fs = std::filesystem;
using progiso::index3;
using progiso::sample_type;
using progiso::test::contains;
using progiso::test::gzip;
using progiso::test::mrc_file;
using progiso::test::read_whole_file;
using progiso::test::stored_sample;
using progiso::test::write_file;
constexpr auto error_naming = [](const fs::path& file, auto&& f) {
  return progiso::test::error_message_naming(file, f);
};

class scratch_dir : public progiso::test::scratch_dir {
 public:
  scratch_dir() : progiso::test::scratch_dir("progiso-mrc-reader-test-") {}
};

/// Runs `script` with the python that imports mrcfile, `args` after it; false when it fails.
bool run_mrcfile_script(const scratch_dir& dir, const std::string& script,
                        const std::string& args) {
  const fs::path file = dir / "write_maps.py";
  std::ofstream(file) << script;
  const std::string command =
      std::string(PROGISO_MRCFILE_PYTHON) + " " + file.string() + " " + args;
  return std::system(command.c_str()) == 0;
}

/// The doubles of a file of little-endian f64 (numpy's tofile on '<f8').
std::vector<double> read_doubles(const fs::path& file) {
  const std::string bytes = read_whole_file(file);
  std::vector<double> out(bytes.size() / 8);
  for (std::size_t i = 0; i < out.size(); ++i) {
    std::array<char, 8> b{};
    std::memcpy(b.data(), bytes.data() + 8 * i, 8);
    if (std::endian::native == std::endian::big) std::reverse(b.begin(), b.end());
    out[i] = std::bit_cast<double>(b);
  }
  return out;
}

void expect_samples(const progiso::volume& v, const std::vector<double>& want,
                    const std::string& what) {
  ASSERT_EQ(static_cast<std::size_t>(v.dims()[0] * v.dims()[1] * v.dims()[2]), want.size()) << what;
  for (std::size_t i = 0; i < want.size(); ++i) {
    ASSERT_EQ(stored_sample(v, i), want[i]) << what << " sample " << i;
  }
}

constexpr const char* mrcfile_maps = R"(
import sys, numpy as np, mrcfile
out = sys.argv[1]
rng = np.random.default_rng(7)
shape = (5, 4, 6)
for dt in ['i1', '<i2', '>i2', '<u2', '>u2', '<f4', '>f4', '<f2', '>f2']:
    for comp in [None, 'gzip']:
        if dt.endswith('f4'):
            d = (rng.standard_normal(shape) * 100).astype(dt)
        elif dt.endswith('f2'):
            d = (rng.standard_normal(shape) * 10).astype(dt)
            d.flat[0] = 6e-8
            d.flat[1] = -3.0e-5
            d.flat[2] = 65504
        else:
            info = np.iinfo(np.dtype(dt))
            d = rng.integers(info.min, info.max, size=shape, endpoint=True).astype(dt)
        name = out + '/' + dt.replace('<', 'le').replace('>', 'be') + ('.mrc.gz' if comp else '.mrc')
        with mrcfile.new(name, overwrite=True, compression=comp) as m:
            m.set_data(d)
            m.voxel_size = (1.5, 2.0, 2.5)
            m.header.origin = (10.0, -20.0, 30.5)
        d.astype('<f8').tofile(name + '.expected')
stack = (rng.standard_normal((3, 4, 5, 6)) * 50).astype('<f4')
with mrcfile.new(out + '/stack.mrcs', overwrite=True) as m:
    m.set_data(stack)
    m.voxel_size = 1.25
for k in range(3):
    stack[k].astype('<f8').tofile(out + '/stack.mrcs.' + str(k))
)";

bool have_mrcfile() { return std::string_view(PROGISO_MRCFILE_PYTHON).size() > 0; }

TEST(MrcReader, agrees_with_mrcfile_on_every_mode_byte_order_and_compression) {
  if (!have_mrcfile()) GTEST_SKIP() << "python3 with mrcfile (python3-mrcfile) not found";
  scratch_dir dir;
  ASSERT_TRUE(run_mrcfile_script(dir, mrcfile_maps, dir.path().string()));
  struct expected_type {
    std::string name;
    sample_type type;
  };
  const std::vector<expected_type> cases{
      {"i1", sample_type::i8},    {"lei2", sample_type::i16}, {"bei2", sample_type::i16},
      {"leu2", sample_type::u16}, {"beu2", sample_type::u16}, {"lef4", sample_type::f32},
      {"bef4", sample_type::f32}, {"lef2", sample_type::f32}, {"bef2", sample_type::f32}};
  for (const expected_type& c : cases) {
    for (const std::string ext : {".mrc", ".mrc.gz"}) {
      const fs::path file = dir / (c.name + ext);
      const progiso::volume v = progiso::read_mrc(file);
      EXPECT_EQ(v.type(), c.type) << file;
      EXPECT_EQ(v.dims(), (index3{6, 4, 5})) << file;
      EXPECT_EQ(v.spacing(), (std::array<double, 3>{1.5, 2.0, 2.5})) << file;
      EXPECT_EQ(v.origin(), (std::array<double, 3>{10.0, -20.0, 30.5})) << file;
      fs::path expected = file;
      expected += ".expected";
      expect_samples(v, read_doubles(expected), file.string());
    }
  }
  // The half floats mrcfile stored include a subnormal, a negative subnormal and the largest.
  const progiso::volume halves = progiso::read_mrc(dir / "bef2.mrc");
  EXPECT_EQ(stored_sample(halves, 0), std::ldexp(1.0, -24));  // 6e-8 rounds to 2^-24
  EXPECT_EQ(stored_sample(halves, 2), 65504.0);
}

TEST(MrcReader, reads_the_chosen_volume_of_a_volume_stack_mrcfile_writes) {
  if (!have_mrcfile()) GTEST_SKIP() << "python3 with mrcfile (python3-mrcfile) not found";
  scratch_dir dir;
  ASSERT_TRUE(run_mrcfile_script(dir, mrcfile_maps, dir.path().string()));
  const fs::path file = dir / "stack.mrcs";
  for (std::int64_t k = 0; k < 3; ++k) {
    const progiso::volume v = progiso::read_mrc(file, {.volume = k});
    EXPECT_EQ(v.dims(), (index3{6, 5, 4}));
    EXPECT_EQ(v.spacing(), (std::array<double, 3>{1.25, 1.25, 1.25}));
    expect_samples(v, read_doubles(dir / ("stack.mrcs." + std::to_string(k))),
                   "volume " + std::to_string(k));
  }
  const std::string unchosen = error_naming(file, [&] { (void)progiso::read_mrc(file); });
  EXPECT_TRUE(contains(unchosen, "time series of 3 volumes (NZ / MZ = 3)")) << unchosen;
  const std::string beyond =
      error_naming(file, [&] { (void)progiso::read_mrc(file, {.volume = 3}); });
  EXPECT_TRUE(contains(beyond, "0 to 2")) << beyond;
}

/// A map of float32 samples whose value names its place: 100·x + 10·y + z, stored with columns,
/// rows and sections along `map` (MAPC, MAPR, MAPS), the grid being dims along X, Y, Z.
mrc_file coded_map(const std::array<std::int32_t, 3>& map, const index3& dims) {
  mrc_file f;
  f.map = map;
  std::array<std::int64_t, 3> n{};
  for (std::size_t i = 0; i < 3; ++i) n[i] = dims[static_cast<std::size_t>(map[i] - 1)];
  f.n = {static_cast<std::int32_t>(n[0]), static_cast<std::int32_t>(n[1]),
         static_cast<std::int32_t>(n[2])};
  f.m = {static_cast<std::int32_t>(dims[0]), static_cast<std::int32_t>(dims[1]),
         static_cast<std::int32_t>(dims[2])};
  f.cell = {static_cast<float>(dims[0]) * 0.5f, static_cast<float>(dims[1]) * 2.0f,
            static_cast<float>(dims[2]) * 4.0f};
  for (std::int64_t s = 0; s < n[2]; ++s) {
    for (std::int64_t r = 0; r < n[1]; ++r) {
      for (std::int64_t c = 0; c < n[0]; ++c) {
        std::array<std::int64_t, 3> xyz{};
        xyz[static_cast<std::size_t>(map[0] - 1)] = c;
        xyz[static_cast<std::size_t>(map[1] - 1)] = r;
        xyz[static_cast<std::size_t>(map[2] - 1)] = s;
        const auto v = static_cast<float>(100 * xyz[0] + 10 * xyz[1] + xyz[2]);
        const auto* b = reinterpret_cast<const std::byte*>(&v);
        f.samples.insert(f.samples.end(), b, b + 4);
      }
    }
  }
  return f;
}

TEST(MrcReader, transposes_maps_stored_along_permuted_axes_to_x_fastest) {
  // Every order of the axes (crystallographic FFT programs write sections along X or Y), each
  // sample at its X, Y, Z place, spacing and start indices along the axis they belong to; also
  // big endian, gzip and half floats, which take the transposing path's conversions.
  scratch_dir dir;
  const index3 dims{5, 3, 4};
  std::array<std::int32_t, 3> map{1, 2, 3};
  int files = 0;
  do {
    for (int variant = 0; variant < 3; ++variant) {
      mrc_file f = coded_map(map, dims);
      f.start = {7 * map[0], 7 * map[1], 7 * map[2]};  // 7 × the axis number, along each axis
      f.big_endian = variant == 1;
      if (variant == 2) {  // half floats: every coded value is exact in binary16
        std::vector<std::byte> halves;
        for (std::size_t i = 0; i < f.samples.size(); i += 4) {
          float v = 0;
          std::memcpy(&v, f.samples.data() + i, 4);
          // binary16 of small whole numbers: exponent and the top mantissa bits.
          const auto whole = static_cast<std::uint32_t>(v);
          std::uint16_t bits = 0;
          if (whole != 0) {
            const auto e = static_cast<std::uint32_t>(std::bit_width(whole)) - 1u;
            bits = static_cast<std::uint16_t>(((e + 15u) << 10) | ((whole << (10u - e)) & 0x3ffu));
          }
          const auto* b = reinterpret_cast<const std::byte*>(&bits);
          halves.insert(halves.end(), b, b + 2);
        }
        f.samples = std::move(halves);
        f.item = 2;
        f.mode = 12;
      }
      const std::string name =
          "map" + std::to_string(files++) + (variant == 1 ? ".map.gz" : ".mrc");
      const fs::path file = dir / name;
      const std::string bytes = f.bytes();
      write_file(file, variant == 1 ? gzip(bytes) : bytes);
      const progiso::volume v = progiso::read_mrc(file);
      ASSERT_EQ(v.dims(), dims) << name;
      EXPECT_EQ(v.spacing(), (std::array<double, 3>{0.5, 2.0, 4.0})) << name;
      EXPECT_EQ(v.origin(), (std::array<double, 3>{7 * 1 * 0.5, 7 * 2 * 2.0, 7 * 3 * 4.0})) << name;
      for (std::int64_t z = 0; z < dims[2]; ++z) {
        for (std::int64_t y = 0; y < dims[1]; ++y) {
          for (std::int64_t x = 0; x < dims[0]; ++x) {
            const auto i = static_cast<std::size_t>(x + dims[0] * (y + dims[1] * z));
            ASSERT_EQ(stored_sample(v, i), static_cast<double>(100 * x + 10 * y + z))
                << name << " map " << map[0] << map[1] << map[2] << " at " << x << "," << y << ","
                << z;
          }
        }
      }
    }
  } while (std::next_permutation(map.begin(), map.end()));
  EXPECT_EQ(files, 18);
}

TEST(MrcReader, places_the_map_by_origin_or_start_and_skews_an_oblique_cell_in_the_world_map) {
  scratch_dir dir;
  mrc_file f = coded_map({1, 2, 3}, {4, 3, 2});  // steps 0.5, 2, 4
  // ORIGIN given: the first sample's position, as is.
  f.origin = {-3.0f, 0.0f, 8.5f};
  f.start = {10, 20, 30};
  write_file(dir / "origin.mrc", f.bytes());
  EXPECT_EQ(progiso::read_mrc(dir / "origin.mrc").origin(),
            (std::array<double, 3>{-3.0, 0.0, 8.5}));
  // ORIGIN zero: the start indices × the steps (a box cut from a crystal's unit cell).
  f.origin = {0.0f, 0.0f, 0.0f};
  write_file(dir / "start.mrc", f.bytes());
  EXPECT_EQ(progiso::read_mrc(dir / "start.mrc").origin(),
            (std::array<double, 3>{5.0, 40.0, 120.0}));
  const auto world = progiso::read_volume_world(dir / "start.mrc", std::nullopt);
  ASSERT_TRUE(world.has_value());
  EXPECT_EQ(world->apply({1.0, 1.0, 1.0}), (std::array<double, 3>{5.5, 42.0, 124.0}));
  // A hexagonal cell (α = β = 90°, γ = 120°): b lies at 120° from a in the xy plane; the grid's
  // steps are the cell's axes over MX, MY, MZ, and their volume the cell's over the samples.
  f.angles = {90.0f, 90.0f, 120.0f};
  f.start = {0, 0, 0};
  write_file(dir / "hex.ccp4", f.bytes());
  const auto hex = progiso::read_volume_world(dir / "hex.ccp4", std::nullopt);
  ASSERT_TRUE(hex.has_value());
  const auto b_step = hex->apply({0.0, 1.0, 0.0});
  EXPECT_NEAR(b_step[0], -1.0, 1e-12);  // 2 · cos 120°
  EXPECT_NEAR(b_step[1], std::sqrt(3.0), 1e-12);
  EXPECT_NEAR(b_step[2], 0.0, 1e-12);
  EXPECT_NEAR(hex->determinant(), 0.5 * 2.0 * 4.0 * std::sin(2.0 * std::acos(-1.0) / 3.0), 1e-12);
  // A triclinic cell: the c step's length stays the spacing along Z, at the angles CELLB gives.
  f.angles = {70.0f, 80.0f, 100.0f};
  write_file(dir / "triclinic.map", f.bytes());
  const auto tri = progiso::read_volume_world(dir / "triclinic.map", std::nullopt);
  ASSERT_TRUE(tri.has_value());
  const auto c = tri->apply({0.0, 0.0, 1.0});
  const auto b = tri->apply({0.0, 1.0, 0.0});
  const double rad = std::acos(-1.0) / 180.0;
  EXPECT_NEAR(std::hypot(c[0], c[1], c[2]), 4.0, 1e-9);
  EXPECT_NEAR((b[0] * c[0] + b[1] * c[1] + b[2] * c[2]) / (2.0 * 4.0), std::cos(70.0 * rad), 1e-6);
  EXPECT_NEAR(c[0] / 4.0, std::cos(80.0 * rad), 1e-6);
  EXPECT_GT(tri->determinant(), 0.0);
  // Positions without the world map stay origin + index × spacing.
  EXPECT_EQ(progiso::read_mrc(dir / "triclinic.map").spacing(),
            (std::array<double, 3>{0.5, 2.0, 4.0}));
}

TEST(MrcReader, widens_every_half_float_exactly) {
  // All 65 536 binary16 patterns against their value computed from the fields.
  for (std::uint32_t bits = 0; bits < 65536; ++bits) {
    const auto h = static_cast<std::uint16_t>(bits);
    const float got = progiso::detail::half_to_float(h);
    const int e = (bits >> 10) & 31;
    const auto mantissa = static_cast<double>(bits & 1023u);
    const double sign = (bits & 0x8000u) != 0 ? -1.0 : 1.0;
    if (e == 31) {
      if (mantissa == 0.0) {
        EXPECT_EQ(static_cast<double>(got), sign * HUGE_VAL) << bits;
      } else {
        EXPECT_TRUE(std::isnan(got)) << bits;
      }
      continue;
    }
    const double want =
        e == 0 ? sign * std::ldexp(mantissa, -24) : sign * std::ldexp(1024.0 + mantissa, e - 25);
    ASSERT_EQ(static_cast<double>(got), want) << bits;
    EXPECT_EQ(std::signbit(got), sign < 0.0) << bits;
  }
}

TEST(MrcReader, reads_imod_unsigned_bytes_signed_bytes_and_guesses_a_missing_stamp) {
  scratch_dir dir;
  mrc_file f;
  f.mode = 0;
  f.item = 1;
  for (int i = 0; i < 24; ++i) f.samples.push_back(static_cast<std::byte>(200 + i));
  // MRC2014: mode 0 is signed.
  write_file(dir / "signed.mrc", f.bytes());
  const progiso::volume s = progiso::read_mrc(dir / "signed.mrc");
  EXPECT_EQ(s.type(), sample_type::i8);
  EXPECT_EQ(stored_sample(s, 0), -56.0);
  // IMOD's stamp with its "signed" flag clear: unsigned.
  f.imod_unsigned = true;
  write_file(dir / "imod.rec", f.bytes());
  const progiso::volume u = progiso::read_mrc(dir / "imod.rec");
  EXPECT_EQ(u.type(), sample_type::u8);
  EXPECT_EQ(stored_sample(u, 23), 223.0);
  // No machine stamp: the byte order in which MODE and NX make sense, either one.
  for (const bool big : {false, true}) {
    mrc_file g = coded_map({1, 2, 3}, {4, 3, 2});
    g.stamp = false;
    g.big_endian = big;
    g.mode = 1;  // int16 samples
    g.item = 2;
    std::vector<std::byte> shorts;
    for (std::size_t i = 0; i < g.samples.size(); i += 4) {
      float v = 0;
      std::memcpy(&v, g.samples.data() + i, 4);
      const auto x = static_cast<std::int16_t>(v);
      const auto* b = reinterpret_cast<const std::byte*>(&x);
      shorts.insert(shorts.end(), b, b + 2);
    }
    g.samples = shorts;
    const fs::path file = dir / (big ? "nostamp_be.map" : "nostamp_le.map");
    write_file(file, g.bytes());
    const progiso::volume v = progiso::read_mrc(file);
    EXPECT_EQ(v.type(), sample_type::i16) << file;
    EXPECT_EQ(stored_sample(v, 1 + 4 * (2 + 3 * 1)), 121.0) << file;  // x 1, y 2, z 1
  }
}

TEST(MrcReader, skips_the_extended_header_and_reads_a_map_by_name_or_identifier) {
  scratch_dir dir;
  mrc_file f = coded_map({1, 2, 3}, {4, 3, 2});
  f.nsymbt = 1000;  // FEI, SerialEM and symmetry records: skipped unread
  const std::string bytes = f.bytes();
  write_file(dir / "ext.mrc", bytes);
  const progiso::volume v = progiso::read_mrc(dir / "ext.mrc");
  EXPECT_EQ(stored_sample(v, 23), 321.0);
  // read_volume: by name, in any case, gzip included; by "MAP " at byte 208 for other names.
  for (const std::string name : {"A.MRC", "b.Map", "c.ccp4", "d.rec", "e.mrcs", "f.map.gz"}) {
    write_file(dir / name, name == "f.map.gz" ? gzip(bytes) : bytes);
    const progiso::volume r = progiso::read_volume(dir / name, std::nullopt, std::nullopt);
    EXPECT_EQ(stored_sample(r, 23), 321.0) << name;
  }
  write_file(dir / "emd_1234", bytes);
  EXPECT_EQ(progiso::read_volume(dir / "emd_1234", std::nullopt, std::nullopt).dims(),
            (index3{4, 3, 2}));
  // A given spacing wins over the cell's; the files a read opens: the map alone.
  EXPECT_EQ(
      progiso::read_volume(dir / "ext.mrc", std::nullopt, std::array<double, 3>{1, 1, 1}).spacing(),
      (std::array<double, 3>{1.0, 1.0, 1.0}));
  EXPECT_EQ(progiso::volume_input_files(dir / "ext.mrc", std::nullopt),
            std::vector<fs::path>{dir / "ext.mrc"});
  // Without the identifier, an unknown name stays unknown.
  f.identifier = false;
  write_file(dir / "plain.bin", f.bytes());
  const std::string unknown = error_naming(dir / "plain.bin", [&] {
    (void)progiso::read_volume(dir / "plain.bin", std::nullopt, std::nullopt);
  });
  EXPECT_TRUE(contains(unknown, "unknown volume format")) << unknown;
  EXPECT_TRUE(contains(unknown, ".mrc")) << unknown;
}

TEST(MrcReader, refuses_hostile_headers_with_one_line_naming_the_file) {
  scratch_dir dir;
  struct hostile {
    std::string what;
    void (*mutate)(mrc_file&);
    std::string expected;
  };
  const std::vector<hostile> cases{
      {"complex", [](mrc_file& f) { f.mode = 4; }, "MODE 4 (complex 32-bit floats)"},
      {"rgb", [](mrc_file& f) { f.mode = 16; }, "MODE 16 (RGB bytes)"},
      {"4bit", [](mrc_file& f) { f.mode = 101; }, "MODE 101 (4-bit integers"},
      {"unknown", [](mrc_file& f) { f.mode = 7; }, "MODE 7 (an unknown mode)"},
      {"nx0", [](mrc_file& f) { f.n[0] = 0; }, "NX is 0, expected at least 1"},
      {"ny-", [](mrc_file& f) { f.n[1] = -5; }, "NY is -5, expected at least 1"},
      {"image", [](mrc_file& f) { f.n[2] = 1; }, "a single image (NZ = 1)"},
      {"huge", [](mrc_file& f) { f.n[0] = 40000; }, "NX is 40000, expected 2 to 32769"},
      {"map",
       [](mrc_file& f) {
         f.map = {1, 1, 3};
       },
       "MAPC, MAPR, MAPS are 1, 1, 3"},
      {"map4",
       [](mrc_file& f) {
         f.map = {1, 2, 4};
       },
       "a permutation of 1, 2, 3"},
      {"nsymbt", [](mrc_file& f) { f.nsymbt = -1; }, "NSYMBT"},
      {"stack",
       [](mrc_file& f) {
         f.ispg = 401;
         f.n[2] = 5;
         f.m[2] = 2;
       },
       "not a whole number of volumes of MZ = 2"},
      {"stackaxes",
       [](mrc_file& f) {
         f.ispg = 401;
         f.n[2] = 4;
         f.m[2] = 2;
         f.map = {2, 1, 3};
       },
       "axes are not in the order X, Y, Z"},
      {"nostamp",
       [](mrc_file& f) {
         f.stamp = false;
         f.mode = 1000;
       },
       "not an MRC file"},
  };
  for (const hostile& h : cases) {
    mrc_file f;
    f.samples.resize(24 * 4);
    h.mutate(f);
    const fs::path file = dir / (h.what + ".mrc");
    write_file(file, f.bytes());
    const std::string message = error_naming(file, [&] { (void)progiso::read_mrc(file); });
    EXPECT_TRUE(contains(message, h.expected)) << h.what << ": " << message;
  }
  // A file that ends inside the header.
  write_file(dir / "short.mrc", mrc_file{}.bytes().substr(0, 500));
  const std::string header =
      error_naming(dir / "short.mrc", [&] { (void)progiso::read_mrc(dir / "short.mrc"); });
  EXPECT_TRUE(contains(header, "file ends after 500 bytes, inside the 1024-byte MRC header"))
      << header;
}

TEST(MrcReader, refuses_short_truncated_and_corrupt_data_without_allocating_the_declared_size) {
  scratch_dir dir;
  // A header that declares 32769³ float32 samples (140 TB) over 1 KB of data: refused from the
  // sizes before anything is allocated, plain and gzip.
  mrc_file f;
  f.n = {32769, 32769, 32769};
  f.samples.resize(1000);
  write_file(dir / "huge.mrc", f.bytes());
  const std::string plain =
      error_naming(dir / "huge.mrc", [&] { (void)progiso::read_mrc(dir / "huge.mrc"); });
  EXPECT_TRUE(contains(plain, "MRC data ends: the file has 2024 bytes, too few for the declared"))
      << plain;
  write_file(dir / "huge.mrc.gz", gzip(f.bytes()));
  const std::string gz =
      error_naming(dir / "huge.mrc.gz", [&] { (void)progiso::read_mrc(dir / "huge.mrc.gz"); });
  EXPECT_TRUE(contains(gz, "bytes of gzip data cannot hold the declared")) << gz;
  // Data that ends inside the samples: plain (caught by size), gzip (caught while inflating),
  // and a transposed map (caught in its section loop).
  mrc_file g = coded_map({1, 2, 3}, {4, 3, 2});
  const std::string whole = g.bytes();
  write_file(dir / "cut.mrc", whole.substr(0, whole.size() - 4));
  const std::string cut =
      error_naming(dir / "cut.mrc", [&] { (void)progiso::read_mrc(dir / "cut.mrc"); });
  EXPECT_TRUE(contains(cut, "too few for the declared 96 bytes")) << cut;
  write_file(dir / "cut.mrc.gz", gzip(whole.substr(0, whole.size() - 4)));
  const std::string cut_gz =
      error_naming(dir / "cut.mrc.gz", [&] { (void)progiso::read_mrc(dir / "cut.mrc.gz"); });
  EXPECT_TRUE(contains(cut_gz, "MRC data ends after 92 of the 96 bytes")) << cut_gz;
  mrc_file t = coded_map({3, 1, 2}, {4, 3, 2});
  const std::string transposed = t.bytes();
  write_file(dir / "cut_t.map.gz", gzip(transposed.substr(0, transposed.size() - 10)));
  const std::string cut_t =
      error_naming(dir / "cut_t.map.gz", [&] { (void)progiso::read_mrc(dir / "cut_t.map.gz"); });
  EXPECT_TRUE(contains(cut_t, "MRC data ends after")) << cut_t;
  // Corrupt gzip: one line naming the file and zlib's complaint.
  std::string bad = gzip(whole);
  bad[bad.size() / 2] = static_cast<char>(bad[bad.size() / 2] ^ 0x5a);
  bad[bad.size() / 2 + 1] = static_cast<char>(bad[bad.size() / 2 + 1] ^ 0xa5);
  write_file(dir / "bad.mrc.gz", bad);
  const std::string corrupt =
      error_naming(dir / "bad.mrc.gz", [&] { (void)progiso::read_mrc(dir / "bad.mrc.gz"); });
  EXPECT_TRUE(contains(corrupt, "MRC gzip data") || contains(corrupt, "MRC data ends")) << corrupt;
  // A NaN sample is refused by the volume, the message naming the file.
  mrc_file n = coded_map({1, 2, 3}, {4, 3, 2});
  const float nan = std::nanf("");
  std::memcpy(n.samples.data() + 8, &nan, 4);
  write_file(dir / "nan.mrc", n.bytes());
  const std::string not_a_number =
      error_naming(dir / "nan.mrc", [&] { (void)progiso::read_mrc(dir / "nan.mrc"); });
  EXPECT_TRUE(contains(not_a_number, "expected finite samples")) << not_a_number;
}

}  // namespace
