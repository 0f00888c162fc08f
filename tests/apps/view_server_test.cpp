// `progiso view`'s server, against WebSocket and HTTP clients of Boost.Beast in this process:
// frames that rebuild the engine's cut exactly, many pages and a stalled one, pages that vanish
// mid-stream, hostile messages and origins, and the page's files only.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstring>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>

#include <progiso/core/field/analytic.hpp>
#include <progiso/core/surface/surface_change.hpp>
#include <progiso/scheduler/engine.hpp>

#include "support/render_checks.hpp"
#include "view/frame_codec.hpp"
#include "view/view_assets.hpp"
#include "view/view_server.hpp"

namespace progiso {
namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using namespace std::chrono_literals;

// An engine refining a field, and the server on it, serving on its own thread.
class served {
 public:
  explicit served(int n = 41)
      : eng_(make_demo_volume(n), demo_isovalue, options()),
        server_(eng_, refine_goal::error(0.0), server_options(eng_.field())) {
    eng_.start(refine_goal::error(0.0));
    thread_ = std::thread([this] { server_.run(); });
  }
  ~served() {
    server_.stop();
    thread_.join();
  }
  served(const served&) = delete;
  served& operator=(const served&) = delete;

  engine& eng() { return eng_; }
  view::server& srv() { return server_; }
  [[nodiscard]] std::uint16_t port() const { return server_.port(); }

 private:
  static engine_options options() {
    engine_options o;
    o.threads = 2;
    o.uniform_cuts = false;
    return o;
  }
  static view::server_options server_options(const volume& field) {
    view::server_options o;
    o.spacing = field.spacing();
    o.origin = field.origin();
    o.port = 0;
    o.assets = view::page_assets();
    o.frame_interval = 5ms;
    return o;
  }
  engine eng_;
  view::server server_;
  std::thread thread_;
};

// A page: a WebSocket client that applies every frame to a render_slots pool.
class page {
 public:
  explicit page(std::uint16_t port, const std::string& origin = "", int receive_buffer = 0)
      : ws_(ioc_) {
    tcp::resolver resolver(ioc_);
    if (receive_buffer > 0) {
      ws_.next_layer().open(tcp::v4());
      ws_.next_layer().set_option(net::socket_base::receive_buffer_size(receive_buffer));
    }
    net::connect(ws_.next_layer(), resolver.resolve("127.0.0.1", std::to_string(port)));
    host_ = "127.0.0.1:" + std::to_string(port);
    ws_.set_option(websocket::stream_base::decorator([origin, this](websocket::request_type& r) {
      r.set(http::field::origin, origin.empty() ? "http://" + host_ : origin);
    }));
    ws_.handshake(host_, "/ws");
  }
  // Reads one frame and applies it; false when the connection ended.
  bool next(view::decoded_frame* out = nullptr) {
    beast::flat_buffer b;
    beast::error_code ec;
    ws_.read(b, ec);
    if (ec) return false;
    std::vector<std::byte> bytes(b.size());
    std::memcpy(bytes.data(), b.data().data(), b.size());
    const auto f = view::decode_frame(bytes);
    EXPECT_TRUE(f.has_value());
    if (!f) return false;
    surface_change c;
    c.rebuilt = f->rebuilt;
    c.gone = f->gone;
    c.added = f->added;
    c.positions = f->positions;
    c.normals = f->normal_values;
    slots.apply(c);
    if (acks) say("ack");  // applied: a page that draws acknowledges here
    static_cast<view::decoded_frame&>(last) = *f;
    last.magic_seen = true;
    bytes_read += bytes.size();
    if (out != nullptr) *out = *f;
    return true;
  }
  // A failed write (the server closed the connection first) shows in the reads that follow.
  void say(const std::string& text) {
    beast::error_code ec;
    ws_.write(net::buffer(text), ec);
  }
  void say_binary(const std::string& bytes) {
    ws_.binary(true);
    beast::error_code ec;
    ws_.write(net::buffer(bytes), ec);
  }
  websocket::stream<tcp::socket>& socket() { return ws_; }

  render_slots slots;
  struct : view::decoded_frame {
    bool magic_seen = false;
  } last;
  std::size_t bytes_read = 0;
  bool acks = true;

