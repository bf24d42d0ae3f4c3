#pragma once
/// @file nodal_fast.hpp
/// The fast force kernels of nodal blocks (included by operators/nodal_force.cpp, which runs them
/// over a block): the gathers of F, Fdot and L from a point's stencil (shared stencils, whole-vector
/// batches of 8 points where the stencils agree), the scatters of V0 P, NSNI's sub-point triplets,
/// and the batch pass over the stress points with the material update. Their plain scalar twin,
/// which a newcomer reads first, is nodal_reference.cpp beside this file;
/// verification/operators/test_reference_kernels.cpp holds the two to round-off.
#include "rkfem/core/parallel.hpp"
#include "rkfem/operators/kernels/assumed_strain_hourglass.hpp"
#include "rkfem/operators/kernels/nodal_gather.hpp"

namespace rkfem::nodal_kernels
{
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
    // plastic scaling: the lanes' points' elastic shares (computed in their batch, just before)
    const bool scaling = !blk.stab_share.empty();
    alignas(64) real_t shr[W];
    for (int l = 0; l < W; ++l)
        shr[l] = scaling ? blk.stab_share[static_cast<std::size_t>(p0 + (l < nl ? l : 0))] : 1.0;
    // the point's rotation of the step, for its three sub-points (elastic_update's from w)
    alignas(64) real_t R[9][W];
    RKFEM_SIMD()
    for (int l = 0; l < W; ++l)
    {
        const Rotation<real_t> r = hughes_winget(wl[0][l], wl[1][l], wl[2][l], dt);
        R[0][l] = r.r00, R[1][l] = r.r01, R[2][l] = r.r02, R[3][l] = r.r10, R[4][l] = r.r11, R[5][l] = r.r12;
        R[6][l] = r.r20, R[7][l] = r.r21, R[8][l] = r.r22;
    }
    alignas(64) real_t P[3][9][W];
    for (int i = 0; i < 3; ++i)
    {
        RKFEM_SIMD()
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
            if (scaling)
            {
                const real_t old[6] = {o0, o1, o2, o3, o4, o5};
                real_t t[6] = {t0, t1, t2, t3, t4, t5};
                scale_stabilization_load(r, old, shr[l], t);
                t0 = t[0], t1 = t[1], t2 = t[2], t3 = t[3], t4 = t[4], t5 = t[5];
            }
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
        if (blk.options().prefetch_points && p0 + W + l < blk.n_points())
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
template <PlasticPoints::Kind MK, bool FULL>
[[gnu::noinline]] void nodal_points_batch(NodalBlock& blk, const real_t* u, const real_t* v, index_t batch, real_t dt,
                                          real_t* buf, index_t lo)
{
    constexpr bool PLASTIC = MK != PlasticPoints::Kind::None; // the material, chosen once per block (dispatch_kind)
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
    RKFEM_SIMD()
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
        RKFEM_SIMD()
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
        store_batch8<6>(sn, s_out, snp, static_cast<std::size_t>(p0), buf != nullptr && blk.options().stream_stress);
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
                    RKFEM_SIMD()
                    for (int l = 0; l < W; ++l)
                        sn[k][l] = so[k][l] = s_in[k * snp + static_cast<std::size_t>(p0) + l];
                }
            else
                for (int l = 0; l < W; ++l)
                    for (int k = 0; k < 6; ++k)
                        sn[k][l] = so[k][l] = s_in[k * snp + pt[l]];
            if constexpr (MK == PlasticPoints::Kind::J2)
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
            store_batch8<6>(sn, s_out, snp, static_cast<std::size_t>(p0),
                            buf != nullptr && blk.options().stream_stress);
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
                    blk.plastic.template update_as<MK>(static_cast<index_t>(p), d, w, dt, s);
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
    // bulk viscosity (LS-DYNA form) with l = J^(1/3) l0, the point's length (the stable step is
    // alpha times the element form's on it: alpha calibrates the step, not the viscosity),
    // energies, V0 P = V0 J (sigma - q 1) F^-T
    alignas(64) real_t P[9][W], e_int[W], e_bv[W], dtl[W];
    RKFEM_SIMD()
    for (int l = 0; l < W; ++l)
    {
        const std::size_t p = lane_point(l);
        const real_t J = Jl[l];
        real_t r = 1.0 + (J - 1.0) / 3.0;
        r -= (r * r * r - J) / (3.0 * r * r);
        r -= (r * r * r - J) / (3.0 * r * r);
        r += far[l] * (root[l] - r);
        const real_t len = r * blk.length0[p];
        const real_t trd = dl[0][l] + dl[1][l] + dl[2][l];
        const real_t q = bulk_q(mat.rho / J, c, len, trd, q1, q2);
        dtl[l] = alpha * element_dt(c, len, trd, q1, q2);
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
        if constexpr (PLASTIC)
            if (!blk.stab_share.empty())
            {
                const real_t o[6] = {so[0][l], so[1][l], so[2][l], so[3][l], so[4][l], so[5][l]};
                const real_t n[6] = {sn[0][l], sn[1][l], sn[2][l], sn[3][l], sn[4][l], sn[5][l]};
                const real_t d[6] = {dl[0][l], dl[1][l], dl[2][l], dl[3][l], dl[4][l], dl[5][l]};
                const real_t w[3] = {wl[0][l], wl[1][l], wl[2][l]};
                blk.stab_share[p] = assumed_strain_tangent_share<real_t>(o, n, d, w, mat.mu, dt);
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
                if (nsni_here && blk.options().prefetch_triplets)
                    prefetch_to_l2(blk.stab_triplets.view(static_cast<index_t>(p + W)));
                else if (!nsni_here && blk.options().prefetch_points)
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

/// The instantiation of nodal_points_batch for material kind KIND (None, J2, Kcc, Cscm), both FULL
/// forms: each kind is compiled in a unit of its own (kernels/nodal_points_<kind>.cpp); with
/// `extern` (RKFEM_NODAL_POINTS_BATCHES(extern, KIND)) the declaration nodal_force.cpp makes so
/// that it instantiates none of them.
#define RKFEM_NODAL_POINTS_BATCHES(EXTERN, KIND)                                                                       \
    EXTERN template void nodal_points_batch<PlasticPoints::Kind::KIND, true>(                                          \
        NodalBlock&, const real_t*, const real_t*, index_t, real_t, real_t*, index_t);                                 \
    EXTERN template void nodal_points_batch<PlasticPoints::Kind::KIND, false>(                                         \
        NodalBlock&, const real_t*, const real_t*, index_t, real_t, real_t*, index_t)
} // namespace rkfem::nodal_kernels
