// Continuous surface cap model (MAT_159 analog): Murray's generated parameters at f'c = 30 MPa,
// the Rubin scaling on its three meridians, the cap function, the hydrostatic path on the cap's
// compaction law, the yield condition after every return, the fracture energy dissipated in
// tension and compression for two crack-band lengths, the Duvaut-Lions overstress, monotone
// damage and non-negative plastic work, objectivity under a rigid rotation.
#include <gtest/gtest.h>

#include <cstdio>
#include <numbers>

#include "rkfem/analysis/material_point.hpp"
#include "rkfem/config/deck.hpp"
#include "rkfem/materials/cscm_concrete.hpp"

using namespace rkfem;

namespace
{
constexpr real_t MPa = 1e6;
constexpr real_t pi = std::numbers::pi;

MaterialPointDeck cscm_deck(const std::string& type, real_t strain, int steps = 4000, real_t length = 0.0)
{
    MaterialPointDeck d;
    d.material.model = "cscm";
    d.material.rho = 2400;
    d.material.fc = 30 * MPa;
    d.material.nu = 0.2;
    d.material.E = 21.5e9 * std::cbrt(3.0);
    d.load_path.type = type;
    d.load_path.strain = strain;
    d.load_path.rate = 1e-5;
    d.load_path.steps = steps;
    d.load_path.length = length;
    return d;
}

const CscmModel& model30()
{
    static const CscmModel m = CscmModel::from_fc(30 * MPa, 2400);
    return m;
}

/// Dissipated work density after the peak of the axial stress, int sigma d eps (trapezoids).
real_t post_peak_work(const std::vector<MaterialPointRecord>& h)
{
    std::size_t ipk = 0;
    for (std::size_t k = 0; k < h.size(); ++k)
        if (std::abs(h[k].stress[0]) > std::abs(h[ipk].stress[0]))
            ipk = k;
    real_t g = 0.0;
    for (std::size_t k = ipk + 1; k < h.size(); ++k)
        g += 0.5 * (h[k].stress[0] + h[k - 1].stress[0]) * (h[k].strain[0] - h[k - 1].strain[0]);
    return g;
}
} // namespace

TEST(Cscm, GeneratedParametersAt30MPa)
{
    // Murray's fits (materials.md section 3.2) evaluated by hand at f'c = 30 MPa
    const CscmModel& m = model30();
    EXPECT_NEAR(m.alpha / MPa, -0.003 * 900 + 0.3169747 * 30 + 7.7047, 1e-12); // 14.513941
    EXPECT_NEAR(m.theta, 1.3216e-5 * 900 + 2.3548e-3 * 30 + 0.2140058, 1e-14); // 0.2965442
    EXPECT_NEAR(m.lambda / MPa, 10.5, 1e-12);
    EXPECT_NEAR(m.beta * MPa, 1.929e-2, 1e-15);
    EXPECT_NEAR(m.X0 / MPa, 8.769178e-3 * 900 - 7.3302306e-2 * 30 + 84.85, 1e-11); // 90.54319
    EXPECT_NEAR(m.theta1 * MPa, -4.0856e-7 * 900 - 1.2132e-6 * 30 + 1.5593e-3, 1e-15);
    EXPECT_NEAR(m.beta2 * MPa, -1.9972e-5 * 900 + 2.2655e-4 * 30 + 8.2748e-2, 1e-15);
    EXPECT_NEAR(m.D2 * MPa * MPa, 3.49e-7, 1e-20);
    // kappa0 puts the initial cap at X0; Ff vanishes at the apex
    EXPECT_NEAR(m.cap_X(m.kappa0), m.X0, 1e-9 * m.X0);
    EXPECT_NEAR(m.Ff(m.p_apex), 0.0, 1e-6);
    std::printf("f'c 30 MPa: kappa0 %.4f MPa, apex I1 %.4f MPa, fcu %.4f MPa (%.4f f'c), ftu %.4f MPa, E %.1f GPa\n",
                m.kappa0 / MPa, m.p_apex / MPa, m.fcu / MPa, m.fcu / m.fc, m.ftu / MPa, m.E / 1e9);
    // Q1, Q2 reach 1/sqrt3 and 1/2 at I1 = 0 (continuous with the tension branch)
    EXPECT_NEAR(m.Q1(0.0), 1.0 / std::sqrt(3.0), 1e-5);
    EXPECT_NEAR(m.Q2(0.0), 0.5, 1e-12);
}

