#include "rkfem/operators/hex_block.hpp"

#include <algorithm>
#include <immintrin.h>
#include <cmath>
#include <type_traits>

#include "rkfem/approximation/fem/hex8_basis.hpp"
#include "rkfem/approximation/fem/hex8_volume_gradient.hpp"
#include "rkfem/core/huge_pages.hpp"
#include "rkfem/operators/bulk_viscosity.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/simd.hpp"
#include "rkfem/core/stream_stores.hpp"
#include "rkfem/discretization/hex_mesh.hpp"

// GCC 12's AVX-512 intrinsics (gathers, unpacks, 128-bit shuffles, extracts) start from an
// undefined source written "__m512d __Y = __Y", which -Wmaybe-uninitialized / -Wuninitialized
// report once inlined here; every value used is defined.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

namespace rkfem
{
namespace
{
constexpr int W = 8; // lanes per batch (one AVX-512 register of doubles)

index_t n_batches(index_t ne) { return (ne + W - 1) / W; }

/// One batch of W elements. FULL: all W lanes are elements (every batch but a partial last one),
/// so the lane loops carry no lane test and the material/bulk-viscosity loop vectorizes.
// 512-bit lane loops (core/simd.hpp; 1-point viscous at 1e4 elements: 67 -> 61 ns per
// element-cycle)
template <HourglassType HG, bool PLASTIC, bool FULL>
RKFEM_WIDE_VECTORS void force_1pt_batch(HexBlock& blk, const NodeSet& nodes, index_t batch, real_t dt, real_t* buf, index_t lo)
{
    const index_t ne = blk.n_elements();
    const index_t e0 = batch * W;
    const int nl = FULL ? W : static_cast<int>(std::min<index_t>(W, ne - e0));
    auto lane_element = [&](int l) { return static_cast<std::size_t>(e0 + (FULL || l < nl ? l : 0)); };
    auto active = [&](int l) { return FULL || l < nl; };

    alignas(64) real_t xe[8][3][W];
    alignas(64) real_t ve[8][3][W];
#if defined(__AVX512F__)
    // bit I: node I of the batch's 8 elements is 8 consecutive nodes (as along a structured
    // mesh's rows), loaded with line loads and permutes here and added as whole vectors below
    unsigned consecutive = 0;
    if constexpr (FULL)
    {
        // node I of the batch's 8 elements: one 8-lane gather per coordinate, or the line loads
        const index_t* g3 = &blk.gather_index[64 * static_cast<std::size_t>(batch)];
        const __m256i step = _mm256_setr_epi32(0, 3, 6, 9, 12, 15, 18, 21);
        for (int I = 0; I < 8; ++I)
        {
            const __m256i idx = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(g3 + 8 * I));
            const __m256i row = _mm256_add_epi32(_mm256_set1_epi32(g3[8 * I]), step);
            if (_mm256_cmpeq_epi32_mask(idx, row) == 0xFF)
            {
                consecutive |= 1u << I;
                __m512d X, Y, Z;
                simd::load_triples(nodes.x.data() + g3[8 * I], X, Y, Z);
                _mm512_store_pd(xe[I][0], X);
                _mm512_store_pd(xe[I][1], Y);
                _mm512_store_pd(xe[I][2], Z);
                simd::load_triples(nodes.v.data() + g3[8 * I], X, Y, Z);
                _mm512_store_pd(ve[I][0], X);
                _mm512_store_pd(ve[I][1], Y);
                _mm512_store_pd(ve[I][2], Z);
                continue;
            }
            for (int d = 0; d < 3; ++d)
            {
                _mm512_store_pd(xe[I][d], _mm512_i32gather_pd(idx, nodes.x.data() + d, 8));
                _mm512_store_pd(ve[I][d], _mm512_i32gather_pd(idx, nodes.v.data() + d, 8));
            }
        }
    }
    else
#endif
    for (int l = 0; l < W; ++l)
    {
        const std::size_t e = lane_element(l);
        const index_t* c = &blk.conn[8 * e];
        for (int I = 0; I < 8; ++I)
        {
            const std::size_t n = 3 * static_cast<std::size_t>(c[I]);
            for (int d = 0; d < 3; ++d)
            {
                xe[I][d][l] = nodes.x[n + d];
                ve[I][d][l] = nodes.v[n + d];
            }
        }
    }

