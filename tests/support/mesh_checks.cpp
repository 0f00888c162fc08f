#include <support/mesh_checks.hpp>

#include <algorithm>
#include <iterator>
#include <numeric>
#include <sstream>
#include <unordered_map>
#include <utility>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>

namespace progiso::test {
namespace {

using kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using cgal_point = kernel::Point_3;
using cgal_mesh = CGAL::Surface_mesh<cgal_point>;

// ---------------------------------------------------------------------------------------------
// Messages

std::string format(const vec3& p) {
  std::ostringstream s;
  s.precision(17);
  s << '(' << p[0] << ", " << p[1] << ", " << p[2] << ')';
  return s.str();
}

std::string vertex_text(const triangle_mesh& mesh, std::uint32_t v) {
  return std::string("v").append(std::to_string(v)).append(" ").append(format(mesh.vertices[v]));
}

std::string triangle_text(const triangle_mesh& mesh, std::size_t t) {
  const auto& tri = mesh.triangles[t];
  return "triangle " + std::to_string(t) + " [" + vertex_text(mesh, tri[0]) + ", " +
         vertex_text(mesh, tri[1]) + ", " + vertex_text(mesh, tri[2]) + "]";
}

check_result failure(std::string message) { return {false, std::move(message)}; }

// Every check first makes sure the indices can be followed at all.
check_result indices_in_range(const triangle_mesh& mesh) {
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    for (const std::uint32_t v : mesh.triangles[t]) {
      if (v >= mesh.vertices.size()) {
        return failure("triangle " + std::to_string(t) + " uses vertex index " + std::to_string(v) +
                       ", but the mesh has " + std::to_string(mesh.vertices.size()) + " vertices");
      }
    }
  }
  return {};
}

// ---------------------------------------------------------------------------------------------
// Edge table: for each undirected edge {lo, hi}, how often it is traversed lo→hi and hi→lo,
// and the first two triangles that use it.

struct edge_use {
  std::uint32_t forward = 0;
  std::uint32_t backward = 0;
  std::array<std::size_t, 2> triangles{};

  [[nodiscard]] std::uint32_t total() const noexcept { return forward + backward; }
};

std::uint64_t undirected_key(std::uint32_t a, std::uint32_t b) noexcept {
  const std::uint32_t lo = std::min(a, b);
  const std::uint32_t hi = std::max(a, b);
  return (std::uint64_t{lo} << 32) | hi;
}

using edge_map = std::unordered_map<std::uint64_t, edge_use>;

// Needs indices_in_range(mesh).
edge_map edge_table(const triangle_mesh& mesh) {
  edge_map edges;
  edges.reserve(mesh.triangles.size() * 2);
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    for (std::size_t i = 0; i < 3; ++i) {
      const std::uint32_t a = tri[i];
      const std::uint32_t b = tri[(i + 1) % 3];
      edge_use& use = edges[undirected_key(a, b)];
      if (use.total() < 2) use.triangles[use.total()] = t;
      (a < b ? use.forward : use.backward) += 1;
    }
  }
  return edges;
}

// Calls f(a, b, use) for every edge occurrence, in triangle order, until f returns false.
template <class F>
void for_each_edge(const triangle_mesh& mesh, const edge_map& edges, F&& f) {
  for (const auto& tri : mesh.triangles) {
    for (std::size_t i = 0; i < 3; ++i) {
      const std::uint32_t a = tri[i];
      const std::uint32_t b = tri[(i + 1) % 3];
      if (!f(a, b, edges.at(undirected_key(a, b)))) return;
    }
  }
}

std::string edge_text(const triangle_mesh& mesh, std::uint32_t a, std::uint32_t b) {
  return "edge " + vertex_text(mesh, a) + " - " + vertex_text(mesh, b);
}

cgal_point to_cgal(const vec3& p) { return {p[0], p[1], p[2]}; }

// The mesh as a CGAL Surface_mesh whose face i is triangle i, or the reason it cannot be one.
std::pair<cgal_mesh, check_result> to_surface_mesh(const triangle_mesh& mesh) {
  cgal_mesh sm;
  if (check_result r = indices_in_range(mesh); !r) return {std::move(sm), std::move(r)};
  std::vector<std::array<std::size_t, 3>> polygons;
  polygons.reserve(mesh.triangles.size());
  for (const auto& tri : mesh.triangles) polygons.push_back({tri[0], tri[1], tri[2]});
  if (!CGAL::Polygon_mesh_processing::is_polygon_soup_a_polygon_mesh(polygons)) {
    // Name the defect when one of the topological checks finds it.
    std::string reason = "a non-manifold vertex";
    if (check_result r = edge_manifold(mesh); !r) {
      reason = r.message;
    } else if (check_result o = consistently_oriented(mesh); !o) {
      reason = o.message;
    }
    return {std::move(sm), failure("not a valid polygon mesh, so CGAL cannot test it for "
                                   "self-intersections: " +
                                   reason)};
  }
  for (const vec3& p : mesh.vertices) sm.add_vertex(to_cgal(p));
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    const auto face = sm.add_face(cgal_mesh::Vertex_index(tri[0]), cgal_mesh::Vertex_index(tri[1]),
                                  cgal_mesh::Vertex_index(tri[2]));
    if (face == cgal_mesh::null_face()) {
      return {std::move(sm), failure("CGAL::Surface_mesh rejects " + triangle_text(mesh, t) +
                                     ": cannot test for self-intersections")};
    }
  }
  return {std::move(sm), {}};
}

