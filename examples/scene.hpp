#pragma once
// What the surgical scenes (fat_grasp, vessel_twist, liver_cage, liver_cut, sheet_tear) share: their command line
// (--steps N, --every K, --out DIR, --threads N, --mode accurate|realtime, --csv FILE, --help),
// a progress line, and the per-step timings they end with (and append to FILE as a bench row:
// bench/scenes.sh); and the skin of a Hex8 mesh as a finer triangle surface to embed in it.
#include <plastifem/embedding/cage.hpp>
#include <plastifem/embedding/triangle_surface.hpp>
#include <plastifem/plastifem.hpp>

#include <fmt/core.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <utility>
#include <string>
#include <string_view>
#include <vector>

namespace scene {

struct Options {
  int steps = 0;   ///< time steps (the scene's default until --steps)
  int every = 10;  ///< a PVD frame every K steps
  std::string out = "out";
  int threads = 1;  ///< SolverSettings::threads
  plastifem::NewmarkMode mode = plastifem::NewmarkMode::Accurate;
  std::string csv;  ///< where to append the timings as a CSV row (none: empty)

  /// Sets the threads and the mode on the scene's settings (after it has chosen its scheme).
  void apply(plastifem::SolverSettings& st) const {
    st.threads = threads;
    st.newmark.mode = mode;
  }
  const char* mode_name() const { return mode == plastifem::NewmarkMode::RealTime ? "realtime" : "accurate"; }
};

/// The damping every tissue scene (and the live demo) runs with: tissue in fluid, mass damping
/// (alpha = 5 /s) settles the motion once let go; a release, a cut or a tear lets go of stress at
/// once, a snap that rings in the mesh's highest modes, which the trapezoidal rule keeps and
/// generalized-alpha (rho_inf = 0.5) damps. Not stiffness-proportional damping: even 2 ms of it
/// made the vessel's twist lag, its torque twice the static one at 20 degrees (docs/scenes.md).
/// Set the threads and the mode afterwards (Options::apply).
inline plastifem::SolverSettings tissue_settings() {
  plastifem::SolverSettings st;
  st.rayleigh_mass = 5;
  st.newmark = plastifem::NewmarkSettings::generalized_alpha(0.5);
  return st;
}

/// The flags every scene takes, for its usage text.
inline constexpr const char* common_usage =
    "  --steps N   time steps      --every K   a PVD frame every K steps   --out DIR   output folder\n"
    "  --threads N  threads (1)    --mode accurate|realtime (accurate)      --csv FILE  append the timings\n";

/// A whole positive number, or an error naming the option (std::stoi would accept "12abc" and
/// throw a bare "stoi" for "abc").
inline int positive_int(std::string_view option, std::string_view text) {
  int v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || v < 1)
    plastifem::fail<plastifem::InvalidArgument>("{} needs a whole number >= 1, got '{}'", option, text);
  return v;
}

/// The stepping mode called `m` (accurate, realtime), or an error naming `flag`.
inline plastifem::NewmarkMode mode_named(std::string_view flag, const std::string& m) {
  if (m == "accurate") return plastifem::NewmarkMode::Accurate;
  if (m == "realtime") return plastifem::NewmarkMode::RealTime;
  plastifem::fail<plastifem::InvalidArgument>("{} needs accurate or realtime, got '{}'", flag, m);
}

/// Calls on_option(flag, value) for each command-line flag, where value() takes the flag's
/// value (InvalidArgument if there is none).
template <class OnOption>
void for_each_option(int argc, char** argv, OnOption&& on_option) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) plastifem::fail<plastifem::InvalidArgument>("option {} needs a value", a);
      return argv[++i];
    };
    on_option(a, value);
  }
}

/// Parses the scene's flags; --help prints `usage` and exits. Throws InvalidArgument on a bad
/// flag.
inline Options parse(int argc, char** argv, int default_steps, const char* usage) {
  Options o;
  o.steps = default_steps;
  for_each_option(argc, argv, [&](const std::string& a, auto&& value) {
    if (a == "--steps") o.steps = positive_int(a, value());
    else if (a == "--every") o.every = positive_int(a, value());
    else if (a == "--out") o.out = value();
    else if (a == "--threads") o.threads = positive_int(a, value());
    else if (a == "--csv") o.csv = value();
    else if (a == "--mode") o.mode = mode_named(a, value());
    else if (a == "--help" || a == "-h") {
      fmt::print("{}{}", usage, common_usage);
      std::exit(0);
    } else plastifem::fail<plastifem::InvalidArgument>("unknown option '{}' (try --help)", a);
  });
  return o;
}

/// Keeps each step's wall time, and the times of the scene's events (a cut's growth, a tear's);
/// prints a progress line every tenth of the run; ends with the median and largest of each,
/// appended to Options::csv as a row when one is given.
class Timings {
 public:
  /// `event` names what event() times ("" for a scene without events).
  Timings(const Options& o, std::string scene, std::string event = {})
      : o_(o), scene_(std::move(scene)), event_(std::move(event)) {
    ms_.reserve(static_cast<size_t>(o.steps));
  }