    // b_I = dV/dx_I (Flanagan-Belytschko, exact volume integration), from the compile-time
    // table: 24 pair cross products, then nine +-1/12 terms per node (unrolled)
    using VG = Hex8VolumeGradientFixed;
    alignas(64) real_t cr[VG::n_pairs][3][W];
#pragma GCC unroll 24
    for (int p = 0; p < VG::n_pairs; ++p)
    {
        const int k = VG::pairs[p][0], m = VG::pairs[p][1];
#pragma omp simd
        for (int l = 0; l < W; ++l)
        {
            cr[p][0][l] = xe[k][1][l] * xe[m][2][l] - xe[k][2][l] * xe[m][1][l];
            cr[p][1][l] = xe[k][2][l] * xe[m][0][l] - xe[k][0][l] * xe[m][2][l];
            cr[p][2][l] = xe[k][0][l] * xe[m][1][l] - xe[k][1][l] * xe[m][0][l];
        }
    }
    alignas(64) real_t b[8][3][W];
#pragma GCC unroll 8
    for (int I = 0; I < 8; ++I)
        for (int d = 0; d < 3; ++d)
#pragma omp simd
            for (int l = 0; l < W; ++l)
            {
                real_t s = 0.0;
#pragma GCC unroll 9
                for (int t = 0; t < 9; ++t)
                    s += VG::terms[I][t][1] * cr[VG::terms[I][t][0]][d][l];
                b[I][d][l] = s * (1.0 / 12.0);
            }
    alignas(64) real_t vol[W], inv_v[W];
#pragma omp simd
    for (int l = 0; l < W; ++l)
    {
        real_t s = 0.0;
        for (int I = 0; I < 8; ++I)
            s += b[I][0][l] * xe[I][0][l] + b[I][1][l] * xe[I][1][l] + b[I][2][l] * xe[I][2][l];
        vol[l] = s / 3.0;
        inv_v[l] = 1.0 / vol[l];
    }

    // velocity gradient L_ij = (1/V) sum_I v_iI b_jI
    alignas(64) real_t L[3][3][W];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
#pragma omp simd
            for (int l = 0; l < W; ++l)
            {
                real_t s = 0.0;
                for (int I = 0; I < 8; ++I)
                    s += ve[I][i][l] * b[I][j][l];
                L[i][j][l] = s * inv_v[l];
            }

    const ElasticParams mat = blk.material;
    const real_t c = mat.wave_speed();
    const real_t q1 = blk.bulk_viscosity.quadratic, q2 = blk.bulk_viscosity.linear;
    const std::size_t np = static_cast<std::size_t>(ne), ss = blk.stress_stride;
    const real_t* s_in = blk.stress.data();
    real_t* s_out = blk.stress_trial.data();

