#pragma once
// The plastic flow of one element in one step (seed 000, section 3): from the element's rest
// shape X (the material mesh at its nodes) and its current nodes x, the element's plastic
// target shape z, and its updated yield thresholds. Formulas as reconstructed from the paper
// (its PDF text garbles them), with the equation numbers of the paper:
//
// Deformation gradients (eq. 1). F = x dN/dX at reference points: F_o at the element centre,
// F_a at each node a, and the blended gradients Fbar_a = (F_a + F_o) / 2 (the paper's vertex
// blending, its appendix: a third-order accurate "half-gradient" deformation). Plastic stretch
// flows at the nodes from Fbar_a for the small-strain models (Linear, Corotational,
// CorotationalPerElement and their mean-dilatation forms), at the Gauss points from F_g for the
// hyperelastic ones; a node then takes the plastic stretch of its nearest Gauss point (the
// average of equally near ones: Tet10's mid-edge nodes). Plastic rotation flows at the nodes
// from Fbar_a for every model (the paper left it out for the hyperelastic model for speed).
//
// Stress. The paper's second Piola-Kirchhoff stress S, as the Mandel stress M = C S = F^T P,
// which equals S to first order in the strain and whose deviator is free of the pressure at
// any strain (dev S keeps p J dev(C^-1): a nearly incompressible body under 10% confined
// compression read 40 times its shear stress; M's invariants are the Kirchhoff stress J sigma's,
// the measure of finite-strain J2 plasticity, Simo 1992). The hyperelastic models' own: F^T P
// of the law (for a MeanDilatation variant of its deviatoric energy, the element's pressure
// having no deviator), mu (C - I) + lambda ln J I in closed form for the Neo-Hookean energy; for
// the small-strain models the St Venant-Kirchhoff stress of the Green strain,
// S = lambda tr(E) I + 2 mu E, E = (F^T F - I) / 2 ("we compute C = F^T F, E = (C - I)/2 and
// the second Piola-Kirchhoff stress"): equal to their stress to first order in the strain,
// and invariant under rotation, so that a rigidly rotated Linear element does not yield on its
// ghost stress. Only the deviator enters: s = k dev(M) - alpha (dev S = 2 mu dev E for the
// small-strain models), with k the stress scale (1 by default) and alpha the kinematic centre,
// and its von Mises norm |s| = sqrt(3/2 s:s). (The paper writes sqrt(3/2 sigma:sigma); von
// Mises is the norm of the deviator, and with the whole tensor a hydrostatic pressure would
// yield.)
//
// Plastic stretch (eq. 4). With F = U D V^T (here from C = F^T F = V D^2 V^T, which needs no U
// and is exact also for reflections):
//     Sp = V (D / det(D)^(1/3))^gamma V^T,   gamma = min(nu dt (|s| - tau) / |s|, 1)  if |s| > tau,
// i.e. Sp = exp(gamma dev(log U)): a fraction gamma of the isochoric part of the stretch U.
// gamma is continuous at the yield surface (zero there), so the flow does not depend on how
// closely Newton converged.
//
// Plastic rotation (eq. 5, vertex-blended). With Fbar_a = Rbar_a Ubar_a and F_o = R_o U_o, the
// distortion at a vertex is the geodesic distance phi_a = Phi(Rbar_a, R_o) = |log(Rbar_a R_o^T)|,
// and where it exceeds the rotation yield a fraction of the vertex rotation becomes plastic,
//     eta_a = min(nu_R dt (phi_a - tau_R) / phi_a, 1),   Rp_a = Rbar_a^eta_a,   Re_a = Rbar_a^(1 - eta_a),
// the same rule as eq. 4's gamma for the stretch: rate times relative overstress. Cell-centered
// (eq. 6): one rotation per element from the largest vertex distortion,
//     phi~ = max_a phi_a,   eta~ = min(nu_R dt (phi~ - tau_R) / phi~, 1),   Rp_o = R_o^eta~.
// The element's material turns towards its world orientation (rigidly for cell-centered, vertex
// by vertex, so distorting the element, for vertex-blended), and the fused material mesh
// (plastic/fusion.hpp) takes the turns of neighbouring elements against each other as the
// plastic twist or bend. The paper divides by phi + Phi(I, R_o) instead of phi: every element
// then turns by about the same angle, nu_R dt (phi - tau_R), whatever its rotation, which fuses
// to a rigid rotation of the material mesh (measured: a clamped bar twisted by 1.5 rad and
// released kept 0.065 rad of twist, all of it at the clamp; with phi alone it keeps 0.9 rad
// with cell-centered rotation). A rigid motion has phi = 0: no flow. Where a body both rotates
// rigidly and yields in part, the yielding part turns its material towards the rigid rotation
// too: the paper's assumption, which surgery allows, is that the anatomy does not spin freely.
// Both rules are capped (PlasticParams::max_step_rotation per step, max_total_rotation
// accumulated, the paper's "maximal per-element rotation capped below pi"), each cap counted.
//
// Hardening. Isotropic: tau += kappa gamma |s|, tau_R += kappa eta phi. Kinematic (reconstructed
// so that it has the units of a stress, the paper's "alpha <- alpha + kappa gamma (sigma -
// alpha)/|sigma - alpha|" does not): alpha += min(kappa_k gamma, 1) (k dev(M) - alpha), the
// centre at most onto the stress.
//
// Rest-shape update (eq. 7-8). The plastic increment Fp = Rp Sp (the right factors of
// F = Re Rp Se Sp, eq. 3) maps the rest shape about its centre c = X N(centre):
//     z_a = c + Rp_a Sp_a (X_a - c)
// (the paper's y_q <- y_q + Sp_q u_q with u_q the non-rigid displacement, read as the plastic
// part of the displacement, (Sp - I)(X_q - c): with Sp = I nothing must move). The accumulated
// rotation map Pi <- Pi Rp (eq. 8) is kept per vertex or per element.
//
// Volume restitution (eq. 9). det Sp = det Rp = 1, but per-node increments change the volume;
// with beta = vol(z) / vol(original element) (exact volumes, element/element.hpp):
//     z_a <- c + (1 + (1 - beta) min(r dt, 1/3)) (z_a - c),   r = PlasticParams::volume_restitution,
// the paper's y <- y + (y - o)(1 - beta) dt for small dt (r = 1), never overshooting for large dt.
//
// Safeguard. If z would have a smallest scaled Jacobian (element/element.hpp, check_shape) below
// PlasticParams::min_rest_quality times the element's original one (and below that of X),
// plasticity is switched off for the element: it keeps X and goes on elastically ("our
// implementation switches off plasticity before an element is inverted").
#include <plastifem/core/rotation.hpp>
#include <plastifem/core/symmetric_eigen.hpp>
#include <plastifem/elastic/elastic.hpp>
#include <plastifem/plastic/params.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <type_traits>