TEST(Cscm, RubinScalingOnTheThreeMeridians)
{
    const CscmModel& m = model30();
    for (real_t P : {-5 * MPa, 0.0, 20 * MPa, 50 * MPa, 150 * MPa})
    {
        EXPECT_NEAR(m.rubin(P, pi / 6), 1.0, 1e-12) << P;      // TXC
        EXPECT_NEAR(m.rubin(P, 0.0), m.Q1(P), 1e-12) << P;     // TOR
        EXPECT_NEAR(m.rubin(P, -pi / 6), m.Q2(P), 1e-12) << P; // TXE
        // monotone between the meridians
        real_t prev = m.rubin(P, -pi / 6);
        for (int k = 1; k <= 20; ++k)
        {
            const real_t r = m.rubin(P, -pi / 6 + k * pi / 60);
            EXPECT_GE(r, prev - 1e-14);
            prev = r;
        }
    }
}

TEST(Cscm, ShearSurfaceAndCapValues)
{
    const CscmModel& m = model30();
    // shear surface against the formula at stated pressures
    for (real_t P : {0.0, 30 * MPa, 100 * MPa})
        EXPECT_NEAR(m.Ff(P), m.alpha - m.lambda * std::exp(-m.beta * P) + m.theta * P, 1e-9);
    EXPECT_NEAR(m.Ff(0.0) / MPa, 14.513941 - 10.5, 1e-9);
    // cap: 1 up to L, 0 at X, the ellipse in between; X grows with the compaction law
    const real_t L = m.kappa0, X = m.X0;
    EXPECT_EQ(m.Fc(0.5 * L, m.kappa0), 1.0);
    EXPECT_NEAR(m.Fc(L, m.kappa0), 1.0, 1e-15);
    EXPECT_NEAR(m.Fc(X, m.kappa0), 0.0, 1e-12);
    EXPECT_NEAR(m.Fc(0.5 * (L + X), m.kappa0), 0.75, 1e-12);
    for (real_t evp : {0.001, 0.01, 0.04})
    {
        const real_t Xe = m.X_of_compaction(evp);
        EXPECT_NEAR(m.compaction_of_X(Xe), evp, 1e-14);
        EXPECT_NEAR(m.cap_X(m.kappa_of_X(Xe)), Xe, 1e-9 * Xe);
    }
    // uniaxial strengths lie on the surface
    EXPECT_NEAR(m.yield(m.fcu, m.fcu * m.fcu / 3.0, pi / 6, m.kappa0) / (m.fc * m.fc), 0.0, 1e-12);
    EXPECT_NEAR(m.yield(-m.ftu, m.ftu * m.ftu / 3.0, -pi / 6, m.kappa0) / (m.fc * m.fc), 0.0, 1e-12);
}

TEST(Cscm, HydrostaticPathFollowsTheCap)
{
    // I1 / (3K) + W (1 - exp(-D1 (I1 - X0) - D2 (I1 - X0)^2)) = volumetric strain, once I1 > X0
    const auto h = run_material_point(cscm_deck("hydrostatic", -0.04, 2000));
    const CscmModel& m = model30();
    real_t worst = 0.0, I1_end = 0.0;
    for (const auto& r : h)
    {
        const real_t I1 = -(r.stress[0] + r.stress[1] + r.stress[2]);
        const real_t ev = -(r.strain[0] + r.strain[1] + r.strain[2]);
        const real_t evp = I1 > m.X0 ? m.compaction_of_X(I1) : 0.0;
        worst = std::max(worst, std::abs(I1 / (3.0 * m.bulk) + evp - ev));
        I1_end = I1;
        EXPECT_LT(r.failed, 1e-12); // no damage under hydrostatic compression (d_max = 0)
    }
    std::printf("hydrostatic to 4%% volumetric strain: I1 %.1f MPa; worst strain error %.2e\n", I1_end / MPa, worst);
    EXPECT_GT(I1_end, 3.0 * m.X0);
    EXPECT_LT(worst, 1e-12);
}

