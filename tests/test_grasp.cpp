// Prescribed motion in dynamics: a grasper that pulls tissue, holds, and lets go.
//
// Facts checked:
//  - the velocity and acceleration at constrained dofs are the prescribed path's derivatives:
//    exactly 0 while a grasp holds still, the ramp's slope (and zero acceleration) on a ramp,
//    and the analytic derivatives of a sine (to the one-sided differences' truncation,
//    (h omega)^2 ~ 4e-7, when only the displacement is given; exactly when they are given);
//  - during a held grasp with damping, the reaction converges to the static reaction of the
//    same held displacement (an independent static solve);
//  - after release the nodes move on freely from their current velocity and the total energy
//    of the damped system does not grow;
//  - constraint sets are handles: released, replaced, and an earlier set on the same dofs
//    applies again when a later one is released.
#include "catch.hpp"

#include <plastifem/plastifem.hpp>

#include <fmt/core.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <tuple>

using namespace plastifem;

namespace {

const Material soft{3000, 0.45, 1.0};  // SCENES.md bar material

/// The four nodes at the centre of the bar's free end face (x = nx, y and z in [1, ny - 1]).
template <FiniteElement E>
std::vector<Index> end_centre_nodes(const Mesh<E>& mesh, Scalar nx, Scalar ny, Scalar nz) {
  return select_nodes(mesh, [&](const Vec3& p) {
    return std::abs(p.x() - nx) < 1e-9 && p.y() > 0.9 && p.y() < ny - 0.9 && p.z() > 0.9 && p.z() < nz - 0.9 &&
           std::abs(p.y() - std::round(p.y())) < 1e-9 && std::abs(p.z() - std::round(p.z())) < 1e-9;
  });
}

Vec3 sum_at(const Vector& f, const std::vector<Index>& nodes) {
  Vec3 s = Vec3::Zero();
  for (Index i : nodes) s += f.template segment<3>(3 * i);
  return s;
}

/// Grasp, stretch (0 -> 0.5 in z over 1 s), hold, release: bar90 with gravity and mass
/// damping, the SCENES bar otherwise.
template <FiniteElement E>
void grasp_stretch_hold_release(MassKind mass) {
  const Mesh<E> mesh = bar_mesh<E>(10, 3, 3);
  const std::vector<Index> grasped = end_centre_nodes(mesh, 10, 3, 3);
  REQUIRE(grasped.size() == 4);
  SolverSettings s;
  s.mass = mass;
  // Rayleigh damping: mass alpha = 5 (with both ends held, bar90's lowest mode, fixed-fixed
  // beam omega_1 ~ 10 rad/s from beam theory, decays like exp(-alpha t / 2): a 5 s hold leaves
  // 4e-6 of the motion the ramp's stop excited) and stiffness beta = 2e-3 on K0 (damping ratio
  // beta omega / 2 ~ 0.5 at omega ~ 500 rad/s: the stiff modes, which the trapezoidal rule
  // does not dissipate and mass damping barely reaches at omega dt >> 1).
  s.rayleigh_mass = 5;
  s.rayleigh_stiffness = 2e-3;
  Solver<E, Corotational> solver(mesh, soft, s);
  solver.fix(mesh.node_set("xmin"));
  solver.add_gravity(Vec3(0, 0, -9.81));
  const Scalar dt = 0.01;
  const ConstraintHandle grasp = solver.grasp(grasped, [](Scalar t) { return Vec3(0, 0, 0.5 * std::min(t, 1.0)); });
  std::vector<Index> grasped_dofs, free_dofs;
  for (Index i : grasped)
    for (int d = 0; d < 3; ++d) grasped_dofs.push_back(3 * i + d);
  for (Index d = 0; d < solver.num_dofs(); ++d)
    if (!solver.is_constrained(d)) free_dofs.push_back(d);

  // Ramp: v = (0, 0, 0.5) and a = 0 at every grasped dof after every step.
  Scalar ramp_v_error = 0, ramp_a = 0, free_a_peak = 0;
  for (int k = 0; k < 100; ++k) {
    solver.step(dt);
    for (Index i : grasped) {
      ramp_v_error = std::max(ramp_v_error, (solver.velocity().template segment<3>(3 * i) - Vec3(0, 0, 0.5)).norm());
      ramp_a = std::max(ramp_a, solver.acceleration().template segment<3>(3 * i).norm());
    }
    for (Index d : free_dofs) free_a_peak = std::max(free_a_peak, std::abs(solver.acceleration()[d]));
  }
  // Hold for 5 s: v = a = 0 exactly at the grasped dofs (the path is constant, its
  // differences are exact zeros); the reaction settles.
  Scalar hold_va = 0;
  std::vector<Vec3> reaction;
  for (int k = 0; k < 500; ++k) {
    solver.step(dt);
    for (Index d : grasped_dofs) hold_va = std::max({hold_va, std::abs(solver.velocity()[d]), std::abs(solver.acceleration()[d])});
    for (Index d : free_dofs) free_a_peak = std::max(free_a_peak, std::abs(solver.acceleration()[d]));
    reaction.push_back(sum_at(solver.reaction_forces(), grasped));
  }
  // The same held displacement in statics: the grasped nodes fixed where the grasp holds them.
  Solver<E, Corotational> statics(mesh, soft, s);
  statics.fix(mesh.node_set("xmin"));
  statics.add_gravity(Vec3(0, 0, -9.81));
  std::vector<Vec3> held;
  for (Index i : grasped) held.push_back(solver.displacement(i));
  statics.prescribe(grasped, [&](Scalar, const Vec3& X) {
    for (size_t k = 0; k < grasped.size(); ++k)
      if ((mesh.node(grasped[k]) - X).norm() == 0) return held[k];
    return Vec3(Vec3::Zero());
  });
  statics.solve_static(4);
  const Vec3 R_static = sum_at(statics.reaction_forces(), grasped);
  const Vec3 R_end = reaction.back();
  // Smoothness: the reaction history during the hold has no step-to-step oscillation (it
  // alternated by +-12,900 around ~61 when v and a came from Newmark-differencing the path).
  Scalar jump = 0;
  for (size_t k = 1; k < reaction.size(); ++k) jump = std::max(jump, (reaction[k] - reaction[k - 1]).norm());

  // Release: the nodes move on from their current velocity (zero after the hold); the total
  // energy (kinetic + strain - work of gravity) of the damped system does not grow.
  auto energy = [&] { return solver.kinetic_energy() + solver.strain_energy() - solver.external_work_potential(); };
  solver.release(grasp);
  const Scalar E0 = energy();
  Scalar E_max = E0, moved = 0;
  const Vector u_release = solver.displacement();
  for (int k = 0; k < 100; ++k) {
    solver.step(dt);
    E_max = std::max(E_max, energy());
  }
  for (Index i : grasped) moved = std::max(moved, (solver.displacement(i) - u_release.template segment<3>(3 * i)).norm());

  fmt::print("grasp {:5} {:10}: ramp |v - 0.5| {:.1e}, |a| {:.1e}; hold max |v|,|a| {:.1e}; free |a| peak {:.3g}; "
             "reaction end {:.4f} vs static {:.4f} (rel {:.1e}), max step jump {:.3g}; release: moved {:.3f}, "
             "energy {:.6g} -> max {:.6g}\n",
             E::name, mass == MassKind::Lumped ? "lumped" : "consistent", ramp_v_error, ramp_a, hold_va, free_a_peak,
             R_end.z(), R_static.z(), (R_end - R_static).norm() / R_static.norm(), jump, moved, E0, E_max);
  // The ramp's slope: one-sided differences are exact for a linear path up to the round-off
  // of the path values (~eps |g| / h = 1e-12 at h = 1e-4); the kink at t = 1 s falls on a step.
  CHECK(ramp_v_error < 1e-9);
  CHECK(ramp_a < 1e-5);  // second differences: ~12 eps |g| / h^2 = 6e-8; 1e-5 with room
  CHECK(hold_va == 0);
  // Reaction within 1e-5 of the static one (the issue asks 1e-3): what the damping has not yet
  // removed (4e-6 of the motion) plus the Newton tolerance of both solves (1e-6 relative);
  // measured 3e-7 to 4e-7.
  CHECK((R_end - R_static).norm() <= 1e-5 * R_static.norm());
  // No alternation: consecutive reactions differ by a small fraction of the reaction.
  CHECK(jump < 0.2 * R_static.norm());
  // Free nodes: accelerations of the physical motion, not the 1e4-scale echo of differencing.
  CHECK(free_a_peak < 500);
  CHECK(moved > 0.05);  // released: the pulled end falls back
  CHECK(E_max <= E0 + 1e-6 * std::abs(E0));
}

}  // namespace

