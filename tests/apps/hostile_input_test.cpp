// The progiso command against hostile input, one class of defect per test: every
// refusal is exit status 2 with one error line, no file created, no input or other output
// changed, in bounded time, and — where memory is the point — in bounded memory: the command
// runs under an address-space limit (setrlimit; not in sanitizer builds) and its peak resident
// memory is read back.
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/types.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <zlib.h>

#include <progiso/io/contour_io.hpp>
#include <progiso/io/mesh_io.hpp>

#include "support/bounded_run.hpp"
#include "support/dicom_files.hpp"
#include "support/io_test_helpers.hpp"
#include "support/mrc_files.hpp"
#include "support/scratch_dir.hpp"
#include "support/test_data.hpp"
#include "support/tiff_files.hpp"

namespace progiso {
namespace {

// The peak a refused input may cost the command: far below what the hostile declarations ask
// for (gigabytes). Sanitizer builds carry more: ASan's shadow and quarantine, in a binary that
// also holds the viewer's server.
#if defined(PROGISO_SANITIZER_BUILD)
constexpr long far_below_kib = 512 * 1024;
#else
constexpr long far_below_kib = 400 * 1024;
#endif

namespace fs = std::filesystem;
using test::bounded_result;
using test::bounds;
using test::gzip;

constexpr std::uint64_t one_gib = std::uint64_t{1} << 30;

class Hostile : public ::testing::Test {
 protected:
  Hostile() : dir_("progiso-hostile-") {}

  fs::path path(const std::string& name) const { return dir_ / name; }

  fs::path write(const std::string& name, const std::string& bytes) const {
    const fs::path p = path(name);
    std::ofstream(p, std::ios::binary) << bytes;
    return p;
  }

  bounded_result run(const std::vector<std::string>& args, bounds b = {}) const {
    return test::run_bounded(PROGISO_CLI, args, runs_.path(), b);
  }

  /// Every file and directory in the scratch directory, with its contents (directories: "").
  std::map<std::string, std::string> snapshot() const {
    std::map<std::string, std::string> m;
    for (const auto& e : fs::recursive_directory_iterator(dir_.path())) {
      const fs::file_status st = fs::symlink_status(e.path());
      m[fs::relative(e.path(), dir_.path()).string()] =
          fs::is_regular_file(st) ? test::read_whole(e.path()) : std::string();
    }
    return m;
  }

  /// Exit status 2, one stderr line containing `needle`, and the scratch directory exactly as
  /// it was before the run (nothing created, nothing changed, no temporary left).
  void expect_refused(const std::vector<std::string>& args, const std::string& needle,
                      bounds b = {}) const {
    const auto before = snapshot();
    const bounded_result r = run(args, b);
    std::string all;
    for (const auto& a : args) all += a + " ";
    EXPECT_FALSE(r.timed_out) << all;
    EXPECT_EQ(r.status, 2) << all << "\nstderr: " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << all << "\nstderr: " << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << all << "\nstderr: " << r.err;
    EXPECT_TRUE(snapshot() == before) << all << ": the scratch directory changed";
  }