namespace plastifem {

/// Whether an elastic model is one of the hyperelastic family (plastic stretch at Gauss points).
template <class M>
struct is_hyperelastic : std::false_type {};
template <class Energy, Volumetric V>
struct is_hyperelastic<Hyperelastic<Energy, V>> : std::true_type {};
template <class M>
inline constexpr bool is_hyperelastic_v = is_hyperelastic<M>::value;
/// Whether it is a hyperelastic MeanDilatation variant (its pressure is U'(Jbar), hyperelastic.hpp).
template <class M>
inline constexpr bool is_mean_dilatation_hyperelastic_v = false;
template <class Energy>
inline constexpr bool is_mean_dilatation_hyperelastic_v<Hyperelastic<Energy, Volumetric::MeanDilatation>> = true;

namespace plastic {

/// isochoric_stretch_power by the eigen-decomposition of C = F^T F (the reference, and the
/// path for strongly distorted points).
inline bool isochoric_stretch_power_eigen(const Mat3& C, Scalar gamma, Mat3& Sp) {
  Vec3 l;
  Mat3 V;
  symmetric_eigen<3>(C, l, V);
  if (!(l.minCoeff() > 1e-24 * l.maxCoeff()) || !l.allFinite()) return false;
  const Vec3 d = 0.5 * l.array().log().matrix();  // log of the principal stretches
  const Scalar mean = d.sum() / 3;
  const Vec3 p = (gamma * (d.array() - mean)).exp().matrix();
  Sp = V * p.asDiagonal() * V.transpose();
  return true;
}

/// Sp = exp(gamma dev(log U)) with U^2 = C = F^T F (eq. 4). false (Sp untouched) if C is not
/// positive definite (a collapsed point).
///
/// Sp = f(C) for f(l) = (l / (l1 l2 l3)^(1/3))^(gamma/2), and a function of a 3x3 symmetric
/// matrix is the polynomial interpolating f at its eigenvalues (Newton's form):
///     f(C) = f(l1) I + f[l1, l2] (C - l1 I) + f[l1, l2, l3] (C - l1 I)(C - l2 I),
/// with the eigenvalues in closed form (l = q + 2 p cos(phi + 2 pi k / 3), Smith 1961) and no
/// eigenvectors. Close eigenvalues do no harm: f[a, b] = f(a) expm1(gamma/2 log1p((b - a)/a))
/// / (b - a) has no cancellation, and where the second divided difference loses digits it
/// multiplies (C - l1)(C - l2), as small as the eigenvalue gaps. Agrees with the
/// eigen-decomposition to 1e-14 where l1 / l3 <= 16 (tested); beyond (stretch ratios above 4,
/// where the closed-form small eigenvalue loses digits) the decomposition is used. 1.8 times
/// faster than the decomposition (100 against 180 ns): it was a quarter of a flowing step.
inline bool isochoric_stretch_power(const Mat3& F, Scalar gamma, Mat3& Sp) {
  const Mat3 C = F.transpose() * F;
  const Scalar q = C.trace() / 3;
  const Scalar a0 = C(0, 0) - q, a1 = C(1, 1) - q, a2 = C(2, 2) - q;
  const Scalar p2 = a0 * a0 + a1 * a1 + a2 * a2 + 2 * (C(0, 1) * C(0, 1) + C(0, 2) * C(0, 2) + C(1, 2) * C(1, 2));
  if (!(q > 0) || !std::isfinite(p2)) return false;
  const Scalar p = std::sqrt(p2 / 6);
  if (!(p > 8 * std::numeric_limits<Scalar>::epsilon() * q)) {  // C = q I to round-off: no distortion
    Sp.setIdentity();
    return true;
  }
  Mat3 B = C / p;  // (C - q I) / p, whose eigenvalues are 2 cos(phi + 2 pi k / 3)
  B.diagonal().array() -= q / p;
  const Scalar phi = std::acos(std::clamp(B.determinant() / 2, Scalar(-1), Scalar(1))) / 3;
  const Scalar c = std::cos(phi), s = std::sin(phi);
  const Scalar l1 = q + 2 * p * c;                          // the largest
  const Scalar l3 = q - p * (c + std::sqrt(Scalar(3)) * s);  // the smallest, 2 cos(phi + 2 pi / 3)
  const Scalar l2 = 3 * q - l1 - l3;
  if (!(l3 > 0) || l1 > 16 * l3) return isochoric_stretch_power_eigen(C, gamma, Sp);
  // f_i = (l_i^3 / det C)^(gamma/6), det C = l1 l2 l3 from C itself; f1 f2 f3 = 1 gives f2
  // (two logarithms and two exponentials instead of three each: libm was half of this function).
  const Scalar g = gamma / 2, detC = C.determinant();
  if (!(detC > 0)) return isochoric_stretch_power_eigen(C, gamma, Sp);
  const Scalar f1 = std::exp(g / 3 * std::log(l1 * l1 * (l1 / detC)));
  const Scalar f3 = std::exp(g / 3 * std::log(l3 * l3 * (l3 / detC)));
  const Scalar f2 = 1 / (f1 * f3);
  auto divided = [g](Scalar la, Scalar fa, Scalar lb, Scalar fb) {  // f[a, b]
    const Scalar d = lb - la;
    if (std::abs(d) > 1e-3 * la) return (fb - fa) / d;  // loses at most 3 of 16 digits
    if (d == 0) return g * fa / la;                      // f'(a)
    return fa * std::expm1(g * std::log1p(d / la)) / d;
  };
  const Scalar d12 = divided(l1, f1, l2, f2), d23 = divided(l2, f2, l3, f3);
  const Scalar d123 = (d23 - d12) / (l3 - l1);  // l3 < l1: p > 0
  Mat3 A1 = C, A2 = C;
  A1.diagonal().array() -= l1;
  A2.diagonal().array() -= l2;
  const Mat3 P = A1 * A2;  // symmetric in exact arithmetic (A1, A2 commute): symmetrised
  Sp = d12 * A1 + (0.5 * d123) * (P + P.transpose());
  Sp.diagonal().array() += f1;
  return true;
}

/// The deviator of the flow stress at F (the Mandel stress F^T P of a hyperelastic model, 2 mu E
/// of a small-strain one; see the file comment); false where it is undefined (the hyperelastic
/// energies with ln J at J <= 0).
template <class Elastic>
bool deviatoric_flow_stress(const typename Elastic::Law& law, const Material& m, const Mat3& F, Mat3& dev) {
  Mat3 M;
  if constexpr (is_mean_dilatation_hyperelastic_v<Elastic>) {
    // F^T (P_dev + U'(Jbar) cof F) = F^T P_dev + U'(Jbar) J I: the element's pressure (and the
    // point's locked one, which the variant removes) has no deviator.
    Scalar psi;
    Mat3 P;
    if (!law.energy.deviatoric(F, psi, P, nullptr)) return false;
    M = F.transpose() * P;
  } else if constexpr (requires { law.energy.mandel_stress(F, M); }) {
    if (!law.energy.mandel_stress(F, M)) return false;  // a closed form (NeoHookeanEnergy)
  } else if constexpr (is_hyperelastic_v<Elastic>) {
    Mat3 P;
    if (!std::isfinite(law.evaluate(F, P, nullptr))) return false;
    M = F.transpose() * P;
  } else {
    M = m.mu() * (F.transpose() * F - Mat3::Identity());  // 2 mu E: the lambda tr(E) I part has no deviator
  }
  M = 0.5 * (M + M.transpose());  // symmetric in exact arithmetic for an isotropic law
  dev = M - M.trace() / 3 * Mat3::Identity();
  return dev.allFinite();
}

/// |s| = sqrt(3/2 s:s).
inline Scalar von_mises_norm(const Mat3& s) { return std::sqrt(1.5 * s.squaredNorm()); }

/// A symmetric deviator packed as 6 numbers (xx, yy, zz, xy, xz, yz) and back.
inline void pack(const Mat3& s, Scalar* p) {
  p[0] = s(0, 0), p[1] = s(1, 1), p[2] = s(2, 2), p[3] = s(0, 1), p[4] = s(0, 2), p[5] = s(1, 2);
}
inline Mat3 unpack(const Scalar* p) {
  Mat3 s;
  s << p[0], p[3], p[4], p[3], p[1], p[5], p[4], p[5], p[2];
  return s;
}

/// Element-type constants of the flow: where the flow points are, and which Gauss points are
/// nearest to each node.
template <FiniteElement E, bool Gauss>
struct FlowPoints {
  static constexpr int N = E::num_nodes;
  static constexpr int Q = decltype(E::template quadrature<E::stiffness_degree>())::size;
  static constexpr int size = Gauss ? Q : N;
  std::array<Vec3, size> xi;              ///< reference coordinates of the flow points
  std::array<Eigen::Matrix<Scalar, N, 3>, N + 1> dN_nodes;  ///< dN/dxi at the nodes and (last) the centre
  std::array<Eigen::Matrix<Scalar, N, 3>, Q> dN_gauss;      ///< dN/dxi at the Gauss points
  std::array<Scalar, Q> w_gauss;                             ///< their weights
  Eigen::Matrix<Scalar, N, 1> N_centre;
  std::array<std::array<int, 4>, N> nearest{};  ///< Gauss flow: the Gauss points nearest to each node
  std::array<int, N> num_nearest{};