    alignas(64) real_t sig[6][W]; // effective stress for the force (incl. bulk viscosity)
    alignas(64) real_t lc[W], dt_e[W], de_int[W], de_bv[W];
    // characteristic length from the largest face (staged over lanes so each loop vectorizes)
    alignas(64) real_t amax2[W];
#pragma omp simd
    for (int l = 0; l < W; ++l)
        amax2[l] = 0.0;
#pragma GCC unroll 6
    for (int fi = 0; fi < 6; ++fi)
    {
        const auto& f = hex_faces[fi];
#pragma omp simd
        for (int l = 0; l < W; ++l)
        {
            const real_t a0 = xe[f[2]][0][l] - xe[f[0]][0][l], a1 = xe[f[2]][1][l] - xe[f[0]][1][l],
                         a2 = xe[f[2]][2][l] - xe[f[0]][2][l];
            const real_t b0 = xe[f[3]][0][l] - xe[f[1]][0][l], b1 = xe[f[3]][1][l] - xe[f[1]][1][l],
                         b2 = xe[f[3]][2][l] - xe[f[1]][2][l];
            const real_t cx = a1 * b2 - a2 * b1, cy = a2 * b0 - a0 * b2, cz = a0 * b1 - a1 * b0;
            const real_t a = 0.25 * (cx * cx + cy * cy + cz * cz);
            amax2[l] = a > amax2[l] ? a : amax2[l];
        }
    }
    // stress update per lane (strain rate d, old and new stress kept for the stress power)
    alignas(64) real_t dl[6][W], so[6][W], sn[6][W];
    if constexpr (FULL && !PLASTIC)
    {
        // straight-line over lanes: vectorizes
#pragma omp simd
        for (int l = 0; l < W; ++l)
        {
            const std::size_t e = static_cast<std::size_t>(e0) + l;
            const real_t d0 = L[0][0][l], d1 = L[1][1][l], d2 = L[2][2][l];
            const real_t d3 = 0.5 * (L[0][1][l] + L[1][0][l]), d4 = 0.5 * (L[1][2][l] + L[2][1][l]),
                         d5 = 0.5 * (L[2][0][l] + L[0][2][l]);
            real_t s0 = s_in[e], s1 = s_in[ss + e], s2 = s_in[2 * ss + e], s3 = s_in[3 * ss + e],
                   s4 = s_in[4 * ss + e], s5 = s_in[5 * ss + e];
            so[0][l] = s0, so[1][l] = s1, so[2][l] = s2, so[3][l] = s3, so[4][l] = s4, so[5][l] = s5;
            dl[0][l] = d0, dl[1][l] = d1, dl[2][l] = d2, dl[3][l] = d3, dl[4][l] = d4, dl[5][l] = d5;
            elastic_update(mat, d0, d1, d2, d3, d4, d5, 0.5 * (L[0][1][l] - L[1][0][l]), 0.5 * (L[1][2][l] - L[2][1][l]),
                           0.5 * (L[2][0][l] - L[0][2][l]), dt, s0, s1, s2, s3, s4, s5);
            sn[0][l] = s0, sn[1][l] = s1, sn[2][l] = s2, sn[3][l] = s3, sn[4][l] = s4, sn[5][l] = s5;
        }
        store_batch8<6>(sn, s_out, ss, static_cast<std::size_t>(e0), buf != nullptr && blk.stream_stress);
    }
    else
    {
        // a partial batch (lanes past the block's end repeat its first element, unstored) or an
        // inelastic block (the point's model update per lane)
        for (int l = 0; l < W; ++l)
        {
            const std::size_t e = lane_element(l);
            const real_t d[6] = {L[0][0][l],
                                 L[1][1][l],
                                 L[2][2][l],
                                 0.5 * (L[0][1][l] + L[1][0][l]),
                                 0.5 * (L[1][2][l] + L[2][1][l]),
                                 0.5 * (L[2][0][l] + L[0][2][l])};
            const real_t w[3] = {0.5 * (L[0][1][l] - L[1][0][l]), 0.5 * (L[1][2][l] - L[2][1][l]),
                                 0.5 * (L[2][0][l] - L[0][2][l])};
            real_t s[6];
            for (int k = 0; k < 6; ++k)
                so[k][l] = s[k] = s_in[k * ss + e];
            if constexpr (PLASTIC)
            {
                if (active(l))
                    blk.plastic.update(e, d, w, dt, s);
            }
            else
                elastic_update(mat, d, w, dt, s);
            for (int k = 0; k < 6; ++k)
            {
                dl[k][l] = d[k];
                sn[k][l] = s[k];
                if (active(l))
                    s_out[k * ss + e] = s[k];
            }
        }
    }
    // bulk viscosity, time step, energies, effective stress
#pragma omp simd
    for (int l = 0; l < W; ++l)
    {
        const real_t trd = dl[0][l] + dl[1][l] + dl[2][l];
        lc[l] = vol[l] / std::sqrt(amax2[l]);
        const real_t rho = mat.rho * blk.volume0[lane_element(l)] / vol[l];
        const real_t q = bulk_q(rho, c, lc[l], trd, q1, q2);
        dt_e[l] = element_dt(c, lc[l], trd, q1, q2);
        const real_t power = 0.5 * ((so[0][l] + sn[0][l]) * dl[0][l] + (so[1][l] + sn[1][l]) * dl[1][l] +
                                    (so[2][l] + sn[2][l]) * dl[2][l]) +
                             (so[3][l] + sn[3][l]) * dl[3][l] + (so[4][l] + sn[4][l]) * dl[4][l] +
                             (so[5][l] + sn[5][l]) * dl[5][l];
        de_int[l] = dt * vol[l] * power;
        de_bv[l] = -dt * vol[l] * q * trd;
        sig[0][l] = sn[0][l] - q;
        sig[1][l] = sn[1][l] - q;
        sig[2][l] = sn[2][l] - q;
        sig[3][l] = sn[3][l];
        sig[4][l] = sn[4][l];
        sig[5][l] = sn[5][l];
    }

