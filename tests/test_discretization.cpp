// Discretization (assembly/discretization.hpp) on its own, without a Solver, each result
// against an independent fact:
//  - f_int is the central-difference gradient of the assembled energy, the exact tangent the
//    central-difference Jacobian of f_int;
//  - f_int and K are the element kernels (Elastic::prepare / evaluate, full matrices) scattered
//    by the elements' node ids, here into a dense matrix;
//  - rigid motions: no force at any rotation, six null vectors of the rest stiffness, which is
//    linear elasticity's;
//  - volume and element stress under homogeneous deformations against closed forms;
//  - the dof map (a slot added), invalid states (an inverted element) and rest-shape changes.
// Cuts (Enriched = true) are tested through the Solver in test_enrichment.cpp and
// test_plastic_cut.cpp; instantiating them here would cost the X-FEM headers' compile.
#include "catch.hpp"

#include <plastifem/assembly/discretization.hpp>
#include <plastifem/elastic/elastic.hpp>
#include <plastifem/mesh/generators.hpp>

#include "eigenvalues.hpp"

#include <fmt/core.h>

#include <cmath>
#include <limits>
#include <random>
#include <tuple>

using namespace plastifem;

namespace {

const Material soft{3000, 0.45, 1.0};
// The material's stiffness scale: the P-wave modulus lambda + 2 mu, from E and nu directly.
const Scalar lame_mu = 3000 / (2 * 1.45), lame_lambda = 3000 * 0.45 / (1.45 * 0.1), modulus = lame_lambda + 2 * lame_mu;

template <class E_, class M_>
struct Combo {
  using E = E_;
  using M = M_;
};
// One combination per element type, both models with an exact tangent on Hex8.
using Combos = std::tuple<Combo<Tet4, Corotational>, Combo<Tet10, NeoHookean>, Combo<Hex8, Corotational>,
                          Combo<Hex8, NeoHookean>, Combo<Wedge6, Corotational>>;

template <FiniteElement E>
Vector rest_positions(const Mesh<E>& mesh) {
  return Eigen::Map<const Vector>(mesh.nodes().data(), 3 * mesh.num_nodes());
}

/// u = A X + t (a homogeneous deformation F = I + A, translated).
template <FiniteElement E>
Vector affine(const Mesh<E>& mesh, const Mat3& A, const Vec3& t = Vec3::Zero()) {
  Vector u(3 * mesh.num_nodes());
  for (Index i = 0; i < mesh.num_nodes(); ++i) u.segment<3>(3 * i) = A * mesh.nodes().col(i) + t;
  return u;
}

Mat3 random_matrix(std::mt19937& rng, Scalar amplitude) {
  std::uniform_real_distribution<Scalar> r(-amplitude, amplitude);
  Mat3 G;
  for (int i = 0; i < 9; ++i) G.data()[i] = r(rng);
  return G;
}

const Mat3 big_rotation = Eigen::AngleAxisd(2.5, Vec3(1, -2, 0.5).normalized()).toRotationMatrix();

/// A random finite deformation: a large rotation of 15% homogeneous strain, plus 5% of the
/// (unit) cell size at random at each node. Not inverted anywhere.
template <FiniteElement E>
Vector finite_deformation(const Mesh<E>& mesh, std::mt19937& rng) {
  Vector u = affine(mesh, big_rotation * (Mat3::Identity() + random_matrix(rng, 0.15)) - Mat3::Identity());
  std::uniform_real_distribution<Scalar> r(-0.05, 0.05);
  for (Index k = 0; k < u.size(); ++k) u[k] += r(rng);
  return u;
}

template <class D>
Vector internal_force(const D& d, const Vector& u) {
  Vector f(d.num_dofs());
  REQUIRE(d.assemble(u, f, nullptr, TangentKind::Projected, 1));
  return f;
}

template <class D>
Eigen::MatrixXd tangent(const D& d, const Vector& u, TangentKind kind, Vector& f) {
  BlockSymmetricMatrix K = d.assembler().zero_matrix();
  f.resize(d.num_dofs());
  REQUIRE(d.assemble(u, f, &K, kind, 1));
  return Eigen::MatrixXd(K.to_sparse());
}

/// The independent assembly: every element's kernel, prepared from its mesh nodes and
/// evaluated with full (not lower-block) matrices, scattered into a dense matrix.
template <FiniteElement E, class M>
Scalar reference_assembly(const Mesh<E>& mesh, const Vector& u, TangentKind kind, Vector& f, Eigen::MatrixXd& K) {
  const Index n = 3 * mesh.num_nodes();
  const Vector x = rest_positions(mesh) + u.head(n);
  f.setZero(n);
  K.setZero(n, n);
  Scalar W = 0;
  ElementVector<E> fe;
  ElementMatrix<E> Ke;
  for (Index e = 0; e < mesh.num_elements(); ++e) {
    const auto data = M::template prepare<E>(mesh.element_nodes(e), soft);
    W += M::template evaluate<E>(data, mesh.element_nodes(e, x), fe, &Ke, kind, false);
    const auto& c = mesh.element(e);
    for (int a = 0; a < E::num_nodes; ++a) {
      f.segment<3>(3 * c[a]) += fe.template segment<3>(3 * a);
      for (int b = 0; b < E::num_nodes; ++b) K.block<3, 3>(3 * c[a], 3 * c[b]) += Ke.template block<3, 3>(3 * a, 3 * b);
    }
  }
  return W;
}

bool bitwise_equal(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() && (a.array() == b.array()).all();
}

}  // namespace