  FlowPoints() {
    const auto Xref = E::reference_nodes();
    const auto q = E::template quadrature<E::stiffness_degree>();
    const Vec3 c = reference_centre<E>();
    for (int a = 0; a < N; ++a) dN_nodes[a] = E::gradient(Xref.col(a));
    dN_nodes[N] = E::gradient(c);
    N_centre = E::shape(c);
    for (int g = 0; g < Q; ++g) dN_gauss[g] = E::gradient(q.points[g]), w_gauss[g] = q.weights[g];
    for (int k = 0; k < size; ++k) xi[k] = Gauss ? Vec3(q.points[k]) : Vec3(Xref.col(k));
    for (int a = 0; a < N; ++a) {
      Scalar best = std::numeric_limits<Scalar>::max();
      for (int g = 0; g < Q; ++g) best = std::min(best, (Vec3(q.points[g]) - Xref.col(a)).norm());
      for (int g = 0; g < Q; ++g)
        if ((Vec3(q.points[g]) - Xref.col(a)).norm() <= best * (1 + 1e-9) && num_nearest[a] < 4)
          nearest[a][num_nearest[a]++] = g;
    }
  }
};

/// F = (x dN) (X dN)^{-1} for the reference gradient dN of one point.
template <FiniteElement E>
Mat3 gradient_at(const ElementNodes<E>& X, const ElementNodes<E>& x, const Eigen::Matrix<Scalar, E::num_nodes, 3>& dN) {
  const Mat3 J = X * dN, j = x * dN;
  return j * J.inverse();
}

/// The rest-space shape gradients of one rest shape at the points the flow reads, so that each
/// F is one product x G: the blended gradients (dN/dX(node a) + dN/dX(centre)) / 2 of the N
/// nodes (F x G_a is the blended Fbar_a) and the centre's dN/dX (index N); for the Gauss flow
/// also the Q Gauss points' dN/dX, point-major (GT(q, 3a + j) = dN_a/dX_j at point q), so that
/// the yield check computes F at all points at once (one SIMD lane per point).
template <FiniteElement E, bool Gauss>
struct FlowGradients {
  static constexpr int N = E::num_nodes;
  static constexpr int Q = decltype(E::template quadrature<E::stiffness_degree>())::size;
  std::array<ShapeGradients<E>, N + 1> G;
  struct None {};
  std::conditional_t<Gauss, Eigen::Matrix<Scalar, Q, 3 * N>, None> GT;
  std::conditional_t<Gauss, std::array<Scalar, Q>, None> dv;  ///< the Gauss points' rest volumes
  Scalar volume = 0;                                          ///< their sum (Gauss flow)

