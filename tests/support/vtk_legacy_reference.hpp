// tests/support/vtk_legacy_reference.hpp — VTK's own legacy reader (vtkStructuredPointsReader)
// behind a plain interface: VTK 9.1's headers do not compile as C++20, so its side is a C++17
// library (vtk_legacy_reference.cpp), built where VTK is installed.
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
  std::array<double, 3> origin{};
  int components = 0;
  std::size_t sample_bytes = 0;
  std::vector<std::byte> samples;  ///< the point scalars, host byte order
};

/// Reads `file` with vtkStructuredPointsReader; ok is false when VTK reports an error or finds
/// no point scalars.
vtk_reference_volume read_with_vtk(const std::string& file);

}  // namespace progiso::test