    // Hourglass control (Flanagan-Belytschko). Mode a has base vector Gamma_a and shape vector
    // gamma_aI = Gamma_aI - (1/V) b_I . h_a with h_a = sum_J Gamma_aJ x_J. With g_a = sum_J
    // Gamma_aJ v_J the hourglass velocity is qdot_ai = sum_I v_iI gamma_aI = g_ai - L_ij h_aj
    // (sum_I v_iI b_jI = V L_ij), and the nodal forces sum_a gamma_aI Q_ai = sum_a Gamma_aI Q_ai
    // - b_jI M_ji with M_ji = (1/V) sum_a h_aj Q_ai, which joins the stress term below. The
    // Gamma sums over the nodes are butterflies (hourglass_sums, hourglass_spread).
    alignas(64) real_t de_hg[W] = {};
    alignas(64) real_t M[3][3][W] = {}; // M_ji at [j][i]
    alignas(64) real_t hq[8][3][W];     // sum_a Gamma_aI Q_ai
    if constexpr (HG != HourglassType::None)
    {
        const real_t qm = blk.hourglass.coefficient;
        // per-lane hourglass coefficient: viscous a_h = QM rho c V^(2/3) / 4 with V^(2/3) taken
        // as lc^2 (equal for cubes); stiffness k = QM (lambda + 2 mu) sum_I |b_I|^2 / (3 V)
        // (Flanagan-Belytschko)
        alignas(64) real_t coef[W];
#pragma omp simd
        for (int l = 0; l < W; ++l)
        {
            if constexpr (HG == HourglassType::Stiffness)
            {
                real_t bb = 0.0;
                for (int I = 0; I < 8; ++I)
                    bb += b[I][0][l] * b[I][0][l] + b[I][1][l] * b[I][1][l] + b[I][2][l] * b[I][2][l];
                coef[l] = qm * mat.plane_wave_modulus() * bb * inv_v[l] / 3.0;
            }
            else
                coef[l] = 0.25 * qm * mat.rho * c * lc[l] * lc[l];
        }
        alignas(64) real_t hx[4][3][W], g[4][3][W];
        for (int d = 0; d < 3; ++d)
#pragma omp simd
            for (int l = 0; l < W; ++l)
            {
                hourglass_sums(xe[0][d][l], xe[1][d][l], xe[2][d][l], xe[3][d][l], xe[4][d][l], xe[5][d][l],
                               xe[6][d][l], xe[7][d][l], hx[0][d][l], hx[1][d][l], hx[2][d][l], hx[3][d][l]);
                hourglass_sums(ve[0][d][l], ve[1][d][l], ve[2][d][l], ve[3][d][l], ve[4][d][l], ve[5][d][l],
                               ve[6][d][l], ve[7][d][l], g[0][d][l], g[1][d][l], g[2][d][l], g[3][d][l]);
            }
        // hourglass velocity and generalized force Q_ai
        alignas(64) real_t Q[4][3][W];
        for (int a = 0; a < 4; ++a)
            for (int i = 0; i < 3; ++i)
#pragma omp simd
                for (int l = 0; l < W; ++l)
                {
                    real_t qd = g[a][i][l];
                    if constexpr (HG != HourglassType::ViscousPlain) // the plain form takes gamma = Gamma
                        qd -= L[i][0][l] * hx[a][0][l] + L[i][1][l] * hx[a][1][l] + L[i][2][l] * hx[a][2][l];
                    if constexpr (HG == HourglassType::Stiffness)
                    {
                        const real_t k = coef[l];
                        const std::size_t slot = static_cast<std::size_t>(3 * a + i) * np + lane_element(l);
                        const real_t Qold = blk.hg_force[slot];
                        const real_t Qnew = Qold + k * dt * qd;
                        if (active(l))
                            blk.hg_force_trial[slot] = Qnew;
                        Q[a][i][l] = Qnew;
                        de_hg[l] += 0.5 * (Qold + Qnew) * qd * dt;
                    }
                    else
                    {
                        Q[a][i][l] = coef[l] * qd;
                        de_hg[l] += Q[a][i][l] * qd * dt;
                    }
                }
        if constexpr (HG != HourglassType::ViscousPlain)
            for (int j = 0; j < 3; ++j)
                for (int i = 0; i < 3; ++i)
#pragma omp simd
                    for (int l = 0; l < W; ++l)
                        M[j][i][l] = inv_v[l] * (hx[0][j][l] * Q[0][i][l] + hx[1][j][l] * Q[1][i][l] +
                                                 hx[2][j][l] * Q[2][i][l] + hx[3][j][l] * Q[3][i][l]);
        for (int i = 0; i < 3; ++i)
#pragma omp simd
            for (int l = 0; l < W; ++l)
                hourglass_spread(Q[0][i][l], Q[1][i][l], Q[2][i][l], Q[3][i][l], hq[0][i][l], hq[1][i][l], hq[2][i][l],
                                 hq[3][i][l], hq[4][i][l], hq[5][i][l], hq[6][i][l], hq[7][i][l]);
    }

    // internal force f_iI = (sigma_ij - M_ji) b_jI + sum_a Gamma_aI Q_ai
    alignas(64) real_t T[3][3][W]; // sigma_ij - M_ji
    static constexpr int voigt[3][3] = {{0, 3, 5}, {3, 1, 4}, {5, 4, 2}};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
#pragma omp simd
            for (int l = 0; l < W; ++l)
                T[i][j][l] = sig[voigt[i][j]][l] - M[j][i][l];
    alignas(64) real_t f[8][3][W];
    for (int I = 0; I < 8; ++I)
        for (int i = 0; i < 3; ++i)
#pragma omp simd
            for (int l = 0; l < W; ++l)
            {
                const real_t fi = T[i][0][l] * b[I][0][l] + T[i][1][l] * b[I][1][l] + T[i][2][l] * b[I][2][l];
                if constexpr (HG != HourglassType::None)
                    f[I][i][l] = fi + hq[I][i][l];
                else
                    f[I][i][l] = fi;
            }