  test::scratch_dir dir_;
  test::scratch_dir runs_{"progiso-hostile-runs-"};
};

std::string cube_bytes(int n) {
  std::string s(static_cast<std::size_t>(n * n * n), '\0');
  for (int i = 0; i < n * n * n; ++i) s[static_cast<std::size_t>(i)] = static_cast<char>(i % 200);
  return s;
}

std::string pgm(int w, int h) {
  std::string s = "P5\n" + std::to_string(w) + " " + std::to_string(h) + "\n255\n";
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      s += static_cast<char>(
          static_cast<int>(127.5 + 120 * std::sin(x * 0.09) * std::cos(y * 0.07)));
  return s;
}

// ---- 1. Untrusted NRRD headers never reach a printf, and parse in linear time.

TEST_F(Hostile, detached_header_with_printf_field_widths_is_one_error_line) {
  write("d.raw", cube_bytes(4));
  for (const std::string pattern :
       {"%64d 0 1 1", "%100000d 0 1 1", "%s 0 1 1", "%n 0 1 1", "%d%d 0 1 1"}) {
    const fs::path h = write("v.nhdr",
                             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n"
                             "data file: " +
                                 pattern + "\n");
    expect_refused({"extract", h.string(), "--iso", "50", "-o", path("o.ply").string()}, "v.nhdr",
                   test::limited(std::chrono::seconds(20), one_gib));
    fs::remove(h);
  }
}

TEST_F(Hostile, a_hundred_thousand_key_value_lines_parse_in_bounded_time) {
  std::string header = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n";
  for (int i = 0; i < 100000; ++i) header += "key" + std::to_string(i) + ":=value\n";
  const fs::path in = write("many.nrrd", header + "\n" + cube_bytes(4));
  const bounded_result r =
      run({"extract", in.string(), "--iso", "50", "-o", path("o.ply").string()},
          test::limited(std::chrono::seconds(20), one_gib));
  EXPECT_FALSE(r.timed_out);
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_LT(r.seconds, 10.0);
}

// ---- 2. Memory follows the data, not the declared size.

TEST_F(Hostile, declared_sizes_beyond_the_data_fail_before_allocating) {
  // 2000 × 2000 × 1000 samples declared, 33 KB present: raw bytes, and gzip of doubles.
  const fs::path raw = write("big.nrrd",
                             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2000 2000 1000\n"
                             "encoding: raw\n\n" +
                                 std::string(33000, '\x11'));
  const fs::path gz = write("big_gz.nrrd",
                            "NRRD0004\ntype: double\ndimension: 3\nsizes: 2000 2000 1000\n"
                            "endian: little\nencoding: gzip\n\n" +
                                gzip(std::string(4 << 20, '\0')));
  // The same in NIfTI: a plain file of bytes and a gzip file of doubles.
  const fs::path nii = write("big.nii", test::nifti1_file({2000, 2000, 1000}, 2, 8, {1, 1, 1},
                                                          std::string(33000, '\x11')));
  const fs::path nii_gz = write(
      "big.nii.gz",
      gzip(test::nifti1_file({2000, 2000, 1000}, 64, 64, {1, 1, 1}, std::string(4 << 20, '\0'))));
  // And in MetaImage: raw bytes after the header, and zlib-compressed doubles in a data file.
  const fs::path mha = write("big.mha",
                             "NDims = 3\nDimSize = 2000 2000 1000\nElementType = MET_UCHAR\n"
                             "ElementDataFile = LOCAL\n" +
                                 std::string(33000, '\x11'));
  write("big.zraw", test::gzip(std::string(4 << 20, '\0'), 6, true));
  const fs::path mhd = write("big.mhd",
                             "NDims = 3\nDimSize = 2000 2000 1000\nElementType = MET_DOUBLE\n"
                             "CompressedData = True\nElementDataFile = big.zraw\n");
  // And in legacy VTK: binary bytes after the header.
  const fs::path vtk = write("big.vtk",
                             "# vtk DataFile Version 3.0\nbig\nBINARY\nDATASET STRUCTURED_POINTS\n"
                             "DIMENSIONS 2000 2000 1000\nPOINT_DATA 4000000000\n"
                             "SCALARS s unsigned_char\nLOOKUP_TABLE default\n" +
                                 std::string(33000, '\x11'));
  // And in VTK XML image data: appended raw bytes, and one zlib block said to inflate to 4 GB.
  const auto vti_head = [](const std::string& compressor) {
    return "<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"LittleEndian\" "
           "header_type=\"UInt64\"" +
           compressor +
           ">\n<ImageData WholeExtent=\"0 1999 0 1999 0 999\">\n"
           "<Piece Extent=\"0 1999 0 1999 0 999\"><PointData><DataArray type=\"UInt8\" "
           "Name=\"s\" format=\"appended\" offset=\"0\"/></PointData></Piece></ImageData>\n"
           "<AppendedData encoding=\"raw\">_";
  };
  const auto u64 = [](std::uint64_t v) {
    return std::string(reinterpret_cast<const char*>(&v), sizeof v);
  };
  const std::uint64_t four_gb = 4000000000;
  const fs::path vti = write("big.vti", vti_head("") + u64(four_gb) + std::string(33000, '\x11'));
  const std::string packed = test::gzip(std::string(4 << 20, '\0'), 6, true);
  const fs::path vti_z =
      write("big_z.vti", vti_head(" compressor=\"vtkZLibDataCompressor\"") + u64(1) + u64(four_gb) +
                             u64(0) + u64(packed.size()) + packed);
  // And a DICOM series whose two slices declare 65535 × 65535 pixels of 32 bits (17 GB) each,
  // with 4 KB of pixel data.
  const fs::path series = path("series");
  fs::create_directory(series);
  for (int k = 0; k < 2; ++k) {
    test::dicom_slice_file f;
    f.rows = 65535;
    f.columns = 65535;
    f.bits_allocated = 32;
    f.bits_stored = 32;
    f.position = {0.0, 0.0, 1.0 * k};
    f.pixels.resize(4096);
    f.write(series, "IM" + std::to_string(k));
  }
  // And an enhanced DICOM file of 32769 frames of 65535 × 65535 pixels of 32 bits (563 TB),
  // each placed, with 4 KB of pixel data.
  test::dicom_slice_file frames;
  frames.rows = 65535;
  frames.columns = 65535;
  frames.bits_allocated = 32;
  frames.bits_stored = 32;
  for (int k = 0; k < 32769; ++k) frames.frame_positions.push_back({0.0, 0.0, 1.0 * k});
  frames.pixels.resize(4096);
  const fs::path enhanced = frames.write(path(""), "frames.dcm");
  // And the same frames as lossless JPEG (16 bits) in one fragment of 4 KB: JPEG codes each
  // sample in at least a bit, so 4 KB holds 32 768 samples, not 141 T.
  frames.transfer_syntax = test::dicom_jpeg_lossless;
  frames.bits_allocated = 16;
  frames.bits_stored = 16;
  frames.pixels.clear();
  frames.fragments = {std::string(4096, '\x55')};
  const fs::path jpeg = frames.write(path(""), "frames_jpeg.dcm");
  // And as RLE, whose longest run (two bytes) makes 128.
  frames.transfer_syntax = "1.2.840.10008.1.2.5";
  const fs::path rle = frames.write(path(""), "frames_rle.dcm");
  // And a .pvti of 2000 × 2000 × 1000 points whose one piece holds 8.
  write("small.vti",
        "<VTKFile type=\"ImageData\"><ImageData WholeExtent=\"0 1 0 1 0 1\">"
        "<Piece Extent=\"0 1 0 1 0 1\"><PointData><DataArray type=\"UInt8\" "
        "Name=\"s\" format=\"ascii\">1 2 3 4 5 6 7 8</DataArray></PointData>"
        "</Piece></ImageData></VTKFile>\n");
  const fs::path pvti =
      write("big.pvti",
            "<VTKFile type=\"PImageData\"><PImageData WholeExtent=\"0 1999 0 1999 "
            "0 999\"><PPointData><PDataArray type=\"UInt8\" Name=\"s\"/>"
            "</PPointData><Piece Extent=\"0 1 0 1 0 1\" Source=\"small.vti\"/>"
            "</PImageData></VTKFile>\n");
  // And a TIFF stack of 3 pages of 32769 × 32769 doubles (25.8 GB) whose LZW strips hold 4 KB
  // each (LZW expands at most 4096 times: 16 MB a page).
  const std::string strip(4096, '\x55');
  const fs::path tiff = write(
      "big.tif", test::hand_made_tiff(false, 32769, 32769, 64, SAMPLEFORMAT_IEEEFP, COMPRESSION_LZW,
                                      PREDICTOR_NONE, {strip, strip, strip}));
  // And an MRC map of 2000 × 2000 × 1000 float32 samples in 33 KB, plain, and in 4 MB of gzip.
  test::mrc_file map;
  map.n = {2000, 2000, 1000};
  map.samples.resize(33000);
  const fs::path mrc = write("big.mrc", map.bytes());
  map.samples.assign(std::size_t{4} << 20, std::byte{0});
  const fs::path mrc_gz = write("big.map.gz", gzip(map.bytes()));
  for (const fs::path& in : {raw, gz, nii, nii_gz, mha, mhd, vtk, vti, vti_z, pvti, series,
                             enhanced, jpeg, rle, tiff, mrc, mrc_gz}) {
    const auto before = snapshot();
    const bounded_result r =
        run({"extract", in.string(), "--iso", "1", "-o", path("o.ply").string()},
            test::limited(std::chrono::seconds(30), one_gib));
    EXPECT_FALSE(r.timed_out);
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(in.filename().string()), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("allocate"), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("out of memory"), std::string::npos) << r.err;
    // Far below the 3.7 GB (7.5 GB) the declaration asks for.
    EXPECT_LT(r.max_rss_kib, far_below_kib) << in;
    EXPECT_TRUE(snapshot() == before);
  }
  // Series whose chosen volume is small but whose declared volumes are not there: a NIfTI of
  // 1000 volumes of 125 MB in 33 KB, plain, and of 2 volumes of 32 GB doubles in 4 MB of gzip;
  // a MetaImage of 50 volumes of 4 GB in 33 KB; 4-D NRRDs below. Refused from the sizes,
  // whichever volume.
  const auto series_of = test::nifti1_series;
  const fs::path nii_series = write(
      "series.nii",
      series_of(test::nifti1_file({500, 500, 500}, 2, 8, {1, 1, 1}, std::string(33000, '\x11')),
                1000));
  const fs::path nii_gz_series =
      write("series.nii.gz", gzip(series_of(test::nifti1_file({2000, 2000, 1000}, 64, 64, {1, 1, 1},
                                                              std::string(4 << 20, '\0')),
                                            2)));
  const fs::path mha_series = write("series.mha",
                                    "NDims = 4\nDimSize = 2000 2000 1000 50\n"
                                    "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n" +
                                        std::string(33000, '\x11'));
  // A 4-D NRRD of 50 volumes of 4 GB in 33 KB, volumes last, and interleaved (first) in gzip.
  const fs::path nrrd_series = write("series.nrrd",
                                     "NRRD0005\ntype: uchar\ndimension: 4\n"
                                     "sizes: 2000 2000 1000 50\nencoding: raw\n\n" +
                                         std::string(33000, '\x11'));
  const fs::path nrrd_dwi = write("dwi.nrrd",
                                  "NRRD0005\ntype: short\ndimension: 4\n"
                                  "sizes: 30 1000 1000 500\nkinds: list domain domain domain\n"
                                  "endian: little\nencoding: gzip\n\n" +
                                      gzip(std::string(4 << 20, '\0')));
  // An MRC volume stack of 50 volumes of 500³ bytes in 33 KB.
  test::mrc_file stack;
  stack.mode = 0;
  stack.ispg = 401;
  stack.n = {500, 500, 25000};
  stack.m = {500, 500, 500};
  stack.samples.resize(33000);
  stack.item = 1;
  const fs::path mrc_stack = write("stack.mrcs", stack.bytes());
  for (const fs::path& in :
       {nii_series, nii_gz_series, mha_series, nrrd_series, nrrd_dwi, mrc_stack}) {
    const auto before = snapshot();
    const bounded_result r =
        run({"extract", in.string(), "--volume", "1", "--iso", "1", "-o", path("o.ply").string()},
            test::limited(std::chrono::seconds(30), one_gib));
    EXPECT_FALSE(r.timed_out);
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(in.filename().string()), std::string::npos) << r.err;
    EXPECT_LT(r.max_rss_kib, far_below_kib) << in;
    EXPECT_TRUE(snapshot() == before);
  }
}

