// Materials as pointwise value types: the Hughes-Winget rotation is exactly orthogonal (a rigid
// spin leaves invariants unchanged), the elastic update reproduces Hooke's law, and the J2 model
// (MAT_024 analog): uniaxial-stress bilinear response exact at every step, the yield condition
// after the return, Cowper-Symonds scaling, failure at the stated plastic strain; the lane-batched
// elastic path agrees with update() to round-off on the lanes it takes and leaves the others to it.
#include <gtest/gtest.h>

#include <cstdio>
#include <limits>
#include <random>

#include "rkfem/materials/j2_plasticity.hpp"
#include "rkfem/materials/point_history.hpp"

using namespace rkfem;

namespace
{
const real_t E = 200e9, nu = 0.3;
const ElasticParams el = ElasticParams::from_E_nu(7850, E, nu);

real_t von_mises(const real_t s[6])
{
    const real_t p = (s[0] + s[1] + s[2]) / 3.0;
    const real_t d0 = s[0] - p, d1 = s[1] - p, d2 = s[2] - p;
    return std::sqrt(1.5 * (d0 * d0 + d1 * d1 + d2 * d2 + 2 * (s[3] * s[3] + s[4] * s[4] + s[5] * s[5])));
}

/// Uniaxial stress in x at strain rate `rate`: lateral strain rates found by Newton on the lateral
/// stresses (elastic compliance as the Jacobian), from the committed state each iteration.
template <class Update> void uniaxial_step(Update&& update, real_t rate, real_t dt, real_t s[6], real_t& lat)
{
    for (int it = 0; it < 50; ++it)
    {
        real_t trial[6];
        std::copy(s, s + 6, trial);
        const real_t d[6] = {rate, lat, lat, 0, 0, 0};
        update(d, dt, trial, false);
        const real_t r = 0.5 * (trial[1] + trial[2]);
        if (std::abs(r) < 1e-9 * (std::abs(trial[0]) + 1.0))
            break;
        // d sigma_lat / d lat ~ 2 (lambda + mu) dt (lateral pair, elastic)
        lat -= r / (2.0 * (el.lambda + el.mu) * dt);
    }
    const real_t d[6] = {rate, lat, lat, 0, 0, 0};
    update(d, dt, s, true);
}
/// One uniaxial-stress step of a J2 point; returns sqrt(d:d) of the converged rate.
real_t j2_uniaxial(const J2Params& p, real_t rate, real_t dt, real_t s[6], real_t& ep, real_t& failed, real_t& lat)
{
    real_t dd = 0.0;
    uniaxial_step(
        [&](const real_t* d, real_t h, real_t* st, bool commit)
        {
            real_t e = ep, f = failed;
            const real_t w[3] = {0, 0, 0};
            j2_update(p, d, w, h, st, e, f);
            if (commit)
            {
                ep = e, failed = f;
                dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            }
        },
        rate, dt, s, lat);
    return std::sqrt(dd);
}
} // namespace