    // nodal forces: into the chunk's buffer (scatter assembly) or the element force buffer
    if (buf != nullptr)
    {
        // node by node of the batch, lane by lane: a fixed order of the chunk's sums
#if defined(__AVX512F__)
        if constexpr (FULL)
        {
            // lanes to (x, y, z, 0) per element: unpack x/y and z/0, then pair the 128-bit halves;
            // zmm k holds lanes (2k', 2k'+2) or (2k'+1, 2k'+3) in its 256-bit halves
            const index_t* g3 = &blk.gather_index[64 * static_cast<std::size_t>(batch)];
            const __m512d zero = _mm512_setzero_pd();
            for (int I = 0; I < 8; ++I)
            {
                const __m512d X = _mm512_load_pd(f[I][0]), Y = _mm512_load_pd(f[I][1]), Z = _mm512_load_pd(f[I][2]);
                if (consecutive >> I & 1u)
                {
                    // consecutive nodes: their 8 (x, y, z, 0) quadruples are 4 whole vectors
                    __m512d q[4];
                    simd::interleave4(X, Y, Z, q);
                    real_t* b = buf + 4 * static_cast<std::size_t>(g3[8 * I] / 3 - lo);
                    for (int k = 0; k < 4; ++k)
                        _mm512_storeu_pd(b + 8 * k, _mm512_add_pd(_mm512_loadu_pd(b + 8 * k), q[k]));
                    continue;
                }
                const __m512d xy_even = _mm512_unpacklo_pd(X, Y), xy_odd = _mm512_unpackhi_pd(X, Y);
                const __m512d z_even = _mm512_unpacklo_pd(Z, zero), z_odd = _mm512_unpackhi_pd(Z, zero);
                // [xy(l), z0(l), xy(l+2), z0(l+2)] for l = 0, 1 (low 128-bit pairs) and 4, 5 (high)
                __m512d v[4];
                v[0] = _mm512_shuffle_f64x2(xy_even, z_even, _MM_SHUFFLE(1, 0, 1, 0)); // xy0 xy2 z0 z2
                v[1] = _mm512_shuffle_f64x2(xy_odd, z_odd, _MM_SHUFFLE(1, 0, 1, 0));   // lanes 1, 3
                v[2] = _mm512_shuffle_f64x2(xy_even, z_even, _MM_SHUFFLE(3, 2, 3, 2)); // lanes 4, 6
                v[3] = _mm512_shuffle_f64x2(xy_odd, z_odd, _MM_SHUFFLE(3, 2, 3, 2));   // lanes 5, 7
                for (int k = 0; k < 4; ++k)
                    v[k] = _mm512_shuffle_f64x2(v[k], v[k], _MM_SHUFFLE(3, 1, 2, 0)); // (xy z) lane a | lane a+2
                static constexpr int lane_of[4][2] = {{0, 2}, {1, 3}, {4, 6}, {5, 7}};
                for (int k = 0; k < 4; ++k)
                    for (int h = 0; h < 2; ++h)
                    {
                        const int l = lane_of[k][h];
                        real_t* b = buf + 4 * static_cast<std::size_t>(g3[8 * I + l] / 3 - lo);
                        const __m256d add = h == 0 ? _mm512_castpd512_pd256(v[k]) : _mm512_extractf64x4_pd(v[k], 1);
                        _mm256_storeu_pd(b, _mm256_add_pd(_mm256_loadu_pd(b), add));
                    }
            }
        }
        else
#endif
        for (int I = 0; I < 8; ++I)
            for (int l = 0; l < nl; ++l)
            {
                real_t* b = buf + 4 * static_cast<std::size_t>(blk.conn[8 * static_cast<std::size_t>(e0 + l) + I] - lo);
                b[0] += f[I][0][l];
                b[1] += f[I][1][l];
                b[2] += f[I][2][l];
            }
    }
    else
        for (int l = 0; l < nl; ++l)
        {
            real_t* fe = &blk.elem_force[24 * static_cast<std::size_t>(e0 + l)];
            for (int I = 0; I < 8; ++I)
                for (int d = 0; d < 3; ++d)
                    fe[3 * I + d] = f[I][d][l];
        }
    // batch results
    real_t sum_int = 0.0, sum_hg = 0.0, sum_bv = 0.0, dt_min = 1e300;
    index_t dt_elem = -1, bad = -1;
    for (int l = 0; l < nl; ++l)
    {
        const index_t e = e0 + l;
        sum_int += de_int[l];
        sum_hg += de_hg[l];
        sum_bv += de_bv[l];
        if (dt_e[l] < dt_min)
        {
            dt_min = dt_e[l];
            dt_elem = e;
        }
        if (!(vol[l] > 0.0) && bad < 0)
            bad = e;
    }
    blk.batch_sums[4 * batch + 0] = sum_int;
    blk.batch_sums[4 * batch + 1] = sum_hg;
    blk.batch_sums[4 * batch + 2] = sum_bv;
    blk.batch_sums[4 * batch + 3] = dt_min;
    blk.batch_idx[2 * batch + 0] = dt_elem;
    blk.batch_idx[2 * batch + 1] = bad;
}

/// Fully integrated hex: 8 Gauss points, stress per point, bulk viscosity from the mean tr D.
template <bool PLASTIC>
void force_2x2x2_element(HexBlock& blk, const NodeSet& nodes, index_t e, real_t dt, real_t out[4],
                         index_t& bad)
{
    const std::size_t ss = blk.stress_stride;
    real_t xe[8][3], ve[8][3];
    for (int I = 0; I < 8; ++I)
    {
        const std::size_t n = 3 * static_cast<std::size_t>(blk.conn[8 * e + I]);
        for (int d = 0; d < 3; ++d)
        {
            xe[I][d] = nodes.x[n + d];
            ve[I][d] = nodes.v[n + d];
        }
    }
    const ElasticParams mat = blk.material;
    const real_t c = mat.wave_speed();
    const real_t g = 1.0 / std::sqrt(3.0);
    real_t f[8][3] = {};
    real_t vol = 0.0, trd_mean = 0.0, de_int = 0.0;
    real_t dNdx[8][8][3], detj[8], s_new[8][6];
    for (int gp = 0; gp < 8; ++gp)
    {
        const real_t xi[3] = {g * hex8_nodes[gp][0], g * hex8_nodes[gp][1], g * hex8_nodes[gp][2]};
        detj[gp] = hex8_gradients(xe, xi, dNdx[gp]);
        if (!(detj[gp] > 0.0) && bad < 0)
            bad = e;
        real_t Lm[3][3] = {};
        for (int I = 0; I < 8; ++I)
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    Lm[i][j] += ve[I][i] * dNdx[gp][I][j];
        const real_t d[6] = {Lm[0][0], Lm[1][1], Lm[2][2], 0.5 * (Lm[0][1] + Lm[1][0]),
                             0.5 * (Lm[1][2] + Lm[2][1]), 0.5 * (Lm[2][0] + Lm[0][2])};
        const real_t w[3] = {0.5 * (Lm[0][1] - Lm[1][0]), 0.5 * (Lm[1][2] - Lm[2][1]),
                             0.5 * (Lm[2][0] - Lm[0][2])};
        const std::size_t p = 8 * static_cast<std::size_t>(e) + gp;
        real_t s_old[6];
        for (int k = 0; k < 6; ++k)
            s_old[k] = s_new[gp][k] = blk.stress[k * ss + p];
        if constexpr (PLASTIC)
            blk.plastic.update(p, d, w, dt, s_new[gp]);
        else
            elastic_update(mat, d, w, dt, s_new[gp]);
        for (int k = 0; k < 6; ++k)
            blk.stress_trial[k * ss + p] = s_new[gp][k];
        real_t power = 0.0;
        for (int k = 0; k < 3; ++k)
            power += 0.5 * (s_old[k] + s_new[gp][k]) * d[k] + (s_old[k + 3] + s_new[gp][k + 3]) * d[k + 3];
        de_int += dt * detj[gp] * power;
        vol += detj[gp];
        trd_mean += detj[gp] * (d[0] + d[1] + d[2]);
    }
    trd_mean /= vol;
    real_t amax2 = 0.0;
    for (const auto& fc : hex_faces)
    {
        Vec3 d1, d2;
        for (int d = 0; d < 3; ++d)
        {
            d1[d] = xe[fc[2]][d] - xe[fc[0]][d];
            d2[d] = xe[fc[3]][d] - xe[fc[1]][d];
        }
        amax2 = std::max(amax2, 0.25 * d1.cross(d2).squaredNorm());
    }
    const real_t lc = vol / std::sqrt(amax2);
    const real_t q1 = blk.bulk_viscosity.quadratic, q2 = blk.bulk_viscosity.linear;
    const real_t rho = mat.rho * blk.volume0[e] / vol;
    const real_t q = bulk_q(rho, c, lc, trd_mean, q1, q2);
    for (int gp = 0; gp < 8; ++gp)
    {
        const real_t* s = s_new[gp];
        for (int I = 0; I < 8; ++I)
        {
            const real_t* B = dNdx[gp][I];
            f[I][0] += detj[gp] * ((s[0] - q) * B[0] + s[3] * B[1] + s[5] * B[2]);
            f[I][1] += detj[gp] * (s[3] * B[0] + (s[1] - q) * B[1] + s[4] * B[2]);
            f[I][2] += detj[gp] * (s[5] * B[0] + s[4] * B[1] + (s[2] - q) * B[2]);
        }
    }
    real_t* fe = &blk.elem_force[24 * static_cast<std::size_t>(e)];
    for (int I = 0; I < 8; ++I)
        for (int d = 0; d < 3; ++d)
            fe[3 * I + d] = f[I][d];
    out[0] = de_int;
    out[1] = 0.0;
    out[2] = -dt * vol * q * trd_mean;
    out[3] = element_dt(c, lc, trd_mean, q1, q2);
}
} // namespace

