#include "view_server.hpp"

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

#include <boost/asio/dispatch.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/strand.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>

#include <progiso/core/base/error.hpp>
#include <progiso/core/surface/surface_change.hpp>

#include "frame_codec.hpp"

namespace progiso::view {
namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using namespace std::chrono_literals;

bool same_mark(const cut_mark& a, const cut_mark& b) {
  return a.owner == b.owner && a.generation == b.generation && a.records == b.records &&
         a.root == b.root;
}

}  // namespace

class page_session;

struct server::impl {
  impl(engine& e, refine_goal g, server_options o) : eng(e), goal(g), opt(std::move(o)) {}

  engine& eng;
  refine_goal goal;
  server_options opt;
  std::mutex pages_mutex;
  std::vector<std::weak_ptr<page_session>> pages;
  std::atomic<bool> stopping{false};
  // Wakes the frame thread early: an isovalue request wants its first frame now, while the new
  // isovalue's cut is still coarse and small, not at the next tick.
  std::mutex wake_mutex;
  std::condition_variable wake;
  bool woken = false;
  std::mutex control;  // the goal, the view and the paused flag, with the engine calls they go with
  bool paused = false;
  std::optional<command> view;  // the last page's camera

  /// The goal with the view's focus (under `control`).
  refine_goal viewed_goal() const;
  // Counters: relaxed, each exact at some moment.
  std::atomic<std::uint64_t> page_count{0};
  std::atomic<std::uint64_t> frames{0};
  std::atomic<std::uint64_t> frame_bytes{0};
  std::atomic<std::uint64_t> skipped{0};
  std::atomic<std::uint64_t> refused{0};
  std::atomic<std::uint64_t> closed_hostile{0};
  // Last, so destroyed first: the handlers the context still holds destroy their sessions, which
  // count themselves out of page_count above.
  net::io_context ioc{1};
  tcp::acceptor acceptor{ioc};

  void accept();
  void apply(const command& c, page_session& from);
  void frame_loop();
  struct made_frame {
    cut_mark from;
    std::uint32_t sequence;
    std::shared_ptr<std::vector<std::byte>> frame;
    cut_mark to;
    bool running;  // the run, or more of this cut to come
  };
  made_frame make_frame(const surface_snapshot& snap, bool running, const cut_mark& from,
                        std::uint32_t sequence, surface_change& change);
  std::uint64_t frame_target(const cut_mark& from, const surface_snapshot& s) const;
  void add(const std::shared_ptr<page_session>& p) {
    std::lock_guard lock(pages_mutex);
    std::erase_if(pages, [](const std::weak_ptr<page_session>& w) { return w.expired(); });
    pages.push_back(p);
  }
};

// One page's WebSocket: reads its commands, writes the frames the frame thread hands it.
class page_session : public std::enable_shared_from_this<page_session> {
 public:
  page_session(tcp::socket&& socket, server::impl& s) : ws_(std::move(socket)), server_(s) {
    server_.page_count.fetch_add(1, std::memory_order_relaxed);
  }
  ~page_session() { server_.page_count.fetch_sub(1, std::memory_order_relaxed); }
  page_session(const page_session&) = delete;
  page_session& operator=(const page_session&) = delete;

  void run(http::request<http::empty_body> request) {
    // Frames go out as soon as they are written: with Nagle's algorithm a frame's last segment
    // waits for the acknowledgement of the one before, which the page's TCP delays (delayed
    // ACK), and an isovalue's first frame would wait that long.
    beast::error_code ignored;
    ws_.next_layer().socket().set_option(tcp::no_delay(true), ignored);
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_.read_message_max(max_command_bytes);
    ws_.binary(true);
    ws_.async_accept(request,
                     beast::bind_front_handler(&page_session::on_accept, shared_from_this()));
  }

  // The frame thread's side (it alone touches these): what the page was last sent.
  cut_mark mark{};
  std::uint32_t sent_sequence = 0;
  bool sent_running = false;
  /// A write is in flight. Set by the frame thread before it posts a write; cleared by the
  /// write's handler with release, which the frame thread's acquire load pairs with, so the
  /// frame thread sees the session's buffer released before it hands over the next frame.
  std::atomic<bool> busy{false};
  /// A frame was sent that the page has not acknowledged ("ack": drawn). Set by the frame
  /// thread as it sends, cleared by the page's ack. Relaxed: no data hangs on it (the write's
  /// buffer is guarded by `busy`), and a stale read only delays the next frame by one round.
  std::atomic<bool> unacknowledged{false};
  /// The sequence number of this page's last isovalue request, stored with release once the
  /// engine has published the new isovalue's surface; the frame thread's acquire load, taken
  /// before its snapshot, then guarantees the snapshot is of that isovalue or a later one.
  std::atomic<std::uint32_t> requested_sequence{0};
  /// Open for frames: set when the handshake is done, cleared when a read or write fails.
  /// Relaxed: a frame posted to a closed page fails its write, which is harmless.
  std::atomic<bool> open{false};

