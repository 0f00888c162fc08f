// progiso's VTK readers against VTK's own (built where scripts/install-deps.sh --peers installed
// VTK; support/vtk_reference.hpp):
// - legacy .vtk: progiso and vtkStructuredPointsReader read the same generated files (every data
//   type, binary and ASCII, SCALARS and FIELD arrays, keywords in either case, SPACING and
//   ASPECT_RATIO) and must agree on the sizes, every sample, the spacing and the origin;
// - vertex normals: progiso's (surface/normals.hpp) and vtkFlyingEdges3D's with ComputeNormals
//   on agree on every axis-aligned grid edge both place a vertex on;
// - .vti: every file vtkXMLImageDataWriter writes (every data type × ascii, inline binary,
//   appended raw and appended base64 × no compressor and zlib in small and default blocks ×
//   UInt32 and UInt64 headers, on an extent that does not start at 0) reads as the samples VTK
//   was given, with VTK's spacing and the position of VTK's first point as the origin; and every
//   file progiso's tests write by hand (support/vti_files.hpp, big-endian ones too) reads in
//   vtkXMLImageDataReader as in progiso.
#include <progiso/io/volume_io.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include <progiso/core/field/analytic.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/refine/refiner.hpp>

#include "support/io_test_helpers.hpp"
#include "support/scratch_dir.hpp"
#include "support/test_data.hpp"
#include "support/vti_files.hpp"
#include "support/vtk_legacy_files.hpp"
#include "support/vtk_reference.hpp"