TEST_CASE("prescribed path derivatives: ramp, hold, sine - given derivatives are used exactly", "[grasp][path]") {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(4, 1, 1);
  const std::vector<Index> end = mesh.node_set("xmax");
  const Scalar A = 0.05, w = 2 * std::numbers::pi;
  SECTION("a sine given by its displacement only: one-sided differences of second order") {
    Solver<Hex8, Corotational> s(mesh, soft);
    s.fix(mesh.node_set("xmin"));
    s.prescribe(end, [&](Scalar t, const Vec3&) { return Vec3(0, 0, A * std::sin(w * t)); });
    Scalar ev = 0, ea = 0;
    for (int k = 0; k < 60; ++k) {
      s.step(0.01);
      const Scalar t = s.time();
      for (Index i : end) {
        ev = std::max(ev, std::abs(s.velocity()[3 * i + 2] - A * w * std::cos(w * t)) / (A * w));
        ea = std::max(ea, std::abs(s.acceleration()[3 * i + 2] + A * w * w * std::sin(w * t)) / (A * w * w));
      }
    }
    fmt::print("sine path, differences: max relative error v {:.2e}, a {:.2e}\n", ev, ea);
    // Truncation (h omega)^2 / 3 = 1.3e-7 for v and (h omega)^2 11/12 = 3.6e-7 for a at
    // h = 1e-4; round-off 12 eps |g| / (h^2 A omega^2) ~ 7e-8. 2e-6 bounds both.
    CHECK(ev < 2e-6);
    CHECK(ea < 2e-6);
  }
  SECTION("with the derivatives given, they are the state's, bit for bit") {
    Solver<Hex8, Corotational> s(mesh, soft);
    s.fix(mesh.node_set("xmin"));
    s.prescribe(end, PrescribedMotion{[&](Scalar t, const Vec3&) { return Vec3(0, 0, A * std::sin(w * t)); },
                                      [&](Scalar t, const Vec3&) { return Vec3(0, 0, A * w * std::cos(w * t)); },
                                      [&](Scalar t, const Vec3&) { return Vec3(0, 0, -A * w * w * std::sin(w * t)); }});
    for (int k = 0; k < 20; ++k) {
      s.step(0.01);
      const Scalar t = s.time();
      for (Index i : end) {
        REQUIRE(s.velocity()[3 * i + 2] == A * w * std::cos(w * t));
        REQUIRE(s.acceleration()[3 * i + 2] == -A * w * w * std::sin(w * t));
        REQUIRE(s.displacement()[3 * i + 2] == A * std::sin(w * t));
      }
    }
  }
  SECTION("a velocity alone: the acceleration is its difference") {
    Solver<Hex8, Corotational> s(mesh, soft);
    s.fix(mesh.node_set("xmin"));
    s.prescribe(end, PrescribedMotion{[&](Scalar t, const Vec3&) { return Vec3(0, 0, A * std::sin(w * t)); },
                                      [&](Scalar t, const Vec3&) { return Vec3(0, 0, A * w * std::cos(w * t)); },
                                      {}});
    s.step(0.01);
    const Scalar t = s.time();
    CHECK(s.acceleration()[3 * end[0] + 2] == Approx(-A * w * w * std::sin(w * t)).epsilon(1e-6));
  }
  SECTION("a motion with a velocity but no displacement is refused") {
    Solver<Hex8, Corotational> s(mesh, soft);
    CHECK_THROWS_AS(s.prescribe(end, PrescribedMotion{{}, [](Scalar, const Vec3&) { return Vec3(1, 0, 0); }, {}}),
                    InvalidArgument);
  }
}