  // From the frame thread: `busy` is already set.
  void send(std::shared_ptr<std::vector<std::byte>> frame) {
    net::post(ws_.get_executor(), [self = shared_from_this(), frame = std::move(frame)]() mutable {
      self->out_ = std::move(frame);
      self->ws_.async_write(net::buffer(self->out_->data(), self->out_->size()),
                            [self](beast::error_code ec, std::size_t) {
                              self->out_.reset();
                              if (ec) self->open.store(false, std::memory_order_relaxed);
                              // Partner: the frame thread's acquire load of busy.
                              self->busy.store(false, std::memory_order_release);
                            });
    });
  }

 private:
  void on_accept(beast::error_code ec) {
    if (ec) return;
    open.store(true, std::memory_order_relaxed);
    server_.add(shared_from_this());
    read();
  }

  void read() {
    ws_.async_read(in_, beast::bind_front_handler(&page_session::on_read, shared_from_this()));
  }

  void on_read(beast::error_code ec, std::size_t) {
    if (ec) {
      // A message over read_message_max ends here too (message_too_big): closed.
      if (ec == websocket::error::message_too_big) {
        server_.closed_hostile.fetch_add(1, std::memory_order_relaxed);
      }
      open.store(false, std::memory_order_relaxed);
      return;
    }
    const bool text = ws_.got_text();
    const std::string message = beast::buffers_to_string(in_.data());
    in_.consume(in_.size());
    const std::optional<command> c = text ? parse_command(message) : std::nullopt;
    if (!c) {
      server_.closed_hostile.fetch_add(1, std::memory_order_relaxed);
      open.store(false, std::memory_order_relaxed);
      ws_.async_close(websocket::close_code::policy_error,
                      [self = shared_from_this()](beast::error_code) {});
      return;
    }
    server_.apply(*c, *this);
    read();
  }

  websocket::stream<beast::tcp_stream> ws_;
  beast::flat_buffer in_;
  std::shared_ptr<std::vector<std::byte>> out_;
  server::impl& server_;
};

// One HTTP connection: the page's files, or the upgrade to a page_session.
class http_session : public std::enable_shared_from_this<http_session> {
 public:
  http_session(tcp::socket&& socket, server::impl& s) : stream_(std::move(socket)), server_(s) {}

  void run() {
    net::dispatch(stream_.get_executor(),
                  beast::bind_front_handler(&http_session::read, shared_from_this()));
  }

 private:
  void read() {
    parser_.emplace();
    parser_->header_limit(8192);
    parser_->body_limit(0);
    stream_.expires_after(30s);
    http::async_read(stream_, buffer_, *parser_,
                     beast::bind_front_handler(&http_session::on_read, shared_from_this()));
  }

  void on_read(beast::error_code ec, std::size_t) {
    if (ec == http::error::end_of_stream) {
      stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
      return;
    }
    if (ec) {
      if (ec != beast::error::timeout) server_.refused.fetch_add(1, std::memory_order_relaxed);
      return;  // closed: header too large, a body, garbage, a timeout
    }
    http::request<http::empty_body> request = parser_->release();
    if (websocket::is_upgrade(request)) {
      // A browser always sends Origin with a WebSocket handshake; a page of another origin is
      // refused, so another site open in the same browser cannot drive the engine.
      const std::string origin(request[http::field::origin]);
      const std::string host(request[http::field::host]);
      if ((!origin.empty() && origin != "http://" + host) || request.target() != "/ws") {
        server_.refused.fetch_add(1, std::memory_order_relaxed);
        return respond(status_only(request, http::status::forbidden));
      }
      if (server_.page_count.load(std::memory_order_relaxed) >= server_.opt.max_pages) {
        server_.refused.fetch_add(1, std::memory_order_relaxed);
        return respond(status_only(request, http::status::service_unavailable));
      }
      stream_.expires_never();
      std::make_shared<page_session>(stream_.release_socket(), server_)->run(std::move(request));
      return;
    }
    respond(file_response(request));
  }

