#include "rkfem/operators/nodal_force.hpp"

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

namespace rkfem
{
namespace
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
template <int W>
inline void first_piola(real_t VJ, real_t q, const real_t (&sn)[6][W], const real_t (&Fi)[3][3][W], int l,
                        real_t (&P)[9][W])
{
    const real_t S[3][3] = {
        {sn[0][l] - q, sn[3][l], sn[5][l]}, {sn[3][l], sn[1][l] - q, sn[4][l]}, {sn[5][l], sn[4][l], sn[2][l] - q}};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            P[3 * j + i][l] = VJ * (S[i][0] * Fi[j][0][l] + S[i][1] * Fi[j][1][l] + S[i][2] * Fi[j][2][l]);
}

/// NSNI in the stress points' batch (NodalBlock::stabilization_triplets, chunked scatter): for
/// the good lanes of points p0 .. p0 + nl - 1, the three sub-points 3 p + i get
/// G_i = sum_k v_k (x) g_ik (gather_triplet), D_i = sym(G_i F_p^-1), sigma_i += dt c_s C : D_i
/// (rotated with W_p) and V0_i J_p sigma_i F_p^-T g_ik into the chunk's buffer, which covers their
/// nodes (build_tables). The algebra runs as lane loops like the points'; the plain twin is the
/// separate stabilization pass (one sub-point at a time), which the gather assembly takes.
template <int W>
void nsni_batch(NodalBlock& blk, const real_t* v, index_t p0, int nl, const bool (&good)[W],
                const real_t (&Fi)[3][3][W], const real_t (&wl)[3][W], const real_t (&Jl)[W], real_t dt, real_t* buf,
                index_t lo)
{
    const IntegrationOperator& st = blk.stabilization;
    const std::size_t sns = static_cast<std::size_t>(blk.n_stab());
    ElasticParams smat = blk.material;
    smat.lambda *= blk.stabilization_coefficient;
    smat.mu *= blk.stabilization_coefficient;
    alignas(64) real_t G[3][3][3][W];
    // the packed triplets when built (build_tables), else the three sub-point stencils
    const bool packed = !blk.stab_triplets.empty();
    // the views are taken where they are read (a few loads each): arrays of them for the lanes
    // were value-initialized, a 1.3 KB memset per batch
    auto sub_point_views = [&](index_t t, StencilView(&sv)[3])
    {
        for (int i = 0; i < 3; ++i)
            sv[i] = stencil_view(st, blk.stab_stencils, 3 * t + i);
    };
#if defined(__AVX512F__)
    // a full batch along a lattice row with one triplet stencil: the whole-vector path
    const bool uniform = W == 8 && nl == W && packed && uniform_batch(blk.stab_triplets.uniform, p0 / W);
    if (uniform)
        gather_triplets_uniform(blk.stab_triplets.view(p0), v, G);
#else
    constexpr bool uniform = false;
#endif
    for (int l = 0; l < W && !uniform; ++l)
    {
        const index_t t = p0 + (l < nl ? l : 0);
        real_t g[3][3][3];
        if (packed)
            gather_triplet(PackedTriplet{blk.stab_triplets.view(t)}, v, g);
        else
        {
            StencilView sv[3];
            sub_point_views(t, sv);
            gather_triplet(SubPointTriplet{sv}, v, g);
        }
        for (int i = 0; i < 3; ++i)
            for (int a = 0; a < 3; ++a)
                for (int j = 0; j < 3; ++j)
                    G[i][a][j][l] = g[i][a][j];
    }
    bool all_good = nl == W;
    for (int l = 0; l < nl; ++l)
        all_good = all_good && good[l];
    // the lanes' sub-point states by direction, os[i][k][l] = component k of sub-point
    // 3 (p0 + l) + i (and its weight): the 24 sub-points of a full batch are consecutive, so with
    // AVX-512 each component is three vector loads split by direction (simd::load_triples)
    // instead of 24 strided ones inside the lane loop; the same values either way
    const real_t* __restrict s_in = blk.stab_stress.data();
    real_t* __restrict s_out = blk.stab_stress_trial.data();
    const real_t* __restrict weight = st.weight.data();
    alignas(64) real_t os[3][6][W], ws[3][W], sn[3][6][W], e[3][W];
    [[maybe_unused]] const std::size_t s0 = 3 * static_cast<std::size_t>(p0); // the batch's first sub-point
#if defined(__AVX512F__)
    constexpr bool triples = W == 8;
#else
    constexpr bool triples = false;
#endif
    if (triples && nl == W)
    {
#if defined(__AVX512F__)
        if constexpr (W == 8)
        {
            for (int k = 0; k < 6; ++k)
            {
                __m512d X, Y, Z;
                simd::load_triples(s_in + k * sns + s0, X, Y, Z);
                _mm512_store_pd(os[0][k], X);
                _mm512_store_pd(os[1][k], Y);
                _mm512_store_pd(os[2][k], Z);
            }
            __m512d X, Y, Z;
            simd::load_triples(weight + s0, X, Y, Z);
            _mm512_store_pd(ws[0], X);
            _mm512_store_pd(ws[1], Y);
            _mm512_store_pd(ws[2], Z);
        }
#endif
    }
    else
        for (int i = 0; i < 3; ++i)
            for (int l = 0; l < W; ++l)
            {
                const std::size_t s = 3 * static_cast<std::size_t>(p0 + (l < nl ? l : 0)) + i;
                for (int k = 0; k < 6; ++k)
                    os[i][k][l] = s_in[k * sns + s];
                ws[i][l] = weight[s];
            }
    // the point's rotation of the step, for its three sub-points (elastic_update's from w)
    alignas(64) real_t R[9][W];
#pragma omp simd
    for (int l = 0; l < W; ++l)
    {
        const Rotation<real_t> r = hughes_winget(wl[0][l], wl[1][l], wl[2][l], dt);
        R[0][l] = r.r00, R[1][l] = r.r01, R[2][l] = r.r02, R[3][l] = r.r10, R[4][l] = r.r11, R[5][l] = r.r12;
        R[6][l] = r.r20, R[7][l] = r.r21, R[8][l] = r.r22;
    }
    alignas(64) real_t P[3][9][W];
    for (int i = 0; i < 3; ++i)
    {
#pragma omp simd
        for (int l = 0; l < W; ++l)
        {
            real_t Ls[3][3];
            for (int a = 0; a < 3; ++a)
                for (int j = 0; j < 3; ++j)
                    Ls[a][j] = G[i][a][0][l] * Fi[0][j][l] + G[i][a][1][l] * Fi[1][j][l] + G[i][a][2][l] * Fi[2][j][l];
            const real_t d0 = Ls[0][0], d1 = Ls[1][1], d2 = Ls[2][2], d3 = 0.5 * (Ls[0][1] + Ls[1][0]),
                         d4 = 0.5 * (Ls[1][2] + Ls[2][1]), d5 = 0.5 * (Ls[2][0] + Ls[0][2]);
            const real_t o0 = os[i][0][l], o1 = os[i][1][l], o2 = os[i][2][l], o3 = os[i][3][l], o4 = os[i][4][l],
                         o5 = os[i][5][l];
            real_t t0 = o0, t1 = o1, t2 = o2, t3 = o3, t4 = o4, t5 = o5;
            const Rotation<real_t> r{R[0][l], R[1][l], R[2][l], R[3][l], R[4][l], R[5][l], R[6][l], R[7][l], R[8][l]};
            elastic_update(smat, d0, d1, d2, d3, d4, d5, r, dt, t0, t1, t2, t3, t4, t5);
            sn[i][0][l] = t0, sn[i][1][l] = t1, sn[i][2][l] = t2, sn[i][3][l] = t3, sn[i][4][l] = t4, sn[i][5][l] = t5;
            const real_t power = 0.5 * ((o0 + t0) * d0 + (o1 + t1) * d1 + (o2 + t2) * d2) + (o3 + t3) * d3 +
                                 (o4 + t4) * d4 + (o5 + t5) * d5;
            const real_t VJ = ws[i][l] * Jl[l];
            e[i][l] = dt * VJ * power;
            const real_t S[3][3] = {{t0, t3, t5}, {t3, t1, t4}, {t5, t4, t2}};
            for (int a = 0; a < 3; ++a)
                for (int j = 0; j < 3; ++j)
                    P[i][3 * j + a][l] = VJ * (S[a][0] * Fi[j][0][l] + S[a][1] * Fi[j][1][l] + S[a][2] * Fi[j][2][l]);
        }
    }
    // the new states of the good lanes (a full batch's as three vector stores each)
    if (triples && all_good)
    {
#if defined(__AVX512F__)
        if constexpr (W == 8)
        {
            for (int k = 0; k < 6; ++k)
                simd::store_triples(s_out + k * sns + s0, _mm512_load_pd(sn[0][k]), _mm512_load_pd(sn[1][k]),
                                    _mm512_load_pd(sn[2][k]));
        }
#endif
    }
    else
        for (int l = 0; l < nl; ++l)
        {
            if (!good[l])
                continue;
            for (int i = 0; i < 3; ++i)
            {
                const std::size_t s = 3 * static_cast<std::size_t>(p0 + l) + i;
                for (int k = 0; k < 6; ++k)
                    s_out[k * sns + s] = sn[i][k][l];
            }
        }
    // the batch's share of the pass's stabilization work, its good sub-points' in their order
    // (the pass sums the batches: no per-sub-point work is stored, nor swept per step)
    real_t work = 0.0;
    for (int l = 0; l < nl; ++l)
        if (good[l])
            for (int i = 0; i < 3; ++i)
                work += e[i][l];
    blk.batch_sums[4 * static_cast<std::size_t>(p0 / W) + 3] = work;
#if defined(__AVX512F__)
    if (uniform && all_good)
    {
        scatter_triplets_uniform(blk.stab_triplets.view(p0), P, buf, lo);
        return;
    }
#endif
    for (int l = 0; l < nl; ++l)
    {
        // the next batch's lane l: its stencil, which the next gather reads first
        if (blk.prefetch_points && p0 + W + l < blk.n_points())
            prefetch_to_l2(stencil_view(blk.points, blk.point_stencils, p0 + W + l));
        if (!good[l])
            continue;
        real_t Pl[3][9];
        for (int i = 0; i < 3; ++i)
            for (int k = 0; k < 9; ++k)
                Pl[i][k] = P[i][k][l];
        if (packed)
            scatter_triplet(PackedTriplet{blk.stab_triplets.view(p0 + l)}, Pl, buf, lo);
        else
        {
            StencilView sv[3];
            sub_point_views(p0 + l, sv);
            scatter_triplet(SubPointTriplet{sv}, Pl, buf, lo);
        }
    }
}

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

