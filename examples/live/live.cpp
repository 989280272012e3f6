// The live demo's server (examples/live/README.md): runs a surgical scene in real time in its own
// thread and serves, on 127.0.0.1 only, the page (web/), three.js (node_modules/three) and:
//
//   GET  /frame     the surface's vertex positions and normals at the last committed step, with a
//                   status block (binary, little-endian; layout below), polled by the page at its
//                   frame rate
//   GET  /topology  the triangles (binary), fetched again only when a cut or a tear changed them
//   GET  /status    the status as JSON (scene, mode, times, the last error)
//   POST /command   one JSON command: grasp, move, release, cut, scene, reset, mode, save
//
// HTTP/1.1 keep-alive requests rather than a WebSocket: the page asks for a frame when it can
// draw one (no queue builds up behind a slow client), a reload or a second page needs no
// session, and cpp-httplib (Debian's libcpp-httplib-dev) is the one library it takes. On the
// loopback a frame request costs about a tenth of a millisecond plus the copy.
//
// Commands are checked when they arrive (a malformed one gets 400 and a reason, and changes
// nothing) and applied by the simulation thread between steps, so the network never waits for a
// step; the reply comes when the command has been applied (or fails: 409 and why). A step that
// fails leaves the state as it was (the library's guarantee): the grasp is let go, the page keeps
// the last good frame and shows the error. The server writes only into --out (the save command).
//
//   live [--port N] [--scene organ|fat|sheet] [--mode realtime|accurate] [--threads N] [--dt S]
//        [--out DIR] [--web DIR] [--three DIR] [--seconds S]
#include "live_scenes.hpp"

#include <httplib.h>
#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstring>
#include <deque>
#include <filesystem>
#include <functional>
#include <future>
#include <mutex>
#include <thread>

#ifndef PLASTIFEM_LIVE_DIR
#define PLASTIFEM_LIVE_DIR "."
#endif

using json = nlohmann::json;
using namespace plastifem;

