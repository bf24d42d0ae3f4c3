#pragma once
/// @file nodal_gather.hpp
/// The gathers and scatters of the nodal blocks' fast force kernels (nodal_fast.hpp): F, Fdot and L
/// from a point's stencil (shared stencils, whole-vector batches of 8 points where the stencils
/// agree), the scatters of V0 P, NSNI's sub-point triplets. Their plain scalar twin,
/// which a newcomer reads first, is nodal_reference.cpp beside this file;
/// verification/operators/test_reference_kernels.cpp holds the two to round-off.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <immintrin.h>
#include <memory>

#include "rkfem/core/error.hpp"
#include "rkfem/core/huge_pages.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/simd.hpp"
#include "rkfem/core/stream_stores.hpp"
#include "rkfem/operators/bulk_viscosity.hpp"
#include "rkfem/operators/nodal_block.hpp"

namespace rkfem::nodal_kernels
{
#if defined(__AVX2__) && defined(__FMA__)
const __m256i lanes3 = _mm256_setr_epi64x(-1, -1, -1, 0);
#endif

/// Asks for the lines of [p, p + bytes) in the second-level cache (one software prefetch per
/// line). The force pass streams the next batch's stencils in so while it scatters this one's:
/// see NodalBlock::prefetch_points.
inline void prefetch_to_l2(const void* p, std::size_t bytes)
{
    const std::uintptr_t first = reinterpret_cast<std::uintptr_t>(p) & ~std::uintptr_t{63};
    const std::uintptr_t end = reinterpret_cast<std::uintptr_t>(p) + bytes;
    for (std::uintptr_t a = first; a < end; a += 64)
        _mm_prefetch(reinterpret_cast<const char*>(a), _MM_HINT_T1);
}
inline void prefetch_to_l2(const StencilView& s)
{
    prefetch_to_l2(s.grad, 3 * sizeof(real_t) * static_cast<std::size_t>(s.size));
    prefetch_to_l2(s.offset, sizeof(index_t) * static_cast<std::size_t>(s.size));
}
inline void prefetch_to_l2(const TripletView& t)
{
    prefetch_to_l2(t.hess, 6 * sizeof(real_t) * static_cast<std::size_t>(t.size));
    prefetch_to_l2(t.offset, sizeof(index_t) * static_cast<std::size_t>(t.size));
}

/// F = 1 + sum_k u_k (x) g_k and Fd = sum_k v_k (x) g_k over the entries of point p. With AVX2
/// each column is one 4-lane FMA (lane 3 unused): 6 FMAs per entry instead of 18 scalar ones.
inline void gather_gradients(const StencilView& st, const real_t* u, const real_t* v, real_t F[3][3], real_t Fd[3][3])
{
#if defined(__AVX2__) && defined(__FMA__)
    __m256d f0 = _mm256_setr_pd(1, 0, 0, 0), f1 = _mm256_setr_pd(0, 1, 0, 0), f2 = _mm256_setr_pd(0, 0, 1, 0);
    __m256d d0 = _mm256_setzero_pd(), d1 = _mm256_setzero_pd(), d2 = _mm256_setzero_pd();
    for (index_t k = 0; k < st.size; ++k)
    {
        const std::size_t n = 3 * static_cast<std::size_t>(st.base + st.offset[k]);
        const real_t* g = st.grad + 3 * static_cast<std::size_t>(k);
        const __m256d uu = _mm256_maskload_pd(u + n, lanes3), vv = _mm256_maskload_pd(v + n, lanes3);
        const __m256d g0 = _mm256_broadcast_sd(g), g1 = _mm256_broadcast_sd(g + 1), g2 = _mm256_broadcast_sd(g + 2);
        f0 = _mm256_fmadd_pd(uu, g0, f0);
        f1 = _mm256_fmadd_pd(uu, g1, f1);
        f2 = _mm256_fmadd_pd(uu, g2, f2);
        d0 = _mm256_fmadd_pd(vv, g0, d0);
        d1 = _mm256_fmadd_pd(vv, g1, d1);
        d2 = _mm256_fmadd_pd(vv, g2, d2);
    }
    alignas(32) real_t c[6][4];
    _mm256_store_pd(c[0], f0);
    _mm256_store_pd(c[1], f1);
    _mm256_store_pd(c[2], f2);
    _mm256_store_pd(c[3], d0);
    _mm256_store_pd(c[4], d1);
    _mm256_store_pd(c[5], d2);
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
        {
            F[i][j] = c[j][i];
            Fd[i][j] = c[3 + j][i];
        }
#else
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
        {
            F[i][j] = i == j ? 1.0 : 0.0;
            Fd[i][j] = 0.0;
        }
    for (index_t k = 0; k < st.size; ++k)
    {
        const std::size_t n = 3 * static_cast<std::size_t>(st.base + st.offset[k]);
        const real_t* g = st.grad + 3 * static_cast<std::size_t>(k);
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
            {
                F[i][j] += u[n + i] * g[j];
                Fd[i][j] += v[n + i] * g[j];
            }
    }
#endif
}

/// G = sum_k v_k (x) g_k over the entries of a stencil (stabilization sub-cells).
inline void gather_velocity_gradient(const StencilView& st, const real_t* v, real_t G[3][3])
{
#if defined(__AVX2__) && defined(__FMA__)
    __m256d d0 = _mm256_setzero_pd(), d1 = _mm256_setzero_pd(), d2 = _mm256_setzero_pd();
    for (index_t k = 0; k < st.size; ++k)
    {
        const real_t* g = st.grad + 3 * static_cast<std::size_t>(k);
        const __m256d vv = _mm256_maskload_pd(v + 3 * static_cast<std::size_t>(st.base + st.offset[k]), lanes3);
        d0 = _mm256_fmadd_pd(vv, _mm256_broadcast_sd(g), d0);
        d1 = _mm256_fmadd_pd(vv, _mm256_broadcast_sd(g + 1), d1);
        d2 = _mm256_fmadd_pd(vv, _mm256_broadcast_sd(g + 2), d2);
    }
    alignas(32) real_t c[3][4];
    _mm256_store_pd(c[0], d0);
    _mm256_store_pd(c[1], d1);
    _mm256_store_pd(c[2], d2);
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            G[i][j] = c[j][i];
#else
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            G[i][j] = 0.0;
    for (index_t k = 0; k < st.size; ++k)
    {
        const std::size_t n = 3 * static_cast<std::size_t>(st.base + st.offset[k]);
        const real_t* g = st.grad + 3 * static_cast<std::size_t>(k);
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                G[i][j] += v[n + i] * g[j];
    }
#endif
}

/// f = sum over the node's slots of P_point g (P stored by columns: [9 q + 3 j + a] = P_aj).
inline void gather_forces(const NodalBlock& blk, index_t i, real_t f[3])
{
#if defined(__AVX2__) && defined(__FMA__)
    // three accumulators (one per gradient component): three independent FMA chains
    __m256d a0 = _mm256_setzero_pd(), a1 = _mm256_setzero_pd(), a2 = _mm256_setzero_pd();
    for (index_t q = blk.node_entry_offsets[i]; q < blk.node_entry_offsets[i + 1]; ++q)
    {
        const real_t* g = &blk.node_grad[3 * static_cast<std::size_t>(q)];
        const real_t* P = &blk.point_tensor[9 * static_cast<std::size_t>(blk.node_point[q])];
        a0 = _mm256_fmadd_pd(_mm256_maskload_pd(P, lanes3), _mm256_broadcast_sd(g), a0);
        a1 = _mm256_fmadd_pd(_mm256_maskload_pd(P + 3, lanes3), _mm256_broadcast_sd(g + 1), a1);
        a2 = _mm256_fmadd_pd(_mm256_maskload_pd(P + 6, lanes3), _mm256_broadcast_sd(g + 2), a2);
    }
    alignas(32) real_t c[4];
    _mm256_store_pd(c, _mm256_add_pd(_mm256_add_pd(a0, a1), a2));
    f[0] = c[0], f[1] = c[1], f[2] = c[2];
#else
    f[0] = f[1] = f[2] = 0.0;
    for (index_t q = blk.node_entry_offsets[i]; q < blk.node_entry_offsets[i + 1]; ++q)
    {
        const real_t* g = &blk.node_grad[3 * static_cast<std::size_t>(q)];
        const real_t* P = &blk.point_tensor[9 * static_cast<std::size_t>(blk.node_point[q])];
        for (int a = 0; a < 3; ++a)
            f[a] += P[a] * g[0] + P[3 + a] * g[1] + P[6 + a] * g[2];
    }
#endif
}

/// buf[4 (n - lo) + a] += sum_j P_aj g_j for every entry (n, g) of a stencil; P by columns.
inline void scatter_point(const StencilView& st, const real_t P[9], real_t* buf, index_t lo)
{
#if defined(__AVX2__) && defined(__FMA__)
    const __m256d c0 = _mm256_setr_pd(P[0], P[1], P[2], 0.0), c1 = _mm256_setr_pd(P[3], P[4], P[5], 0.0),
                  c2 = _mm256_setr_pd(P[6], P[7], P[8], 0.0);
    real_t* const b = buf + 4 * static_cast<std::ptrdiff_t>(st.base - lo);
    for (index_t k = 0; k < st.size; ++k)
    {
        real_t* f = b + 4 * static_cast<std::size_t>(st.offset[k]);
        const real_t* g = st.grad + 3 * static_cast<std::size_t>(k);
        __m256d acc = _mm256_loadu_pd(f);
        acc = _mm256_fmadd_pd(c0, _mm256_broadcast_sd(g), acc);
        acc = _mm256_fmadd_pd(c1, _mm256_broadcast_sd(g + 1), acc);
        acc = _mm256_fmadd_pd(c2, _mm256_broadcast_sd(g + 2), acc);
        _mm256_storeu_pd(f, acc);
    }
#else
    for (index_t k = 0; k < st.size; ++k)
    {
        real_t* f = buf + 4 * static_cast<std::size_t>(st.base + st.offset[k] - lo);
        const real_t* g = st.grad + 3 * static_cast<std::size_t>(k);
        for (int a = 0; a < 3; ++a)
            f[a] += P[a] * g[0] + P[3 + a] * g[1] + P[6 + a] * g[2];
    }
#endif
}

/// NSNI triplets (NodalBlock::stabilization_triplets): the sub-points 3 L + i (i = 0..2) of
/// point L have the same nodes in the same order, and entry k's coefficients are the rows of
/// one symmetric matrix, g_ikj = H_k(i, j) (RkShapeFunctions::hessians symmetrizes exactly), so
/// one pass over the nodes forms G_i = sum_k v_k (x) g_ik for the three (G[i][a][j]) from the six
/// sums A_ij = sum_k v_k H_k(i, j), i <= j. The entries come from the three sub-point stencils
/// (SubPointTriplet) or from the packed triplet table (PackedTriplet, stencil_table.hpp), the
/// same values in the same order. The plain twin is three gather_velocity_gradient calls.
struct SubPointTriplet
{
    const StencilView* st; ///< the three sub-points' stencils
    index_t size() const { return st[0].size; }
    index_t node(index_t k) const { return st[0].base + st[0].offset[k]; }
    /// H_k's six distinct values (00, 01, 02, 11, 12, 22)
    void values(index_t k, const real_t* (&h)[6]) const
    {
        const real_t* h0 = st[0].grad + 3 * static_cast<std::size_t>(k);
        const real_t* h1 = st[1].grad + 3 * static_cast<std::size_t>(k);
        const real_t* h2 = st[2].grad + 3 * static_cast<std::size_t>(k);
        h[0] = h0, h[1] = h0 + 1, h[2] = h0 + 2, h[3] = h1 + 1, h[4] = h1 + 2, h[5] = h2 + 2;
    }
};
struct PackedTriplet
{
    TripletView t;
    index_t size() const { return t.size; }
    index_t node(index_t k) const { return t.base + t.offset[k]; }
    void values(index_t k, const real_t* (&h)[6]) const
    {
        const real_t* e = t.hess + 6 * static_cast<std::size_t>(k);
        for (int q = 0; q < 6; ++q)
            h[q] = e + q;
    }
};

template <class Triplet> inline void gather_triplet(const Triplet& tr, const real_t* v, real_t G[3][3][3])
{
    alignas(32) real_t c[6][4];
#if defined(__AVX2__) && defined(__FMA__)
    __m256d a00 = _mm256_setzero_pd(), a01 = a00, a02 = a00, a11 = a00, a12 = a00, a22 = a00;
    for (index_t k = 0; k < tr.size(); ++k)
    {
        const __m256d vv = _mm256_maskload_pd(v + 3 * static_cast<std::size_t>(tr.node(k)), lanes3);
        const real_t* h[6];
        tr.values(k, h);
        a00 = _mm256_fmadd_pd(vv, _mm256_broadcast_sd(h[0]), a00);
        a01 = _mm256_fmadd_pd(vv, _mm256_broadcast_sd(h[1]), a01);
        a02 = _mm256_fmadd_pd(vv, _mm256_broadcast_sd(h[2]), a02);
        a11 = _mm256_fmadd_pd(vv, _mm256_broadcast_sd(h[3]), a11);
        a12 = _mm256_fmadd_pd(vv, _mm256_broadcast_sd(h[4]), a12);
        a22 = _mm256_fmadd_pd(vv, _mm256_broadcast_sd(h[5]), a22);
    }
    _mm256_store_pd(c[0], a00);
    _mm256_store_pd(c[1], a01);
    _mm256_store_pd(c[2], a02);
    _mm256_store_pd(c[3], a11);
    _mm256_store_pd(c[4], a12);
    _mm256_store_pd(c[5], a22);
#else
    for (int q = 0; q < 6; ++q)
        for (int a = 0; a < 4; ++a)
            c[q][a] = 0.0;
    for (index_t k = 0; k < tr.size(); ++k)
    {
        const real_t* vk = v + 3 * static_cast<std::size_t>(tr.node(k));
        const real_t* h[6];
        tr.values(k, h);
        for (int q = 0; q < 6; ++q)
            for (int a = 0; a < 3; ++a)
                c[q][a] += vk[a] * *h[q];
    }
#endif
    constexpr int sym[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};
    for (int i = 0; i < 3; ++i)
        for (int a = 0; a < 3; ++a)
            for (int j = 0; j < 3; ++j)
                G[i][a][j] = c[sym[i][j]][a];
}

/// buf[4 (n - lo) + a] += sum_i sum_j (P_i)_aj H_k(i, j) over the shared entries of a triplet
/// (each P_i by columns), as sum_{i <= j} Q_ij H_k(i, j) with Q_ii = P_i e_i, Q_ij = P_i e_j +
/// P_j e_i; the plain twin is three scatter_point calls.
template <class Triplet> inline void scatter_triplet(const Triplet& tr, const real_t P[3][9], real_t* buf, index_t lo)
{
#if defined(__AVX2__) && defined(__FMA__)
    auto col = [&](int i, int j) { return _mm256_setr_pd(P[i][3 * j], P[i][3 * j + 1], P[i][3 * j + 2], 0.0); };
    const __m256d q00 = col(0, 0), q11 = col(1, 1), q22 = col(2, 2), q01 = _mm256_add_pd(col(0, 1), col(1, 0)),
                  q02 = _mm256_add_pd(col(0, 2), col(2, 0)), q12 = _mm256_add_pd(col(1, 2), col(2, 1));
    for (index_t k = 0; k < tr.size(); ++k)
    {
        real_t* f = buf + 4 * static_cast<std::ptrdiff_t>(tr.node(k) - lo);
        const real_t* h[6];
        tr.values(k, h);
        // two independent chains, joined at the end
        __m256d x = _mm256_mul_pd(q00, _mm256_broadcast_sd(h[0]));
        __m256d y = _mm256_mul_pd(q11, _mm256_broadcast_sd(h[3]));
        x = _mm256_fmadd_pd(q01, _mm256_broadcast_sd(h[1]), x);
        y = _mm256_fmadd_pd(q12, _mm256_broadcast_sd(h[4]), y);
        x = _mm256_fmadd_pd(q02, _mm256_broadcast_sd(h[2]), x);
        y = _mm256_fmadd_pd(q22, _mm256_broadcast_sd(h[5]), y);
        _mm256_storeu_pd(f, _mm256_add_pd(_mm256_loadu_pd(f), _mm256_add_pd(x, y)));
    }
#else
    real_t q[6][3];
    constexpr int pairs[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
    for (int r = 0; r < 6; ++r)
    {
        const int i = pairs[r][0], j = pairs[r][1];
        for (int a = 0; a < 3; ++a)
            q[r][a] = i == j ? P[i][3 * j + a] : P[i][3 * j + a] + P[j][3 * i + a];
    }
    for (index_t k = 0; k < tr.size(); ++k)
    {
        real_t* f = buf + 4 * static_cast<std::ptrdiff_t>(tr.node(k) - lo);
        const real_t* h[6];
        tr.values(k, h);
        for (int a = 0; a < 3; ++a)
            f[a] += (q[0][a] * *h[0] + q[1][a] * *h[1] + q[2][a] * *h[2]) +
                    (q[3][a] * *h[3] + q[4][a] * *h[4] + q[5][a] * *h[5]);
    }
#endif
}

#if defined(__AVX512F__)
/// Is batch b uniform (uniform_batches, which the table holds from build_tables)? Then its 8
/// points read one stencil at consecutive bases, as whole vectors.
inline bool uniform_batch(const std::vector<char>& uniform, index_t b)
{
    return static_cast<std::size_t>(b) < uniform.size() && uniform[static_cast<std::size_t>(b)] != 0;
}

/// F = 1 + sum_k u_k (x) g_k and Fd = sum_k v_k (x) g_k for the 8 lanes of a uniform batch,
/// into F[i][j][l]. The sums run over the lanes' node triples as they lie in memory (three
/// vectors per entry, no shuffles), with the same FMAs in the same order as gather_gradients,
/// so the bits are those of the lane-by-lane path; the triples are unpacked once at the end.
inline void gather_gradients_uniform(const StencilView& st, const real_t* u, const real_t* v, real_t (&F)[3][3][8],
                                     real_t (&Fd)[3][3][8])
{
    // fu[j][r]: vector r of the triples (F_0j, F_1j, F_2j) of lanes 0..7 (position 8 r + e is
    // lane (8 r + e) / 3, component (8 r + e) % 3), starting from the identity's column j
    __m512d fu[3][3], fv[3][3];
    for (int j = 0; j < 3; ++j)
        for (int r = 0; r < 3; ++r)
        {
            alignas(64) real_t init[8];
            for (int e = 0; e < 8; ++e)
                init[e] = (8 * r + e) % 3 == j ? 1.0 : 0.0;
            fu[j][r] = _mm512_load_pd(init);
            fv[j][r] = _mm512_setzero_pd();
        }
    for (index_t k = 0; k < st.size; ++k)
    {
        const std::size_t n = 3 * static_cast<std::size_t>(st.base + st.offset[k]);
        const __m512d u0 = _mm512_loadu_pd(u + n), u1 = _mm512_loadu_pd(u + n + 8), u2 = _mm512_loadu_pd(u + n + 16);
        const __m512d v0 = _mm512_loadu_pd(v + n), v1 = _mm512_loadu_pd(v + n + 8), v2 = _mm512_loadu_pd(v + n + 16);
        const real_t* g = st.grad + 3 * static_cast<std::size_t>(k);
        for (int j = 0; j < 3; ++j)
        {
            const __m512d gj = _mm512_set1_pd(g[j]);
            fu[j][0] = _mm512_fmadd_pd(u0, gj, fu[j][0]);
            fu[j][1] = _mm512_fmadd_pd(u1, gj, fu[j][1]);
            fu[j][2] = _mm512_fmadd_pd(u2, gj, fu[j][2]);
            fv[j][0] = _mm512_fmadd_pd(v0, gj, fv[j][0]);
            fv[j][1] = _mm512_fmadd_pd(v1, gj, fv[j][1]);
            fv[j][2] = _mm512_fmadd_pd(v2, gj, fv[j][2]);
        }
    }
    for (int j = 0; j < 3; ++j)
    {
        __m512d X, Y, Z;
        simd::deinterleave3(fu[j][0], fu[j][1], fu[j][2], X, Y, Z);
        _mm512_store_pd(F[0][j], X);
        _mm512_store_pd(F[1][j], Y);
        _mm512_store_pd(F[2][j], Z);
        simd::deinterleave3(fv[j][0], fv[j][1], fv[j][2], X, Y, Z);
        _mm512_store_pd(Fd[0][j], X);
        _mm512_store_pd(Fd[1][j], Y);
        _mm512_store_pd(Fd[2][j], Z);
    }
}

/// buf += V0 P g for the 8 lanes of a uniform batch (P[3 j + i][l] = P_ij of lane l). Column j
/// of the lanes' P as padded quadruples (x, y, z, 0), 4 vectors; per entry the 8 consecutive
/// nodes' quadruples are 4 vectors of the buffer. The entries run in the table's add order
/// (uniform_add_order), so each node takes its lanes' terms in lane order, with the FMAs of
/// scatter_point: the same bits.
inline void scatter_uniform(const StencilView& st, const real_t (&P)[9][8], real_t* buf, index_t lo)
{
    __m512d c[3][4];
    for (int j = 0; j < 3; ++j)
        simd::interleave4(_mm512_load_pd(P[3 * j]), _mm512_load_pd(P[3 * j + 1]), _mm512_load_pd(P[3 * j + 2]), c[j]);
    real_t* const b = buf + 4 * static_cast<std::ptrdiff_t>(st.base - lo);
    for (index_t e = 0; e < st.size; ++e)
    {
        const index_t k = st.add_order ? st.add_order[e] : st.size - 1 - e;
        real_t* f = b + 4 * static_cast<std::size_t>(st.offset[k]);
        const real_t* g = st.grad + 3 * static_cast<std::size_t>(k);
        const __m512d g0 = _mm512_set1_pd(g[0]), g1 = _mm512_set1_pd(g[1]), g2 = _mm512_set1_pd(g[2]);
        for (int q = 0; q < 4; ++q)
        {
            __m512d acc = _mm512_loadu_pd(f + 8 * q);
            acc = _mm512_fmadd_pd(c[0][q], g0, acc);
            acc = _mm512_fmadd_pd(c[1][q], g1, acc);
            acc = _mm512_fmadd_pd(c[2][q], g2, acc);
            _mm512_storeu_pd(f + 8 * q, acc);
        }
    }
}
#endif

#if defined(__AVX512F__)
/// gather_triplet for the 8 lanes of a uniform triplet batch, into G[i][a][j][l]: per entry the
/// lanes' 8 consecutive node triples are 3 vectors, each of the six Hessian values one broadcast,
/// with gather_triplet's FMAs in its order per lane (the same bits); unpacked once at the end.
inline void gather_triplets_uniform(const TripletView& tv, const real_t* v, real_t (&G)[3][3][3][8])
{
    __m512d acc[6][3];
    for (int q = 0; q < 6; ++q)
        for (int r = 0; r < 3; ++r)
            acc[q][r] = _mm512_setzero_pd();
    for (index_t k = 0; k < tv.size; ++k)
    {
        const real_t* vk = v + 3 * static_cast<std::size_t>(tv.base + tv.offset[k]);
        const __m512d v0 = _mm512_loadu_pd(vk), v1 = _mm512_loadu_pd(vk + 8), v2 = _mm512_loadu_pd(vk + 16);
        const real_t* h = tv.hess + 6 * static_cast<std::size_t>(k);
        for (int q = 0; q < 6; ++q)
        {
            const __m512d hq = _mm512_set1_pd(h[q]);
            acc[q][0] = _mm512_fmadd_pd(v0, hq, acc[q][0]);
            acc[q][1] = _mm512_fmadd_pd(v1, hq, acc[q][1]);
            acc[q][2] = _mm512_fmadd_pd(v2, hq, acc[q][2]);
        }
    }
    constexpr int sym[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
        {
            __m512d X, Y, Z;
            const int q = sym[i][j];
            simd::deinterleave3(acc[q][0], acc[q][1], acc[q][2], X, Y, Z);
            _mm512_store_pd(G[i][0][j], X);
            _mm512_store_pd(G[i][1][j], Y);
            _mm512_store_pd(G[i][2][j], Z);
        }
}

/// scatter_triplet for the 8 lanes of a uniform triplet batch (P[i][3 j + a][l]): the six
/// column sums Q_ij of the lanes as padded quadruples, 4 vectors each; the entries run in the
/// table's add order (uniform_add_order), so each node takes its lanes' terms in lane order, with
/// scatter_triplet's operations: the same bits.
inline void scatter_triplets_uniform(const TripletView& tv, const real_t (&P)[3][9][8], real_t* buf, index_t lo)
{
    constexpr int pairs[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
    __m512d Q[6][4];
    for (int r = 0; r < 6; ++r)
    {
        const int i = pairs[r][0], j = pairs[r][1];
        __m512d c[3];
        for (int a = 0; a < 3; ++a)
        {
            c[a] = _mm512_load_pd(P[i][3 * j + a]);
            if (i != j)
                c[a] = _mm512_add_pd(c[a], _mm512_load_pd(P[j][3 * i + a]));
        }
        simd::interleave4(c[0], c[1], c[2], Q[r]);
    }
    real_t* const b = buf + 4 * static_cast<std::ptrdiff_t>(tv.base - lo);
    for (index_t e = 0; e < tv.size; ++e)
    {
        const index_t k = tv.add_order ? tv.add_order[e] : tv.size - 1 - e;
        real_t* f = b + 4 * static_cast<std::size_t>(tv.offset[k]);
        const real_t* h = tv.hess + 6 * static_cast<std::size_t>(k);
        const __m512d h0 = _mm512_set1_pd(h[0]), h1 = _mm512_set1_pd(h[1]), h2 = _mm512_set1_pd(h[2]),
                      h3 = _mm512_set1_pd(h[3]), h4 = _mm512_set1_pd(h[4]), h5 = _mm512_set1_pd(h[5]);
        for (int m = 0; m < 4; ++m)
        {
            // scatter_triplet's two chains, joined at the end
            __m512d x = _mm512_mul_pd(Q[0][m], h0);
            __m512d y = _mm512_mul_pd(Q[3][m], h3);
            x = _mm512_fmadd_pd(Q[1][m], h1, x);
            y = _mm512_fmadd_pd(Q[4][m], h4, y);
            x = _mm512_fmadd_pd(Q[2][m], h2, x);
            y = _mm512_fmadd_pd(Q[5][m], h5, y);
            _mm512_storeu_pd(f + 8 * m, _mm512_add_pd(_mm512_loadu_pd(f + 8 * m), _mm512_add_pd(x, y)));
        }
    }
}
#endif

/// V0 P = V0 J (sigma - q 1) F^-T of lane l, by columns ([3 j + i] = P_ij).
} // namespace rkfem::nodal_kernels