TEMPLATE_LIST_TEST_CASE("Discretization: f_int = dW/du and exact K = df_int/du by central differences", "[disc][fd]",
                        Combos) {
  using E = typename TestType::E;
  using M = typename TestType::M;
  const Mesh<E> mesh = bar_mesh<E>(2, 1, 1);
  const Discretization<E, M> d(mesh, soft);
  std::mt19937 rng(11);
  const Vector u = finite_deformation(mesh, rng);
  Vector f;
  const TangentKind kind = Discretization<E, M>::has_exact_tangent ? TangentKind::Exact : TangentKind::Projected;
  const Eigen::MatrixXd K = tangent(d, u, kind, f);
  // The energy of the assembly is the energy at u (the same element sums, possibly by another
  // kernel: NeoHookean's closed form without K, the generic one with it): round-off.
  const Scalar W = d.energy();
  CHECK(std::abs(W - d.strain_energy(u)) <= 1e-13 * std::abs(W));
  // h = 1e-6 of the unit cell: truncation ~h^2 |W'''| / 6 and round-off ~eps |W| / h, both
  // ~1e-10 of |f| (|W| ~ 1e3, |f| ~ 1e4 here); a wrong term in f or K is O(1) relative. The
  // bound 1e-6 leaves three decades over the measured errors.
  const Scalar h = 1e-6;
  Vector grad(u.size());
  Eigen::MatrixXd jac(u.size(), u.size());
  for (Index i = 0; i < u.size(); ++i) {
    Vector up = u, um = u;
    up[i] += h;
    um[i] -= h;
    grad[i] = (d.strain_energy(up) - d.strain_energy(um)) / (2 * h);
    jac.col(i) = (internal_force(d, up) - internal_force(d, um)) / (2 * h);
  }
  const Scalar grad_error = (grad - f).norm() / f.norm(), jac_error = (jac - K).norm() / K.norm();
  fmt::print("{} {} ({} dofs): |f - dW/du| / |f| = {:.1e}, |K - df/du| / |K| = {:.1e}\n", E::name, M::name, u.size(),
             grad_error, jac_error);
  CHECK(grad_error < 1e-6);
  CHECK(jac_error < 1e-6);
}