namespace {

/// /frame's layout: 16 bytes of uint32 {magic "PFLV", topology version, vertices, frame number},
/// 48 bytes of float32 status, then float32 x, y, z per vertex, then float32 normals.
constexpr std::uint32_t frame_magic = 0x564c4650;  // "PFLV"
enum StatusField : int { kTime, kStepMs, kDofs, kRealTime, kFx, kFy, kFz, kGrasping, kSpeed, kFailed, kStepsPerS, kSpare };
constexpr int status_floats = 12;

/// A command, checked: what the simulation thread applies.
struct Command {
  enum Kind { Grasp, Move, Release, Cut, Scene, Reset, Mode, Save } kind;
  Vec3 point = Vec3::Zero();                  // grasp: where; move: the target
  std::vector<std::pair<Index, Vec3>> stroke;  // cut: (triangle, barycentric) per point
  Vec3 direction = Vec3::Zero();              // cut: the view direction
  std::uint32_t topology = 0;                 // cut: the triangles the stroke was drawn on
  bool open_start = false, open_end = false;  // cut: the stroke began / ended off the tissue
  std::string name;                           // scene
  NewmarkMode mode = NewmarkMode::RealTime;
  std::promise<json> done;
};

/// Bad input from a client: 400 and the message.
struct BadCommand : std::runtime_error {
  using std::runtime_error::runtime_error;
};

Vec3 vec3_of(const json& j, const char* what) {
  if (!j.is_array() || j.size() != 3) throw BadCommand(fmt::format("'{}' must be an array of 3 numbers", what));
  Vec3 v;
  for (int d = 0; d < 3; ++d) {
    if (!j[static_cast<size_t>(d)].is_number()) throw BadCommand(fmt::format("'{}' must be an array of 3 numbers", what));
    v[d] = j[static_cast<size_t>(d)].get<double>();
  }
  // Positions are in metres; a scene is centimetres across: beyond 10 m is an error, not a drag.
  if (!v.allFinite() || v.cwiseAbs().maxCoeff() > 10)
    throw BadCommand(fmt::format("'{}' must be finite and within 10 m of the origin", what));
  return v;
}

/// Parses and checks one command (throws BadCommand).
std::unique_ptr<Command> parse_command(const std::string& body) {
  json j;
  try {
    j = json::parse(body);
  } catch (const json::exception& e) {  // parse_error, or out_of_range for 1e400
    throw BadCommand(fmt::format("not JSON: {}", e.what()));
  }
  if (!j.is_object() || !j.contains("cmd") || !j["cmd"].is_string())
    throw BadCommand("a command is a JSON object with a string 'cmd'");
  auto c = std::make_unique<Command>();
  const std::string cmd = j["cmd"];
  if (cmd == "grasp") c->kind = Command::Grasp, c->point = vec3_of(j.value("point", json()), "point");
  else if (cmd == "move") c->kind = Command::Move, c->point = vec3_of(j.value("target", json()), "target");
  else if (cmd == "release") c->kind = Command::Release;
  else if (cmd == "reset") c->kind = Command::Reset;
  else if (cmd == "save") c->kind = Command::Save;
  else if (cmd == "scene") {
    c->kind = Command::Scene;
    if (!j.contains("name") || !j["name"].is_string()) throw BadCommand("'scene' needs a string 'name'");
    c->name = j["name"];
    if (c->name != "organ" && c->name != "fat" && c->name != "sheet")
      throw BadCommand(fmt::format("unknown scene '{}' (organ, fat, sheet)", c->name.substr(0, 40)));
  } else if (cmd == "mode") {
    c->kind = Command::Mode;
    const json m = j.value("mode", json());
    if (m == "realtime") c->mode = NewmarkMode::RealTime;
    else if (m == "accurate") c->mode = NewmarkMode::Accurate;
    else throw BadCommand("'mode' must be \"realtime\" or \"accurate\"");
  } else if (cmd == "cut") {
    c->kind = Command::Cut;
    c->direction = vec3_of(j.value("direction", json()), "direction");
    if (c->direction.norm() < 1e-9) throw BadCommand("'direction' must not be zero");
    const json t = j.value("topology", json());
    if (!t.is_number_unsigned() || t.get<std::uint64_t>() > 0xffffffffu)
      throw BadCommand("'topology' must be the surface's topology version");
    c->topology = t.get<std::uint32_t>();
    for (const char* key : {"open_start", "open_end"})
      if (j.contains(key) && !j[key].is_boolean()) throw BadCommand(fmt::format("'{}' must be true or false", key));
    c->open_start = j.value("open_start", false);
    c->open_end = j.value("open_end", false);
    const json stroke = j.value("stroke", json());
    if (!stroke.is_array() || stroke.size() > 4096) throw BadCommand("'stroke' must be an array of at most 4096 points");
    for (const json& p : stroke) {
      if (!p.is_object() || !p.contains("triangle") || !p["triangle"].is_number_unsigned() || !p.contains("bary"))
        throw BadCommand("a stroke point is {\"triangle\": index, \"bary\": [3 numbers]}");
      const Vec3 b = vec3_of(p["bary"], "bary");
      if (b.minCoeff() < -1e-3 || std::abs(b.sum() - 1) > 1e-3)
        throw BadCommand("'bary' must be barycentric coordinates (>= 0, summing to 1)");
      const std::uint64_t triangle = p["triangle"].get<std::uint64_t>();
      if (triangle > (1u << 30)) throw BadCommand("'triangle' is not a triangle of the surface");
      c->stroke.emplace_back(static_cast<Index>(triangle), b);
    }
  } else {
    throw BadCommand(fmt::format("unknown command '{}'", cmd.substr(0, 40)));
  }
  return c;
}

struct Options {
  // One thread: the HTTP threads and the page share the cores, and OpenMP's workers, which
  // wait for work spinning while the real-time loop sleeps, made 2 threads slower (organ: 25.7
  // against 17.7 ms a step on 2 cores; docs/scenes.md#live-demo).
  int port = 8765, threads = 1;
  double dt = 0.02;  // s: 50 steps a second keep the organ in real time on a 2-core laptop
  std::string scene = "organ", out = "out/live", web = PLASTIFEM_LIVE_DIR "/web",
              three = PLASTIFEM_LIVE_DIR "/node_modules/three";
  NewmarkMode mode = NewmarkMode::RealTime;
  double seconds = 0;  // run this long, then exit (0: until interrupted)
};

Options parse_options(int argc, char** argv) {
  Options o;
  scene::for_each_option(argc, argv, [&](const std::string& a, auto&& value) {
    if (a == "--port") {
      const std::string v = value();
      o.port = v == "0" ? 0 : scene::positive_int(a, v);  // 0: any free port (the tests' choice)
      if (o.port > 65535) fail<InvalidArgument>("--port must be at most 65535");
    } else if (a == "--threads") o.threads = scene::positive_int(a, value());
    else if (a == "--scene") o.scene = value();
    else if (a == "--out") o.out = value();
    else if (a == "--web") o.web = value();
    else if (a == "--three") o.three = value();
    else if (a == "--seconds") o.seconds = scene::positive_int(a, value());
    else if (a == "--dt") {
      const std::string v = value();
      char* end = nullptr;
      o.dt = std::strtod(v.c_str(), &end);
      if (end != v.c_str() + v.size() || !(o.dt >= 1e-4 && o.dt <= 0.05))
        fail<InvalidArgument>("--dt must be a time step in [1e-4, 0.05] s, got '{}'", v);
    }
    else if (a == "--mode") o.mode = scene::mode_named(a, value());
    else if (a == "--help" || a == "-h") {
      fmt::print(
          "usage: live [--port N (8765; 0: any free one)] [--scene organ|fat|sheet] [--mode realtime|accurate] [--threads N (1)]\n"
          "            [--dt S (0.02)] [--out DIR (out/live)] [--web DIR] [--three DIR] [--seconds S]\n"
          "  serves the live demo on http://127.0.0.1:N/\n");
      std::exit(0);
    } else fail<InvalidArgument>("unknown option '{}' (try --help)", a);
  });
  if (o.scene != "organ" && o.scene != "fat" && o.scene != "sheet")
    fail<InvalidArgument>("--scene must be organ, fat or sheet, got '{}'", o.scene);
  return o;
}

/// The simulation thread and what it shares with the server's threads.
class Simulation {
 public:
  explicit Simulation(const Options& o) : o_(o) {
    std::filesystem::create_directories(o_.out);
    load(o_.scene, o_.mode);
    started_ = std::chrono::steady_clock::now();
    thread_ = std::thread([this] { run(); });
  }
  ~Simulation() {
    stop_ = true;
    wake_.notify_all();
    thread_.join();
  }

