// The browser editor's server (`meshpde serve` starts it). One HTTP and WebSocket port
// (web_server.h: websocketpp on standalone asio, one I/O thread): the page and its scripts from
// the web root, uploads and downloads under /api, and per page a WebSocket whose
// EditorSession (meshpde/editor/editor_session.h) does the numerics. A 60 Hz timer sends each
// page only what changed: binary frames of moved vertices and, when a field changes,
// its values, plus a small JSON stats message. The haptic probe runs at 1 kHz on
// its own thread inside the session.
//
// Threads: the I/O thread only parses, queues and sends. Each page has a worker
// thread of its own (PageWorker) that runs everything touching its session, in order:
// its requests, its uploads and saves, and its frames (one frame queued at a time, so
// a slow page skips frames instead of piling them up). A correction of several hundred
// milliseconds on one page therefore delays only that page. Limits per connection
// (docs/editor.md): messages of at most 1 MiB (a larger one closes the connection with
// status 1009), kMessagesPerSecond messages a second (more are dropped with an error to
// that page), kMaxQueued requests waiting, and an HTTP request or handshake must be
// complete within 10 s.
//
// A page's protocol (its requests, frames, uploads and saves; the wire format) is
// editor_page.h's EditorPage.
#include "editor_server.h"

#include <fmt/format.h>
#include <malloc.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <thread>

#include "editor_page.h"
#include "meshpde/core/errors.h"
#include "meshpde/image/volume.h"
#include "meshpde/mesh/units.h"
#include "web_server.h"

namespace meshpde::editor {
namespace {

using Hdl = int;  // a page's connection id
namespace fs = std::filesystem;

// Percent-decodes a URL path; nullopt for malformed escapes or a NUL byte.
std::optional<std::string> url_decode(const std::string& s) {
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] != '%') {
      out += s[i];
      continue;
    }
    if (i + 2 >= s.size() || !std::isxdigit(static_cast<unsigned char>(s[i + 1])) ||
        !std::isxdigit(static_cast<unsigned char>(s[i + 2])))
      return std::nullopt;
    const char c = static_cast<char>(std::stoi(s.substr(i + 1, 2), nullptr, 16));
    if (c == '\0') return std::nullopt;
    out += c;
    i += 2;
  }
  return out;
}

std::map<std::string, std::string> query_params(const std::string& query) {
  std::map<std::string, std::string> q;
  std::stringstream ss(query);
  std::string item;
  while (std::getline(ss, item, '&')) {
    const auto eq = item.find('=');
    const auto key = url_decode(item.substr(0, eq));
    const auto value = url_decode(eq == std::string::npos ? "" : item.substr(eq + 1));
    if (key && value) q[*key] = *value;
  }
  return q;
}

// The file under `root` that a request path names, or nullopt when the path is
// malformed or would leave the root (.., absolute, backslashes, encoded variants:
// the check runs on the decoded path and again on the canonical result).
std::optional<fs::path> static_file(const fs::path& root, const std::string& raw_path) {
  const auto decoded = url_decode(raw_path);
  if (!decoded || decoded->empty() || (*decoded)[0] != '/') return std::nullopt;
  std::string rel = decoded->substr(1);
  if (rel.empty()) rel = "index.html";
  if (rel.find('\\') != std::string::npos || rel[0] == '/') return std::nullopt;
  for (const auto& part : fs::path(rel))
    if (part == ".." || part == ".") return std::nullopt;
  std::error_code ec;
  const fs::path base = fs::canonical(root, ec);
  if (ec) return std::nullopt;
  const fs::path full = fs::weakly_canonical(base / rel, ec);
  if (ec) return std::nullopt;
  const std::string b = base.string() + "/", f = full.string();
  if (f.compare(0, b.size(), b) != 0) return std::nullopt;
  if (!fs::is_regular_file(full, ec)) return std::nullopt;
  return full;
}

std::string content_type(const fs::path& p) {
  const std::string e = p.extension().string();
  if (e == ".html") return "text/html; charset=utf-8";
  if (e == ".js" || e == ".mjs") return "text/javascript; charset=utf-8";
  if (e == ".css") return "text/css; charset=utf-8";
  if (e == ".png") return "image/png";
  if (e == ".json") return "application/json";
  if (e == ".svg") return "image/svg+xml";
  return "application/octet-stream";
}

// A page's own thread: runs its tasks one after another, in the order queued.
class PageWorker {
 public:
  PageWorker() : thread_([this] { loop(); }) {}
  ~PageWorker() {
    close();
    thread_.join();
  }
  PageWorker(const PageWorker&) = delete;
  PageWorker& operator=(const PageWorker&) = delete;