// ---------------------------------------------------------------------------------------------
// Topology. Each check has a body that takes a prebuilt edge table (make_report builds one for
// all of them) and a public wrapper that validates indices and builds it.

check_result manifold_with(const triangle_mesh& mesh, const edge_map& edges) {
  // Sorted vertex triples, keyed by their first two indices, then the third.
  std::unordered_map<std::uint64_t, std::unordered_map<std::uint32_t, std::size_t>> triples;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    auto tri = mesh.triangles[t];
    if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) {
      return failure(triangle_text(mesh, t) + " repeats a vertex index");
    }
    std::sort(tri.begin(), tri.end());
    const auto [it, inserted] = triples[undirected_key(tri[0], tri[1])].try_emplace(tri[2], t);
    if (!inserted) {
      return failure(triangle_text(mesh, t) + " uses the same vertices as triangle " +
                     std::to_string(it->second));
    }
  }
  check_result result;
  for_each_edge(mesh, edges, [&](std::uint32_t a, std::uint32_t b, const edge_use& use) {
    if (use.total() <= 2) return true;
    result = failure(edge_text(mesh, a, b) + " belongs to " + std::to_string(use.total()) +
                     " triangles (first " + std::to_string(use.triangles[0]) + " and " +
                     std::to_string(use.triangles[1]) + ")");
    return false;
  });
  return result;
}

check_result boundary_with(const triangle_mesh& mesh, const edge_map& edges, const vec3& box_min,
                           const vec3& box_max) {
  check_result result;
  for_each_edge(mesh, edges, [&](std::uint32_t a, std::uint32_t b, const edge_use& use) {
    if (use.total() != 1) return true;
    const vec3& p = mesh.vertices[a];
    const vec3& q = mesh.vertices[b];
    for (std::size_t axis = 0; axis < 3; ++axis) {
      for (const double plane : {box_min[axis], box_max[axis]}) {
        if (p[axis] == plane && q[axis] == plane) return true;
      }
    }
    result = failure("open " + edge_text(mesh, a, b) + " of triangle " +
                     std::to_string(use.triangles[0]) + " does not lie on a face of the box " +
                     format(box_min) + " - " + format(box_max));
    return false;
  });
  return result;
}

check_result oriented_with(const triangle_mesh& mesh, const edge_map& edges) {
  check_result result;
  for_each_edge(mesh, edges, [&](std::uint32_t a, std::uint32_t b, const edge_use& use) {
    if (use.total() != 2 || (use.forward == 1 && use.backward == 1)) return true;
    result = failure(edge_text(mesh, a, b) + " is traversed in the same direction by triangles " +
                     std::to_string(use.triangles[0]) + " and " + std::to_string(use.triangles[1]));
    return false;
  });
  return result;
}

std::int64_t euler_with(const triangle_mesh& mesh, const edge_map& edges) {
  std::vector<bool> used(mesh.vertices.size(), false);
  for (const auto& tri : mesh.triangles) {
    for (const std::uint32_t v : tri) used[v] = true;
  }
  const auto vertices = static_cast<std::int64_t>(std::count(used.begin(), used.end(), true));
  return vertices - static_cast<std::int64_t>(edges.size()) +
         static_cast<std::int64_t>(mesh.triangles.size());
}

std::size_t boundary_count_with(const edge_map& edges) {
  return static_cast<std::size_t>(std::count_if(
      edges.begin(), edges.end(), [](const auto& e) { return e.second.total() == 1; }));
}

}  // namespace

check_result edge_manifold(const triangle_mesh& mesh) {
  if (check_result r = indices_in_range(mesh); !r) return r;
  return manifold_with(mesh, edge_table(mesh));
}

check_result boundary_on_box(const triangle_mesh& mesh, const vec3& box_min, const vec3& box_max) {
  if (check_result r = indices_in_range(mesh); !r) return r;
  return boundary_with(mesh, edge_table(mesh), box_min, box_max);
}

