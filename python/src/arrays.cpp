#include "arrays.hpp"

#include <span>

namespace progiso::python {

namespace {

// The sample type a native dtype is read as in place; false for the others.
bool native_type(const py::dtype& dt, sample_type& out) {
  const char kind = dt.kind();
  const auto size = dt.itemsize();
  // '=' and '|' are native; '<' is native on the little-endian machines progiso builds for.
  const char order = dt.byteorder();
  if (order == '>') return false;
  if (kind == 'b') {  // numpy's bool is one byte, 0 or 1
    out = sample_type::u8;
    return size == 1;
  }
  if (kind == 'u') {
    if (size == 1) out = sample_type::u8;
    if (size == 2) out = sample_type::u16;
    if (size == 4) out = sample_type::u32;
    return size == 1 || size == 2 || size == 4;
  }
  if (kind == 'i') {
    if (size == 1) out = sample_type::i8;
    if (size == 2) out = sample_type::i16;
    if (size == 4) out = sample_type::i32;
    return size == 1 || size == 2 || size == 4;
  }
  if (kind == 'f') {
    if (size == 4) out = sample_type::f32;
    if (size == 8) out = sample_type::f64;
    return size == 4 || size == 8;
  }
  return false;
}

}  // namespace

sample_array as_samples(const py::handle& obj, int rank, const char* what) {
  py::module_ np = py::module_::import("numpy");
  sample_array out;
  out.array = py::array::ensure(obj);
  if (!out.array) {
    PyErr_Clear();
    throw py::value_error(std::string(what) + ": expected a numpy array, found " +
                          std::string(py::str(py::type::handle_of(obj).attr("__name__"))));
  }
  if (out.array.ndim() != rank) {
    throw py::value_error(std::string(what) + ": expected a " + std::to_string(rank) +
                          "-D array, found " + std::to_string(out.array.ndim()) + "-D");
  }
  if (out.array.size() == 0) {
    throw py::value_error(std::string(what) + ": expected samples, found an empty array");
  }
  const py::dtype dt = out.array.dtype();
  const char kind = dt.kind();
  const bool c_order = (out.array.flags() & py::array::c_style) != 0;
  if (c_order && native_type(dt, out.type)) return out;
  // Converted once: other integer widths and booleans to the type that holds them exactly
  // where one exists, 64-bit integers and float16 to float64 / float32.
  py::dtype target;
  if (kind == 'b') {
    target = py::dtype("uint8");
  } else if (kind == 'u' || kind == 'i') {
    target = dt.itemsize() <= 4 ? py::dtype(std::string(1, kind) + std::to_string(dt.itemsize()))
                                : py::dtype("float64");
  } else if (kind == 'f') {
    target = dt.itemsize() <= 4 ? py::dtype("float32") : py::dtype("float64");
  } else {
    throw py::value_error(std::string(what) + ": expected real numbers, found dtype " +
                          dt.attr("name").cast<std::string>());
  }
  out.array = np.attr("ascontiguousarray")(out.array, target);
  out.copied = true;
  if (!native_type(out.array.dtype(), out.type)) {
    throw py::value_error(std::string(what) + ": cannot read dtype " +
                          dt.attr("name").cast<std::string>());
  }
  return out;
}

volume view_volume(const sample_array& a, const std::array<double, 3>& spacing_axes,
                   const parallel_loop& run) {
  const auto rank = a.array.ndim();
  index3 dims{};
  std::array<double, 3> spacing{};
  if (rank == 3) {
    dims = {a.array.shape(2), a.array.shape(1), a.array.shape(0)};
    spacing = {spacing_axes[2], spacing_axes[1], spacing_axes[0]};
  } else {
    dims = {a.array.shape(1), a.array.shape(0), 1};
    spacing = {spacing_axes[1], spacing_axes[0], 1.0};
  }
  const std::span<const std::byte> bytes(static_cast<const std::byte*>(a.array.data()),
                                         static_cast<std::size_t>(a.array.nbytes()));
  return volume::borrow(dims, a.type, bytes, nullptr, spacing, {0.0, 0.0, 0.0}, run);
}

py::array floats_as_axes(std::vector<float>&& xyz, bool per_triangle) {
  const std::size_t points = xyz.size() / 3;
  for (std::size_t i = 0; i < points; ++i) std::swap(xyz[3 * i], xyz[3 * i + 2]);
  if (per_triangle) {
    const auto rows = static_cast<py::ssize_t>(points / 3);
    return own(std::move(xyz), {rows, 3, 3});
  }
  return own(std::move(xyz), {static_cast<py::ssize_t>(points), 3});
}

}  // namespace progiso::python
