// read_hdf5() (io/detail/hdf5_reader.hpp): Imaris and BigDataViewer resolution pyramids. Files
// written by h5py (Debian's python3-h5py: Imaris's text attributes and padded blocks, gzip and
// shuffle, several timepoints and channels or setups, BigDataViewer's int16 as unsigned) must
// read to the samples NumPy holds, byte for byte, at every level, with the spacing and origin
// the files declare. Hostile files must each give one error naming the file: a decompression
// bomb (refused before anything of its size is allocated), a truncated file, sizes beyond the
// dataset, missing attributes and groups, text where numbers belong, a dataset of another rank
// or type, a level or volume that is not there.
#include <progiso/io/volume_io.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <progiso/core/base/error.hpp>

#include "support/io_test_helpers.hpp"
#include "support/scratch_dir.hpp"

namespace progiso {
namespace {

namespace fs = std::filesystem;
using test::contains;
using test::read_whole_file;

class scratch_dir : public test::scratch_dir {
 public:
  scratch_dir() : test::scratch_dir("progiso-hdf5-reader-test-") {}
};

bool have_h5py() { return std::string_view(PROGISO_H5PY_PYTHON).size() > 0; }

bool run_python(const scratch_dir& dir, const std::string& script) {
  const fs::path file = dir.path() / "write.py";
  std::ofstream(file) << script;
  const std::string command =
      std::string(PROGISO_H5PY_PYTHON) + " " + file.string() + " " + dir.path().string();
  return std::system(command.c_str()) == 0;
}

// Each file and what NumPy holds for it: `<name>.<level>.<volume>.bin`, the samples in host
// order, x fastest (a C-order (z, y, x) array's bytes).
constexpr const char* h5py_files = R"(
import sys, os, numpy as np, h5py
out = sys.argv[1]
rng = np.random.default_rng(5)

def expect(name, level, volume, a):
    np.ascontiguousarray(a).astype(a.dtype.newbyteorder('=')).tofile(
        os.path.join(out, '%s.%d.%d.bin' % (name, level, volume)))

def text(obj, name, value):
    obj.attrs.create(name, np.array(list(value), dtype='|S1'))

def block_mean(a):
    z, y, x = (s // 2 for s in a.shape)
    return a[:2*z, :2*y, :2*x].reshape(z, 2, y, 2, x, 2).mean(axis=(1, 3, 5)).astype(a.dtype)

# Imaris: 2 timepoints x 3 channels, uint16, three levels (block means), data padded to blocks
# of 8 and stored in gzip chunks with shuffle; the box from (-3, 1, 0.5) to (10.2, 9.8, 41.7).
full = rng.integers(0, 4000, size=(2, 3, 21, 17, 13)).astype('<u2')
box = [(-3.0, 10.2), (1.0, 9.8), (0.5, 41.7)]
with h5py.File(os.path.join(out, 'cells.ims'), 'w') as f:
    text(f, 'ImarisDataSet', 'ImarisDataSet')
    text(f, 'ImarisVersion', '5.5.0')
    info = f.create_group('DataSetInfo/Image')
    for q, (lo, hi) in enumerate(box):
        text(info, 'ExtMin%d' % q, repr(lo))
        text(info, 'ExtMax%d' % q, repr(hi))
    for t in range(2):
        for c in range(3):
            level = full[t, c]
            for r in range(3):
                g = f.create_group('DataSet/ResolutionLevel %d/TimePoint %d/Channel %d' % (r, t, c))
                z, y, x = level.shape
                text(g, 'ImageSizeX', str(x)); text(g, 'ImageSizeY', str(y))
                text(g, 'ImageSizeZ', str(z))
                pad = np.zeros((-(-z // 8) * 8, -(-y // 8) * 8, -(-x // 8) * 8), dtype=level.dtype)
                pad[:z, :y, :x] = level
                g.create_dataset('Data', data=pad, chunks=(8, 8, 8), compression='gzip',
                                 shuffle=True)
                expect('cells', r, 3 * t + c, level)
                level = block_mean(level)

# BigDataViewer: 1 timepoint x 2 setups, 16-bit data stored as int16 (values past 32767 too),
# levels by factors (1,1,1), (2,2,1), (4,4,2).
factors = [(1, 1, 1), (2, 2, 1), (4, 4, 2)]
with h5py.File(os.path.join(out, 'bdv.h5'), 'w') as f:
    for s in range(2):
        f.create_dataset('s%02d/resolutions' % s, data=np.array(factors, dtype=float))
        f.create_dataset('s%02d/subdivisions' % s, data=np.array([[16, 16, 8]] * 3, dtype=np.int32))
        base = rng.integers(0, 65536, size=(12, 30, 26)).astype('<u2')
        for l, (fx, fy, fz) in enumerate(factors):
            level = np.ascontiguousarray(base[::fz, ::fy, ::fx])
            chunks = tuple(min(c, n) for c, n in zip((4, 8, 8), level.shape))
            f.create_dataset('t00000/s%02d/%d/cells' % (s, l), data=level.view('<i2'),
                             chunks=chunks, compression='gzip')
            expect('bdv', l, s, level)

# A bomb: 4096^3 declared, one chunk stored.
with h5py.File(os.path.join(out, 'bomb.h5'), 'w') as f:
    f.create_dataset('s00/resolutions', data=np.array([[1, 1, 1]], dtype=float))
    d = f.create_dataset('t00000/s00/0/cells', shape=(4096, 4096, 4096), dtype=np.uint8,
                         chunks=(64, 64, 64), compression='gzip')
    d[0:64, 0:64, 0:64] = 7

def imaris(name, size=('13', '17', '21'), data=None, ext=('0', '4')):
    with h5py.File(os.path.join(out, name), 'w') as f:
        text(f, 'ImarisDataSet', 'ImarisDataSet')
        info = f.create_group('DataSetInfo/Image')
        for q in range(3):
            text(info, 'ExtMin%d' % q, ext[0]); text(info, 'ExtMax%d' % q, ext[1])
        g = f.create_group('DataSet/ResolutionLevel 0/TimePoint 0/Channel 0')
        for axis, n in zip('XYZ', size):
            if n is not None:
                text(g, 'ImageSize' + axis, n)
        g.create_dataset('Data', data=np.zeros((21, 17, 13), np.uint8) if data is None else data)

imaris('beyond.ims', size=('13', '17', '40'))
imaris('no_size.ims', size=('13', None, '21'))
imaris('words.ims', size=('thirteen', '17', '21'))
imaris('huge.ims', size=('100000', '17', '21'))
imaris('flat.ims', data=np.zeros((17, 13), np.uint8))
imaris('strings.ims', data=np.array([[[b'ab']]] * 2))
imaris('inverted_box.ims', ext=('4', '0'))
with h5py.File(os.path.join(out, 'neither.h5'), 'w') as f:
    f.create_dataset('volume', data=np.zeros((4, 4, 4), np.uint8))
)";

class Hdf5Reader : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!have_h5py()) GTEST_SKIP() << "python3 with h5py (python3-h5py) not found";
    ASSERT_TRUE(run_python(dir_, h5py_files)) << "h5py could not write the test files";
  }
  [[nodiscard]] fs::path at(const std::string& name) const { return dir_.path() / name; }
  scratch_dir dir_;
};

std::string bytes_of(const volume& v) {
  return {reinterpret_cast<const char*>(v.bytes()), v.byte_size()};
}

TEST_F(Hdf5Reader, imaris_levels_timepoints_and_channels_read_to_numpys_samples) {
  const volume_source src(at("cells.ims"), std::nullopt, volume_choice{{}, 4, {}});
  EXPECT_EQ(src.levels(), 3U);
  for (std::int64_t level = 0; level < 3; ++level) {
    for (std::int64_t vol = 0; vol < 6; ++vol) {
      SCOPED_TRACE("level " + std::to_string(level) + ", volume " + std::to_string(vol));
      const volume v = read_hdf5(at("cells.ims"), volume_choice{{}, vol, level});
      EXPECT_EQ(v.type(), sample_type::u16);
      EXPECT_TRUE(bytes_of(v) == read_whole_file(at("cells." + std::to_string(level) + "." +
                                                    std::to_string(vol) + ".bin")));
    }
  }
  // The box (-3, 1, 0.5) to (10.2, 9.8, 41.7) over 13 x 17 x 21 voxels, then 6 x 8 x 10.
  const volume v0 = read_hdf5(at("cells.ims"), volume_choice{{}, 0, 0});
  EXPECT_EQ(v0.dims(), (index3{13, 17, 21}));
  EXPECT_NEAR(v0.spacing()[0], 13.2 / 13, 1e-12);
  EXPECT_NEAR(v0.spacing()[2], 41.2 / 21, 1e-12);
  EXPECT_NEAR(v0.origin()[0], -3.0 + 0.5 * 13.2 / 13, 1e-12);
  const volume v1 = read_hdf5(at("cells.ims"), volume_choice{{}, 0, 1});
  EXPECT_EQ(v1.dims(), (index3{6, 8, 10}));
  EXPECT_NEAR(v1.spacing()[1], 8.8 / 8, 1e-12);
  EXPECT_NEAR(v1.origin()[1], 1.0 + 0.5 * 8.8 / 8, 1e-12);
}

TEST_F(Hdf5Reader, bigdataviewer_setups_and_levels_read_int16_as_unsigned) {
  for (std::int64_t level = 0; level < 3; ++level) {
    for (std::int64_t setup = 0; setup < 2; ++setup) {
      SCOPED_TRACE("level " + std::to_string(level) + ", setup " + std::to_string(setup));
      const volume v = read_hdf5(at("bdv.h5"), volume_choice{{}, setup, level});
      EXPECT_EQ(v.type(), sample_type::u16);
      EXPECT_TRUE(bytes_of(v) == read_whole_file(at("bdv." + std::to_string(level) + "." +
                                                    std::to_string(setup) + ".bin")));
    }
  }
  // Factors (4, 4, 2) at level 2: spacing 4, 4, 2 of level 0's 1, origin (f − 1) / 2.
  const volume v2 = read_hdf5(at("bdv.h5"), volume_choice{{}, 1, 2});
  EXPECT_EQ(v2.spacing(), (std::array<double, 3>{4.0, 4.0, 2.0}));
  EXPECT_EQ(v2.origin(), (std::array<double, 3>{1.5, 1.5, 0.5}));
  // A read asked to stop gives nothing (the child reading it is ended).
  EXPECT_FALSE(volume_source(at("bdv.h5"), std::nullopt, volume_choice{{}, 0, {}})
                   .read_level(0, std::nullopt, [] { return true; })
                   .has_value());
  // A given spacing is level 0's, and scales the level's.
  volume_source src(at("bdv.h5"), std::nullopt, volume_choice{{}, 1, {}});
  const std::optional<volume> s2 = src.read_level(2, std::array<double, 3>{0.5, 0.5, 3.0});
  ASSERT_TRUE(s2.has_value());
  EXPECT_EQ(s2->spacing(), (std::array<double, 3>{2.0, 2.0, 6.0}));
}

TEST_F(Hdf5Reader, a_plane_window_holds_numpys_planes_for_every_level_and_volume) {
  // Imaris (chunked, gzip) and BigDataViewer: windows of 1 and 3 planes, forward, each read by a
  // child, then one back to the start.
  for (const std::string name : {"cells.ims", "bdv.h5"}) {
    const std::int64_t volumes = name == "cells.ims" ? 6 : 2;
    for (std::int64_t level = 0; level < 3; ++level) {
      for (std::int64_t vol = 0; vol < volumes; ++vol) {
        SCOPED_TRACE(name + " level " + std::to_string(level) + ", volume " + std::to_string(vol));
        const volume whole = read_hdf5(at(name), volume_choice{{}, vol, level});
        const std::string want = bytes_of(whole);
        for (const std::int64_t step : {1, 3}) {
          volume_source source(at(name), std::nullopt, volume_choice{{}, vol, level});
          std::optional<plane_window> w = source.window();
          ASSERT_TRUE(w.has_value());
          const volume& f = w->field();
          EXPECT_EQ(f.dims(), whole.dims());
          EXPECT_EQ(f.spacing(), whole.spacing());
          EXPECT_EQ(f.origin(), whole.origin());
          EXPECT_GE(w->chunk_planes(), 1);
          const auto plane =
              static_cast<std::size_t>(f.dims()[0] * f.dims()[1]) * sample_size(f.type());
          const std::int64_t nz = f.dims()[2];
          const auto same = [&](std::int64_t z0, std::int64_t z1) {
            const std::size_t from = plane * static_cast<std::size_t>(z0);
            return std::memcmp(f.bytes() + from, want.data() + from,
                               plane * static_cast<std::size_t>(z1 - z0)) == 0;
          };
          for (std::int64_t z = 0; z < nz; z += step) {
            const std::int64_t end = std::min(nz, z + step);
            w->hold(z, end);
            EXPECT_TRUE(same(z, end)) << "planes " << z << " to " << end - 1;
          }
          w->hold(0, 1);
          EXPECT_TRUE(same(0, 1)) << "back to the start";
        }
      }
    }
  }
  // A hostile level is refused before any plane is held or any memory of its size reserved.
  for (const auto& [name, says] :
       {std::pair<std::string, std::string>{"bomb.h5", "decompression bomb"},
        {"beyond.ims", "expected a dataset at least 13 x 17 x 40"}}) {
    volume_source source(at(name), std::nullopt, volume_choice{{}, 0, {}});
    const std::string m = test::error_message_naming(at(name), [&] { (void)source.window(); });
    EXPECT_TRUE(contains(m, says)) << m;
  }
}

TEST_F(Hdf5Reader, a_file_with_the_signature_is_read_whatever_its_name) {
  fs::copy_file(at("bdv.h5"), at("scan.data"));
  const volume v =
      read_volume(at("scan.data"), std::nullopt, std::nullopt, volume_choice{{}, 0, {}});
  EXPECT_TRUE(bytes_of(v) == read_whole_file(at("bdv.0.0.bin")));
}

void expect_refused(const fs::path& file, const volume_choice& choice, const std::string& says) {
  try {
    (void)read_volume(file, std::nullopt, std::nullopt, choice);
    ADD_FAILURE() << file << " was read";
  } catch (const error& e) {
    const std::string m = e.what();
    EXPECT_TRUE(contains(m, file.filename().string())) << m;
    EXPECT_TRUE(contains(m, says)) << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  }
}

TEST_F(Hdf5Reader, hostile_files_each_give_one_error_naming_the_file) {
  const volume_choice v0{{}, 0, {}};
  expect_refused(at("bomb.h5"), v0, "decompression bomb");
  expect_refused(at("beyond.ims"), v0, "expected a dataset at least 13 x 17 x 40");
  expect_refused(at("no_size.ims"), v0, "ImageSizeY");
  expect_refused(at("words.ims"), v0, "expected a number, found 'thirteen'");
  expect_refused(at("huge.ims"), v0, "1 to 32769 samples per axis");
  expect_refused(at("flat.ims"), v0, "three-dimensional dataset");
  expect_refused(at("strings.ims"), v0, "expected samples of uint8");
  expect_refused(at("inverted_box.ims"), v0, "ExtMax0 above ExtMin0");
  expect_refused(at("neither.h5"), v0, "an Imaris file");
  expect_refused(at("cells.ims"), volume_choice{{}, 6, {}}, "volume 6 was chosen");
  expect_refused(at("cells.ims"), volume_choice{{}, 0, 3}, "level 3 was chosen");
  expect_refused(at("cells.ims"), volume_choice{}, "time series of 6 volumes");
  // Truncated anywhere: an error, never a crash.
  const std::string whole = read_whole_file(at("cells.ims"));
  for (const std::size_t keep :
       {std::size_t{0}, std::size_t{8}, std::size_t{700}, whole.size() / 3, whole.size() - 100}) {
    SCOPED_TRACE(keep);
    test::write_file(at("cut.ims"), whole.substr(0, keep));
    try {
      (void)read_volume(at("cut.ims"), std::nullopt, std::nullopt, v0);
      ADD_FAILURE() << "a truncated file was read";
    } catch (const error& e) {
      EXPECT_TRUE(contains(e.what(), "cut.ims")) << e.what();
    }
  }
}

TEST_F(Hdf5Reader, a_source_reads_the_chosen_level_and_lists_the_one_file) {
  volume_source src(at("cells.ims"), std::nullopt, volume_choice{{}, 1, 2});
  EXPECT_EQ(src.read().dims(), (index3{3, 4, 5}));
  const std::vector<fs::path> inputs =
      volume_input_files(at("cells.ims"), std::nullopt, volume_choice{{}, 1, 0});
  ASSERT_EQ(inputs.size(), 1U);
  EXPECT_EQ(inputs[0], at("cells.ims"));
}

}  // namespace
}  // namespace progiso
