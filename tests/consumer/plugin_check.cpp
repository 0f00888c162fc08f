// A stand-in for a Python extension or a ParaView plugin: a shared object built from progiso's
// static libraries (whole archives, so every object must be position-independent).
#include <cstddef>

#include <progiso/core/field/analytic.hpp>
#include <progiso/scheduler/engine.hpp>

extern "C" __attribute__((visibility("default"))) std::size_t progiso_plugin_triangles() {
  progiso::engine e(progiso::make_marschner_lobb({17, 17, 17}), 0.5, {});
  e.refine_full();
  return e.snapshot().mesh().triangles.size();
}
