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

#include <algorithm>

#ifdef _OPENMP
#include <omp.h>
#endif

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

/// The vector passes of CG in fixed chunks of `vector_chunk` dofs: each chunk's sums are formed
/// as dot() forms them, then added in chunk order. Which thread ran a chunk changes nothing, so
/// any thread count gives the same bits, and zeros appended to the vectors add exact zeros (to
/// the last chunk's lanes, or as chunks of their own). 3072 dofs: a multiple of 3 (a node's
/// three rows never straddle two chunks) and of 2 P for any packet up to AVX-512's (P = 8).
inline constexpr Index vector_chunk = 3072;
inline Index num_vector_chunks(Index n) { return (n + vector_chunk - 1) / vector_chunk; }

/// pass(c, i0, i1) for each chunk c = [i0, i1) of [0, n), on up to `threads` threads (static
/// schedule). Below 4 chunks per thread a pass is serial: the fork costs more than it saves.
template <class Pass>
void for_each_vector_chunk(Index n, int threads, Pass&& pass) {
  const Index chunks = num_vector_chunks(n);
#ifdef _OPENMP
#pragma omp parallel for schedule(static) num_threads(threads) if (threads > 1 && chunks >= 4 * threads)
#else
  (void)threads;
#endif
  for (Index c = 0; c < chunks; ++c) pass(c, c * vector_chunk, std::min(n, (c + 1) * vector_chunk));
}

/// x . y by chunks (`partial`: room for num_vector_chunks(n) values).
inline Scalar dot(const Scalar* x, const Scalar* y, Index n, int threads, Scalar* partial) {
  for_each_vector_chunk(n, threads, [&](Index c, Index i0, Index i1) { partial[c] = dot(x + i0, y + i0, i1 - i0); });
  Scalar s = 0;
  for (Index c = 0; c < num_vector_chunks(n); ++c) s += partial[c];
  return s;
}

/// cg_update by chunks (`partial`: room for 2 num_vector_chunks(n) values).
inline void cg_update(Scalar alpha, const Scalar* p, const Scalar* q, const Scalar* d, Scalar* x, Scalar* r, Scalar* z,
                      Index n, Scalar& rz, Scalar& rr, int threads, Scalar* partial) {
  for_each_vector_chunk(n, threads, [&](Index c, Index i0, Index i1) {
    cg_update(alpha, p + i0, q + i0, d + i0, x + i0, r + i0, z + i0, i1 - i0, partial[2 * c], partial[2 * c + 1]);
  });
  rz = rr = 0;
  for (Index c = 0; c < num_vector_chunks(n); ++c) rz += partial[2 * c], rr += partial[2 * c + 1];
}

/// z = B r at one node, B its symmetric 3 x 3 block (9 values, row-major): the node-block
/// preconditioner's one product, shared by its initial pass and its fused update.
inline void node_block_times(const Scalar* B, Scalar r0, Scalar r1, Scalar r2, Scalar* z) {
  z[0] = B[0] * r0 + B[1] * r1 + B[2] * r2;
  z[1] = B[3] * r0 + B[4] * r1 + B[5] * r2;
  z[2] = B[6] * r0 + B[7] * r1 + B[8] * r2;
}

/// z = B r with a 3 x 3 block per node (`blocks`: 9 values per node, n a multiple of 3), by
/// chunks on up to `threads` threads.
inline void apply_node_blocks(const Scalar* blocks, const Scalar* r, Scalar* z, Index n, int threads) {
  eigen_assert(n % 3 == 0 && "apply_node_blocks: whole nodes of 3 dofs");
  for_each_vector_chunk(n, threads, [&](Index, Index i0, Index i1) {
    for (Index i = i0; i < i1; i += 3) node_block_times(blocks + 3 * i, r[i], r[i + 1], r[i + 2], z + i);
  });
}

/// cg_update with z = B r, B a symmetric 3 x 3 block per node (`blocks`: 9 values per node, n a
/// multiple of 3): x += alpha p, r -= alpha q, z = B r, and r.z and r.r, in one pass by chunks
/// (`partial` as for cg_update). Within a chunk the sums run in row order.
inline void cg_update_node_blocks(Scalar alpha, const Scalar* p, const Scalar* q, const Scalar* blocks, Scalar* x,
                                  Scalar* r, Scalar* z, Index n, Scalar& rz, Scalar& rr, int threads,
                                  Scalar* partial) {
  eigen_assert(n % 3 == 0 && "cg_update_node_blocks: whole nodes of 3 dofs");
  for_each_vector_chunk(n, threads, [&](Index c, Index i0, Index i1) {
    Scalar s_rz = 0, s_rr = 0;
    for (Index i = i0; i < i1; i += 3) {
      x[i] += alpha * p[i], x[i + 1] += alpha * p[i + 1], x[i + 2] += alpha * p[i + 2];
      const Scalar r0 = r[i] - alpha * q[i], r1 = r[i + 1] - alpha * q[i + 1], r2 = r[i + 2] - alpha * q[i + 2];
      Scalar zi[3];
      node_block_times(blocks + 3 * i, r0, r1, r2, zi);  // node i / 3's block
      r[i] = r0, r[i + 1] = r1, r[i + 2] = r2;
      z[i] = zi[0], z[i + 1] = zi[1], z[i + 2] = zi[2];
      s_rz += r0 * zi[0] + r1 * zi[1] + r2 * zi[2];
      s_rr += r0 * r0 + r1 * r1 + r2 * r2;
    }
    partial[2 * c] = s_rz, partial[2 * c + 1] = s_rr;
  });
  rz = rr = 0;
  for (Index c = 0; c < num_vector_chunks(n); ++c) rz += partial[2 * c], rr += partial[2 * c + 1];
}

/// p = z + beta p (CG's new direction), by chunks on up to `threads` threads.
inline void update_direction(const Scalar* z, Scalar beta, Scalar* p, Index n, int threads) {
  for_each_vector_chunk(n, threads, [&](Index, Index i0, Index i1) {
    for (Index i = i0; i < i1; ++i) p[i] = z[i] + beta * p[i];
  });
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
