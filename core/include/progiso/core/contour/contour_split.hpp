// progiso/core/contour/contour_split.hpp — what splitting one 2D diamond does to the isocontour
// (paper §3).
//
// Splitting diamond D bisects its spine CD at its centre E; each of its (one or) two triangles
// CDX (X = A, B, the ring apexes) becomes CEX and EDX. Only the interior of the quadrilateral
// ACBD changes. A contour split record lists the oriented segments of the new triangles, each
// tagged with the child diamond that owns its triangle, classifies the split into the paper's
// cases (a)–(h) (Figure 3) with their boundary variants, and gives the exact sequence of the six
// primitives of §3.2 that turns the old segments into the new ones. Colours as in 3D: black if
// f > w, white if f ≤ w; a, b, c, d, e are the colours of A, B, C, D, E.
//
//   c ≠ d      (a) a = b = e      VertexMove(CD→M)                 M: the crossed half CE or ED
//              (b) a = b ≠ e      VertexMove, VertexSplit(M, EA), VertexSplit(M, EB)
//              (c) a ≠ b          VertexMove, one VertexSplit(M, EX) for the side with x ≠ e
//   c = d = e  (d) a = b ≠ c      VertexSplit(CA, EA), VertexSplit(CB, EB)
//              (e) a ≠ b          one VertexSplit(CX, EX) for the side with x ≠ c
//   c = d ≠ e  (g) a = b = c      NewLoop(CE, AE, DE, BE)
//              (h) a = b ≠ c      EdgeFlip(CA–DA, CB–DB → CA–CB, DA–DB),
//                                 VertexSplit(CA, CE), VertexSplit(DA, DE)
//              (f) a ≠ b          VertexSplit(CX, CE), VertexSplit(CE, YE), VertexSplit(YE, DE)
//                                 (X the side with x ≠ c, Y the other)
//
// Boundary variants (CD on the grid border, one triangle CDX): (a)/(b) as above with one side;
// (d) one VertexSplit; (g) NewEdge(CE, XE), VertexSplit(XE, DE); (h) VertexSplit(DX, DE),
// VertexOpen(DE, CE). Departure from the paper's list: case (f) creates three vertices (on CE,
// EY and ED), so it takes three VertexSplits, not one VertexMove and two VertexSplits.
//
// Primitive semantics (on the contour graph, vertices named by edge keys):
//   VertexMove(P, P')      vertex P becomes P' (new position) in all its segments;
//   VertexSplit(P, Q, R)   new vertex Q and segment P–Q; if R is given, segment P–R becomes Q–R;
//   VertexOpen(P, Q, R)    segment P–R becomes Q–R, with no segment P–Q;
//   EdgeFlip(P, Q, R, S)   segments P–Q and R–S become P–R and Q–S;
//   NewEdge(P, Q)          a new segment P–Q;  NewLoop(P, Q, R, S)  segments PQ, QR, RS, SP.
// apply_contour_ops() executes a sequence on a segment set; the tests check that it yields
// exactly the marching-triangles segments of the new triangles, case by case.
//
// compute_contour_split() is a pure function of (diamond, image, isovalue).
#pragma once

#include <array>
#include <cstdint>
#include <string_view>
#include <vector>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/contour/contour.hpp>
#include <progiso/core/contour/hierarchy2d.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/surface/marching.hpp>

namespace progiso {

/// The paper's eight cases (Figure 3); `none` when the split changes nothing.
enum class contour_case : std::uint8_t { none, a, b, c, d, e, f, g, h };
inline constexpr std::size_t contour_case_count = 9;
[[nodiscard]] std::string_view to_string(contour_case c) noexcept;

/// The six primitives of §3.2.
enum class contour_primitive : std::uint8_t {
  vertex_move,
  vertex_split,
  vertex_open,
  edge_flip,
  new_edge,
  new_loop
};
inline constexpr std::size_t contour_primitive_count = 6;
[[nodiscard]] std::string_view to_string(contour_primitive p) noexcept;

/// "No vertex" in a primitive's argument list.
inline constexpr std::uint64_t no_key = ~std::uint64_t{0};

/// One primitive with its arguments (edge keys of contour vertices, no_key when unused).
struct contour_op {
  contour_primitive kind = contour_primitive::vertex_move;
  std::array<std::uint64_t, 4> args{no_key, no_key, no_key, no_key};
  friend bool operator==(const contour_op&, const contour_op&) = default;
};

/// An oriented segment (black on its left) in a triangle owned by diamond `owner` (grid index of
/// its centre; ~0 for a finest triangle).
struct owned_segment {
  std::uint64_t owner = ~std::uint64_t{0};
  std::array<std::uint64_t, 2> keys{};
};

/// Classification of one 2D split.
struct contour_split_summary {
  contour_case kind = contour_case::none;
  bool boundary = false;  ///< only one triangle (the spine is on the grid border)
  int triangles = 0;
  int removed_segments = 0;
  int added_segments = 0;
  std::array<contour_op, 4> ops{};
  int op_count = 0;
  /// The split's colouring and triangle count, one of contour_split_classes: it alone gives the
  /// case and the primitives' kinds (contour_split_class_info()), so a refiner counts it and
  /// adds the cases and primitives up when its statistics are read.
  std::uint8_t split_class = 0;
};

/// Number of split classes: 5 colour bits (spine ends, centre, first and second apex in the
/// grid) and the triangle count 0, 1 or 2.
inline constexpr std::size_t contour_split_classes = 96;

/// What a split class determines: the case and the kinds of its primitive sequence.
struct contour_split_class {
  contour_case kind = contour_case::none;
  std::uint8_t op_count = 0;
  std::array<contour_primitive, 4> ops{};
};

/// The case and primitive kinds of split class k (< contour_split_classes).
[[nodiscard]] const contour_split_class& contour_split_class_info(std::size_t k) noexcept;

/// Oriented marching-triangles segment of triangle p (values f) at isovalue w, if crossed.
/// Keys are edge_key2 of the crossed edges; black (f > w) lies on the segment's left.
[[nodiscard]] bool march_triangle(const std::array<ipoint2, 3>& p, const std::array<double, 3>& f,
                                  double isovalue, std::array<std::uint64_t, 2>& out) noexcept;

/// Contour vertex on crossed edge (a, b): canonical order, clamped t (as marching.hpp). Inline:
/// a split places up to eight ends, and their divisions overlap only when the compiler sees them.
[[nodiscard]] inline vec2 interpolate2(const ipoint2& a, double fa, const ipoint2& b, double fb,
                                       double isovalue) noexcept {
  const bool swap = vertex_less2(b, a);
  const ipoint2& p = swap ? b : a;
  const ipoint2& q = swap ? a : b;
  const double t = crossing_parameter(swap ? fb : fa, swap ? fa : fb, isovalue);
  return {static_cast<double>(p[0]) + t * static_cast<double>(q[0] - p[0]),
          static_cast<double>(p[1]) + t * static_cast<double>(q[1] - p[1])};
}

/// Computes diamond d's split record at isovalue w: appends the new segments to `out`.
contour_split_summary compute_contour_split(const hierarchy2d& hier, const volume& image,
                                            double isovalue, const diamond2& d,
                                            std::vector<owned_segment>& out);

/// An undirected segment between two contour vertices (keys, smaller first).
using key_segment = std::array<std::uint64_t, 2>;

/// Applies primitives to an undirected segment set. Throws progiso::error if an operation's
/// preconditions fail (a segment it needs is absent), which the tests use to check sequences.
void apply_contour_ops(std::vector<key_segment>& segments, const contour_op* ops, int count);

}  // namespace progiso