// ---- 3. Only regular files are read: devices and FIFOs are refused at once.

TEST_F(Hostile, devices_and_fifos_are_refused_at_once) {
  const bounds quick = test::limited(std::chrono::seconds(20), one_gib);
  const fs::path fifo = path("f.pgm");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  fs::create_symlink("/dev/zero", path("zero.pgm"));
  fs::create_symlink("/dev/urandom", path("random.png"));
  fs::create_symlink("/dev/zero", path("zero.png"));
  for (const std::string in : {"f.pgm", "zero.pgm", "random.png", "zero.png"}) {
    expect_refused({"contour", path(in).string(), "--iso", "10", "-o", path("o.svg").string()}, in,
                   quick);
  }
  // Raw volumes, and NRRD detached data files.
  const fs::path raw_fifo = path("v.raw");
  ASSERT_EQ(::mkfifo(raw_fifo.c_str(), 0600), 0);
  expect_refused({"extract", raw_fifo.string(), "--dims", "4,4,4", "--type", "u8", "--iso", "5",
                  "-o", path("o.ply").string()},
                 "FIFO", quick);
  const fs::path data_fifo = path("d.raw");
  ASSERT_EQ(::mkfifo(data_fifo.c_str(), 0600), 0);
  fs::create_symlink("/dev/zero", path("z.raw"));
  for (const std::string data : {"d.raw", "z.raw"}) {
    const fs::path h = write("v.nhdr",
                             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n"
                             "data file: " +
                                 data + "\n");
    expect_refused({"extract", h.string(), "--iso", "5", "-o", path("o.ply").string()}, data,
                   quick);
    fs::remove(h);
  }
  // The .img of a NIfTI header and data pair.
  const fs::path hdr = write("pair.hdr", test::nifti1_file({4, 4, 4}, 2, 8, {1, 1, 1}, {}, true));
  ASSERT_EQ(::mkfifo(path("pair.img").c_str(), 0600), 0);
  expect_refused({"extract", hdr.string(), "--iso", "5", "-o", path("o.ply").string()},
                 "pair.img: expected a regular NIfTI data file, found a FIFO", quick);
  // A MetaImage header whose slices are a FIFO and /dev/zero.
  const fs::path mhd = write("v.mhd",
                             "NDims = 3\nDimSize = 4 4 2\nElementType = MET_UCHAR\n"
                             "ElementDataFile = LIST\nd.raw\nz.raw\n");
  expect_refused({"extract", mhd.string(), "--iso", "5", "-o", path("o.ply").string()},
                 "d.raw: expected a regular MetaImage data file, found a FIFO", quick);
  // A TIFF stack that is a FIFO or /dev/zero.
  ASSERT_EQ(::mkfifo(path("fifo.tif").c_str(), 0600), 0);
  fs::create_symlink("/dev/zero", path("zero.tiff"));
  for (const std::string in : {"fifo.tif", "zero.tiff"}) {
    expect_refused({"extract", path(in).string(), "--iso", "5", "-o", path("o.ply").string()},
                   in + ": expected a regular TIFF file", quick);
  }
  // An MRC map that is a FIFO or /dev/zero.
  ASSERT_EQ(::mkfifo(path("fifo.mrc").c_str(), 0600), 0);
  fs::create_symlink("/dev/zero", path("zero.map"));
  for (const std::string in : {"fifo.mrc", "zero.map"}) {
    expect_refused({"extract", path(in).string(), "--iso", "5", "-o", path("o.ply").string()},
                   in + ": expected a regular MRC file", quick);
  }
  // A .pvti whose pieces are a FIFO and /dev/zero.
  ASSERT_EQ(::mkfifo(path("p0.vti").c_str(), 0600), 0);
  fs::create_symlink("/dev/zero", path("p1.vti"));
  for (const std::string piece : {"p0.vti", "p1.vti"}) {
    const fs::path pvti =
        write("v.pvti",
              "<VTKFile type=\"PImageData\"><PImageData WholeExtent=\"0 3 0 3 0 3\">"
              "<PPointData><PDataArray type=\"UInt8\" Name=\"s\"/></PPointData>"
              "<Piece Extent=\"0 3 0 3 0 3\" Source=\"" +
                  piece + "\"/></PImageData></VTKFile>\n");
    expect_refused({"extract", pvti.string(), "--iso", "5", "-o", path("o.ply").string()},
                   piece + ": expected a regular VTK XML piece file", quick);
    fs::remove(pvti);
  }
}

