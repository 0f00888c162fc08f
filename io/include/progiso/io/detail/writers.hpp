// progiso/io/detail/writers.hpp — the mesh writers onto an output the caller created.
//
// write_ply(), write_obj(), write_stl() and write_mesh() (mesh_io.hpp) create their own
// atomic_output; these write into one that exists already, so the command can create every output's
// temporary before computing anything and publish them all at the end (file_output.hpp).
#pragma once

#include <progiso/core/surface/mesh.hpp>
#include <progiso/io/detail/file_output.hpp>

namespace progiso::detail {

/// Binary PLY, as write_ply(). Throws progiso::error (naming out.target()) for more than
/// 2^31 − 1 vertices or a coordinate beyond the float range.
void write_ply_to(atomic_output& out, const triangle_mesh& mesh);
/// OBJ, as write_obj().
void write_obj_to(atomic_output& out, const triangle_mesh& mesh);
/// Binary STL, as write_stl(). Throws progiso::error (naming out.target()) for more than
/// 2^32 − 1 triangles or a coordinate beyond the float range.
void write_stl_to(atomic_output& out, const triangle_mesh& mesh);
/// glTF binary, as write_glb().
void write_glb_to(atomic_output& out, const triangle_mesh& mesh);
/// VTK XML PolyData, as write_vtp().
void write_vtp_to(atomic_output& out, const triangle_mesh& mesh);
/// PLY, OBJ, STL, GLB or VTP by the extension of out.target(), as write_mesh().
void write_mesh_to(atomic_output& out, const triangle_mesh& mesh);

}  // namespace progiso::detail
