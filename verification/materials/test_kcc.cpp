// K&C concrete point update through the material-point driver: EOS loading/unloading/reloading,
// uniaxial compression peaks at f'c and starts yielding at 0.4484 f'c, triaxial compression peaks
// follow the maximum surface (section 5a), damage lambda is monotone and the plastic work never
// negative; objectivity under a rigid rotation.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "rkfem/analysis/material_point.hpp"
#include "rkfem/config/deck.hpp"
#include "rkfem/materials/kcc_concrete.hpp"
#include "rkfem/materials/point_history.hpp"
#include "rkfem/model/material_from_deck.hpp"

using namespace rkfem;

namespace
{
constexpr real_t MPa = 1e6;

MaterialPointDeck kcc_deck(const std::string& type, real_t strain, real_t conf = 0.0, int steps = 4000)
{
    MaterialPointDeck d;
    d.material.model = "kcc";
    d.material.rho = 2400;
    d.material.fc = 45.6 * MPa;
    d.material.nu = 0.19;
    d.material.E = 4700.0 * std::sqrt(45.6) * MPa;
    d.load_path.type = type;
    d.load_path.strain = strain;
    d.load_path.rate = 1e-5;
    d.load_path.confinement = conf;
    d.load_path.steps = steps;
    return d;
}

real_t peak_compression(const std::vector<MaterialPointRecord>& h, real_t& at_strain)
{
    real_t peak = 0.0;
    for (const auto& r : h)
        if (-r.stress[0] > peak)
        {
            peak = -r.stress[0];
            at_strain = -r.strain[0];
        }
    return peak;
}
} // namespace

TEST(KccConcrete, EosLoadingUnloadingReloading)
{
    const KccModel m = KccModel::from_fc(45.6 * MPa, 2400);
    real_t ev_min = 0.0;
    for (int i = 1; i < 10; ++i)
    {
        const real_t p = m.eos(m.eos_strain[i], ev_min);
        EXPECT_NEAR(p, m.eos_pressure[i], 1e-9 * m.eos_pressure[i]) << i;
    }
    // unload from point 6 with slope K_6, reload rejoins the loading curve without ratcheting
    real_t hist = 0.0;
    m.eos(m.eos_strain[6], hist);
    const real_t back = m.eos_strain[6] + 0.002;
    EXPECT_NEAR(m.eos(back, hist), m.eos_pressure[6] - m.eos_unload[6] * 0.002, 1e-9 * m.eos_pressure[6]);
    EXPECT_NEAR(m.eos(m.eos_strain[6], hist), m.eos_pressure[6], 1e-9 * m.eos_pressure[6]);
    const real_t further = 0.5 * (m.eos_strain[6] + m.eos_strain[7]);
    EXPECT_NEAR(m.eos(further, hist), 0.5 * (m.eos_pressure[6] + m.eos_pressure[7]), 1e-9 * m.eos_pressure[7]);
}

TEST(KccConcrete, UniaxialCompressionPeaksAtFcAndYieldsAt0_4484Fc)
{
    const auto h = run_material_point(kcc_deck("uniaxial-stress", -0.004, 0.0, 2000));
    real_t at = 0.0;
    const real_t peak = peak_compression(h, at);
    // first plastic step
    real_t yield = 0.0;
    for (const auto& r : h)
        if (r.plastic_strain > 0)
        {
            yield = -r.stress[0];
            break;
        }
    bool monotone = true, work_ok = true;
    for (std::size_t k = 1; k < h.size(); ++k)
    {
        monotone = monotone && h[k].failed >= h[k - 1].failed;
        work_ok = work_ok && h[k].work >= h[k - 1].work;
    }
    std::printf("UC: peak %.3f MPa at axial strain %.3e (f'c 45.6); first yield at %.3f MPa (0.4484 f'c = %.3f); "
                "final lambda %.3e, final stress %.3f MPa\n",
                peak / MPa, at, yield / MPa, 0.4484 * 45.6, h.back().failed, -h.back().stress[0] / MPa);
    EXPECT_NEAR(peak, 45.6 * MPa, 0.02 * 45.6 * MPa);
    EXPECT_NEAR(yield, 0.4484 * 45.6 * MPa, 0.02 * 45.6 * MPa);
    EXPECT_TRUE(monotone) << "lambda must not decrease";
    EXPECT_TRUE(work_ok) << "plastic work must not decrease";
    EXPECT_LT(-h.back().stress[0], 0.5 * peak); // softened after the peak
}

