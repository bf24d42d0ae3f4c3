#pragma once
/// @file hex_fast.hpp
/// The fast force kernels of Gauss-point hex blocks (included by operators/hex_block.cpp, which
/// runs them over a block): force_1pt_batch, one batch of simd::kLanes one-point elements, one
/// element per lane, and force_2x2x2_element, one fully integrated element. Their plain scalar
/// twin, which a newcomer reads first, is hex1pt_reference.cpp beside this file;
/// verification/operators/test_reference_kernels.cpp holds the two to round-off.
#include <algorithm>
#include <cmath>
#include <immintrin.h>
#include <type_traits>

#include "rkfem/approximation/fem/hex8_basis.hpp"
#include "rkfem/approximation/fem/hex8_modes.hpp"
#include "rkfem/approximation/fem/hex8_volume_gradient.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/simd.hpp"
#include "rkfem/core/stream_stores.hpp"
#include "rkfem/operators/bulk_viscosity.hpp"
#include "rkfem/operators/hex_block.hpp"
#include "rkfem/operators/kernels/assumed_strain_hourglass.hpp"

// GCC 12's AVX-512 intrinsics (gathers, unpacks, 128-bit shuffles, extracts) start from an
// undefined source written "__m512d __Y = __Y", which -Wmaybe-uninitialized / -Wuninitialized
// report once inlined; every value used is defined.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

