// progiso/core/base/detail/borrow.hpp — refusing temporaries where a class keeps references.
//
// range_data, refiner, range_data2d and contour_refiner keep references (or pointers) to the
// volume, hierarchy and range data they are built from. Each declares a deleted constructor
// template constrained by any_rvalue<…>: a temporary argument binds to it better than to the
// const& constructor, so `refiner r(make_demo_volume(65), h, rd, 0.5);` fails to compile
// ("use of deleted function") instead of compiling and then reading a destroyed volume.
#pragma once

#include <type_traits>

namespace progiso::detail {

/// True when at least one of the forwarded argument types is an rvalue (a temporary).
template <class... Args>
concept any_rvalue = (std::is_rvalue_reference_v<Args&&> || ...);

}  // namespace progiso::detail