check_result watertight(const triangle_mesh& mesh) {
  if (check_result r = indices_in_range(mesh); !r) return r;
  const auto edges = edge_table(mesh);
  check_result result;
  for_each_edge(mesh, edges, [&](std::uint32_t a, std::uint32_t b, const edge_use& use) {
    if (use.total() != 1) return true;
    result = failure("open " + edge_text(mesh, a, b) + " of triangle " +
                     std::to_string(use.triangles[0]));
    return false;
  });
  return result;
}

check_result consistently_oriented(const triangle_mesh& mesh) {
  if (check_result r = indices_in_range(mesh); !r) return r;
  return oriented_with(mesh, edge_table(mesh));
}

std::int64_t euler_characteristic(const triangle_mesh& mesh) {
  if (!indices_in_range(mesh)) return 0;
  return euler_with(mesh, edge_table(mesh));
}

std::size_t connected_components(const triangle_mesh& mesh) {
  std::vector<std::uint32_t> parent(mesh.vertices.size());
  std::iota(parent.begin(), parent.end(), std::uint32_t{0});
  const auto root = [&](std::uint32_t v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  std::vector<bool> used(mesh.vertices.size(), false);
  for (const auto& tri : mesh.triangles) {
    if (tri[0] >= used.size() || tri[1] >= used.size() || tri[2] >= used.size()) continue;
    for (const std::uint32_t v : tri) used[v] = true;
    parent[root(tri[1])] = root(tri[0]);
    parent[root(tri[2])] = root(tri[0]);
  }
  std::size_t count = 0;
  for (std::uint32_t v = 0; v < used.size(); ++v) {
    if (used[v] && root(v) == v) ++count;
  }
  return count;
}

std::size_t boundary_edge_count(const triangle_mesh& mesh) {
  if (!indices_in_range(mesh)) return 0;
  return boundary_count_with(edge_table(mesh));
}

// ---------------------------------------------------------------------------------------------
// Geometry

check_result no_degenerate_triangles(const triangle_mesh& mesh) {
  if (check_result r = indices_in_range(mesh); !r) return r;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    const vec3& a = mesh.vertices[tri[0]];
    const vec3& b = mesh.vertices[tri[1]];
    const vec3& c = mesh.vertices[tri[2]];
    if (a == b || b == c || a == c) {
      return failure(triangle_text(mesh, t) + " has two equal positions");
    }
    if (CGAL::collinear(to_cgal(a), to_cgal(b), to_cgal(c))) {
      return failure(triangle_text(mesh, t) + " is collinear");
    }
  }
  return {};
}

std::optional<std::size_t> self_intersection_count(const triangle_mesh& mesh, unsigned limit) {
  const auto [sm, built] = to_surface_mesh(mesh);
  if (!built) return std::nullopt;
  std::vector<std::pair<cgal_mesh::Face_index, cgal_mesh::Face_index>> pairs;
  CGAL::Polygon_mesh_processing::self_intersections(sm, std::back_inserter(pairs),
                                                    CGAL::parameters::maximum_number(limit));
  return pairs.size();
}

check_result no_self_intersections(const triangle_mesh& mesh) {
  namespace pmp = CGAL::Polygon_mesh_processing;
  const auto [sm, built] = to_surface_mesh(mesh);
  if (!built) return built;
  if (!pmp::does_self_intersect(sm)) return {};

  constexpr unsigned limit = 1000;
  std::vector<std::pair<cgal_mesh::Face_index, cgal_mesh::Face_index>> pairs;
  pmp::self_intersections(sm, std::back_inserter(pairs), CGAL::parameters::maximum_number(limit));
  std::string message = std::to_string(pairs.size()) + (pairs.size() >= limit ? " or more" : "") +
                        " pairs of triangles intersect";
  if (!pairs.empty()) {
    // Face i of the Surface_mesh is triangle i (faces were added in order).
    const auto f = static_cast<std::size_t>(pairs.front().first.idx());
    const auto g = static_cast<std::size_t>(pairs.front().second.idx());
    message += f == g ? ", first: " + triangle_text(mesh, f) + " is degenerate"
                      : ", first: " + triangle_text(mesh, f) + " and " + triangle_text(mesh, g);
  }
  return failure(std::move(message));
}

double signed_volume(const triangle_mesh& mesh) {
  double six_v = 0.0;
  for (const auto& tri : mesh.triangles) {
    const vec3& a = mesh.vertices.at(tri[0]);
    const vec3& b = mesh.vertices.at(tri[1]);
    const vec3& c = mesh.vertices.at(tri[2]);
    six_v += a[0] * (b[1] * c[2] - b[2] * c[1]) + a[1] * (b[2] * c[0] - b[0] * c[2]) +
             a[2] * (b[0] * c[1] - b[1] * c[0]);
  }
  return six_v / 6.0;
}