  FlowGradients() = default;
  FlowGradients(const FlowPoints<E, Gauss>& pts, const ElementNodes<E>& X) {
    for (int a = 0; a <= N; ++a) G[a] = physical_gradient_at<E>(X, pts.dN_nodes[a]);
    for (int a = 0; a < N; ++a) G[a] = 0.5 * (G[a] + G[N]);
    if constexpr (Gauss)
      for (int g = 0; g < Q; ++g) {
        Scalar det_J;
        const ShapeGradients<E> Gg = physical_gradient_at<E>(X, pts.dN_gauss[g], &det_J);
        for (int a = 0; a < N; ++a)
          for (int j = 0; j < 3; ++j) GT(g, 3 * a + j) = Gg(a, j);
        dv[g] = pts.w_gauss[g] * det_J;
        volume += dv[g];
      }
  }

  /// F = x dN/dX at Gauss point g (the Gauss flow).
  Mat3 gauss_gradient(const ElementNodes<E>& x, int g) const
    requires Gauss
  {
    Mat3 F;
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) {
        Scalar s = 0;
        for (int a = 0; a < N; ++a) s += x(i, a) * GT(g, 3 * a + j);
        F(i, j) = s;
      }
    return F;
  }
  /// F at every Gauss point at once, component-wise: F[i + 3j](g) = F_g(i, j).
  PointMat3<Q> gauss_gradients(const ElementNodes<E>& x) const
    requires Gauss
  {
    PointMat3<Q> F;
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) {
        PointArray<Q> s = x(i, 0) * GT.col(j).array();
        for (int a = 1; a < N; ++a) s += x(i, a) * GT.col(3 * a + j).array();
        F[i + 3 * j] = s;
      }
    return F;
  }
};

