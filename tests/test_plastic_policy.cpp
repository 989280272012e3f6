// A plastic policy written outside the library composes with Solver (issue 32: policies are
// types). `NodalCreep` below is a third plastic rule, unlike seed 000's two: wherever an
// element's stretch exceeds a threshold, its nodes' rest positions creep towards their current
// positions. It is defined here, from the PlasticModel and PlasticEngine concepts
// (plastic/plastic.hpp) alone, and checked against facts that hold for any such rule:
//  - with an infinite threshold it never flows, and the run is the elastic solver's bit for bit;
//  - its gate is objective: a rigid rotation of the whole body makes no flow;
//  - a bar pulled, held and let go keeps a permanent stretch, less than the stretch it was held
//    at, in dynamics (accurate and real time) and in statics (over its static_time);
//  - a step that fails after its first sub-step flowed leaves the plastic state bit for bit.
#include "catch.hpp"

#include <plastifem/plastic/table.hpp>  // the state it keeps: the library's PlasticTable
#include <plastifem/plastifem.hpp>

#include <Eigen/Eigenvalues>
#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <vector>

using namespace plastifem;

namespace {

/// The engine: what PlasticHooks calls (plastic/plastic.hpp, PlasticEngine). Its state is the
/// library's PlasticTable, of which it uses the material mesh `rest`, `version` and `off`.
template <FiniteElement E>
class NodalCreepEngine {
 public:
  template <class Body>
  void init(const Body& body, const PlasticParams&, PlasticTable& t) {
    const Mesh<E>& mesh = body.mesh();
    t.rest = Eigen::Map<const Vector>(mesh.nodes().data(), 3 * mesh.num_nodes());
    t.off.assign(static_cast<size_t>(mesh.num_elements()), 0);
    t.version = 0;
    synced_ = 0;
  }
  /// The body's element data to the table's rest shapes (every element: a test need not be fast).
  template <class Body>
  bool sync(Body& body, const PlasticTable& t, int threads) {
    if (t.version == synced_) return false;
    const Mesh<E>& mesh = body.mesh();
    std::vector<Index> all(static_cast<size_t>(mesh.num_elements()));
    for (Index e = 0; e < mesh.num_elements(); ++e) all[static_cast<size_t>(e)] = e;
    body.set_rest_shapes(all, [&](Index e) { return mesh.element_nodes(e, t.rest); }, threads);
    body.set_rest_displacement(t.rest - Eigen::Map<const Vector>(mesh.nodes().data(), 3 * mesh.num_nodes()));
    synced_ = t.version;
    return true;
  }
  /// The rule: an element whose stretch U (F = R U at its centre, against its rest shape) is
  /// further than tau = yield_stress (here a strain, |U - I|_F) from I gives its nodes the share
  /// g = min(1, flow_rate dt) (1 - tau / |U - I|); a node's rest position moves by the largest
  /// share of its elements towards its current position. Anchored nodes stay put.
  template <class Body>
  PlasticReport update(const Body& body, const Vector& u, Scalar dt, const PlasticParams& prm, PlasticTable& t,
                       std::uint64_t version, int, const std::vector<char>& anchor) {
    const Mesh<E>& mesh = body.mesh();
    PlasticReport rep;
    share_.assign(static_cast<size_t>(mesh.num_nodes()), 0.0);
    const Vec3 centre = reference_centre<E>();
    for (Index e = 0; e < mesh.num_elements(); ++e) {
      if (t.off[static_cast<size_t>(e)]) continue;
      const ElementNodes<E> X = mesh.element_nodes(e, t.rest);
      ElementNodes<E> x;
      for (int a = 0; a < E::num_nodes; ++a) {
        const Index i = mesh.element(e)[static_cast<size_t>(a)];
        x.col(a) = mesh.node(i) + u.template segment<3>(3 * i);
      }
      const Mat3 F = jacobian<E>(x, centre) * jacobian<E>(X, centre).inverse();
      Eigen::SelfAdjointEigenSolver<Mat3> eig(F.transpose() * F);
      const Mat3 U = eig.eigenvectors() * eig.eigenvalues().cwiseSqrt().asDiagonal() * eig.eigenvectors().transpose();
      const Scalar stretch = (U - Mat3::Identity()).norm();
      if (!(stretch > prm.yield_stress)) continue;
      const Scalar g = std::min(Scalar(1), prm.flow_rate * dt) * (1 - prm.yield_stress / stretch);
      for (Index i : mesh.element(e)) share_[static_cast<size_t>(i)] = std::max(share_[static_cast<size_t>(i)], g);
      ++rep.elements_changed;
      rep.max_gamma = std::max(rep.max_gamma, g);
    }
    if (rep.elements_changed == 0) return rep;
    for (Index i = 0; i < mesh.num_nodes(); ++i) {
      if (static_cast<size_t>(i) < anchor.size() && anchor[static_cast<size_t>(i)]) continue;
      const Vec3 x = mesh.node(i) + u.template segment<3>(3 * i);
      t.rest.template segment<3>(3 * i) += share_[static_cast<size_t>(i)] * (x - t.rest.template segment<3>(3 * i));
    }
    t.version = version;
    return rep;
  }
  void change_params(const PlasticParams&, const PlasticParams&, PlasticTable&) const {}
  void pattern_changed() {}

