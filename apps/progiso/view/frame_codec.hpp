// apps/progiso/view/frame_codec.hpp — what `progiso view` and its page say to each other.
//
// Server to page: one binary WebSocket message per frame, the change from the cut the page holds
// to the newest one (surface_change.hpp), little-endian, every array aligned to its element:
//
//   offset  type       field
//   0       u32        magic 0x31564750 ("PGV1")
//   4       u32        flags: 1 rebuilt (drop everything first), 2 normals present, 4 running
//   8       f64        isovalue of the cut
//   16      u64        generation (isovalue changes before it)
//   24      u64        split diamonds in the cut
//   32      u64        triangles in the cut
//   40      f64        error of the next split (0: none known)
//   48      u32        uniform stride (0: a cut of split records)
//   52      u32        sequence number of the last isovalue request this frame answers
//   56      u32        gone: ids removed (G)
//   60      u32        added: pieces added (A)
//   64      u64[G]     gone ids
//   …       u64[A]     added ids (pieces of one triangle share an id)
//   …       f32[9A]    positions: three corners, x y z each, per piece
//   …       f32[9A]    normals, when flag 2
//
// Page to server: short text commands, one per message (at most max_command_bytes):
//   "iso W SEQ"         move the isovalue to W (finite), SEQ a u32 the frames echo back; it
//                       acknowledges too (the new isovalue's frame does not wait for a draw)
//   "ack"               the page has drawn the last frame it was sent: the server sends the
//                       next only then, so a page holds at most one frame it has not drawn
//   "pause", "resume"   cancel the run / start the goal again
//   "goal full" | "goal error E" | "goal deadline MS" | "goal triangles K" (1 ≤ K ≤ 2^40)
//   "view EX EY EZ TX TY TZ [A B C D]…"   the camera: eye, the point it orbits, and 0 to 6
//                       frustum planes A·x + B·y + C·z + D ≥ 0 inside (physical coordinates);
//                       refinement goes first where it looks (server.hpp)
// Anything else is malformed: the server closes that connection.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <progiso/core/surface/surface_change.hpp>

namespace progiso::view {

inline constexpr std::uint32_t frame_magic = 0x31564750u;
inline constexpr std::size_t frame_header_bytes = 64;
inline constexpr std::size_t max_command_bytes = 1024;

/// The cut a frame brings the page to.
struct frame_state {
  double isovalue = 0.0;
  std::uint64_t generation = 0;
  std::uint64_t splits = 0;
  std::uint64_t triangles = 0;
  double next_error = 0.0;
  std::uint32_t uniform_stride = 0;
  std::uint32_t iso_sequence = 0;
  bool running = false;
};

/// The frame of `change` (see the file comment) into `out` (its storage reused).
void encode_frame(const surface_change& change, const frame_state& state,
                  std::vector<std::byte>& out);

/// A decoded frame (tests; the page decodes in JavaScript).
struct decoded_frame {
  frame_state state;
  bool rebuilt = false;
  bool normals = false;
  std::vector<std::uint64_t> gone;
  std::vector<std::uint64_t> added;
  std::vector<float> positions;
  std::vector<float> normal_values;
};
/// Decodes a frame; nullopt when it is malformed (sizes that do not add up, a wrong magic).
[[nodiscard]] std::optional<decoded_frame> decode_frame(const std::vector<std::byte>& bytes);

/// A page's command.
struct command {
  enum class kind {
    iso,
    ack,
    pause,
    resume,
    goal_full,
    goal_error,
    goal_deadline,
    goal_triangles,
    view
  };
  kind what = kind::pause;
  double value =
      0.0;  // iso: the isovalue; goal_error: E; goal_deadline: milliseconds; goal_triangles: K
  std::uint32_t sequence = 0;  // iso
  // view: physical coordinates; planes with a non-zero normal
  std::array<double, 3> eye{};
  std::array<double, 3> target{};
  std::array<std::array<double, 4>, 6> planes{};
  std::uint32_t plane_count = 0;
};
/// Parses one command (see the file comment); nullopt for anything malformed.
[[nodiscard]] std::optional<command> parse_command(std::string_view text);

}  // namespace progiso::view