TEST(Cscm, ReturnSatisfiesTheYieldCondition)
{
    // from a stressed state, strain increments in many directions: after each update the
    // undamaged stress satisfies f <= 0 to 1e-8 J2 (the return's tolerance: the Lode angle of a
    // state on the compressive meridian, a corner of Rubin's section, is known to ~1e-8 rad)
    const CscmModel& m = model30();
    real_t worst = 0.0;
    int plastic = 0;
    for (int k = 0; k < 200; ++k)
    {
        CscmState st;
        real_t s[6];
        const real_t w[3] = {0, 0, 0};
        const real_t pre[6] = {-1.0, 0.2, 0.2, 0, 0, 0}; // uniaxial compression to ~ 0.8 fc
        cscm_update(m, pre, w, 7e-4, s, st);
        real_t d[6];
        for (int c = 0; c < 6; ++c)
            d[c] = std::sin(1.7 * k + 2.3 * c) * (c < 3 ? 1.0 : 0.5);
        const real_t dt = 2e-4 * (1 + k % 7);
        cscm_update(m, d, w, dt, s, st);
        const real_t P = -(st.svp[0] + st.svp[1] + st.svp[2]);
        real_t dv[6];
        for (int c = 0; c < 6; ++c)
            dv[c] = st.svp[c] + (c < 3 ? P / 3.0 : 0.0);
        const real_t J2 =
            0.5 * (dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]) + dv[3] * dv[3] + dv[4] * dv[4] + dv[5] * dv[5];
        real_t bh = pi / 6;
        if (J2 > 0)
        {
            const real_t J3 = dv[0] * (dv[1] * dv[2] - dv[4] * dv[4]) - dv[3] * (dv[3] * dv[2] - dv[4] * dv[5]) +
                              dv[5] * (dv[3] * dv[4] - dv[1] * dv[5]);
            bh = std::asin(std::clamp(-1.5 * std::sqrt(3.0) * J3 / std::pow(J2, 1.5), -1.0, 1.0)) / 3.0;
        }
        const real_t kap = std::isnan(st.kappa) ? m.kappa0 : st.kappa;
        worst = std::max(worst, m.yield(P, J2, bh, kap) / std::max(J2, 1e-6 * m.fc * m.fc));
        plastic += st.eps_p > 0;
    }
    std::printf("%d of 200 updates plastic; worst f / J2 after return %.2e\n", plastic, worst);
    EXPECT_GT(plastic, 50);
    EXPECT_LT(worst, 1e-8);
}

TEST(Cscm, SofteningDissipatesTheFractureEnergyOverTheCrackBand)
{
    const CscmModel& m = model30();
    for (real_t h : {0.05, 0.2})
    {
        // tension: the post-peak work times h is G_ft (perfectly plastic at ftu, exact closed form)
        const auto ut = run_material_point(cscm_deck("uniaxial-stress", 0.01, 20000, h));
        const real_t gt = post_peak_work(ut) * h;
        // compression: G_fc, with the cap's slight hardening after the peak
        const auto uc = run_material_point(cscm_deck("uniaxial-stress", -0.12, 20000, h));
        const real_t gc = post_peak_work(uc) * h; // (-sigma)(-d eps)
        std::printf(
            "h %.0f mm: tension %.2f J/m^2 (G_ft %.2f, %+.3f %%), compression %.1f J/m^2 (G_fc %.1f, %+.2f %%)\n",
            h * 1e3, gt, m.Gft, 100 * (gt / m.Gft - 1), gc, m.Gfc, 100 * (gc / m.Gfc - 1));
        // the closed forms assume a perfectly plastic post-peak: exact in tension (the state stays
        // on the shear surface), within the cap's small hardening in compression
        EXPECT_NEAR(gt / m.Gft, 1.0, 1e-3) << h;
        EXPECT_NEAR(gc / m.Gfc, 1.0, 5e-3) << h;
        // damage monotone and plastic work never negative
        for (const auto* hist : {&ut, &uc})
            for (std::size_t k = 1; k < hist->size(); ++k)
            {
                EXPECT_GE((*hist)[k].failed, (*hist)[k - 1].failed);
                EXPECT_GE((*hist)[k].work, (*hist)[k - 1].work);
            }
    }
}