 private:
  std::uint64_t synced_ = 0;
  std::vector<Scalar> share_;
};

/// The policy: a name, active, its parameters, its state and its engine. Nothing else.
struct NodalCreep {
  static constexpr const char* name = "NodalCreep";
  static constexpr bool active = true;
  using Params = PlasticParams;
  using State = PlasticTable;
  template <FiniteElement E, class Elastic>
  using Engine = NodalCreepEngine<E>;
};
static_assert(PlasticModel<NodalCreep>);

const Material soft{3000, 0.45, 1.0};  // SCENES.md bar material

PlasticParams creep(Scalar threshold) {
  PlasticParams p;
  p.yield_stress = threshold;  // read by NodalCreep as a strain
  p.flow_rate = 1;
  return p;
}

/// The end position of the bar's free end face (mean x of its nodes' current positions).
template <class S>
Scalar end_x(const S& s) {
  Scalar sum = 0;
  const auto nodes = s.mesh().node_set("xmax");
  for (Index i : nodes) sum += s.mesh().node(i).x() + s.displacement(i).x();
  return sum / static_cast<Scalar>(nodes.size());
}

}  // namespace

TEST_CASE("a plastic policy written outside the library: an infinite threshold is the elastic run bit for bit",
          "[plasticity][policy]") {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(6, 2, 2);
  SolverSettings st;
  st.rayleigh_mass = 1;
  Solver<Hex8, Corotational> elastic(mesh, soft, st);
  Solver<Hex8, Corotational, NodalCreep> never(mesh, soft, st, creep(std::numeric_limits<Scalar>::infinity()));
  elastic.fix(mesh.node_set("xmin"));
  never.fix(mesh.node_set("xmin"));
  elastic.add_gravity(Vec3(0, 0, -9.81));
  never.add_gravity(Vec3(0, 0, -9.81));
  for (int k = 0; k < 30; ++k) {
    elastic.step(0.01);
    never.step(0.01);
  }
  CHECK(never.displacement() == elastic.displacement());
  CHECK(never.velocity() == elastic.velocity());
  CHECK(never.state().plastic.version == 0);
  CHECK(elastic.displacement().cwiseAbs().maxCoeff() > 0.1);  // it did bend
}

TEST_CASE("a plastic policy written outside the library: a rigid rotation makes no flow", "[plasticity][policy]") {
  // The whole bar turned about z by up to 90 degrees, prescribed at every node: F = R, U = I.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(4, 1, 1);
  Solver<Hex8, Corotational, NodalCreep> s(mesh, soft, {}, creep(1e-6));
  std::vector<Index> all(static_cast<size_t>(mesh.num_nodes()));
  for (Index i = 0; i < mesh.num_nodes(); ++i) all[static_cast<size_t>(i)] = i;
  s.prescribe(all, [](Scalar t, const Vec3& X) {
    const Scalar a = std::numbers::pi / 2 * std::min(t, Scalar(1));
    return Vec3(std::cos(a) * X.x() - std::sin(a) * X.y() - X.x(), std::sin(a) * X.x() + std::cos(a) * X.y() - X.y(), 0);
  });
  for (int k = 0; k < 100; ++k) CHECK(s.step(0.01).plastic.elements_changed == 0);
  CHECK(s.state().plastic.version == 0);
  CHECK(s.displacement().cwiseAbs().maxCoeff() > 1);  // it did turn
}