  /// Records step k (1-based) and prints the progress line when it is due; `extra` is appended.
  void record(int k, const plastifem::StepReport& r, const std::string& extra = {}) {
    ms_.push_back(r.wall_ms);
    redone_ += r.realtime_redone > 0;
    if (k % std::max(1, o_.steps / 10) == 0 || k == o_.steps)
      fmt::print("  [{:3.0f}%] step {:4d}/{}  {:6.2f} ms  Newton {:2d}  CG {:4d}  {}\n", 100.0 * k / o_.steps, k,
                 o_.steps, r.wall_ms, r.newton_iterations, r.linear_iterations, extra);
  }
  /// Records one event's wall time.
  void event(double ms) { events_.push_back(ms); }
  double median() const { return median_of(ms_); }
  double max() const { return max_of(ms_); }

  /// Prints the summary and appends the CSV row.
  void summary() const {
    fmt::print("per step ({}, {} thread{}): median {:.2f} ms, max {:.2f} ms over {} steps", o_.mode_name(), o_.threads,
               o_.threads > 1 ? "s" : "", median(), max(), ms_.size());
    // Real time: steps beyond the linearisation's reach were redone as accurate ones.
    if (redone_ > 0)
      fmt::print(" ({} step{} redone as accurate: NewmarkSettings::realtime_reach)", redone_, redone_ == 1 ? "" : "s");
    fmt::print("\n");
    if (!event_.empty() && !events_.empty())
      fmt::print("{}: median {:.2f} ms, max {:.2f} ms over {}\n", event_, median_of(events_), max_of(events_),
                 events_.size());
    if (o_.csv.empty()) return;
    const bool fresh = !std::filesystem::exists(o_.csv) || std::filesystem::file_size(o_.csv) == 0;
    std::ofstream f(o_.csv, std::ios::app);
    if (!f) plastifem::fail<plastifem::IoError>("cannot append to {}", o_.csv);
    if (fresh) f << "scene,mode,threads,steps,step_median_ms,step_max_ms,event,events,event_median_ms,event_max_ms\n";
    f << fmt::format("{},{},{},{},{:.3f},{:.3f},{},{},{:.3f},{:.3f}\n", scene_, o_.mode_name(), o_.threads, ms_.size(),
                     median(), max(), event_.empty() ? "-" : event_, events_.size(), median_of(events_),
                     max_of(events_));
  }

 private:
  static double median_of(std::vector<double> v) {
    if (v.empty()) return 0;
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    return v[v.size() / 2];
  }
  static double max_of(const std::vector<double>& v) { return v.empty() ? 0 : *std::max_element(v.begin(), v.end()); }

  Options o_;
  int redone_ = 0;  ///< steps with a sub-step redone as an accurate step
  std::string scene_, event_;
  std::vector<double> ms_, events_;
};

/// The liver scenes' organ (liver_cage, liver_cut): the library's liver-like surface, 20 cm long
/// (liver_surface: 20,480 triangles), and its cage of `cell` Hex8 cells, each weighted by the
/// fraction of it inside.
struct CagedLiver {
  plastifem::TriangleSurface surface;
  plastifem::Cage<plastifem::Hex8> cage;
};
inline CagedLiver caged_liver(plastifem::Scalar cell) {
  plastifem::TriangleSurface liver = plastifem::liver_surface(plastifem::Vec3::Zero(), 0.1, 5);
  plastifem::Cage<plastifem::Hex8> cage = plastifem::cage_around<plastifem::Hex8>(liver, cell);
  return {std::move(liver), std::move(cage)};
}

/// The grasp point on the liver's left lobe: the surface's highest vertex within 1 cm of
/// (-0.07, 0) in plan. The upper surface rises towards the right lobe, so this lands on the
/// disc's right rim: about 6 cm left of the middle (x about -0.061), on the lobe's upper slope,
/// not a local top.
inline plastifem::Vec3 left_lobe_top(const plastifem::TriangleSurface& liver) {
  plastifem::Vec3 top = plastifem::Vec3::Constant(-1e9);
  for (plastifem::Index v = 0; v < liver.num_vertices(); ++v) {
    const plastifem::Vec3 p = liver.vertices.col(v);
    if ((p.head<2>() - Eigen::Vector2d(-0.07, 0)).norm() < 0.01 && p.z() > top.z()) top = p;
  }
  return top;
}

/// Scene (a)'s fat layer (fat_grasp, the live demo): a thick shell, 1 cm thick in 3 Hex8 layers,
/// grown upwards from a gently domed 8 x 6 cm patch of 24 x 18 cells over [0, 8 cm] x [0, 6 cm],
/// z = 8 mm cos(pi x') cos(pi y') (x', y' in [-1/2, 1/2]); its bottom face is the node set
/// "bottom".
inline constexpr double fat_length = 0.08, fat_width = 0.06, fat_dome = 0.008, fat_thickness = 0.01;
inline plastifem::Mesh<plastifem::Hex8> fat_layer() {
  constexpr int nx = 24, ny = 18;
  plastifem::QuadSurface s;  // counter-clockwise from above: the shell grows upwards
  s.nodes.resize(3, (nx + 1) * (ny + 1));
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i) {
      const double x = fat_length * i / nx, y = fat_width * j / ny;
      s.nodes.col(j * (nx + 1) + i) =
          plastifem::Vec3(x, y, fat_dome * std::cos(std::numbers::pi * (x / fat_length - 0.5)) *
                                    std::cos(std::numbers::pi * (y / fat_width - 0.5)));
    }
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const plastifem::Index a = j * (nx + 1) + i;
      s.quads.push_back({a, a + 1, a + nx + 2, a + nx + 1});
    }
  return plastifem::thick_shell_hex8(s, fat_thickness, 3);
}