    alignas(64) real_t F[3][3][W], Fd[3][3][W];
#if defined(__AVX512F__)
    const bool uniform = FULL && uniform_batch(blk.point_stencils.uniform, batch);
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
        // a partial batch or an inelastic block: the point's model update per lane (J2 lanes
        // that stay elastic at once)
        bool elastic[W] = {};
        bool all_elastic = false; // a full batch whose lanes all stay elastic (J > 0)
        if constexpr (PLASTIC)
        {
            std::size_t pt[W];
            for (int l = 0; l < W; ++l)
                pt[l] = lane_point(l);
            if constexpr (FULL) // the batch's points are consecutive: a row per component
                for (int k = 0; k < 6; ++k)
                {
#pragma omp simd
                    for (int l = 0; l < W; ++l)
                        sn[k][l] = so[k][l] = s_in[k * snp + static_cast<std::size_t>(p0) + l];
                }
            else
                for (int l = 0; l < W; ++l)
                    for (int k = 0; k < 6; ++k)
                        sn[k][l] = so[k][l] = s_in[k * snp + pt[l]];
            blk.plastic.j2_elastic_lanes<W>(pt, nl, dl, wl, dt, sn, elastic);
            if constexpr (FULL)
            {
                all_elastic = true;
                for (int l = 0; l < W; ++l)
                    all_elastic = all_elastic && elastic[l] && Jl[l] > 0.0;
            }
        }
        // then the predictor's stresses are the new ones (what the lane loop below stores)
        if (all_elastic)
            store_batch8<6>(sn, s_out, snp, static_cast<std::size_t>(p0), buf != nullptr && blk.stream_stress);
        for (int l = 0; l < W && !all_elastic; ++l)
        {
            const std::size_t p = lane_point(l);
            const bool active = FULL || l < nl;
            const real_t d[6] = {dl[0][l], dl[1][l], dl[2][l], dl[3][l], dl[4][l], dl[5][l]};
            const real_t w[3] = {wl[0][l], wl[1][l], wl[2][l]};
            real_t s[6];
            for (int k = 0; k < 6; ++k)
            {
                if constexpr (!PLASTIC) // PLASTIC: loaded above for j2_elastic_lanes
                    so[k][l] = s_in[k * snp + p];
                s[k] = so[k][l];
            }
            if constexpr (PLASTIC)
            {
                if (elastic[l] && Jl[l] > 0.0)
                    for (int k = 0; k < 6; ++k)
                        s[k] = sn[k][l];
                else if (active && Jl[l] > 0.0)
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
    // (a costly scalar call; measurements: docs/performance.md) only for the lanes outside,
    // blended in without a branch
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
    // the stabilization of this point's sub-cells needs F^-1 and W (unless it runs in this batch)
    const bool stabilized = blk.n_stab() > 0 && !(blk.stabilization_triplets && buf);
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
    const bool nsni_here = blk.stabilization_triplets && buf;
    if (nsni_here)
        nsni_batch<W>(blk, v, p0, nl, good, Fi, wl, Jl, dt, buf, lo);
        // V0 P g into the chunk's buffer (or V0 P out for the transpose gather), for the good points
#if defined(__AVX512F__)
    if (uniform && buf && bad < 0)
        scatter_uniform(blk.point_stencils.view(p0), P, buf, lo);
    else
#endif
        for (int l = 0; l < nl; ++l)
        {
            const std::size_t p = static_cast<std::size_t>(p0 + l);
            // the next batch's lane l: its triplet when NSNI runs in the batches (its stencil was
            // asked for while NSNI scattered), else its stencil
            if (p + W < static_cast<std::size_t>(np))
            {
                if (nsni_here && blk.prefetch_triplets)
                    prefetch_to_l2(blk.stab_triplets.view(static_cast<index_t>(p + W)));
                else if (!nsni_here && blk.prefetch_points)
                    prefetch_to_l2(stencil_view(op, blk.point_stencils, static_cast<index_t>(p + W)));
            }
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
    blk.batch_sums[4 * b] = sum_int;
    blk.batch_sums[4 * b + 1] = sum_bv;
    blk.batch_sums[4 * b + 2] = dt_min;
    blk.batch_idx[2 * b] = dt_point;
    blk.batch_idx[2 * b + 1] = bad;
}
} // namespace

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
                                   [&](index_t b, real_t* buf, index_t lo)
                                   { batch.template operator()<PLASTIC>(b, buf, lo); });
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
        if (blk.batch_sums[4 * b + 2] < r.dt_stable)
        {
            r.dt_stable = blk.batch_sums[4 * b + 2];
            r.dt_element = blk.batch_idx[2 * b];
        }
    }

    // the stabilization's own pass; NSNI with the chunked scatter ran in the points' batches
    // (nsni_batch)
    if (ns > 0 && !(blk.stabilization_triplets && blk.scatter_assembly()))
    {
        const IntegrationOperator& st = blk.stabilization;
        const std::size_t sns = static_cast<std::size_t>(ns);
        ElasticParams smat = mat;
        smat.lambda *= blk.stabilization_coefficient;
        smat.mu *= blk.stabilization_coefficient;
        // sub-point s with velocity gradient G: stress update and V0 J sigma F^-T (by columns);
        // the block's arrays through restrict pointers (stores into the stress would otherwise
        // make the compiler reload every other array's address)
        const real_t* __restrict finv = blk.finv.data();
        const real_t* __restrict spin = blk.spin.data();
        const real_t* __restrict jac = blk.jacobian.data();
        const real_t* __restrict s_in = blk.stab_stress.data();
        real_t* __restrict s_out = blk.stab_stress_trial.data();
        real_t* __restrict energy = blk.stab_energy.data();
        const index_t* __restrict parent = st.parent.data();
        const real_t* __restrict weight = st.weight.data();
        auto sub_point = [=](index_t s, const real_t G[3][3], real_t P[9])
        {
            const index_t L = parent[s];
            const real_t* Fi = finv + 9 * static_cast<std::size_t>(L);
            real_t Ls[3][3];
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    Ls[i][j] = G[i][0] * Fi[j] + G[i][1] * Fi[3 + j] + G[i][2] * Fi[6 + j];
            const real_t d[6] = {Ls[0][0],
                                 Ls[1][1],
                                 Ls[2][2],
                                 0.5 * (Ls[0][1] + Ls[1][0]),
                                 0.5 * (Ls[1][2] + Ls[2][1]),
                                 0.5 * (Ls[2][0] + Ls[0][2])};
            const real_t* w = spin + 3 * static_cast<std::size_t>(L);
            real_t s_old[6], sg[6];
            for (int k = 0; k < 6; ++k)
                s_old[k] = sg[k] = s_in[k * sns + s];
            elastic_update(smat, d, w, dt, sg);
            for (int k = 0; k < 6; ++k)
                s_out[k * sns + s] = sg[k];
            real_t power = 0.0;
            for (int k = 0; k < 3; ++k)
                power += 0.5 * (s_old[k] + sg[k]) * d[k] + (s_old[k + 3] + sg[k + 3]) * d[k + 3];
            const real_t VJ = weight[s] * jac[L];
            energy[s] = dt * VJ * power;
            const real_t S[3][3] = {{sg[0], sg[3], sg[5]}, {sg[3], sg[1], sg[4]}, {sg[5], sg[4], sg[2]}};
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    P[3 * j + i] = VJ * (S[i][0] * Fi[3 * j] + S[i][1] * Fi[3 * j + 1] + S[i][2] * Fi[3 * j + 2]);
        };
        auto sub_cell = [&](index_t s, real_t P[9])
        {
            real_t G[3][3];
            gather_velocity_gradient(stencil_view(st, blk.stab_stencils, s), v, G);
            sub_point(s, G, P);
        };
        // NSNI: the three sub-points of point t in one pass over their shared nodes
        auto triplet = [&](index_t t, real_t P[3][9])
        {
            const StencilView sv[3] = {stencil_view(st, blk.stab_stencils, 3 * t),
                                       stencil_view(st, blk.stab_stencils, 3 * t + 1),
                                       stencil_view(st, blk.stab_stencils, 3 * t + 2)};
            real_t G[3][3][3];
            gather_triplet(SubPointTriplet{sv}, v, G);
            for (int i = 0; i < 3; ++i)
                sub_point(3 * t + i, G[i], P[i]);
        };
        if (blk.stabilization_triplets)
            parallel_for("rkfem::nodal_stabilization", ns / 3,
                         [&](index_t t)
                         {
                             real_t P[3][9];
                             triplet(t, P);
                             for (int i = 0; i < 3; ++i)
                                 std::copy(P[i], P[i] + 9,
                                           &blk.point_tensor[9 * (static_cast<std::size_t>(np) + 3 * t + i)]);
                         });
        else if (blk.scatter_assembly())
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

    r.d_internal = parallel_reduce_sum("rkfem::nodal_energy", nb, [&](index_t b) { return blk.batch_sums[4 * b]; });
    r.d_bulk_viscosity =
        parallel_reduce_sum("rkfem::nodal_bv_energy", nb, [&](index_t b) { return blk.batch_sums[4 * b + 1]; });
    // NSNI in the points' batches summed its sub-points' work per batch (nsni_batch)
    if (ns > 0 && blk.stabilization_triplets && blk.scatter_assembly())
        r.d_hourglass =
            parallel_reduce_sum("rkfem::nodal_stab_energy", nb, [&](index_t b) { return blk.batch_sums[4 * b + 3]; });
    else
        r.d_hourglass =
            parallel_reduce_sum("rkfem::nodal_stab_energy", ns, [&](index_t s) { return blk.stab_energy[s]; });
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
} // namespace rkfem