// One case per element and mass kind: they run in parallel (the four took 99 s in one case
// under the sanitizers).
TEMPLATE_TEST_CASE("grasp, stretch, hold and release on bar90, consistent mass", "[grasp][dynamics]", Hex8, Tet10) {
  grasp_stretch_hold_release<TestType>(MassKind::Consistent);
}

TEMPLATE_TEST_CASE("grasp, stretch, hold and release on bar90, lumped mass", "[grasp][dynamics]", Hex8, Tet10) {
  grasp_stretch_hold_release<TestType>(MassKind::Lumped);
}

TEST_CASE("constraint handles: release mid-ramp keeps the velocity, replace changes the path, sets stack",
          "[grasp][handles]") {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(4, 1, 1);
  const std::vector<Index> end = mesh.node_set("xmax");
  SECTION("released mid-ramp: the nodes keep moving at the ramp's speed") {
    Solver<Hex8, Linear> s(mesh, soft);
    s.fix(mesh.node_set("xmin"));
    const auto h = s.prescribe(end, [](Scalar t, const Vec3&) { return Vec3(0, 0, 0.2 * t); });
    for (int k = 0; k < 10; ++k) s.step(0.01);
    s.release(h);
    const Scalar z0 = s.displacement(end[0]).z();
    s.step(0.001);  // a short step: the nodes move on at ~0.2 (their velocity), not back to rest
    const Scalar v = (s.displacement(end[0]).z() - z0) / 0.001;
    INFO("velocity over the first step after release: " << v);
    // It moves on at the ramp's 0.2, slowed only by the elastic pull over 1 ms (measured
    // 0.195); a release that snapped back or stayed clamped would give <= 0.
    CHECK(v == Approx(0.2).epsilon(0.05));
    CHECK_FALSE(s.is_constrained(3 * end[0] + 2));
    CHECK_THROWS_AS(s.release(h), InvalidArgument);  // a handle names its set once
  }
  SECTION("replace: the set follows a new path from the next step on") {
    Solver<Hex8, Linear> s(mesh, soft);
    s.fix(mesh.node_set("xmin"));
    const auto h = s.prescribe(end, [](Scalar, const Vec3&) { return Vec3(0, 0, 0.1); });
    s.step(0.01);
    s.replace(h, PrescribedMotion{[](Scalar, const Vec3&) { return Vec3(0, 0.05, 0.1); }, {}, {}});
    s.step(0.01);
    CHECK(s.displacement(end[0]) == Vec3(0, 0.05, 0.1));
  }
  SECTION("a later set wins on shared dofs; releasing it brings back the earlier one") {
    Solver<Hex8, Linear> s(mesh, soft);
    s.fix(mesh.node_set("xmin"));
    s.fix(end);
    const auto lift = s.prescribe(end, [](Scalar, const Vec3&) { return Vec3(0, 0, 0.1); });
    s.step(0.01);
    CHECK(s.displacement(end[0]).z() == 0.1);
    s.release(lift);
    s.step(0.01);
    CHECK(s.displacement(end[0]).z() == 0);  // fixed again by the first set
    CHECK(s.is_constrained(3 * end[0] + 2));
  }
  SECTION("a grasp starts where the nodes are") {
    Solver<Hex8, Corotational> s(mesh, soft);
    s.fix(mesh.node_set("xmin"));
    s.add_gravity(Vec3(0, 0, -9.81));
    for (int k = 0; k < 20; ++k) s.step(0.01);
    const Vec3 before = s.displacement(end[0]);
    s.grasp(end, [](Scalar t) { return Vec3(t, 0, 0); });
    s.step(0.01);
    CHECK((s.displacement(end[0]) - before - Vec3(0.01, 0, 0)).norm() < 1e-12);
  }
}