  /// Queues a task; false when closed or when `limit` tasks are already waiting.
  bool post(std::function<void()> task, std::size_t limit) {
    {
      std::lock_guard lock(m_);
      if (closed_ || q_.size() >= limit) return false;
      q_.push_back(std::move(task));
    }
    cv_.notify_one();
    return true;
  }
  /// No more tasks: the running one finishes, the waiting ones are dropped.
  void close() {
    {
      std::lock_guard lock(m_);
      closed_ = true;
      q_.clear();
    }
    cv_.notify_one();
  }
  bool finished() const { return finished_; }

 private:
  void loop() {
    for (;;) {
      std::function<void()> task;
      {
        std::unique_lock lock(m_);
        cv_.wait(lock, [&] { return closed_ || !q_.empty(); });
        if (closed_) break;
        task = std::move(q_.front());
        q_.pop_front();
      }
      try {
        task();  // tasks catch and report their own errors; this is the last guard
      } catch (const std::exception& e) {
        fmt::print(stderr, "meshpde serve: a page's task failed: {}\n", e.what());
      }
    }
    finished_ = true;
  }

  std::mutex m_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> q_;
  bool closed_ = false;
  std::atomic<bool> finished_{false};
  std::thread thread_;  // last: starts once the rest is built
};

// Messages a second one connection may send (a token bucket of this many, refilled
// at this rate); requests waiting on one page's worker.
constexpr double kMessagesPerSecond = 500;
constexpr std::size_t kMaxQueued = 256;

// The I/O thread's record of a page: its worker, its rate limit and whether a frame
// is already queued. The EditorPage itself is touched only by the worker.
struct Page {
  std::shared_ptr<EditorPage> editor;
  std::unique_ptr<PageWorker> worker;
  std::shared_ptr<std::atomic<bool>> frame_queued = std::make_shared<std::atomic<bool>>(false);
  double tokens = kMessagesPerSecond;
  std::chrono::steady_clock::time_point refilled = std::chrono::steady_clock::now();
  long long dropped = 0;
  std::chrono::steady_clock::time_point last_drop_report{};
};

class EditorServer {
 public:
  explicit EditorServer(const EditorServerOptions& a)
      : args_(a),
        server_(net::WebHandlers{.on_open = [this](int h) { on_open(h); },
                                 .on_close = [this](int h) { on_close(h); },
                                 .on_message = [this](int h, const std::string& payload,
                                                      bool binary) { on_message(h, payload, binary); },
                                 .on_http = [this](const net::HttpRequest& r,
                                                   net::HttpRespond respond) { on_http(r, std::move(respond)); },
                                 .on_tick = [this] { on_tick(); }},
                static_cast<std::size_t>(a.max_upload_mb * 1024 * 1024), 1 << 20, 16) {
    web_root_ = a.web_root;
    if (!fs::exists(web_root_ / "index.html"))
      throw InputError(
          fmt::format("{}: no index.html (build the page: npm --prefix web ci && npm --prefix web run "
                      "build, or pass --web-root)",
                      web_root_.string()));
    units_ = parse_length_unit(a.units);
    if (!a.segmentation.empty()) {
      if (!a.mesh.empty()) throw InputError("give a MESH or --segmentation, not both");
      if (units_ != LengthUnit::Millimetre)
        throw InputError("--units goes with a MESH: a segmentation's surface is made in millimetres");
      segmentation_ = load_editor_segmentation(a.segmentation, a.segment, a.overwrite);
      initial_ = segmentation_surface(*segmentation_);  // in LPS, as its space says
    } else if (!a.mesh.empty() && is_session_file(a.mesh)) {
      // A saved session: each page reopens it. Opened once here, so that a damaged file
      // is refused at the start rather than on every page.
      std::ifstream in(a.mesh, std::ios::binary);
      if (!in) throw InputError(fmt::format("{}: cannot open", a.mesh));
      std::ostringstream bytes;
      bytes << in.rdbuf();
      initial_session_ = bytes.str();
      initial_session_name_ = fs::path(a.mesh).filename().string();
      EditorPage check(PageSink{.text = [](std::string) {}, .binary = [](std::string) {}}, nullptr, Space::LPS);
      check.open_session(initial_session_, initial_session_name_);
    } else if (!a.mesh.empty()) {
      initial_.data = read_mesh(a.mesh);
      initial_.name = fs::path(a.mesh).filename().string();
      initial_.units = units_;
      // Warned here as well as on the page: the terminal is where the user typed it.
      const std::string warning =
          units_warning(Mesh(initial_.data.V, initial_.data.F), units_, initial_.name, "--units ");
      if (!warning.empty()) fmt::print(stderr, "warning: {}\n", warning);
    } else {
      initial_ = generated("dented");
    }
    if (segmentation_ == nullptr && (!a.segment.empty() || a.overwrite))
      throw InputError("--segment and --overwrite go with --segmentation");
    space_ = !a.space.empty() ? parse_space(a.space) : initial_.data.space == "RAS" ? Space::RAS : Space::LPS;
    laplacian_ = parse_laplacian_kind(a.laplacian);
    if (!a.image.empty()) image_ = load_editor_image(a.image, a.series);
  }