TEST(KccConcrete, TriaxialCompressionPeaksFollowTheMaximumSurface)
{
    const std::pair<real_t, real_t> table[] = {{10, 101.84}, {20, 143.98}, {50, 237.84}};
    for (const auto& [pc, s1] : table)
    {
        const auto h = run_material_point(kcc_deck("triaxial", -0.02, pc * MPa, 2000));
        real_t at = 0.0;
        const real_t peak = peak_compression(h, at);
        std::printf("TXC %3.0f MPa: peak sigma_1 %.2f MPa at axial strain %.3e (table %.2f)\n", pc, peak / MPa, at, s1);
        EXPECT_NEAR(peak / MPa, s1, 0.01 * s1) << pc;
    }
}

TEST(KccConcrete, RigidRotationKeepsInvariants)
{
    const KccModel m = KccModel::from_fc(45.6 * MPa, 2400);
    KccState st;
    real_t s[6] = {};
    // load in uniaxial strain past yield, then spin
    const real_t d[6] = {-1.0, 0, 0, 0, 0, 0}, w0[3] = {0, 0, 0};
    for (int k = 0; k < 100; ++k)
        kcc_update(m, d, w0, 2e-5, s, st);
    // one still step: the dilatancy of the last loading step reaches the pressure one update later
    const real_t still[6] = {0, 0, 0, 0, 0, 0};
    kcc_update(m, still, w0, 1e-3, s, st);
    const real_t tr0 = s[0] + s[1] + s[2];
    const real_t vm0 = std::sqrt(
        0.5 * ((s[0] - s[1]) * (s[0] - s[1]) + (s[1] - s[2]) * (s[1] - s[2]) + (s[2] - s[0]) * (s[2] - s[0])) +
        3 * (s[3] * s[3] + s[4] * s[4] + s[5] * s[5]));
    const real_t dz[6] = {0, 0, 0, 0, 0, 0}, w[3] = {-1.0, 0.3, 0.2};
    for (int k = 0; k < 1000; ++k)
        kcc_update(m, dz, w, 1e-3, s, st);
    const real_t vm1 = std::sqrt(
        0.5 * ((s[0] - s[1]) * (s[0] - s[1]) + (s[1] - s[2]) * (s[1] - s[2]) + (s[2] - s[0]) * (s[2] - s[0])) +
        3 * (s[3] * s[3] + s[4] * s[4] + s[5] * s[5]));
    EXPECT_NEAR((s[0] + s[1] + s[2]) / tr0, 1.0, 1e-10);
    EXPECT_NEAR(vm1 / vm0, 1.0, 1e-10);
}

TEST(KccConcrete, PostPeakDilatancyDecaysAsEtaToTheEdrop)
{
    // a point sheared under compression (shear with some compaction) past the peak; from the same
    // state one step with edrop 0 and one with edrop 2: the damage moves alike (the dilatancy acts
    // on the pressure one step later), and the dilatant volumetric strain of the step is
    // omega eta(lambda)^edrop of the undecayed one past the peak, the same bits before it
    const KccModel m0 = KccModel::from_fc(45.6 * MPa, 2400);
    KccModel m2 = m0;
    m2.surfaces.edrop = 2.0;
    const real_t d[6] = {-0.2, 0.0, 0.0, 2.0, 0.0, 0.0}, w[3] = {0, 0, 0}, dt = 2e-6;
    real_t s[6] = {};
    KccState st;
    int before = 0, after = 0;
    for (int k = 0; k < 6000 && after < 5; ++k)
    {
        real_t s0[6], s2[6];
        std::copy(s, s + 6, s0);
        std::copy(s, s + 6, s2);
        KccState a = st, b = st;
        kcc_update(m0, d, w, dt, s0, a);
        kcc_update(m2, d, w, dt, s2, b);
        ASSERT_EQ(a.lambda, b.lambda) << k;
        const real_t dv0 = a.ev_plastic - st.ev_plastic, dv2 = b.ev_plastic - st.ev_plastic;
        const real_t eta = m0.surfaces.eta(a.lambda);
        if (dv0 > 0.0 && a.lambda <= m0.surfaces.lambda_m)
        {
            EXPECT_EQ(dv2, dv0) << "before the peak, step " << k;
            ++before;
        }
        else if (dv0 > 0.0 && eta > 0.2 && eta < 0.8)
        {
            std::printf("step %d: lambda %.3e, eta %.3f: dilatancy %.3e with edrop 2 against %.3e (ratio %.6f, eta^2 "
                        "%.6f)\n",
                        k, a.lambda, eta, dv2, dv0, dv2 / dv0, eta * eta);
            EXPECT_NEAR(dv2 / dv0, eta * eta, 1e-12) << k;
            ++after;
        }
        std::copy(s0, s0 + 6, s);
        st = a;
    }
    EXPECT_GE(before, 1);
    EXPECT_GE(after, 1);
}