TEST_CASE("constraint and load handles name their own solver's sets: another solver's handle is refused",
          "[grasp][handles]") {
  // Issue 33 item 12: handles were bare counters, so the first set of one solver and the first
  // of another had equal handles, and release() with the other solver's handle released this
  // solver's own clamp (remove_load, this solver's own load).
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(4, 1, 1);
  Solver<Hex8, Linear> a(mesh, soft), b(mesh, soft);
  const ConstraintHandle clamp_a = a.fix(mesh.node_set("xmin"));
  const ConstraintHandle clamp_b = b.fix(mesh.node_set("xmin"));
  const LoadHandle load_a = a.add_gravity(Vec3(0, 0, -9.81));
  const LoadHandle load_b = b.add_gravity(Vec3(0, 0, -9.81));
  const Index clamped_dof = 3 * mesh.node_set("xmin")[0];
  auto refused = [](const char* what, const auto& call) {
    try {
      call();
    } catch (const InvalidArgument& e) {
      fmt::print("{}: refused: {}\n", what, e.what());
      return std::string(e.what()).find("another solver") != std::string::npos;
    }
    fmt::print("{}: accepted\n", what);
    return false;
  };
  CHECK(refused("a.release(b's clamp)", [&] { a.release(clamp_b); }));
  CHECK(a.is_constrained(clamped_dof));  // a's own clamp holds
  CHECK(refused("a.replace(b's clamp)", [&] { a.replace(clamp_b, PrescribedMotion{}); }));
  CHECK(refused("a.remove_load(b's gravity)", [&] { a.remove_load(load_b); }));
  // The handles are unequal, though each is its solver's first of its kind.
  CHECK_FALSE(clamp_a == clamp_b);
  CHECK_FALSE(load_a == load_b);
  // Each solver's own handles still work, once.
  a.remove_load(load_a);
  a.release(clamp_a);
  CHECK_FALSE(a.is_constrained(clamped_dof));
  CHECK(b.is_constrained(clamped_dof));  // b's untouched
  b.release(clamp_b);
  b.remove_load(load_b);
  CHECK_THROWS_AS(a.release(clamp_a), InvalidArgument);
  CHECK_THROWS_AS(a.remove_load(load_a), InvalidArgument);
  // A default-constructed handle names nothing.
  CHECK_THROWS_AS(a.release(ConstraintHandle{}), InvalidArgument);
  CHECK_THROWS_AS(a.remove_load(LoadHandle{}), InvalidArgument);
}

