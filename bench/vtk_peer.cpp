// VTK's side of bench/peer_bench.cpp, compiled as C++17 (see vtk_peer.hpp).
#include "vtk_peer.hpp"

#include <cstdint>

#include <vtkAOSDataArrayTemplate.h>
#include <vtkFlyingEdges2D.h>
#include <vtkFlyingEdges3D.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPolyData.h>
#include <vtkRTAnalyticSource.h>
#include <vtkSMPTools.h>
#include <vtkSmartPointer.h>

namespace progiso::bench {

struct flying_edges::impl {
  vtkSmartPointer<vtkImageData> image;
  vtkSmartPointer<vtkFlyingEdges3D> fe3;
  vtkSmartPointer<vtkFlyingEdges2D> fe2;
};

namespace {

template <class T>
void wrap(vtkImageData* image, const void* samples, vtkIdType count) {
  auto array = vtkSmartPointer<vtkAOSDataArrayTemplate<T>>::New();
  array->SetNumberOfComponents(1);
  // save = 1: VTK never frees (nor, in these filters, writes) the caller's samples.
  array->SetArray(static_cast<T*>(const_cast<void*>(samples)), count, 1);
  array->SetName("samples");
  image->GetPointData()->SetScalars(array);
}

}  // namespace

flying_edges::flying_edges(const int dims[3], const double spacing[3], const double origin[3],
                           vtk_sample type, const void* samples, double isovalue, bool normals)
    : impl_(std::make_unique<impl>()) {
  impl_->image = vtkSmartPointer<vtkImageData>::New();
  impl_->image->SetDimensions(dims[0], dims[1], dims[2]);
  impl_->image->SetSpacing(spacing[0], spacing[1], spacing[2]);
  impl_->image->SetOrigin(origin[0], origin[1], origin[2]);
  const vtkIdType count = vtkIdType{dims[0]} * dims[1] * dims[2];
  switch (type) {
    case vtk_sample::u8:
      wrap<std::uint8_t>(impl_->image, samples, count);
      break;
    case vtk_sample::i8:
      wrap<std::int8_t>(impl_->image, samples, count);
      break;
    case vtk_sample::u16:
      wrap<std::uint16_t>(impl_->image, samples, count);
      break;
    case vtk_sample::i16:
      wrap<std::int16_t>(impl_->image, samples, count);
      break;
    case vtk_sample::u32:
      wrap<std::uint32_t>(impl_->image, samples, count);
      break;
    case vtk_sample::i32:
      wrap<std::int32_t>(impl_->image, samples, count);
      break;
    case vtk_sample::f32:
      wrap<float>(impl_->image, samples, count);
      break;
    case vtk_sample::f64:
      wrap<double>(impl_->image, samples, count);
      break;
  }
  if (dims[2] == 1) {
    impl_->fe2 = vtkSmartPointer<vtkFlyingEdges2D>::New();
    impl_->fe2->SetInputData(impl_->image);
    impl_->fe2->SetValue(0, isovalue);
    impl_->fe2->ComputeScalarsOff();
  } else {
    impl_->fe3 = vtkSmartPointer<vtkFlyingEdges3D>::New();
    impl_->fe3->SetInputData(impl_->image);
    impl_->fe3->SetValue(0, isovalue);
    impl_->fe3->SetComputeNormals(normals ? 1 : 0);
    impl_->fe3->ComputeGradientsOff();
    impl_->fe3->ComputeScalarsOff();
    impl_->fe3->InterpolateAttributesOff();
  }
}

flying_edges::~flying_edges() = default;

std::size_t flying_edges::run() {
  if (impl_->fe2) {
    impl_->fe2->Modified();
    impl_->fe2->Update();
    return static_cast<std::size_t>(impl_->fe2->GetOutput()->GetNumberOfLines());
  }
  impl_->fe3->Modified();
  impl_->fe3->Update();
  return static_cast<std::size_t>(impl_->fe3->GetOutput()->GetNumberOfPolys());
}

std::string vtk_threads(int threads) {
  vtkSMPTools::Initialize(threads);
  const char* backend = vtkSMPTools::GetBackend();
  return backend != nullptr ? backend : "?";
}

std::vector<float> vtk_wavelet(int n) {
  vtkNew<vtkRTAnalyticSource> source;
  const int lo = -n / 2;
  const int hi = n - 1 - n / 2;
  source->SetWholeExtent(lo, hi, lo, hi, lo, hi);
  source->Update();
  vtkDataArray* scalars = source->GetOutput()->GetPointData()->GetScalars();
  std::vector<float> out(static_cast<std::size_t>(scalars->GetNumberOfTuples()));
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i] = static_cast<float>(scalars->GetComponent(static_cast<vtkIdType>(i), 0));
  }
  return out;
}

}  // namespace progiso::bench