  /// Queues a checked command; the reply once it has been applied.
  json submit(std::unique_ptr<Command> c) {
    std::future<json> f = c->done.get_future();
    {
      std::lock_guard lock(m_);
      if (commands_.size() >= 256) return json{{"ok", false}, {"error", "too many commands queued"}};
      commands_.push_back(std::move(c));
    }
    wake_.notify_all();
    // A scene change builds a cage (about a second); a step in accurate mode may take a while.
    if (f.wait_for(std::chrono::seconds(20)) != std::future_status::ready)
      return json{{"ok", true}, {"queued", true}};
    return f.get();
  }

  std::string frame() const {
    std::lock_guard lock(m_);
    return frame_;
  }
  std::string topology() const {
    std::lock_guard lock(m_);
    return topology_;
  }
  json status() const {
    std::lock_guard lock(m_);
    return status_;
  }
  /// Whether --seconds have passed since the scene was ready.
  bool expired() const {
    return o_.seconds > 0 && std::chrono::steady_clock::now() - started_ > std::chrono::duration<double>(o_.seconds);
  }

 private:
  void load(const std::string& name, NewmarkMode mode) {
    const auto t0 = std::chrono::steady_clock::now();
    scene_ = live::make_scene(name, mode, o_.threads);
    scene_name_ = name;
    failures_ = 0;
    error_.clear();
    ms_.clear();
    restart_clocks();
    fmt::print("live: scene '{}' ready in {:.0f} ms: {} dofs, {} surface triangles\n", name,
               std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count(),
               scene_->num_dofs(), scene_->surface().surface().num_triangles());
    publish(true, 0);
  }