// ---- 4. Outputs never destroy data and are never left half-made.

TEST_F(Hostile, outputs_naming_an_input_or_each_other_are_refused) {
  const std::string cube = cube_bytes(6);
  const fs::path in = write("in.ply", cube);  // a raw volume that happens to end in .ply
  const std::vector<std::string> raw{"--dims", "6,6,6", "--type", "u8", "--iso", "50"};
  const auto extract = [&](const std::vector<std::string>& more) {
    std::vector<std::string> a{"extract", in.string()};
    a.insert(a.end(), raw.begin(), raw.end());
    a.insert(a.end(), more.begin(), more.end());
    return a;
  };
  expect_refused(extract({"-o", in.string()}), "input");
  expect_refused(extract({"-o", path("m.ply").string(), "--stats-json", in.string()}), "input");
  // The same file under other names: a relative path with "..", a symbolic link, a hard link.
  const std::string dotted = (dir_.path() / ".." / dir_.path().filename() / "in.ply").string();
  expect_refused(extract({"-o", dotted}), "input");
  fs::create_symlink(in, path("link.ply"));
  expect_refused(extract({"-o", path("link.ply").string()}), "input");
  fs::create_hard_link(in, path("hard.ply"));
  expect_refused(extract({"-o", path("hard.ply").string()}), "input");
  // Two outputs on one file, existing or not.
  expect_refused(extract({"-o", path("m.ply").string(), "--stats-json", path("m.ply").string()}),
                 "--stats-json");
  write("old.ply", "old");
  expect_refused(
      extract({"-o", path("old.ply").string(), "--stats-json", path("old.ply").string()}),
      "--stats-json");
  // A detached data file is an input too.
  write("data.obj", cube);
  const fs::path h = write("v.nhdr",
                           "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 6 6 6\nencoding: raw\n"
                           "data file: data.obj\n");
  expect_refused({"extract", h.string(), "--iso", "50", "-o", path("data.obj").string()}, "input");
  // So is the .img of a NIfTI header and data pair, here through a link named like a mesh.
  const fs::path hdr = write("pair.hdr", test::nifti1_file({6, 6, 6}, 2, 8, {1, 1, 1}, {}, true));
  write("pair.img", cube);
  fs::create_symlink(path("pair.img"), path("pair_img.ply"));
  expect_refused({"extract", hdr.string(), "--iso", "50", "-o", path("pair_img.ply").string()},
                 "input");
  EXPECT_EQ(test::read_whole_file(path("pair.img")), cube);
  // And a MetaImage slice file named by a pattern, through a link named like a mesh.
  write("slice_2.raw", cube.substr(0, 36));
  for (int z = 1; z <= 6; ++z) {
    if (z != 2) write("slice_" + std::to_string(z) + ".raw", cube.substr(0, 36));
  }
  const fs::path mhd = write("slices.mhd",
                             "NDims = 3\nDimSize = 6 6 6\nElementType = MET_UCHAR\n"
                             "ElementDataFile = slice_%d.raw 1 6 1\n");
  fs::create_symlink(path("slice_2.raw"), path("slice_2.ply"));
  expect_refused({"extract", mhd.string(), "--iso", "50", "-o", path("slice_2.ply").string()},
                 "input");
  EXPECT_EQ(test::read_whole_file(path("slice_2.raw")), cube.substr(0, 36));
  // And a .pvti's piece, through a link named like a mesh.
  const std::string piece =
      "<VTKFile type=\"ImageData\"><ImageData WholeExtent=\"0 1 0 1 0 1\">"
      "<Piece Extent=\"0 1 0 1 0 1\"><PointData><DataArray type=\"UInt8\" "
      "Name=\"s\" format=\"ascii\">1 2 3 4 5 6 7 200</DataArray>"
      "</PointData></Piece></ImageData></VTKFile>\n";
  write("piece.vti", piece);
  const fs::path pvti = write("v.pvti",
                              "<VTKFile type=\"PImageData\"><PImageData WholeExtent=\"0 1 0 1 0 "
                              "1\"><PPointData><PDataArray type=\"UInt8\" Name=\"s\"/>"
                              "</PPointData><Piece Extent=\"0 1 0 1 0 1\" Source=\"piece.vti\"/>"
                              "</PImageData></VTKFile>\n");
  fs::create_symlink(path("piece.vti"), path("piece.ply"));
  expect_refused({"extract", pvti.string(), "--iso", "50", "-o", path("piece.ply").string()},
                 "input");
  EXPECT_EQ(test::read_whole_file(path("piece.vti")), piece);
  // contour: -o through a link to the image, --frames on -o, --stats-json on the image.
  const fs::path img = write("img.pgm", pgm(40, 30));
  fs::create_symlink(img, path("img.svg"));
  expect_refused({"contour", img.string(), "--iso", "100", "-o", path("img.svg").string()},
                 "input");
  expect_refused({"contour", img.string(), "--iso", "100", "-o", path("c.svg").string(), "--frames",
                  path("c.svg").string()},
                 "--frames");
  expect_refused({"contour", img.string(), "--iso", "100", "-o", path("c.svg").string(),
                  "--stats-json", img.string()},
                 "input");
}