  using response = http::response<http::string_body>;

  response status_only(const http::request<http::empty_body>& request, http::status s) {
    response r{s, request.version()};
    r.set(http::field::server, "progiso");
    r.set(http::field::content_type, "text/plain");
    r.body() = std::string(http::obsolete_reason(s)) + "\n";
    r.keep_alive(false);
    r.prepare_payload();
    return r;
  }

  response file_response(const http::request<http::empty_body>& request) {
    if (request.method() != http::verb::get && request.method() != http::verb::head) {
      server_.refused.fetch_add(1, std::memory_order_relaxed);
      return status_only(request, http::status::method_not_allowed);
    }
    std::string_view path(request.target().data(), request.target().size());
    path = path.substr(0, path.find('?'));  // the page's own parameters (its slider's range)
    if (path == "/") path = "/index.html";
    const auto& assets = server_.opt.assets;
    const auto it =
        std::find_if(assets.begin(), assets.end(), [&](const asset& a) { return a.path == path; });
    if (it == assets.end()) {
      server_.refused.fetch_add(1, std::memory_order_relaxed);
      return status_only(request, http::status::not_found);
    }
    response r{http::status::ok, request.version()};
    r.set(http::field::server, "progiso");
    r.set(
        http::field::content_type,
        std::string(it->content_type) + (it->content_type == "text/html" ? "; charset=utf-8" : ""));
    r.set(http::field::cache_control, "no-store");
    r.set("X-Content-Type-Options", "nosniff");
    if (request.method() == http::verb::get) {
      r.body().assign(reinterpret_cast<const char*>(it->bytes.data()), it->bytes.size());
    }
    r.keep_alive(request.keep_alive());
    r.prepare_payload();
    if (request.method() == http::verb::head) r.content_length(it->bytes.size());
    return r;
  }

  void respond(response&& r) {
    auto held = std::make_shared<response>(std::move(r));
    http::async_write(stream_, *held,
                      [self = shared_from_this(), held](beast::error_code ec, std::size_t) {
                        if (ec) return;
                        if (held->need_eof()) {
                          self->stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
                          return;
                        }
                        self->read();
                      });
  }

  beast::tcp_stream stream_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::empty_body>> parser_;
  server::impl& server_;
};

void server::impl::accept() {
  acceptor.async_accept(net::make_strand(ioc), [this](beast::error_code ec, tcp::socket socket) {
    if (stopping.load(std::memory_order_relaxed)) return;
    if (!ec) std::make_shared<http_session>(std::move(socket), *this)->run();
    accept();
  });
}

refine_goal server::impl::viewed_goal() const {
  if (!view || goal.what == refine_goal::kind::full) return goal;
  // Physical to grid coordinates: x = origin + g × spacing, so a plane n·x + d ≥ 0 is
  // (n × spacing)·g + (n·origin + d) ≥ 0.
  std::array<double, 3> eye{};
  double target_distance2 = 0.0;
  for (std::size_t q = 0; q < 3; ++q) {
    eye[q] = (view->eye[q] - opt.origin[q]) / opt.spacing[q];
    const double t = (view->target[q] - view->eye[q]) / opt.spacing[q];
    target_distance2 += t * t;
  }
  std::array<std::array<double, 4>, 6> planes{};
  for (std::uint32_t k = 0; k < view->plane_count; ++k) {
    const std::array<double, 4>& p = view->planes[k];
    planes[k] = {p[0] * opt.spacing[0], p[1] * opt.spacing[1], p[2] * opt.spacing[2],
                 p[0] * opt.origin[0] + p[1] * opt.origin[1] + p[2] * opt.origin[2] + p[3]};
  }
  refine_goal g = goal;
  if (g.what == refine_goal::kind::error) {
    g.max_error *= opt.view_falloff / (opt.view_falloff + std::sqrt(target_distance2));
  }
  return g.viewed(eye, opt.view_falloff,
                  std::span<const std::array<double, 4>>(planes.data(), view->plane_count),
                  opt.view_outside);
}