TEST_CASE("a plastic policy written outside the library: a bar pulled, held and let go keeps a permanent stretch",
          "[plasticity][policy]") {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(8, 2, 2);
  const Scalar L = 8, force = 600;  // stretches the 8 m bar by F L / (E A) = 0.4 m elastically (strain 0.05)
  auto pulled = [&](auto& s) {
    s.fix(mesh.node_set("xmin"));
    return s.add_traction(mesh.face_set("xmax"), Vec3(force / 4, 0, 0), ramp_hold_release(0.5, 1.5));
  };
  SECTION("dynamics, accurate and real time") {
    for (NewmarkMode mode : {NewmarkMode::Accurate, NewmarkMode::RealTime}) {
      SolverSettings st;
      st.newmark.mode = mode;
      st.rayleigh_mass = 3;  // settles within the run once let go
      Solver<Hex8, Corotational, NodalCreep> s(mesh, soft, st, creep(0.02));
      Solver<Hex8, Corotational> e(mesh, soft, st);
      pulled(s);
      pulled(e);
      Scalar held = 0;
      for (int k = 1; k <= 400; ++k) {
        s.step(0.01);
        e.step(0.01);
        if (k == 150) held = end_x(s) - L;  // the stretch it is held at, just before the release
      }
      const Scalar set = end_x(s) - L, elastic = end_x(e) - L;
      INFO((mode == NewmarkMode::Accurate ? "accurate" : "real time")
           << ": held at " << held << ", permanent " << set << ", elastic " << elastic);
      CHECK(held > 0.3);
      CHECK(set > 0.1 * held);        // it kept a visible share of the stretch ...
      CHECK(set < held);              // ... but sprang back some: the clamp and the end keep strain
      // The elastic bar came back: mass damping decays the release's oscillation as
      // exp(-alpha t / 2) = exp(-3.75) = 2.4% of its amplitude (the held stretch) in 2.5 s.
      CHECK(std::abs(elastic) < 0.03 * held);
      CHECK(s.state().plastic.version > 0);
    }
  }
  SECTION("statics: the flow over static_time per solve") {
    Solver<Hex8, Corotational, NodalCreep> s(mesh, soft, {}, creep(0.02));
    s.fix(mesh.node_set("xmin"));
    const LoadHandle h = s.add_traction(mesh.face_set("xmax"), Vec3(force / 4, 0, 0));
    const StepReport r = s.solve_static(4);
    CHECK(r.plastic.elements_changed > 0);
    CHECK(r.relative_residual <= 1e-6);
    const Scalar held = end_x(s) - L;
    s.remove_load(h);
    s.solve_static();
    const Scalar set = end_x(s) - L;
    INFO("held at " << held << ", permanent " << set);
    CHECK(set > 0.01 * held);
    CHECK(set < held);
  }
  SECTION("a failed step after flow leaves the plastic state as it was") {
    Solver<Hex8, Corotational, NodalCreep> s(mesh, soft, {}, creep(0.02));
    pulled(s);
    for (int k = 0; k < 100; ++k) s.step(0.01);
    REQUIRE(s.state().plastic.version > 0);
    // A load that cannot be evaluated past t0 + dt / 2: the step fails, is cut in halves, and
    // its first half converges and flows (into the working copy) before the second fails,
    // down to the smallest cut. The committed state, plastic table included, is untouched.
    const Scalar t0 = s.time();
    const LoadHandle bad = s.add_nodal_force(mesh.node_set("xmax"), Vec3(1, 0, 0), [t0](Scalar t) -> Scalar {
      if (t > t0 + 0.005 + 1e-12) throw SolverError("the load cannot be evaluated past t0 + dt / 2");
      return 0;
    });
    const auto before = s.state();
    CHECK_THROWS_AS(s.step(0.01), SolverError);
    CHECK(s.state() == before);
    // The half step that the failed step's first sub-step was does flow on its own.
    s.remove_load(bad);
    s.step(0.005);
    CHECK(s.state().plastic.version != before.plastic.version);
  }
}