TEST_CASE("device samples: a path through readings, linear between them, extended at the last velocity",
          "[grasp][path]") {
  DeviceSamples d(1.0, Vec3(0, 0, 1));
  const auto g = d.path();
  CHECK(g(0.5) == Vec3(0, 0, 1));  // before the first sample, and with one sample: that sample
  CHECK(g(2.0) == Vec3(0, 0, 1));
  d.add(1.5, Vec3(0, 1, 2));
  CHECK((g(1.25) - Vec3(0, 0.5, 1.5)).norm() < 1e-15);
  CHECK((g(2.0) - Vec3(0, 2, 3)).norm() < 1e-15);  // on at the last segment's velocity
  for (int k = 0; k < 20; ++k) d.add(2.0 + k, Vec3(k, 0, 0));  // more than the kept window
  CHECK((g(20.5) - Vec3(18.5, 0, 0)).norm() < 1e-12);
  CHECK_THROWS_AS(d.add(21.0, Vec3(0, 0, 0)), InvalidArgument);  // not after the last
  CHECK_THROWS_AS(d.add(30.0, Vec3(0, std::nan(""), 0)), InvalidArgument);
  CHECK_THROWS_AS(d.add(std::numeric_limits<Scalar>::infinity(), Vec3(0, 0, 0)), InvalidArgument);
  // A recorded trajectory queued ahead is followed from its start (found by review, 2026-12-01:
  // only the last 8 samples were kept, and the path gave the 13th at t = 0 and at 0.05).
  DeviceSamples ahead(0, Vec3::Zero());
  for (int k = 1; k <= 20; ++k) ahead.add(0.01 * k, Vec3(0, 0, 0.01 * k));
  const auto h = ahead.path();
  CHECK(h(0) == Vec3::Zero());
  CHECK((h(0.05) - Vec3(0, 0, 0.05)).norm() < 1e-15);
  CHECK((h(0.155) - Vec3(0, 0, 0.155)).norm() < 1e-15);
  // Past the capacity the oldest samples go, and a time before those kept is refused.
  DeviceSamples many(0, Vec3::Zero());
  const Scalar n = static_cast<Scalar>(DeviceSamples::capacity);
  for (int k = 1; k <= static_cast<int>(DeviceSamples::capacity) + 10; ++k) many.add(k, Vec3(k, 0, 0));
  CHECK_THROWS_AS(many.path()(5.0), InvalidArgument);
  CHECK((many.path()(n + 0.5) - Vec3(n + 0.5, 0, 0)).norm() < 1e-9);
}

