#pragma once
// The live demo's scenes (examples/live/README.md): the surgical scenes of examples/ (docs/scenes.md)
// behind one interface the server drives: step, grasp a point and move the grasper, release,
// cut along a surface, and the embedded surface the page draws. Each scene is a plastifem
// Solver of its own composition; the interface is virtual because the server switches scenes
// at run time (one call per step: nothing on the solver's hot path).
#include "../scene.hpp"

#include <plastifem/cutting.hpp>
#include <plastifem/embedding/cage.hpp>
#include <plastifem/embedding/embedded_surface.hpp>
#include <plastifem/enrichment/tearing.hpp>
#include <plastifem/mesh/io/io.hpp>
#include <plastifem/plasticity.hpp>

#include <algorithm>
#include <memory>
#include <numbers>
#include <optional>
#include <string>

namespace live {

using namespace plastifem;

/// What the server asks of a scene. Every call comes from the simulation thread.
class Scene {
 public:
  virtual ~Scene() = default;
  virtual std::string name() const = 0;
  /// One step of dt; throws SolverError with the state unchanged.
  virtual StepReport step(Scalar dt) = 0;
  /// The surface at the committed state (split along the cuts), and its triangles' version:
  /// it changes when a cut or a tear changes the triangles.
  virtual void update_surface() = 0;
  virtual const EmbeddedSurface<Hex8>& surface() const = 0;
  /// Grasps the tissue near `point` (current position): the nodes within `radius` of it follow
  /// the grasper from now on. Throws InvalidArgument if there is nothing there to hold.
  virtual void grasp(const Vec3& point, Scalar radius) = 0;
  /// The grasper's target position (it moves there at a bounded speed).
  virtual void move_grasper(const Vec3& target) = 0;
  virtual void release() = 0;
  virtual bool grasping() const = 0;
  /// The force the grasper exerts on the tissue (sum of the reactions at its nodes).
  virtual Vec3 grasp_force() const = 0;
  /// Cuts along `sheet` (rest configuration). Throws InvalidArgument if the scene cannot cut
  /// or the sheet misses the body.
  virtual void cut(const CutSurface& sheet) = 0;
  virtual Index num_dofs() const = 0;
  virtual Scalar time() const = 0;
  virtual void set_mode(NewmarkMode mode) = 0;
  virtual NewmarkMode mode() const = 0;
  /// The body's size (the largest side of its rest bounding box), for the cut sheet's depth.
  virtual Scalar size() const = 0;
};

/// The grasper's largest speed (m/s): the mouse can jump, the tissue is dragged at most this fast.
inline constexpr Scalar grasper_speed = 0.5;

/// A Scene over one Solver type S (Hex8), its skin embedded, optionally tearing.
template <class S>
class SolverScene final : public Scene {
  static_assert(S::EnrichmentPolicy::active, "every live scene can be cut: its solver needs an enrichment");

 public:
  SolverScene(std::string name, std::unique_ptr<S> solver, const TriangleSurface& skin)
      : name_(std::move(name)), s_(std::move(solver)), skin_(s_->mesh(), skin) {
    skin_.update(*s_);
    const auto& X = s_->mesh().nodes();
    size_ = (X.rowwise().maxCoeff() - X.rowwise().minCoeff()).maxCoeff();
  }
  S& solver() { return *s_; }
  /// The grasper moves in the plane z = const only (a sheet on a tray, held in z).
  void set_planar_grasp() { planar_ = true; }
  void enable_tearing(const TearingSettings& t, std::vector<Vec3> nick) {
    tearing_ = std::make_unique<Tearing<S>>(*s_, t);
    if (!nick.empty()) tearing_->start(std::move(nick));
  }

  std::string name() const override { return name_; }
  StepReport step(Scalar dt) override {
    if (grasp_) {
      // The grasper moves towards its target at most grasper_speed: the device sample for the
      // end of this step (solver/boundary.hpp's DeviceSamples: the grasped nodes move at its
      // velocity within the step, so inertia and damping see the motion).
      const Vec3 want = target_ - grasp_->start;
      const Vec3 d = want - grasp_->offset;
      const Scalar most = grasper_speed * dt;
      grasp_->offset += d.norm() > most ? Vec3(d * (most / d.norm())) : d;
      grasp_->device.add(s_->time() + dt, grasp_->offset);
    }
    StepReport r = s_->step(dt);
    if (tearing_) tearing_->update();
    if (grasp_) force_ = sum_at(s_->reaction_forces(), grasp_->nodes);
    return r;
  }
  void update_surface() override { skin_.update(*s_); }
  const EmbeddedSurface<Hex8>& surface() const override { return skin_; }