void server::impl::apply(const command& c, page_session& from) {
  std::lock_guard lock(control);
  try {
    switch (c.what) {
      case command::kind::iso:
        eng.set_isovalue(c.value);  // publishes the new isovalue's root surface
        // The frame thread sends that surface now, while a finished run is started again below
        // (set_isovalue resumes a run it interrupted). Partner: the frame thread's acquire load,
        // before its snapshot.
        from.requested_sequence.store(c.sequence, std::memory_order_release);
        from.unacknowledged.store(false, std::memory_order_relaxed);  // the new isovalue: now
        {
          std::lock_guard w(wake_mutex);
          woken = true;
        }
        wake.notify_one();
        if (!paused && !eng.running()) eng.start(viewed_goal());
        break;
      case command::kind::ack:
        from.unacknowledged.store(false, std::memory_order_relaxed);
        {
          std::lock_guard w(wake_mutex);
          woken = true;  // the page is ready for what is newest now
        }
        wake.notify_one();
        break;
      case command::kind::pause:
        paused = true;
        eng.cancel();
        break;
      case command::kind::resume:
        paused = false;
        eng.start(viewed_goal());
        break;
      case command::kind::view: {
        const refine_goal before = viewed_goal();
        const std::optional<command> previous = view;
        view = c;
        refine_goal after;
        try {
          after = viewed_goal();
          check_goal(after);
        } catch (const error&) {
          view = previous;  // a view the engine would refuse (coordinates overflowing): dropped
          throw;
        }
        // A new focus re-keys the queue; a run towards the same goal goes on undisturbed.
        if (!paused && !(before.focus == after.focus && before.max_error == after.max_error)) {
          eng.start(after);
        }
        break;
      }
      case command::kind::goal_full:
      case command::kind::goal_error:
      case command::kind::goal_deadline:
      case command::kind::goal_triangles:
        goal = c.what == command::kind::goal_full    ? refine_goal::full()
               : c.what == command::kind::goal_error ? refine_goal::error(c.value)
               : c.what == command::kind::goal_triangles
                   ? refine_goal::triangles(static_cast<std::uint64_t>(c.value))
                   : refine_goal::within(std::chrono::duration<double>(c.value / 1000.0));
        paused = false;
        eng.start(viewed_goal());
        break;
    }
  } catch (const error&) {
    // A command the engine refuses (it validated already: nothing reaches here but misuse)
    // changes nothing.
  }
}

// The cut a page holding `from` is brought to, as records of s: all of them, except that a page
// holding another root (a new isovalue, a page just connected) gets the root surface first, and
// one holding this root at most max_frame_records more. Each is a prefix of the publication
// order, so a valid cut (surface_snapshot::truncate()): frames stay small, and a new isovalue's
// first frame never waits behind a large one.
std::uint64_t server::impl::frame_target(const cut_mark& from, const surface_snapshot& s) const {
  const cut_mark now = s.mark();
  if (s.uniform_stride() > 0 || opt.max_frame_records == 0) return now.records;
  const bool same_root = from.owner == now.owner && from.generation == now.generation &&
                         from.root == now.root && from.records != 0 && from.records <= now.records;
  if (!same_root) return 1;
  return now.records - from.records <= opt.max_frame_records ? now.records
                                                             : from.records + opt.max_frame_records;
}

server::impl::made_frame server::impl::make_frame(const surface_snapshot& snap, bool running,
                                                  const cut_mark& from, std::uint32_t sequence,
                                                  surface_change& change) {
  const surface_snapshot* s = &snap;
  surface_snapshot part;
  bool more = false;
  if (frame_target(from, snap) < snap.mark().records) {
    part = eng.snapshot();  // of the same root, or of a newer one: either way the target is its
    const std::uint64_t records = part.mark().records;
    part.truncate(frame_target(from, part));
    more = part.mark().records < records;
    s = &part;
  }
  frame_state state;
  state.isovalue = s->isovalue();
  state.generation = s->generation();
  state.splits = s->split_count();
  state.triangles = s->triangle_count();
  state.uniform_stride = static_cast<std::uint32_t>(std::max(0, s->uniform_stride()));
  state.running = running || more;
  state.next_error = opt.next_error ? opt.next_error() : 0.0;
  state.iso_sequence = sequence;
  change.clear();
  s->change_since(from, change, vertex_normals::gradient);
  auto frame = std::make_shared<std::vector<std::byte>>();
  encode_frame(change, state, *frame);
  return {from, sequence, std::move(frame), s->mark(), state.running};
}