TEST_CASE("a path defined from the start time only moves its nodes from the first step", "[grasp][path]") {
  // A step's initial acceleration took the path's derivatives from the left, at t - 1e-4 ...
  // t - 3e-4: a recorded table that starts at t = 0 (and throws before it, or gives NaN) made
  // the first step fail (found by review, 2026-12-01). The initial acceleration is the right
  // limit, over [t, t + 3h]: what the step that starts at t needs.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(4, 1, 1);
  for (const NewmarkMode mode : {NewmarkMode::Accurate, NewmarkMode::RealTime})
    for (const bool nan_before : {false, true}) {
      INFO((mode == NewmarkMode::RealTime ? "real time" : "accurate") << (nan_before ? ", NaN before 0" : ", throws before 0"));
      SolverSettings settings;
      settings.newmark.mode = mode;
      Solver<Hex8, Corotational> s(mesh, soft, settings);
      s.fix(mesh.node_set("xmin"));
      s.prescribe(mesh.node_set("xmax"), [nan_before](Scalar t, const Vec3&) {
        if (t < 0) {
          if (nan_before) return Vec3(0, 0, std::numeric_limits<Scalar>::quiet_NaN());
          throw std::out_of_range("the table starts at t = 0");
        }
        return Vec3(0, 0, 0.5 * t * t);  // a = 1 from the start
      });
      for (int k = 0; k < 5; ++k) s.step(0.01);
      for (Index i : mesh.node_set("xmax")) {
        CHECK(s.displacement()[3 * i + 2] == Approx(0.5 * 0.05 * 0.05).epsilon(1e-12));
        CHECK(s.acceleration()[3 * i + 2] == Approx(1).epsilon(1e-6));  // second differences, h = 1e-4 (round-off 1e-8)
      }
    }
}