 private:
  net::io_context ioc_;
  websocket::stream<tcp::socket> ws_;
  std::string host_;
};

// Reads frames until the page holds the engine's finished cut; returns whether it does. (A
// page is sent a frame whenever the cut it holds is not the newest, so once the run has ended
// the last frame is that of the finished cut.)
bool follow_to_the_end(page& p, engine& eng) {
  const auto give_up = std::chrono::steady_clock::now() + 60s;
  bool read_one = p.last.magic_seen;
  while (std::chrono::steady_clock::now() < give_up) {
    if (read_one && !eng.running() && !p.last.state.running) {
      const surface_snapshot s = eng.snapshot();
      if (p.last.state.splits == s.split_count() && p.last.state.generation == s.generation() &&
          p.last.state.isovalue == s.isovalue()) {
        render_buffers b;
        s.mesh_into(b, vertex_normals::gradient);
        return test::slot_triangles(p.slots, true) == test::buffer_triangles(b, true);
      }
    }
    if (!p.next()) return false;
    read_one = true;
  }
  return false;
}

TEST(ViewServer, a_page_that_applies_every_frame_holds_the_engines_cut_triangle_for_triangle) {
  served s;
  page p(s.port());
  std::uint64_t last_splits = 0;
  view::decoded_frame f;
  ASSERT_TRUE(p.next(&f));
  EXPECT_TRUE(f.rebuilt);  // the first frame is the whole cut
  while (f.state.running) {
    ASSERT_TRUE(p.next(&f));
    EXPECT_FALSE(f.rebuilt);
    EXPECT_GE(f.state.splits, last_splits);  // cuts only grow within one isovalue
    last_splits = f.state.splits;
  }
  EXPECT_TRUE(follow_to_the_end(p, s.eng()));
}

TEST(ViewServer, an_isovalue_request_is_answered_by_a_frame_of_the_new_isovalue) {
  served s;
  page p(s.port());
  ASSERT_TRUE(p.next());
  p.say("iso 0.31 7");
  view::decoded_frame f;
  do {
    ASSERT_TRUE(p.next(&f));
  } while (f.state.iso_sequence != 7);
  EXPECT_EQ(f.state.isovalue, 0.31);
  EXPECT_TRUE(f.rebuilt);
  EXPECT_EQ(f.state.splits, 0u);  // the new isovalue's root surface first, however far it went
  EXPECT_TRUE(follow_to_the_end(p, s.eng()));
  EXPECT_EQ(s.eng().isovalue(), 0.31);
}

TEST(ViewServer, a_page_far_behind_catches_up_by_valid_cuts_of_bounded_size) {
  served s(65);
  s.eng().wait();  // the whole refinement is done before the page asks
  page p(s.port());
  view::decoded_frame f;
  std::uint64_t frames = 0;
  std::uint64_t splits = 0;
  do {
    ASSERT_TRUE(p.next(&f));
    ++frames;
    EXPECT_LE(f.state.splits - splits, view::server_options{}.max_frame_records);
    splits = f.state.splits;
    // What the page holds is the engine's cut of that many records (a prefix: a valid cut).
    surface_snapshot prefix = s.eng().snapshot();
    prefix.truncate(f.state.splits + 1);
    render_buffers b;
    prefix.mesh_into(b, vertex_normals::gradient);
    ASSERT_EQ(test::slot_triangles(p.slots, true), test::buffer_triangles(b, true)) << splits;
  } while (f.state.running);
  EXPECT_EQ(splits, s.eng().snapshot().split_count());
  EXPECT_GT(frames, 3u);
}

// Says `text` and waits until the engine has started a run since (the command is applied on
// the server's own thread).
void say_and_wait_for_a_run(page& p, engine& eng, const std::string& text) {
  const std::uint64_t runs = eng.statistics().runs;
  p.say(text);
  const auto until = std::chrono::steady_clock::now() + 10s;
  while (eng.statistics().runs == runs && std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(1ms);
  }
  EXPECT_GT(eng.statistics().runs, runs) << text;
}

// Pauses the run and waits until the engine is quiet.
void pause_and_wait(page& p, engine& eng) {
  p.say("pause");
  const auto until = std::chrono::steady_clock::now() + 10s;
  while (eng.running() && std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(1ms);
  }
}

TEST(ViewServer, pause_resume_and_goals_drive_the_engine) {
  served s(65);
  page p(s.port());
  ASSERT_TRUE(p.next());
  pause_and_wait(p, s.eng());
  EXPECT_FALSE(s.eng().running());
  // Paused, a new isovalue shows its root surface and refines nothing.
  p.say("iso 0.31 1");
  while (p.last.state.iso_sequence != 1) ASSERT_TRUE(p.next());
  EXPECT_TRUE(follow_to_the_end(p, s.eng()));
  EXPECT_EQ(p.last.state.iso_sequence, 1u);
  EXPECT_EQ(p.last.state.splits, 0u);
  say_and_wait_for_a_run(p, s.eng(), "goal triangles 20000");
  EXPECT_TRUE(follow_to_the_end(p, s.eng()));
  EXPECT_LE(p.last.state.triangles, 20000u);
  EXPECT_GT(p.last.state.triangles, 15000u);
  const std::uint64_t budgeted = p.last.state.splits;
  EXPECT_GT(budgeted, 0u);
  say_and_wait_for_a_run(p, s.eng(), "goal error 0.02");
  EXPECT_TRUE(follow_to_the_end(p, s.eng()));
  const std::uint64_t coarse = p.last.state.splits;
  EXPECT_GT(coarse, budgeted);
  say_and_wait_for_a_run(p, s.eng(), "goal error 0");
  EXPECT_TRUE(follow_to_the_end(p, s.eng()));
  EXPECT_GT(p.last.state.splits, coarse);
  p.say("pause");
  p.say("iso 0.4 2");
  say_and_wait_for_a_run(p, s.eng(), "resume");  // the goal again: error 0, new isovalue
  EXPECT_TRUE(follow_to_the_end(p, s.eng()));
  EXPECT_EQ(p.last.state.isovalue, 0.4);
  EXPECT_GT(p.last.state.splits, 0u);
}

// The triangles of the page's surface whose centroid lies below x = mid, and the others.
std::array<std::size_t, 2> halves(const page& p, float mid) {
  std::array<std::size_t, 2> n{};
  for (const auto& [t, count] : test::slot_triangles(p.slots, false)) {
    n[(t[0] + t[3] + t[6]) / 3.0f < mid ? 0 : 1] += static_cast<std::size_t>(count);
  }
  return n;
}

TEST(ViewServer, a_view_refines_what_it_looks_at_and_leaves_the_rest_coarser) {
  served s(65);  // grid 0 … 64, spacing 1
  page p(s.port());
  ASSERT_TRUE(p.next());
  pause_and_wait(p, s.eng());
  // A camera looking at the centre along x, with one frustum plane: the half it faces.
  const auto refine_seen_from = [&](const std::string& view, std::uint32_t sequence, double w) {
    p.say(view);
    p.say("iso " + std::to_string(w) + " " + std::to_string(sequence));
    while (p.last.state.iso_sequence != sequence) EXPECT_TRUE(p.next());
    say_and_wait_for_a_run(p, s.eng(), "goal error 0.1");
    EXPECT_TRUE(follow_to_the_end(p, s.eng()));
    return halves(p, 32.0f);
  };
  const auto from_right = refine_seen_from("view 232 32 32 32 32 32 1 0 0 -32", 1, 0.31);
  const auto from_left = refine_seen_from("view -168 32 32 32 32 32 -1 0 0 32", 2, 0.3);
  ASSERT_GT(from_right[0] + from_right[1], 1000u);
  EXPECT_GT(from_right[1], 2 * from_right[0]);
  EXPECT_GT(from_left[0], 2 * from_left[1]);
  // The same view again does not restart the finished run; another view does (once).
  const std::uint64_t runs = s.eng().statistics().runs;
  p.say("view -168 32 32 32 32 32 -1 0 0 32");
  say_and_wait_for_a_run(p, s.eng(), "view -168 32 32 32 32 32 -1 0 0 31");
  std::this_thread::sleep_for(50ms);
  EXPECT_EQ(s.eng().statistics().runs, runs + 1);
}

TEST(ViewServer, a_page_is_sent_its_next_frame_only_once_it_has_drawn_the_last) {
  served s(65);
  page p(s.port());
  p.acks = false;
  ASSERT_TRUE(p.next());
  // However long the engine refines, nothing more comes until the page acknowledges.
  std::this_thread::sleep_for(300ms);
  EXPECT_EQ(s.srv().statistics().frames, 1u);
  EXPECT_GT(s.srv().statistics().skipped, 0u);
  p.acks = true;
  p.say("ack");
  EXPECT_TRUE(follow_to_the_end(p, s.eng()));
  EXPECT_GT(s.srv().statistics().frames, 1u);
}

TEST(ViewServer, eight_pages_and_a_stalled_one_each_get_the_latest_cut_and_the_stall_costs_none) {
  served s(65);
  std::vector<std::unique_ptr<page>> pages;
  for (int i = 0; i < 8; ++i) pages.push_back(std::make_unique<page>(s.port()));
  page stalled(s.port(), "", 4096);  // never reads: its socket fills, its writes wait
  std::vector<std::thread> readers;
  std::atomic<int> ok{0};
  for (auto& p : pages) {
    readers.emplace_back([&, q = p.get()] {
      if (follow_to_the_end(*q, s.eng())) ok.fetch_add(1);
    });
  }
  for (auto& t : readers) t.join();
  EXPECT_EQ(ok.load(), 8);
  EXPECT_EQ(s.srv().statistics().pages, 9u);
  // New isovalues, each a whole new cut for every page: the stalled page's socket is full, so
  // its write stays in flight and it skips every version meanwhile (the server holds at most
  // that one frame for it), while the first page follows each to the end.
  for (std::uint32_t k = 1; k <= 3; ++k) {
    pages[0]->say("iso " + std::to_string(0.3 + 0.02 * k) + " " + std::to_string(k));
    while (pages[0]->last.state.iso_sequence != k) ASSERT_TRUE(pages[0]->next());
    EXPECT_TRUE(follow_to_the_end(*pages[0], s.eng())) << k;
  }
  EXPECT_GT(s.srv().statistics().skipped, 0u);
}

TEST(ViewServer, pages_that_vanish_mid_stream_leave_the_others_whole) {
  served s(65);
  page survivor(s.port());
  for (int i = 0; i < 6; ++i) {
    page p(s.port());
    ASSERT_TRUE(p.next());
    p.socket().next_layer().close();  // gone without a close frame, mid-stream
  }
  EXPECT_TRUE(follow_to_the_end(survivor, s.eng()));
  const auto until = std::chrono::steady_clock::now() + 10s;
  while (s.srv().statistics().pages != 1 && std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(5ms);
  }
  EXPECT_EQ(s.srv().statistics().pages, 1u);
}

TEST(ViewServer, malformed_binary_and_oversized_messages_close_only_their_connection) {
  served s;
  page good(s.port());
  ASSERT_TRUE(good.next());
  const std::vector<std::string> hostile{"iso nan 1",
                                         "iso 1",
                                         "goal error -1",
                                         "drop tables",
                                         "iso 0.3 99999999999",
                                         std::string(5000, 'x'),
                                         ""};
  for (const std::string& text : hostile) {
    page bad(s.port());
    ASSERT_TRUE(bad.next());
    bad.say(text);
    bool closed = false;
    for (int i = 0; i < 1000 && !closed; ++i) closed = !bad.next();
    EXPECT_TRUE(closed) << "'" << text.substr(0, 40) << "' left the connection open";
  }
  {
    page bad(s.port());
    ASSERT_TRUE(bad.next());
    bad.say_binary("iso 0.3 1");
    bool closed = false;
    for (int i = 0; i < 1000 && !closed; ++i) closed = !bad.next();
    EXPECT_TRUE(closed);
  }
  EXPECT_GE(s.srv().statistics().closed_hostile, hostile.size());
  EXPECT_EQ(s.eng().isovalue(), demo_isovalue);  // none of them moved the engine
  EXPECT_TRUE(follow_to_the_end(good, s.eng()));
}

TEST(ViewServer, a_cross_origin_websocket_is_refused) {
  served s;
  EXPECT_THROW(page(s.port(), "http://evil.example"), beast::system_error);
  EXPECT_THROW(page(s.port(), "http://127.0.0.1:1"), beast::system_error);
  EXPECT_GE(s.srv().statistics().refused, 2u);
  page same(s.port());  // the page's own origin
  EXPECT_TRUE(same.next());
}

// One HTTP request; the status and body.
std::pair<unsigned, std::string> get(std::uint16_t port, const std::string& target,
                                     http::verb verb = http::verb::get) {
  net::io_context ioc;
  beast::tcp_stream stream(ioc);
  tcp::resolver resolver(ioc);
  stream.connect(resolver.resolve("127.0.0.1", std::to_string(port)));
  http::request<http::empty_body> req{verb, target, 11};
  req.set(http::field::host, "127.0.0.1");
  http::write(stream, req);
  beast::flat_buffer b;
  http::response<http::string_body> res;
  beast::error_code ec;
  http::read(stream, b, res, ec);
  return {res.result_int(), res.body()};
}

TEST(ViewServer, serves_the_pages_own_files_and_nothing_else) {
  served s;
  const auto [status, body] = get(s.port(), "/?min=0&max=1&iso=0.5");
  EXPECT_EQ(status, 200u);
  EXPECT_NE(body.find("<canvas id=\"view\">"), std::string::npos);
  for (const auto& a : view::page_assets()) {
    const auto [st, b] = get(s.port(), std::string(a.path));
    EXPECT_EQ(st, 200u) << a.path;
    EXPECT_EQ(b.size(), a.bytes.size()) << a.path;
  }
  for (const std::string target :
       {"/../../etc/passwd", "/etc/passwd", "/index.html/..", "//index.html", "/%2e%2e/x",
        "/web/src/viewer.js", "/CMakeLists.txt", "/viewer.js/", "*"}) {
    EXPECT_EQ(get(s.port(), target).first, 404u) << target;
  }
  EXPECT_EQ(get(s.port(), "/index.html", http::verb::post).first, 405u);
  EXPECT_EQ(get(s.port(), "/ws").first, 404u);  // not a WebSocket handshake
}

TEST(ViewServer, oversized_request_headers_close_the_connection) {
  served s;
  net::io_context ioc;
  beast::tcp_stream stream(ioc);
  tcp::resolver resolver(ioc);
  stream.connect(resolver.resolve("127.0.0.1", std::to_string(s.port())));
  const std::string request =
      "GET / HTTP/1.1\r\nHost: x\r\nX-Big: " + std::string(20000, 'a') + "\r\n\r\n";
  beast::error_code ec;
  net::write(stream, net::buffer(request), ec);
  beast::flat_buffer b;
  http::response<http::string_body> res;
  http::read(stream, b, res, ec);
  EXPECT_TRUE(ec) << "a 20 kB header was answered";
  page p(s.port());  // the server goes on
  EXPECT_TRUE(p.next());
}

TEST(FrameCodec, commands_parse_strictly) {
  EXPECT_TRUE(view::parse_command("iso 0.5 3").has_value());
  EXPECT_EQ(view::parse_command("iso -1e3 4294967295")->sequence, 4294967295u);
  EXPECT_TRUE(view::parse_command("goal deadline 200").has_value());
  EXPECT_EQ(view::parse_command("ack")->what, view::command::kind::ack);
  EXPECT_EQ(view::parse_command("goal triangles 5000")->value, 5000.0);
  const auto v = view::parse_command("view 1 2 3 4 5 6 0 1 0 -2.5 0 0 -1 7");
  ASSERT_TRUE(v.has_value());
  EXPECT_EQ(v->plane_count, 2u);
  EXPECT_EQ(v->target[2], 6.0);
  EXPECT_EQ(v->planes[0][3], -2.5);
  EXPECT_EQ(v->planes[1][3], 7.0);
  EXPECT_TRUE(view::parse_command("view 1 2 3 4 5 6").has_value());
  for (const char* bad :
       {"iso 0.5",
        "iso  0.5 3",
        "iso 0.5 3 ",
        " pause",
        "pause ",
        "Pause",
        "iso inf 1",
        "iso 0x1p3 1",
        "goal error",
        "goal deadline 1e9",
        "resume now",
        "view 1 2 3 4 5",
        "view 1 2 3 4 5 6 1 0 0",
        "view 1 2 3 4 5 6 0 0 0 1",
        "view 1 2 3 4 5 nan",
        "goal triangles 0",
        "goal triangles -3",
        "goal triangles 1.5",
        "goal triangles 2000000000000",
        "view 0 0 0 0 0 0 1 0 0 0 1 0 0 0 1 0 0 0 1 0 0 0 1 0 0 0 1 0 0 0 1 0 0 0"}) {
    EXPECT_FALSE(view::parse_command(bad).has_value()) << bad;
  }
}

}  // namespace
}  // namespace progiso
