#include <support/reference_mtri.hpp>

#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/error.hpp>

namespace progiso::test {
namespace {

using point = std::array<std::int64_t, 2>;
using triangle = std::array<point, 3>;

std::uint64_t key_of(const point& a, const point& b) {
  return static_cast<std::uint64_t>(a[0] + b[0]) | static_cast<std::uint64_t>(a[1] + b[1]) << 32;
}

// The two triangles of the unit square with min corner b: the diagonal joins its all-even corner
// e to its all-odd corner o; the third corners are the other two of the square.
std::array<triangle, 2> square_triangles(const point& b) {
  const point e{b[0] % 2 == 0 ? b[0] : b[0] + 1, b[1] % 2 == 0 ? b[1] : b[1] + 1};
  const point o{e[0] == b[0] ? b[0] + 1 : b[0], e[1] == b[1] ? b[1] + 1 : b[1]};
  return {triangle{e, o, point{o[0], e[1]}}, triangle{e, o, point{e[0], o[1]}}};
}

void check_arguments(const volume& image, double isovalue) {
  if (std::isnan(isovalue)) throw error("reference marching triangles: isovalue is NaN");
  if (image.dims()[2] != 1) {
    throw error("reference marching triangles: expected an image (depth 1), got depth " +
                std::to_string(image.dims()[2]));
  }
}

class marcher {
 public:
  marcher(const volume& image, double isovalue) : image_(image), w_(isovalue) {}

  void march(const triangle& t) {
    std::array<double, 3> f{};
    std::array<bool, 3> black{};
    int blacks = 0;
    for (std::size_t c = 0; c < 3; ++c) {
      f[c] = image_.at(image_.linear(t[c][0], t[c][1], 0));
      black[c] = f[c] > w_;
      blacks += black[c] ? 1 : 0;
    }
    if (blacks == 0 || blacks == 3) return;
    // The lone corner (the one black, or the one white) is joined to each of the others.
    const bool lone_colour = blacks == 1;
    std::size_t lone = 0;
    while (black[lone] != lone_colour) ++lone;
    std::size_t a = (lone + 1) % 3;
    std::size_t b = (lone + 2) % 3;
    // Direct p → q (p on edge lone–a, q on lone–b) so that a black corner k is on the left:
    // cross(q − p, k − p) > 0, on doubled midpoints (integers: exact; their line separates the
    // lone corner from the other two, so the cross product is never 0).
    const std::size_t k = black[lone] ? lone : a;
    const point p2{t[lone][0] + t[a][0], t[lone][1] + t[a][1]};
    const point q2{t[lone][0] + t[b][0], t[lone][1] + t[b][1]};
    const point k2{2 * t[k][0], 2 * t[k][1]};
    const std::int64_t cross =
        (q2[0] - p2[0]) * (k2[1] - p2[1]) - (q2[1] - p2[1]) * (k2[0] - p2[0]);
    PROGISO_ASSERT(cross != 0);
    if (cross < 0) std::swap(a, b);
    segment s;
    s.p[0] = position(t[lone], f[lone], t[a], f[a]);
    s.p[1] = position(t[lone], f[lone], t[b], f[b]);
    s.keys = {key_of(t[lone], t[a]), key_of(t[lone], t[b])};
    out_.push_back(s);
  }

  std::vector<segment> take() { return std::move(out_); }

 private:
  // The contour vertex on crossed edge (u, fu)–(v, fv), from the canonically ordered ends.
  [[nodiscard]] vec2 position(const point& u, double fu, const point& v, double fv) const {
    const bool u_first = u[1] != v[1] ? u[1] < v[1] : u[0] < v[0];
    const point& a = u_first ? u : v;
    const point& b = u_first ? v : u;
    const double fa = u_first ? fu : fv;
    const double fb = u_first ? fv : fu;
    constexpr double margin = 1.0 / 4096.0;
    double t = (w_ - fa) / (fb - fa);
    t = t < margin ? margin : (t > 1.0 - margin ? 1.0 - margin : t);
    vec2 r{};
    for (std::size_t q = 0; q < 2; ++q) {
      const double grid = static_cast<double>(a[q]) + t * static_cast<double>(b[q] - a[q]);
      r[q] = image_.origin()[q] + grid * image_.spacing()[q];
    }
    return r;
  }

