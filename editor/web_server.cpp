// websocketpp behind web_server.h. Built as C++17 (see the header).
#define ASIO_STANDALONE
#include "web_server.h"

#include <algorithm>
#include <asio/post.hpp>
#include <asio/signal_set.hpp>
#include <atomic>
#include <chrono>
#include <csignal>
#include <map>
#include <stdexcept>
#include <utility>
#include <vector>
#include <websocketpp/config/asio_no_tls.hpp>
#include <websocketpp/server.hpp>

namespace meshpde::net {

// websocketpp's plain socket, except that ending a connection shuts down only the
// sending side. Shutting down both sides makes Linux answer any byte the page still
// sends with a TCP reset, on which the page's kernel discards what the page has not
// read yet, the close frame included: a page whose message was over the limit saw 1006
// (connection lost) instead of 1009 (message too big) about one time in four.
class HalfCloseSocket : public websocketpp::transport::asio::basic_socket::connection {
 public:
  void async_shutdown(websocketpp::transport::asio::socket::shutdown_handler h) {
    asio::error_code ec;
    get_socket().shutdown(asio::ip::tcp::socket::shutdown_send, ec);
    h(ec);
  }
};
struct HalfCloseSocketEndpoint : websocketpp::transport::asio::basic_socket::endpoint {
  using socket_con_type = HalfCloseSocket;
  using socket_con_ptr = std::shared_ptr<websocketpp::transport::asio::basic_socket::connection>;
};
struct ServerConfig : websocketpp::config::asio {
  struct transport_config : websocketpp::config::asio::transport_config {
    using socket_type = HalfCloseSocketEndpoint;
  };
  using transport_type = websocketpp::transport::asio::endpoint<transport_config>;
};
using Server = websocketpp::server<ServerConfig>;
using Hdl = websocketpp::connection_hdl;

struct WebServer::Impl {
  WebHandlers handlers;
  Server server;
  int tick_ms = 16;
  bool stopping = false;
  int next_id = 0;
  std::map<Hdl, int, std::owner_less<Hdl>> ids;
  std::map<int, Hdl> hdls;
  std::unique_ptr<asio::signal_set> signals;
  // Connections the server closed for what their page sent (a message over the limit),
  // kept open a moment after the close frame; see the close handler. Declared after
  // `server`, so they are released while its I/O service still exists.
  std::vector<std::pair<std::chrono::steady_clock::time_point, Server::connection_ptr>> lingering;

  // Ticks on a fixed schedule (the handler's own time is taken off the wait), so a
  // 16 ms tick really runs 62.5 times a second when the handler is quick.
  std::chrono::steady_clock::time_point next_tick{};
  void schedule_tick() {
    if (stopping) return;
    const auto now = std::chrono::steady_clock::now();
    if (next_tick.time_since_epoch().count() == 0 || next_tick < now - std::chrono::milliseconds(tick_ms))
      next_tick = now;  // first tick, or fell behind: restart the schedule
    next_tick += std::chrono::milliseconds(tick_ms);
    const long wait = std::max<long>(
        0, static_cast<long>(std::chrono::duration_cast<std::chrono::milliseconds>(next_tick - now).count()));
    server.set_timer(wait, [this](const websocketpp::lib::error_code& ec) {
      if (ec || stopping) return;
      if (handlers.on_tick) handlers.on_tick();
      const auto t = std::chrono::steady_clock::now();
      lingering.erase(std::remove_if(lingering.begin(), lingering.end(), [t](const auto& l) { return l.first <= t; }),
                      lingering.end());
      schedule_tick();
    });
  }