TEST_CASE("a grasp driven by device samples moves at their velocity, with the reaction of the smooth path",
          "[grasp][dynamics]") {
  // Issue 33 item 11: a grasp whose path returns the device's latest reading (updated between
  // steps) is a staircase: its velocity is 0 inside every step, so with Rayleigh beta 0.01 the
  // reaction was off by up to 45.6 (static 60.9). Driven through DeviceSamples (each reading
  // the position for the end of the coming step) the grasp of the end of bar90 lifted at 0.5
  // follows the same path as the analytic one, 0.5 t: same states, same reactions.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  const std::vector<Index> end = mesh.node_set("xmax");
  SolverSettings st;
  st.rayleigh_stiffness = 0.01;
  auto sum_z = [&](const Vector& r) {
    Scalar z = 0;
    for (Index i : end) z += r[3 * i + 2];
    return z;
  };
  enum class Drive { analytic, samples, latest_reading, noisy_samples };
  auto run = [&](Drive drive) {
    Solver<Hex8, Corotational> s(mesh, soft, st);
    s.fix(mesh.node_set("xmin"));
    DeviceSamples device(0, Vec3::Zero());
    Vec3 latest = Vec3::Zero();
    std::mt19937 rng(3);
    std::uniform_real_distribution<Scalar> noise(-1e-3, 1e-3);
    if (drive == Drive::analytic) s.grasp(end, [](Scalar t) { return Vec3(0, 0, 0.5 * t); });
    else if (drive == Drive::latest_reading) s.grasp(end, [&latest](Scalar) { return latest; });
    else s.grasp(end, device.path());
    std::vector<Scalar> reaction, velocity;
    for (int k = 1; k <= 100; ++k) {
      const Scalar t = 0.01 * k;
      const Vec3 reading(0, 0, 0.5 * t + (drive == Drive::noisy_samples ? noise(rng) : 0.0));
      device.add(t, reading);
      latest = reading;
      s.step(0.01);
      reaction.push_back(sum_z(s.reaction_forces()));
      velocity.push_back(s.velocity()[3 * end[0] + 2]);
    }
    return std::pair{reaction, velocity};
  };
  const auto [r_exact, v_exact] = run(Drive::analytic);
  const auto [r_samples, v_samples] = run(Drive::samples);
  const auto [r_latest, v_latest] = run(Drive::latest_reading);
  const auto [r_noisy, v_noisy] = run(Drive::noisy_samples);
  Scalar scale = 0, d_samples = 0, d_latest = 0, d_noisy = 0, v_latest_max = 0;
  for (size_t k = 0; k < r_exact.size(); ++k) {
    scale = std::max(scale, std::abs(r_exact[k]));
    d_samples = std::max(d_samples, std::abs(r_samples[k] - r_exact[k]));
    d_latest = std::max(d_latest, std::abs(r_latest[k] - r_exact[k]));
    d_noisy = std::max(d_noisy, std::abs(r_noisy[k] - r_exact[k]));
    v_latest_max = std::max(v_latest_max, std::abs(v_latest[k]));
    CHECK(std::abs(v_samples[k] - 0.5) < 1e-9);
  }
  INFO("largest reaction " << scale << "; off by: samples " << d_samples << ", latest reading " << d_latest
                           << ", samples with +-1e-3 noise " << d_noisy << "; the latest reading's velocity at most "
                           << v_latest_max);
  CHECK(d_samples <= 1e-9 * scale);  // the same linear path: round-off
  CHECK(v_latest_max == 0);          // the staircase the samples replace
  CHECK(d_latest > 0.1 * scale);
  CHECK(std::isfinite(d_noisy));
}

TEST_CASE("a prescribed path that jumps: derivatives from after the jump, kinks and smooth paths are not jumps",
          "[grasp][path]") {
  // Constraints::evaluate at t with dt = 0.125: h = 1e-4, the differences look back to t - 3h.
  const std::vector<Index> node{0};
  auto derivatives = [&](PrescribedDisplacement g, Scalar t) {
    Constraints c(1);
    c.add(node, PrescribedMotion{std::move(g), {}, {}}, DofMask{});
    Vector u = Vector::Zero(3), v = Vector::Zero(3), a = Vector::Zero(3);
    const Index jumps = c.evaluate(t, 0.125, [](Index) { return Vec3::Zero(); }, u, &v, &a);
    return std::tuple{jumps, Scalar(u[2]), Scalar(v[2]), Scalar(a[2])};
  };
  SECTION("a jump at t, and one inside the differences' window: the path after it, 2 t from t on") {
    for (const Scalar t_jump : {1.0, 1.0 - 1e-6, 1.0 - 2.9e-4}) {
      const auto [jumps, u, v, a] = derivatives(
          [=](Scalar t, const Vec3&) { return Vec3(0, 0, t < t_jump ? 0.5 * t : 2 * t - 1); }, 1.0);
      INFO("jump at " << t_jump << ": v " << v << ", a " << a);
      CHECK(jumps == 1);
      CHECK(u == 1.0);
      CHECK(std::abs(v - 2) < 1e-9);  // a linear path: exact up to round-off of 1 / h
      CHECK(std::abs(a) < 1e-3);      // round-off 16 eps / h^2 ~ 4e-7 of the values' size
    }
  }
  SECTION("a small jump on a fast path: 0.01 at 10 units/s, ten steps' motion of h") {
    const auto [jumps, u, v, a] =
        derivatives([](Scalar t, const Vec3&) { return Vec3(0, 0, 10 * t + (t < 1 ? 0.0 : 0.01)); }, 1.0);
    INFO("v " << v << ", a " << a);  // before the outlier test: v = 160, a = 2e6 (not found)
    CHECK(jumps == 1);
    CHECK(std::abs(v - 10) < 1e-6);
    CHECK(std::abs(a) < 1);  // round-off of 10 t over h^2
  }
  SECTION("a jump just before the window, a kink in it, a smooth turn: not jumps") {
    const auto [j0, u0, v0, a0] =
        derivatives([](Scalar t, const Vec3&) { return Vec3(0, 0, t < 1 - 3.1e-4 ? 0.0 : 1.0); }, 1.0);
    CHECK(j0 == 0);
    CHECK(v0 == 0);
    CHECK(a0 == 0);
    const auto [j1, u1, v1, a1] =
        derivatives([](Scalar t, const Vec3&) { return Vec3(0, 0, 0.5 * std::min(t, 1 - 1.5e-4)); }, 1.0);
    CHECK(j1 == 0);
    CHECK(std::isfinite(v1));
    const auto [j2, u2, v2, a2] =
        derivatives([](Scalar t, const Vec3&) { return Vec3(0, 0, std::cos(2 * std::numbers::pi * t)); }, 1.0);
    CHECK(j2 == 0);  // its velocity crosses zero at t = 1
    CHECK(std::abs(a2 + 4 * std::numbers::pi * std::numbers::pi) < 1e-4);
  }
}

