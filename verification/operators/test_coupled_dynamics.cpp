// A coupled FE | RK part in explicit dynamics: the uniaxial-strain wave of test_uniaxial_wave
// (steel, c_p = 5856.4 m/s, plateau -rho c_p v = -459.7 MPa) crossing from a fem-nodal half into
// an RK half through a transition layer. The plateau holds on both sides, the interface
// reflects little (the FE side is compared with an all-FE run of the same mesh, which has no
// interface), and a free coupled column conserves momentum.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "../support.hpp"
#include "rkfem/approximation/coupling/coupled_shapes.hpp"
#include "rkfem/run/simulation.hpp"
#include "rkfem/time/central_difference.hpp"

using namespace rkfem;

namespace
{
const char* deck = R"(
title: wave through an FE-RK interface
time: {end: 40 us}
parts:
  column:
    generator: {type: box, size: [1 mm, 1 mm, 300 mm], divisions: [1, 1, 300]}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: fem-nodal
    regions:
      - {formulation: rkpm, select: {type: box, min: [-1 mm, -1 mm, 150 mm], max: [2 mm, 2 mm, 301 mm]}}
node_sets:
  all: {select: {type: named, name: all}}
  end: {select: {type: named, name: bottom}}
boundary_conditions:
  - {node_set: all, fixed: [x, y]}
  - {node_set: end, velocity: {z: 10 m/s}}
)";

struct Wave
{
    std::vector<real_t> szz; ///< per element
    real_t balance = 0.0;    ///< worst balance error after the start-up transient
};

Wave run_wave(const std::vector<std::string>& overrides)
{
    Model m = test::model_from(deck, overrides);
    const real_t c = 5856.4, h = 1e-3;
    Wave w;
    RunOptions opt;
    opt.progress = false;
    const RunSummary s = run_simulation(m, opt,
                                        [&](const Model& mm, real_t t, real_t, std::int64_t)
                                        {
                                            if (t > 20 * h / c)
                                                w.balance = std::max(w.balance, mm.energy.balance_error());
                                        });
    EXPECT_EQ(s.status, "completed") << s.message;
    for (index_t e = 0; e < m.blocks[0].n_elements(); ++e)
        w.szz.push_back(m.element_stress(0, e)[ZZ]);
    return w;
}
} // namespace

TEST(CoupledWave, CrossesTheInterfaceWithItsPlateauAndLittleReflection)
{
    const real_t plateau = -7850 * 5856.4 * 10.0; // -459.7 MPa
    const Wave fe = run_wave({"parts.column.regions=~"});
    for (const char* transition : {"mixed", "ramp"})
    {
        const Wave cw = run_wave({std::string("parts.column.transition=") + transition});
        // the front is at c t = 234 mm: plateau on the FE side (20-120 mm) and the RK side
        // (170-210 mm, behind the transmitted front)
        real_t fe_err = 0.0, rk_err = 0.0, reflected = 0.0;
        for (index_t e = 20; e < 120; ++e)
            fe_err = std::max(fe_err, std::abs(cw.szz[e] / plateau - 1));
        for (index_t e = 170; e < 210; ++e)
            rk_err = std::max(rk_err, std::abs(cw.szz[e] / plateau - 1));
        // the reflection from 150 mm has travelled back to about 66 mm by 40 us: compare the FE
        // side with the all-FE run, which has no interface
        for (index_t e = 70; e < 145; ++e)
            reflected = std::max(reflected, std::abs(cw.szz[e] - fe.szz[e]) / std::abs(plateau));
        std::printf("%s: plateau error FE side %.2e, RK side %.2e; reflected wave %.2e of the incident; "
                    "balance error %.2e (all-FE run %.2e)\n",
                    transition, fe_err, rk_err, reflected, cw.balance, fe.balance);
        EXPECT_LT(fe_err, 0.02);
        EXPECT_LT(rk_err, 0.02);
        EXPECT_LT(cw.balance, 0.005);
        if (std::string(transition) == "mixed")
            EXPECT_LT(reflected, 0.01);
    }
}

TEST(CoupledWave, FreeColumnConservesMomentum)
{
    // no conditions, a velocity field that deforms the column: the internal forces sum to zero
    // (the smoothed gradients of every point sum to zero), so the momentum of the unknowns
    // sum_I m_I v_I stays what it was
    for (const char* transition : {"mixed", "ramp"})
    {
        Model m = test::model_from(deck, {"boundary_conditions=~", std::string("parts.column.transition=") + transition,
                                          "parts.column.generator.divisions=[3, 3, 40]",
                                          "parts.column.generator.size=[3 mm, 3 mm, 40 mm]",
                                          "parts.column.regions.0.select.min=[-1 mm, -1 mm, 20 mm]",
                                          "parts.column.regions.0.select.max=[4 mm, 4 mm, 41 mm]"});
        for (index_t i = 0; i < m.nodes.size(); ++i)
        {
            const real_t z = m.nodes.x0[3 * i + 2];
            m.nodes.v[3 * i] = 2.0 * std::sin(80.0 * z);
            m.nodes.v[3 * i + 2] = 10.0 * std::cos(150.0 * z) + 3.0;
        }
        auto momentum = [&]
        {
            Vec3 p = Vec3::Zero();
            for (index_t i = 0; i < m.nodes.size(); ++i)
                p += m.nodes.mass[i] * Vec3(m.nodes.v[3 * i], m.nodes.v[3 * i + 1], m.nodes.v[3 * i + 2]);
            return p;
        };
        const Vec3 p0 = momentum();
        real_t mv = 0.0; // scale: sum m |v|
        for (index_t i = 0; i < m.nodes.size(); ++i)
            mv += m.nodes.mass[i] * std::sqrt(std::pow(m.nodes.v[3 * i], 2) + std::pow(m.nodes.v[3 * i + 2], 2));
        CentralDifference cd;
        const TimeSpec ts = m.deck().time;
        StepReport r = cd.initialize(m, 0.0);
        real_t t = 0.0, worst = 0.0, force = 0.0;
        for (int k = 1; k <= 400; ++k)
        {
            r = cd.step(m, t, next_time_step(ts, t, r.dt_stable), k);
            t = r.t;
            worst = std::max(worst, (momentum() - p0).norm() / mv);
            for (index_t j = 0; j < 3 * m.nodes.size(); ++j)
                force = std::max(force, std::abs(m.nodes.f_int[j]));
        }
        std::printf("%s: free coupled column, 400 steps: |p - p0| / sum m|v| = %.2e (largest nodal force %.2e N)\n",
                    transition, worst, force);
        EXPECT_GT(force, 1.0);
        EXPECT_LT(worst, 1e-12);
    }
}