  /// Copies the scene's surface and status into the buffers the server threads read.
  void publish(bool topology_changed, double step_ms) {
    const auto& skin = scene_->surface();
    const auto& x = skin.positions();
    const auto& n = skin.normals();
    const std::uint32_t nv = static_cast<std::uint32_t>(x.cols());
    if (topology_changed) ++topology_version_;
    std::string f(64 + 24 * static_cast<size_t>(nv), '\0');
    const std::uint32_t head[4] = {frame_magic, topology_version_, nv, static_cast<std::uint32_t>(++frame_number_)};
    std::memcpy(f.data(), head, sizeof head);
    const Vec3 force = scene_->grasp_force();
    float st[status_floats] = {};
    st[kTime] = static_cast<float>(scene_->time());
    st[kStepMs] = static_cast<float>(step_ms);
    st[kDofs] = static_cast<float>(scene_->num_dofs());
    st[kRealTime] = scene_->mode() == NewmarkMode::RealTime ? 1.0f : 0.0f;
    st[kFx] = static_cast<float>(force.x()), st[kFy] = static_cast<float>(force.y()), st[kFz] = static_cast<float>(force.z());
    st[kGrasping] = scene_->grasping() ? 1.0f : 0.0f;
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start_).count();
    st[kSpeed] = wall > 0 ? static_cast<float>((scene_->time() - sim_start_) / wall) : 0.0f;
    st[kFailed] = error_.empty() ? 0.0f : 1.0f;
    std::memcpy(f.data() + 16, st, sizeof st);
    float* p = reinterpret_cast<float*>(f.data() + 64);
    for (std::uint32_t v = 0; v < nv; ++v)
      for (int d = 0; d < 3; ++d) p[3 * v + d] = static_cast<float>(x(d, v)), p[3 * nv + 3 * v + d] = static_cast<float>(n(d, v));
    std::string t;
    if (topology_changed) {
      const auto& tri = skin.surface().triangles;
      t.resize(8 + 12 * tri.size());
      const std::uint32_t th[2] = {topology_version_, static_cast<std::uint32_t>(tri.size())};
      std::memcpy(t.data(), th, sizeof th);
      auto* q = reinterpret_cast<std::uint32_t*>(t.data() + 8);
      for (size_t k = 0; k < tri.size(); ++k)
        for (int c = 0; c < 3; ++c) q[3 * k + static_cast<size_t>(c)] = static_cast<std::uint32_t>(tri[k][static_cast<size_t>(c)]);
    }
    json s = {{"scene", scene_name_},
              {"mode", scene_->mode() == NewmarkMode::RealTime ? "realtime" : "accurate"},
              {"time", scene_->time()},
              {"step_ms", step_ms},
              {"median_ms", median_ms()},
              {"surface_ms", surface_ms_},
              {"dofs", scene_->num_dofs()},
              {"vertices", nv},
              {"triangles", skin.surface().num_triangles()},
              {"topology", topology_version_},
              {"grasping", scene_->grasping()},
              {"force", {force.x(), force.y(), force.z()}},
              {"speed", st[kSpeed]},
              {"error", error_},
              {"frame", frame_number_}};
    std::lock_guard lock(m_);
    frame_.swap(f);
    if (topology_changed) topology_.swap(t);
    status_ = std::move(s);
  }

  double median_ms() const {
    if (ms_.empty()) return 0;
    std::vector<double> v = ms_;
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    return v[v.size() / 2];
  }

  /// Applies one command; returns the reply (throws InvalidArgument / SolverError on refusal).
  json apply(Command& c) {
    const auto& skin = scene_->surface();
    switch (c.kind) {
      case Command::Grasp: scene_->grasp(c.point, 0.012); break;
      case Command::Move: scene_->move_grasper(c.point); break;
      case Command::Release: scene_->release(); break;
      case Command::Reset: load(scene_name_, scene_->mode()); break;
      case Command::Scene: load(c.name, scene_->mode()); break;
      case Command::Mode: scene_->set_mode(c.mode); break;
      case Command::Save: {
        if (saves_ >= 1000) fail<InvalidArgument>("save: 1000 files written already; restart the server to save more");
        const auto path = std::filesystem::path(o_.out) / fmt::format("{}_{:04d}.vtu", scene_name_, ++saves_);
        skin.write_vtu(path);
        return json{{"ok", true}, {"file", path.string()}};
      }
      case Command::Cut: {
        if (c.topology != topology_version_)
          fail<InvalidArgument>("cut: the surface changed since the stroke was drawn (topology {} now, {} drawn on)",
                                topology_version_, c.topology);
        // Each stroke point's rest position: its triangle's rest vertices, weighted.
        const TriangleSurface& tri = skin.surface();
        std::vector<Vec3> rest;
        for (const auto& [t, b] : c.stroke) {
          if (t >= tri.num_triangles()) fail<InvalidArgument>("cut: triangle {} does not exist ({} triangles)", t, tri.num_triangles());
          const auto& v = tri.triangles[static_cast<size_t>(t)];
          const Vec3 p = b[0] * tri.vertices.col(v[0]) + b[1] * tri.vertices.col(v[1]) + b[2] * tri.vertices.col(v[2]);
          if (rest.empty() || (p - rest.back()).norm() > 5e-4) rest.push_back(p);  // 0.5 mm apart at least
        }
        const Index before = tri.num_triangles();
        scene_->cut(live::swept_stroke(rest, c.direction, scene_->size(), c.open_start, c.open_end));
        publish(true, 0);
        return json{{"ok", true}, {"triangles", scene_->surface().surface().num_triangles()}, {"before", before}};
      }
    }
    publish(false, 0);
    return json{{"ok", true}};
  }