TEST(Cscm, DuvautLionsOverstressInHydrostaticTension)
{
    // equal tensile strain rates e past the apex, rate effects on: the inviscid state sits at the
    // apex; the viscoplastic mean stress exceeds it by the Duvaut-Lions steady state K (3 e) eta,
    // eta = eta0t / rate^Nt with rate = sqrt(2/3 D:D) = sqrt(2) e (below the OVERT cap)
    CscmModel m = model30();
    m.rate_effects = true;
    const CscmModel& inviscid = model30();
    const real_t e = 1.0, rate = std::sqrt(2.0) * e;
    const real_t eta = m.eta0t / std::pow(rate, m.nt);
    const real_t dt = 1e-6;
    CscmState a, b;
    real_t s[6];
    const real_t w[3] = {0, 0, 0};
    const real_t d[6] = {e, e, e, 0, 0, 0};
    for (int k = 0; k < 4000; ++k)
    {
        cscm_update(m, d, w, dt, s, a);
        cscm_update(inviscid, d, w, dt, s, b);
    }
    const real_t mean_a = (a.svp[0] + a.svp[1] + a.svp[2]) / 3.0, mean_b = (b.svp[0] + b.svp[1] + b.svp[2]) / 3.0;
    const real_t over = mean_a - mean_b, expected = m.bulk * 3.0 * e * eta;
    std::printf("mean-stress overstress %.5f MPa, K (3e) eta = %.5f MPa (eta %.3e s); inviscid at the apex: %.3e\n",
                over / MPa, expected / MPa, eta, (-3.0 * mean_b - inviscid.p_apex) / MPa);
    EXPECT_NEAR(-3.0 * mean_b, inviscid.p_apex, 1e-9 * MPa);
    EXPECT_LT(m.E * rate * eta, m.overt);
    EXPECT_NEAR(over / expected, 1.0, 1e-9);
}

TEST(Cscm, RigidRotationKeepsInvariants)
{
    auto d = cscm_deck("rotation", -0.0015, 400);
    d.load_path.angle = pi / 3;
    const auto h = run_material_point(d);
    const auto& a = h[400];
    const auto& b = h.back();
    auto inv = [](const MaterialPointRecord& r)
    {
        const real_t* s = r.stress;
        const real_t I1 = s[0] + s[1] + s[2];
        const real_t J2 =
            (s[0] * s[0] + s[1] * s[1] + s[2] * s[2] - I1 * I1 / 3.0) / 2.0 + s[3] * s[3] + s[4] * s[4] + s[5] * s[5];
        return std::pair{I1, J2};
    };
    const auto [i1a, j2a] = inv(a);
    const auto [i1b, j2b] = inv(b);
    std::printf("eps_p %.12e -> %.12e, d %.3e -> %.3e\n", a.plastic_strain, b.plastic_strain, a.failed, b.failed);
    EXPECT_GT(a.plastic_strain, 0.0); // the rotation starts from a yielded state
    EXPECT_NEAR(i1b, i1a, 1e-10 * std::abs(i1a));
    EXPECT_NEAR(j2b, j2a, 1e-10 * j2a);
    EXPECT_EQ(b.failed, a.failed);
}

TEST(Cscm, Dilogarithm)
{
    EXPECT_NEAR(dilog(-1.0), -pi * pi / 12, 1e-14);
    EXPECT_NEAR(dilog(0.5), pi * pi / 12 - 0.5 * std::log(2.0) * std::log(2.0), 1e-14);
    EXPECT_NEAR(dilog(1.0), pi * pi / 6, 1e-14);
    // inversion: Li2(-x) + Li2(-1/x) = -pi^2/6 - ln^2(x)/2 checked through the series branch
    const real_t x = 0.3;
    EXPECT_NEAR(dilog(-1.0 / x) + dilog(-x), -pi * pi / 6 - 0.5 * std::log(x) * std::log(x), 1e-13);
    // -Li2(-B) = int_0^inf t B e^-t / (1 + B e^-t) dt at B = 100 (midpoint rule, 2e5 cells)
    real_t integral = 0.0;
    const real_t B = 100.0, h = 60.0 / 200000;
    for (int k = 0; k < 200000; ++k)
    {
        const real_t t = (k + 0.5) * h;
        integral += t * B * std::exp(-t) / (1.0 + B * std::exp(-t)) * h;
    }
    EXPECT_NEAR(-dilog(-B), integral, 1e-8 * integral);
}