namespace rkfem::hex_kernels
{
constexpr int W = simd::kLanes; // lanes per batch (one vector register of doubles)

inline index_t n_batches(index_t ne)
{
    return (ne + W - 1) / W;
}

/// One batch of W elements, one element per lane of a simd::dvec. FULL: all W lanes are elements
/// (every batch but a partial last one), so loads and stores are whole lane vectors; a partial
/// batch's lanes past the block's end repeat its first element and are not stored.
///
/// The element is worked in its mode basis (hex8_modes.hpp): positions and velocities go to
/// modes in one butterfly each, the exact-volume gradient is 12 cross products of position
/// modes, the velocity gradient and the hourglass velocities come from the velocity modes, and
/// the nodal forces (stress and hourglass) are one inverse butterfly of their modes.
template <HourglassType HG, PlasticPoints::Kind MK, bool FULL>
RKFEM_WIDE_VECTORS void force_1pt_batch(HexBlock& blk, const NodeSet& nodes, index_t batch, real_t dt, real_t* buf,
                                        index_t lo)
{
    constexpr bool PLASTIC = MK != PlasticPoints::Kind::None; // the material, chosen once per block (dispatch_kind)
    using simd::dvec;
    using simd::mul_add;
    const index_t ne = blk.n_elements();
    const index_t e0 = batch * W;
    const int nl = FULL ? W : static_cast<int>(std::min<index_t>(W, ne - e0));
    auto lane_element = [&](int l) { return static_cast<std::size_t>(e0 + (FULL || l < nl ? l : 0)); };
    // a field of the block's elements (component stride n) for the batch's lanes
    auto load_lanes = [&](const real_t* field) -> dvec
    {
        if constexpr (FULL)
            return simd::load(field + e0);
        else
        {
            alignas(64) real_t t[W];
            for (int l = 0; l < W; ++l)
                t[l] = field[lane_element(l)];
            return simd::load(t);
        }
    };
    auto store_lanes = [&](real_t* field, dvec v)
    {
        if constexpr (FULL)
            simd::store(field + e0, v);
        else
        {
            alignas(64) real_t t[W];
            simd::store(t, v);
            for (int l = 0; l < nl; ++l)
                field[e0 + l] = t[l];
        }
    };

#if defined(__AVX512F__)
    // bit I: node I of the batch's 8 elements is 8 consecutive nodes (as along a structured
    // mesh's rows), loaded with line loads and permutes and added as whole vectors below
    unsigned consecutive = 0;
    const index_t* g3 = FULL ? &blk.gather_index[64 * static_cast<std::size_t>(batch)] : nullptr;
    if constexpr (FULL)
    {
        const __m256i step = _mm256_setr_epi32(0, 3, 6, 9, 12, 15, 18, 21);
        for (int I = 0; I < 8; ++I)
        {
            const __m256i idx = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(g3 + 8 * I));
            const __m256i row = _mm256_add_epi32(_mm256_set1_epi32(g3[8 * I]), step);
            consecutive |= (_mm256_cmpeq_epi32_mask(idx, row) == 0xFF ? 1u : 0u) << I;
        }
    }
#endif
    // the modes Y_k (k = 1..7; the constant mode is not used) of a nodal field (x or v) over the
    // batch's elements: node I of the 8 elements by line loads or one 8-lane gather per component
    auto field_modes = [&](const std::vector<real_t>& field, dvec(&Y)[8][3]) __attribute__((always_inline))
    {
        dvec y[8][3];
#if defined(__AVX512F__)
        if constexpr (FULL)
        {
            for (int I = 0; I < 8; ++I)
            {
                if (consecutive >> I & 1u)
                {
                    simd::load_triples(field.data() + g3[8 * I], y[I][0], y[I][1], y[I][2]);
                    continue;
                }
                const __m256i idx = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(g3 + 8 * I));
                for (int d = 0; d < 3; ++d)
                    y[I][d] = _mm512_i32gather_pd(idx, field.data() + d, 8);
            }
        }
        else
#endif
        {
            alignas(64) real_t yl[8][3][W];
            for (int l = 0; l < W; ++l)
            {
                const index_t* c = &blk.conn[8 * lane_element(l)];
                for (int I = 0; I < 8; ++I)
                    for (int d = 0; d < 3; ++d)
                        yl[I][d][l] = field[3 * static_cast<std::size_t>(c[I]) + d];
            }
            for (int I = 0; I < 8; ++I)
                for (int d = 0; d < 3; ++d)
                    y[I][d] = simd::load(yl[I][d]);
        }
        hex8_to_modes(y, Y);
    };

    // b_I = dV/dx_I in modes (Flanagan-Belytschko, exact volume integration), the volume, and
    // the velocity gradient L_ij = (1/V) sum_I v_iI b_jI = (1/V) sum_k U_ki B_kj (positions
    // first, velocities after: fewer lane vectors live at once)
    dvec A[8][3], B[8][3];
    field_modes(nodes.x, A);
    const dvec vol = hex8_mode_volume_gradient(A, B);
    // characteristic length lc = V / a with a the largest face area: one division for 1/V and 1/a
    const dvec area = simd::sqrt(hex8_mode_max_face_area2(A));
    const dvec r = 1.0 / (vol * area);
    const dvec inv_v = r * area, inv_a = r * vol;
    const dvec lc = vol * inv_a;
    dvec U[8][3];
    field_modes(nodes.v, U);
    dvec L[3][3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
        {
            dvec s = U[1][i] * B[1][j];
            for (int k = 2; k <= 6; ++k)
                s = mul_add(U[k][i], B[k][j], s);
            L[i][j] = s * inv_v;
        }

    const ElasticParams mat = blk.material;
    const real_t c = mat.wave_speed();
    const real_t q1 = blk.bulk_viscosity.quadratic, q2 = blk.bulk_viscosity.linear;
    const std::size_t np = static_cast<std::size_t>(ne), ss = blk.stress_stride;
    const real_t* s_in = blk.stress.data();
    real_t* s_out = blk.stress_trial.data();

    // stress update (strain rate d, old and new stress kept for the stress power)
    const dvec dl[6] = {
        L[0][0], L[1][1], L[2][2], 0.5 * (L[0][1] + L[1][0]), 0.5 * (L[1][2] + L[2][1]), 0.5 * (L[2][0] + L[0][2])};
    const dvec wl[3] = {0.5 * (L[0][1] - L[1][0]), 0.5 * (L[1][2] - L[2][1]), 0.5 * (L[2][0] - L[0][2])};
    dvec so[6], sn[6];
    for (int k = 0; k < 6; ++k)
        so[k] = load_lanes(s_in + k * ss);
    if constexpr (PLASTIC)
    {
        // the point's model update per lane
        alignas(64) real_t dv[6][W], wv[3][W], sv[6][W];
        for (int k = 0; k < 6; ++k)
        {
            simd::store(dv[k], dl[k]);
            simd::store(sv[k], so[k]);
        }
        for (int k = 0; k < 3; ++k)
            simd::store(wv[k], wl[k]);
        // the lanes that stay elastic (J2) at once, the others one by one
        std::size_t pt[W];
        bool elastic[W] = {};
        for (int l = 0; l < W; ++l)
            pt[l] = lane_element(l < nl ? l : 0);
        if constexpr (MK == PlasticPoints::Kind::J2)
            blk.plastic.j2_elastic_lanes<W>(pt, nl, dv, wv, dt, sv, elastic);
        for (int l = 0; l < nl; ++l)
        {
            if (elastic[l])
                continue;
            const real_t d[6] = {dv[0][l], dv[1][l], dv[2][l], dv[3][l], dv[4][l], dv[5][l]};
            const real_t w[3] = {wv[0][l], wv[1][l], wv[2][l]};
            real_t s[6] = {sv[0][l], sv[1][l], sv[2][l], sv[3][l], sv[4][l], sv[5][l]};
            blk.plastic.template update_as<MK>(lane_element(l), d, w, dt, s);
            for (int k = 0; k < 6; ++k)
                sv[k][l] = s[k];
        }
        for (int k = 0; k < 6; ++k)
            sn[k] = simd::load(sv[k]);
    }
    else
    {
        for (int k = 0; k < 6; ++k)
            sn[k] = so[k];
        elastic_update(mat, dl[0], dl[1], dl[2], dl[3], dl[4], dl[5], wl[0], wl[1], wl[2], dt, sn[0], sn[1], sn[2],
                       sn[3], sn[4], sn[5]);
    }
#if defined(__AVX512F__)
    // a full batch of 8 is one line per component, which may be streamed (store_batch8)
    if constexpr (FULL)
    {
        alignas(64) real_t st[6][W];
        for (int k = 0; k < 6; ++k)
            simd::store(st[k], sn[k]);
        store_batch8<6>(st, s_out, ss, static_cast<std::size_t>(e0), buf != nullptr && blk.stream_stress);
    }
    else
#endif
        for (int k = 0; k < 6; ++k)
            store_lanes(s_out + k * ss, sn[k]);

    // bulk viscosity, time step, energies, effective stress (characteristic length: volume over
    // the largest face area)
    const dvec trd = dl[0] + dl[1] + dl[2];
    const dvec rho = mat.rho * load_lanes(blk.volume0.data()) * inv_v;
    const dvec q = bulk_q(rho, c, lc, trd, q1, q2);
    // the stable step, kept as its inverse (no division per element; the batch's smallest step
    // is one division): 1/lc = a/V
    const dvec inv_dt = element_dt_inverse(c, lc, area * inv_v, trd, q1, q2);
    dvec power = (so[0] + sn[0]) * dl[0];
    power = mul_add(so[1] + sn[1], dl[1], power);
    power = mul_add(so[2] + sn[2], dl[2], power) * 0.5;
    for (int k = 3; k < 6; ++k)
        power = mul_add(so[k] + sn[k], dl[k], power);
    const dvec de_int = dt * vol * power;
    const dvec de_bv = -dt * vol * q * trd;
    const dvec sig[6] = {sn[0] - q, sn[1] - q, sn[2] - q, sn[3], sn[4], sn[5]};

    // Hourglass control (Flanagan-Belytschko). Mode a (base vector Gamma_a, position mode
    // k = 4 + a) has gamma_aI = Gamma_aI - (1/V) b_I . h_a with h_a = sum_J Gamma_aJ x_J = A_k.
    // With g_a = sum_J Gamma_aJ v_J = U_k the hourglass velocity is qdot_ai = sum_I v_iI gamma_aI
    // = g_ai - L_ij h_aj, and the nodal forces sum_a gamma_aI Q_ai = sum_a Gamma_aI Q_ai - b_jI
    // M_ji with M_ji = (1/V) sum_a h_aj Q_ai, which joins the stress term below.
    dvec de_hg = simd::broadcast(0.0);
    dvec T[3][3]; // sigma_ij - M_ji
    static constexpr int voigt[3][3] = {{0, 3, 5}, {3, 1, 4}, {5, 4, 2}};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            T[i][j] = sig[voigt[i][j]];
    dvec Q[4][3];
    if constexpr (HG == HourglassType::AssumedStrain)
    {
        // assumed strain in the co-rotational frame (kernels/assumed_strain_hourglass.hpp): the
        // stored generalized forces (frame components, 12 per element) grow with the frame's
        // hourglass velocities; Q back in the global frame, scaled to the FB base vectors (1/8)
        dvec e[3][3], Jf[3];
        assumed_strain_frame(A[mode_xi], A[mode_eta], A[mode_zeta], e, Jf);
        const dvec inv_j[3] = {1.0 / Jf[0], 1.0 / Jf[1], 1.0 / Jf[2]};
        const real_t nu = mat.lambda / (2.0 * (mat.lambda + mat.mu));
        // the stored forces follow the change of their stiffness since they were stored
        dvec Jo[3], keep[4][3];
        for (int i = 0; i < 3; ++i)
        {
            const std::size_t row = static_cast<std::size_t>(HexBlock::kHgSizeRow + i) * np;
            Jo[i] = load_lanes(blk.hg_force.data() + row);
            store_lanes(blk.hg_force_trial.data() + row, Jf[i]);
        }
        assumed_strain_keep(Jo, Jf, keep);
        const dvec gain = simd::broadcast(blk.hourglass.coefficient * mat.mu / 3.0 * dt);
        // materials with history: loads take the share of the step the material took
        // elastically (an elastic material takes the whole increment), unloads all of it
        [[maybe_unused]] dvec share;
        [[maybe_unused]] bool scaled = false;
        if constexpr (PLASTIC)
            if (blk.hourglass.plastic_scaling)
            {
                share = assumed_strain_tangent_share(so, sn, dl, wl, mat.mu, dt);
                scaled = true;
            }
        // the stored forces Q (frame components) grow by the stiffness of the present shape
        // applied to the step's hourglass stress increment dS = gain q / J
        dvec q[4][3], dS[4][3], dQ[4][3], Qn[4][3];
        for (int m = 0; m < 4; ++m)
        {
            const int k = mode_xi_eta + kAssumedStrainMode[m];
            dvec qd[3];
            for (int i = 0; i < 3; ++i)
                qd[i] = simd::neg_mul_add(
                    L[i][2], A[k][2],
                    simd::neg_mul_add(L[i][1], A[k][1], simd::neg_mul_add(L[i][0], A[k][0], U[k][i])));
            for (int i = 0; i < 3; ++i)
            {
                q[m][i] = 0.125 * mul_add(e[i][2], qd[2], mul_add(e[i][1], qd[1], e[i][0] * qd[0]));
                dS[m][i] = gain * q[m][i] * inv_j[i];
            }
        }
        assumed_strain_forces(dS, Jf, nu, dQ);
        for (int m = 0; m < 4; ++m)
        {
            const int a = kAssumedStrainMode[m];
            for (int i = 0; i < 3; ++i)
            {
                const std::size_t slot = static_cast<std::size_t>(3 * m + i) * np;
                const dvec Qo = load_lanes(blk.hg_force.data() + slot) * keep[m][i];
                if (scaled)
                {
                    Qn[m][i] = scaled_hourglass_update(Qo, dQ[m][i], share);
                    de_hg = mul_add((Qo + Qn[m][i]) * q[m][i], 0.5 * dt, de_hg);
                }
                else
                {
                    Qn[m][i] = Qo + dQ[m][i];
                    de_hg = mul_add(mul_add(0.5, dQ[m][i], Qo) * q[m][i], dt, de_hg);
                }
                store_lanes(blk.hg_force_trial.data() + slot, Qn[m][i]);
            }
            for (int j = 0; j < 3; ++j)
                Q[a][j] = 0.125 * mul_add(e[2][j], Qn[m][2], mul_add(e[1][j], Qn[m][1], e[0][j] * Qn[m][0]));
        }
    }
    else if constexpr (HG != HourglassType::None)
    {
        const real_t qm = blk.hourglass.coefficient;
        // hourglass coefficient: viscous a_h = QM rho c V^(2/3) / 4 with V^(2/3) taken as lc^2
        // (equal for cubes); stiffness k = QM (lambda + 2 mu) sum_I |b_I|^2 / (24 V)
        // (Flanagan-Belytschko's / (3 V) on their modes normalized by 1/sqrt(8); the reference
        // kernel), sum_I |b_I|^2 = 8 sum_k |B_k|^2 by the modes' orthogonality
        dvec coef;
        if constexpr (HG == HourglassType::Stiffness)
        {
            dvec bb = B[1][0] * B[1][0];
            for (int k = 1; k <= 6; ++k)
                for (int d = k == 1 ? 1 : 0; d < 3; ++d)
                    bb = mul_add(B[k][d], B[k][d], bb);
            coef = (qm * mat.plane_wave_modulus() / 3.0) * bb * inv_v;
        }
        else
            coef = 0.25 * qm * mat.rho * c * lc * lc;
        // the stiffness form's loads scaled where the material flows (plastic_scaling; unloads whole)
        const dvec coef_dt = coef * dt;
        [[maybe_unused]] dvec share;
        [[maybe_unused]] bool scaled = false;
        if constexpr (PLASTIC && HG == HourglassType::Stiffness)
            if (blk.hourglass.plastic_scaling)
            {
                share = assumed_strain_tangent_share(so, sn, dl, wl, mat.mu, dt);
                scaled = true;
            }
        for (int a = 0; a < 4; ++a)
        {
            // stiffness form: the stored force turns with the element's spin first, Q += dt W Q
            // (W = (L - L^T) / 2; the first-order rotation of the Jaumann stress update)
            dvec Qrot[3];
            if constexpr (HG == HourglassType::Stiffness)
            {
                dvec Qo[3];
                for (int i = 0; i < 3; ++i)
                    Qo[i] = load_lanes(blk.hg_force.data() + static_cast<std::size_t>(3 * a + i) * np);
                for (int i = 0; i < 3; ++i)
                {
                    Qrot[i] = Qo[i];
                    for (int j = 0; j < 3; ++j)
                        if (j != i)
                            Qrot[i] = mul_add((0.5 * dt) * (L[i][j] - L[j][i]), Qo[j], Qrot[i]);
                }
            }
            for (int i = 0; i < 3; ++i)
            {
                const int k = mode_xi_eta + a;
                dvec qd = U[k][i];
                if constexpr (HG != HourglassType::ViscousPlain) // the plain form takes gamma = Gamma
                    qd = simd::neg_mul_add(
                        L[i][2], A[k][2], simd::neg_mul_add(L[i][1], A[k][1], simd::neg_mul_add(L[i][0], A[k][0], qd)));
                if constexpr (HG == HourglassType::Stiffness)
                {
                    const std::size_t slot = static_cast<std::size_t>(3 * a + i) * np;
                    const dvec Qnew =
                        scaled ? scaled_hourglass_update(Qrot[i], coef_dt * qd, share) : mul_add(coef_dt, qd, Qrot[i]);
                    store_lanes(blk.hg_force_trial.data() + slot, Qnew);
                    Q[a][i] = Qnew;
                    de_hg = mul_add((Qrot[i] + Qnew) * qd, 0.5 * dt, de_hg);
                }
                else
                {
                    Q[a][i] = coef * qd;
                    de_hg = mul_add(Q[a][i] * qd, dt, de_hg);
                }
            }
        }
    }
    // the hourglass forces' share of the gradient term, M_ji (not for the plain form)
    if constexpr (HG != HourglassType::None && HG != HourglassType::ViscousPlain)
        for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 3; ++i)
                T[i][j] = simd::neg_mul_add(
                    inv_v,
                    mul_add(A[7][j], Q[3][i], mul_add(A[6][j], Q[2][i], mul_add(A[5][j], Q[1][i], A[4][j] * Q[0][i]))),
                    T[i][j]);

    // internal force f_iI = (sigma_ij - M_ji) b_jI + sum_a Gamma_aI Q_ai: in modes F_ki =
    // T_ij B_kj (k = 1..6) plus Q_ai in mode 4 + a, then one inverse butterfly
    dvec F[8][3], f[8][3];
    for (int k = 1; k <= 6; ++k)
        for (int i = 0; i < 3; ++i)
            F[k][i] = mul_add(T[i][2], B[k][2], mul_add(T[i][1], B[k][1], T[i][0] * B[k][0]));
    for (int i = 0; i < 3; ++i)
    {
        if constexpr (HG != HourglassType::None)
        {
            for (int a = 0; a < 3; ++a)
                F[mode_xi_eta + a][i] = F[mode_xi_eta + a][i] + Q[a][i];
            F[mode_xi_eta_zeta][i] = Q[3][i];
        }
        else
            F[mode_xi_eta_zeta][i] = simd::broadcast(0.0);
    }
    hex8_from_modes_no_mean(F, f);
    // the forces lane by lane, for the paths that add or write them element by element
    auto force_lanes = [&](real_t(&fl)[8][3][W])
    {
        for (int I = 0; I < 8; ++I)
            for (int d = 0; d < 3; ++d)
                simd::store(fl[I][d], f[I][d]);
    };

    // nodal forces: into the chunk's buffer (scatter assembly) or the element force buffer
    if (buf != nullptr)
    {
        // node by node of the batch, lane by lane: a fixed order of the chunk's sums
#if defined(__AVX512F__)
        if constexpr (FULL)
        {
            // lanes to (x, y, z, 0) per element: unpack x/y and z/0, then pair the 128-bit halves;
            // zmm k holds lanes (2k', 2k'+2) or (2k'+1, 2k'+3) in its 256-bit halves
            const __m512d zero = _mm512_setzero_pd();
            // node I's 8 terms, one node row of the buffer
            auto add_node = [&](int I)
            {
                const __m512d X = f[I][0], Y = f[I][1], Z = f[I][2];
                if (consecutive >> I & 1u)
                {
                    // consecutive nodes: their 8 (x, y, z, 0) quadruples are 4 whole vectors
                    __m512d qv[4];
                    simd::interleave4(X, Y, Z, qv);
                    real_t* b = buf + 4 * static_cast<std::size_t>(g3[8 * I] / 3 - lo);
                    for (int k = 0; k < 4; ++k)
                        _mm512_storeu_pd(b + 8 * k, _mm512_add_pd(_mm512_loadu_pd(b + 8 * k), qv[k]));
                    return;
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
            };
            // Nodes (0, 1), (2, 3), (4, 5), (6, 7) are neighbours along xi. Where both rows of
            // a pair are consecutive and one is the other shifted by a node (a structured row),
            // the pair's 9 nodes are summed in registers: the buffer is read and written once
            // instead of twice with 7 of 8 nodes in common (the second read would wait for the
            // first write: a load half over a store cannot take its data from the store buffer).
            // The terms are added in the node-by-node order: the same bits.
            for (int P = 0; P < 8; P += 2)
            {
                // along xi node 1 follows 0, 2 follows 3, 5 follows 4, 6 follows 7
                const bool first_low = P == 0 || P == 4;
                const int I_low = first_low ? P : P + 1, I_high = first_low ? P + 1 : P;
                if ((consecutive >> P & 3u) != 3u || g3[8 * I_high] != g3[8 * I_low] + 3)
                {
                    add_node(P);
                    add_node(P + 1);
                    continue;
                }
                __m512d ql[4], qh[4], r[4];
                simd::interleave4(f[I_low][0], f[I_low][1], f[I_low][2], ql);
                simd::interleave4(f[I_high][0], f[I_high][1], f[I_high][2], qh);
                // the high row's quadruples a node (half a vector) on: r[k] = (qh[k-1] high, qh[k] low)
                r[0] = _mm512_shuffle_f64x2(qh[0], qh[0], _MM_SHUFFLE(1, 0, 1, 0));
                for (int k = 1; k < 4; ++k)
                    r[k] = _mm512_shuffle_f64x2(qh[k - 1], qh[k], _MM_SHUFFLE(1, 0, 3, 2));
                real_t* b = buf + 4 * static_cast<std::size_t>(g3[8 * I_low] / 3 - lo);
                for (int k = 0; k < 4; ++k)
                {
                    const __m512d old = _mm512_loadu_pd(b + 8 * k);
                    // r[0]'s low half is no node of the high row: not added (a -0 stays -0)
                    const __mmask8 m = k == 0 ? 0xF0 : 0xFF;
                    __m512d sum;
                    if (first_low)
                    {
                        sum = _mm512_add_pd(old, ql[k]);
                        sum = _mm512_mask_add_pd(sum, m, sum, r[k]);
                    }
                    else
                        sum = _mm512_add_pd(_mm512_mask_add_pd(old, m, old, r[k]), ql[k]);
                    _mm512_storeu_pd(b + 8 * k, sum);
                }
                _mm256_storeu_pd(b + 32, _mm256_add_pd(_mm256_loadu_pd(b + 32), _mm512_extractf64x4_pd(qh[3], 1)));
            }
        }
        else
#endif
        {
            alignas(64) real_t fl[8][3][W];
            force_lanes(fl);
            for (int I = 0; I < 8; ++I)
                for (int l = 0; l < nl; ++l)
                {
                    real_t* b =
                        buf + 4 * static_cast<std::size_t>(blk.conn[8 * static_cast<std::size_t>(e0 + l) + I] - lo);
                    b[0] += fl[I][0][l];
                    b[1] += fl[I][1][l];
                    b[2] += fl[I][2][l];
                }
        }
    }
    else
    {
        alignas(64) real_t fl[8][3][W];
        force_lanes(fl);
        for (int l = 0; l < nl; ++l)
        {
            real_t* fe = &blk.elem_force[24 * static_cast<std::size_t>(e0 + l)];
            for (int I = 0; I < 8; ++I)
                for (int d = 0; d < 3; ++d)
                    fe[3 * I + d] = fl[I][d][l];
        }
    }
    // batch results
    alignas(64) real_t vol_l[W], inv_dt_l[W], int_l[W], hg_l[W], bv_l[W];
    simd::store(vol_l, vol);
    simd::store(inv_dt_l, inv_dt);
    simd::store(int_l, de_int);
    simd::store(hg_l, de_hg);
    simd::store(bv_l, de_bv);
    real_t sum_int = 0.0, sum_hg = 0.0, sum_bv = 0.0, inv_dt_max = 0.0;
    index_t dt_elem = -1, bad = -1;
    for (int l = 0; l < nl; ++l)
    {
        const index_t e = e0 + l;
        sum_int += int_l[l];
        sum_hg += hg_l[l];
        sum_bv += bv_l[l];
        if (inv_dt_l[l] > inv_dt_max)
        {
            inv_dt_max = inv_dt_l[l];
            dt_elem = e;
        }
        if (!(vol_l[l] > 0.0) && bad < 0)
            bad = e;
    }
    blk.batch_sums[4 * batch + 0] = sum_int;
    blk.batch_sums[4 * batch + 1] = sum_hg;
    blk.batch_sums[4 * batch + 2] = sum_bv;
    blk.batch_sums[4 * batch + 3] = dt_elem >= 0 ? 1.0 / inv_dt_max : kNoLimit;
    blk.batch_idx[2 * batch + 0] = dt_elem;
    blk.batch_idx[2 * batch + 1] = bad;
}

