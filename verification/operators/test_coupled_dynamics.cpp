// A coupled FE | RK part in explicit dynamics: the uniaxial-strain wave of test_uniaxial_wave
// (steel, c_p = 5856.4 m/s, plateau -rho c_p v = -459.7 MPa) crossing from a fem-nodal half into
// an RK half through a transition layer. The plateau holds on both sides, the interface
// reflects little (the FE side is compared with an all-FE run of the same mesh, which has no
// interface), and a free coupled column conserves momentum.
#include <gtest/gtest.h>

#include <array>
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
    const test::RunWithBalance r = test::run_with_balance(m, 20 * h / c);
    EXPECT_EQ(r.summary.status, "completed") << r.summary.message;
    w.balance = r.balance;
    for (index_t e = 0; e < m.meshes[0].n_elements(); ++e)
        w.szz.push_back(m.element_stress(0, e)[ZZ]);
    return w;
}
/// At 40 us the front is at c t = 234 mm: the plateau's largest relative error on the FE side
/// (20-120 mm) and the RK side (170-210 mm, behind the transmitted front), and the reflected
/// wave: the reflection from 150 mm has travelled back to about 66 mm, so the FE side is compared
/// with a run of the same mesh without the interface.
std::array<real_t, 3> wave_errors(const Wave& coupled, const Wave& no_interface)
{
    const real_t plateau = -7850 * 5856.4 * 10.0; // -459.7 MPa
    std::array<real_t, 3> err = {0.0, 0.0, 0.0};
    for (index_t e = 20; e < 120; ++e)
        err[0] = std::max(err[0], std::abs(coupled.szz[e] / plateau - 1));
    for (index_t e = 170; e < 210; ++e)
        err[1] = std::max(err[1], std::abs(coupled.szz[e] / plateau - 1));
    for (index_t e = 70; e < 145; ++e)
        err[2] = std::max(err[2], std::abs(coupled.szz[e] - no_interface.szz[e]) / std::abs(plateau));
    return err;
}
} // namespace

TEST(CoupledWave, CrossesTheInterfaceWithItsPlateauAndLittleReflection)
{
    const Wave fe = run_wave({"parts.column.regions=~"});
    for (const char* transition : {"mixed", "ramp"})
    {
        const Wave cw = run_wave({std::string("parts.column.transition=") + transition});
        const auto [fe_err, rk_err, reflected] = wave_errors(cw, fe);
        std::printf("%s: plateau error FE side %.2e, RK side %.2e; reflected wave %.2e of the incident; "
                    "balance error %.2e (all-FE run %.2e)\n",
                    transition, fe_err, rk_err, reflected, cw.balance, fe.balance);
        EXPECT_LT(fe_err, 0.02);
        EXPECT_LT(rk_err, 0.02);
        EXPECT_LT(cw.balance, 0.005);
        if (std::string(transition) == "mixed")
        {
            EXPECT_LT(reflected, 0.01);
        }
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
        test::deforming_column_velocity(m.nodes);
        auto momentum = [&] { return test::momentum(m.nodes); };
        const Vec3 p0 = momentum();
        const real_t mv = test::momentum_scale(m.nodes);
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

TEST(CoupledWave, FemOnePointSideCrossesTheInterfaceToo)
{
    // the FE side as 1-point hexes (viscous hourglass control) and the transition and RK
    // elements' nodes on their dual cells: the same plateau and reflection checks, against an
    // all-fem-1pt run of the same mesh
    const Wave fe = run_wave({"parts.column.regions=~", "parts.column.formulation=fem-1pt"});
    const Wave cw = run_wave({"parts.column.formulation=fem-1pt"});
    const auto [fe_err, rk_err, reflected] = wave_errors(cw, fe);
    std::printf("fem-1pt | mixed | rkpm: plateau error FE side %.2e, RK side %.2e; reflected wave %.2e; balance error "
                "%.2e (all fem-1pt %.2e)\n",
                fe_err, rk_err, reflected, cw.balance, fe.balance);
    EXPECT_LT(fe_err, 0.02);
    EXPECT_LT(rk_err, 0.02);
    EXPECT_LT(reflected, 0.01);
    EXPECT_LT(cw.balance, 0.005);
}

TEST(CoupledPatch, LinearVelocityFieldThroughAFemOnePointSide)
{
    // a linear velocity field (coefficients of particles = the field at their positions) held
    // over a few steps: uniform stress everywhere, so every FE node off the outer boundary,
    // those of the transition layer included (their forces come from the 1-point elements and
    // the dual cells), carries no force. (RK test functions of interior particles reach the
    // boundary on this small block and carry its traction: the static patch tests cover them.)
    const char* box = R"(
time: {end: 1 s}
parts:
  b:
    generator: {type: box, size: [4 mm, 4 mm, 6 mm], divisions: [4, 4, 6]}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: fem-1pt
    hourglass: {type: stiffness, coefficient: 0.05}
    bulk_viscosity: {linear: 0, quadratic: 0}
    regions:
      - {select: {type: box, min: [-1 mm, -1 mm, 3 mm], max: [5 mm, 5 mm, 7 mm]}}
)";
    for (const char* transition : {"mixed", "ramp"})
        for (const char* form : {"fem-1pt", "fem-nodal"})
        {
            Model m = test::model_from(box, {std::string("parts.b.transition=") + transition,
                                             std::string("parts.b.formulation=") + form,
                                             std::string(form) == "fem-1pt" ? "title=x" : "parts.b.hourglass=~"});
            const real_t A[3][3] = {{1.0, 0.3, -0.2}, {0.1, -0.5, 0.4}, {0.25, 0.2, 0.7}}; // 1/s
            const real_t dt = 1e-8;
            for (int step = 1; step <= 5; ++step)
            {
                test::linear_velocity_step(m.nodes, A, dt);
                m.compute_forces(step * dt, dt, step);
                m.commit();
            }
            real_t residual = 0.0, scale = 0.0;
            index_t checked = 0;
            for (index_t i = 0; i < m.nodes.size(); ++i)
            {
                const Vec3 x(m.nodes.x0[3 * i], m.nodes.x0[3 * i + 1], m.nodes.x0[3 * i + 2]);
                const bool interior = !m.carries_coefficients(i) && x[0] > 1e-7 && x[0] < 4e-3 - 1e-7 && x[1] > 1e-7 &&
                                      x[1] < 4e-3 - 1e-7 && x[2] > 1e-7 && x[2] < 6e-3 - 1e-7;
                for (int d = 0; d < 3; ++d)
                {
                    scale = std::max(scale, std::abs(m.nodes.f_int[3 * i + d]));
                    if (interior)
                        residual = std::max(residual, std::abs(m.nodes.f_int[3 * i + d]));
                }
                checked += interior;
            }
            std::printf("%s side, %s: %ld interior FE nodes, force / largest boundary force %.2e\n", form, transition,
                        static_cast<long>(checked), residual / scale);
            EXPECT_GE(checked, 2 * 3 * 3); // two interior FE layers, the second one the transition's
            EXPECT_LT(residual / scale, 1e-10) << form << ", " << transition;
        }
}