  void grasp(const Vec3& point, Scalar radius) override {
    if (!point.allFinite()) fail<InvalidArgument>("grasp: the point must be finite");
    release();
    std::vector<Index> nodes;
    const auto& mesh = s_->mesh();
    for (Index i = 0; i < mesh.num_nodes(); ++i)
      if ((mesh.node(i) + s_->displacement(i) - point).norm() < radius && !s_->is_constrained(3 * i)) nodes.push_back(i);
    if (nodes.empty())
      fail<InvalidArgument>("grasp: no free node within {:.0f} mm of ({:.3f}, {:.3f}, {:.3f})", 1e3 * radius,
                            point.x(), point.y(), point.z());
    Grasp g{nodes, point, Vec3::Zero(), DeviceSamples(s_->time(), Vec3::Zero()), {}};
    g.handle = s_->grasp(g.nodes, g.device.path());
    grasp_ = std::move(g);
    target_ = point;
    force_.setZero();
  }
  void move_grasper(const Vec3& target) override {
    if (!target.allFinite()) fail<InvalidArgument>("move: the target must be finite");
    if (!grasp_) fail<InvalidArgument>("move: nothing is grasped");
    // At most a body's size from where it took hold: a drag cannot throw the tissue away.
    Vec3 d = target - grasp_->start;
    if (planar_) d.z() = 0;
    target_ = grasp_->start + (d.norm() > size_ ? Vec3(d * (size_ / d.norm())) : d);
  }
  void release() override {
    if (!grasp_) return;
    s_->release(grasp_->handle);
    grasp_.reset();
    force_.setZero();
  }
  bool grasping() const override { return grasp_.has_value(); }
  Vec3 grasp_force() const override { return force_; }

  void cut(const CutSurface& sheet) override {
    s_->cut(sheet);
    skin_.update(*s_);
  }
  Index num_dofs() const override { return s_->num_dofs(); }
  Scalar time() const override { return s_->time(); }
  void set_mode(NewmarkMode mode) override {
    SolverSettings st = s_->settings();
    st.newmark.mode = mode;
    s_->set_settings(st);
  }
  NewmarkMode mode() const override { return s_->settings().newmark.mode; }
  Scalar size() const override { return size_; }

 private:
  struct Grasp {
    std::vector<Index> nodes;
    Vec3 start, offset;
    DeviceSamples device;
    ConstraintHandle handle;
  };
  static Vec3 sum_at(const Vector& r, const std::vector<Index>& nodes) {
    Vec3 f = Vec3::Zero();
    for (Index i : nodes) f += r.segment<3>(3 * i);
    return f;
  }