TEMPLATE_LIST_TEST_CASE("Discretization: f_int and K are the element kernels scattered by node ids", "[disc][scatter]",
                        Combos) {
  using E = typename TestType::E;
  using M = typename TestType::M;
  const Mesh<E> mesh = bar_mesh<E>(2, 1, 1);
  const Discretization<E, M> d(mesh, soft);
  std::mt19937 rng(12);
  const Vector u = finite_deformation(mesh, rng);
  for (TangentKind kind : {TangentKind::Projected, TangentKind::Exact}) {
    Vector f, f_ref;
    Eigen::MatrixXd K_ref;
    const Eigen::MatrixXd K = tangent(d, u, kind, f);
    const Scalar W_ref = reference_assembly<E, M>(mesh, u, kind, f_ref, K_ref);
    // The same kernels on the same element data (shared by shape: prepared from a translated
    // copy of the element, exact for the generators' integer coordinates or within round-off),
    // summed in another order, the lower blocks mirrored: a few eps of the largest entries.
    const Scalar f_error = (f - f_ref).cwiseAbs().maxCoeff() / f_ref.cwiseAbs().maxCoeff();
    const Scalar K_error = (K - K_ref).cwiseAbs().maxCoeff() / K_ref.cwiseAbs().maxCoeff();
    fmt::print("{} {} {}: scatter |f - f_ref| {:.1e}, |K - K_ref| {:.1e}, |W - W_ref| {:.1e} (relative, max)\n",
               E::name, M::name, kind == TangentKind::Exact ? "exact" : "projected", f_error, K_error,
               std::abs(d.energy() - W_ref) / std::abs(W_ref));
    CHECK(f_error < 1e-13);
    CHECK(K_error < 1e-13);
    CHECK(std::abs(d.energy() - W_ref) <= 1e-13 * std::abs(W_ref));
    // The reference is symmetric (full element matrices), so the symmetric storage lost nothing.
    CHECK((K_ref - K_ref.transpose()).cwiseAbs().maxCoeff() <= 1e-12 * K_ref.cwiseAbs().maxCoeff());
  }
}

