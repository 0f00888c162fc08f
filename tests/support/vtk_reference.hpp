// tests/support/vtk_reference.hpp — VTK's own readers and writer behind a plain interface, the
// references of readers_vs_vtk_test.cpp: vtkStructuredPointsReader (legacy .vtk), and
// vtkXMLImageDataWriter and vtkXMLImageDataReader (.vti). VTK 9.1's headers do not compile as
// C++20, so its side is a C++17 library (vtk_reference.cpp), built where VTK is installed.
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

namespace progiso::test {

struct vtk_reference_volume {
  bool ok = false;
  std::array<int, 3> dims{};
  std::array<double, 3> spacing{};
  std::array<double, 3> origin{};  ///< the position of the first point
  int components = 0;
  std::size_t sample_bytes = 0;
  std::vector<std::byte> samples;  ///< the point scalars, host byte order
};

/// Reads `file` with vtkStructuredPointsReader; ok is false when VTK reports an error or finds
/// no point scalars.
vtk_reference_volume read_with_vtk(const std::string& file);

/// How VTK's writer is set up: data mode, appended encoding, compressor, header type, block size.
struct vtk_vti_options {
  enum class data_mode { ascii, binary, appended } mode = data_mode::appended;
  bool encode_appended = false;  ///< base64 appended data, else raw
  bool zlib = false;
  bool uint64_headers = false;
  int block_bytes = 32768;
};

/// Writes a .vti with vtkXMLImageDataWriter: a point array named "density" of `type_name` (a
/// VTK XML type: Int8 … Float64) holding `samples` (host order) over `extent`, with `spacing` and
/// `origin`, set as the active scalars after a Float32 array "decoy" of the same size. Returns
/// whether VTK wrote it.
bool write_vti_with_vtk(const std::string& file, const vtk_vti_options& options,
                        const std::string& type_name, const std::vector<std::byte>& samples,
                        const std::array<int, 6>& extent, const std::array<double, 3>& spacing,
                        const std::array<double, 3>& origin);

/// Writes `file` (.pvti) and its `pieces` piece files with vtkXMLPImageDataWriter, from the same
/// image write_vti_with_vtk() makes. Returns whether VTK wrote them.
bool write_pvti_with_vtk(const std::string& file, int pieces, const vtk_vti_options& options,
                         const std::string& type_name, const std::vector<std::byte>& samples,
                         const std::array<int, 6>& extent, const std::array<double, 3>& spacing,
                         const std::array<double, 3>& origin);

/// Reads a .pvti with vtkXMLPImageDataReader, as read_vti_with_vtk() reads a .vti.
vtk_reference_volume read_pvti_with_vtk(const std::string& file);

/// Reads `file` with vtkXMLImageDataReader: the active point scalars (else the first point
/// array), the dimensions, spacing and the position of the first point (dims, spacing, origin);
/// ok is false when VTK reports an error or finds no point array.
vtk_reference_volume read_vti_with_vtk(const std::string& file);

/// vtkFlyingEdges3D's surface of f64 samples (x fastest) at isovalue w, with ComputeNormals on:
/// its points and their normals (as VTK computes them: gradients of central differences at the
/// edge's ends, one-sided on the faces, interpolated along the edge). ok is false when VTK
/// reports an error.
struct vtk_reference_surface {
  bool ok = false;
  std::vector<std::array<double, 3>> points;
  std::vector<std::array<double, 3>> normals;
};
vtk_reference_surface flying_edges_with_normals(const std::vector<double>& samples,
                                                const std::array<int, 3>& dims,
                                                const std::array<double, 3>& spacing,
                                                const std::array<double, 3>& origin, double w);

}  // namespace progiso::test