  void run() {
    const Scalar dt = o_.dt;
    while (!stop_) {
      std::deque<std::unique_ptr<Command>> todo;
      {
        std::lock_guard lock(m_);
        todo.swap(commands_);
      }
      for (auto& c : todo) {
        try {
          c->done.set_value(apply(*c));
        } catch (const std::exception& e) {
          c->done.set_value(json{{"ok", false}, {"error", e.what()}});
        }
      }
      if (failures_ >= 20) {  // paused until a reset or another scene
        std::unique_lock lock(m_);
        wake_.wait_for(lock, std::chrono::milliseconds(100));
        continue;
      }
      // Real time: no further ahead of the wall clock than one step.
      const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - pace_wall_start_).count();
      const double ahead = (scene_->time() - pace_sim_start_) - wall;
      if (ahead < -catch_up_limit) {
        // Behind after slow steps (accurate mode, a slow scene): keep the pace from now on
        // instead of running flat out later to make the lost time up. (The status's share of the
        // wall clock still counts from the scene's start.)
        pace_wall_start_ = std::chrono::steady_clock::now();
        pace_sim_start_ = scene_->time();
      } else if (ahead > dt) {
        std::unique_lock lock(m_);
        wake_.wait_for(lock, std::chrono::duration<double>(ahead - dt));
        continue;
      }
      try {
        // A tear splits the surface: new triangles and vertices.
        const auto& before = scene_->surface().surface();
        const Index triangles = before.num_triangles(), vertices = before.num_vertices();
        const StepReport r = scene_->step(dt);
        const auto t0 = std::chrono::steady_clock::now();
        scene_->update_surface();
        ms_.push_back(r.wall_ms);
        if (ms_.size() > 500) ms_.erase(ms_.begin(), ms_.begin() + 250);
        failures_ = 0;
        error_.clear();
        const auto& after = scene_->surface().surface();
        publish(after.num_triangles() != triangles || after.num_vertices() != vertices, r.wall_ms);
        // What a frame costs besides the step: the surface's update and its copy for the server.
        surface_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      } catch (const std::exception& e) {
        // The state is the last good one; let go of the grasp (what drove the tissue there).
        ++failures_;
        error_ = e.what();
        try {
          scene_->release();
        } catch (const std::exception& r) {
          error_ += fmt::format(" (and the release failed: {})", r.what());
        }
        fmt::print("live: step failed ({}): {}\n", failures_, error_);
        if (failures_ >= 20) error_ += " (paused: reset or choose a scene)";
        publish(false, 0);
        restart_clocks();  // do not run away from the wall clock while failing
      }
    }
  }

  /// Both clock pairs (the status's and the pace's) start again from now and the scene's time.
  void restart_clocks() {
    wall_start_ = pace_wall_start_ = std::chrono::steady_clock::now();
    sim_start_ = pace_sim_start_ = scene_->time();
  }

  Options o_;
  std::unique_ptr<live::Scene> scene_;
  std::string scene_name_, error_;
  int failures_ = 0, saves_ = 0;
  std::vector<double> ms_;
  double surface_ms_ = 0;
  // The status's share of the wall clock counts from the scene's start (wall_start_, sim_start_);
  // the real-time pace from its last rebase (pace_*), at most catch_up_limit behind.
  std::chrono::steady_clock::time_point wall_start_, pace_wall_start_, started_ = std::chrono::steady_clock::now();
  Scalar sim_start_ = 0, pace_sim_start_ = 0;
  static constexpr double catch_up_limit = 0.25;  // s
  std::uint32_t topology_version_ = 0;
  std::uint64_t frame_number_ = 0;

  mutable std::mutex m_;
  std::condition_variable wake_;
  std::deque<std::unique_ptr<Command>> commands_;
  std::string frame_, topology_;
  json status_;
  std::atomic<bool> stop_ = false;
  std::thread thread_;
};