TEST(KccConcrete, CrackBandScalingOfTheTensileDamage)
{
    KccModel m = KccModel::from_fc(45.6 * MPa, 2400);
    m.fracture_energy = ceb_fracture_energy(45.6 * MPa);
    std::printf("G_f (CEB-FIP, f'c 45.6 MPa, 16 mm aggregate) = %.2f J/m^2\n", m.fracture_energy);
    EXPECT_NEAR(m.fracture_energy, 0.030e3 * std::pow(5.36, 0.7), 1e-9);
    // faster tensile damage (larger scale) dissipates less work
    real_t prev = 1e300;
    for (real_t scale : {0.1, 0.3, 1.0, 3.0, 10.0})
    {
        const real_t w = kcc_tension_work(m, scale);
        std::printf("tensile damage scale %5.2f: tension work %.4e J/m^3\n", scale, w);
        EXPECT_LT(w, prev) << scale;
        prev = w;
    }
    // every crack band from 2.5 mm to 200 mm dissipates G_f (b2 alone could not below ~20 mm)
    for (real_t h : {0.0025, 0.005, 0.02, 0.05, 0.2})
    {
        const real_t s = kcc_tension_scale_for_length(m, h);
        const real_t gf = h * kcc_tension_work(m, s);
        std::printf("h = %5.1f mm: scale = %.4f, h x work = %.2f J/m^2\n", h * 1e3, s, gf);
        EXPECT_NEAR(gf, m.fracture_energy, 0.01 * m.fracture_energy) << h;
    }
}

// The crack-band calibration's uniaxial tension test is uniaxial: at every strain step the
// lateral stresses are held at zero (to 1e-9 f_t), for brittle to ductile tensile damage and with
// rate effects, whose lateral response the elastic slope alone followed so poorly that up to
// 1,804 steps kept a lateral stress of up to 16 % of f_t (a work off by up to 30 %).
// The only steps excused are jumps: a very brittle point (scale 10, a crack band of about a metre)
// drops in one step to the hydrostatic tension cutoff, and no lateral rate gives zero lateral
// stress there (the residual jumps from -0.02 f_t to +0.32 f_t); none below scale 3.
TEST(KccConcrete, TensionTestHoldsTheLateralStressAtZero)
{
    for (const bool rate : {false, true})
        for (const real_t scale : {0.03, 0.1, 0.3, 1.0, 3.0, 10.0})
        {
            KccModel m = KccModel::from_fc(35.0 * MPa, 2300);
            if (rate)
                m.rate = RateLaw::standard(m.surfaces.fc);
            const KccTensionTest t = kcc_tension_test(m, scale);
            std::printf(
                "rate effects %d, scale %5.2f: work %.5e J/m^3 over %d steps, %.2f updates per step, %d jumps\n", rate,
                scale, t.work, t.steps, static_cast<double>(t.updates) / t.steps, t.jumps);
            EXPECT_EQ(t.unheld, 0) << "lateral stress left: " << t.worst_lateral << " f_t";
            if (scale <= 3.0)
            {
                EXPECT_EQ(t.jumps, 0);
            }
            EXPECT_GT(t.steps, 50); // 50 steps to the peak
            EXPECT_EQ(t.work, kcc_tension_work(m, scale));
        }
}