/// Scene (d)'s sheet (sheet_tear, the live demo): 10 x 8 cm, 2 mm thick, 20 x 16 x 1 Hex8 over
/// [0, 10 cm] x [0, 8 cm]; and its 1 cm nick into the left edge, along the middle of an element
/// row (Tearing::start's path).
inline constexpr double sheet_width = 0.10, sheet_height = 0.08, sheet_thickness = 0.002;
inline plastifem::Mesh<plastifem::Hex8> tear_sheet() {
  return plastifem::bar_mesh<plastifem::Hex8>(
      plastifem::BoxSpec{20, 16, 1, plastifem::Vec3(sheet_width, sheet_height, sheet_thickness)});
}
inline std::vector<plastifem::Vec3> sheet_nick() {
  const double y = sheet_height / 2 + 0.5 * sheet_height / 16;
  return {plastifem::Vec3(-0.01, y, sheet_thickness / 2), plastifem::Vec3(0.01, y, sheet_thickness / 2)};
}

/// The lowest node of each vertical column of a grid of `cell` cells (where a table under the
/// organ touches it), ordered by column.
inline std::vector<plastifem::Index> lowest_of_columns(const plastifem::Mesh<plastifem::Hex8>& mesh,
                                                       plastifem::Scalar cell) {
  std::map<std::pair<long, long>, plastifem::Index> lowest;
  for (plastifem::Index i = 0; i < mesh.num_nodes(); ++i) {
    const plastifem::Vec3 p = mesh.node(i);
    const std::pair<long, long> column{std::lround(p.x() / cell * 2), std::lround(p.y() / cell * 2)};
    if (auto [it, added] = lowest.try_emplace(column, i); !added && p.z() < mesh.node(it->second).z()) it->second = i;
  }
  std::vector<plastifem::Index> nodes;
  for (const auto& [column, i] : lowest) nodes.push_back(i);
  return nodes;
}

/// The boundary of a Hex8 mesh as triangles: each boundary face split into r x r quads on its
/// bilinear map (which is the element's own map there, so every vertex lies in the mesh), two
/// triangles each, facing out, with vertices shared across faces: a closed surface when the
/// boundary is closed. For embedding with EmbeddedSurface: its normals are smooth where the
/// mesh's faces are flat.
inline plastifem::TriangleSurface refined_boundary(const plastifem::Mesh<plastifem::Hex8>& mesh, int r) {
  using plastifem::Index, plastifem::Vec3;
  std::vector<Vec3> vertices;
  std::map<std::array<long long, 3>, Index> at;  // vertices by position, rounded to 1 nm
  auto vertex = [&](const Vec3& p) {
    const std::array<long long, 3> key{std::llround(p.x() * 1e9), std::llround(p.y() * 1e9), std::llround(p.z() * 1e9)};
    const auto [it, added] = at.try_emplace(key, static_cast<Index>(vertices.size()));
    if (added) vertices.push_back(p);
    return it->second;
  };
  plastifem::TriangleSurface s;
  for (const plastifem::FaceRef& f : plastifem::boundary_faces(mesh)) {
    const auto c = mesh.face_nodes(f);  // counter-clockwise seen from outside
    std::vector<Index> grid;
    for (int j = 0; j <= r; ++j)
      for (int i = 0; i <= r; ++i) {
        const double u = double(i) / r, v = double(j) / r;
        grid.push_back(vertex((1 - u) * (1 - v) * mesh.node(c[0]) + u * (1 - v) * mesh.node(c[1]) +
                              u * v * mesh.node(c[2]) + (1 - u) * v * mesh.node(c[3])));
      }
    for (int j = 0; j < r; ++j)
      for (int i = 0; i < r; ++i) {
        const Index a = grid[static_cast<size_t>(j * (r + 1) + i)], b = grid[static_cast<size_t>(j * (r + 1) + i + 1)],
                    d = grid[static_cast<size_t>((j + 1) * (r + 1) + i)],
                    e = grid[static_cast<size_t>((j + 1) * (r + 1) + i + 1)];
        s.triangles.push_back({a, b, e});
        s.triangles.push_back({a, e, d});
      }
  }
  s.vertices.resize(3, static_cast<Index>(vertices.size()));
  for (size_t k = 0; k < vertices.size(); ++k) s.vertices.col(static_cast<Index>(k)) = vertices[k];
  return s;
}

}  // namespace scene