void HexBlock::initialize(const NodeSet& nodes, Assembly assembly)
{
    const index_t ne = n_elements();
    const std::size_t np = static_cast<std::size_t>(n_points());
    stress_stride = batch8_stride(np);
    stress.assign(6 * stress_stride, 0.0);
    stress_trial.assign(6 * stress_stride, 0.0);
    if (plastic.active())
        plastic.resize(np);
    hg_force.assign(12 * static_cast<std::size_t>(ne), 0.0);
    hg_force_trial.assign(12 * static_cast<std::size_t>(ne), 0.0);
    // 1-point blocks whose element order has locality assemble by chunked scatter (the element
    // forces are never written out); others (2x2x2, an element order without locality: chunk
    // ranges adding up to over 3 nodes per node) through the element force buffer
    scatter.clear();
    if (formulation == Formulation::Fem1pt && assembly != Assembly::Gather)
    {
        scatter.node_begin = node_begin;
        scatter.node_end = node_end;
        const std::size_t covered = scatter.add_chunks(ne, ChunkedScatter::chunk_size(ne, W),
                                                       [&](index_t first, index_t last, index_t& lo, index_t& hi)
                                                       {
                                                           for (std::size_t k = 8 * static_cast<std::size_t>(first);
                                                                k < 8 * static_cast<std::size_t>(last); ++k)
                                                           {
                                                               lo = std::min(lo, conn[k]);
                                                               hi = std::max(hi, conn[k] + 1);
                                                           }
                                                       });
        if (assembly == Assembly::Scatter || covered <= 4 * 3 * static_cast<std::size_t>(node_end - node_begin))
            scatter.finish();
        else
            scatter.clear();
    }
    elem_force.assign(scatter.empty() ? 24 * static_cast<std::size_t>(ne) : 0, 0.0);
    volume0.assign(static_cast<std::size_t>(ne), 0.0);
    const index_t nb = formulation == Formulation::Fem1pt ? n_batches(ne) : ne;
    batch_sums.assign(4 * static_cast<std::size_t>(nb), 0.0);
    batch_idx.assign(2 * static_cast<std::size_t>(nb), -1);
    for (index_t e = 0; e < ne; ++e)
    {
        real_t xe[8][3], b[8][3];
        for (int I = 0; I < 8; ++I)
            for (int d = 0; d < 3; ++d)
                xe[I][d] = nodes.x0[3 * static_cast<std::size_t>(conn[8 * e + I]) + d];
        volume0[e] = hex8_volume_gradient(xe, b);
    }
    // node -> (element, local) CSR, counts -> offsets -> slots
    const index_t nn = node_end - node_begin;
    node_elem_offsets.assign(static_cast<std::size_t>(nn) + 1, 0);
    for (index_t s = 0; s < 8 * ne; ++s)
        ++node_elem_offsets[conn[s] - node_begin + 1];
    for (index_t i = 0; i < nn; ++i)
        node_elem_offsets[i + 1] += node_elem_offsets[i];
    node_elem_slots.assign(static_cast<std::size_t>(8) * ne, 0);
    std::vector<index_t> fill(node_elem_offsets.begin(), node_elem_offsets.end() - 1);
    for (index_t s = 0; s < 8 * ne; ++s)
        node_elem_slots[fill[conn[s] - node_begin]++] = s;
    // batch-major gather indices: [64 b + 8 I + l] = 3 x (node I of element 8 b + l), full batches
    gather_index.assign(64 * static_cast<std::size_t>(ne / W), 0);
    for (index_t b = 0; b < ne / W; ++b)
        for (int I = 0; I < 8; ++I)
            for (int l = 0; l < W; ++l)
                gather_index[64 * static_cast<std::size_t>(b) + 8 * I + l] = 3 * conn[8 * (W * b + l) + I];
    use_huge_pages(gather_index);
    use_huge_pages(stress);
    use_huge_pages(stress_trial);
    for (auto* a : {&hg_force, &hg_force_trial, &elem_force, &volume0})
        use_huge_pages(*a);
    use_huge_pages(conn);
    use_huge_pages(node_elem_slots);
}

