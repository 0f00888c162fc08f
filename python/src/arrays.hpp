// python/src/arrays.hpp — numpy arrays in and out of the binding, without copies.
//
// In: a C-contiguous array in native byte order of one of the eight sample types is viewed as a
// borrowed volume (volume::borrow()); any other layout or dtype is converted by numpy once. Out:
// a C++ vector is moved to the heap and handed to numpy with a capsule that frees it, so the
// array owns the vector's memory.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <progiso/core/base/parallel_loop.hpp>
#include <progiso/core/field/volume.hpp>

namespace progiso::python {

namespace py = pybind11;

/// An array whose memory a volume can read in place, with its sample type: the caller's own
/// array when its layout allowed, else numpy's converted copy (`copied`).
struct sample_array {
  py::array array;
  sample_type type = sample_type::u8;
  bool copied = false;
};

/// `obj` as samples (see the file comment). `what` names the argument in errors. Throws
/// ValueError (py::value_error) for an array of another rank than `rank`, an empty one, or a
/// dtype that holds no numbers (objects, strings, complex).
[[nodiscard]] sample_array as_samples(const py::handle& obj, int rank, const char* what);

/// A volume reading `a` in place, numpy axis order (axis 0 slowest) mapped to progiso's z, y, x;
/// `spacing_axes` is per numpy axis. A 2-D array is an image (one sample thick). The caller keeps
/// `a` alive while the volume is used. Floating-point samples are checked through `run`.
[[nodiscard]] volume view_volume(const sample_array& a, const std::array<double, 3>& spacing_axes,
                                 const parallel_loop& run = {});

/// A numpy array owning `data` (moved to the heap), of `shape`, element type T.
template <class T>
[[nodiscard]] py::array own(std::vector<T>&& data, std::vector<py::ssize_t> shape) {
  auto* held = new std::vector<T>(std::move(data));
  py::capsule free_it(held, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<T>(std::move(shape), held->data(), free_it);
}

/// Floats, 3 per point in x, y, z order, reversed in place to axis order; shape (n, 3) (or
/// (n, 3, 3) with `per_triangle`: three corners per row).
[[nodiscard]] py::array floats_as_axes(std::vector<float>&& xyz, bool per_triangle = false);

}  // namespace progiso::python
