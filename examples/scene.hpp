#pragma once
// What the surgical scenes (fat_grasp, vessel_twist, liver_cage, liver_cut, sheet_tear) share: their command line
// (--steps N, --every K, --out DIR, --help), a progress line, and the per-step timings they end
// with; and the skin of a Hex8 mesh as a finer triangle surface to embed in it.
#include <plastifem/embedding/triangle_surface.hpp>
#include <plastifem/plastifem.hpp>

#include <fmt/core.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace scene {

struct Options {
  int steps = 0;   ///< time steps (the scene's default until --steps)
  int every = 10;  ///< a PVD frame every K steps
  std::string out = "out";
};

/// A whole positive number, or an error naming the option (std::stoi would accept "12abc" and
/// throw a bare "stoi" for "abc").
inline int positive_int(std::string_view option, std::string_view text) {
  int v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || v < 1)
    plastifem::fail<plastifem::InvalidArgument>("{} needs a whole number >= 1, got '{}'", option, text);
  return v;
}

/// Parses the scene's flags; --help prints `usage` and exits. Throws InvalidArgument on a bad
/// flag.
inline Options parse(int argc, char** argv, int default_steps, const char* usage) {
  Options o;
  o.steps = default_steps;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) plastifem::fail<plastifem::InvalidArgument>("option {} needs a value", a);
      return argv[++i];
    };
    if (a == "--steps") o.steps = positive_int(a, value());
    else if (a == "--every") o.every = positive_int(a, value());
    else if (a == "--out") o.out = value();
    else if (a == "--help" || a == "-h") {
      fmt::print("{}", usage);
      std::exit(0);
    } else plastifem::fail<plastifem::InvalidArgument>("unknown option '{}' (try --help)", a);
  }
  return o;
}

/// Keeps each step's wall time; prints a progress line every tenth of the run and the median
/// and largest step time at the end.
class Timings {
 public:
  explicit Timings(int steps) : steps_(steps) { ms_.reserve(static_cast<size_t>(steps)); }

  /// Records step k (1-based) and prints the progress line when it is due; `extra` is appended.
  void record(int k, const plastifem::StepReport& r, const std::string& extra = {}) {
    ms_.push_back(r.wall_ms);
    if (k % std::max(1, steps_ / 10) == 0 || k == steps_)
      fmt::print("  [{:3.0f}%] step {:4d}/{}  {:6.2f} ms  Newton {:2d}  CG {:4d}  {}\n", 100.0 * k / steps_, k, steps_,
                 r.wall_ms, r.newton_iterations, r.linear_iterations, extra);
  }
  double median() const {
    std::vector<double> s = ms_;
    if (s.empty()) return 0;
    std::nth_element(s.begin(), s.begin() + static_cast<long>(s.size() / 2), s.end());
    return s[s.size() / 2];
  }
  double max() const { return ms_.empty() ? 0 : *std::max_element(ms_.begin(), ms_.end()); }
  void summary() const {
    fmt::print("per step: median {:.2f} ms, max {:.2f} ms over {} steps\n", median(), max(), ms_.size());
  }

 private:
  int steps_;
  std::vector<double> ms_;
};

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
