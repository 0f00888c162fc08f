#include "cli_outputs.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <limits>
#include <optional>
#include <string>
#include <system_error>
#include <utility>

#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/file_output.hpp>

namespace progiso::cli {

namespace fs = std::filesystem;

namespace {

struct identity {
  dev_t device = 0;
  ino_t inode = 0;
  bool character_device = false;
  bool operator==(const identity& o) const noexcept {
    return device == o.device && inode == o.inode;
  }
};

/// The file's identity when it exists (symbolic links followed).
std::optional<identity> identify(const fs::path& p) {
  struct stat st {};
  if (::stat(p.c_str(), &st) != 0) return std::nullopt;
  return identity{st.st_dev, st.st_ino, S_ISCHR(st.st_mode)};
}

/// An absolute path with symbolic links resolved as far as the path exists, for comparing
/// outputs that do not exist yet.
fs::path normalised(const fs::path& p) {
  std::error_code ec;
  fs::path n = fs::weakly_canonical(fs::absolute(p, ec), ec);
  if (ec) n = fs::absolute(p, ec).lexically_normal();
  // "dir/" and "dir" name the same thing.
  while (!n.empty() && n.filename().empty() && n != n.root_path()) n = n.parent_path();
  return n;
}

void on_fatal_signal(int sig) {
  detail::remove_registered_temporaries();
  // SA_RESETHAND has restored the default action: end the process by the same signal.
  std::raise(sig);
}

}  // namespace

void refuse_clashing_outputs(const std::vector<fs::path>& inputs,
                             const std::vector<named_output>& outputs) {
  for (std::size_t i = 0; i < outputs.size(); ++i) {
    const named_output& out = outputs[i];
    const std::optional<identity> id = identify(out.path);
    if (id) {
      for (const fs::path& in : inputs) {
        const std::optional<identity> in_id = identify(in);
        if (in_id && *in_id == *id) {
          throw error(out.path.string() + ": " + out.flag + " names the input file " + in.string() +
                      " (refusing to overwrite an input)");
        }
      }
    }
    for (std::size_t j = 0; j < i; ++j) {
      const named_output& other = outputs[j];
      const std::optional<identity> other_id = identify(other.path);
      const bool same = id && other_id
                            ? *id == *other_id && !id->character_device
                            : !id && !other_id && normalised(out.path) == normalised(other.path);
      if (same) {
        throw error(out.path.string() + ": " + out.flag + " names the same file as " + other.flag +
                    " (each output needs its own file)");
      }
    }
  }
}

void remove_temporaries_on_signals() {
  struct sigaction action {};
  action.sa_handler = on_fatal_signal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = static_cast<int>(SA_RESETHAND);
  for (const int sig : {SIGINT, SIGTERM, SIGHUP}) sigaction(sig, &action, nullptr);
}

/// Refuses a PLY, STL, GLB or VTP output whose float coordinates could not hold the volume's extent
/// (in the scanner coordinates of `world` when given: the box's corners mapped).
void check_float_range(const std::filesystem::path& output, const progiso::volume& vol,
                       const std::optional<progiso::index_to_world>& world) {
  const std::string ext = progiso::detail::lower_extension(output);
  if (ext != ".ply" && ext != ".stl" && ext != ".glb" && ext != ".vtp") return;
  const std::string format = ext == ".ply"   ? "PLY"
                             : ext == ".stl" ? "STL"
                             : ext == ".glb" ? "glTF"
                                             : "VTP";
  constexpr double float_max = static_cast<double>(std::numeric_limits<float>::max());
  std::array<double, 3> far{};
  for (int corner = 0; corner < 8; ++corner) {
    std::array<double, 3> index{};
    for (std::size_t a = 0; a < 3; ++a) {
      index[a] = ((corner >> a) & 1) != 0 ? static_cast<double>(vol.dims()[a] - 1) : 0.0;
    }
    std::array<double, 3> p{};
    if (world) {
      p = world->apply(index);
    } else {
      for (std::size_t a = 0; a < 3; ++a) p[a] = vol.origin()[a] + index[a] * vol.spacing()[a];
    }
    for (std::size_t a = 0; a < 3; ++a) far[a] = std::max(far[a], std::fabs(p[a]));
  }
  for (std::size_t a = 0; a < 3; ++a) {
    if (!(far[a] <= float_max)) {
      throw error(output.string() + ": coordinates up to " + std::to_string(far[a]) +
                  " are beyond the float range of " + format +
                  " (write .obj for double coordinates)");
    }
  }
}

/// The mesh in scanner coordinates: each vertex's grid index (its position in the data's
/// origin + index × spacing) mapped by `world`, and every triangle's winding reversed when the
/// map mirrors, so that triangles keep facing the side they faced. Normals (−∇f) are mapped as
/// gradients are: the index-space gradient is spacing × the physical one, and a world gradient
/// is the inverse transpose of the map's 3 × 3 part M times an index-space one; M⁻ᵀ is M's
/// cofactor matrix over det M. A map with det M = 0 (a .vti Direction that is singular, which
/// flattens the mesh itself) leaves the normals as they were.
void to_world(progiso::triangle_mesh& mesh, const progiso::volume& data,
              const progiso::index_to_world& world) {
  for (progiso::vec3& p : mesh.vertices) {
    std::array<double, 3> index{};
    for (std::size_t a = 0; a < 3; ++a) index[a] = (p[a] - data.origin()[a]) / data.spacing()[a];
    p = world.apply(index);
  }
  const double det = world.determinant();
  if (!mesh.normals.empty()) {
    const auto& m = world.m;
    const auto at = [&m](std::size_t r, std::size_t c) { return m[r % 3][c % 3]; };
    std::array<std::array<double, 3>, 3> inverse_t{};  // cofactor(r, c) / det
    for (std::size_t r = 0; r < 3; ++r) {
      for (std::size_t c = 0; c < 3; ++c) {
        inverse_t[r][c] =
            (at(r + 1, c + 1) * at(r + 2, c + 2) - at(r + 1, c + 2) * at(r + 2, c + 1)) / det;
      }
    }
    for (progiso::vec3& n : mesh.normals) {
      progiso::vec3 g{};
      for (std::size_t a = 0; a < 3; ++a) g[a] = n[a] * data.spacing()[a];
      progiso::vec3 w{};
      for (std::size_t r = 0; r < 3; ++r) {
        w[r] = inverse_t[r][0] * g[0] + inverse_t[r][1] * g[1] + inverse_t[r][2] * g[2];
      }
      const double len = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
      if (len > 0.0 && std::isfinite(len)) n = {w[0] / len, w[1] / len, w[2] / len};
    }
  }
  if (det < 0.0) {
    for (auto& t : mesh.triangles) std::swap(t[1], t[2]);
  }
}

std::optional<progiso::index_to_world> asked_world(bool asked, const volume_source* source,
                                                   const std::string& input) {
  if (!asked) return std::nullopt;
  std::optional<progiso::index_to_world> world;
  if (source != nullptr) world = source->world();
  if (!world) {
    throw error(input +
                ": --world: the file declares no orientation (expected a NIfTI sform or qform, "
                "NRRD space directions, or a MetaImage header)");
  }
  return world;
}

std::int64_t window_planes(const progiso::plane_window& w) {
  std::uint64_t budget = progiso::detail::finest_slab_bytes / 4;
  if (const char* e = std::getenv("PROGISO_WINDOW_BYTES"); e != nullptr && *e != '\0') {
    budget = std::strtoull(e, nullptr, 10);
  }
  const progiso::volume& f = w.field();
  const std::uint64_t row = static_cast<std::uint64_t>(f.dims()[0] * f.dims()[1]) *
                            progiso::sample_size(f.type()) *
                            static_cast<std::uint64_t>(w.chunk_planes());
  return w.chunk_planes() * static_cast<std::int64_t>(std::max<std::uint64_t>(1, budget / row));
}

void finest_in_windows(progiso::plane_window& w, double iso, const progiso::parallel_loop& loop,
                       std::size_t parts, const progiso::detail::finest_piece& add,
                       const std::function<std::array<std::uint64_t, 2>()>& counted,
                       std::int64_t z_begin, std::int64_t z_end) {
  const std::int64_t nz = w.field().dims()[2];
  const std::int64_t step = window_planes(w);
  for (std::int64_t z = z_begin; z < z_end; z += step) {
    std::int64_t end = std::min(z + step, z_end);
    // The grid's last plane holds no cubes: it goes with the share before it.
    if (z_end == nz && end >= nz - 1) end = nz;
    const std::array<std::uint64_t, 2> first = counted();
    w.hold(z, std::min(end + 2, nz), loop);
    progiso::detail::finest_surface_pieces(w.field(), iso, loop, parts, {}, add, 0,
                                           {z, end, first[0], first[1]});
    if (end == nz) break;
  }
}

}  // namespace progiso::cli