  // Runs until SIGINT or SIGTERM.
  void run() {
    int port = 0;
    try {
      port = server_.listen(args_.host, args_.port);
    } catch (const std::runtime_error& e) {
      throw InputError(e.what());
    }
    fmt::print("meshpde editor: http://{}:{}/  (Ctrl-C to stop)\n", args_.host, port);
    if (args_.host != "127.0.0.1" && args_.host != "::1" && args_.host != "localhost")
      fmt::print(stderr,
                 "warning: the editor has no authentication: anyone who can reach {}:{} can open, edit and "
                 "download meshes. Serve on loopback or a trusted network only.\n",
                 args_.host, port);
    std::fflush(stdout);
    server_.run();
    pages_.clear();  // joins the workers before the server goes
    retired_.clear();
    fmt::print("meshpde editor: stopped\n");
  }

 private:
  // User text (file names, error messages quoting them) need not be UTF-8: bad bytes
  // are sent as U+FFFD instead of making dump() throw.
  static std::string dump(const nlohmann::json& j) {
    return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  }
  void send_json(Hdl h, const nlohmann::json& j) { server_.send_text(h, dump(j)); }

  void on_open(Hdl h) {
    Page page;
    page.editor = std::make_shared<EditorPage>(
        PageSink{.text = [this, h](std::string s) { server_.send_text(h, std::move(s)); },
                 .binary = [this, h](std::string s) { server_.send_binary(h, std::move(s)); }},
        image_, space_, laplacian_, segmentation_, units_);
    page.worker = std::make_unique<PageWorker>();
    send_json(h, {{"type", "hello"}, {"client", h}});
    EditorPage* c = page.editor.get();
    page.worker->post(
        [this, h, c] {
          try {
            if (initial_session_.empty())
              c->load(initial_);
            else
              c->open_session(initial_session_, initial_session_name_);
          } catch (const std::exception& e) {
            send_json(h, {{"type", "error"}, {"message", e.what()}});
          }
        },
        kMaxQueued);
    pages_.emplace(h, std::move(page));
  }

  // The page's worker finishes what it is doing on its own; it is joined from a
  // later tick, so a closing page never holds up the I/O thread.
  void on_close(Hdl h) {
    const auto it = pages_.find(h);
    if (it == pages_.end()) return;
    it->second.worker->close();
    retired_.push_back(std::move(it->second));
    pages_.erase(it);
  }

  // Whether one more message from this page fits its rate; tells the page (at most
  // once a second) how many were dropped.
  bool within_rate(Hdl h, Page& p) {
    const auto now = std::chrono::steady_clock::now();
    p.tokens = std::min(kMessagesPerSecond,
                        p.tokens + kMessagesPerSecond * std::chrono::duration<double>(now - p.refilled).count());
    p.refilled = now;
    if (p.tokens >= 1) {
      p.tokens -= 1;
      return true;
    }
    ++p.dropped;
    if (now - p.last_drop_report >= std::chrono::seconds(1)) {
      p.last_drop_report = now;
      send_json(h, {{"type", "error"},
                    {"request", "?"},
                    {"message", fmt::format("rate limit: more than {} messages a second; {} dropped",
                                            kMessagesPerSecond, p.dropped)}});
    }
    return false;
  }

  void on_message(Hdl h, const std::string& payload, bool binary) {
    const auto it = pages_.find(h);
    if (it == pages_.end()) return;
    Page& p = it->second;
    if (!within_rate(h, p)) return;
    EditorPage* c = p.editor.get();
    if (!p.worker->post([c, payload, binary] { c->handle(payload, binary); }, kMaxQueued))
      send_json(h,
                {{"type", "error"},
                 {"request", "?"},
                 {"message", fmt::format("busy: {} requests are already waiting; this one was dropped", kMaxQueued)}});
  }

  void on_tick() {
    for (auto& [h, p] : pages_) {
      if (p.frame_queued->exchange(true)) continue;  // the last one has not run yet
      EditorPage* c = p.editor.get();
      auto queued = p.frame_queued;
      const Hdl hh = h;
      const bool ok = p.worker->post(
          [this, hh, c, queued] {
            queued->store(false);
            try {
              c->frame();
            } catch (const std::exception& e) {
              send_json(hh, {{"type", "error"}, {"message", e.what()}});
            }
          },
          kMaxQueued + 1);
      if (!ok) p.frame_queued->store(false);
    }
    // Closed pages whose worker has finished: joined now, without waiting. Their
    // sessions were allocated on the worker threads, in glibc arenas of their own;
    // trimming hands the freed pages back, so the server's memory returns to where it
    // was after pages come and go.
    if (std::erase_if(retired_, [](const Page& p) { return p.worker->finished(); }) > 0) malloc_trim(0);
  }