TEST(ObjectiveRate, RigidSpinKeepsInvariants)
{
    real_t s[6] = {3e8, -1e8, 5e7, 8e7, -2e7, 4e7};
    const real_t w[3] = {1e4, -3e3, 7e3}; // rad/s
    const real_t vm0 = von_mises(s), tr0 = s[0] + s[1] + s[2];
    for (int k = 0; k < 100000; ++k)
        rotate_stress(w, 1e-7, s);
    std::printf("after 100000 spin steps: von Mises drift %.2e, trace drift %.2e (relative)\n", von_mises(s) / vm0 - 1,
                (s[0] + s[1] + s[2]) / tr0 - 1);
    EXPECT_NEAR(von_mises(s) / vm0, 1.0, 1e-10);
    EXPECT_NEAR((s[0] + s[1] + s[2]) / tr0, 1.0, 1e-10);
    // and it rotates: a quarter turn about z maps sigma_xx to sigma_yy
    real_t q[6] = {1.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    const real_t wz[3] = {-1.0, 0.0, 0.0}; // W_xy = -omega_z for a spin omega_z about +z
    const int n = 20000;
    for (int k = 0; k < n; ++k)
        rotate_stress(wz, 0.5 * M_PI / n, q);
    EXPECT_NEAR(q[0], 0.0, 1e-8);
    EXPECT_NEAR(q[1], 1.0, 1e-8);
}

TEST(ObjectiveRate, HughesWingetRotationIsOrthogonalAndSharedOnce)
{
    // the Cayley transform of a skew matrix is orthogonal: R R^T = 1 to round-off, even for a
    // spin step of order one (h |W| about 0.9 here)
    const real_t w[3] = {1e4, -3e3, 7e3}, dt = 1.5e-4;
    const Rotation<real_t> R = hughes_winget(w[0], w[1], w[2], dt);
    const real_t M[3][3] = {{R.r00, R.r01, R.r02}, {R.r10, R.r11, R.r12}, {R.r20, R.r21, R.r22}};
    real_t worst = 0.0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
        {
            const real_t rrt = M[i][0] * M[j][0] + M[i][1] * M[j][1] + M[i][2] * M[j][2];
            worst = std::max(worst, std::abs(rrt - (i == j ? 1.0 : 0.0)));
        }
    std::printf("|R R^T - 1| = %.1e\n", worst);
    EXPECT_LT(worst, 1e-15);
    // a stress rotated by the rotation formed once (NSNI's sub-points share their particle's)
    // is the one rotated from the spin: the same bits
    real_t a[6] = {3e8, -1e8, 5e7, 8e7, -2e7, 4e7}, b[6];
    std::copy(a, a + 6, b);
    rotate_stress(w, dt, a);
    rotate_stress(R, b[0], b[1], b[2], b[3], b[4], b[5]);
    for (int k = 0; k < 6; ++k)
        EXPECT_EQ(a[k], b[k]);
}

TEST(J2Plasticity, UniaxialBilinearResponseIsExactAtEveryStep)
{
    const real_t sigy = 400e6, etan = 2e9;
    const J2Params p = J2Params::bilinear(el, E, sigy, etan);
    real_t s[6] = {}, ep = 0, failed = 0, lat = -nu * 1e-3, eps = 0.0;
    const real_t rate = 1e-3, dt = 1.0; // 0.1 % strain per step
    real_t worst = 0.0;
    for (int k = 0; k < 40; ++k)
    {
        j2_uniaxial(p, rate, dt, s, ep, failed, lat);
        eps += rate * dt;
        const real_t expect = eps <= sigy / E ? E * eps : sigy + etan * (eps - sigy / E);
        worst = std::max(worst, std::abs(s[0] - expect) / expect);
    }
    std::printf("bilinear uniaxial stress to 4 %% strain: worst relative error %.2e, eps_p = %.5f\n", worst, ep);
    EXPECT_LT(worst, 1e-8);
    // unloading is elastic with slope E
    const real_t s_before = s[0];
    j2_uniaxial(p, -rate, 0.1, s, ep, failed, lat);
    EXPECT_NEAR(s[0], s_before - E * rate * 0.1, 1e-8 * s_before);
}

TEST(J2Plasticity, YieldConditionHoldsAfterTheReturnOnRandomPaths)
{
    J2Params p;
    p.elastic = el;
    p.curve = {{0.0, 792e6},   {0.01, 946e6},  {0.05, 1026e6}, {0.10, 1072e6},
               {0.20, 1128e6}, {0.50, 1218e6}, {1.0, 1302e6}};
    std::mt19937 gen(5);
    std::uniform_real_distribution<real_t> u(-1.0, 1.0);
    real_t s[6] = {}, ep = 0, failed = 0, worst = 0.0;
    int plastic = 0;
    for (int k = 0; k < 2000; ++k)
    {
        const real_t d[6] = {u(gen), u(gen), u(gen), u(gen), u(gen), u(gen)};
        const real_t w[3] = {u(gen), u(gen), u(gen)};
        const real_t dep = j2_update(p, d, w, 2e-3, s, ep, failed);
        if (dep > 0)
        {
            ++plastic;
            real_t sy, h;
            p.yield(ep, sy, h);
            worst = std::max(worst, std::abs(von_mises(s) - sy) / sy);
        }
    }
    std::printf("%d plastic steps, eps_p = %.3f: |q - sigma_y(eps_p)| / sigma_y <= %.2e\n", plastic, ep, worst);
    EXPECT_GT(plastic, 100);
    EXPECT_LT(worst, 1e-10);
}

TEST(J2Plasticity, CowperSymondsScalesTheYieldStress)
{
    // perfectly plastic, C = 40.4 /s, P = 5 (mild steel): at a strain rate of 100 /s the flow
    // stress is (1 + (100 / 40.4)^(1/5)) sigy; the rate is sqrt(d:d) of the uniaxial-stress path
    J2Params p = J2Params::bilinear(el, E, 250e6, 0.0);
    p.cs_c = 40.4;
    p.cs_p = 5.0;
    real_t s[6] = {}, ep = 0, failed = 0, lat = -nu * 100.0;
    const real_t rate = 100.0, dt = 1e-6;
    real_t rate_eff = 0.0;
    for (int k = 0; k < 100; ++k) // 1 % strain
        rate_eff = j2_uniaxial(p, rate, dt, s, ep, failed, lat);
    const real_t beta = 1.0 + std::pow(rate_eff / 40.4, 0.2);
    std::printf("Cowper-Symonds: sigma / sigy = %.6f, beta(sqrt(d:d) = %.2f /s) = %.6f\n", s[0] / 250e6, rate_eff,
                beta);
    EXPECT_NEAR(s[0], beta * 250e6, 1e-6 * 250e6);
}

TEST(J2Plasticity, FailsAtTheStatedPlasticStrain)
{
    J2Params p = J2Params::bilinear(el, E, 400e6, 2e9);
    p.fail = 0.02;
    real_t s[6] = {}, ep = 0, failed = 0, lat = -nu * 1e-3;
    real_t ep_at_failure = -1.0;
    for (int k = 0; k < 60 && failed == 0; ++k)
    {
        j2_uniaxial(p, 1e-3, 1.0, s, ep, failed, lat);
        if (failed != 0 && ep_at_failure < 0)
            ep_at_failure = ep;
    }
    std::printf("failed at eps_p = %.5f (FAIL = 0.02, steps of 0.1 %% strain)\n", ep_at_failure);
    ASSERT_NE(failed, 0.0);
    EXPECT_GE(ep_at_failure, 0.02);
    EXPECT_LT(ep_at_failure, 0.02 + 1e-3); // within one step's plastic increment
    // a failed point carries neither deviatoric stress nor tension
    const real_t d[6] = {1e-3, 0, 0, 5e-4, 0, 0}, w[3] = {0, 0, 0};
    j2_update(p, d, w, 1.0, s, ep, failed);
    EXPECT_EQ(von_mises(s), 0.0);
    EXPECT_LE(s[0], 0.0);
}

TEST(EquationOfState, GruneisenAndLinear)
{
    // 4340 steel (Steinberg): c0 4578 m/s, s 1.33, gamma0 1.67, a 0.43
    Eos g;
    g.kind = Eos::Kind::Gruneisen;
    g.rho0 = 7850;
    g.c0 = 4578;
    g.s = 1.33;
    g.gamma0 = 1.67;
    g.a = 0.43;
    const real_t k0 = g.rho0 * g.c0 * g.c0;
    // small compression: the bulk modulus is rho0 c0^2
    const real_t mu_small = 1e-7;
    EXPECT_NEAR(g.pressure(-std::log1p(mu_small), 0.0) / mu_small, k0, 1e-5 * k0);
    // mu = 0.1, E = 0 and E = 1e9 J/m^3, against the formula
    const real_t mu = 0.1, ev = -std::log(1.0 + mu);
    const real_t p0 = k0 * mu * (1 + (1 - 0.5 * 1.67) * mu - 0.5 * 0.43 * mu * mu) / std::pow(1 - 0.33 * mu, 2);
    EXPECT_NEAR(g.pressure(ev, 0.0), p0, 1e-12 * p0);
    EXPECT_NEAR(g.pressure(ev, 1e9) - g.pressure(ev, 0.0), (1.67 + 0.43 * mu) * 1e9, 1e-6 * 1e9);
    // tension: linear in mu
    EXPECT_NEAR(g.pressure(-std::log(0.99), 0.0), k0 * (-0.01), 1e-9 * k0);

    // J2 + linear EOS is the incremental bulk response: hydrostatic compression gives -K ln(V/V0)
    J2Params p = J2Params::bilinear(el, E, 400e6, 2e9);
    J2Params pl = p;
    pl.eos.kind = Eos::Kind::Linear;
    pl.eos.bulk = el.bulk_modulus();
    real_t s1[6] = {}, s2[6] = {}, ep1 = 0, ep2 = 0, f1 = 0, f2 = 0, evv = 0, en = 0;
    const real_t d[6] = {-1e-4, -1e-4, -1e-4, 0, 0, 0}, w[3] = {0, 0, 0}; // to ln(V/V0) = -0.03
    for (int k = 0; k < 100; ++k)
    {
        j2_update(p, d, w, 1.0, s1, ep1, f1);
        j2_update(pl, d, w, 1.0, s2, ep2, f2, &evv, &en);
    }
    EXPECT_NEAR(s2[0], s1[0], 1e-12 * std::abs(s1[0]));
    EXPECT_NEAR(-s2[0], -el.bulk_modulus() * evv, 1e-12 * std::abs(s1[0]));
    // with Gruneisen the same path follows the EOS at the accumulated energy
    J2Params pg = p;
    pg.eos = g;
    real_t s3[6] = {}, ep3 = 0, f3 = 0, ev3 = 0, en3 = 0;
    for (int k = 0; k < 100; ++k)
        j2_update(pg, d, w, 1.0, s3, ep3, f3, &ev3, &en3);
    std::printf("hydrostatic ln(V/V0) = %.3f: linear EOS p = %.4e Pa, Gruneisen p = %.4e Pa, E = %.4e J/m^3\n", ev3,
                -s2[0], -s3[0], en3);
    EXPECT_GT(en3, 0.0);
    // the last step's energy predictor lags by one step: agreement to the step's energy change
    EXPECT_NEAR(-s3[0], g.pressure(ev3, en3), 1e-3 * std::abs(s3[0]));
}

TEST(J2Plasticity, ElasticLanesAgreeWithTheUpdate)
{
    // 8 points of a piecewise J2 block (some yielded before, one failed) on random rates and
    // spins, scaled so that about half the lanes stay elastic: the lanes j2_elastic_lanes takes
    // must carry update()'s stress to round-off (the same operations, some fused differently by
    // the compiler in the vectorized loop: each of the ~20 roundings of a component is at most
    // an ulp of the lane's largest stress, so 32 ulp bounds it) and its trial history exactly,
    // the others must be left as they were and be the yielding (or failed) ones
    PlasticPoints pp;
    pp.kind = PlasticPoints::Kind::J2;
    pp.params.elastic = el;
    pp.params.curve = {{0.0, 792e6}, {0.01, 946e6}, {0.05, 1026e6}, {1.0, 1302e6}};
    constexpr int W = 8;
    pp.resize(W);
    std::mt19937 gen(11);
    std::uniform_real_distribution<real_t> u(-1.0, 1.0);
    int taken = 0, left = 0;
    real_t worst_ulp = 0.0;
    for (int round = 0; round < 400; ++round)
    {
        const int nl = round % 5 == 0 ? 5 : W; // partial batches too
        std::size_t pt[W];
        real_t d[6][W], w[3][W], s[6][W], s0[6][W];
        for (int l = 0; l < W; ++l)
        {
            pt[l] = static_cast<std::size_t>(l < nl ? l : 0);
            pp.eps_p[l] = l % 3 == 0 ? 0.0 : 0.02 * (0.5 + 0.5 * u(gen));
            pp.failed[l] = l == 6 ? 1.0 : 0.0;
            for (int k = 0; k < 6; ++k)
                s0[k][l] = s[k][l] = 500e6 * u(gen);
            for (int k = 0; k < 6; ++k)
                d[k][l] = 1e3 * u(gen) * (round % 2 ? 1.0 : 1e-3);
            for (int k = 0; k < 3; ++k)
                w[k][l] = 1e3 * u(gen);
        }
        bool elastic[W];
        const real_t dt = 1e-6;
        pp.j2_elastic_lanes<W>(pt, nl, d, w, dt, s, elastic);
        for (int l = 0; l < nl; ++l)
        {
            const real_t dl[6] = {d[0][l], d[1][l], d[2][l], d[3][l], d[4][l], d[5][l]};
            const real_t wl[3] = {w[0][l], w[1][l], w[2][l]};
            real_t ref[6] = {s0[0][l], s0[1][l], s0[2][l], s0[3][l], s0[4][l], s0[5][l]};
            PlasticPoints one = pp;
            one.eps_p_trial[l] = -1.0;
            one.update(static_cast<std::size_t>(l), dl, wl, dt, ref);
            if (elastic[l])
            {
                ++taken;
                real_t scale = 0.0;
                for (int k = 0; k < 6; ++k)
                    scale = std::max({scale, std::abs(ref[k]), std::abs(s0[k][l])});
                const real_t ulp = std::numeric_limits<real_t>::epsilon() * scale;
                for (int k = 0; k < 6; ++k)
                {
                    worst_ulp = std::max(worst_ulp, std::abs(s[k][l] - ref[k]) / ulp);
                    ASSERT_LE(std::abs(s[k][l] - ref[k]), 32 * ulp) << "lane " << l << " component " << k;
                }
                EXPECT_EQ(pp.eps_p_trial[l], pp.eps_p[l]);
                EXPECT_EQ(one.eps_p_trial[l], pp.eps_p[l]); // update() found it elastic too
                EXPECT_EQ(pp.failed_trial[l], pp.failed[l]);
            }
            else
            {
                ++left;
                for (int k = 0; k < 6; ++k)
                    ASSERT_EQ(s[k][l], s0[k][l]);
                // yielding or failed: update() moved the plastic strain or zeroed the deviator
                EXPECT_TRUE(one.eps_p_trial[l] > pp.eps_p[l] || pp.failed[l] != 0.0) << "lane " << l;
            }
        }
    }
    std::printf("%d lanes taken elastic (largest difference from update() %.1f ulp of the lane's largest "
                "stress), %d left to update()\n",
                taken, worst_ulp, left);
    EXPECT_GT(taken, 500);
    EXPECT_GT(left, 500);
    // with a rate effect, at dt = 0 or with an EOS no lane is taken
    PlasticPoints rate = pp;
    rate.params.cs_c = 40.0;
    rate.params.cs_p = 5.0;
    std::size_t pt[W] = {0, 1, 2, 3, 4, 5, 6, 7};
    real_t d[6][W] = {}, w[3][W] = {}, s[6][W] = {};
    bool elastic[W];
    rate.j2_elastic_lanes<W>(pt, W, d, w, 1e-6, s, elastic);
    EXPECT_EQ(std::count(elastic, elastic + W, true), 0);
    pp.j2_elastic_lanes<W>(pt, W, d, w, 0.0, s, elastic);
    EXPECT_EQ(std::count(elastic, elastic + W, true), 0);
    pp.j2_elastic_lanes<W>(pt, W, d, w, 1e-6, s, elastic);
    EXPECT_EQ(std::count(elastic, elastic + W, true), W - 1); // all but the failed point
}
