#pragma once
// Dot products whose result does not depend on the vector's length beyond its non-zero part.
//
// Eigen's vectorised reductions split a vector into packets counted from its start and its
// end, so appending zeros (the dof map grows: solver/state.hpp) regroups the existing terms and
// changes the rounding. Here element i always goes to accumulator lane i mod (2 P) (P doubles
// per SIMD packet), the last partial block is padded with zeros and takes the same fused
// multiply-add as a full one, and the lanes are summed in a fixed order: appended zeros add
// exact zeros to their lanes, so the result is the same bit for bit. As fast as Eigen's dot
// (two independent packet accumulators).
#include <plastifem/core/types.hpp>

namespace plastifem {

inline Scalar dot(const Scalar* x, const Scalar* y, Index n) {
  using namespace Eigen::internal;
  using Packet = packet_traits<Scalar>::type;
  constexpr int P = packet_traits<Scalar>::size;
  Packet a0 = pset1<Packet>(0.0), a1 = pset1<Packet>(0.0);
  Index i = 0;
  for (; i + 2 * P <= n; i += 2 * P) {
    a0 = pmadd(ploadu<Packet>(x + i), ploadu<Packet>(y + i), a0);
    a1 = pmadd(ploadu<Packet>(x + i + P), ploadu<Packet>(y + i + P), a1);
  }
  if (i < n) {
    alignas(64) Scalar bx[2 * P] = {}, by[2 * P] = {};
    for (Index k = 0; i + k < n; ++k) bx[k] = x[i + k], by[k] = y[i + k];
    a0 = pmadd(pload<Packet>(bx), pload<Packet>(by), a0);
    a1 = pmadd(pload<Packet>(bx + P), pload<Packet>(by + P), a1);
  }
  alignas(64) Scalar lane[2 * P];
  pstore(lane, a0);
  pstore(lane + P, a1);
  // Pairwise in a fixed order.
  for (int w = P; w >= 1; w /= 2)
    for (int k = 0; k < w; ++k) lane[k] = lane[k] + lane[k + w];
  return lane[0];
}

/// The update of one conjugate-gradient iteration in one pass over the vectors:
///   x += alpha p,  r -= alpha q,  z = d .* r,  and returns r.z and r.r,
/// with the reductions laid out as in dot() (independent of appended zeros). Seven separate
/// vector passes become one.
inline void cg_update(Scalar alpha, const Scalar* p, const Scalar* q, const Scalar* d, Scalar* x, Scalar* r, Scalar* z,
                      Index n, Scalar& rz, Scalar& rr) {
  using namespace Eigen::internal;
  using Packet = packet_traits<Scalar>::type;
  constexpr int P = packet_traits<Scalar>::size;
  const Packet a = pset1<Packet>(alpha);
  Packet rz0 = pset1<Packet>(0.0), rz1 = rz0, rr0 = rz0, rr1 = rz0;
  auto block = [&](const Scalar* pp, const Scalar* qq, const Scalar* dd, Scalar* xx, Scalar* rr_, Scalar* zz) {
    for (int h = 0; h < 2; ++h) {
      const int o = h * P;
      const Packet rv = psub(ploadu<Packet>(rr_ + o), pmul(a, ploadu<Packet>(qq + o)));
      const Packet zv = pmul(ploadu<Packet>(dd + o), rv);
      pstoreu(xx + o, padd(ploadu<Packet>(xx + o), pmul(a, ploadu<Packet>(pp + o))));
      pstoreu(rr_ + o, rv);
      pstoreu(zz + o, zv);
      if (h == 0) rz0 = pmadd(rv, zv, rz0), rr0 = pmadd(rv, rv, rr0);
      else rz1 = pmadd(rv, zv, rz1), rr1 = pmadd(rv, rv, rr1);
    }
  };
  Index i = 0;
  for (; i + 2 * P <= n; i += 2 * P) block(p + i, q + i, d + i, x + i, r + i, z + i);
  if (i < n) {
    alignas(64) Scalar bp[2 * P] = {}, bq[2 * P] = {}, bd[2 * P] = {}, bx[2 * P] = {}, br[2 * P] = {}, bz[2 * P] = {};
    const Index m = n - i;
    for (Index k = 0; k < m; ++k) bp[k] = p[i + k], bq[k] = q[i + k], bd[k] = d[i + k], bx[k] = x[i + k], br[k] = r[i + k];
    block(bp, bq, bd, bx, br, bz);
    for (Index k = 0; k < m; ++k) x[i + k] = bx[k], r[i + k] = br[k], z[i + k] = bz[k];
  }
  auto reduce = [](const Packet& u, const Packet& v) {
    alignas(64) Scalar lane[2 * P];
    pstore(lane, u);
    pstore(lane + P, v);
    for (int w = P; w >= 1; w /= 2)
      for (int k = 0; k < w; ++k) lane[k] = lane[k] + lane[k + w];
    return lane[0];
  };
  rz = reduce(rz0, rz1);
  rr = reduce(rr0, rr1);
}

template <class A, class B>
Scalar dot(const Eigen::MatrixBase<A>& x, const Eigen::MatrixBase<B>& y) {
  return dot(x.derived().data(), y.derived().data(), static_cast<Index>(x.size()));
}
template <class A>
Scalar squared_norm(const Eigen::MatrixBase<A>& x) {
  return dot(x, x);
}
template <class A>
Scalar norm(const Eigen::MatrixBase<A>& x) {
  return std::sqrt(squared_norm(x));
}

}  // namespace plastifem