TEMPLATE_LIST_TEST_CASE("Discretization: rigid motions, rest stiffness and volume", "[disc][rigid]", Combos) {
  using E = typename TestType::E;
  using M = typename TestType::M;
  const Mesh<E> mesh = bar_mesh<E>(2, 1, 1);
  const Discretization<E, M> d(mesh, soft);
  const Index n = d.num_dofs();

  // A rotation by 2.5 rad and a translation: no force, no energy. Round-off in P ~ eps
  // (lambda + 2 mu) per point, summed over at most a few dozen points on unit faces: below
  // 1e-13 of the modulus (measured: a few eps); the energy's cancellation (I1 - 3, ln J) too.
  const Vector u_rigid = affine(mesh, big_rotation - Mat3::Identity(), Vec3(0.3, -1, 2));
  const Vector f = internal_force(d, u_rigid);
  fmt::print("{} {}: rigid |f|_inf / (lambda + 2 mu) = {:.1e}, W / (lambda + 2 mu) = {:.1e}\n", E::name, M::name,
             f.cwiseAbs().maxCoeff() / modulus, d.energy() / modulus);
  CHECK(f.cwiseAbs().maxCoeff() <= 1e-13 * modulus);
  CHECK(std::abs(d.energy()) <= 1e-13 * modulus);

  // The rest stiffness: the infinitesimal rigid motions are its null vectors ...
  BlockSymmetricMatrix K0 = d.assembler().zero_matrix();
  d.assemble_rest_stiffness(K0);
  const Eigen::MatrixXd K = K0.to_sparse();
  Eigen::MatrixXd rigid(n, 6);
  const Vector X = rest_positions(mesh);
  for (Index i = 0; i < mesh.num_nodes(); ++i)
    for (int k = 0; k < 3; ++k) {
      rigid.block<3, 1>(3 * i, k) = Vec3::Unit(k);
      rigid.block<3, 1>(3 * i, 3 + k) = Vec3::Unit(k).cross(X.segment<3>(3 * i));
    }
  // Entries ~modulus summed along a row against |r| <= ~3: round-off ~1e-15 of |K| |r|.
  const Scalar null_error = (K * rigid).cwiseAbs().maxCoeff() / (K.cwiseAbs().maxCoeff() * rigid.cwiseAbs().maxCoeff());
  // ... and the only ones (no zero-energy mode: full integration): the seventh eigenvalue is a
  // bending mode of the 2 x 1 x 1 bar, orders of magnitude above round-off.
  const Vector ev = testing::symmetric_eigenvalues(K);
  fmt::print("{} {}: rest |K r| {:.1e} (relative), eigenvalues 6, 7 / max: {:.1e} {:.1e}\n", E::name, M::name,
             null_error, ev[5] / ev[n - 1], ev[6] / ev[n - 1]);
  CHECK(null_error < 1e-13);
  CHECK(std::abs(ev[5]) < 1e-12 * ev[n - 1]);
  CHECK(ev[6] > 1e-4 * ev[n - 1]);
  // Both models linearise to linear elasticity at rest: K0 is Linear's stiffness (its element
  // K0 scattered by the reference assembly), to round-off.
  Vector f_lin;
  Eigen::MatrixXd K_lin;
  reference_assembly<E, Linear>(mesh, Vector::Zero(n), TangentKind::Projected, f_lin, K_lin);
  const Scalar lin_error = (K - K_lin).cwiseAbs().maxCoeff() / K_lin.cwiseAbs().maxCoeff();
  CHECK(lin_error < 1e-12);

  // Volume: the mesh's (2 unit cubes) at rest, det F times it under a homogeneous F (the
  // quadrature is exact for an affine map of a straight element: round-off).
  std::mt19937 rng(13);
  const Mat3 F = big_rotation * (Mat3::Identity() + random_matrix(rng, 0.3));
  const Scalar v0_error = std::abs(d.volume(Vector::Zero(n)) - 2) / 2;
  const Vector u_F = affine(mesh, F - Mat3::Identity(), Vec3(1, 2, 3));
  const Scalar v_error = std::abs(d.volume(u_F) / (2 * F.determinant()) - 1);
  fmt::print("{} {}: rest K0 vs Linear {:.1e}, volume at rest {:.1e}, under F {:.1e} (relative)\n", E::name, M::name,
             lin_error, v0_error, v_error);
  CHECK(v0_error < 1e-14);
  CHECK(v_error < 1e-13);
}