TEST(KccConcrete, TabulatedCrackBandScalesHoldToTheExactSolves)
{
    // a graded mesh: 400 distinct lengths from 3 to 30 mm take the table (16 exact solves over
    // the range); each interpolated scale against its own exact solve, and the energy it
    // dissipates against G_f
    KccModel m = KccModel::from_fc(35.0 * MPa, 2400);
    m.fracture_energy = ceb_fracture_energy(35.0 * MPa);
    std::vector<real_t> h;
    for (int i = 0; i < 400; ++i)
        h.push_back(0.003 * std::pow(10.0, i / 399.0) + 1e-7 * (i % 7)); // distinct to 1 nm
    const std::vector<real_t> s = kcc_tension_scales(m, h);
    real_t worst_scale = 0.0, worst_gf = 0.0;
    for (int i = 0; i < 400; i += 79)
    {
        const real_t exact = kcc_tension_scale_for_length(m, h[static_cast<std::size_t>(i)]);
        worst_scale = std::max(worst_scale, std::abs(s[static_cast<std::size_t>(i)] / exact - 1.0));
        const real_t gf = h[static_cast<std::size_t>(i)] * kcc_tension_work(m, s[static_cast<std::size_t>(i)]);
        worst_gf = std::max(worst_gf, std::abs(gf / m.fracture_energy - 1.0));
    }
    std::printf("tabulated crack-band scales: within %.2e of the exact solves, dissipation within %.2e of G_f\n",
                worst_scale, worst_gf);
    EXPECT_LT(worst_scale, 2e-3);
    EXPECT_LT(worst_gf, 0.01); // the exact solves' own bound (CrackBandScalingOfTheTensileDamage)
    // few distinct lengths: the exact solve for each, bit for bit
    const std::vector<real_t> few = kcc_tension_scales(m, {0.01, 0.02, 0.01});
    EXPECT_EQ(few[0], kcc_tension_scale_for_length(m, 0.01));
    EXPECT_EQ(few[1], kcc_tension_scale_for_length(m, 0.02));
    EXPECT_EQ(few[2], few[0]);
    // a cache (PlasticPoints keeps one per block for its events) gives the same bits: on first
    // use it solves and keeps the lengths; asked again, it solves none and returns the same scales
    KccScaleCache solved;
    EXPECT_EQ(kcc_tension_scales(m, {0.01, 0.02, 0.01}, &solved), few);
    ASSERT_EQ(solved.size(), 2u);
    solved[0.01] = -1.0; // a marker: a lookup, not a new solve, answers the next call
    EXPECT_EQ(kcc_tension_scales(m, {0.02, 0.01}, &solved), (std::vector<real_t>{few[1], -1.0}));
    KccScaleCache graded;
    EXPECT_EQ(kcc_tension_scales(m, h, &graded), s);
    EXPECT_EQ(graded.size(), static_cast<std::size_t>(kExactLengths));
    EXPECT_EQ(kcc_tension_scales(m, h, &graded), s);
    EXPECT_EQ(graded.size(), static_cast<std::size_t>(kExactLengths));
}

