#include "support/vtk_reference.hpp"

#include <cstring>

#include <vtkDataArray.h>
#include <vtkDoubleArray.h>
#include <vtkFlyingEdges3D.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPolyData.h>
#include <vtkSMPTools.h>
#include <vtkSmartPointer.h>
#include <vtkStructuredPoints.h>
#include <vtkStructuredPointsReader.h>
#include <vtkType.h>
#include <vtkXMLImageDataReader.h>
#include <vtkXMLImageDataWriter.h>
#include <vtkXMLPImageDataReader.h>
#include <vtkXMLPImageDataWriter.h>

namespace progiso::test {
namespace {

/// VTK's own parallel loops (the XML writer computes each array's range with vtkSMPTools) run
/// sequentially: the reference is about the files, and VTK's TBB tasks, spawned from a library
/// ThreadSanitizer does not instrument, look like races on its stack to the TSan preset.
void sequential_vtk() {
  static const bool set = vtkSMPTools::SetBackend("Sequential");
  (void)set;
}

/// What a reader made of an image: its active point scalars (else its first point array), its
/// dimensions, spacing and the position of its first point; ok false without an array.
vtk_reference_volume reference_of(vtkImageData* image) {
  vtk_reference_volume out;
  if (image == nullptr) return out;
  vtkDataArray* a = image->GetPointData()->GetScalars();
  if (a == nullptr && image->GetPointData()->GetNumberOfArrays() > 0) {
    a = image->GetPointData()->GetArray(0);
  }
  if (a == nullptr) return out;
  int dims[3];
  image->GetDimensions(dims);
  double spacing[3];
  double first[3];
  image->GetSpacing(spacing);
  image->GetPoint(0, first);
  for (int i = 0; i < 3; ++i) {
    out.dims[static_cast<std::size_t>(i)] = dims[i];
    out.spacing[static_cast<std::size_t>(i)] = spacing[i];
    out.origin[static_cast<std::size_t>(i)] = first[i];
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

int vtk_type_of(const std::string& name) {
  if (name == "Int8") return VTK_SIGNED_CHAR;
  if (name == "UInt8") return VTK_UNSIGNED_CHAR;
  if (name == "Int16") return VTK_SHORT;
  if (name == "UInt16") return VTK_UNSIGNED_SHORT;
  if (name == "Int32") return VTK_INT;
  if (name == "UInt32") return VTK_UNSIGNED_INT;
  if (name == "Float32") return VTK_FLOAT;
  return VTK_DOUBLE;
}

}  // namespace

vtk_reference_volume read_with_vtk(const std::string& file) {
  sequential_vtk();
  vtkNew<vtkStructuredPointsReader> reader;
  reader->SetFileName(file.c_str());
  reader->ReadAllScalarsOn();
  reader->ReadAllFieldsOn();
  reader->Update();
  if (reader->GetErrorCode() != 0) return {};
  return reference_of(reader->GetOutput());
}

namespace {

/// The image write_vti_with_vtk() writes; null when the samples do not fit the extent.
vtkSmartPointer<vtkImageData> image_of(const std::string& type_name,
                                       const std::vector<std::byte>& samples,
                                       const std::array<int, 6>& extent,
                                       const std::array<double, 3>& spacing,
                                       const std::array<double, 3>& origin) {
  auto image = vtkSmartPointer<vtkImageData>::New();
  image->SetExtent(extent[0], extent[1], extent[2], extent[3], extent[4], extent[5]);
  image->SetSpacing(spacing[0], spacing[1], spacing[2]);
  image->SetOrigin(origin[0], origin[1], origin[2]);
  const vtkIdType n = image->GetNumberOfPoints();
  vtkSmartPointer<vtkDataArray> a =
      vtkSmartPointer<vtkDataArray>::Take(vtkDataArray::CreateDataArray(vtk_type_of(type_name)));
  a->SetName("density");
  a->SetNumberOfTuples(n);
  if (static_cast<std::size_t>(n) * static_cast<std::size_t>(a->GetDataTypeSize()) !=
      samples.size()) {
    return nullptr;
  }
  std::memcpy(a->GetVoidPointer(0), samples.data(), samples.size());
  vtkSmartPointer<vtkDataArray> decoy =
      vtkSmartPointer<vtkDataArray>::Take(vtkDataArray::CreateDataArray(VTK_FLOAT));
  decoy->SetName("decoy");
  decoy->SetNumberOfTuples(n);
  for (vtkIdType i = 0; i < n; ++i) decoy->SetTuple1(i, -0.25 * static_cast<double>(i));
  image->GetPointData()->AddArray(decoy);
  image->GetPointData()->SetScalars(a);
  return image;
}

/// A writer (serial or parallel) set up as `options` say.
void set_up(vtkXMLWriter* w, const vtk_vti_options& options) {
  switch (options.mode) {
    case vtk_vti_options::data_mode::ascii:
      w->SetDataModeToAscii();
      break;
    case vtk_vti_options::data_mode::binary:
      w->SetDataModeToBinary();
      break;
    case vtk_vti_options::data_mode::appended:
      w->SetDataModeToAppended();
      break;
  }
  w->SetEncodeAppendedData(options.encode_appended);
  if (options.zlib) {
    w->SetCompressorTypeToZLib();
  } else {
    w->SetCompressorTypeToNone();
  }
  if (options.uint64_headers) {
    w->SetHeaderTypeToUInt64();
  } else {
    w->SetHeaderTypeToUInt32();
  }
  w->SetBlockSize(static_cast<size_t>(options.block_bytes));
}

/// The image of the samples written by a new `Writer` as `options` say, after `configure(w)`.
template <class Writer, class Configure>
bool write_with(const std::string& file, const vtk_vti_options& options,
                const std::string& type_name, const std::vector<std::byte>& samples,
                const std::array<int, 6>& extent, const std::array<double, 3>& spacing,
                const std::array<double, 3>& origin, Configure&& configure) {
  sequential_vtk();
  const vtkSmartPointer<vtkImageData> image = image_of(type_name, samples, extent, spacing, origin);
  if (image == nullptr) return false;
  vtkNew<Writer> w;
  w->SetInputData(image);
  w->SetFileName(file.c_str());
  configure(w.GetPointer());
  set_up(w, options);
  return w->Write() == 1;
}

}  // namespace

bool write_vti_with_vtk(const std::string& file, const vtk_vti_options& options,
                        const std::string& type_name, const std::vector<std::byte>& samples,
                        const std::array<int, 6>& extent, const std::array<double, 3>& spacing,
                        const std::array<double, 3>& origin) {
  return write_with<vtkXMLImageDataWriter>(file, options, type_name, samples, extent, spacing,
                                           origin, [](vtkXMLImageDataWriter*) {});
}

bool write_pvti_with_vtk(const std::string& file, int pieces, const vtk_vti_options& options,
                         const std::string& type_name, const std::vector<std::byte>& samples,
                         const std::array<int, 6>& extent, const std::array<double, 3>& spacing,
                         const std::array<double, 3>& origin) {
  return write_with<vtkXMLPImageDataWriter>(file, options, type_name, samples, extent, spacing,
                                            origin, [pieces](vtkXMLPImageDataWriter* w) {
                                              w->SetNumberOfPieces(pieces);
                                              w->SetStartPiece(0);
                                              w->SetEndPiece(pieces - 1);
                                            });
}

vtk_reference_volume read_vti_with_vtk(const std::string& file) {
  sequential_vtk();
  vtkNew<vtkXMLImageDataReader> reader;
  reader->SetFileName(file.c_str());
  reader->Update();
  if (reader->GetErrorCode() != 0) return {};
  return reference_of(reader->GetOutput());
}

vtk_reference_volume read_pvti_with_vtk(const std::string& file) {
  sequential_vtk();
  vtkNew<vtkXMLPImageDataReader> reader;
  reader->SetFileName(file.c_str());
  reader->Update();
  if (reader->GetErrorCode() != 0) return {};
  return reference_of(reader->GetOutput());
}

vtk_reference_surface flying_edges_with_normals(const std::vector<double>& samples,
                                                const std::array<int, 3>& dims,
                                                const std::array<double, 3>& spacing,
                                                const std::array<double, 3>& origin, double w) {
  sequential_vtk();
  vtkNew<vtkImageData> image;
  image->SetDimensions(dims[0], dims[1], dims[2]);
  image->SetSpacing(spacing[0], spacing[1], spacing[2]);
  image->SetOrigin(origin[0], origin[1], origin[2]);
  vtkNew<vtkDoubleArray> array;
  array->SetNumberOfComponents(1);
  array->SetNumberOfTuples(static_cast<vtkIdType>(samples.size()));
  for (std::size_t i = 0; i < samples.size(); ++i) {
    array->SetValue(static_cast<vtkIdType>(i), samples[i]);
  }
  array->SetName("samples");
  image->GetPointData()->SetScalars(array);
  vtkNew<vtkFlyingEdges3D> fe;
  fe->SetInputData(image);
  fe->SetValue(0, w);
  fe->ComputeNormalsOn();
  fe->ComputeGradientsOff();
  fe->ComputeScalarsOff();
  fe->Update();
  vtk_reference_surface out;
  if (fe->GetErrorCode() != 0) return out;
  vtkPolyData* poly = fe->GetOutput();
  vtkDataArray* normals = poly->GetPointData()->GetNormals();
  if (normals == nullptr) return out;
  const vtkIdType n = poly->GetNumberOfPoints();
  for (vtkIdType i = 0; i < n; ++i) {
    std::array<double, 3> p{};
    poly->GetPoint(i, p.data());
    out.points.push_back(p);
    std::array<double, 3> q{};
    normals->GetTuple(i, q.data());
    out.normals.push_back(q);
  }
  out.ok = true;
  return out;
}

}  // namespace progiso::test