  const volume& image_;
  double w_;
  std::vector<segment> out_;
};

// Reads a header token of a PGM, skipping whitespace and comments.
std::string pgm_token(const std::string& bytes, std::size_t& at) {
  while (at < bytes.size()) {
    const auto ch = static_cast<unsigned char>(bytes[at]);
    if (ch == '#') {
      while (at < bytes.size() && bytes[at] != '\n') ++at;
    } else if (std::isspace(ch) != 0) {
      ++at;
    } else {
      break;
    }
  }
  const std::size_t start = at;
  while (at < bytes.size() && std::isspace(static_cast<unsigned char>(bytes[at])) == 0) ++at;
  return bytes.substr(start, at - start);
}

}  // namespace

std::vector<segment> reference_segments(const volume& image, double isovalue) {
  check_arguments(image, isovalue);
  marcher m(image, isovalue);
  const index3& n = image.dims();
  for (std::int64_t j = 0; j + 1 < n[1]; ++j) {
    for (std::int64_t i = 0; i + 1 < n[0]; ++i) {
      for (const triangle& t : square_triangles({i, j})) m.march(t);
    }
  }
  return m.take();
}

contour_set reference_contours(const volume& image, double isovalue) {
  const std::vector<segment> segments = reference_segments(image, isovalue);
  contour_set out;
  constexpr std::size_t none = std::numeric_limits<std::size_t>::max();
  // One vertex per key; per vertex the segment leaving it and the one arriving at it (each
  // crossed edge has at most two triangles, and their segments run through it in one direction).
  std::unordered_map<std::uint64_t, std::uint32_t> index;
  std::vector<std::size_t> leaving;
  std::vector<std::size_t> arriving;
  std::vector<std::array<std::uint32_t, 2>> ends(segments.size());
  for (std::size_t s = 0; s < segments.size(); ++s) {
    for (std::size_t e = 0; e < 2; ++e) {
      const auto [it, inserted] =
          index.try_emplace(segments[s].keys[e], static_cast<std::uint32_t>(out.vertices.size()));
      if (inserted) {
        out.vertices.push_back(segments[s].p[e]);
        leaving.push_back(none);
        arriving.push_back(none);
      }
      ends[s][e] = it->second;
    }
    PROGISO_ASSERT(leaving[ends[s][0]] == none && arriving[ends[s][1]] == none);
    leaving[ends[s][0]] = s;
    arriving[ends[s][1]] = s;
  }
  std::vector<bool> used(segments.size(), false);
  const auto walk = [&](std::size_t s, bool closed) {
    polyline line;
    line.closed = closed;
    line.isovalue = isovalue;
    line.vertices.push_back(ends[s][0]);
    while (s != none && !used[s]) {
      used[s] = true;
      line.vertices.push_back(ends[s][1]);
      s = leaving[ends[s][1]];
    }
    if (closed) line.vertices.pop_back();  // back at the start
    out.polylines.push_back(std::move(line));
  };
  for (std::size_t s = 0; s < segments.size(); ++s) {
    if (!used[s] && arriving[ends[s][0]] == none) walk(s, false);
  }
  for (std::size_t s = 0; s < segments.size(); ++s) {
    if (!used[s]) walk(s, true);
  }
  return out;
}

const std::vector<shared_image>& shared_images() {
  static const std::vector<shared_image> table{
      {"camera", "camera_512x512.pgm", {64, 128, 192}},
      {"coins", "coins_384x303.pgm", {64, 128, 192}},
      {"dem", "jacksboro_dem_403x344_u16.pgm", {300, 400, 500, 600, 700, 800, 900, 1000}},
  };
  return table;
}

volume load_pgm(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw error(path.string() + ": cannot open PGM");
  std::string bytes(static_cast<std::size_t>(in.tellg()), '\0');
  in.seekg(0);
  if (!in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()))) {
    throw error(path.string() + ": cannot read PGM");
  }
  std::size_t at = 0;
  if (pgm_token(bytes, at) != "P5") throw error(path.string() + ": not a binary PGM (P5)");
  std::array<long, 3> header{};
  for (long& v : header) {
    const std::string token = pgm_token(bytes, at);
    try {
      v = std::stol(token);
    } catch (const std::exception&) {
      throw error(path.string() + ": bad PGM header field '" + token + "'");
    }
  }
  const long width = header[0];
  const long height = header[1];
  const long maxval = header[2];
  if (width < 2 || height < 2 || maxval < 1 || maxval > 65535) {
    throw error(path.string() + ": PGM header " + std::to_string(width) + "x" +
                std::to_string(height) + " maxval " + std::to_string(maxval) + " not supported");
  }
  ++at;  // the single whitespace character after maxval
  const std::size_t size = maxval < 256 ? 1 : 2;
  const std::size_t count = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  if (bytes.size() < at || bytes.size() - at != count * size) {
    throw error(path.string() + ": expected " + std::to_string(count * size) +
                " bytes of PGM samples");
  }
  std::vector<std::byte> samples(count * size);
  for (std::size_t i = 0; i < count; ++i) {
    if (size == 1) {
      samples[i] = static_cast<std::byte>(bytes[at + i]);
    } else {
      // Big-endian on disk, host order in the volume.
      const auto hi = static_cast<unsigned char>(bytes[at + 2 * i]);
      const auto lo = static_cast<unsigned char>(bytes[at + 2 * i + 1]);
      const auto v = static_cast<std::uint16_t>((hi << 8) | lo);
      std::memcpy(&samples[2 * i], &v, 2);
    }
  }
  return volume({width, height, 1}, size == 1 ? sample_type::u8 : sample_type::u16,
                std::move(samples));
}

volume make_test_image(std::int64_t w, std::int64_t h, double (*f)(double, double)) {
  std::vector<std::byte> b(static_cast<std::size_t>(w * h) * sizeof(float));
  auto* p = reinterpret_cast<float*>(b.data());
  for (std::int64_t y = 0; y < h; ++y) {
    for (std::int64_t x = 0; x < w; ++x) {
      p[x + w * y] = static_cast<float>(f(static_cast<double>(x), static_cast<double>(y)));
    }
  }
  return volume({w, h, 1}, sample_type::f32, std::move(b));
}

}  // namespace progiso::test