  // On the I/O thread only (hdls is the I/O thread's).
  void send(int client, const std::string& data, websocketpp::frame::opcode::value op) {
    const auto it = hdls.find(client);
    if (it == hdls.end()) return;
    websocketpp::lib::error_code ec;
    server.send(it->second, data, op, ec);  // a closing connection just drops the frame
  }
  void post(std::function<void()> fn) { asio::post(server.get_io_service(), std::move(fn)); }
};

WebServer::WebServer(WebHandlers handlers, std::size_t max_body, std::size_t max_message, int tick_ms,
                     long request_timeout_ms)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.handlers = std::move(handlers);
  m.tick_ms = tick_ms;
  m.server.clear_access_channels(websocketpp::log::alevel::all);
  m.server.clear_error_channels(websocketpp::log::elevel::all);
  m.server.init_asio();
  m.server.set_reuse_addr(true);
  m.server.set_max_http_body_size(max_body);
  m.server.set_max_message_size(max_message);
  // A request that never finishes (a half-sent header or body) is dropped, not kept.
  m.server.set_open_handshake_timeout(request_timeout_ms);
  // Updates are small frames sent 60 times a second: without TCP_NODELAY, Nagle's
  // algorithm holds the second frame of an update back until the page's delayed ACK,
  // and updates arrive in pairs 32 ms apart. Set once the connection is accepted (the
  // socket does not exist yet when websocketpp's socket-init handler runs).
  m.server.set_tcp_post_init_handler([this](Hdl h) {
    asio::error_code ec;
    impl_->server.get_con_from_hdl(h)->get_socket().set_option(asio::ip::tcp::no_delay(true), ec);
  });
  m.server.set_open_handler([this](Hdl h) {
    Impl& s = *impl_;
    const int id = ++s.next_id;
    s.ids[h] = id;
    s.hdls[id] = h;
    if (s.handlers.on_open) s.handlers.on_open(id);
  });
  m.server.set_close_handler([this](Hdl h) {
    Impl& s = *impl_;
    // websocketpp ends the connection right after the close frame it sends for a
    // protocol error (status 1009 for a message over the limit), with the rest of that
    // message unread. Closing a socket with unread data sends a TCP reset (see
    // HalfCloseSocket): the socket, shut down for sending by now, is closed a second
    // later, once the page has read the close frame.
    const auto con = s.server.get_con_from_hdl(h);
    if (con->get_remote_close_code() == websocketpp::close::status::abnormal_close &&
        websocketpp::close::status::terminal(con->get_local_close_code()))
      s.lingering.emplace_back(std::chrono::steady_clock::now() + std::chrono::seconds(1), con);
    const auto it = s.ids.find(h);
    if (it == s.ids.end()) return;
    const int id = it->second;
    s.ids.erase(it);
    s.hdls.erase(id);
    if (s.handlers.on_close) s.handlers.on_close(id);
  });
  m.server.set_message_handler([this](Hdl h, Server::message_ptr msg) {
    Impl& s = *impl_;
    const auto it = s.ids.find(h);
    if (it == s.ids.end() || !s.handlers.on_message) return;
    s.handlers.on_message(it->second, msg->get_payload(), msg->get_opcode() == websocketpp::frame::opcode::binary);
  });
  m.server.set_http_handler([this](Hdl h) {
    Impl& s = *impl_;
    auto con = s.server.get_con_from_hdl(h);
    HttpRequest req{con->get_request().get_method(), con->get_resource(), con->get_request_body()};
    if (!s.handlers.on_http) {
      con->set_status(websocketpp::http::status_code::not_found);
      return;
    }
    // The answer may come later from another thread: it is handed to the I/O thread,
    // which fills in the deferred response and sends it.
    con->defer_http_response();
    auto answered = std::make_shared<std::atomic<bool>>(false);
    HttpRespond respond = [this, con, answered](HttpResponse res) {
      if (answered->exchange(true)) return;
      impl_->post([con, res = std::move(res)] {
        con->set_status(static_cast<websocketpp::http::status_code::value>(res.status));
        con->replace_header("Content-Type", res.content_type);
        con->replace_header("Cache-Control", "no-store");
        for (const auto& [k, v] : res.headers) con->replace_header(k, v);
        con->set_body(res.body);
        websocketpp::lib::error_code ec;
        con->send_http_response(ec);  // a connection closed meanwhile just drops it
      });
    };
    try {
      s.handlers.on_http(req, respond);
    } catch (const std::exception& e) {
      respond(HttpResponse{500, e.what(), "text/plain; charset=utf-8", {}});
    }
  });
}

WebServer::~WebServer() = default;

int WebServer::listen(const std::string& host, int port) {
  Impl& m = *impl_;
  asio::error_code aec;
  const auto address = asio::ip::make_address(host, aec);
  if (aec) throw std::runtime_error("'" + host + "' is not an IP address");
  websocketpp::lib::error_code ec;
  m.server.listen(asio::ip::tcp::endpoint(address, static_cast<unsigned short>(port)), ec);
  if (ec) throw std::runtime_error("cannot listen on " + host + ":" + std::to_string(port) + ": " + ec.message());
  m.server.start_accept(ec);
  if (ec) throw std::runtime_error("cannot accept on " + host + ":" + std::to_string(port) + ": " + ec.message());
  return m.server.get_local_endpoint(aec).port();
}

void WebServer::run() {
  Impl& m = *impl_;
  m.signals = std::make_unique<asio::signal_set>(m.server.get_io_service(), SIGINT, SIGTERM);
  m.signals->async_wait([this](const asio::error_code& ec, int) {
    if (!ec) stop();
  });
  m.schedule_tick();
  m.server.run();
}

void WebServer::stop() {
  Impl& m = *impl_;
  if (m.stopping) return;
  m.stopping = true;
  websocketpp::lib::error_code ec;
  m.server.stop_listening(ec);
  for (const auto& [id, h] : m.hdls) m.server.close(h, websocketpp::close::status::going_away, "server stopping", ec);
  if (m.signals) m.signals->cancel();
  // Give the close handshakes a moment, then end run() whatever is left.
  m.server.set_timer(500, [this](const websocketpp::lib::error_code&) { impl_->server.stop(); });
}

void WebServer::send_text(int client, std::string text) {
  impl_->post([this, client, text = std::move(text)] { impl_->send(client, text, websocketpp::frame::opcode::text); });
}
void WebServer::send_binary(int client, std::string bytes) {
  impl_->post(
      [this, client, bytes = std::move(bytes)] { impl_->send(client, bytes, websocketpp::frame::opcode::binary); });
}
void WebServer::post(std::function<void()> fn) {
  impl_->post(std::move(fn));
}

}  // namespace meshpde::net
