#include "frame_codec.hpp"

#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>

namespace progiso::view {
namespace {

template <class T>
void put(std::vector<std::byte>& out, std::size_t at, T v) {
  std::memcpy(out.data() + at, &v, sizeof v);
}

template <class T>
T get(const std::vector<std::byte>& in, std::size_t at) {
  T v{};
  std::memcpy(&v, in.data() + at, sizeof v);
  return v;
}

// The words of `text` separated by single spaces; empty words make the text malformed.
std::vector<std::string_view> words_of(std::string_view text) {
  std::vector<std::string_view> words;
  std::size_t at = 0;
  while (at <= text.size()) {
    const std::size_t space = text.find(' ', at);
    const std::size_t end = space == std::string_view::npos ? text.size() : space;
    words.push_back(text.substr(at, end - at));
    if (space == std::string_view::npos) break;
    at = space + 1;
  }
  return words;
}

std::optional<double> finite_number(std::string_view w) {
  double v = 0.0;
  const auto r = std::from_chars(w.data(), w.data() + w.size(), v);
  if (r.ec != std::errc{} || r.ptr != w.data() + w.size() || !std::isfinite(v)) return {};
  return v;
}

}  // namespace

void encode_frame(const surface_change& change, const frame_state& state,
                  std::vector<std::byte>& out) {
  static_assert(std::numeric_limits<float>::is_iec559, "frames carry IEEE floats");
  const std::size_t g = change.gone.size();
  const std::size_t a = change.added.size();
  const bool normals = !change.normals.empty();
  const std::size_t size = frame_header_bytes + 8 * (g + a) + 36 * a * (normals ? 2 : 1);
  out.resize(size);
  std::uint32_t flags = 0;
  if (change.rebuilt) flags |= 1u;
  if (normals) flags |= 2u;
  if (state.running) flags |= 4u;
  put(out, 0, frame_magic);
  put(out, 4, flags);
  put(out, 8, state.isovalue);
  put(out, 16, state.generation);
  put(out, 24, state.splits);
  put(out, 32, state.triangles);
  put(out, 40, state.next_error);
  put(out, 48, state.uniform_stride);
  put(out, 52, state.iso_sequence);
  put(out, 56, static_cast<std::uint32_t>(g));
  put(out, 60, static_cast<std::uint32_t>(a));
  std::size_t at = frame_header_bytes;
  if (g != 0) std::memcpy(out.data() + at, change.gone.data(), 8 * g);
  at += 8 * g;
  if (a != 0) std::memcpy(out.data() + at, change.added.data(), 8 * a);
  at += 8 * a;
  if (a != 0) std::memcpy(out.data() + at, change.positions.data(), 36 * a);
  at += 36 * a;
  if (normals && a != 0) std::memcpy(out.data() + at, change.normals.data(), 36 * a);
}

std::optional<decoded_frame> decode_frame(const std::vector<std::byte>& in) {
  if (in.size() < frame_header_bytes || get<std::uint32_t>(in, 0) != frame_magic) return {};
  decoded_frame f;
  const auto flags = get<std::uint32_t>(in, 4);
  f.rebuilt = (flags & 1u) != 0;
  f.normals = (flags & 2u) != 0;
  f.state.running = (flags & 4u) != 0;
  f.state.isovalue = get<double>(in, 8);
  f.state.generation = get<std::uint64_t>(in, 16);
  f.state.splits = get<std::uint64_t>(in, 24);
  f.state.triangles = get<std::uint64_t>(in, 32);
  f.state.next_error = get<double>(in, 40);
  f.state.uniform_stride = get<std::uint32_t>(in, 48);
  f.state.iso_sequence = get<std::uint32_t>(in, 52);
  const std::size_t g = get<std::uint32_t>(in, 56);
  const std::size_t a = get<std::uint32_t>(in, 60);
  if (in.size() != frame_header_bytes + 8 * (g + a) + 36 * a * (f.normals ? 2 : 1)) return {};
  std::size_t at = frame_header_bytes;
  f.gone.resize(g);
  if (g != 0) std::memcpy(f.gone.data(), in.data() + at, 8 * g);
  at += 8 * g;
  f.added.resize(a);
  if (a != 0) std::memcpy(f.added.data(), in.data() + at, 8 * a);
  at += 8 * a;
  f.positions.resize(9 * a);
  if (a != 0) std::memcpy(f.positions.data(), in.data() + at, 36 * a);
  at += 36 * a;
  if (f.normals) {
    f.normal_values.resize(9 * a);
    if (a != 0) std::memcpy(f.normal_values.data(), in.data() + at, 36 * a);
  }
  return f;
}

std::optional<command> parse_command(std::string_view text) {
  if (text.empty() || text.size() > max_command_bytes) return {};
  const std::vector<std::string_view> w = words_of(text);
  command c;
  if (w.size() == 1 && w[0] == "pause") {
    c.what = command::kind::pause;
    return c;
  }
  if (w.size() == 1 && w[0] == "ack") {
    c.what = command::kind::ack;
    return c;
  }
  if (w.size() == 1 && w[0] == "resume") {
    c.what = command::kind::resume;
    return c;
  }
  if (w.size() == 3 && w[0] == "iso") {
    const auto v = finite_number(w[1]);
    std::uint32_t seq = 0;
    const auto r = std::from_chars(w[2].data(), w[2].data() + w[2].size(), seq);
    if (!v || r.ec != std::errc{} || r.ptr != w[2].data() + w[2].size()) return {};
    c.what = command::kind::iso;
    c.value = *v;
    c.sequence = seq;
    return c;
  }
  if (w.size() == 2 && w[0] == "goal" && w[1] == "full") {
    c.what = command::kind::goal_full;
    return c;
  }
  if (w.size() == 3 && w[0] == "goal" && w[1] == "triangles") {
    std::uint64_t k = 0;
    const auto r = std::from_chars(w[2].data(), w[2].data() + w[2].size(), k);
    if (r.ec != std::errc{} || r.ptr != w[2].data() + w[2].size() || k == 0 ||
        k > (std::uint64_t{1} << 40)) {
      return {};
    }
    c.what = command::kind::goal_triangles;
    c.value = static_cast<double>(k);
    return c;
  }
  if (w.size() == 3 && w[0] == "goal" && (w[1] == "error" || w[1] == "deadline")) {
    const auto v = finite_number(w[2]);
    if (!v || *v < 0.0 || (w[1] == "deadline" && *v > 3.6e6)) return {};
    c.what = w[1] == "error" ? command::kind::goal_error : command::kind::goal_deadline;
    c.value = *v;
    return c;
  }
  if (w.size() >= 7 && w[0] == "view" && (w.size() - 7) % 4 == 0 && (w.size() - 7) / 4 <= 6) {
    std::array<double, 3 + 3 + 24> v{};
    for (std::size_t i = 1; i < w.size(); ++i) {
      const auto x = finite_number(w[i]);
      if (!x) return {};
      v[i - 1] = *x;
    }
    c.what = command::kind::view;
    c.eye = {v[0], v[1], v[2]};
    c.target = {v[3], v[4], v[5]};
    c.plane_count = static_cast<std::uint32_t>((w.size() - 7) / 4);
    for (std::uint32_t k = 0; k < c.plane_count; ++k) {
      std::array<double, 4>& p = c.planes[k];
      for (std::size_t q = 0; q < 4; ++q) p[q] = v[6 + 4 * k + q];
      if (p[0] == 0.0 && p[1] == 0.0 && p[2] == 0.0) return {};
    }
    return c;
  }
  return {};
}

}  // namespace progiso::view