void server::impl::frame_loop() {
  surface_change change;
  std::vector<std::shared_ptr<page_session>> live;
  std::vector<std::uint32_t> sequences;
  std::vector<made_frame> made_now;  // this round's frames, by the cut they start from
  while (!stopping.load(std::memory_order_relaxed)) {
    {
      std::unique_lock w(wake_mutex);
      wake.wait_for(w, opt.frame_interval, [this] { return woken; });
      woken = false;
    }
    live.clear();
    {
      std::lock_guard lock(pages_mutex);
      std::erase_if(pages, [](const std::weak_ptr<page_session>& w) { return w.expired(); });
      for (const auto& w : pages) {
        if (auto p = w.lock(); p && p->open.load(std::memory_order_relaxed)) live.push_back(p);
      }
    }
    if (live.empty()) continue;
    sequences.clear();
    for (const auto& p : live) {
      // Partner: the release store in apply(), after the engine published the isovalue.
      sequences.push_back(p->requested_sequence.load(std::memory_order_acquire));
    }
    // Read before the snapshot: a run that had ended then has published its last cut, so a frame
    // saying "not running" holds the final cut.
    const bool running = eng.running();
    const surface_snapshot snap = eng.snapshot();
    const cut_mark now = snap.mark();
    made_now.clear();
    for (std::size_t i = 0; i < live.size(); ++i) {
      page_session& p = *live[i];
      // Partner: the release store in the write's handler.
      if (p.busy.load(std::memory_order_acquire) ||
          p.unacknowledged.load(std::memory_order_relaxed)) {
        if (!same_mark(p.mark, now)) skipped.fetch_add(1, std::memory_order_relaxed);
        continue;
      }
      // Also when only the run's state changed: a page must learn that refinement has ended
      // even when the last cut it was sent is the final one (an empty change then).
      if (same_mark(p.mark, now) && p.sent_sequence == sequences[i] && p.sent_running == running) {
        continue;
      }
      // Pages that hold the same cut and asked the same get the same frame: made once.
      const made_frame* m = nullptr;
      for (const made_frame& x : made_now) {
        if (same_mark(x.from, p.mark) && x.sequence == sequences[i]) m = &x;
      }
      if (m == nullptr) {
        made_now.push_back(make_frame(snap, running, p.mark, sequences[i], change));
        m = &made_now.back();
      }
      p.mark = m->to;
      p.sent_sequence = sequences[i];
      p.sent_running = m->running;
      frames.fetch_add(1, std::memory_order_relaxed);
      frame_bytes.fetch_add(m->frame->size(), std::memory_order_relaxed);
      // Relaxed: only this thread sets it; the handler's release store clears it.
      p.busy.store(true, std::memory_order_relaxed);
      p.unacknowledged.store(true, std::memory_order_relaxed);
      p.send(m->frame);
    }
  }
}

server::server(engine& eng, refine_goal goal, server_options options)
    : impl_(std::make_unique<impl>(eng, goal, std::move(options))) {
  beast::error_code ec;
  const auto address = net::ip::make_address(impl_->opt.bind, ec);
  if (ec) throw error("--bind: expected an IP address, found '" + impl_->opt.bind + "'");
  const tcp::endpoint at(address, impl_->opt.port);
  const std::string where = impl_->opt.bind + ":" + std::to_string(impl_->opt.port);
  impl_->acceptor.open(at.protocol(), ec);
  if (!ec) impl_->acceptor.set_option(net::socket_base::reuse_address(true), ec);
  if (!ec) impl_->acceptor.bind(at, ec);
  if (!ec) impl_->acceptor.listen(net::socket_base::max_listen_connections, ec);
  if (ec) throw error("view: cannot listen on " + where + ": " + ec.message());
}

server::~server() = default;

std::uint16_t server::port() const noexcept { return impl_->acceptor.local_endpoint().port(); }

void server::run() {
  impl_->accept();
  std::thread frames([this] { impl_->frame_loop(); });
  impl_->ioc.run();
  impl_->stopping.store(true, std::memory_order_relaxed);
  frames.join();
}

void server::stop() {
  impl_->stopping.store(true, std::memory_order_relaxed);
  impl_->ioc.stop();
}

server_statistics server::statistics() const {
  server_statistics s;
  s.pages = impl_->page_count.load(std::memory_order_relaxed);
  s.frames = impl_->frames.load(std::memory_order_relaxed);
  s.frame_bytes = impl_->frame_bytes.load(std::memory_order_relaxed);
  s.skipped = impl_->skipped.load(std::memory_order_relaxed);
  s.refused = impl_->refused.load(std::memory_order_relaxed);
  s.closed_hostile = impl_->closed_hostile.load(std::memory_order_relaxed);
  return s;
}

}  // namespace progiso::view