TEST(KccConcrete, VolumetricDamageB3InHydrostaticTension)
{
    // equal tensile strain rates: once the pressure reaches the cutoff -f_t, lambda grows by
    // b3 d eps_v (f_d = 1 at J2 = 0, k_d = 1) and the pressure follows -f_t eta(lambda)
    auto d = kcc_deck("hydrostatic", 0.003, 0.0, 3000);
    const auto h = run_material_point(d);
    const KccParameters k = KccParameters::from_fc(45.6 * MPa);
    real_t worst_slope = 0.0, worst_p = 0.0, lambda_end = 0.0;
    int on_cutoff = 0;
    for (std::size_t n = 2; n < h.size(); ++n)
    {
        const real_t p = -(h[n].stress[0] + h[n].stress[1] + h[n].stress[2]) / 3.0;
        const real_t lam = h[n].failed, lam0 = h[n - 1].failed;
        // steps wholly past the first yield, while the cutoff is still open (eta > 0)
        if (h[n - 2].failed > 0.0 && lam0 < k.lambda_z)
        {
            ++on_cutoff;
            const real_t dev = (h[n].strain[0] + h[n].strain[1] + h[n].strain[2]) -
                               (h[n - 1].strain[0] + h[n - 1].strain[1] + h[n - 1].strain[2]);
            worst_slope = std::max(worst_slope, std::abs((lam - lam0) / dev - k.b3));
            // the cutoff of this step used lambda before the step
            const real_t eta = lam0 <= k.lambda_m ? 1.0 : k.eta(lam0);
            worst_p = std::max(worst_p, std::abs(p + k.ft * eta) / k.ft);
        }
        lambda_end = lam;
    }
    std::printf("%d steps on the cutoff; lambda %.3e at eps_v 3e-3; |d lambda / d eps_v - b3| <= %.2e; "
                "|p + f_t eta| <= %.2e f_t\n",
                on_cutoff, lambda_end, worst_slope, worst_p);
    EXPECT_GT(on_cutoff, 100);
    EXPECT_GT(lambda_end, k.lambda_z); // softened to zero tensile strength
    EXPECT_LT(worst_slope, 1e-9);
    EXPECT_LT(worst_p, 1e-9);
}

TEST(KccConcrete, GeneratedParametersCanBeOverridden)
{
    MaterialSpec ms = kcc_deck("uniaxial-stress", -0.004).material;
    ms.overrides = {{"a0", 15 * MPa}, {"b1", 1.2}, {"ft", 4 * MPa}};
    PlasticPoints pp;
    configure_points(pp, ms);
    const KccParameters& k = pp.kcc.surfaces;
    EXPECT_EQ(k.a0, 15 * MPa);
    EXPECT_EQ(k.b1, 1.2);
    EXPECT_EQ(k.ft, 4 * MPa);
    EXPECT_EQ(k.a1, KccParameters::from_fc(45.6 * MPa).a1); // the others stay generated
    // derived quantities follow the overrides: the yield hyperbola through (f_yc/3, f_yc)
    EXPECT_NEAR(k.yield_surface(k.fyc / 3.0), k.fyc, 1e-9 * k.fyc);
}

TEST(KccConcrete, DamageAndEosTablesCanBeReplaced)
{
    // a user eta(lambda) table moves lambda_m and lambda_z; uniaxial compression still peaks on
    // the maximum surface (at lambda_m); a user EOS table is followed in hydrostatic compression
    auto d = kcc_deck("uniaxial-stress", -0.006, 0.0, 3000);
    d.material.kcc_eta = {{0, 0}, {2e-5, 0.9}, {1e-4, 1.0}, {2e-4, 0.5}, {4e-4, 0.0}};
    PlasticPoints pp;
    configure_points(pp, d.material);
    EXPECT_EQ(pp.kcc.surfaces.lambda_m, 1e-4);
    EXPECT_EQ(pp.kcc.surfaces.lambda_z, 4e-4);
    EXPECT_NEAR(pp.kcc.surfaces.eta(3e-4), 0.25, 1e-15);
    const auto h = run_material_point(d);
    real_t at = 0.0;
    const real_t peak = peak_compression(h, at);
    std::printf("user eta table: UC peak %.3f MPa (f'c 45.6)\n", peak / MPa);
    EXPECT_NEAR(peak / (45.6 * MPa), 1.0, 2e-3);

    auto hyd = kcc_deck("hydrostatic", -0.02, 0.0, 2000);
    const KccModel gen = KccModel::from_fc(45.6 * MPa, 2400, 0.19, 4700.0 * std::sqrt(45.6) * MPa);
    for (int i = 0; i < 10; ++i)
    {
        hyd.material.kcc_eos_strain.push_back(gen.eos_strain[i]);
        hyd.material.kcc_eos_pressure.push_back(1.5 * gen.eos_pressure[i]);
        hyd.material.kcc_eos_unload.push_back(1.5 * gen.eos_unload[i]);
    }
    const auto hh = run_material_point(hyd);
    // at eps_v = -0.0101 (table point 3) the pressure is 1.5 x the generated one
    real_t worst = 0.0;
    for (const auto& r : hh)
    {
        const real_t ev = r.strain[0] + r.strain[1] + r.strain[2];
        if (std::abs(ev - gen.eos_strain[3]) < 1e-12)
        {
            const real_t p = -(r.stress[0] + r.stress[1] + r.stress[2]) / 3.0;
            worst = std::max(worst, std::abs(p / (1.5 * gen.eos_pressure[3]) - 1.0));
            std::printf("user EOS table: p(%.4f) = %.3f MPa (1.5 x generated %.3f)\n", ev, p / MPa,
                        gen.eos_pressure[3] / MPa);
        }
    }
    EXPECT_LT(worst, 1e-9);
}