namespace {

namespace fs = std::filesystem;
using progiso::test::vtk_vti_options;

/// VTK's reading and progiso's agree on the sizes, samples, spacing and first point.
void expect_same(const progiso::test::vtk_reference_volume& ref, const progiso::volume& v) {
  ASSERT_TRUE(ref.ok);
  for (std::size_t a = 0; a < 3; ++a) {
    EXPECT_EQ(ref.dims[a], v.dims()[a]);
    EXPECT_DOUBLE_EQ(std::abs(ref.spacing[a]), v.spacing()[a]);
    EXPECT_DOUBLE_EQ(ref.origin[a], v.origin()[a]);
  }
  EXPECT_EQ(ref.components, 1);
  EXPECT_EQ(ref.sample_bytes, progiso::sample_size(v.type()));
  ASSERT_EQ(ref.samples.size(), v.byte_size());
  EXPECT_EQ(std::memcmp(ref.samples.data(), v.bytes(), v.byte_size()), 0);
}

TEST(VtkLegacyVsVtk, agree_on_every_type_encoding_attribute_and_keyword_case) {
  progiso::test::scratch_dir dir("progiso-vtk-legacy-vtk-test-");
  unsigned seed = 1;
  for (const auto& t : progiso::test::vtk_types) {
    for (int variant = 0; variant < 8; ++variant) {
      progiso::test::vtk_legacy_file f;
      f.type_name = t.name;
      f.type = t.type;
      f.samples = progiso::test::random_samples(t.type, 60, seed);
      f.ascii = (variant & 1) != 0;
      f.upper_case = (variant & 2) == 0;
      f.as_field = (variant & 4) != 0;
      f.aspect_ratio = variant == 3;
      f.spacing = "0.5 2 1.25";
      f.origin = "-3 4.5 100";
      const std::filesystem::path file = f.write(dir.path(), "v" + std::to_string(seed++));
      SCOPED_TRACE(file.string());
      expect_same(progiso::test::read_with_vtk(file.string()), progiso::read_vtk_legacy(file));
    }
  }
}

TEST(VtiVsVtk, reads_every_file_vtks_writer_makes) {
  progiso::test::scratch_dir dir("progiso-vti-vtk-test-");
  const std::array<int, 6> extent{3, 9, -2, 2, 5, 8};  // 7 × 5 × 4 points
  const std::size_t count = 7 * 5 * 4;
  unsigned seed = 1;
  int files = 0;
  for (const auto& t : progiso::test::vti_types) {
    for (int m = 0; m < 4; ++m) {
      for (int variant = 0; variant < 6; ++variant) {
        vtk_vti_options o;
        o.mode = m == 0   ? vtk_vti_options::data_mode::ascii
                 : m == 1 ? vtk_vti_options::data_mode::binary
                          : vtk_vti_options::data_mode::appended;
        o.encode_appended = m == 3;
        o.zlib = variant >= 2;
        o.block_bytes = variant >= 4 ? 32768 : 40;
        o.uint64_headers = (variant & 1) != 0;
        if (m == 0 && variant > 0) continue;
        const std::vector<std::byte> samples = progiso::test::random_samples(t.type, count, seed);
        const fs::path file = dir / ("w" + std::to_string(seed++) + ".vti");
        ASSERT_TRUE(progiso::test::write_vti_with_vtk(file.string(), o, t.name, samples, extent,
                                                      {0.5, 2.0, 1.25}, {-3.0, 4.5, 100.0}));
        SCOPED_TRACE(file.string());
        const progiso::volume v = progiso::read_vti(file);
        EXPECT_EQ(v.type(), t.type);
        ASSERT_EQ(v.byte_size(), samples.size());
        EXPECT_EQ(std::memcmp(v.bytes(), samples.data(), samples.size()), 0);
        expect_same(progiso::test::read_vti_with_vtk(file.string()), v);
        ++files;
      }
    }
  }
  EXPECT_EQ(files, 8 * (1 + 3 * 6));
}

TEST(VtiVsVtk, vtk_reads_the_hand_written_files_as_progiso_does) {
  progiso::test::scratch_dir dir("progiso-vti-vtk-test-");
  unsigned seed = 100;
  for (const auto& t : progiso::test::vti_types) {
    for (int m = 0; m < 4; ++m) {
      for (int variant = 0; variant < 8; ++variant) {
        progiso::test::vti_file f;
        f.type_name = t.name;
        f.type = t.type;
        f.extent = {2, 6, -1, 2, 10, 12};
        f.samples = progiso::test::random_samples(t.type, f.count(), seed);
        f.how = static_cast<progiso::test::vti_file::mode>(m);
        f.zlib = (variant & 1) != 0;
        f.uint64_headers = (variant & 2) != 0;
        f.big_endian = (variant & 4) != 0;
        f.decoy_first = variant != 6;
        if (m == 0 && variant > 0) continue;
        const fs::path file = f.write(dir.path(), "h" + std::to_string(seed++));
        SCOPED_TRACE(file.string());
        expect_same(progiso::test::read_vti_with_vtk(file.string()), progiso::read_vti(file));
      }
    }
  }
}

TEST(VtiVsVtk, reads_every_pvti_vtks_parallel_writer_makes_as_vtks_reader_does) {
  progiso::test::scratch_dir dir("progiso-vti-vtk-test-");
  const std::array<int, 6> extent{-4, 5, 0, 6, 1, 4};  // 10 × 7 × 4 points
  const std::size_t count = 10 * 7 * 4;
  unsigned seed = 500;
  for (const auto& t : progiso::test::vti_types) {
    for (int m = 0; m < 3; ++m) {
      for (const int pieces : {1, 3, 5}) {
        vtk_vti_options o;
        o.mode = m == 0   ? vtk_vti_options::data_mode::ascii
                 : m == 1 ? vtk_vti_options::data_mode::binary
                          : vtk_vti_options::data_mode::appended;
        o.zlib = pieces != 3;
        const std::vector<std::byte> samples = progiso::test::random_samples(t.type, count, seed);
        const fs::path file = dir / ("p" + std::to_string(seed++) + ".pvti");
        ASSERT_TRUE(progiso::test::write_pvti_with_vtk(file.string(), pieces, o, t.name, samples,
                                                       extent, {0.5, 2.0, 1.25},
                                                       {-3.0, 4.5, 100.0}));
        SCOPED_TRACE(file.string());
        const progiso::volume v = progiso::read_pvti(file);
        ASSERT_EQ(v.byte_size(), samples.size());
        EXPECT_EQ(std::memcmp(v.bytes(), samples.data(), samples.size()), 0);
        expect_same(progiso::test::read_pvti_with_vtk(file.string()), v);
        EXPECT_EQ(progiso::volume_input_files(file, std::nullopt).size(),
                  static_cast<std::size_t>(pieces) + 1);
      }
    }
  }
}

// progiso's vertex normals (add_vertex_normals) against vtkFlyingEdges3D's with ComputeNormals on,
// at the vertices both place on the same axis-aligned grid edge (marching tetrahedra also puts
// vertices on cell diagonals, which Flying Edges has none of): VTK interpolates the central
// differences of the edge's ends along the edge; progiso's trilinear weights reduce to the same
// two ends there. Vertices moved by the clamp that keeps progiso's strictly inside their edge
// (within 1/4096 of an end) are skipped; VTK's points and normals are floats. On an analytic field
// with anisotropic spacing and an origin, and on the shared volumes where the data folder is found.
struct edge_key {
  std::array<std::int64_t, 3> low;
  int axis;
  bool operator<(const edge_key& o) const { return std::tie(low, axis) < std::tie(o.low, o.axis); }
};

// The axis-aligned grid edge a point of index coordinates q lies on, if it lies on one.
std::optional<edge_key> edge_of(const std::array<double, 3>& q) {
  int fractional = -1;
  edge_key k{};
  for (int a = 0; a < 3; ++a) {
    const double r = std::round(q[static_cast<std::size_t>(a)]);
    // VTK's points are floats: integral to within their rounding (a vertex clamped inside its
    // edge lies at least 1/4096 from either end).
    if (std::abs(q[static_cast<std::size_t>(a)] - r) < 1e-4) {
      k.low[static_cast<std::size_t>(a)] = static_cast<std::int64_t>(r);
    } else {
      if (fractional >= 0) return std::nullopt;
      fractional = a;
      k.low[static_cast<std::size_t>(a)] =
          static_cast<std::int64_t>(std::floor(q[static_cast<std::size_t>(a)]));
    }
  }
  if (fractional < 0) return std::nullopt;
  k.axis = fractional;
  return k;
}

void expect_normals_of_flying_edges(const progiso::volume& v, double w, const std::string& name) {
  SCOPED_TRACE(name + " w " + std::to_string(w));
  std::vector<double> samples(v.voxel_count());
  for (std::size_t i = 0; i < samples.size(); ++i) samples[i] = v.at(i);
  const auto& d = v.dims();
  const progiso::test::vtk_reference_surface fe = progiso::test::flying_edges_with_normals(
      samples, {static_cast<int>(d[0]), static_cast<int>(d[1]), static_cast<int>(d[2])},
      v.spacing(), v.origin(), w);
  ASSERT_TRUE(fe.ok);
  ASSERT_GT(fe.points.size(), 100u);
  progiso::extract_options o;
  o.normals = true;
  const progiso::triangle_mesh m = progiso::extract_isosurface(v, w, o).mesh;
  const auto index_of = [&v](const std::array<double, 3>& p) {
    std::array<double, 3> q{};
    for (std::size_t a = 0; a < 3; ++a) q[a] = (p[a] - v.origin()[a]) / v.spacing()[a];
    return q;
  };
  std::map<edge_key, std::size_t> ours;
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    if (const auto k = edge_of(index_of(m.vertices[i]))) ours.emplace(*k, i);
  }
  std::size_t compared = 0;
  double worst = 1.0;
  for (std::size_t i = 0; i < fe.points.size(); ++i) {
    const auto q = index_of(fe.points[i]);
    const auto k = edge_of(q);
    if (!k) continue;  // on a grid point (VTK does not clamp)
    const auto it = ours.find(*k);
    ASSERT_NE(it, ours.end()) << "no vertex of progiso on Flying Edges' edge";
    const auto p = index_of(m.vertices[it->second]);
    if (std::abs(p[static_cast<std::size_t>(k->axis)] - q[static_cast<std::size_t>(k->axis)]) >
        5e-5) {
      continue;  // moved by the clamp
    }
    const auto& a = m.normals[it->second];
    const auto& b = fe.normals[i];
    const double cosine = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    worst = std::min(worst, cosine);
    for (std::size_t c = 0; c < 3; ++c) {
      ASSERT_NEAR(a[c], b[c], 1e-5) << "vertex at (" << q[0] << ", " << q[1] << ", " << q[2] << ")";
    }
    ++compared;
  }
  EXPECT_GT(compared, fe.points.size() / 2);
  EXPECT_GT(worst, 0.9999);
}

TEST(NormalsVsVtk, equal_flying_edges_normals_on_the_grid_edges_both_use) {
  // Marschner–Lobb on an anisotropic grid with an origin (spacing enters the normals).
  const progiso::volume ml = progiso::make_marschner_lobb({41, 37, 33});
  std::vector<std::byte> bytes(ml.byte_size());
  std::memcpy(bytes.data(), ml.bytes(), bytes.size());
  const progiso::volume v(ml.dims(), ml.type(), std::move(bytes), {0.5, 1.25, 2.0},
                          {-3.0, 4.5, 10.0});
  expect_normals_of_flying_edges(v, 0.5, "Marschner-Lobb");
  const auto dir = progiso::test::shared_data_dir();
  if (!dir) GTEST_SKIP() << "shared data folder not found (../shared/data or PROGISO_DATA_DIR)";
  for (const char* name : {"hipip", "headsq", "brainsmall"}) {
    const progiso::test::shared_volume& info = *progiso::test::find_shared_volume(name);
    const progiso::volume data = progiso::test::load_shared_volume(info, *dir);
    expect_normals_of_flying_edges(data, info.isovalues.front(), name);
  }
}

}  // namespace
