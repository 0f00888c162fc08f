#include "support/vtk_legacy_reference.hpp"

#include <cstring>

#include <vtkDataArray.h>
#include <vtkFieldData.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkStructuredPoints.h>
#include <vtkStructuredPointsReader.h>

namespace progiso::test {

vtk_reference_volume read_with_vtk(const std::string& file) {
  vtk_reference_volume out;
  vtkNew<vtkStructuredPointsReader> reader;
  reader->SetFileName(file.c_str());
  reader->ReadAllScalarsOn();
  reader->ReadAllFieldsOn();
  reader->Update();
  if (reader->GetErrorCode() != 0) return out;
  vtkImageData* image = reader->GetOutput();
  if (image == nullptr) return out;
  vtkDataArray* a = image->GetPointData()->GetScalars();
  if (a == nullptr && image->GetPointData()->GetNumberOfArrays() > 0) {
    a = image->GetPointData()->GetArray(0);
  }
  if (a == nullptr) return out;
  int dims[3];
  image->GetDimensions(dims);
  double spacing[3];
  double origin[3];
  image->GetSpacing(spacing);
  image->GetOrigin(origin);
  for (int i = 0; i < 3; ++i) {
    out.dims[static_cast<std::size_t>(i)] = dims[i];
    out.spacing[static_cast<std::size_t>(i)] = spacing[i];
    out.origin[static_cast<std::size_t>(i)] = origin[i];
  }
  out.components = a->GetNumberOfComponents();
  out.sample_bytes = static_cast<std::size_t>(a->GetDataTypeSize());
  const std::size_t bytes =
      static_cast<std::size_t>(a->GetNumberOfTuples() * a->GetNumberOfComponents()) *
      out.sample_bytes;
  out.samples.resize(bytes);
  std::memcpy(out.samples.data(), a->GetVoidPointer(0), bytes);
  out.ok = true;
  return out;
}

}  // namespace progiso::test