TEST_F(Hostile, device_outputs_are_written_into_not_replaced) {
  // A private null device: writing it must leave it a character device.
  const fs::path dev = path("null-device");
  if (::mknod(dev.c_str(), S_IFCHR | 0666, makedev(1, 3)) != 0) {
    GTEST_SKIP() << "cannot create a device node here (not root)";
  }
  const fs::path in = write("c.raw", cube_bytes(6));
  const bounded_result r = run({"extract", in.string(), "--dims", "6,6,6", "--type", "u8", "--iso",
                                "50", "-o", path("m.ply").string(), "--stats-json", dev.string()});
  EXPECT_EQ(r.status, 0) << r.err;
  struct stat st {};
  ASSERT_EQ(::stat(dev.c_str(), &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode)) << "the device node was replaced";
  EXPECT_TRUE(fs::exists(path("m.ply")));
  for (const auto& e : fs::directory_iterator(dir_.path())) {
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
  }
}

TEST_F(Hostile, a_fifo_output_without_a_reader_is_refused_without_waiting) {
  const fs::path fifo = path("out.ply");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const fs::path in = write("c.raw", cube_bytes(6));
  expect_refused({"extract", in.string(), "--dims", "6,6,6", "--type", "u8", "--iso", "50", "-o",
                  fifo.string()},
                 "no process is reading it", test::limited(std::chrono::seconds(20)));
}