  static net::HttpResponse json_response(int status, const nlohmann::json& j) {
    return net::HttpResponse{status, dump(j), "application/json", {}};
  }

  // The page's record for a ?client= id, or null.
  Page* find_page(const std::map<std::string, std::string>& query, Hdl& h) {
    if (!query.count("client")) return nullptr;
    h = std::atoi(query.at("client").c_str());
    const auto it = pages_.find(h);
    return it == pages_.end() ? nullptr : &it->second;
  }

  void on_http(const net::HttpRequest& req, net::HttpRespond respond) {
    const auto qpos = req.resource.find('?');
    const std::string path = req.resource.substr(0, qpos);
    const auto query = query_params(qpos == std::string::npos ? "" : req.resource.substr(qpos + 1));
    try {
      if (path == "/api/upload" || path == "/api/save" || path == "/api/session") {
        const bool upload = path == "/api/upload", session = path == "/api/session";
        if (upload && req.method != "POST") return respond(json_response(405, {{"error", "POST the file"}}));
        if (session && req.method != "POST")
          return respond(json_response(405, {{"error", "POST the page's settings (a JSON object)"}}));
        Hdl h = 0;
        Page* p = find_page(query, h);
        if (!p) return respond(json_response(400, {{"error", "unknown client"}}));
        // Parsing, loading and saving run on the page's worker, in order with its
        // requests; the answer is sent from there.
        EditorPage* c = p->editor.get();
        SaveOptions save_options;
        if (query.count("format")) save_options.format = query.at("format");
        save_options.displacement = query.count("displacement") && query.at("displacement") == "1";
        auto task = [c, upload, session, respond, body = req.body, save_options,
                     name = query.count("name") ? query.at("name") : std::string("upload.ply")] {
          try {
            if (upload && is_volume_upload(name)) {
              c->upload_image(body, name);
              respond(json_response(200, {{"ok", true}, {"image", name}}));
            } else if (upload) {
              const int vertices = c->upload(body, name);
              respond(json_response(200, {{"ok", true}, {"vertices", vertices}}));
            } else {
              auto [bytes, filename] = session ? c->save_session(body) : c->save(save_options);
              net::HttpResponse r{200, std::move(bytes), "application/octet-stream", {}};
              r.headers.emplace_back("Content-Disposition", fmt::format("attachment; filename=\"{}\"", filename));
              respond(std::move(r));
            }
          } catch (const std::exception& e) {
            respond(json_response(400, {{"error", e.what()}}));
          }
        };
        if (!p->worker->post(std::move(task), kMaxQueued))
          respond(json_response(503, {{"error", "busy: too many requests waiting"}}));
        return;
      }
      if (req.method != "GET" && req.method != "HEAD") return respond(json_response(405, {{"error", "GET only"}}));
      const auto file = static_file(web_root_, path);
      if (!file) return respond(net::HttpResponse{404, "not found", "text/plain; charset=utf-8", {}});
      std::ifstream in(*file, std::ios::binary);
      std::ostringstream ss;
      ss << in.rdbuf();
      respond(net::HttpResponse{200, ss.str(), content_type(*file), {}});
    } catch (const std::exception& e) {
      respond(json_response(400, {{"error", e.what()}}));
    }
  }

  EditorServerOptions args_;
  net::WebServer server_;
  fs::path web_root_;
  Loaded initial_;
  std::string initial_session_, initial_session_name_;  // a saved session each page opens
  Space space_ = Space::LPS;
  LengthUnit units_ = LengthUnit::Millimetre;
  LaplacianKind laplacian_ = LaplacianKind::Auto;
  std::shared_ptr<const EditorImage> image_;
  std::shared_ptr<const EditorSegmentation> segmentation_;
  std::map<Hdl, Page> pages_;  // the I/O thread's
  std::vector<Page> retired_;  // closed, their workers finishing
};

}  // namespace

// The built page: installed beside the tool (found from the executable's own path),
// else the source tree's web/dist this binary was built from.
std::string default_web_root() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed = (exe.parent_path() / MESHPDE_INSTALLED_WEB_ROOT_FROM_BINDIR).lexically_normal();
    if (fs::exists(installed / "index.html", ec)) return installed.string();
  }
  return MESHPDE_WEB_ROOT;
}

void serve(const EditorServerOptions& options) {
  if (options.port < 0 || options.port > 65535)
    throw InputError(fmt::format("port {} is outside 0..65535", options.port));
  EditorServer server(options);
  server.run();
}

}  // namespace meshpde::editor
