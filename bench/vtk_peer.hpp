// bench/vtk_peer.hpp — VTK's Flying Edges behind a plain interface, for bench/peer_bench.cpp.
//
// VTK 9.1's headers do not compile as C++20 (vtkSMPTools.h names a constructor with a
// template-id, which C++20 forbids), and progiso's headers need C++20, so the two never meet in
// one translation unit: vtk_peer.cpp is compiled as C++17 and this header uses nothing else.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

namespace progiso::bench {

/// The sample types of the wrapped array (progiso's sample_type order).
enum class vtk_sample { u8, i8, u16, i16, u32, i32, f32, f64 };

/// A Flying Edges filter (3D, or 2D for a depth of 1) on samples it reads in place.
class flying_edges {
 public:
  /// `samples` (x fastest) must outlive the filter; VTK only reads them. `normals` turns
  /// vtkFlyingEdges3D's ComputeNormals on (vertex normals from the samples' gradient).
  flying_edges(const int dims[3], const double spacing[3], const double origin[3], vtk_sample type,
               const void* samples, double isovalue, bool normals = false);
  ~flying_edges();
  flying_edges(const flying_edges&) = delete;
  flying_edges& operator=(const flying_edges&) = delete;

  /// Runs the filter from scratch; returns the triangles (3D) or line segments (2D) made.
  std::size_t run();

 private:
  struct impl;
  std::unique_ptr<impl> impl_;
};

/// Sets vtkSMPTools' thread count; returns the SMP backend's name.
std::string vtk_threads(int threads);

/// vtkRTAnalyticSource's wavelet (its default parameters) on n³ samples, x fastest.
std::vector<float> vtk_wavelet(int n);

}  // namespace progiso::bench