/// F = x G for one point: 3 x N times N x 3, written out (Eigen's product dispatch costs more
/// than the 9 N multiply-adds at this size).
template <FiniteElement E>
Mat3 times(const ElementNodes<E>& x, const ShapeGradients<E>& G) {
  Mat3 F;
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) {
      Scalar s = 0;
      for (int a = 0; a < E::num_nodes; ++a) s += x(i, a) * G(a, j);
      F(i, j) = s;
    }
  return F;
}

/// Volume of a rest shape, exact for the element's own geometry with the fewest points (the
/// rule of det J's degree, E::volume_degree).
template <FiniteElement E>
Scalar rest_volume(const ElementNodes<E>& X) {
  constexpr int degree = E::volume_degree;
  const auto q = E::template quadrature<degree>();
  const auto& dN = quadrature_gradients<E, degree>();
  Scalar v = 0;
  for (int k = 0; k < q.size; ++k) v += q.weights[k] * jacobian_at<E>(X, dN[k]).determinant();
  return v;
}

/// The smallest scaled Jacobian determinant at the corners (check_shape's measure, corners
/// only): an upper bound of check_shape's, at a fifth of its cost on Hex8.
template <FiniteElement E>
Scalar corner_quality(const ElementNodes<E>& X) {
  Scalar h = 0;
  for (const auto& ed : E::edges) h = std::max(h, (X.col(ed[0]) - X.col(ed[1])).squaredNorm());
  if (!(h > 0) || !std::isfinite(h)) return std::numeric_limits<Scalar>::quiet_NaN();
  const auto& dN = corner_gradients<E>();
  Scalar q = std::numeric_limits<Scalar>::max();
  for (int a = 0; a < E::num_vertices; ++a) q = std::min(q, jacobian_at<E>(X, dN[a]).determinant());
  return q / (h * std::sqrt(h)) * E::reference_volume;
}

/// Whether rest shape X keeps at least `threshold` of check_shape's measure: the corners first,
/// the full check (corners and the mass rule's points) only where the corners come within 50%
/// of the threshold.
template <FiniteElement E>
bool shape_quality_at_least(const ElementNodes<E>& X, Scalar threshold) {
  const Scalar corners = corner_quality<E>(X);
  if (!(corners >= threshold)) return false;
  if (corners >= 1.5 * threshold) return true;
  return check_shape<E>(X).min_scaled_jacobian >= threshold;
}

/// The per-element entries of the plastic table an update reads and writes (pointers into it).
struct ElementPlasticEntries {
  Scalar* tau;       ///< one per flow point
  Scalar* alpha;     ///< 6 per flow point, or null (no kinematic hardening)
  Scalar* tau_R;     ///< one per node (vertex-blended) or one (cell-centered)
  Scalar* rotation;  ///< 3 (rotation vector of Pi) per node or one set of 3
};

/// What one element's flow did.
enum class FlowResult {
  Unchanged,  ///< nothing flowed, no restitution due: z and the entries untouched
  Changed,    ///< z is the new rest shape, the entries are updated
  Refused,    ///< the safeguard refused z (it would degenerate): switch the element off
};

/// One element's flow: see the file comment.
template <FiniteElement E, class Elastic, bool PerVertexRotation>
class ElementFlow {
 public:
  static constexpr int N = E::num_nodes;
  static constexpr bool gauss = is_hyperelastic_v<Elastic>;
  using Points = FlowPoints<E, gauss>;
  using Gradients = FlowGradients<E, gauss>;
  static constexpr int P = Points::size;
  static constexpr int NR = PerVertexRotation ? N : 1;