TEST_CASE("a grasp whose path jumps: the state after the jump is the path's, and the steps go on",
          "[grasp][dynamics]") {
  // Issue 33 item 11's neighbour, item 10: the end of bar90 lifted at 0.5 t until t = 1 and
  // dropped back to 0 then (t < 1 ? 0.5 t : 0) committed v = -1.92e4 and a = -6.55e8 at t = 1, by
  // differences across the jump, and the next step failed. The step that ends at the jump now
  // takes the node's velocity and acceleration from the path after it (0 here) and says so in its
  // report; the following steps go on from there.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  const std::vector<Index> end = mesh.node_set("xmax");
  for (const NewmarkMode mode : {NewmarkMode::Accurate, NewmarkMode::RealTime}) {
    SolverSettings st;
    st.newmark.mode = mode;
    st.rayleigh_mass = 0.2;
    Solver<Hex8, Corotational> s(mesh, soft, st);
    s.fix(mesh.node_set("xmin"));
    s.prescribe(end, [](Scalar t, const Vec3&) { return Vec3(0, 0, t < 1 ? 0.5 * t : 0.0); });
    std::vector<std::string> notes;
    const NoteHandler previous = set_note_handler([&](const std::string& n) { notes.push_back(n); });
    Index reported = 0;
    Scalar v_max = 0, a_max = 0, free_max = 0;
    for (int k = 1; k <= 16; ++k) {  // dt = 1/8: t = 1 exactly at k = 8
      const StepReport r = s.step(0.125);
      reported += r.path_jumps;
      if (k == 8) CHECK(r.path_jumps == static_cast<Index>(end.size()));
      for (Index i : end) {
        v_max = std::max(v_max, std::abs(s.velocity()[3 * i + 2]));
        a_max = std::max(a_max, std::abs(s.acceleration()[3 * i + 2]));
        if (k >= 8) CHECK(s.displacement()[3 * i + 2] == 0.0);
      }
      free_max = std::max(free_max, s.displacement().cwiseAbs().maxCoeff());
    }
    set_note_handler(previous);
    REQUIRE(notes.size() == 1);  // the step that ends at the jump says so, once
    CHECK(notes[0].find("t = 1: the prescribed path (or given velocity) of 16 constrained node(s) jumps") !=
          std::string::npos);
    INFO((mode == NewmarkMode::Accurate ? "accurate" : "real time")
         << ": end nodes' largest |v| " << v_max << ", |a| " << a_max << "; largest |u| " << free_max);
    CHECK(reported == static_cast<Index>(end.size()));  // at t = 1 only
    CHECK(std::abs(v_max - 0.5) < 1e-9);  // the path's own before the jump (0 after), up to round-off
    CHECK(a_max < 1e-4);  // 0 for the linear path, up to round-off 16 eps / h^2
    CHECK(s.displacement().allFinite());
    CHECK(free_max < 1.0);  // the body follows the lift of 0.5 and its drop, nothing wild
  }
}
