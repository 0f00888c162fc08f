// progiso/core/refine/detail/path_choice.hpp — the one-shot calls with their path chosen by the
// caller, for the benchmarks and tests that compare the two paths to the same cut.
//
// The public entries (extract_isosurface(), extract_contours(), and the engine's
// extract_isosurface_parallel()) give a full goal's finest cut by two streaming passes over the
// samples (finest_surface(), finest_contours()). The hierarchy's path refines to the end and
// extracts the cut: the same surface, numbered in cut order, with split statistics. No user
// needs to choose; a benchmark that measures the one against the other, or a test that checks
// they agree, does.
#pragma once

#include <progiso/core/contour/contour_refiner.hpp>
#include <progiso/core/refine/refiner.hpp>

namespace progiso::detail {

struct path_choice {
  /// kind::full (without frames, in 2D) by the direct path; false: by the hierarchy's.
  bool finest_direct = true;
};

/// extract_isosurface() on the chosen path.
[[nodiscard]] extract_result extract_isosurface(const volume& vol, double isovalue,
                                                const extract_options& options, path_choice path);

/// extract_contours() on the chosen path.
[[nodiscard]] contour_result extract_contours(const volume& image,
                                              const std::vector<double>& isovalues,
                                              const contour_options& options, path_choice path);

}  // namespace progiso::detail