  /// The common case, cheaply: whether anything can flow at all. false only when no point is
  /// above yield, no rotation is to be tested, no kinematic centre and no volume to restore.
  /// The small-strain family: |s|^2 = 3/2 (2 mu k)^2 |dev E|^2 against tau^2, one product x G
  /// and one F^T F per point; the hyperelastic family: the stress run() would compute, at the
  /// Gauss points (a point where it is undefined goes to run(), which counts it). run() decides
  /// in every other case.
  static bool may_flow(const Gradients& grad, const typename Elastic::Law& law, const Material& m,
                       const PlasticParams& prm, const ElementNodes<E>& x, Scalar beta, const ElementPlasticEntries& en) {
    if ((prm.rotation_active() && en.tau_R) || en.alpha) return true;
    if (prm.volume_restitution > 0 && std::abs(1 - beta) > prm.volume_tolerance) return true;
    if (!prm.stretch_active()) return false;
    if constexpr (gauss) {
      if constexpr (!is_mean_dilatation_hyperelastic_v<Elastic> &&
                    requires { law.energy.template deviatoric_mandel_norm2<P>(grad.gauss_gradients(x)); }) {
        // All points at once (the energy's closed form, one SIMD lane per point). Conservative
        // by 1e-6 of tau^2: the batched arithmetic differs from run()'s in round-off, amplified
        // where the deviator is small against the whole stress (up to 5e-11 relative on random
        // F); a point this close to yield goes to run(), which decides.
        const PointArray<P> s2 =
            (1.5 * prm.stress_scale * prm.stress_scale) * law.energy.template deviatoric_mandel_norm2<P>(grad.gauss_gradients(x));
        for (int k = 0; k < P; ++k)
          if (!(s2[k] <= en.tau[k] * en.tau[k] * (1 - 1e-6))) return true;  // NaN: undefined, run() counts it
        return false;
      } else {
        std::array<Mat3, P> F;
        for (int k = 0; k < P; ++k) F[k] = grad.gauss_gradient(x, k);
        for (int k = 0; k < P; ++k) {
          Mat3 dev;
          if (!deviatoric_flow_stress<Elastic>(law, m, F[k], dev)) return true;
          if (von_mises_norm(prm.stress_scale * dev) > en.tau[k]) return true;
        }
        return false;
      }
    } else {
      (void)law;
      const Scalar c = 1.5 * (2 * m.mu() * prm.stress_scale) * (2 * m.mu() * prm.stress_scale);
      Scalar s2 = 0;  // |s|^2 at flow point k
      for (int k = 0; k < P; ++k) {
        // A constant-gradient element (Tet4) has one stress at all its points (every blended
        // gradient is the element's); only their thresholds differ (hardening).
        if (k == 0 || E::stiffness_degree > 0) {
          const Mat3 F = times<E>(x, grad.G[k]);
          Mat3 Es = 0.5 * (F.transpose() * F);
          Es.diagonal().array() -= Es.trace() / 3;  // dev E (the -I/2 has no deviator)
          s2 = c * Es.squaredNorm();
        }
        if (s2 > en.tau[k] * en.tau[k]) return true;
      }
      return false;
    }
  }