TEST_F(Hostile, bad_output_locations_fail_before_any_computation_and_leave_nothing) {
  const fs::path in = write("c.raw", cube_bytes(6));
  fs::create_directory(path("a-directory"));
  const std::vector<std::string> base{
      "extract", in.string(), "--dims", "6,6,6", "--type",
      "u8",      "--iso",     "50",     "-o",    path("m.ply").string()};
  const auto with = [&](std::vector<std::string> more) {
    std::vector<std::string> a = base;
    a.insert(a.end(), more.begin(), more.end());
    return a;
  };
  expect_refused(with({"--stats-json", path("a-directory").string()}), "directory");
  expect_refused(with({"--stats-json", ""}), "--stats-json");
  expect_refused(with({"--stats-json", path("missing/s.json").string()}), "missing");
  // The demo takes seconds to refine in a debug build: a bad output must fail before that.
  const bounded_result r = run({"extract", "--demo", "--full", "-o", path("m.ply").string(),
                                "--stats-json", path("a-directory").string()});
  EXPECT_EQ(r.status, 2);
  EXPECT_LT(r.seconds, 5.0);
  EXPECT_FALSE(fs::exists(path("m.ply")));
  // contour: --frames is created only when everything succeeded.
  const fs::path img = write("img.pgm", pgm(40, 30));
  expect_refused({"contour", img.string(), "--iso", "100", "-o", path("missing/c.svg").string(),
                  "--frames", path("frames").string()},
                 "missing");
  expect_refused({"contour", img.string(), "--iso", "100", "-o", path("c.svg").string(), "--frames",
                  path("frames").string(), "--stats-json", path("a-directory").string()},
                 "directory");
  expect_refused({"contour", img.string(), "--iso", "100", "-o", path("c.svg").string(), "--frames",
                  in.string()},
                 "expected a directory");
}