/// Fully integrated hex: 8 Gauss points, stress per point, bulk viscosity from the mean tr D.
template <PlasticPoints::Kind MK>
void force_2x2x2_element(HexBlock& blk, const NodeSet& nodes, index_t e, real_t dt, real_t out[4], index_t& bad)
{
    constexpr bool PLASTIC = MK != PlasticPoints::Kind::None;
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
        const real_t d[6] = {Lm[0][0],
                             Lm[1][1],
                             Lm[2][2],
                             0.5 * (Lm[0][1] + Lm[1][0]),
                             0.5 * (Lm[1][2] + Lm[2][1]),
                             0.5 * (Lm[2][0] + Lm[0][2])};
        const real_t w[3] = {0.5 * (Lm[0][1] - Lm[1][0]), 0.5 * (Lm[1][2] - Lm[2][1]), 0.5 * (Lm[2][0] - Lm[0][2])};
        const std::size_t p = 8 * static_cast<std::size_t>(e) + gp;
        real_t s_old[6];
        for (int k = 0; k < 6; ++k)
            s_old[k] = s_new[gp][k] = blk.stress[k * ss + p];
        if constexpr (PLASTIC)
            blk.plastic.template update_as<MK>(p, d, w, dt, s_new[gp]);
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
} // namespace rkfem::hex_kernels

#pragma GCC diagnostic pop
