// apps/progiso/view/view_server.hpp — the server of `progiso view`: its page over HTTP, the
// engine's surface over WebSockets (frame_codec.hpp), the pages' commands back to the engine.
//
// Threads. One I/O thread runs every connection (Boost.Asio, each connection on a strand of its
// own); one frame thread takes the engine's snapshots (a snapshot stays on the thread that took
// it) and, for every page ready, encodes the change from the cut that page holds to the newest
// and starts its write. A page is ready once its last write is done and it has acknowledged
// (drawn) its last frame; until then it is skipped, and then gets the change to whatever is
// newest. So a slow page, slow on the wire or slow to draw, skips versions instead of queueing
// them (in the server, the socket or the browser), holds at most one frame, and never delays the
// engine or another page.
//
// The view. A page sends its camera (frame_codec.hpp, "view"); the engine's goal then carries it
// as a focus (refine_goal::viewed(): screen-space error, culled to the frustum) and the run is
// restarted so its queue is keyed for the new view: refinement goes first where the camera looks
// and, for an error, budget or deadline goal, the cut stays coarser out of view. The last view
// received wins (pages share one engine). A full goal ignores views.
//
// Hostile clients. Requests: GET or HEAD of the page's own files only (a fixed table; no path
// reaches the file system), headers of at most 8 KiB, no body. WebSockets: an Origin other than
// the page's own is refused (403); a message above frame_codec's limit, a binary one, or one
// that does not parse closes that connection. Timeouts close idle HTTP connections.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <progiso/core/refine/goal.hpp>
#include <progiso/scheduler/engine.hpp>

namespace progiso::view {

/// A file of the page: its request path ("/viewer.js"), its MIME type and its bytes.
struct asset {
  std::string_view path;
  std::string_view content_type;
  std::span<const std::byte> bytes;
};

struct server_options {
  std::string bind = "127.0.0.1";
  std::uint16_t port = 8080;  ///< 0: any free port (port() tells which)
  std::vector<asset> assets;
  std::chrono::milliseconds frame_interval{15};
  std::size_t max_pages = 64;  ///< WebSocket connections at once; more are refused (503)
  /// Split records a frame may add to the cut a page holds (0: no bound). A page further behind
  /// catches up by prefixes of the publication order, each a valid cut, and a new isovalue's
  /// root surface goes first: no frame is so large that a new isovalue waits long behind it.
  std::uint64_t max_frame_records = 2048;
  /// The error of the engine's next split, for the status line (from its progress hook); empty:
  /// 0.
  std::function<double()> next_error;
  /// The field's grid: physical = origin + index × spacing (a page's camera is physical).
  std::array<double, 3> spacing{1.0, 1.0, 1.0};
  std::array<double, 3> origin{0.0, 0.0, 0.0};
  /// A page's view weights each diamond's error by falloff / (falloff + d), d its distance from
  /// the eye in grid units (screen-space error), and out of its frustum by `view_outside`
  /// (refine_focus). An error goal E then means E where the camera orbits: the target there is
  /// scaled by the weight at that distance.
  double view_falloff = 1.0;
  double view_outside = 0.25;
};

/// Counters, readable from any thread.
struct server_statistics {
  std::uint64_t pages = 0;           ///< WebSocket connections now
  std::uint64_t frames = 0;          ///< frames sent
  std::uint64_t frame_bytes = 0;     ///< their bytes
  std::uint64_t skipped = 0;         ///< newer cuts a busy page was not sent (it skips them)
  std::uint64_t refused = 0;         ///< requests and connections refused
  std::uint64_t closed_hostile = 0;  ///< connections closed for a malformed message
};

class server {
 public:
  /// Binds and listens (throws progiso::error naming the address when it cannot). The engine
  /// must outlive the server; `goal` is what "resume" and a new isovalue refine towards.
  server(engine& eng, refine_goal goal, server_options options);
  ~server();
  server(const server&) = delete;
  server& operator=(const server&) = delete;

  [[nodiscard]] std::uint16_t port() const noexcept;
  /// Serves until stop(): runs the I/O and the frame thread.
  void run();
  /// Any thread: run() returns soon after.
  void stop();
  [[nodiscard]] server_statistics statistics() const;

  struct impl;  // the sessions' shared state (view_server.cpp)

 private:
  std::unique_ptr<impl> impl_;
};

}  // namespace progiso::view
