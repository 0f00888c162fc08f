// read_zarr() (io/detail/zarr_reader.hpp): Zarr v2 arrays and OME-Zarr multiscale images.
// Images written by zarr-python (Debian's python3-zarr and python3-numcodecs: every codec,
// byte order, memory order and chunk separator the reader accepts, a series along leading axes,
// pyramid levels with their scales and translations, missing chunks) must read to the samples
// NumPy holds, byte for byte. Hostile images (written here, byte by byte) must each give one
// error naming the file: chunks that lie about their size, corrupt or oversized chunks, a
// decompression bomb, absent data behind a large declared shape (refused before anything of its
// size is allocated), paths out of the image, JSON nested without end, unsupported dtypes.
#include <progiso/io/volume_io.hpp>

#include <gtest/gtest.h>

#include <blosc.h>
#include <zlib.h>
#include <zstd.h>

#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <progiso/core/base/error.hpp>

#include "support/io_test_helpers.hpp"
#include "support/scratch_dir.hpp"
#include "support/zarr_files.hpp"

namespace progiso {
namespace {

namespace fs = std::filesystem;
using test::contains;
using test::read_whole_file;
using test::write_file;

class scratch_dir : public test::scratch_dir {
 public:
  scratch_dir() : test::scratch_dir("progiso-zarr-reader-test-") {}
};

bool have_zarr() { return std::string_view(PROGISO_ZARR_PYTHON).size() > 0; }

bool run_python(const scratch_dir& dir, const std::string& script) {
  const fs::path file = dir.path() / "write.py";
  std::ofstream(file) << script;
  const std::string command =
      std::string(PROGISO_ZARR_PYTHON) + " " + file.string() + " " + dir.path().string();
  return std::system(command.c_str()) == 0;
}

// Each image and what NumPy holds for it: `<name>.<level>.<volume>.bin`, the samples in host
// order, x fastest (a C-order (z, y, x) array's bytes).
constexpr const char* zarr_images = R"(
import sys, os, json, numpy as np, zarr, numcodecs, shutil
out = sys.argv[1]
rng = np.random.default_rng(11)

def expect(name, level, volume, a):
    np.ascontiguousarray(a).astype(a.dtype.newbyteorder('=')).tofile(
        os.path.join(out, '%s.%d.%d.bin' % (name, level, volume)))

# An OME-Zarr 0.4 image: t = 2, c = 1, z, y, x = 21, 17, 13, uint16, blosc lz4 with shuffle,
# three levels (every second sample), scales and translations.
root = zarr.open_group(os.path.join(out, 'ome.zarr'), mode='w')
full = (rng.integers(0, 4000, size=(2, 1, 21, 17, 13))).astype('<u2')
datasets = []
for k in range(3):
    level = full[:, :, ::2**k, ::2**k, ::2**k]
    root.create_dataset(str(k), data=level, chunks=(1, 1, 8, 8, 8),
                        compressor=numcodecs.Blosc(cname='lz4', shuffle=numcodecs.Blosc.SHUFFLE))
    datasets.append({'path': str(k), 'coordinateTransformations': [
        {'type': 'scale', 'scale': [1, 1, 0.5 * 2**k, 0.25 * 2**k, 0.125 * 2**k]},
        {'type': 'translation', 'translation': [0, 0, 3.0, -2.0, 1.5]}]})
    for t in range(2):
        expect('ome', k, t, level[t, 0])
root.attrs['multiscales'] = [{'version': '0.4', 'name': 'test', 'datasets': datasets,
    'axes': [{'name': 't', 'type': 'time'}, {'name': 'c', 'type': 'channel'},
             {'name': 'z', 'type': 'space'}, {'name': 'y', 'type': 'space'},
             {'name': 'x', 'type': 'space'}]}]

# Lone arrays, one per codec and layout.
def lone(name, data, separator='.', **kw):
    store = zarr.DirectoryStore(os.path.join(out, name + '.zarr'), dimension_separator=separator)
    zarr.array(data, store=store, **kw)
    expect(name, 0, 0, data)

f = rng.standard_normal((9, 10, 11)).astype('<f4')
lone('zstd', f, chunks=(4, 5, 6), compressor=numcodecs.Zstd(level=3))
lone('zlib', (f * 100).astype('<i4'), chunks=(9, 3, 11), compressor=numcodecs.Zlib(level=5))
lone('gzip', (f * 100).astype('>i2'), chunks=(2, 10, 4), compressor=numcodecs.GZip(level=5))
lone('raw', (f * 1000).astype('<f8'), chunks=(3, 3, 3), compressor=None)
lone('fortran', (f * 10).astype('<i2'), chunks=(4, 4, 4), order='F',
     compressor=numcodecs.Blosc(cname='zstd', shuffle=numcodecs.Blosc.BITSHUFFLE))
lone('nested', (f * 10).astype('|u1'), chunks=(5, 5, 5), separator='/',
     compressor=numcodecs.Blosc(cname='blosclz'))
# A missing chunk reads as fill_value.
g = (rng.integers(0, 200, size=(8, 8, 8))).astype('|u1')
a = zarr.array(g, chunks=(4, 4, 4), fill_value=77,
               store=zarr.DirectoryStore(os.path.join(out, 'holes.zarr')))
os.remove(os.path.join(out, 'holes.zarr', '1.0.1'))
g[4:8, 0:4, 4:8] = 77
expect('holes', 0, 0, g)
)";

std::string expected_bytes(const scratch_dir& dir, const std::string& name, int level, int volume) {
  return read_whole_file(
      dir.path() / (name + "." + std::to_string(level) + "." + std::to_string(volume) + ".bin"));
}

void expect_bytes(const volume& v, const std::string& want, const std::string& what) {
  ASSERT_EQ(v.byte_size(), want.size()) << what;
  EXPECT_EQ(std::memcmp(v.bytes(), want.data(), want.size()), 0) << what;
}

TEST(ZarrReader, images_written_by_zarr_python_read_to_the_samples_numpy_holds) {
  if (!have_zarr()) GTEST_SKIP() << "python3 with zarr and numcodecs not found";
  const scratch_dir dir;
  ASSERT_TRUE(run_python(dir, zarr_images));
  // Every level of every volume of the OME-Zarr image, with its spacing and origin.
  for (int level = 0; level < 3; ++level) {
    for (int t = 0; t < 2; ++t) {
      const volume v = read_zarr(dir.path() / "ome.zarr", {std::nullopt, t, level});
      const std::string what = "level " + std::to_string(level) + " volume " + std::to_string(t);
      expect_bytes(v, expected_bytes(dir, "ome", level, t), what);
      EXPECT_EQ(v.type(), sample_type::u16);
      const double s = static_cast<double>(1 << level);
      EXPECT_EQ(v.spacing(), (std::array<double, 3>{0.125 * s, 0.25 * s, 0.5 * s})) << what;
      EXPECT_EQ(v.origin(), (std::array<double, 3>{1.5, -2.0, 3.0})) << what;
    }
  }
  EXPECT_EQ(read_zarr(dir.path() / "ome.zarr", {std::nullopt, 0, 2}).dims(), (index3{4, 5, 6}));
  // The command's way in: a directory holding .zattrs is Zarr (read_volume()).
  expect_bytes(read_volume(dir.path() / "ome.zarr", std::nullopt, std::nullopt, {std::nullopt, 1}),
               expected_bytes(dir, "ome", 0, 1), "read_volume");
  // Codecs, byte orders, memory orders, separators, fill.
  for (const char* name : {"zstd", "zlib", "gzip", "raw", "fortran", "nested", "holes"}) {
    const volume v = read_zarr(dir.path() / (std::string(name) + ".zarr"));
    expect_bytes(v, expected_bytes(dir, name, 0, 0), name);
  }
  // A series must be chosen, a level must exist, a level on another format is refused.
  const fs::path ome = dir.path() / "ome.zarr";
  EXPECT_TRUE(contains(test::error_message_naming(ome, [&] { (void)read_zarr(ome); }),
                       "choose one by its index, 0 to 1"));
  EXPECT_TRUE(contains(test::error_message_naming(ome,
                                                  [&] {
                                                    (void)read_zarr(ome, {std::nullopt, 0, 3});
                                                  }),
                       "3 levels (0 to 2)"));
  const fs::path lone = dir.path() / "zstd.zarr";
  EXPECT_TRUE(contains(test::error_message_naming(lone,
                                                  [&] {
                                                    (void)read_zarr(lone, {std::nullopt, 0, 1});
                                                  }),
                       "one level (0)"));
}

// ---- Hostile images, written byte by byte.

std::string zarray(const std::string& shape, const std::string& chunks, const std::string& dtype,
                   const std::string& compressor, const std::string& extra = "") {
  return "{\"zarr_format\": 2, \"shape\": " + shape + ", \"chunks\": " + chunks +
         ", \"dtype\": \"" + dtype + "\", \"compressor\": " + compressor +
         ", \"fill_value\": 0, \"order\": \"C\", \"filters\": null" + extra + "}";
}

std::string blosc_chunk(const std::string& bytes) {
  std::string out(bytes.size() + BLOSC_MAX_OVERHEAD, '\0');
  const int n =
      blosc_compress_ctx(5, 1, 1, bytes.size(), bytes.data(), out.data(), out.size(), "lz4", 0, 1);
  out.resize(static_cast<std::size_t>(std::max(n, 0)));
  return out;
}

std::string zstd_chunk(const std::string& bytes) {
  std::string out(ZSTD_compressBound(bytes.size()), '\0');
  out.resize(ZSTD_compress(out.data(), out.size(), bytes.data(), bytes.size(), 3));
  return out;
}

TEST(ZarrReader, hostile_images_give_one_error_naming_the_file) {
  const scratch_dir dir;
  const fs::path a = dir.path() / "a.zarr";
  fs::create_directories(a);
  const std::string samples(4 * 4 * 4, '\x05');
  const auto message = [&](const fs::path& named) {
    return test::error_message_naming(named, [&] { (void)read_zarr(a); });
  };

  // A blosc chunk whose header says another size than the chunk's.
  write_file(a / ".zarray", zarray("[4, 4, 4]", "[4, 4, 4]", "|u1", "{\"id\": \"blosc\"}"));
  write_file(a / "0.0.0", blosc_chunk(std::string(1000, '\x05')));
  EXPECT_TRUE(contains(message(a / "0.0.0"), "a blosc chunk of 1000 bytes; expected 64"))
      << message(a / "0.0.0");
  // Not blosc at all.
  write_file(a / "0.0.0", std::string(40, '\xff'));
  EXPECT_TRUE(contains(message(a / "0.0.0"), "corrupt chunk"));
  // A zstd chunk decoding past the chunk's bytes (a bomb stops at the chunk's size).
  write_file(a / ".zarray", zarray("[4, 4, 4]", "[4, 4, 4]", "|u1", "{\"id\": \"zstd\"}"));
  write_file(a / "0.0.0", zstd_chunk(std::string(1 << 20, '\0')));
  EXPECT_TRUE(contains(message(a / "0.0.0"), "corrupt chunk"));
  write_file(a / "0.0.0", zstd_chunk(samples.substr(1)));
  EXPECT_TRUE(contains(message(a / "0.0.0"), "a zstd chunk of 63 bytes; expected 64"));
  // A zlib bomb: 512 KiB of zeros behind a chunk of 64 bytes.
  write_file(a / ".zarray", zarray("[4, 4, 4]", "[4, 4, 4]", "|u1", "{\"id\": \"zlib\"}"));
  {
    const std::string zeros(512 << 10, '\0');
    uLongf n = compressBound(static_cast<uLong>(zeros.size()));
    std::string z(n, '\0');
    ASSERT_EQ(compress2(reinterpret_cast<Bytef*>(z.data()), &n,
                        reinterpret_cast<const Bytef*>(zeros.data()),
                        static_cast<uLong>(zeros.size()), 9),
              Z_OK);
    z.resize(n);
    write_file(a / "0.0.0", z);
  }
  EXPECT_TRUE(contains(message(a / "0.0.0"), "more than 64 bytes; expected 64"));
  // An uncompressed chunk of the wrong size, and one far larger than any encoding.
  write_file(a / ".zarray", zarray("[4, 4, 4]", "[4, 4, 4]", "|u1", "null"));
  write_file(a / "0.0.0", samples.substr(3));
  EXPECT_TRUE(contains(message(a / "0.0.0"), "expected exactly 64"));
  write_file(a / ".zarray", zarray("[4, 4, 4]", "[4, 4, 4]", "|u1", "{\"id\": \"gzip\"}"));
  write_file(a / "0.0.0", std::string(8192, 'x'));
  EXPECT_TRUE(contains(message(a / "0.0.0"), "a chunk of 8192 bytes; expected at most"));
  fs::remove(a / "0.0.0");

  // A declared grid of 32769³ samples with one chunk of 64 present: refused, nothing allocated
  // (a 32 TiB array would end the test by running out of memory).
  write_file(a / ".zarray", zarray("[32769, 32769, 32769]", "[4, 4, 4]", "|u1", "null"));
  write_file(a / "0.0.0", samples);
  EXPECT_TRUE(contains(message(a), "1 of the "));
  EXPECT_TRUE(contains(message(a), "at least one in 64"));
  // No chunk at all.
  write_file(a / ".zarray", zarray("[4, 4, 4]", "[4, 4, 4]", "|u1", "null"));
  fs::remove(a / "0.0.0");
  EXPECT_TRUE(contains(message(a), "0 of the 1 chunks"));
  write_file(a / "0.0.0", samples);
  EXPECT_EQ(read_zarr(a).byte_size(), 64U);  // the same array, whole, reads

  // Metadata: unsupported dtype, filters, a 2-D array, chunks beyond 2 GiB, JSON too deep, not
  // JSON, a .zarray too large.
  const auto refused = [&](const std::string& zarray_text, const std::string& says) {
    write_file(a / ".zarray", zarray_text);
    EXPECT_TRUE(contains(message(a / ".zarray"), says)) << zarray_text;
  };
  refused(zarray("[4, 4, 4]", "[4, 4, 4]", "<c8", "null"), "<c8");
  refused(zarray("[4, 4, 4]", "[4, 4, 4]", "<c8", "null"), "is not supported");
  refused(zarray("[4, 4, 4]", "[4, 4, 4]", "|u1", "null", ", \"filters\": [{\"id\": \"delta\"}]"),
          "filters");
  refused(zarray("[4, 4]", "[4, 4]", "|u1", "null"), "a 2-D array");
  refused(zarray("[4, 4, 4]", "[2000, 2000, 2000]", "|u1", "null"), "chunks of more than");
  refused(zarray("[4, 4, 1]", "[4, 4, 1]", "|u1", "null"), "spatial axis 2 has 1 samples");
  refused(zarray("[4, 4, 4]", "[4, 4, 4]", "|u1", "{\"id\": \"lzma\"}"), "compressor");
  refused(std::string(100, '[') + std::string(100, ']'), "nested deeper than 64");
  refused("{\"zarr_format\": 2, \"shape\": [4,", "not valid JSON");
  refused(std::string((1 << 20) + 1, ' '), "more than the 1048576");
  refused(zarray("[4, 4, 4]", "[4, 4, 4]", "|u1", "null", ", \"order\": \"X\""), "expected order");

  // A multiscale whose dataset path leaves the image.
  const fs::path m = dir.path() / "m.zarr";
  fs::create_directories(m);
  write_file(m / ".zattrs",
             "{\"multiscales\": [{\"version\": \"0.4\", \"axes\": [\"z\", \"y\", \"x\"], "
             "\"datasets\": [{\"path\": \"../a.zarr\"}]}]}");
  EXPECT_TRUE(contains(test::error_message_naming(m / ".zattrs", [&] { (void)read_zarr(m); }),
                       "expected a dataset path inside the image"));
  // Axes that put space first.
  fs::create_directories(m / "0");
  write_file(m / "0" / ".zarray", zarray("[2, 4, 4, 4]", "[1, 4, 4, 4]", "|u1", "null"));
  write_file(m / ".zattrs",
             "{\"multiscales\": [{\"version\": \"0.4\", \"axes\": [{\"name\": \"x\", \"type\": "
             "\"space\"}, {\"name\": \"z\", \"type\": \"space\"}, {\"name\": \"y\", \"type\": "
             "\"space\"}, {\"name\": \"c\", \"type\": \"channel\"}], \"datasets\": [{\"path\": "
             "\"0\"}]}]}");
  EXPECT_TRUE(contains(test::error_message_naming(m / ".zattrs", [&] { (void)read_zarr(m); }),
                       "is spatial"));
}

// ---- Plane windows (volume_source::window()): the level a few planes at a time.

// Planes [z0, z1) of `w`'s field against `want` (the whole level's bytes, x fastest).
void expect_planes(const plane_window& w, const std::string& want, std::int64_t z0, std::int64_t z1,
                   const std::string& what) {
  const volume& f = w.field();
  const std::size_t plane =
      static_cast<std::size_t>(f.dims()[0] * f.dims()[1]) * sample_size(f.type());
  ASSERT_EQ(want.size(), plane * static_cast<std::size_t>(f.dims()[2])) << what;
  const std::size_t from = plane * static_cast<std::size_t>(z0);
  const std::size_t n = plane * static_cast<std::size_t>(z1 - z0);
  EXPECT_EQ(std::memcmp(f.bytes() + from, want.data() + from, n), 0)
      << what << ": planes " << z0 << " to " << z1 - 1;
}

TEST(PlaneWindow, windows_hold_the_planes_numpy_holds_for_every_codec_layout_and_level) {
  if (!have_zarr()) GTEST_SKIP() << "python3 with zarr and numcodecs not found";
  const scratch_dir dir;
  ASSERT_TRUE(run_python(dir, zarr_images));
  struct image {
    std::string name;
    int level, volume;
  };
  std::vector<image> images;
  for (int level = 0; level < 3; ++level) {
    for (int t = 0; t < 2; ++t) images.push_back({"ome", level, t});
  }
  for (const char* name : {"zstd", "zlib", "gzip", "raw", "fortran", "nested", "holes"}) {
    images.push_back({name, 0, 0});
  }
  for (const image& im : images) {
    const fs::path path = dir.path() / (im.name + ".zarr");
    const volume_choice choice{
        std::nullopt, im.name == "ome" ? std::optional<std::int64_t>(im.volume) : std::nullopt,
        im.level};
    const volume whole = read_zarr(path, choice);
    const std::string want = expected_bytes(dir, im.name, im.level, im.volume);
    // Windows of 1, 2 and 5 planes going forward, then one going back (held again from nothing).
    for (const std::int64_t step : {1, 2, 5}) {
      const std::string what = im.name + " level " + std::to_string(im.level) + " volume " +
                               std::to_string(im.volume) + ", windows of " + std::to_string(step);
      volume_source source(path, std::nullopt, choice);
      std::optional<plane_window> w = source.window();
      ASSERT_TRUE(w.has_value()) << what;
      const volume& f = w->field();
      EXPECT_EQ(f.dims(), whole.dims()) << what;
      EXPECT_EQ(f.type(), whole.type()) << what;
      EXPECT_EQ(f.spacing(), whole.spacing()) << what;
      EXPECT_EQ(f.origin(), whole.origin()) << what;
      const std::int64_t nz = f.dims()[2];
      for (std::int64_t z = 0; z < nz; z += step) {
        const std::int64_t end = std::min(nz, z + step);
        w->hold(z, end);
        expect_planes(*w, want, z, end, what);
      }
      w->hold(0, std::min<std::int64_t>(nz, 2));
      expect_planes(*w, want, 0, std::min<std::int64_t>(nz, 2), what + ", back to the start");
      const auto [lo, hi] = whole.value_range();
      EXPECT_LE(w->range_seen()[0], hi) << what;
      EXPECT_GE(w->range_seen()[1], lo) << what;
    }
  }
  // The whole level seen: the range is the volume's.
  volume_source source(dir.path() / "zlib.zarr", std::nullopt);
  std::optional<plane_window> w = source.window();
  ASSERT_TRUE(w.has_value());
  w->hold(0, w->field().dims()[2]);
  EXPECT_EQ(w->range_seen(), read_zarr(dir.path() / "zlib.zarr").value_range());
}

TEST(PlaneWindow, memory_follows_the_window_and_planes_given_back_are_unreadable) {
  const scratch_dir dir;
  const index3 dims{200, 160, 64};
  const auto sample = [](std::int64_t x, std::int64_t y, std::int64_t z) {
    return static_cast<std::uint8_t>((x * 3 + y * 5 + z * 7 + (x * z) % 11) % 251);
  };
  // Chunks of 4 planes, two per row; chunk (z 3, y 1, x 0) is missing: fill_value 0.
  test::write_zarr_array(dir.path() / "a.zarr", dims, {100, 80, 4}, "|u1", 1,
                         [&](std::int64_t x, std::int64_t y, std::int64_t z, std::byte* out) {
                           *out = static_cast<std::byte>(sample(x, y, z));
                         },
                         {{3, 1, 0}});
  // The window outlives its source (it keeps its own copy of the metadata).
  std::optional<plane_window> w = volume_source(dir.path() / "a.zarr", std::nullopt).window();
  ASSERT_TRUE(w.has_value());
  EXPECT_EQ(w->chunk_planes(), 4);
  const volume& f = w->field();
  const std::uint64_t plane = 200 * 160;
  const std::uint64_t page = static_cast<std::uint64_t>(sysconf(_SC_PAGESIZE));
  for (std::int64_t z = 0; z + 6 <= dims[2]; z += 3) {
    w->hold(z, z + 6);
    for (std::int64_t q = z; q < z + 6; ++q) {
      for (std::int64_t y = 0; y < dims[1]; y += 7) {
        for (std::int64_t x = 0; x < dims[0]; x += 3) {
          const bool hole = q / 4 == 3 && y >= 80 && x < 100;
          ASSERT_EQ(f.value(x, y, q), hole ? 0.0 : static_cast<double>(sample(x, y, q)))
              << x << " " << y << " " << q;
        }
      }
    }
  }
  // Held at once: a window of 6 planes, rounded out to whole chunk rows (at most 3 more), and
  // the pages the first and last planes share with planes not held.
  EXPECT_LE(w->peak_bytes(), (6 + 3) * plane + 2 * page);
  EXPECT_LT(w->peak_bytes(), f.byte_size() / 5);
  // A plane given back is no longer mapped: reading it ends the process.
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_DEATH(
      {
        const double v = f.value(0, 0, 0);
        std::fprintf(stderr, "read %g\n", v);
      },
      "");
  // Raw inputs (mapped or read whole) have no window.
  test::write_file(dir.path() / "r.raw", std::string(8 * 8 * 8, '\1'));
  EXPECT_FALSE(volume_source(dir.path() / "r.raw", raw_layout{{8, 8, 8}, sample_type::u8})
                   .window()
                   .has_value());
}

TEST(PlaneWindow, a_non_finite_sample_is_refused_when_its_plane_is_decoded) {
  // A float NaN and a double infinity, each at one position of plane 17.
  for (const bool wide : {false, true}) {
    const scratch_dir dir;
    const fs::path path = dir.path() / "f.zarr";
    test::write_zarr_array(path, {20, 20, 30}, {20, 20, 5}, wide ? "<f8" : "<f4", wide ? 8 : 4,
                           [wide](std::int64_t x, std::int64_t y, std::int64_t z, std::byte* out) {
                             const bool odd = x == 3 && y == 2 && z == 17;
                             if (wide) {
                               const double v = odd ? std::numeric_limits<double>::infinity()
                                                    : static_cast<double>(x + y + z);
                               std::memcpy(out, &v, sizeof v);
                             } else {
                               const float v = odd ? std::numeric_limits<float>::quiet_NaN()
                                                   : static_cast<float>(x + y + z);
                               std::memcpy(out, &v, sizeof v);
                             }
                           });
    volume_source source(path, std::nullopt);
    std::optional<plane_window> w = source.window();
    ASSERT_TRUE(w.has_value());
    w->hold(0, 15);  // the odd sample's chunk row is not decoded
    EXPECT_EQ(w->field().value(19, 19, 14), 52.0);
    EXPECT_EQ(w->range_seen()[0], 0.0);
    EXPECT_EQ(w->range_seen()[1], 52.0);
    const std::string message = test::error_message_naming(path, [&] { w->hold(15, 20); });
    EXPECT_TRUE(contains(message, "expected finite samples")) << message;
    EXPECT_TRUE(contains(message, "x 3, y 2, z 17")) << message;
  }
}

}  // namespace
}  // namespace progiso