  std::string name_;
  std::unique_ptr<S> s_;
  EmbeddedSurface<Hex8> skin_;
  Scalar size_ = 0;
  bool planar_ = false;
  std::optional<Grasp> grasp_;
  Vec3 target_ = Vec3::Zero(), force_ = Vec3::Zero();
  std::unique_ptr<Tearing<S>> tearing_;
};

using CuttingSolver = Solver<Hex8, Corotational, NoPlasticity, ShiftedHeaviside>;
// Plastic and cut (plastifem::compiled holds it): the cut is a material surface, the elements it
// enriches stop flowing (docs/xfem.md).
using PlasticCuttingSolver = Solver<Hex8, Corotational, VertexBlended, ShiftedHeaviside>;

inline SolverSettings live_settings(NewmarkMode mode, int threads) {
  SolverSettings st = scene::tissue_settings();  // as the scenes: settles once let go, snaps damped
  st.newmark.mode = mode;
  st.threads = threads;
  return st;
}

/// Scene (c)'s organ: the liver in a 1 cm hex cage on a table that ends 6 cm short of its left
/// lobe's tip (x < -0.04 overhangs), so a piece of the lobe cut off there falls. (A cut through
/// cells with a held node stays held on both sides there: docs/xfem.md.)
inline std::unique_ptr<Scene> organ(NewmarkMode mode, int threads) {
  constexpr Scalar cell = 0.01;
  scene::CagedLiver o = scene::caged_liver(cell);
  const Mesh<Hex8>& mesh = o.cage.mesh;
  auto s = std::make_unique<CuttingSolver>(mesh, Material{5e3, 0.45, 1070}, live_settings(mode, threads));
  std::vector<Index> table;
  for (Index i : scene::lowest_of_columns(mesh, cell))
    if (mesh.node(i).x() > -0.04) table.push_back(i);
  s->fix(table);
  s->add_gravity(Vec3(0, 0, -9.81));
  return std::make_unique<SolverScene<CuttingSolver>>("organ", std::move(s), o.surface);
}

/// Scene (a)'s fat layer (scene::fat_layer) on a fixed base; vertex-blended plasticity (yield
/// 400 Pa), so a pull past yield leaves a bump; it can be cut too.
inline std::unique_ptr<Scene> fat(NewmarkMode mode, int threads) {
  const Mesh<Hex8> mesh = scene::fat_layer();
  PlasticParams p;
  p.yield_stress = 400;
  p.flow_rate = 1.0;
  p.hardening = 0.2;
  auto s = std::make_unique<PlasticCuttingSolver>(mesh, Material{3000, 0.45, 920}, live_settings(mode, threads), p);
  s->fix(mesh.node_set("bottom"));
  const TriangleSurface skin = scene::refined_boundary(mesh, 2);
  return std::make_unique<SolverScene<PlasticCuttingSolver>>("fat", std::move(s), skin);
}

/// Scene (d)'s sheet: 10 x 8 cm, 2 mm thick, on a tray (held in z), its lower edge fixed, nicked
/// in the middle; it tears where the principal stress passes 10 kPa.
inline std::unique_ptr<Scene> sheet(NewmarkMode mode, int threads) {
  const Mesh<Hex8> mesh = scene::tear_sheet();
  auto s = std::make_unique<CuttingSolver>(mesh, Material{5e4, 0.4, 1050}, live_settings(mode, threads));
  s->fix(mesh.node_set("ymin"));
  s->fix(select_nodes(mesh, [](const Vec3& p) { return p.y() > 1e-9; }), DofMask{false, false, true});
  const TriangleSurface skin = scene::refined_boundary(mesh, 2);
  auto torn = std::make_unique<SolverScene<CuttingSolver>>("sheet", std::move(s), skin);
  TearingSettings tear;
  tear.strength = 1e4;
  torn->enable_tearing(tear, scene::sheet_nick());
  torn->set_planar_grasp();
  return torn;
}

/// The scene called `name` (organ, fat, sheet); InvalidArgument for another.
inline std::unique_ptr<Scene> make_scene(const std::string& name, NewmarkMode mode, int threads) {
  if (name == "organ") return organ(mode, threads);
  if (name == "fat") return fat(mode, threads);
  if (name == "sheet") return sheet(mode, threads);
  fail<InvalidArgument>("unknown scene '{}' (organ, fat, sheet)", name);
}

/// The cut a stroke makes: the stroke's points (rest positions on the surface, in order) swept
/// along `direction` through the body's whole depth (+-depth), one column of two triangles per
/// stroke segment. An open end (the stroke began or ended off the tissue) is carried on by
/// `depth` along its last segment, across the view: the cut goes through the tissue's edge
/// there instead of stopping at the last point the stroke touched.
inline CutSurface swept_stroke(std::vector<Vec3> stroke, Vec3 direction, Scalar depth, bool open_start = false,
                               bool open_end = false) {
  if (stroke.size() < 2) fail<InvalidArgument>("cut: a stroke needs at least 2 points on the body, got {}", stroke.size());
  if (!direction.allFinite() || direction.norm() < 1e-12) fail<InvalidArgument>("cut: the direction must be finite and non-zero");
  direction.normalize();
  Scalar length = 0;
  for (size_t i = 1; i < stroke.size(); ++i) length += (stroke[i] - stroke[i - 1]).norm();
  if (!(length > 1e-4)) fail<InvalidArgument>("cut: the stroke is {:.2g} mm long; draw across the body", 1e3 * length);
  auto carried = [&](const Vec3& end, const Vec3& inner) {
    Vec3 t = end - inner;
    t -= t.dot(direction) * direction;
    return t.norm() > 1e-9 ? Vec3(end + depth * t.normalized()) : end;
  };
  if (open_start) stroke.insert(stroke.begin(), carried(stroke[0], stroke[1]));
  if (open_end) stroke.push_back(carried(stroke[stroke.size() - 1], stroke[stroke.size() - 2]));
  std::vector<Vec3> v;
  std::vector<std::array<Index, 3>> t;
  for (const Vec3& p : stroke) {
    if (!p.allFinite()) fail<InvalidArgument>("cut: stroke points must be finite");
    v.push_back(p - depth * direction);
    v.push_back(p + depth * direction);
  }
  for (Index i = 0; i + 1 < static_cast<Index>(stroke.size()); ++i) {
    const Index a = 2 * i, b = a + 1, c = a + 2, d = a + 3;
    if ((stroke[static_cast<size_t>(i + 1)] - stroke[static_cast<size_t>(i)]).norm() < 1e-9) continue;  // repeated point
    t.push_back({a, c, d});
    t.push_back({a, d, b});
  }
  return CutSurface(v, t);
}

}  // namespace live