TEST_CASE("Discretization: element stress under a homogeneous deformation is the closed form", "[disc][stress]") {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(2, 1, 1);
  std::mt19937 rng(14);
  // Hooke with mu, lambda from E, nu (not through Material): sigma = 2 mu eps + lambda tr(eps) I.
  auto hooke_ = [](const Mat3& eps) { return 2 * lame_mu * eps + lame_lambda * eps.trace() * Mat3::Identity(); };
  const Mat3 H = random_matrix(rng, 0.01);
  const Mat3 Hs = 0.5 * (H + H.transpose());
  // Each: a 3 x 3 product of entries ~modulus x strain, relative round-off ~1e-15; 1e-12 of
  // the stress's size leaves margin for the cancellation in small components.
  auto check = [](const std::vector<Mat3>& s, const Mat3& expected, const char* what) {
    Scalar worst = 0;
    for (const Mat3& se : s) worst = std::max(worst, (se - expected).norm() / expected.norm());
    fmt::print("element stress, {}: relative error {:.1e}\n", what, worst);
    CHECK(worst < 1e-12);
  };
  {  // Linear: sigma = C sym(grad u), any u = H X + t.
    const Discretization<Hex8, Linear> d(mesh, soft);
    check(d.element_stress(affine(mesh, H, Vec3(0.1, 0.2, 0.3))), hooke_(Hs), "Linear");
  }
  {  // Corotational: F = R U, U = I + S, S symmetric: sigma = R C(S) U R^T / det U (the Biot
     // stress C(S) times U / J; C(S) and U are coaxial, so the product is symmetric).
    const Discretization<Hex8, Corotational> d(mesh, soft);
    const Mat3 S = 10 * Hs, U = Mat3::Identity() + S;
    check(d.element_stress(affine(mesh, big_rotation * U - Mat3::Identity())),
          big_rotation * hooke_(S) * U * big_rotation.transpose() / U.determinant(), "Corotational");
  }
  {  // NeoHookean: sigma = (mu (F F^T - I) + lambda ln J I) / J.
    const Discretization<Hex8, NeoHookean> d(mesh, soft);
    const Mat3 F = big_rotation * (Mat3::Identity() + 20 * H);
    const Scalar J = F.determinant();
    check(d.element_stress(affine(mesh, F - Mat3::Identity())),
          (lame_mu * (F * F.transpose() - Mat3::Identity()) + lame_lambda * std::log(J) * Mat3::Identity()) / J,
          "NeoHookean");
  }
}

TEST_CASE("Discretization: a dof slot grows the map by 3, stale until rebuilt, f_int and K unchanged",
          "[disc][dofs]") {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(2, 1, 1);
  Discretization<Hex8, Corotational> d(mesh, soft);
  std::mt19937 rng(15);
  const Vector u = finite_deformation(mesh, rng);
  const Index n = d.num_dofs();
  REQUIRE(n == 3 * mesh.num_nodes());
  Vector f0, f1;
  const Eigen::MatrixXd K0 = tangent(d, u, TangentKind::Exact, f0);
  CHECK(!d.stale());
  const auto version = d.dof_map().version();

  const Index row = d.dof_map().add_slot(5);
  CHECK(row == mesh.num_nodes());
  CHECK(d.dof_map().version() != version);
  CHECK(d.dof_map().num_dofs() == n + 3);
  CHECK(d.stale());          // the assembler is behind the map ...
  CHECK(d.num_dofs() == n);  // ... and still sized for the old one
  d.rebuild();
  CHECK(!d.stale());
  REQUIRE(d.num_dofs() == n + 3);
  CHECK(d.rest_displacement().size() == n + 3);

  // The new slot is coupled by no element: whatever its value, the old rows are bit for bit
  // what they were and the new ones zero, in f_int and in K.
  Vector u1(n + 3);
  u1 << u, Vec3(0.7, -0.2, 0.4);
  const Eigen::MatrixXd K1 = tangent(d, u1, TangentKind::Exact, f1);
  CHECK(bitwise_equal(f1.head(n), f0));
  CHECK(f1.tail(3).isZero(0));
  CHECK(bitwise_equal(K1.topLeftCorner(n, n), K0));
  CHECK(K1.bottomRows(3).isZero(0));
  CHECK(K1.rightCols(3).isZero(0));
}

