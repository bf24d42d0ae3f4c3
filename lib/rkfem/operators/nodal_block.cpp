#include "rkfem/operators/nodal_block.hpp"

#include "rkfem/approximation/coupling/coupled_shapes.hpp"

#include <algorithm>
#include <map>
#include <immintrin.h>
#include <cmath>

#include "rkfem/core/error.hpp"
#include "rkfem/core/huge_pages.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/simd.hpp"
#include "rkfem/core/stream_stores.hpp"
#include "rkfem/operators/bulk_viscosity.hpp"
#include "rkfem/approximation/shape_evaluator.hpp"
#include "rkfem/discretization/voronoi_cells.hpp"
#include "rkfem/integration/nodal/nodal_integration.hpp"
#include <memory>

namespace rkfem
{
namespace
{
#if defined(__AVX2__) && defined(__FMA__)
const __m256i lanes3 = _mm256_setr_epi64x(-1, -1, -1, 0);
#endif

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

#if defined(__AVX512F__)
/// A batch whose 8 points share one stencil and whose bases are consecutive (points along a
/// lattice row): entry k of lane l touches node base + offset[k] + l, so each entry's nodes are 8
/// consecutive ones, read and written as whole vectors instead of lane by lane.
bool uniform_batch(const StencilTable& t, index_t p0)
{
    if (t.empty())
        return false;
    const __m256i s = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(t.point_stencil.data() + p0));
    const __m256i b = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(t.point_base.data() + p0));
    const __m256i row = _mm256_add_epi32(_mm256_set1_epi32(t.point_base[static_cast<std::size_t>(p0)]),
                                         _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
    return _mm256_cmpeq_epi32_mask(s, _mm256_set1_epi32(t.point_stencil[static_cast<std::size_t>(p0)])) == 0xFF &&
           _mm256_cmpeq_epi32_mask(b, row) == 0xFF;
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
/// nodes' quadruples are 4 vectors of the buffer. The entries run last to first, so each node
/// takes its lanes' terms in lane order, with the FMAs of scatter_point: the same bits.
inline void scatter_uniform(const StencilView& st, const real_t (&P)[9][8], real_t* buf, index_t lo)
{
    __m512d c[3][4];
    for (int j = 0; j < 3; ++j)
        simd::interleave4(_mm512_load_pd(P[3 * j]), _mm512_load_pd(P[3 * j + 1]), _mm512_load_pd(P[3 * j + 2]), c[j]);
    real_t* const b = buf + 4 * static_cast<std::ptrdiff_t>(st.base - lo);
    for (index_t k = st.size - 1; k >= 0; --k)
    {
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

/// V0 P = V0 J (sigma - q 1) F^-T of lane l, by columns ([3 j + i] = P_ij).
template <int W>
inline void first_piola(real_t VJ, real_t q, const real_t (&sn)[6][W], const real_t (&Fi)[3][3][W], int l,
                        real_t (&P)[9][W])
{
    const real_t S[3][3] = {{sn[0][l] - q, sn[3][l], sn[5][l]},
                            {sn[3][l], sn[1][l] - q, sn[4][l]},
                            {sn[5][l], sn[4][l], sn[2][l] - q}};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            P[3 * j + i][l] = VJ * (S[i][0] * Fi[j][0][l] + S[i][1] * Fi[j][1][l] + S[i][2] * Fi[j][2][l]);
}

constexpr int kPointLanes = 8; // stress points per batch (one AVX-512 register of doubles)

/// One batch of kPointLanes stress points: the stencil sums per point (gather_gradients), then
/// the per-point algebra as lane loops over structure-of-arrays scratch (F^-1, L, stress
/// update, bulk viscosity, stable step, V0 P), which the compiler vectorizes across points. The
/// loops are written without branches (min, 0/1 factors); a point with J <= 0 gets NaN or inf
/// in its lane and is flagged after the loops. FULL: all lanes are points; otherwise lanes past
/// the block's end repeat its first point and nothing of theirs is stored. With a scatter buffer
/// (buf != null, chunked assembly) V0 P g goes straight into it; otherwise V0 P is stored for the
/// transpose gather.
template <bool PLASTIC, bool FULL>
[[gnu::noinline]] void nodal_points_batch(NodalBlock& blk, const real_t* u, const real_t* v, index_t batch, real_t dt,
                                          real_t* buf, index_t lo)
{
    constexpr int W = kPointLanes;
    const IntegrationOperator& op = blk.points;
    const index_t np = blk.n_points();
    const std::size_t snp = blk.stress_stride;
    const index_t p0 = batch * W;
    const int nl = FULL ? W : static_cast<int>(std::min<index_t>(W, np - p0));
    auto lane_point = [&](int l) { return static_cast<std::size_t>(p0 + (FULL || l < nl ? l : 0)); };
    const ElasticParams mat = blk.material;
    const real_t c = mat.wave_speed();
    const real_t alpha = blk.dt_factor;
    const real_t q1 = blk.bulk_viscosity.quadratic, q2 = blk.bulk_viscosity.linear;

    // the next batch's stencil (gradients and node ids) is requested now, so that it streams in
    // while this batch computes: the loads of a stencil otherwise wait on memory latency. Only
    // for stencils far larger than the caches: in cache the prefetches only cost (bench_rkpm,
    // 1 thread: 10k particles 94 -> 83 ns per particle-step without them, 30k 97 -> 89; 100k
    // 135 -> 113 and 300k 144 -> 140 with them)
    if (FULL && blk.prefetch_stencils)
    {
        const index_t pn = std::min<index_t>(p0 + 2 * W, np);
        if (p0 + W < pn)
        {
            const std::size_t k0 = static_cast<std::size_t>(op.offsets[p0 + W]), k1 = static_cast<std::size_t>(op.offsets[pn]);
            const char* g = reinterpret_cast<const char*>(op.grad.data());
            for (std::size_t b = 24 * k0; b < 24 * k1; b += 64)
                _mm_prefetch(g + b, _MM_HINT_T0);
            const char* n = reinterpret_cast<const char*>(op.nodes.data());
            for (std::size_t b = 4 * k0; b < 4 * k1; b += 64)
                _mm_prefetch(n + b, _MM_HINT_T0);
        }
    }
    alignas(64) real_t F[3][3][W], Fd[3][3][W];
#if defined(__AVX512F__)
    const bool uniform = FULL && uniform_batch(blk.point_stencils, p0);
    if (uniform)
        gather_gradients_uniform(blk.point_stencils.view(p0), u, v, F, Fd);
    else
#else
    constexpr bool uniform = false;
#endif
    for (int l = 0; l < W; ++l)
    {
        real_t f[3][3], fd[3][3];
        gather_gradients(stencil_view(op, blk.point_stencils, static_cast<index_t>(lane_point(l))), u, v, f, fd);
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                F[i][j][l] = f[i][j], Fd[i][j][l] = fd[i][j];
    }

    alignas(64) real_t Jl[W], Fi[3][3][W], dl[6][W], wl[3][W], so[6][W], sn[6][W];
    const real_t* __restrict s_in = blk.stress.data();
    real_t* __restrict s_out = blk.stress_trial.data();
#pragma omp simd
    for (int l = 0; l < W; ++l)
    {
        const real_t J = F[0][0][l] * (F[1][1][l] * F[2][2][l] - F[1][2][l] * F[2][1][l]) -
                         F[0][1][l] * (F[1][0][l] * F[2][2][l] - F[1][2][l] * F[2][0][l]) +
                         F[0][2][l] * (F[1][0][l] * F[2][1][l] - F[1][1][l] * F[2][0][l]);
        Jl[l] = J;
        const real_t iJ = 1.0 / J;
        Fi[0][0][l] = (F[1][1][l] * F[2][2][l] - F[1][2][l] * F[2][1][l]) * iJ;
        Fi[0][1][l] = (F[0][2][l] * F[2][1][l] - F[0][1][l] * F[2][2][l]) * iJ;
        Fi[0][2][l] = (F[0][1][l] * F[1][2][l] - F[0][2][l] * F[1][1][l]) * iJ;
        Fi[1][0][l] = (F[1][2][l] * F[2][0][l] - F[1][0][l] * F[2][2][l]) * iJ;
        Fi[1][1][l] = (F[0][0][l] * F[2][2][l] - F[0][2][l] * F[2][0][l]) * iJ;
        Fi[1][2][l] = (F[0][2][l] * F[1][0][l] - F[0][0][l] * F[1][2][l]) * iJ;
        Fi[2][0][l] = (F[1][0][l] * F[2][1][l] - F[1][1][l] * F[2][0][l]) * iJ;
        Fi[2][1][l] = (F[0][1][l] * F[2][0][l] - F[0][0][l] * F[2][1][l]) * iJ;
        Fi[2][2][l] = (F[0][0][l] * F[1][1][l] - F[0][1][l] * F[1][0][l]) * iJ;
        real_t L[3][3];
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                L[i][j] = Fd[i][0][l] * Fi[0][j][l] + Fd[i][1][l] * Fi[1][j][l] + Fd[i][2][l] * Fi[2][j][l];
        dl[0][l] = L[0][0];
        dl[1][l] = L[1][1];
        dl[2][l] = L[2][2];
        dl[3][l] = 0.5 * (L[0][1] + L[1][0]);
        dl[4][l] = 0.5 * (L[1][2] + L[2][1]);
        dl[5][l] = 0.5 * (L[2][0] + L[0][2]);
        wl[0][l] = 0.5 * (L[0][1] - L[1][0]);
        wl[1][l] = 0.5 * (L[1][2] - L[2][1]);
        wl[2][l] = 0.5 * (L[2][0] - L[0][2]);
    }
    if constexpr (!PLASTIC && FULL)
    {
#pragma omp simd
        for (int l = 0; l < W; ++l)
        {
            const std::size_t p = static_cast<std::size_t>(p0 + l);
            real_t s0 = s_in[p], s1 = s_in[snp + p], s2 = s_in[2 * snp + p], s3 = s_in[3 * snp + p],
                   s4 = s_in[4 * snp + p], s5 = s_in[5 * snp + p];
            so[0][l] = s0, so[1][l] = s1, so[2][l] = s2, so[3][l] = s3, so[4][l] = s4, so[5][l] = s5;
            elastic_update(mat, dl[0][l], dl[1][l], dl[2][l], dl[3][l], dl[4][l], dl[5][l], wl[0][l], wl[1][l],
                           wl[2][l], dt, s0, s1, s2, s3, s4, s5);
            sn[0][l] = s0, sn[1][l] = s1, sn[2][l] = s2, sn[3][l] = s3, sn[4][l] = s4, sn[5][l] = s5;
        }
        store_batch8<6>(sn, s_out, snp, static_cast<std::size_t>(p0), buf != nullptr && blk.stream_stress);
    }
    else
    {
        // a partial batch or an inelastic block: the point's model update per lane
        for (int l = 0; l < W; ++l)
        {
            const std::size_t p = lane_point(l);
            const bool active = FULL || l < nl;
            const real_t d[6] = {dl[0][l], dl[1][l], dl[2][l], dl[3][l], dl[4][l], dl[5][l]};
            const real_t w[3] = {wl[0][l], wl[1][l], wl[2][l]};
            real_t s[6];
            for (int k = 0; k < 6; ++k)
                so[k][l] = s[k] = s_in[k * snp + p];
            if constexpr (PLASTIC)
            {
                if (active && Jl[l] > 0.0)
                    blk.plastic.update(static_cast<index_t>(p), d, w, dt, s);
            }
            else
                elastic_update(mat, d, w, dt, s);
            for (int k = 0; k < 6; ++k)
            {
                sn[k][l] = s[k];
                if (active)
                    s_out[k * snp + p] = s[k];
            }
        }
    }

    // J^(1/3) for the stable-step length: two Newton steps from 1 + (J - 1)/3 where |J - 1| <
    // 0.25 (relative error below 1e-7, far below what a time-step estimate needs), std::cbrt
    // (about 10 ns) only for the lanes outside, blended in without a branch
    alignas(64) real_t far[W], root[W];
    for (int l = 0; l < W; ++l)
    {
        const bool f = !(std::abs(Jl[l] - 1.0) < 0.25);
        far[l] = static_cast<real_t>(f);
        root[l] = f ? std::cbrt(Jl[l]) : 1.0;
    }
    // bulk viscosity (LS-DYNA form) with l = alpha J^(1/3) l0, the length of the stable-step
    // estimate, energies, V0 P = V0 J (sigma - q 1) F^-T
    alignas(64) real_t P[9][W], e_int[W], e_bv[W], dtl[W];
#pragma omp simd
    for (int l = 0; l < W; ++l)
    {
        const std::size_t p = lane_point(l);
        const real_t J = Jl[l];
        real_t r = 1.0 + (J - 1.0) / 3.0;
        r -= (r * r * r - J) / (3.0 * r * r);
        r -= (r * r * r - J) / (3.0 * r * r);
        r += far[l] * (root[l] - r);
        const real_t len = alpha * r * blk.length0[p];
        const real_t trd = dl[0][l] + dl[1][l] + dl[2][l];
        const real_t q = bulk_q(mat.rho / J, c, len, trd, q1, q2);
        dtl[l] = element_dt(c, len, trd, q1, q2);
        const real_t power = 0.5 * ((so[0][l] + sn[0][l]) * dl[0][l] + (so[1][l] + sn[1][l]) * dl[1][l] +
                                    (so[2][l] + sn[2][l]) * dl[2][l]) +
                             (so[3][l] + sn[3][l]) * dl[3][l] + (so[4][l] + sn[4][l]) * dl[4][l] +
                             (so[5][l] + sn[5][l]) * dl[5][l];
        const real_t VJ = op.weight[p] * J;
        e_int[l] = dt * VJ * power;
        e_bv[l] = -dt * VJ * q * trd;
        first_piola(VJ, q, sn, Fi, l, P);
    }

    // the batch's energies (summed in lane order), smallest step and first bad point: what the
    // step needs of its points, without per-point arrays to write and read back
    const bool stabilized = blk.n_stab() > 0; // the stabilization of this point's sub-cells needs F^-1 and W
    real_t sum_int = 0.0, sum_bv = 0.0, dt_min = std::numeric_limits<real_t>::max();
    index_t dt_point = p0, bad = -1;
    bool good[W] = {}; // the lane's point has J > 0 and a step (its forces are assembled)
    for (int l = 0; l < nl; ++l)
    {
        const std::size_t p = static_cast<std::size_t>(p0 + l);
        const real_t J = Jl[l];
        blk.jacobian[p] = J;
        good[l] = J > 0.0 && dtl[l] > 0.0;
        if (!good[l])
        {
            if (bad < 0)
                bad = static_cast<index_t>(p);
            continue;
        }
        sum_int += e_int[l];
        sum_bv += e_bv[l];
        if (dtl[l] < dt_min)
        {
            dt_min = dtl[l];
            dt_point = static_cast<index_t>(p);
        }
        if (stabilized)
        {
            real_t* fi = &blk.finv[9 * p];
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    fi[3 * i + j] = Fi[i][j][l];
            for (int k = 0; k < 3; ++k)
                blk.spin[3 * p + k] = wl[k][l];
        }
    }
    // V0 P g into the chunk's buffer (or V0 P out for the transpose gather), for the good points
#if defined(__AVX512F__)
    if (uniform && buf && bad < 0)
        scatter_uniform(blk.point_stencils.view(p0), P, buf, lo);
    else
#endif
        for (int l = 0; l < nl; ++l)
        {
            const std::size_t p = static_cast<std::size_t>(p0 + l);
            if (!good[l])
                continue;
            real_t Pp[9];
            for (int k = 0; k < 9; ++k)
                Pp[k] = P[k][l];
            if (buf)
                scatter_point(stencil_view(op, blk.point_stencils, static_cast<index_t>(p)), Pp, buf, lo);
            else
                std::copy(Pp, Pp + 9, &blk.point_tensor[9 * p]);
        }
    (void)uniform;
    const std::size_t b = static_cast<std::size_t>(batch);
    blk.batch_sums[3 * b] = sum_int;
    blk.batch_sums[3 * b + 1] = sum_bv;
    blk.batch_sums[3 * b + 2] = dt_min;
    blk.batch_idx[2 * b] = dt_point;
    blk.batch_idx[2 * b + 1] = bad;
}

/// Default dt factor alpha (dt = alpha J^(1/3) l0 / c) per nodal formulation, calibrated from
/// the largest eigenvalue of M^-1 K on free regular and jittered blocks (verification/
/// operators/test_nodal_dynamics.cpp, NodalTimeStep prints alpha_crit): the smallest critical
/// value found (regular block: rkpm 1.054, fem-nodal 0.957), rounded down. Like l/c for hexes
/// it is the critical estimate; time.dt_scale (0.9) applies on top.
real_t default_dt_factor(const PartSpec& ps)
{
    return ps.formulation == Formulation::Rkpm ? 1.0 : 0.95;
}

} // namespace

RkParams rk_params(const RkSpec& spec)
{
    RkParams rp;
    rp.order = spec.order;
    rp.kernel = spec.kernel == "quintic-bspline" ? KernelType::QuinticBSpline
                : spec.kernel == "gaussian"      ? KernelType::Gaussian
                                                 : KernelType::CubicBSpline;
    rp.support = spec.support == "sphere" ? SupportShape::Sphere : SupportShape::Box;
    rp.normalized_support = spec.normalized_support;
    return rp;
}

namespace
{
NodalBlock block_frame(const PartSpec& ps, index_t n_nodes, index_t offset)
{
    NodalBlock nb;
    nb.material = ElasticParams::from_E_nu(ps.material.rho, ps.material.E, ps.material.nu);
    nb.plastic.configure(ps.material);
    nb.node_begin = offset;
    nb.node_end = offset + n_nodes;
    nb.dt_factor = ps.nodal.dt_factor > 0 ? ps.nodal.dt_factor : default_dt_factor(ps);
    nb.bulk_viscosity = ps.bulk_viscosity;
    return nb;
}

/// RK interpolation Psi_J(X_I) at the particles, for physical nodal values.
void add_interpolation(NodalBlock& nb, const RkShapeFunctions& rk, const std::vector<real_t>& x, index_t offset)
{
    RkSample smp;
    nb.interp_offsets.assign(1, 0);
    for (std::size_t i = 0; 3 * i < x.size(); ++i)
    {
        rk.evaluate(Vec3(x[3 * i], x[3 * i + 1], x[3 * i + 2]), false, smp);
        for (index_t k = 0; k < smp.size(); ++k)
        {
            nb.interp_nodes.push_back(smp.nodes[k] + offset);
            nb.interp_values.push_back(smp.psi[k]);
        }
        nb.interp_offsets.push_back(static_cast<index_t>(nb.interp_nodes.size()));
    }
}

DeckError singular_support(const PartSpec& ps, const SingularMomentError& e)
{
    return DeckError({ps.rk.loc.where.empty() ? ps.loc.where : ps.rk.loc.where, ps.loc.path + ".rk.normalized_support"},
                     e.what(), "expected a support large enough that every point is covered by 4 particles not in one plane");
}

/// Operators to global node ids, l0 per point from the owner node, state arrays, crack bands.
void finish_block(NodalBlock& nb, index_t offset, const std::vector<real_t>& l0, const std::vector<real_t>& band)
{
    for (auto* op : {&nb.points, &nb.stabilization})
    {
        for (auto& n : op->nodes)
            n += offset;
        for (auto& o : op->owner)
            o += offset;
    }
    nb.length0.resize(static_cast<std::size_t>(nb.points.n_points()));
    std::vector<real_t> lengths(nb.length0.size());
    for (index_t p = 0; p < nb.points.n_points(); ++p)
    {
        nb.length0[p] = l0[nb.points.owner[p] - offset];
        lengths[p] = band[nb.points.owner[p] - offset];
    }
    nb.initialize();
    nb.plastic.set_lengths(lengths);
}
} // namespace

NodalBlock build_nodal_block(const PartSpec& ps, const HexMesh& mesh, index_t offset)
{
    NodalBlock nb = block_frame(ps, mesh.n_nodes(), offset);
    const NodalScheme scheme = ps.nodal.scheme == "dni"       ? NodalScheme::Dni
                               : ps.nodal.scheme == "sd-scni" ? NodalScheme::SdScni
                                                              : NodalScheme::Scni;
    std::shared_ptr<const RkShapeFunctions> rk;
    std::unique_ptr<ShapeEvaluator> shapes;
    if (ps.formulation == Formulation::Rkpm)
    {
        rk = std::make_shared<const RkShapeFunctions>(rk_on_mesh(mesh, rk_params(ps.rk)));
        shapes = std::make_unique<RkShapes>(*rk);
        nb.rk = rk;
    }
    else
        shapes = std::make_unique<FemShapes>(mesh);
    try
    {
        nb.points = build_nodal(scheme, mesh, *shapes);
        if (scheme == NodalScheme::Scni && ps.nodal.stabilization == "mscni" && ps.nodal.stabilization_coefficient > 0)
        {
            nb.stabilization = build_mscni_stabilization(nb.points, build_sd_scni(mesh, *shapes));
            nb.stabilization_coefficient = ps.nodal.stabilization_coefficient;
        }
        if (rk)
            add_interpolation(nb, *rk, mesh.x, offset);
    }
    catch (const SingularMomentError& e)
    {
        throw singular_support(ps, e);
    }
    // stable-step length and crack band: the shortest mesh edge at the node
    const std::vector<real_t> l0 = nodal_spacing(mesh, false);
    finish_block(nb, offset, l0, l0);
    return nb;
}

namespace
{
/// Is point c inside region r (box, within radius of a cylinder's axis, sphere)?
bool inside_region(const SelectorSpec& r, const Vec3& c)
{
    switch (r.type)
    {
    case SelectorSpec::Type::Box:
        return (c.array() >= r.min.array()).all() && (c.array() <= r.max.array()).all();
    case SelectorSpec::Type::Cylinder:
    {
        const Vec3 d = c - r.point;
        return (d - d.dot(r.normal) * r.normal).norm() <= r.radius;
    }
    case SelectorSpec::Type::Sphere:
        return (c - r.point).norm() <= r.radius;
    default:
        return false;
    }
}
} // namespace

std::vector<char> rk_region_elements(const PartSpec& ps, const HexMesh& mesh)
{
    std::vector<char> rk(static_cast<std::size_t>(mesh.n_elements()), 0);
    for (index_t e = 0; e < mesh.n_elements(); ++e)
    {
        Vec3 c = Vec3::Zero();
        for (int a = 0; a < 8; ++a)
            c += mesh.node(mesh.conn[8 * e + a]) / 8.0;
        for (const SelectorSpec& r : ps.regions)
            rk[e] = rk[e] || inside_region(r, c);
    }
    return rk;
}

NodalBlock build_coupled_block(const PartSpec& ps, const HexMesh& mesh, index_t offset)
{
    const std::vector<char> rk_elements = rk_region_elements(ps, mesh);
    index_t n_rk = 0;
    for (char c : rk_elements)
        n_rk += c;
    if (n_rk == 0 || n_rk == mesh.n_elements())
        throw DeckError(ps.regions_loc,
                        n_rk == 0 ? "contain no element centroid of the part"
                                  : "contain every element of the part, leaving no FE region",
                        n_rk == 0 ? "expected regions that hold some of the part's elements"
                                  : "expected formulation: rkpm for an all-RK part, or smaller regions");
    NodalBlock nb = block_frame(ps, mesh.n_nodes(), offset);
    const Transition t = ps.transition == "ramp" ? Transition::Ramp : Transition::Mixed;
    try
    {
        auto shapes = std::make_shared<const CoupledShapes>(mesh, rk_elements, rk_params(ps.rk), t);
        nb.points = build_scni(mesh, *shapes);
        if (ps.nodal.stabilization == "mscni" && ps.nodal.stabilization_coefficient > 0)
        {
            nb.stabilization = build_mscni_stabilization(nb.points, build_sd_scni(mesh, *shapes));
            nb.stabilization_coefficient = ps.nodal.stabilization_coefficient;
        }
        // physical values: identity at FE nodes, the RK interpolant at particles
        nb.interp_offsets.assign(1, 0);
        std::vector<index_t> row_nodes;
        std::vector<real_t> row_values;
        for (index_t i = 0; i < mesh.n_nodes(); ++i)
        {
            row_nodes.clear();
            row_values.clear();
            shapes->node_row(i, row_nodes, row_values);
            for (std::size_t k = 0; k < row_nodes.size(); ++k)
            {
                nb.interp_nodes.push_back(row_nodes[k] + offset);
                nb.interp_values.push_back(row_values[k]);
            }
            nb.interp_offsets.push_back(static_cast<index_t>(nb.interp_nodes.size()));
        }
        nb.particle.resize(static_cast<std::size_t>(mesh.n_nodes()));
        for (index_t i = 0; i < mesh.n_nodes(); ++i)
            nb.particle[i] = shapes->is_particle(i);
        nb.coupled = shapes;
    }
    catch (const SingularMomentError& e)
    {
        throw singular_support(ps, e);
    }
    const std::vector<real_t> l0 = nodal_spacing(mesh, false);
    finish_block(nb, offset, l0, l0);
    return nb;
}

std::vector<HalfSpace> cloud_body(const GeneratorSpec& g, index_t n_particles)
{
    if (g.body == GeneratorSpec::Body::Box)
        return box_halfspaces(g.origin, g.origin + g.size);
    // the tangent prism, its facets about a quarter of the mean spacing wide: the body's volume
    // is then the cylinder's to (pi / sides)^2 / 3 (2e-4 at the minimum of 128 sides), and a
    // boundary cell meets a few of them
    const real_t spacing = std::cbrt(M_PI * g.radius * g.radius * g.height / std::max<index_t>(1, n_particles));
    const int sides = std::clamp(static_cast<int>(std::ceil(8.0 * M_PI * g.radius / spacing)), 128, 4096);
    return cylinder_halfspaces(g.origin, g.radius, g.height, sides);
}

NodalBlock build_cloud_block(const PartSpec& ps, const HexMesh& cloud, index_t offset)
{
    const GeneratorSpec& g = ps.generator;
    const index_t n = cloud.n_nodes();
    VoronoiCells cells;
    try
    {
        cells = voronoi_cells(cloud.x, cloud_body(g, n));
    }
    catch (const Error& e)
    {
        throw DeckError({g.loc.where, ps.loc.path + ".generator"}, e.what(),
                        "expected distinct particles inside the body");
    }
    // per particle: the facet area shared with each neighbour, and the longest distance to a
    // neighbour across a facet of at least 10% of the cell's largest (jitter adds small facets to
    // diagonal neighbours, which this leaves out). It sets the support size and the stable-step
    // length: with it the critical alpha of free clouds is 1.15-1.41 for jitter 0-0.45 and for
    // random points (NodalTimeStep.DefaultFactorIsBelowTheCriticalValueOnClouds), against 1.175
    // for the regular lattice; the nearest neighbour's distance gave 2-6 on jittered clouds
    // (needlessly small steps).
    std::vector<real_t> reach(static_cast<std::size_t>(n), 0.0);
    for (index_t i = 0; i < n; ++i)
    {
        std::map<index_t, real_t> area;
        for (index_t q = cells.offsets[i]; q < cells.offsets[i + 1]; ++q)
            if (cells.points[q].neighbour >= 0)
                area[cells.points[q].neighbour] += cells.points[q].nda.norm();
        real_t amax = 0.0;
        for (const auto& [j, a] : area)
            amax = std::max(amax, a);
        for (const auto& [j, a] : area)
        {
            if (a >= 0.1 * amax)
                reach[i] = std::max(reach[i], (cloud.node(i) - cloud.node(j)).norm());
        }
        if (area.empty())
            throw DeckError({g.loc.where, ps.loc.path + ".generator"}, "particle " + std::to_string(i) + " has no neighbour",
                            "expected at least 2 particles");
    }
    NodalBlock nb = block_frame(ps, n, offset);
    std::vector<real_t> a = reach;
    for (auto& v : a)
        v *= ps.rk.normalized_support;
    auto rk = std::make_shared<const RkShapeFunctions>(cloud.x, std::move(a), rk_params(ps.rk));
    nb.rk = rk;
    try
    {
        const RkShapes shapes(*rk);
        // SD-SCNI on a cloud: each Voronoi cell's pyramids (VoronoiCells::sub_cells, the sub-cells
        // MSCNI uses) are stress points of their own, owned by the cell's particle
        nb.points = ps.nodal.scheme == "dni"       ? build_dni_cells(cells.volume, cloud.x, shapes)
                    : ps.nodal.scheme == "sd-scni" ? build_sd_cells(cells, shapes)
                                                   : build_scni_cells(cells, cloud.x, shapes);
        if (ps.nodal.scheme == "scni" && ps.nodal.stabilization == "mscni" && ps.nodal.stabilization_coefficient > 0)
        {
            nb.stabilization = build_mscni_stabilization(nb.points, build_sd_cells(cells, shapes));
            nb.stabilization_coefficient = ps.nodal.stabilization_coefficient;
        }
        add_interpolation(nb, *rk, cloud.x, offset);
    }
    catch (const SingularMomentError& e)
    {
        throw singular_support(ps, e);
    }
    for (const CellFacetPoint& fp : cells.points)
        if (fp.neighbour < 0)
            nb.boundary_facets.push_back(fp);
    std::vector<real_t> band(cells.volume.size());
    for (std::size_t i = 0; i < band.size(); ++i)
        band[i] = std::cbrt(cells.volume[i]); // crack band: the cell's size
    finish_block(nb, offset, reach, band);
    return nb;
}

void NodalBlock::initialize(Assembly assembly)
{
    const index_t np = n_points(), ns = n_stab();
    const index_t ne_p = points.n_entries(), ne_s = stabilization.n_entries();
    const index_t nn = node_end - node_begin;

    // shared stencils first: they snap the operators' gradients, which the transpose copies
    point_stencils.clear();
    stab_stencils.clear();
    if (share_stencils)
    {
        point_stencils = rkfem::share_stencils(points);
        stab_stencils = rkfem::share_stencils(stabilization);
    }

    // chunked scatter: fixed chunks of stress points, then of stabilization points, each with
    // the node range its entries touch
    scatter.clear();
    scatter.node_begin = node_begin;
    scatter.node_end = node_end;
    n_point_chunks = 0;
    bool local = true;
    for (const IntegrationOperator* op : {&points, &stabilization})
    {
        // stabilization chunks cover as many nodes as stress-point chunks (about 8 sub-cells
        // per node)
        const index_t n = op->n_points();
        const index_t size = ChunkedScatter::chunk_size(np, kPointLanes) * std::max<index_t>(1, np > 0 ? n / np : 1);
        const std::size_t added = scatter.add_chunks(n, size,
                                                     [&](index_t first, index_t last, index_t& lo, index_t& hi)
                                                     {
                                                         for (index_t k = op->offsets[first]; k < op->offsets[last]; ++k)
                                                         {
                                                             RKFEM_REQUIRE(op->nodes[k] >= node_begin && op->nodes[k] < node_end,
                                                                           "nodal block: entry touches node "
                                                                               << op->nodes[k] << " outside the part's range ["
                                                                               << node_begin << ", " << node_end << ")");
                                                             lo = std::min(lo, op->nodes[k]);
                                                             hi = std::max(hi, op->nodes[k] + 1);
                                                         }
                                                     });
        if (op == &points)
            n_point_chunks = static_cast<index_t>(scatter.chunks.size());
        // a point order without locality (an imported cloud in random order) makes every
        // chunk's range the whole block: then the transpose gather
        local = local && added <= 4 * 3 * static_cast<std::size_t>(nn);
    }
    const bool use_scatter = assembly == Assembly::Scatter || (assembly == Assembly::Automatic && local);
    if (use_scatter)
        scatter.finish();
    else
    {
        scatter.clear();
        n_point_chunks = 0;
    }
    // transpose (node -> entries) for the gather assembly
    node_entry_offsets.clear();
    node_point.clear();
    node_grad.clear();
    if (!use_scatter)
    {
        std::vector<index_t> entry_point(static_cast<std::size_t>(ne_p + ne_s));
        for (index_t p = 0; p < np; ++p)
            for (index_t k = points.offsets[p]; k < points.offsets[p + 1]; ++k)
                entry_point[k] = p;
        for (index_t s = 0; s < ns; ++s)
            for (index_t k = stabilization.offsets[s]; k < stabilization.offsets[s + 1]; ++k)
                entry_point[ne_p + k] = np + s;
        node_entry_offsets.assign(static_cast<std::size_t>(nn) + 1, 0);
        auto node_of = [&](index_t k) { return k < ne_p ? points.nodes[k] : stabilization.nodes[k - ne_p]; };
        for (index_t k = 0; k < ne_p + ne_s; ++k)
        {
            const index_t n = node_of(k);
            ++node_entry_offsets[n - node_begin + 1];
        }
        for (index_t i = 0; i < nn; ++i)
            node_entry_offsets[i + 1] += node_entry_offsets[i];
        node_point.resize(static_cast<std::size_t>(ne_p + ne_s));
        node_grad.resize(3 * static_cast<std::size_t>(ne_p + ne_s));
        std::vector<index_t> fill(node_entry_offsets.begin(), node_entry_offsets.end() - 1);
        for (index_t k = 0; k < ne_p + ne_s; ++k)
        {
            const index_t q = fill[node_of(k) - node_begin]++;
            node_point[q] = entry_point[k];
            const real_t* g = k < ne_p ? &points.grad[3 * static_cast<std::size_t>(k)]
                                       : &stabilization.grad[3 * static_cast<std::size_t>(k - ne_p)];
            for (int d = 0; d < 3; ++d)
                node_grad[3 * static_cast<std::size_t>(q) + d] = g[d];
        }
    }

    owner_offsets.assign(static_cast<std::size_t>(nn) + 1, 0);
    for (index_t p = 0; p < np; ++p)
        ++owner_offsets[points.owner[p] - node_begin + 1];
    for (index_t i = 0; i < nn; ++i)
        owner_offsets[i + 1] += owner_offsets[i];
    owner_points.resize(static_cast<std::size_t>(np));
    {
        std::vector<index_t> f(owner_offsets.begin(), owner_offsets.end() - 1);
        for (index_t p = 0; p < np; ++p)
            owner_points[f[points.owner[p] - node_begin]++] = p;
    }

    stress_stride = batch8_stride(static_cast<std::size_t>(np));
    stress.assign(6 * stress_stride, 0.0);
    if (plastic.active())
        plastic.resize(static_cast<std::size_t>(np));
    stress_trial = stress;
    stab_stress.assign(6 * static_cast<std::size_t>(ns), 0.0);
    stab_stress_trial = stab_stress;
    jacobian.assign(static_cast<std::size_t>(np), 1.0);
    point_tensor.assign(use_scatter ? 0 : 9 * static_cast<std::size_t>(np + ns), 0.0);
    finv.assign(9 * static_cast<std::size_t>(np), 0.0);
    spin.assign(3 * static_cast<std::size_t>(np), 0.0);
    const std::size_t nb = static_cast<std::size_t>((np + kPointLanes - 1) / kPointLanes);
    batch_sums.assign(3 * nb, 0.0);
    batch_idx.assign(2 * nb, -1);
    stab_energy.assign(static_cast<std::size_t>(ns), 0.0);

    prefetch_stencils = point_stencils.empty() && points.grad.size() * sizeof(real_t) > (std::size_t{32} << 20);
    for (IntegrationOperator* op : {&points, &stabilization})
    {
        use_huge_pages(op->nodes);
        use_huge_pages(op->grad);
        use_huge_pages(op->weight);
    }
    use_huge_pages(stress);
    use_huge_pages(stress_trial);
    for (auto* a : {&node_grad, &stab_stress, &stab_stress_trial, &jacobian, &point_tensor, &finv, &spin, &stab_energy,
                    &length0})
        use_huge_pages(*a);
    use_huge_pages(node_point);
}

ForcePassResult nodal_internal_force(NodalBlock& blk, const NodeSet& nodes, real_t dt)
{
    const index_t np = blk.n_points(), ns = blk.n_stab();
    const ElasticParams mat = blk.material;
    const real_t* u = nodes.u.data();
    const real_t* v = nodes.v.data();

    auto batch = [&]<bool PLASTIC>(index_t b, real_t* buf, index_t lo)
    {
        if ((b + 1) * kPointLanes <= np)
            nodal_points_batch<PLASTIC, true>(blk, u, v, b, dt, buf, lo);
        else
            nodal_points_batch<PLASTIC, false>(blk, u, v, b, dt, buf, lo);
    };
    auto run = [&]<bool PLASTIC>()
    {
        if (blk.scatter_assembly())
            blk.scatter.run_chunks("rkfem::nodal_points", 0, blk.n_point_chunks, kPointLanes,
                                   [&](index_t b, real_t* buf, index_t lo) { batch.template operator()<PLASTIC>(b, buf, lo); });
        else
            parallel_for("rkfem::nodal_points", (np + kPointLanes - 1) / kPointLanes,
                         [&](index_t b) { batch.template operator()<PLASTIC>(b, nullptr, 0); });
    };
    if (blk.plastic.active())
        run.template operator()<true>();
    else
        run.template operator()<false>();

    ForcePassResult r;
    const index_t nb = (np + kPointLanes - 1) / kPointLanes;
    for (index_t b = 0; b < nb; ++b)
    {
        if (blk.batch_idx[2 * b + 1] >= 0)
        {
            r.bad_element = blk.batch_idx[2 * b + 1];
            return r;
        }
        if (blk.batch_sums[3 * b + 2] < r.dt_stable)
        {
            r.dt_stable = blk.batch_sums[3 * b + 2];
            r.dt_element = blk.batch_idx[2 * b];
        }
    }

    if (ns > 0)
    {
        const IntegrationOperator& st = blk.stabilization;
        const std::size_t sns = static_cast<std::size_t>(ns);
        ElasticParams smat = mat;
        smat.lambda *= blk.stabilization_coefficient;
        smat.mu *= blk.stabilization_coefficient;
        // sub-cell s: stress update and V0 P (by columns)
        auto sub_cell = [&](index_t s, real_t P[9])
        {
            const index_t L = st.parent[s];
            real_t G[3][3];
            gather_velocity_gradient(stencil_view(st, blk.stab_stencils, s), v, G);
            const real_t* Fi = &blk.finv[9 * static_cast<std::size_t>(L)];
            real_t Ls[3][3];
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    Ls[i][j] = G[i][0] * Fi[j] + G[i][1] * Fi[3 + j] + G[i][2] * Fi[6 + j];
            const real_t d[6] = {Ls[0][0], Ls[1][1], Ls[2][2], 0.5 * (Ls[0][1] + Ls[1][0]),
                                 0.5 * (Ls[1][2] + Ls[2][1]), 0.5 * (Ls[2][0] + Ls[0][2])};
            const real_t* w = &blk.spin[3 * static_cast<std::size_t>(L)];
            real_t s_old[6], sg[6];
            for (int k = 0; k < 6; ++k)
                s_old[k] = sg[k] = blk.stab_stress[k * sns + s];
            elastic_update(smat, d, w, dt, sg);
            for (int k = 0; k < 6; ++k)
                blk.stab_stress_trial[k * sns + s] = sg[k];
            real_t power = 0.0;
            for (int k = 0; k < 3; ++k)
                power += 0.5 * (s_old[k] + sg[k]) * d[k] + (s_old[k + 3] + sg[k + 3]) * d[k + 3];
            const real_t J = blk.jacobian[L];
            const real_t V0 = st.weight[s];
            blk.stab_energy[s] = dt * V0 * J * power;
            const real_t S[3][3] = {{sg[0], sg[3], sg[5]}, {sg[3], sg[1], sg[4]}, {sg[5], sg[4], sg[2]}};
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    P[3 * j + i] = V0 * J * (S[i][0] * Fi[3 * j] + S[i][1] * Fi[3 * j + 1] + S[i][2] * Fi[3 * j + 2]);
        };
        if (blk.scatter_assembly())
            blk.scatter.run_chunks("rkfem::nodal_stabilization", blk.n_point_chunks,
                                   static_cast<index_t>(blk.scatter.chunks.size()), 1,
                                   [&](index_t s, real_t* buf, index_t lo)
                                   {
                                       real_t P[9];
                                       sub_cell(s, P);
                                       scatter_point(stencil_view(st, blk.stab_stencils, s), P, buf, lo);
                                   });
        else
            parallel_for("rkfem::nodal_stabilization", ns,
                         [&](index_t s) { sub_cell(s, &blk.point_tensor[9 * (static_cast<std::size_t>(np) + s)]); });
    }

    r.d_internal = parallel_reduce_sum("rkfem::nodal_energy", nb, [&](index_t b) { return blk.batch_sums[3 * b]; });
    r.d_bulk_viscosity =
        parallel_reduce_sum("rkfem::nodal_bv_energy", nb, [&](index_t b) { return blk.batch_sums[3 * b + 1]; });
    r.d_hourglass = parallel_reduce_sum("rkfem::nodal_stab_energy", ns, [&](index_t s) { return blk.stab_energy[s]; });
    return r;
}

void assemble_nodal_forces(NodalBlock& blk, NodeSet& nodes, bool add)
{
    const index_t nn = blk.node_end - blk.node_begin;
    if (blk.scatter_assembly())
    {
        blk.scatter.reduce(nodes.f_int, add);
        return;
    }
    parallel_for("rkfem::nodal_assemble", nn,
                 [&](index_t i)
                 {
                     real_t f[3];
                     gather_forces(blk, i, f);
                     const std::size_t n = 3 * static_cast<std::size_t>(blk.node_begin + i);
                     for (int a = 0; a < 3; ++a)
                         nodes.f_int[n + a] = add ? nodes.f_int[n + a] + f[a] : f[a];
                 });
}

void add_nodal_mass(const NodalBlock& blk, NodeSet& nodes)
{
    for (index_t p = 0; p < blk.n_points(); ++p)
        nodes.mass[blk.points.owner[p]] += blk.material.rho * blk.points.weight[p];
}

} // namespace rkfem