/// All batches of a 1-point block, with the material kind chosen once for the block.
template <HourglassType HG> void run_1pt(HexBlock& blk, const NodeSet& nodes, index_t nb, real_t dt)
{
    const bool partial_last = blk.n_elements() % W != 0;
    auto batch = [&]<bool PLASTIC>(index_t b, real_t* buf, index_t lo)
    {
        if (partial_last && b == nb - 1)
            force_1pt_batch<HG, PLASTIC, false>(blk, nodes, b, dt, buf, lo);
        else
            force_1pt_batch<HG, PLASTIC, true>(blk, nodes, b, dt, buf, lo);
    };
    auto run = [&]<bool PLASTIC>()
    {
        if (!blk.scatter.empty())
            blk.scatter.run_chunks("rkfem::hex1pt", 0, static_cast<index_t>(blk.scatter.chunks.size()), W,
                                   [&](index_t b, real_t* buf, index_t lo) { batch.template operator()<PLASTIC>(b, buf, lo); });
        else
            parallel_for("rkfem::hex1pt", nb, [&](index_t b) { batch.template operator()<PLASTIC>(b, nullptr, 0); });
    };
    if (blk.plastic.active())
        run.template operator()<true>();
    else
        run.template operator()<false>();
}

ForcePassResult hex_internal_force(HexBlock& blk, const NodeSet& nodes, real_t dt)
{
    ForcePassResult r;
    const index_t ne = blk.n_elements();
    index_t nb = 0;
    if (blk.formulation == Formulation::Fem1pt)
    {
        nb = n_batches(ne);
        switch (blk.hourglass.type)
        {
        case HourglassType::None:
            run_1pt<HourglassType::None>(blk, nodes, nb, dt);
            break;
        case HourglassType::Viscous:
            run_1pt<HourglassType::Viscous>(blk, nodes, nb, dt);
            break;
        case HourglassType::Stiffness:
            run_1pt<HourglassType::Stiffness>(blk, nodes, nb, dt);
            break;
        case HourglassType::ViscousPlain:
            run_1pt<HourglassType::ViscousPlain>(blk, nodes, nb, dt);
            break;
        }
    }
    else
    {
        nb = ne;
        auto run = [&](auto plastic)
        {
            parallel_for("rkfem::hex2x2x2", ne,
                         [&](index_t e)
                         {
                             real_t out[4];
                             index_t bad = -1;
                             force_2x2x2_element<decltype(plastic)::value>(blk, nodes, e, dt, out, bad);
                             for (int k = 0; k < 4; ++k)
                                 blk.batch_sums[4 * e + k] = out[k];
                             blk.batch_idx[2 * e] = e;
                             blk.batch_idx[2 * e + 1] = bad;
                         });
        };
        if (blk.plastic.active())
            run(std::true_type{});
        else
            run(std::false_type{});
    }
    r.d_internal = parallel_reduce_sum("rkfem::hex_energy", nb,
                                       [&](index_t b) { return blk.batch_sums[4 * b]; });
    r.d_hourglass = parallel_reduce_sum("rkfem::hex_energy", nb,
                                        [&](index_t b) { return blk.batch_sums[4 * b + 1]; });
    r.d_bulk_viscosity = parallel_reduce_sum("rkfem::hex_energy", nb,
                                             [&](index_t b) { return blk.batch_sums[4 * b + 2]; });
    for (index_t b = 0; b < nb; ++b)
    {
        if (blk.batch_sums[4 * b + 3] < r.dt_stable)
        {
            r.dt_stable = blk.batch_sums[4 * b + 3];
            r.dt_element = blk.batch_idx[2 * b];
        }
        if (r.bad_element < 0 && blk.batch_idx[2 * b + 1] >= 0)
            r.bad_element = blk.batch_idx[2 * b + 1];
        if (std::isnan(blk.batch_sums[4 * b + 3]) && r.bad_element < 0)
            r.bad_element = blk.batch_idx[2 * b];
    }
    return r;
}