TEST_CASE("Discretization: an inverted element is named by locate_invalid and fails assemble", "[disc][invalid]") {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(3, 1, 1);
  const Discretization<Hex8, NeoHookean> d(mesh, soft);
  const Discretization<Hex8, Corotational> corot(mesh, soft);
  const Index n = d.num_dofs();
  Vector f(n);
  CHECK(d.assemble(Vector::Zero(n), f, nullptr, TangentKind::Projected, 1));
  CHECK(d.locate_invalid(Vector::Zero(n)).empty());

  // Turn the last element inside out, and only it: a node no other element uses, reflected
  // through the element's centre, lands on the opposite corner, where det J < 0. It is not the
  // first element, so locate_invalid has to search.
  const Index e = 2;
  Index node = -1;
  for (Index i : mesh.element(e)) {
    int users = 0;
    for (Index k = 0; k < mesh.num_elements(); ++k)
      for (Index j : mesh.element(k)) users += j == i;
    if (users == 1) node = i;
  }
  REQUIRE(node >= 0);
  const Vec3 centre = mesh.element_nodes(e).rowwise().mean();
  Vector u = Vector::Zero(n);
  u.segment<3>(3 * node) = 2 * (centre - mesh.nodes().col(node));
  // The independent fact: the element's current shape is inverted, the others' are not.
  CHECK(check_shape<Hex8>(d.current_nodes(e, u)).inverted());
  for (Index k = 0; k < e; ++k) CHECK(check_shape<Hex8>(d.current_nodes(k, u)).valid());

  CHECK(!d.assemble(u, f, nullptr, TangentKind::Projected, 1));
  BlockSymmetricMatrix K = d.assembler().zero_matrix();
  CHECK(!d.assemble(u, f, &K, TangentKind::Exact, 1));
  const std::string where = d.locate_invalid(u);
  fmt::print("locate_invalid:{}\n", where);
  CHECK(where.find("element 2 is inverted") != std::string::npos);
  // ln J is undefined there; the corotational energy is not (it reads the element as
  // compressed through zero), so the same state assembles.
  CHECK(corot.assemble(u, f, nullptr, TangentKind::Projected, 1));
  CHECK(corot.locate_invalid(u).empty());
  // Where a model defined for inverted elements has a non-finite force there, the force
  // overflowed, and the message says so rather than calling the model undefined (found by
  // review, 2026-12-02): E = 1e308 (lambda and mu finite) overflows the inverted element's stress.
  const Discretization<Hex8, Corotational> stiff(mesh, Material{1e308, 0.3, 1.0});
  CHECK(!stiff.assemble(u, f, nullptr, TangentKind::Projected, 1));
  const std::string overflow = stiff.locate_invalid(u);
  INFO(overflow);
  CHECK(overflow.find("element 2 has a non-finite internal force: it is inverted") != std::string::npos);
  CHECK(overflow.find("overflowed") != std::string::npos);
  CHECK(overflow.find("undefined") == std::string::npos);
  static_assert(defined_when_inverted_v<Corotational> && defined_when_inverted_v<Linear> &&
                defined_when_inverted_v<CorotationalPerElement> && defined_when_inverted_v<StableNeoHookean> &&
                !defined_when_inverted_v<NeoHookean> && !defined_when_inverted_v<MooneyRivlin>);

  Vector bad = Vector::Zero(n);
  bad[7] = std::numeric_limits<Scalar>::quiet_NaN();
  CHECK(!corot.assemble(bad, f, nullptr, TangentKind::Projected, 1));
  CHECK(corot.locate_invalid(bad).find("displacement itself is not finite") != std::string::npos);
}