  /// `X`, `x`: rest and current nodes; `V0`: the element's original volume, `beta` its rest
  /// volume over V0, `q0` its original shape quality (check_shape); `frame`: the rigid frame
  /// the plastic rotation is measured against (PlasticParams::RotationFrame; I for World).
  static FlowResult run(const Points& pts, const FlowGradients<E, gauss>& grad, const typename Elastic::Law& law,
                        const Material& m, const PlasticParams& prm, Scalar dt, const Mat3& frame,
                        const ElementNodes<E>& X, const ElementNodes<E>& x,
                        Scalar V0, Scalar beta, Scalar q0, const ElementPlasticEntries& en, const ElementPlasticEntries& out,
                        ElementNodes<E>& z, PlasticReport& rep) {
    const bool stretch = prm.stretch_active(), rotate = prm.rotation_active() && en.tau_R;
    const bool restore = prm.volume_restitution > 0 && std::abs(1 - beta) > prm.volume_tolerance;
    const bool need_vertices = rotate || !gauss;
    // A constant-gradient element (Tet4): its blended gradients are its centre's bit for bit
    // (FlowGradients), so every Fbar_a is F_o, and the per-vertex work is done once.
    constexpr bool constant_gradient = E::stiffness_degree == 0;
    std::array<Mat3, N> Fbar;
    Mat3 F_o = Mat3::Identity();
    if (need_vertices) {
      F_o = times<E>(x, grad.G[N]);
      for (int a = 0; a < N; ++a) Fbar[a] = constant_gradient ? F_o : times<E>(x, grad.G[a]);
    }

    // --- no flow from an inverted configuration: where det F <= 0 at a corner or a flow point
    // (or, with plastic rotation, at a blended vertex gradient) the stress is the elastic model's extension beyond its
    // physical range (the corotational one is defined there) and the element's rotation is not
    // its material's; a rest shape built from it would carry the inversion into the material
    // mesh. The element waits, counted, until it is not inverted.
    // The flow points' F: the Gauss points' own, or the blended vertex gradients (then P = N).
    std::array<Mat3, gauss ? P : 0> F_gauss;
    if constexpr (gauss)
      for (int k = 0; k < P; ++k) F_gauss[k] = grad.gauss_gradient(x, k);
    auto F_point = [&](int k) -> const Mat3& {
      if constexpr (gauss) return F_gauss[k];
      else return Fbar[k];
    };
    {
      bool inverted = !(check_shape<E>(x).min_scaled_jacobian > 0);  // at a corner
      for (int k = 0; k < P && !inverted; ++k) inverted = !(F_point(k).determinant() > 0);
      if (gauss && rotate)  // the vertex family checked them above
        for (int a = 0; a < N && !inverted; ++a) inverted = !(Fbar[a].determinant() > 0);
      if (inverted) {
        ++rep.inverted_elements;
        return FlowResult::Unchanged;
      }
    }

    // --- plastic stretch at the flow points (eq. 4) and hardening
    std::array<Scalar, P> gamma{}, tau_new{};
    std::array<Mat3, P> Sp_point, dev_scaled;
    Sp_point.fill(Mat3::Identity());
    dev_scaled.fill(Mat3::Zero());
    bool flowed = false;
    // Below these a stress or a distortion is the round-off of F (a rigid motion), not a flow:
    // a strain of 1e-12, a rotation of 1e-9 rad (polar decompositions are accurate to ~1e-15).
    const Scalar stress_floor = 1e-12 * prm.stress_scale * 2 * m.mu(), rotation_floor = 1e-9;
    // Vertex flow on a constant-gradient element: one stress, and where the points' gamma agree
    // (unless their hardening histories differ) one plastic stretch.
    constexpr bool one_gradient = !gauss && constant_gradient;
    if (stretch) {
      bool defined = true;  // the stress at the last point that computed one
      for (int k = 0; k < P; ++k) {
        const Mat3& F = F_point(k);
        if (!one_gradient || k == 0) {
          Mat3 dev;
          defined = deviatoric_flow_stress<Elastic>(law, m, F, dev);
          if (defined) dev_scaled[k] = prm.stress_scale * dev;
        } else {
          dev_scaled[k] = dev_scaled[0];
        }
        if (!defined) {
          ++rep.undefined_points;
          continue;
        }
        const Mat3 s = en.alpha ? Mat3(dev_scaled[k] - unpack(en.alpha + 6 * k)) : dev_scaled[k];
        const Scalar vm = von_mises_norm(s);
        if (!std::isfinite(vm)) {  // gamma would be NaN: no flow from it
          ++rep.undefined_points;
          continue;
        }
        if (!(vm > en.tau[k]) || vm <= stress_floor) continue;
        Scalar g = prm.flow_rate * dt * (vm - en.tau[k]) / vm;
        if (g >= 1) g = 1, ++rep.gamma_clamped;
        if (one_gradient && k > 0 && g == gamma[0]) {
          Sp_point[k] = Sp_point[0];  // the same F and gamma
        } else if (!isochoric_stretch_power(F, g, Sp_point[k])) {
          ++rep.undefined_points;
          continue;
        }
        gamma[k] = g;
        // Held at the largest double where kappa gamma |s| overflows (kappa and the stress scale
        // are bounded separately, not their product): no finite stress exceeds either, and the
        // table stays finite, as a saved state must be.
        tau_new[k] = std::min(en.tau[k] + prm.hardening * g * vm, std::numeric_limits<Scalar>::max());
        flowed = true;
        ++rep.points_yielded;
        rep.max_gamma = std::max(rep.max_gamma, g);
      }
    }

    // --- plastic rotation (eq. 5 or 6)
    std::array<Mat3, NR> Rp;
    std::array<Scalar, NR> tauR_new{};
    std::array<Vec3, NR> pi_new;
    pi_new.fill(Vec3::Zero());
    std::array<bool, NR> turned{};
    bool rotated = false;
    if (rotate) {
      const Mat3 R_o = rotation_of(F_o);
      std::array<Mat3, N> Rbar;
      std::array<Scalar, N> phi;
      for (int a = 0; a < N; ++a) {
        if (constant_gradient && a > 0) {
          Rbar[a] = Rbar[0], phi[a] = phi[0];
          continue;
        }
        Rbar[a] = rotation_of(Fbar[a]);
        phi[a] = geodesic_distance(Rbar[a], R_o);
      }
      // Rp = R^eta for the rotation R (angle ph for the yield test), capped.
      auto flow_rotation = [&](int r, const Mat3& R, Scalar ph) {
        Rp[r].setIdentity();
        if (!(ph > en.tau_R[r]) || ph <= rotation_floor) return;
        const Scalar eta = std::min(prm.rotation_flow_rate * dt * (ph - en.tau_R[r]) / ph, Scalar(1));
        Vec3 w = eta * rotation_log(R);
        if (const Scalar angle = w.norm(); angle > prm.max_step_rotation) {
          w *= prm.max_step_rotation / angle;
          ++rep.rotation_clamped;
        }
        const Mat3 step = rotation_exp(w);
        const Vec3 pi = rotation_log(rotation_exp(Vec3(en.rotation[3 * r], en.rotation[3 * r + 1], en.rotation[3 * r + 2])) * step);
        if (pi.norm() > prm.max_total_rotation) {
          ++rep.rotation_clamped;
          return;
        }
        Rp[r] = step;
        pi_new[r] = pi;
        turned[r] = true;
        tauR_new[r] = std::min(en.tau_R[r] + prm.hardening * eta * ph,  // kappa eta phi (eta before the cap)
                               std::numeric_limits<Scalar>::max());
        rotated = true;
        ++rep.rotations_yielded;
        rep.max_rotation = std::max(rep.max_rotation, w.norm());
      };
      // The power is taken of the rotation relative to the rigid frame, frame^T R: a rotation
      // Q superposed on the whole motion turns both (Q R, Q frame) and cancels. With the World
      // frame (frame = I exactly) the product is R bit for bit: the paper's R^eta.
      if constexpr (PerVertexRotation) {
        for (int a = 0; a < N; ++a) flow_rotation(a, frame.transpose() * Rbar[a], phi[a]);
      } else {
        Scalar phi_max = 0;
        for (int a = 0; a < N; ++a) phi_max = std::max(phi_max, phi[a]);
        flow_rotation(0, frame.transpose() * R_o, phi_max);
      }
    }

    // --- volume restitution need (eq. 9)
    if (!flowed && !rotated && !restore) return FlowResult::Unchanged;

    // --- the target shape (eq. 7), then eq. 9
    const Vec3 c = X * pts.N_centre;
    for (int a = 0; a < N; ++a) {
      Mat3 Sp = Mat3::Identity();
      if (flowed) {
        if constexpr (gauss) {
          Mat3 sum = Mat3::Zero();
          int n = 0;
          for (int j = 0; j < pts.num_nearest[a]; ++j)
            if (const int g = pts.nearest[a][j]; gamma[g] > 0) sum += Sp_point[g], ++n;
          if (n > 0) Sp = (sum + (pts.num_nearest[a] - n) * Mat3::Identity()) / pts.num_nearest[a];
        } else {
          if (gamma[a] > 0) Sp = Sp_point[a];
        }
      }
      const Mat3& R = Rp[PerVertexRotation ? a : 0];
      z.col(a) = c + (rotated ? Mat3(R * Sp) : Sp) * (X.col(a) - c);
    }
    if (prm.volume_restitution > 0) {
      const Scalar b = rest_volume<E>(z) / V0;
      if (flowed || rotated || std::abs(1 - b) > prm.volume_tolerance) {
        const Scalar s = 1 + (1 - b) * std::min(prm.volume_restitution * dt, Scalar(1) / 3);
        z = (s * (z.colwise() - c)).colwise() + c;
      }
    }

    // --- safeguard: no degenerate rest shape
    if (!shape_quality_at_least<E>(z, prm.min_rest_quality * q0) &&
        !(check_shape<E>(z).min_scaled_jacobian >= check_shape<E>(X).min_scaled_jacobian))
      return FlowResult::Refused;

    // --- accepted: the element's new entries into `out` (all of them)
    for (int k = 0; k < P; ++k) {
      out.tau[k] = gamma[k] > 0 ? tau_new[k] : en.tau[k];
      if (en.alpha) {
        const Mat3 alpha = unpack(en.alpha + 6 * k);
        // The centre moves towards the stress, at most onto it: kappa_k gamma > 2 overshot by
        // more than it closed, and the centre grew without bound (1e154 at kappa_k = 500).
        const Scalar step = std::min(prm.kinematic_hardening * gamma[k], Scalar(1));
        pack(gamma[k] > 0 ? Mat3(alpha + step * (dev_scaled[k] - alpha)) : alpha, out.alpha + 6 * k);
      }
    }
    for (int r = 0; r < NR && en.tau_R; ++r) {
      out.tau_R[r] = turned[r] ? tauR_new[r] : en.tau_R[r];
      for (int i = 0; i < 3; ++i) out.rotation[3 * r + i] = turned[r] ? pi_new[r][i] : en.rotation[3 * r + i];
    }
    return FlowResult::Changed;
  }
};

}  // namespace plastic
}  // namespace plastifem
