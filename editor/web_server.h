// A small HTTP + WebSocket server on one port, for meshpde serve.
//
// It wraps websocketpp (standalone asio) behind plain types: websocketpp 0.8 does
// not compile as C++20, so web_server.cpp is the one translation unit built as
// C++17, and this header uses nothing newer. Every callback runs on the server's
// single I/O thread, so handlers need no locking among themselves; long work belongs
// on other threads, which hand results back through post(), send_text(),
// send_binary() and an HTTP request's `respond` (all safe from any thread).
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace meshpde::net {

struct HttpRequest {
  std::string method;    ///< GET, POST, ...
  std::string resource;  ///< path and query, as sent (still percent-encoded)
  std::string body;
};

struct HttpResponse {
  int status = 200;
  std::string body;
  std::string content_type = "text/plain; charset=utf-8";
  std::vector<std::pair<std::string, std::string>> headers;
};

/// Answers an HTTP request, now or later, from any thread (once).
using HttpRespond = std::function<void(HttpResponse)>;

struct WebHandlers {
  std::function<void(int client)> on_open;
  std::function<void(int client)> on_close;
  std::function<void(int client, const std::string& payload, bool binary)> on_message;
  std::function<void(const HttpRequest&, HttpRespond respond)> on_http;
  std::function<void()> on_tick;  ///< every tick_ms while running
};

class WebServer {
 public:
  /// max_body: the largest HTTP body accepted (larger requests get 413);
  /// max_message: the largest WebSocket message accepted (a larger one closes that
  /// connection with status 1009, "message too big"); request_timeout_ms: an HTTP
  /// request or WebSocket handshake not complete by then is dropped.
  WebServer(WebHandlers handlers, std::size_t max_body, std::size_t max_message, int tick_ms,
            long request_timeout_ms = 10000);
  ~WebServer();
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  /// Binds; returns the port (useful with port 0). \throw std::runtime_error.
  int listen(const std::string& host, int port);
  /// Serves until stop(), SIGINT or SIGTERM.
  void run();
  /// Closes every connection and makes run() return (call from a handler).
  void stop();

  /// Queue a frame to a page (dropped if it has gone). Safe from any thread.
  void send_text(int client, std::string text);
  void send_binary(int client, std::string bytes);
  /// Runs fn on the I/O thread. Safe from any thread.
  void post(std::function<void()> fn);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace meshpde::net