TEST_CASE("Discretization: a rest-shape change changes only that element's contribution", "[disc][rest]") {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(3, 1, 1);
  Discretization<Hex8, NeoHookean> d(mesh, soft);
  std::mt19937 rng(16);
  const Vector u = finite_deformation(mesh, rng);
  Vector f0, f1, f_after;
  const Eigen::MatrixXd K0 = tangent(d, u, TangentKind::Exact, f0);
  const auto epoch = d.data().epoch();
  CHECK(d.data().num_shapes() == 1);  // a structured grid: one shape

  // A rejected (inverted: two nodes swapped) rest shape changes nothing.
  const Index e = 1;
  const ElementNodes<Hex8> X = mesh.element_nodes(e);
  ElementNodes<Hex8> inverted = X;
  inverted.col(0).swap(inverted.col(1));
  CHECK_THROWS_AS(d.set_rest_shape(e, inverted), InvalidArgument);
  CHECK(d.data().epoch() == epoch);
  CHECK(bitwise_equal(internal_force(d, u), f0));

  // The middle element gets a stretched and sheared rest shape (as plastic flow would give it).
  Mat3 A;
  A << 1.1, 0.05, 0, 0, 0.95, 0.02, 0, 0, 1;
  const Vec3 c = X.rowwise().mean();
  const ElementNodes<Hex8> Xnew = (A * (X.colwise() - c)).colwise() + c;
  d.set_rest_shape(e, Xnew);
  CHECK(d.data().epoch() != epoch);
  CHECK(d.data().num_shapes() == 2);
  const Eigen::MatrixXd K1 = tangent(d, u, TangentKind::Exact, f1);

  // Expected change: element e's kernel at the new rest shape minus at the old, on its nodes.
  const ElementNodes<Hex8> x = d.current_nodes(e, u);
  ElementVector<Hex8> fa, fb;
  ElementMatrix<Hex8> Ka, Kb;
  NeoHookean::evaluate<Hex8>(NeoHookean::prepare<Hex8>(X, soft), x, fa, &Ka, TangentKind::Exact, false);
  NeoHookean::evaluate<Hex8>(NeoHookean::prepare<Hex8>(Xnew, soft), x, fb, &Kb, TangentKind::Exact, false);
  Vector df = Vector::Zero(f0.size());
  Eigen::MatrixXd dK = Eigen::MatrixXd::Zero(K0.rows(), K0.cols());
  std::vector<bool> in_e(mesh.num_nodes(), false);
  const auto& conn = mesh.element(e);
  for (int a = 0; a < Hex8::num_nodes; ++a) {
    in_e[conn[a]] = true;
    df.segment<3>(3 * conn[a]) = (fb - fa).segment<3>(3 * a);
    for (int b = 0; b < Hex8::num_nodes; ++b)
      dK.block<3, 3>(3 * conn[a], 3 * conn[b]) = (Kb - Ka).block<3, 3>(3 * a, 3 * b);
  }
  // Rows of nodes element e does not use: bit for bit (the same sums of the same terms);
  // element e's: the kernel difference, to the round-off of the sums it enters (~eps |f|, |K|).
  bool untouched_f = true, untouched_K = true;
  for (Index i = 0; i < mesh.num_nodes(); ++i)
    if (!in_e[i]) {
      untouched_f = untouched_f && bitwise_equal(f1.segment<3>(3 * i), f0.segment<3>(3 * i));
      untouched_K = untouched_K && bitwise_equal(K1.middleRows<3>(3 * i), K0.middleRows<3>(3 * i));
    }
  CHECK(untouched_f);
  CHECK(untouched_K);
  const Scalar f_error = (f1 - f0 - df).cwiseAbs().maxCoeff() / f0.cwiseAbs().maxCoeff();
  const Scalar K_error = (K1 - K0 - dK).cwiseAbs().maxCoeff() / K0.cwiseAbs().maxCoeff();
  fmt::print("rest-shape change: |df - df_e| {:.1e}, |dK - dK_e| {:.1e} (relative, max); |df_e| {:.1e}\n", f_error,
             K_error, df.cwiseAbs().maxCoeff() / f0.cwiseAbs().maxCoeff());
  CHECK(f_error < 1e-13);
  CHECK(K_error < 1e-13);
  CHECK(df.cwiseAbs().maxCoeff() > 1e-2 * f0.cwiseAbs().maxCoeff());  // the change is not negligible

  // The batched path (what a plastic step calls, on 2 threads) gives the same body bit for bit.
  Discretization<Hex8, NeoHookean> batched(mesh, soft);
  batched.set_rest_shapes({e}, [&](Index) { return Xnew; }, 2);
  CHECK(batched.data().epoch() != epoch);
  Vector f2;
  CHECK(bitwise_equal(tangent(batched, u, TangentKind::Exact, f2), K1));
  CHECK(bitwise_equal(f2, f1));
}
