// progiso/io/detail/writers.hpp — the mesh writers onto an output the caller created.
//
// write_ply(), write_obj(), write_stl() and write_mesh() (mesh_io.hpp) create their own
// atomic_output; these write into one that exists already, so the command can create every output's
// temporary before computing anything and publish them all at the end (file_output.hpp).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <progiso/core/surface/mesh.hpp>
#include <progiso/io/detail/file_output.hpp>

namespace progiso::detail {

/// Binary PLY, as write_ply(). Throws progiso::error (naming out.target()) for more than
/// 2^31 − 1 vertices or a coordinate beyond the float range.
void write_ply_to(atomic_output& out, const triangle_mesh& mesh);
/// A binary PLY as write_ply_to() writes it, from a mesh that comes in pieces (a surface larger
/// than memory, detail::finest_surface_pieces()): each piece's vertices follow the last piece's,
/// and its triangles name vertices by their ids in the whole mesh. The pieces wait in two
/// scratch files (out.scratch_directory()): vertices and faces, since a PLY's header counts both
/// and its faces follow every vertex; write_into() then writes the header and copies both. So
/// memory holds one piece at a time, and the file is the one write_ply_to() writes for the
/// joined mesh, byte for byte. Throws progiso::error naming the output for more than 2^31 − 1
/// vertices, a coordinate beyond the float range, a scratch file that cannot be made or
/// written, or (write_into()) a triangle naming a vertex no piece brought.
class ply_pieces_writer {
 public:
  /// `normals`: every piece carries vertex normals (write_ply_to()'s nx, ny, nz).
  ply_pieces_writer(const atomic_output& out, bool normals);
  void add(const triangle_mesh& piece);
  void write_into(atomic_output& out);
  [[nodiscard]] std::uint64_t vertices() const noexcept { return vertex_count_; }
  [[nodiscard]] std::uint64_t triangles() const noexcept { return triangle_count_; }

 private:
  std::string name_;
  bool normals_;
  scratch_file vertices_;
  scratch_file faces_;
  std::uint64_t vertex_count_ = 0, triangle_count_ = 0, largest_index_ = 0;
};

/// write_ply_to()'s parts, for a PLY assembled from pieces made elsewhere (MPI ranks): the
/// header for these counts, and a piece's vertex and face records appended to `vertices` and
/// `faces` (triangle ids as the piece has them). Throws progiso::error naming `name` for a
/// coordinate beyond the float range.
[[nodiscard]] std::string ply_header_text(std::uint64_t vertices, std::uint64_t triangles,
                                          bool normals);
void append_ply_records(const std::string& name, const triangle_mesh& piece,
                        std::vector<char>& vertices, std::vector<char>& faces);

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