namespace
{
/// The rate measure of the DIF (RateLaw::loading_rate, compression) between records k - 1 and k.
real_t measured_rate(const std::vector<MaterialPointRecord>& h, std::size_t k)
{
    const real_t dt = h[k].time - h[k - 1].time;
    real_t d[6];
    for (int c = 0; c < 6; ++c)
        d[c] = (h[k].strain[c] - h[k - 1].strain[c]) / dt;
    return RateLaw::loading_rate(d, false);
}
} // namespace

// Split-Hopkinson-type check at a material point: uniaxial compression at constant axial strain
// rates 1, 10^2 and 10^4 1/s. Radial scaling of the surfaces by the DIF makes the uniaxial peak
// r_f f'c (the compressive meridian, Delta sigma = 3 p: r_f Delta sigma(p / r_f) = sigma at
// sigma = r_f f'c), and the rate measure in compression is the most compressive principal rate,
// the axial one here, so the peak over the static peak must be the law's DIF at the axial rate
// within 2 %, for the built-in laws with and without their caps and for a user curve. (With the
// effective deviatoric rate as the measure, which jumps as the point dilates at the peak, the
// same check missed by 4 % at 10^2 1/s with the default law and by 16-40 % uncapped.)
TEST(KccConcrete, UniaxialCompressionPeakIsTheLawsDif)
{
    auto deck = [](real_t rate, const RateLaw& law)
    {
        MaterialPointDeck d = kcc_deck("uniaxial-stress", -0.02, 0.0, 4000);
        d.material.fc = 35 * MPa;
        d.material.E = 4700.0 * std::sqrt(35.0) * MPa;
        d.load_path.rate = rate;
        d.material.rate_law = law;
        d.material.rate_effects = law.active();
        return d;
    };
    real_t at = 0.0;
    const real_t static_peak = peak_compression(run_material_point(deck(1e-5, RateLaw{})), at);
    EXPECT_NEAR(static_peak, 35 * MPa, 0.02 * 35 * MPa);
    RateLaw open = RateLaw::standard(35 * MPa);
    open.compression_cap = open.tension_cap = 0.0;
    RateLaw curve;
    curve.kind = RateLaw::Kind::Curve;
    curve.curve = {{-1e4, 6.0}, {0.0, 1.0}, {1.0, 1.1}, {100.0, 1.6}, {1e4, 2.5}};
    const std::pair<const char*, RateLaw> laws[] = {
        {"default", RateLaw::standard(35 * MPa)}, {"uncapped", open}, {"curve", curve}};
    for (const auto& [name, law] : laws)
        for (const real_t rate : {1.0, 1e2, 1e4})
        {
            const auto h = run_material_point(deck(rate, law));
            std::size_t k_peak = 1;
            for (std::size_t k = 1; k < h.size(); ++k)
                if (-h[k].stress[0] > -h[k_peak].stress[0])
                    k_peak = k;
            const real_t measured = measured_rate(h, k_peak);
            const real_t ratio = -h[k_peak].stress[0] / static_peak;
            const real_t dif = law.dif(rate, false);
            std::printf("%-8s axial %7.0e 1/s: measured %9.3e 1/s at the peak, peak / static %.4f, law's DIF %.4f\n",
                        name, rate, measured, ratio, dif);
            EXPECT_NEAR(measured, rate, 1e-9 * rate);
            EXPECT_NEAR(ratio, dif, 0.02 * dif) << name << " at " << rate << " 1/s";
        }
}