void assemble_block_forces(HexBlock& blk, NodeSet& nodes)
{
    if (!blk.scatter.empty())
    {
        blk.scatter.reduce(nodes.f_int);
        return;
    }
    const index_t nn = blk.node_end - blk.node_begin;
    parallel_for("rkfem::assemble", nn,
                 [&](index_t i)
                 {
                     real_t f0 = 0.0, f1 = 0.0, f2 = 0.0;
                     for (index_t k = blk.node_elem_offsets[i]; k < blk.node_elem_offsets[i + 1]; ++k)
                     {
                         const real_t* fe = &blk.elem_force[3 * static_cast<std::size_t>(blk.node_elem_slots[k])];
                         f0 += fe[0];
                         f1 += fe[1];
                         f2 += fe[2];
                     }
                     const std::size_t n = 3 * static_cast<std::size_t>(blk.node_begin + i);
                     nodes.f_int[n] = f0;
                     nodes.f_int[n + 1] = f1;
                     nodes.f_int[n + 2] = f2;
                 });
}

real_t element_volume(const HexBlock& blk, const NodeSet& nodes, index_t e)
{
    real_t xe[8][3], b[8][3];
    for (int I = 0; I < 8; ++I)
        for (int d = 0; d < 3; ++d)
            xe[I][d] = nodes.x[3 * static_cast<std::size_t>(blk.conn[8 * static_cast<std::size_t>(e) + I]) + d];
    return hex8_volume_gradient(xe, b);
}

void add_lumped_mass(const HexBlock& blk, NodeSet& nodes)
{
    const index_t nn = blk.node_end - blk.node_begin;
    for (index_t i = 0; i < nn; ++i)
    {
        real_t m = 0.0;
        for (index_t k = blk.node_elem_offsets[i]; k < blk.node_elem_offsets[i + 1]; ++k)
            m += blk.material.rho * blk.volume0[blk.node_elem_slots[k] / 8] / 8.0;
        nodes.mass[blk.node_begin + i] += m;
    }
}
} // namespace rkfem