TEST_F(Hostile, interrupted_runs_leave_no_temporary_behind) {
  for (const int sig : {SIGINT, SIGTERM}) {
    const auto before = snapshot();
    bool sent = false;
    bounds b;
    b.while_running = [&](pid_t pid) {
      // The temporaries exist from the start (outputs are created before computing).
      for (const auto& e : fs::directory_iterator(dir_.path())) {
        if (e.path().filename().string().find(".tmp-") != std::string::npos) {
          ::kill(pid, sig);
          sent = true;
          return false;
        }
      }
      return true;
    };
    const bounded_result r = run({"extract", "--demo", "--full", "--threads", "1", "-o",
                                  path("m.ply").string(), "--stats-json", path("s.json").string()},
                                 b);
    ASSERT_TRUE(sent) << "the run ended before its temporaries appeared: " << r.err;
    EXPECT_EQ(r.signal, sig) << "exit status " << r.status << ", stderr: " << r.err;
    const auto after = snapshot();
    EXPECT_TRUE(after == before) << "signal " << sig << " left " << after.size() - before.size()
                                 << " files behind, e.g. " << after.rbegin()->first;
  }
  // contour with frames: the staging directory goes too.
  std::string big = "P5\n1025 1025\n255\n";
  for (int y = 0; y < 1025; ++y)
    for (int x = 0; x < 1025; ++x) big += static_cast<char>((x * 7 + y * 13 + x * y) % 251);
  const fs::path img = write("big.pgm", big);
  std::string isos = "1";
  for (int w = 2; w < 250; ++w) isos.append(",").append(std::to_string(w));
  const auto before = snapshot();
  bool sent = false;
  bounds b;
  b.while_running = [&](pid_t pid) {
    std::size_t temporaries = 0;
    for (const auto& e : fs::directory_iterator(dir_.path())) {
      temporaries += e.path().filename().string().find(".tmp-") != std::string::npos ? 1u : 0u;
    }
    if (temporaries >= 2) {  // the SVG's temporary and the frames' staging directory
      std::this_thread::sleep_for(std::chrono::milliseconds(200));  // let frames be written
      ::kill(pid, SIGTERM);
      sent = true;
      return false;
    }
    return true;
  };
  const bounded_result r = run({"contour", img.string(), "--iso", isos, "--full", "-o",
                                path("c.svg").string(), "--frames", path("frames").string()},
                               b);
  ASSERT_TRUE(sent) << r.err;
  EXPECT_EQ(r.signal, SIGTERM) << r.err;
  EXPECT_TRUE(snapshot() == before) << "SIGTERM left files behind";
}

// ---- 5. Numbers out of range: a clear error or the honest result.

std::size_t ply_triangles(const fs::path& p) { return read_ply(p).triangles.size(); }

TEST_F(Hostile, numbers_out_of_range_give_a_clear_error_or_the_honest_result) {
  const fs::path in = write("c.raw", cube_bytes(9));
  const std::vector<std::string> base{"extract", in.string(), "--dims", "9,9,9",
                                      "--type",  "u8",        "--iso",  "77.5"};
  const auto with = [&](std::vector<std::string> more) {
    std::vector<std::string> a = base;
    a.insert(a.end(), more.begin(), more.end());
    return a;
  };
  ASSERT_EQ(run(with({"--full", "-o", path("full.ply").string()})).status, 0);
  const std::size_t full = ply_triangles(path("full.ply"));
  ASSERT_GT(full, 100u);
  // A budget of 295 years or of 2^64 − 1 triangles cannot bind: the full surface.
  const bounded_result t = run(with({"--time-ms", "9.3e12", "-o", path("t.ply").string()}));
  ASSERT_EQ(t.status, 0) << t.err;
  EXPECT_EQ(ply_triangles(path("t.ply")), full);
  const bounded_result k =
      run(with({"--max-triangles", "18446744073709551615", "-o", path("k.ply").string()}));
  ASSERT_EQ(k.status, 0) << k.err;
  EXPECT_EQ(ply_triangles(path("k.ply")), full);
  // Beyond 2^64 − 1 or beyond the number types: one clear line.
  expect_refused(with({"--max-triangles", "3e19", "-o", path("x.ply").string()}),
                 "--max-triangles");
  expect_refused(with({"--max-triangles", "18446744073709551616", "-o", path("x.ply").string()}),
                 "--max-triangles");
  expect_refused(with({"--time-ms", "1e400", "-o", path("x.ply").string()}), "--time-ms");
  // Coordinates: beyond PLY's and STL's float range refused; as doubles in OBJ, finite and
  // honest.
  expect_refused(with({"--spacing", "1e40,1,1", "-o", path("x.ply").string()}), "float range");
  expect_refused(with({"--spacing", "1e40,1,1", "-o", path("x.stl").string()}),
                 "float range of STL");
  const bounded_result o = run(with({"--spacing", "1e40,1,1", "-o", path("far.obj").string()}));
  ASSERT_EQ(o.status, 0) << o.err;
  std::ifstream obj(path("far.obj"));
  std::string tag;
  double x = 0, y = 0, z = 0, max_x = 0;
  while (obj >> tag) {
    if (tag == "v") {
      obj >> x >> y >> z;
      ASSERT_TRUE(std::isfinite(x) && std::isfinite(y) && std::isfinite(z));
      max_x = std::max(max_x, x);
    } else {
      std::getline(obj, tag);
    }
  }
  EXPECT_GT(max_x, 1e40);
  expect_refused(with({"--spacing", "1e308,1,1", "-o", path("x.obj").string()}), "overflow");
  // Subnormal numbers are numbers.
  const fs::path f = write("f.raw", [] {
    std::string s(4 * 4 * 4 * 4, '\0');
    for (std::size_t i = 0; i < 64; ++i) {
      const float v = i % 3 == 0 ? 1e-30f : 0.0f;
      std::memcpy(s.data() + 4 * i, &v, 4);
    }
    return s;
  }());
  const bounded_result sub = run({"extract", f.string(), "--dims", "4,4,4", "--type", "f32",
                                  "--iso", "1e-320", "-o", path("sub.ply").string()});
  EXPECT_EQ(sub.status, 0) << sub.err;
  const fs::path img = write("img.pgm", pgm(40, 30));
  expect_refused({"contour", img.string(), "--iso", "100", "--max-segments", "3e19", "-o",
                  path("c.svg").string()},
                 "--max-segments");
}