std::array<vec3, 2> data_box(const volume& v) {
  std::array<vec3, 2> box{};
  for (std::size_t q = 0; q < 3; ++q) {
    box[0][q] = v.origin()[q];
    box[1][q] = v.origin()[q] + static_cast<double>(v.dims()[q] - 1) * v.spacing()[q];
  }
  return box;
}

// ---------------------------------------------------------------------------------------------
// Reports

std::string mesh_report::summary() const {
  std::string s = "euler characteristic " + std::to_string(euler) + ", " +
                  std::to_string(components) + " components, " + std::to_string(boundary_edges) +
                  " boundary edges";
  const std::pair<const char*, const check_result*> checks[] = {
      {"edge_manifold", &manifold},
      {"boundary_on_box", &boundary},
      {"consistently_oriented", &oriented},
      {"no_degenerate_triangles", &nondegenerate},
      {"no_self_intersections", &self_intersection_free}};
  for (const auto& [name, result] : checks) {
    if (!result->ok) s += std::string("\n  ") + name + " failed: " + result->message;
  }
  return s;
}

mesh_report make_report(const triangle_mesh& mesh, const vec3& box_min, const vec3& box_max) {
  mesh_report r;
  if (check_result bad = indices_in_range(mesh); !bad) {
    r.manifold = r.boundary = r.oriented = r.nondegenerate = r.self_intersection_free = bad;
    return r;
  }
  const edge_map edges = edge_table(mesh);
  r.manifold = manifold_with(mesh, edges);
  r.boundary = boundary_with(mesh, edges, box_min, box_max);
  r.oriented = oriented_with(mesh, edges);
  r.nondegenerate = no_degenerate_triangles(mesh);
  r.self_intersection_free = no_self_intersections(mesh);
  r.euler = euler_with(mesh, edges);
  r.components = connected_components(mesh);
  r.boundary_edges = boundary_count_with(edges);
  return r;
}

::testing::AssertionResult check_valid_cut(const triangle_mesh& mesh, const vec3& box_min,
                                           const vec3& box_max) {
  const mesh_report r = make_report(mesh, box_min, box_max);
  if (r.valid()) {
    // An extracted surface holds only the vertices its triangles use.
    std::vector<bool> used(mesh.vertices.size(), false);
    for (const auto& tri : mesh.triangles) {
      for (const std::uint32_t v : tri) used[v] = true;
    }
    const auto unused = std::find(used.begin(), used.end(), false);
    if (unused == used.end()) return ::testing::AssertionSuccess();
    return ::testing::AssertionFailure() << "vertex " << (unused - used.begin()) << " of "
                                         << mesh.vertices.size() << " is used by no triangle";
  }
  return ::testing::AssertionFailure()
         << "invalid surface (" << mesh.vertices.size() << " vertices, " << mesh.triangles.size()
         << " triangles): " << r.summary();
}

std::vector<position_triangle> canonical_triangles(const triangle_mesh& mesh) {
  std::vector<position_triangle> out;
  out.reserve(mesh.triangles.size());
  for (const auto& tri : mesh.triangles) {
    position_triangle p{mesh.vertices.at(tri[0]), mesh.vertices.at(tri[1]),
                        mesh.vertices.at(tri[2])};
    std::rotate(p.begin(), std::min_element(p.begin(), p.end()), p.end());
    out.push_back(p);
  }
  std::sort(out.begin(), out.end());
  return out;
}

::testing::AssertionResult same_surface(const triangle_mesh& a, const triangle_mesh& b) {
  const auto ca = canonical_triangles(a);
  const auto cb = canonical_triangles(b);
  if (ca == cb) return ::testing::AssertionSuccess();
  std::vector<position_triangle> only_a;
  std::vector<position_triangle> only_b;
  std::set_difference(ca.begin(), ca.end(), cb.begin(), cb.end(), std::back_inserter(only_a));
  std::set_difference(cb.begin(), cb.end(), ca.begin(), ca.end(), std::back_inserter(only_b));
  const auto text = [](const position_triangle& t) {
    return std::string("[")
        .append(format(t[0]))
        .append(", ")
        .append(format(t[1]))
        .append(", ")
        .append(format(t[2]))
        .append("]");
  };
  auto failure_result = ::testing::AssertionFailure();
  failure_result << "surfaces differ: " << ca.size() << " vs " << cb.size() << " triangles; "
                 << only_a.size() << " only in the first, " << only_b.size()
                 << " only in the second";
  if (!only_a.empty()) failure_result << "; first only in the first: " << text(only_a.front());
  if (!only_b.empty()) failure_result << "; first only in the second: " << text(only_b.front());
  return failure_result;
}

}  // namespace progiso::test