httplib::Server* server_for_signal = nullptr;
void on_signal(int) {
  if (server_for_signal) server_for_signal->stop();
}

}  // namespace

int main(int argc, char** argv) try {
  const Options o = parse_options(argc, argv);
  if (!std::filesystem::is_regular_file(std::filesystem::path(o.web) / "index.html"))
    fail<InvalidArgument>("no index.html in --web {}", o.web);
  if (!std::filesystem::is_regular_file(std::filesystem::path(o.three) / "build" / "three.module.js"))
    fail<InvalidArgument>("three.js is not installed in {} (bash cmake/setup.sh live installs it with npm)", o.three);

  httplib::Server server;
  server.set_payload_max_length(1 << 20);  // a cut stroke of 4096 points is ~200 KB of JSON
  server.set_mount_point("/", o.web);
  server.set_mount_point("/three", o.three);
  Simulation sim(o);

  server.Get("/frame", [&](const httplib::Request&, httplib::Response& res) {
    const std::string f = sim.frame();
    res.set_content(f.data(), f.size(), "application/octet-stream");
    res.set_header("Cache-Control", "no-store");
  });
  server.Get("/topology", [&](const httplib::Request&, httplib::Response& res) {
    const std::string t = sim.topology();
    res.set_content(t.data(), t.size(), "application/octet-stream");
    res.set_header("Cache-Control", "no-store");
  });
  server.Get("/status", [&](const httplib::Request&, httplib::Response& res) {
    res.set_content(sim.status().dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
    res.set_header("Cache-Control", "no-store");
  });
  server.Post("/command", [&](const httplib::Request& req, httplib::Response& res) {
    json reply;
    // JSON only: a page of another site can send a text/plain POST without asking first, not
    // an application/json one.
    if (req.get_header_value("Content-Type").rfind("application/json", 0) != 0) {
      res.status = 415;
      res.set_content(R"({"ok":false,"error":"commands are application/json"})", "application/json");
      return;
    }
    try {
      reply = sim.submit(parse_command(req.body));
      if (!reply.value("ok", false)) res.status = 409;
    } catch (const BadCommand& e) {
      reply = json{{"ok", false}, {"error", e.what()}};
      res.status = 400;
    }
    res.set_content(reply.dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
  });
  server.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr) {
    res.status = 500;
    res.set_content(R"({"ok":false,"error":"internal error"})", "application/json");
  });

  // --port 0: the system picks a free port, printed below (no race between choosing and binding).
  int port = o.port;
  if (port == 0) {
    port = server.bind_to_any_port("127.0.0.1");
    if (port <= 0) fail<IoError>("cannot listen on any port of 127.0.0.1");
  } else if (!server.bind_to_port("127.0.0.1", port)) {
    fail<IoError>("cannot listen on 127.0.0.1:{} (in use?)", port);
  }
  // Requests for this server by name only: a page of another site that rebinds its own name to
  // 127.0.0.1 sends its own Host.
  const std::string hosts[] = {fmt::format("127.0.0.1:{}", port), fmt::format("localhost:{}", port)};
  server.set_pre_routing_handler([&hosts](const httplib::Request& req, httplib::Response& res) {
    const std::string host = req.get_header_value("Host");
    if (host == hosts[0] || host == hosts[1]) return httplib::Server::HandlerResponse::Unhandled;
    res.status = 403;
    res.set_content(R"({"ok":false,"error":"unknown Host"})", "application/json");
    return httplib::Server::HandlerResponse::Handled;
  });

  server_for_signal = &server;
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  fmt::print("live: open http://127.0.0.1:{}/ (scene {}, {} mode; Ctrl-C stops)\n", port, o.scene,
             o.mode == NewmarkMode::RealTime ? "real-time" : "accurate");
  std::fflush(stdout);
  // --seconds: stop once they have passed (and the server has started, or stop() is lost).
  std::atomic<bool> done = false;
  std::thread timer;
  if (o.seconds > 0)
    timer = std::thread([&] {
      while (!done && !(server.is_running() && sim.expired())) std::this_thread::sleep_for(std::chrono::milliseconds(100));
      if (!done) {
        fmt::print("live: --seconds {} reached\n", o.seconds);
        server.stop();
      }
    });
  server.listen_after_bind();
  done = true;
  if (timer.joinable()) timer.join();
  fmt::print("live: stopped\n");
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "live: {}\n", e.what());
  return 1;
}
