// meshpde serve: the browser editor's server. One HTTP and WebSocket port
// (web_server.h: websocketpp on standalone asio, one I/O thread): the page and its scripts from
// the web root, uploads and downloads under /api, and per page a WebSocket whose
// EditorSession (apps/editor_session.h) does the numerics. A 60 Hz timer sends each
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
// Wire format (little-endian): every binary frame starts with a four-byte tag.
//   "MESH" u32 nv, u32 nf, f32 positions[3 nv], u32 triangles[3 nf]
//   "POS " u32 n, u32 ids[n], f32 positions[3 n]
//   "FLD " u32 nv, f32 values[nv]
//   "VEC " u32 n, u32 ids[n], f32 vectors[3 n]   (arrows; n = 0 clears them)
// Text frames are JSON objects with a "type" (see docs/editor.md).
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
#include <optional>
#include <sstream>
#include <thread>

#include "commands.h"
#include "meshpde/apps/editor_session.h"
#include "meshpde/apps/local_drag.h"
#include "meshpde/core/errors.h"
#include "meshpde/image/volume.h"
#include "meshpde/mesh/generators.h"
#include "web_server.h"
#ifdef MESHPDE_HAVE_MEDICAL
#include "meshpde/io/medical_io.h"
#endif

namespace meshpde::cli {
namespace {

using Hdl = int;  // a page's connection id
namespace fs = std::filesystem;

struct ServeArgs {
  std::string mesh, host = "127.0.0.1", image, space, web_root;
  int port = 8080;
  double max_upload_mb = 64;
};

// A mesh with the name and format it came in, so saving writes the same format.
struct Loaded {
  MeshData data;
  std::string name = "mesh.ply";
};

std::string lower_ext(const std::string& name) {
  std::string ext = fs::path(name).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

Loaded parse_mesh_bytes(const std::string& bytes, const std::string& name) {
  Loaded l;
  l.name = fs::path(name).filename().string();
  const std::string ext = lower_ext(l.name);
  if (ext == ".vtp" || ext == ".vtk") {
#ifdef MESHPDE_HAVE_MEDICAL
    l.data = read_vtk_mesh_from_memory(bytes, ext.substr(1), l.name);
#else
    throw InputError(fmt::format("{}: .vtp/.vtk need meshpde built with meshpde::medical", l.name));
#endif
  } else {
    l.data = read_mesh_from_memory(bytes, format_from_path(l.name), l.name);
  }
  return l;
}

std::string mesh_bytes(const MeshData& d, const std::string& name) {
  const std::string ext = lower_ext(name);
  if (ext == ".vtp" || ext == ".vtk") {
#ifdef MESHPDE_HAVE_MEDICAL
    return write_vtk_mesh_to_memory(d, ext.substr(1));
#else
    throw InputError("saving .vtp/.vtk needs meshpde::medical");
#endif
  }
  return write_mesh_to_memory(d, format_from_path(name));
}

// The editor's "open" menu: the library's generator table (mesh/generators.h) with
// presets sized for a vessel-scale view, plus "dented" (the bifurcation with its dent).
Loaded generated(const std::string& requested) {
  Loaded l;
  const std::string kind = requested == "dented" ? "bifurcation" : requested == "sphere" ? "icosphere" : requested;
  GeneratorParams p;
  p.bifurcation = BifurcationParams{};
  p.bifurcation.dent = requested == "dented";
  p.level = 4;  // icosphere: 2,562 vertices
  p.radius = kind == "tube" ? 4.0 : 10.0;
  p.length = 40.0;
  p.rings = 60;
  p.segments = 40;
  p.nx = p.ny = 60;
  p.size = 30.0;
  const GeneratedMesh g = generate(kind, p);
  l.name = (requested == "dented" ? "dented-" : "") + kind + ".ply";
  l.data.V = g.V;
  l.data.F = g.F;
  return l;
}

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

template <class T>
void put(std::string& s, T v) {
  s.append(reinterpret_cast<const char*>(&v), sizeof(T));
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
      task();  // tasks catch their own errors
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
// is already queued. The Client itself is touched only by the worker.
struct Client;
struct Page {
  std::shared_ptr<Client> client;
  std::unique_ptr<PageWorker> worker;
  std::shared_ptr<std::atomic<bool>> frame_queued = std::make_shared<std::atomic<bool>>(false);
  double tokens = kMessagesPerSecond;
  std::chrono::steady_clock::time_point refilled = std::chrono::steady_clock::now();
  long long dropped = 0;
  std::chrono::steady_clock::time_point last_drop_report{};
};

struct Client {
  int id = 0;
  Loaded source;
  std::unique_ptr<EditorSession> session;
  Positions sent;                 // positions as the page has them
  Eigen::VectorXd sent_field;     // field as the page has it
  Eigen::MatrixX3d sent_vectors;  // vector field as the page has it
  std::string sent_field_name;
  Eigen::VectorXd stiffness;  // the page's stiffness brush (empty: uniform)
  int intersections = 0;
  double frame_ms = 0;  // time to build the last frame
  std::chrono::steady_clock::time_point last_stats{};
};

class EditorServer {
 public:
  EditorServer(const ServeArgs& a)
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
    if (!a.mesh.empty()) {
      initial_.data = read_mesh_file(a.mesh);
      initial_.name = fs::path(a.mesh).filename().string();
    } else {
      initial_ = generated("dented");
    }
    space_ = mesh_space(a.space, initial_.data);
    if (!a.image.empty()) {
#ifdef MESHPDE_HAVE_MEDICAL
      edges_ = std::make_shared<const Volume>(gradient_magnitude(read_volume(a.image), 1.0));
#else
      throw InputError("--image needs meshpde built with meshpde::medical");
#endif
    }
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
  void send_json(Hdl h, const nlohmann::json& j) {
    server_.send_text(h, j.dump());
  }
  void send_binary(Hdl h, const std::string& bytes) {
    server_.send_binary(h, bytes);
  }

  void load(Hdl h, Client& c, Loaded l) {
    c.session = std::make_unique<EditorSession>(l.data, edges_, space_);
    c.source = std::move(l);
    c.stiffness.resize(0);
    c.intersections = 0;
    const Mesh& m = c.session->mesh();
    send_json(h, {{"type", "mesh"},
                  {"name", c.source.name},
                  {"vertices", m.num_vertices()},
                  {"faces", m.num_faces()},
                  {"mean_edge", c.session->mean_edge_length()},
                  {"has_image", c.session->has_image()},
                  {"fields", [&] {
                     std::vector<std::string> names;
                     for (const auto& [k, v] : c.source.data.vertex_scalars) names.push_back(k);
                     return names;
                   }()}});
    std::string b = "MESH";
    put<std::uint32_t>(b, static_cast<std::uint32_t>(m.num_vertices()));
    put<std::uint32_t>(b, static_cast<std::uint32_t>(m.num_faces()));
    for (int i = 0; i < m.num_vertices(); ++i)
      for (int k = 0; k < 3; ++k) put<float>(b, static_cast<float>(m.positions()(i, k)));
    for (int f = 0; f < m.num_faces(); ++f)
      for (int k = 0; k < 3; ++k) put<std::uint32_t>(b, static_cast<std::uint32_t>(m.triangles()(f, k)));
    send_binary(h, b);
    c.sent = m.positions();
    c.sent_vectors.resize(0, 3);
    c.sent_field.resize(0);
    c.sent_field_name.clear();
  }

  void on_open(Hdl h) {
    Page page;
    page.client = std::make_shared<Client>();
    page.client->id = h;
    page.worker = std::make_unique<PageWorker>();
    send_json(h, {{"type", "hello"}, {"client", h}});
    Client* c = page.client.get();
    page.worker->post(
        [this, h, c] {
          try {
            load(h, *c, initial_);
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

  static Eigen::Vector3d vec3(const nlohmann::json& j, const char* key) {
    if (!j.contains(key) || !j[key].is_array() || j[key].size() != 3)
      throw InputError(fmt::format("'{}' must be an array of three numbers", key));
    Eigen::Vector3d v;
    for (int k = 0; k < 3; ++k) {
      if (!j[key][k].is_number()) throw InputError(fmt::format("'{}' must hold numbers", key));
      v[k] = j[key][k].get<double>();
    }
    if (!v.allFinite()) throw InputError(fmt::format("'{}' is not finite", key));
    return v;
  }
  static int vertex_of(const nlohmann::json& j) {
    if (!j.contains("vertex") || !j["vertex"].is_number_integer()) throw InputError("'vertex' must be an integer");
    return j["vertex"].get<int>();
  }
  static double number(const nlohmann::json& j, const char* key, double fallback) {
    if (!j.contains(key)) return fallback;
    if (!j[key].is_number()) throw InputError(fmt::format("'{}' must be a number", key));
    return j[key].get<double>();
  }

  void on_message(Hdl h, const std::string& payload, bool binary) {
    const auto it = pages_.find(h);
    if (it == pages_.end()) return;
    Page& p = it->second;
    if (!within_rate(h, p)) return;
    Client* c = p.client.get();
    if (!p.worker->post([this, h, c, payload, binary] { handle(h, *c, payload, binary); }, kMaxQueued))
      send_json(h,
                {{"type", "error"},
                 {"request", "?"},
                 {"message", fmt::format("busy: {} requests are already waiting; this one was dropped", kMaxQueued)}});
  }

  // One request of a page, on its worker.
  void handle(Hdl h, Client& c, const std::string& payload, bool binary) {
    std::string type = "?";
    try {
      if (binary) throw InputError("expected a JSON text message");
      const auto j = nlohmann::json::parse(payload, nullptr, false);
      if (j.is_discarded() || !j.is_object()) throw InputError("malformed message: not a JSON object");
      if (!j.contains("type") || !j["type"].is_string()) throw InputError("malformed message: no \"type\"");
      type = j["type"].get<std::string>();
      if (!c.session && type != "generate") throw InputError("no mesh loaded");
      nlohmann::json reply = {{"type", "ok"}, {"request", type}};
      EditorSession& s = *c.session;
      if (type == "generate") {
        const std::string kind = j.value("kind", std::string("dented"));
        load(h, c, generated(kind));
      } else if (type == "poke_begin") {
        s.poke_begin(vertex_of(j), number(j, "influence", 0));
      } else if (type == "poke_move") {
        s.poke_move(vec3(j, "offset"));
        return;  // many a second: no acknowledgement
      } else if (type == "poke_end") {
        s.poke_end();
      } else if (type == "brush") {
        apply_brush(s.mesh(), c.stiffness, Brush{vertex_of(j), number(j, "radius", 3), number(j, "value", 5)});
        reply["brushed"] = true;
      } else if (type == "drag_begin") {
        const double radius = number(j, "radius", 8);
        reply["setup_ms"] = s.drag_begin(vertex_of(j), radius, c.stiffness);
        reply["region_vertices"] = s.drag_region_vertices();
      } else if (type == "drag_move") {
        // Moves after a refused drag_begin (a region too large to preview) are dropped
        // quietly: the page already showed why, and releasing still corrects.
        const Eigen::Vector3d offset = vec3(j, "offset");
        if (s.dragging()) s.drag_move(offset);
        return;  // many a second: no acknowledgement
      } else if (type == "drag_end") {
        s.drag_end();
      } else if (type == "correct") {
        CorrectionParams p;
        p.handles = {{vertex_of(j), vec3(j, "move")}};
        p.radius = number(j, "radius", 8);
        if (!(p.radius > 0)) throw InputError("radius must be > 0");
        p.method = parse_correction_method(j.value("method", std::string("fem")));
        if (p.method == CorrectionMethod::Springs) {
          p.rings = rings_for_radius(s.mesh(), p.radius);
          p.radius = 0;
        }
        p.stiffness = c.stiffness;
        if (!j.value("image", true) || p.method == CorrectionMethod::Springs) p.image.weight = 0;
        const CorrectionResult r = s.correct(p);
        c.intersections = s.self_intersections();
        reply.update({{"moved_vertices", r.moved_vertices},
                      {"new_self_intersections", r.new_self_intersections},
                      {"intersection_action", r.intersection_action},
                      {"time_ms", r.time_ms}});
      } else if (type == "undo" || type == "redo") {
        type == "undo" ? s.undo() : s.redo();
        c.intersections = s.self_intersections();
      } else if (type == "paint") {
        s.paint(vertex_of(j), number(j, "value", 1), number(j, "g1", 0), number(j, "g2", 1));
      } else if (type == "paint_vector") {
        s.paint_vector(vertex_of(j), vec3(j, "vector"), number(j, "g1", 0), number(j, "g2", 1));
      } else if (type == "clear_paint") {
        s.clear_paint();
      } else if (type == "source") {
        s.add_source(vertex_of(j));
      } else if (type == "clear_sources") {
        s.clear_sources();
      } else if (type == "play") {
        s.play(j.value("kind", std::string("heat")));
      } else if (type == "pause") {
        s.pause();
      } else if (type == "ping") {
      } else {
        throw InputError(fmt::format("unknown request '{}'", type));
      }
      send_json(h, reply);
      send_stats(h, c, true);
    } catch (const std::exception& e) {
      // The session stays usable: a bad request changes nothing.
      send_json(h, {{"type", "error"}, {"request", type}, {"message", e.what()}});
    }
  }

  void send_stats(Hdl h, Client& c, bool now) {
    const auto t = std::chrono::steady_clock::now();
    if (!now && t - c.last_stats < std::chrono::milliseconds(100)) return;
    c.last_stats = t;
    const EditorSession& s = *c.session;
    const Eigen::Vector3d f = s.poke_force();
    send_json(h, {{"type", "stats"},
                  {"force", {f.x(), f.y(), f.z()}},
                  {"contact", s.poke_contact()},
                  {"poking", s.poking()},
                  {"active", s.poking() || !s.playing() ? s.poke_active_vertices() : s.simulation_active_vertices()},
                  {"p99_us", s.poke_p99_us()},
                  {"misses", s.poke_misses()},
                  {"intersections", c.intersections},
                  {"can_undo", s.can_undo()},
                  {"can_redo", s.can_redo()},
                  {"playing", s.playing()},
                  {"solve_ms", s.last_solve_ms()},
                  {"frame_ms", c.frame_ms},
                  {"info", s.last_solve_info()}});
  }

  // One frame for one page: the vertices that moved and the field if it changed.
  void frame(Hdl h, Client& c) {
    if (!c.session) return;
    const auto t0 = std::chrono::steady_clock::now();
    EditorSession& s = *c.session;
    if (s.playing()) s.advance(2);
    const Positions V = s.display_positions();
    const double tol = 1e-6 * s.mean_edge_length();
    std::vector<int> moved;
    if (c.sent.rows() == V.rows())
      for (Eigen::Index i = 0; i < V.rows(); ++i)
        if ((V.row(i) - c.sent.row(i)).cwiseAbs().maxCoeff() > tol) moved.push_back(static_cast<int>(i));
    if (!moved.empty()) {
      std::string b = "POS ";
      put<std::uint32_t>(b, static_cast<std::uint32_t>(moved.size()));
      for (int i : moved) put<std::uint32_t>(b, static_cast<std::uint32_t>(i));
      for (int i : moved) {
        for (int k = 0; k < 3; ++k) put<float>(b, static_cast<float>(V(i, k)));
        c.sent.row(i) = V.row(i);
      }
      send_binary(h, b);
    }
    const Eigen::VectorXd& field = s.field();
    if (field.size() == V.rows() &&
        (field.size() != c.sent_field.size() || s.field_name() != c.sent_field_name || field != c.sent_field)) {
      send_json(h, {{"type", "field"}, {"name", s.field_name()}, {"min", field.minCoeff()}, {"max", field.maxCoeff()}});
      std::string b = "FLD ";
      put<std::uint32_t>(b, static_cast<std::uint32_t>(field.size()));
      for (Eigen::Index i = 0; i < field.size(); ++i) put<float>(b, static_cast<float>(field[i]));
      send_binary(h, b);
      c.sent_field = field;
      c.sent_field_name = s.field_name();
    } else if (field.size() == 0 && c.sent_field.size() != 0) {
      send_json(h, {{"type", "field"}, {"name", ""}});
      c.sent_field.resize(0);
      c.sent_field_name.clear();
    }
    // Vectors as arrows: at most about 600 of them, evenly spread over the vertex ids.
    const Eigen::MatrixX3d& vec = s.vectors();
    if (vec.rows() != c.sent_vectors.rows() || (vec.rows() && vec != c.sent_vectors)) {
      std::string b = "VEC ";
      const int n = static_cast<int>(vec.rows()), stride = std::max(1, n / 600);
      std::vector<int> ids;
      for (int i = 0; i < n; i += stride)
        if (vec.row(i).squaredNorm() > 0) ids.push_back(i);
      put<std::uint32_t>(b, static_cast<std::uint32_t>(ids.size()));
      for (int i : ids) put<std::uint32_t>(b, static_cast<std::uint32_t>(i));
      for (int i : ids)
        for (int k = 0; k < 3; ++k) put<float>(b, static_cast<float>(vec(i, k)));
      send_binary(h, b);
      c.sent_vectors = vec;
    }
    c.frame_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    send_stats(h, c, false);
  }

  void on_tick() {
    for (auto& [h, p] : pages_) {
      if (p.frame_queued->exchange(true)) continue;  // the last one has not run yet
      Client* c = p.client.get();
      auto queued = p.frame_queued;
      const Hdl hh = h;
      const bool ok = p.worker->post(
          [this, hh, c, queued] {
            queued->store(false);
            try {
              frame(hh, *c);
            } catch (const std::exception& e) {
              send_json(hh, {{"type", "error"}, {"message", e.what()}});
              if (c->session) c->session->pause();
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
    return net::HttpResponse{status, j.dump(), "application/json", {}};
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
      if (path == "/api/upload" || path == "/api/save") {
        const bool upload = path == "/api/upload";
        if (upload && req.method != "POST") return respond(json_response(405, {{"error", "POST the file"}}));
        Hdl h = 0;
        Page* p = find_page(query, h);
        if (!p) return respond(json_response(400, {{"error", "unknown client"}}));
        // Parsing, loading and saving run on the page's worker, in order with its
        // requests; the answer is sent from there.
        Client* c = p->client.get();
        auto task = [this, h, c, upload, respond, body = req.body,
                     name = query.count("name") ? query.at("name") : std::string("upload.ply")] {
          try {
            if (upload) {
              Loaded l = parse_mesh_bytes(body, name);
              const Mesh check(l.data.V, l.data.F);  // validates before the page's mesh is replaced
              load(h, *c, std::move(l));
              respond(json_response(200, {{"ok", true}, {"vertices", c->session->mesh().num_vertices()}}));
            } else {
              if (!c->session) return respond(json_response(400, {{"error", "no mesh loaded"}}));
              const fs::path n(c->source.name);
              net::HttpResponse r{
                  200, mesh_bytes(c->session->snapshot(), c->source.name), "application/octet-stream", {}};
              r.headers.emplace_back("Content-Disposition", fmt::format("attachment; filename=\"{}-edited{}\"",
                                                                        n.stem().string(), n.extension().string()));
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

  ServeArgs args_;
  net::WebServer server_;
  fs::path web_root_;
  Loaded initial_;
  Space space_ = Space::LPS;
  std::shared_ptr<const Volume> edges_;
  std::map<Hdl, Page> pages_;  // the I/O thread's
  std::vector<Page> retired_;  // closed, their workers finishing
};

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

}  // namespace

void add_serve_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("serve", "Interactive browser editor: poke, correct, paint, heat and wave, live");
  auto a = std::make_shared<ServeArgs>();
  a->web_root = default_web_root();
  cmd->add_option("MESH", a->mesh, "Mesh to open (default: a generated dented bifurcation)");
  cmd->add_option("--port", a->port, "TCP port (0: any free port)")->capture_default_str();
  cmd->add_option("--host", a->host, "Address to bind (default loopback only; 0.0.0.0 exposes the editor)")
      ->capture_default_str();
  cmd->add_option("--image", a->image, "Volume for image-guided correction (.mha .mhd .nii .nii.gz .nrrd .nhdr)");
  cmd->add_option("--space", a->space, "Frame of the mesh coordinates: lps | ras");
  cmd->add_option("--web-root", a->web_root, "Folder with the built page")->capture_default_str();
  cmd->add_option("--max-upload-mb", a->max_upload_mb, "Largest accepted upload")->capture_default_str();
  cmd->callback([a] {
    if (a->port < 0 || a->port > 65535) throw InputError(fmt::format("--port {} is outside 0..65535", a->port));
    EditorServer server(*a);
    server.run();
  });
}

}  // namespace meshpde::cli