// ---- 6. Many isovalues: memory does not grow with their number.

TEST_F(Hostile, eight_hundred_isovalues_take_about_the_memory_of_eight) {
  // coins.pgm from the shared data when present (the image of the report), else an image of
  // the same size.
  fs::path img;
  if (const auto data = test::shared_data_dir(); data && fs::exists(*data / "coins_384x303.pgm")) {
    img = *data / "coins_384x303.pgm";
  } else {
    img = write("coins.pgm", pgm(384, 303));
  }
  const auto list = [](int n) {
    std::string s;
    for (int i = 0; i < n; ++i) s.append(i ? "," : "").append(std::to_string(20.0 + 200.0 * i / n));
    return s;
  };
  const bounds b = test::limited(std::chrono::seconds(300), one_gib);
  const bounded_result few =
      run({"contour", img.string(), "--iso", list(8), "-o", path("few.obj").string()}, b);
  ASSERT_EQ(few.status, 0) << few.err;
  // Sanitizer builds (which do not measure the memory) run a tenth of the isovalues: the
  // output is still checked.
#if defined(PROGISO_SANITIZER_BUILD)
  constexpr int count = 80;
#else
  constexpr int count = 800;
#endif
  const bounded_result many =
      run({"contour", img.string(), "--iso", list(count), "-o", path("many.obj").string()}, b);
  ASSERT_EQ(many.status, 0) << many.err;
  // About 4 MB per isovalue before (3.2 GB for 800): now the output's own size at most. The
  // sanitizers' allocators keep freed memory in quarantine, so only plain builds measure it.
#if !defined(PROGISO_SANITIZER_BUILD)
  EXPECT_LT(many.max_rss_kib - few.max_rss_kib, 40 * 1024)
      << "8 isovalues: " << few.max_rss_kib << " KiB, 800: " << many.max_rss_kib << " KiB";
#endif
  const contour_set c = read_contour_obj(path("many.obj"));
  std::vector<double> seen;
  for (const auto& p : c.polylines) {
    if (seen.empty() || seen.back() != p.isovalue) seen.push_back(p.isovalue);
  }
  EXPECT_GT(seen.size(), count * 7u / 8u);
}

// ---- 7. Messages say what is true and name the file.

TEST_F(Hostile, non_finite_samples_are_refused_with_their_position) {
  std::string bytes(6 * 6 * 6 * 4, '\0');
  for (std::size_t i = 0; i < 216; ++i) {
    const float v = i % 2 == 1 ? std::numeric_limits<float>::quiet_NaN() : static_cast<float>(i);
    std::memcpy(bytes.data() + 4 * i, &v, 4);
  }
  const fs::path nan = write("nan.raw", bytes);
  expect_refused({"extract", nan.string(), "--dims", "6,6,6", "--type", "f32", "--iso", "1e9", "-o",
                  path("o.ply").string()},
                 "nan.raw");
  expect_refused({"extract", nan.string(), "--dims", "6,6,6", "--type", "f32", "--iso", "1e9", "-o",
                  path("o.ply").string()},
                 "x 1, y 0, z 0");
  const float inf = std::numeric_limits<float>::infinity();
  std::memcpy(bytes.data() + 4 * 100, &inf, 4);
  for (std::size_t i = 0; i < 216; ++i) {
    if (i != 100) std::memset(bytes.data() + 4 * i, 0, 4);
  }
  const fs::path infinite = write("inf.raw", bytes);
  expect_refused({"extract", infinite.string(), "--dims", "6,6,6", "--type", "f32", "--iso", "1",
                  "-o", path("o.ply").string()},
                 "finite");
}

TEST_F(Hostile, images_beyond_the_axis_limit_are_refused_naming_the_file) {
  const fs::path wide = write("wide.pgm", "P5\n40000 2\n255\n" + std::string(80000, '\x10'));
  expect_refused({"contour", wide.string(), "--iso", "5", "-o", path("o.svg").string()},
                 "wide.pgm");
  expect_refused({"contour", wide.string(), "--iso", "5", "-o", path("o.svg").string()}, "32769");
}

}  // namespace
}  // namespace progiso
