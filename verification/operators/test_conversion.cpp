// Evolutionary coupling (seed Table 1, feature 4): elements of a fem-nodal part turn into RK
// particles between steps (Model::convert_elements, deck key parts.*.conversion). The points and
// their state stay at the nodes, only the tables and the kinematic map change, so
//   - a linear field keeps a uniform stress through a conversion, to round-off, and the
//     particles' physical values are the field's (the new approximation reproduces it);
//   - momentum and energy carry over exactly: a free column conserves momentum to 1e-12 and
//     its energy as well as one that never converts;
//   - a tension wave that converts the column behind its front keeps its plateau
//     rho c v = 459.7 MPa within 2 % on the RK side and the energy balance of an all-FE run,
//     with central difference and ARKODE.
// fem-1pt parts (ConversionFem1pt) hand their elements' state to the points that take their
// octants: volume-weighted means, the largest damage, mass and momentum kept.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <tuple>
#include <utility>

#include "../support.hpp"
#include "rkfem/contact/kernel_contact.hpp"
#include "rkfem/operators/semi_lagrangian_block.hpp"
#include "rkfem/run/simulation.hpp"
#include "rkfem/time/central_difference.hpp"

using namespace rkfem;

namespace
{
std::vector<char> elements_above(const Model& m, real_t z)
{
    const HexBlock& b = m.meshes[0];
    std::vector<char> flags(static_cast<std::size_t>(b.n_elements()), 0);
    for (index_t e = 0; e < b.n_elements(); ++e)
    {
        real_t zc = 0.0;
        for (int a = 0; a < 8; ++a)
            zc += m.nodes.x0[3 * b.conn[8 * e + a] + 2] / 8.0;
        flags[e] = zc > z;
    }
    return flags;
}
/// A free 3 x 3 x 40 mm fem-nodal column that converts only when a test says so.
const char* free_column = R"(
time: {end: 1 s}
parts:
  column:
    generator: {type: box, size: [3 mm, 3 mm, 40 mm], divisions: [3, 3, 40]}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: fem-nodal
    conversion: {principal_strain: 10}
)";
/// A 4 x 4 x 6 mm fem-nodal box that converts only when a test says so.
const char* box = R"(
time: {end: 1 s}
parts:
  b:
    generator: {type: box, size: [4 mm, 4 mm, 6 mm], divisions: [4, 4, 6]}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: fem-nodal
    bulk_viscosity: {linear: 0, quadratic: 0}
    conversion: {principal_strain: 10}
)";
/// After steps under the linear velocity field A X on the 4 x 4 x 6 mm box: the largest force on
/// an interior node that is not a particle over the largest nodal force, and the largest error of
/// a particle's physical velocity over the largest velocity of the field.
struct LinearFieldCheck
{
    real_t residual = 0.0, velocity_error = 0.0;
    index_t interior = 0, particles = 0;
};
LinearFieldCheck check_linear_field(const Model& m, const real_t (&A)[3][3])
{
    LinearFieldCheck c;
    real_t scale = 0.0, vmax = 0.0;
    for (index_t i = 0; i < m.nodes.size(); ++i)
    {
        const Vec3 X(m.nodes.x0[3 * i], m.nodes.x0[3 * i + 1], m.nodes.x0[3 * i + 2]);
        const bool inside =
            X[0] > 1e-7 && X[0] < 4e-3 - 1e-7 && X[1] > 1e-7 && X[1] < 4e-3 - 1e-7 && X[2] > 1e-7 && X[2] < 6e-3 - 1e-7;
        for (int d = 0; d < 3; ++d)
            scale = std::max(scale, std::abs(m.nodes.f_int[3 * i + d]));
        if (inside && !m.carries_coefficients(i))
        {
            ++c.interior;
            for (int d = 0; d < 3; ++d)
                c.residual = std::max(c.residual, std::abs(m.nodes.f_int[3 * i + d]));
        }
        if (m.carries_coefficients(i))
        {
            ++c.particles;
            const Vec3 v = m.physical(m.nodes.v, i);
            for (int d = 0; d < 3; ++d)
            {
                const real_t exact = A[d][0] * X[0] + A[d][1] * X[1] + A[d][2] * X[2];
                c.velocity_error = std::max(c.velocity_error, std::abs(v[d] - exact));
                vmax = std::max(vmax, std::abs(exact));
            }
        }
    }
    c.residual /= scale;
    c.velocity_error /= vmax;
    return c;
}
} // namespace

TEST(ConversionPatch, LinearFieldKeepsItsUniformStressThroughAConversion)
{
    // a fem-nodal box under a linear velocity field; after step 3 the upper half turns RK
    // (the transition layer below it): every point's stress stays that of the run that never
    // converts, FE nodes off the boundary carry no force, and the particles' physical
    // velocities are the linear field's
    const real_t A[3][3] = {{1.0, 0.3, -0.2}, {0.1, -0.5, 0.4}, {0.25, 0.2, 0.7}}; // 1/s
    const real_t dt = 1e-8;
    for (const char* transition : {"mixed", "ramp"})
    {
        Model plain = test::model_from(box, {std::string("parts.b.transition=") + transition});
        Model conv = test::model_from(box, {std::string("parts.b.transition=") + transition});
        for (int step = 1; step <= 6; ++step)
        {
            if (step == 4)
            {
                ASSERT_EQ(conv.convert_elements(0, elements_above(conv, 3e-3)), 4 * 4 * 3);
            }
            for (Model* m : {&plain, &conv})
            {
                test::linear_velocity_step(m->nodes, A, dt);
                m->compute_forces(step * dt, dt, step);
                m->commit();
            }
        }
        ASSERT_EQ(conv.converted_elements(), 48);
        // stress of every point, against the unconverted run
        const NodalBlock &p = *plain.nodal_block(0), &c = *conv.nodal_block(0);
        real_t smax = 0.0, ds = 0.0;
        for (int k = 0; k < 6; ++k)
            for (index_t q = 0; q < p.n_points(); ++q)
            {
                const std::size_t j = k * p.stress_stride + q;
                smax = std::max(smax, std::abs(p.stress[j]));
                ds = std::max(ds, std::abs(p.stress[j] - c.stress[j]));
            }
        // interior FE nodes (the transition layer's included) carry no force; particles'
        // physical velocity is A X
        const LinearFieldCheck lf = check_linear_field(conv, A);
        std::printf("%s: stress change through the conversion %.2e of the largest, %ld interior FE nodes with force "
                    "%.2e of the largest, %ld particles with velocity error %.2e\n",
                    transition, ds / smax, static_cast<long>(lf.interior), lf.residual, static_cast<long>(lf.particles),
                    lf.velocity_error);
        EXPECT_EQ(lf.particles, 5 * 5 * 4);
        EXPECT_GE(lf.interior, 3 * 3 * 2);
        EXPECT_LT(ds / smax, 1e-10) << transition;
        EXPECT_LT(lf.residual, 1e-10) << transition;
        EXPECT_LT(lf.velocity_error, 1e-12) << transition;
        // the zones the output shows: 16 FE-only elements at the bottom, ... 48 RK
        index_t zones[3] = {0, 0, 0};
        for (index_t e = 0; e < conv.meshes[0].n_elements(); ++e)
            ++zones[conv.element_zone(0, e)];
        EXPECT_EQ(zones[2], 48);
        EXPECT_EQ(zones[1], 16); // the layer below the RK half
        EXPECT_EQ(zones[0], 32);
    }
}

namespace
{
/// What free_column_run measured: the largest |p - p0| over sum m|v|, the largest balance error
/// from step 50 on, the largest change of momentum at an event, and the elements converted and
/// reverted.
struct FreeColumnRun
{
    real_t momentum_error = 0.0, energy_error = 0.0, jump = 0.0;
    index_t converted = 0, reverted = 0;
};
/// The free column (free_column with `overrides`) with a deforming velocity field, `steps` central
/// difference steps; at each step in `at`, `event(k, m)` converts or reverts elements, the stepper
/// started again after it as the run loop does.
FreeColumnRun free_column_run(const std::vector<std::string>& overrides, int steps, const std::vector<int>& at,
                              const std::function<void(int, Model&)>& event)
{
    Model m = test::model_from(free_column, overrides);
    test::deforming_column_velocity(m.nodes);
    const Vec3 p0 = test::momentum(m.nodes);
    const real_t mv = test::momentum_scale(m.nodes);
    CentralDifference cd;
    const TimeSpec ts = m.deck().time;
    StepReport r = cd.initialize(m, 0.0);
    real_t t = 0.0;
    FreeColumnRun out;
    for (int k = 1; k <= steps; ++k)
    {
        const real_t dt = next_time_step(ts, t, r.dt_stable);
        r = cd.step(m, t, dt, k);
        t = r.t;
        if (std::find(at.begin(), at.end(), k) != at.end())
        {
            m.refresh_motion();
            const Vec3 before = test::momentum(m.nodes);
            event(k, m);
            out.jump = std::max(out.jump, (test::momentum(m.nodes) - before).norm());
            r.dt_stable = m.restart_after_event(cd, t, dt);
        }
        out.momentum_error = std::max(out.momentum_error, (test::momentum(m.nodes) - p0).norm() / mv);
        if (k >= 50)
            out.energy_error = std::max(out.energy_error, m.energy.balance_error());
    }
    out.converted = m.converted_elements();
    out.reverted = m.reverted_elements();
    return out;
}

/// free_column_run converting the column from the top in three events (steps 150, 300, 450), or
/// never: the largest momentum and balance errors
std::pair<real_t, real_t> converting_column(const std::vector<std::string>& overrides, bool convert)
{
    const FreeColumnRun run =
        free_column_run(overrides, 600, convert ? std::vector<int>{150, 300, 450} : std::vector<int>{},
                        [](int k, Model& m) {
                            EXPECT_EQ(m.convert_elements(0, elements_above(m, 40e-3 - (k / 150) * 8e-3)), 3 * 3 * 8)
                                << "event at step " << k;
                        });
    EXPECT_EQ(run.converted, convert ? 3 * 3 * 24 : 0);
    return {run.momentum_error, run.energy_error};
}

/// The column with `overrides` converting in three events keeps its momentum to 1e-12 and balances
/// within 5 % of the column that never converts.
void expect_column_conserves(const char* label, const std::vector<std::string>& overrides)
{
    const auto [p_conv, e_conv] = converting_column(overrides, true);
    const auto [p_plain, e_plain] = converting_column(overrides, false);
    std::printf("%s, 600 steps, 3 conversions: |p - p0| / sum m|v| = %.2e, balance error %.2e (never converted: "
                "%.2e, %.2e)\n",
                label, p_conv, e_conv, p_plain, e_plain);
    EXPECT_LT(p_conv, 1e-12);
    EXPECT_LT(e_conv, 1.05 * e_plain);
}
} // namespace

TEST(ConversionDynamics, FreeColumnConservesMomentumAndEnergyThroughConversions)
{
    // no conditions, no loads: a deforming velocity field; the column converts from the top
    // in three events. Momentum of the unknowns stays what it was; the energy ledger balances as
    // well as in the run that never converts
    expect_column_conserves("free column", {});
}

namespace
{
const char* wave_deck = R"(
title: tension wave converting a column behind its front
time: {end: 40 us}
parts:
  column:
    generator: {type: box, size: [1 mm, 1 mm, 300 mm], divisions: [1, 1, 300]}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: fem-nodal
    conversion: {principal_strain: 8e-4}
node_sets:
  all: {select: {type: named, name: all}}
  end: {select: {type: named, name: bottom}}
boundary_conditions:
  - {node_set: all, fixed: [x, y]}
  - {node_set: end, velocity: {z: -10 m/s}}
)";

struct Wave
{
    std::vector<real_t> szz;
    std::vector<int> zone;
    real_t balance = 0.0, balance_end = 0.0;
    index_t converted = 0;
};

Wave run_wave(const std::vector<std::string>& overrides)
{
    Model m = test::model_from(wave_deck, overrides);
    const real_t c = 5856.4, h = 1e-3;
    Wave w;
    const test::RunWithBalance r = test::run_with_balance(m, 20 * h / c);
    EXPECT_EQ(r.summary.status, "completed") << r.summary.message;
    w.balance = r.balance;
    for (index_t e = 0; e < m.meshes[0].n_elements(); ++e)
    {
        w.szz.push_back(m.element_stress(0, e)[ZZ]);
        w.zone.push_back(m.element_zone(0, e));
    }
    w.converted = m.converted_elements();
    w.balance_end = m.energy.balance_error();
    return w;
}
} // namespace

TEST(ConversionWave, TensionWaveConvertsTheColumnBehindItsFrontAndKeepsItsPlateau)
{
    // at 40 us the front is at c t = 234 mm; the plateau strain v / c = 1.7e-3 is past the
    // criterion, so the column is RK behind the front (a transition layer, then FE ahead)
    for (const char* stepper : {"central-difference", "arkode-cd"})
    {
        const Wave fe = run_wave({"parts.column.conversion=~", std::string("time.stepper=") + stepper});
        const Wave w = run_wave({std::string("time.stepper=") + stepper});
        const real_t plateau = 7850 * 5856.4 * 10.0; // 459.7 MPa
        real_t err = 0.0, diff = 0.0;
        for (index_t e = 20; e < 200; ++e)
        {
            err = std::max(err, std::abs(w.szz[e] / plateau - 1));
            diff = std::max(diff, std::abs(w.szz[e] - fe.szz[e]) / plateau);
        }
        index_t rk_behind = 0, fe_ahead = 0;
        for (index_t e = 0; e < 220; ++e)
            rk_behind += w.zone[e] == 2;
        for (index_t e = 250; e < 300; ++e)
            fe_ahead += w.zone[e] == 0;
        std::printf("%s: %ld elements converted, plateau error %.2e (all-FE run %.2e apart), balance error: largest "
                    "after 3.4 us %.2e, at the end %.2e (all-FE %.2e, %.2e)\n",
                    stepper, static_cast<long>(w.converted), err, diff, w.balance, w.balance_end, fe.balance,
                    fe.balance_end);
        EXPECT_EQ(rk_behind, 220);
        EXPECT_EQ(fe_ahead, 50);
        EXPECT_LT(err, 0.02);
        // a conversion near the driven end in the first steps adds a start-up error that decays
        // as the run goes on (0.2 % at 3.4 us); by the end the balance is the all-FE run's
        EXPECT_LT(w.balance, 0.005);
        EXPECT_LT(w.balance_end, 1.25 * fe.balance_end);
    }
}

namespace
{
/// The K&C bar converting at damage 0.5 (5 mm mesh, 20 us: conversion events along the crushed
/// end), as `formulation`: the incremental update and the whole-part rebuild give the same
/// operators, the same kinematic map and the same run.
void expect_update_matches_whole_rebuild(const char* formulation)
{
    const std::string deck = std::string(RKFEM_SOURCE_DIR) + "/studies/decks/concrete_bar_conversion.yaml";
    const std::vector<std::string> set = {"parts.bar.generator.element_size=5mm", "time.end=20us",
                                          std::string("parts.bar.formulation=") + formulation};
    auto run = [&](bool whole)
    {
        auto m = std::make_unique<Model>(Model::build(read_deck(deck, set)));
        m->set_rebuild_whole_part(whole);
        RunOptions opt;
        opt.progress = false;
        EXPECT_EQ(run_simulation(*m, opt).status, "completed");
        return m;
    };
    const auto inc = run(false), whole = run(true);
    ASSERT_GT(inc->converted_elements(), 50);
    ASSERT_EQ(inc->converted_elements(), whole->converted_elements());
    EXPECT_EQ(inc->rk_elements(0), whole->rk_elements(0));
    real_t dg = 0.0, gmax = 0.0;
    auto compare = [&](const IntegrationOperator& a, const IntegrationOperator& b)
    {
        ASSERT_EQ(a.offsets, b.offsets);
        ASSERT_EQ(a.nodes, b.nodes);
        for (std::size_t k = 0; k < a.grad.size(); ++k)
        {
            gmax = std::max(gmax, std::abs(b.grad[k]));
            dg = std::max(dg, std::abs(a.grad[k] - b.grad[k]));
        }
    };
    compare(inc->nodal_block(0)->points, whole->nodal_block(0)->points);
    compare(inc->nodal_block(0)->stabilization, whole->nodal_block(0)->stabilization);
    real_t du = 0.0, umax = 0.0, dmap = 0.0;
    for (index_t i = 0; i < inc->nodes.size(); ++i)
    {
        const Vec3 a = inc->physical(inc->nodes.u, i), b = whole->physical(whole->nodes.u, i);
        du = std::max(du, (a - b).norm());
        umax = std::max(umax, b.norm());
        EXPECT_EQ(inc->carries_coefficients(i), whole->carries_coefficients(i));
        std::vector<std::pair<index_t, real_t>> ra, rb;
        inc->kinematics.for_row(i, [&](index_t j, real_t w) { ra.emplace_back(j, w); });
        whole->kinematics.for_row(i, [&](index_t j, real_t w) { rb.emplace_back(j, w); });
        ASSERT_EQ(ra.size(), rb.size()) << "node " << i;
        for (std::size_t k = 0; k < ra.size(); ++k)
        {
            EXPECT_EQ(ra[k].first, rb[k].first);
            dmap = std::max(dmap, std::abs(ra[k].second - rb[k].second));
        }
    }
    std::printf("%s: %ld elements converted: operators differ by %.2e of the largest gradient, the map by %.2e, "
                "displacements by %.2e of the largest\n",
                formulation, static_cast<long>(inc->converted_elements()), dg / gmax, dmap, du / umax);
    EXPECT_LT(dg / gmax, 1e-13);
    EXPECT_LT(dmap, 1e-14);
    EXPECT_LT(du / umax, 1e-10);
}
} // namespace

TEST(ConversionUpdate, RebuildsOnlyWhereTheApproximationChangedWithTheWholeRebuildsOperators)
{
    expect_update_matches_whole_rebuild("fem-nodal");
}

// fem-1pt: the nodal block is a new one at each event (its points are those of the transition and
// RK elements' nodes), its rows outside the changed region taken from the old block
TEST(ConversionUpdate, Fem1ptBlockBuiltWhereTheApproximationChangedHasTheWholeRebuildsOperators)
{
    expect_update_matches_whole_rebuild("fem-1pt");
}

TEST(ConversionUpdate, Fem1ptPartKeepsOneCrackBandScaleCacheThroughItsEvents)
{
    // the converting fem-1pt K&C bar's FE side and nodal block, built again at each event, keep
    // the part's one cache of crack-band scales: each length is solved once for the part (the
    // cached scales are the solved ones bit for bit: KccConcrete.TabulatedCrackBandScales...)
    const std::string deck = std::string(RKFEM_SOURCE_DIR) + "/studies/decks/concrete_bar_conversion.yaml";
    Model m =
        Model::build(read_deck(deck, {"parts.bar.generator.element_size=5mm", "time.end=20us",
                                      "parts.bar.formulation=fem-1pt", "parts.bar.material.fracture_energy=auto"}));
    const KccScaleCache* at_start = m.nodal_block(0)->plastic.kcc_scales.get();
    ASSERT_EQ(m.fe_side(0)->block.plastic.kcc_scales.get(), at_start);
    const std::size_t solved_at_start = at_start->size();
    RunOptions opt;
    opt.progress = false;
    ASSERT_EQ(run_simulation(m, opt).status, "completed");
    ASSERT_GT(m.converted_elements(), 50);
    EXPECT_EQ(m.nodal_block(0)->plastic.kcc_scales.get(), at_start);
    EXPECT_EQ(m.fe_side(0)->block.plastic.kcc_scales.get(), at_start);
    // a box mesh: the elements' length (cube root of the volume) and the nodes' (shortest edge)
    // differ in the last bits at most; without the shared cache each event's new blocks solved theirs
    std::printf("crack-band lengths solved for the part: %zu at the start, %zu after the events\n", solved_at_start,
                at_start->size());
    EXPECT_GE(solved_at_start, 1u);
    EXPECT_LE(at_start->size(), 4u);
}

TEST(ConversionInterval, ChecksAtTheIntervalConvertInFewerEventsWithTheSameResult)
{
    // the converting K&C bar (5 mm, 30 us; steps of about 1.1 us) with the criteria checked
    // after every step and every 2 us: the events (stepper restarts) fall to about half,
    // elements convert up to 2 us later, and the energies stay within 1 %
    const std::string deck = std::string(RKFEM_SOURCE_DIR) + "/studies/decks/concrete_bar_conversion.yaml";
    auto run = [&](const char* interval)
    {
        Model m = Model::build(read_deck(deck, {"parts.bar.generator.element_size=5mm", "time.end=30us",
                                                std::string("parts.bar.conversion.interval=") + interval}));
        int events = 0;
        RunOptions opt;
        opt.progress = false;
        index_t converted = 0;
        opt.events = [&](Model& mm, real_t, std::int64_t)
        {
            events += mm.converted_elements() != converted;
            converted = mm.converted_elements();
            return false;
        };
        EXPECT_EQ(run_simulation(m, opt).status, "completed");
        std::printf("interval %s: %d conversion events, %ld elements converted, kinetic %.4f J, internal %.4f J, "
                    "balance error %.2e\n",
                    interval, events, static_cast<long>(m.converted_elements()), m.energy.kinetic, m.energy.internal,
                    m.energy.balance_error());
        return std::tuple{events, m.converted_elements(), m.energy};
    };
    const auto [events0, converted0, e0] = run("0");
    const auto [events2, converted2, e2] = run("2us");
    EXPECT_GE(events0, 8);
    EXPECT_LE(events2, 0.7 * events0);
    EXPECT_NEAR(static_cast<real_t>(converted2) / converted0, 1.0, 0.1);
    EXPECT_NEAR(e2.kinetic / e0.kinetic, 1.0, 0.01);
    EXPECT_NEAR(e2.internal / e0.internal, 1.0, 0.01);
    EXPECT_LT(e2.balance_error(), 2e-3);
}

TEST(ConversionLoads, PressureOnConvertedFacesKeepsItsResultantAndMoment)
{
    // a pressure on the top face of a box whose upper half turns RK: the corners' lumped forces
    // act at their physical points and reach the coefficients through the kinematic map, whose
    // rows sum to 1 and reproduce x, so the total force (-p A) and its moment about the origin
    // (the face centre x F) are those of the FE box, to round-off
    Model m = test::model_from(box, {"face_sets={top: {select: {type: plane, point: [0, 0, 6 mm], normal: [0, 0, 1]}}}",
                                     "loads=[{type: pressure, face_set: top, pressure: 1 MPa}]"});
    auto resultant = [&](Vec3& force, Vec3& moment)
    {
        m.external_forces(0.0);
        force.setZero();
        moment.setZero();
        for (index_t i = 0; i < m.nodes.size(); ++i)
        {
            const Vec3 f(m.nodes.f_ext[3 * i], m.nodes.f_ext[3 * i + 1], m.nodes.f_ext[3 * i + 2]);
            force += f;
            moment += Vec3(m.nodes.x0[3 * i], m.nodes.x0[3 * i + 1], m.nodes.x0[3 * i + 2]).cross(f);
        }
    };
    const real_t p = 1e6, A = 16e-6;
    const Vec3 F_exact(0, 0, -p * A), M_exact = Vec3(2e-3, 2e-3, 6e-3).cross(F_exact);
    Vec3 F_fe, M_fe, F_rk, M_rk;
    resultant(F_fe, M_fe);
    ASSERT_EQ(m.convert_elements(0, elements_above(m, 3e-3)), 48);
    resultant(F_rk, M_rk);
    Vec3 F_again, M_again; // every dof the spread writes is zeroed before the next evaluation
    resultant(F_again, M_again);
    EXPECT_EQ(F_again, F_rk);
    EXPECT_EQ(M_again, M_rk);
    index_t spread = 0; // coefficients that carry load beyond the face's own nodes
    for (index_t i = 0; i < m.nodes.size(); ++i)
        spread += m.nodes.x0[3 * i + 2] < 6e-3 - 1e-9 && m.nodes.f_ext[3 * i + 2] != 0.0;
    std::printf("pressure on converted faces: force error %.2e, moment error %.2e (FE box %.2e, %.2e); %ld "
                "coefficients below the face carry load\n",
                (F_rk - F_exact).norm() / F_exact.norm(), (M_rk - M_exact).norm() / M_exact.norm(),
                (F_fe - F_exact).norm() / F_exact.norm(), (M_fe - M_exact).norm() / M_exact.norm(),
                static_cast<long>(spread));
    EXPECT_GT(spread, 0);
    EXPECT_LT((F_fe - F_exact).norm(), 1e-12 * F_exact.norm());
    EXPECT_LT((M_fe - M_exact).norm(), 1e-12 * M_exact.norm());
    EXPECT_LT((F_rk - F_exact).norm(), 1e-12 * F_exact.norm());
    EXPECT_LT((M_rk - M_exact).norm(), 1e-12 * M_exact.norm());
}

namespace
{
/// A 3 x 3 x 1 mm fem-nodal block one element thick (1 mm elements), its bottom held and its top
/// driven at `velocity`, so every node is prescribed and each element deforms exactly as the
/// top's motion says (simple shear or uniaxial stretch), with the trigger `criterion`.
std::string driven_block(const std::string& velocity, const std::string& criterion)
{
    return R"(
time: {end: 200 us}
parts:
  b:
    generator: {type: box, size: [3 mm, 3 mm, 1 mm], divisions: [3, 3, 1]}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: fem-nodal
    conversion: )" +
           criterion + R"(
node_sets:
  bottom: {part: b, select: {type: named, name: bottom}}
  top: {part: b, select: {type: named, name: top}}
boundary_conditions:
  - {node_set: bottom, fixed: all}
  - {node_set: top, velocity: )" +
           velocity + R"(}
)";
}
} // namespace

// Distortion triggers (issue #49): a block sheared at 10 m/s over its 1 mm height has every
// corner's scaled Jacobian at 1 / sqrt(1 + gamma^2), gamma = v t / H, so `scaled_jacobian: 0.5`
// fires at gamma = sqrt(3), t = 173.2 us; stretched along its height at 10 m/s its elements' edges
// are 1 + v t / H against 1 mm, so `aspect_ratio: 2` fires at t = 100 us. Each converts all nine
// elements in one event, at the first step end at or past that time, and none before.
TEST(ConversionTriggers, DistortionFiresAtTheStatedMeasureAndNotBefore)
{
    struct Case
    {
        const char* name;
        std::string velocity, criterion;
        real_t t_fire;
    };
    for (const Case& k : {Case{"shear, scaled_jacobian 0.5", "{x: 10 m/s, y: 0, z: 0}", "{scaled_jacobian: 0.5}",
                               std::sqrt(3.0) * 1e-3 / 10.0},
                          Case{"stretch, aspect_ratio 2", "{x: 0, y: 0, z: 10 m/s}", "{aspect_ratio: 2}", 1e-3 / 10.0}})
    {
        Model m = test::model_from(driven_block(k.velocity, k.criterion));
        real_t t_event = -1.0, t_before = -1.0, dt_event = 0.0;
        index_t converted = 0;
        RunOptions opt;
        opt.progress = false;
        const RunSummary s = run_simulation(m, opt,
                                            [&](const Model& mm, real_t t, real_t dt, std::int64_t)
                                            {
                                                if (mm.converted_elements() > 0 && t_event < 0.0)
                                                {
                                                    t_event = t;
                                                    dt_event = dt;
                                                    converted = mm.converted_elements();
                                                }
                                                else if (mm.converted_elements() == 0)
                                                    t_before = t;
                                            });
        ASSERT_EQ(s.status, "completed") << k.name << ": " << s.message;
        std::printf("%s: converted %d elements at %.4f us (theory: the first step end at or past %.4f us; the "
                    "last step end before it %.4f us, step %.4f us)\n",
                    k.name, static_cast<int>(converted), 1e6 * t_event, 1e6 * k.t_fire, 1e6 * t_before, 1e6 * dt_event);
        EXPECT_EQ(converted, 9) << k.name;
        EXPECT_GE(t_event, k.t_fire * (1.0 - 1e-9)) << k.name;
        EXPECT_LT(t_before, k.t_fire) << k.name;
        EXPECT_LE(t_event - t_before, dt_event * (1.0 + 1e-9)) << k.name; // the step that crossed it
        EXPECT_EQ(m.converted_elements(), 9) << k.name;
    }
}

// The buffer and the cap (issue #49): a 4 x 4 x 4 fem-nodal J2 box whose two opposite corner nodes
// carry a plastic strain of 1 (their elements' mean 1/8 passes effective_plastic_strain 0.1; no
// other element holds either node). With `buffer: 1` each triggered element brings the 7
// elements that share a node with it: 16 in one event; `buffer: 2` the two 3 x 3 x 3 blocks,
// which share the box's middle 2 x 2 x 2: 46;
// `max_per_event: 8` with buffer 1 converts the two triggered elements first and then the
// buffer's in element order, 8 in all, and the capped ones wait for a trigger that no longer
// holds (both corners are RK): 8 at the end. `max_per_event: 1` without a buffer converts one
// corner per event: 1 after the first step, 2 after the second.
TEST(ConversionTriggers, BufferLayersAndTheCapPerEvent)
{
    auto run = [](const std::string& extra, int steps)
    {
        Model m = test::model_from(R"(
time: {end: 1 s}
parts:
  b:
    generator: {type: box, size: [4 mm, 4 mm, 4 mm], divisions: [4, 4, 4]}
    material: {model: j2, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3, sigy: 500 MPa, etan: 1 GPa}
    formulation: fem-nodal
    bulk_viscosity: {linear: 0, quadratic: 0}
    conversion: {effective_plastic_strain: 0.1)" +
                                   extra + R"(}
)");
        NodalBlock& nb = *m.nodal_block(0);
        for (index_t i = 0; i < m.nodes.size(); ++i)
        {
            const real_t x = m.nodes.x0[3 * i], y = m.nodes.x0[3 * i + 1], z = m.nodes.x0[3 * i + 2];
            const bool origin = x < 1e-6 && y < 1e-6 && z < 1e-6;
            const bool far = x > 4e-3 - 1e-6 && y > 4e-3 - 1e-6 && z > 4e-3 - 1e-6;
            if (origin || far)
                for (index_t k = nb.owner_offsets[i - nb.node_begin]; k < nb.owner_offsets[i - nb.node_begin + 1]; ++k)
                {
                    const std::size_t p = static_cast<std::size_t>(nb.owner_points[k]);
                    nb.plastic.eps_p[p] = nb.plastic.eps_p_trial[p] = 1.0;
                }
        }
        std::vector<index_t> counts;
        CentralDifference cd;
        StepReport r = cd.initialize(m, 0.0);
        real_t t = 0.0;
        for (int k = 1; k <= steps; ++k)
        {
            const real_t dt = next_time_step(m.deck().time, t, r.dt_stable);
            r = cd.step(m, t, dt, k);
            t = r.t;
            if (m.apply_events(t, k))
                r.dt_stable = m.restart_after_event(cd, t, dt);
            counts.push_back(m.converted_elements());
        }
        return std::make_pair(counts, m.rk_elements(0));
    };
    const auto [none, rk0] = run("", 2);
    const auto [one, rk1] = run(", buffer: 1", 2);
    const auto [two, rk2] = run(", buffer: 2", 2);
    const auto [capped, rkc] = run(", buffer: 1, max_per_event: 8", 3);
    const auto [single, rks] = run(", max_per_event: 1", 3);
    std::printf("conversions after each step: no buffer %d, buffer 1 %d, buffer 2 %d, buffer 1 capped at 8: %d %d "
                "%d, capped at 1: %d %d %d\n",
                static_cast<int>(none[0]), static_cast<int>(one[0]), static_cast<int>(two[0]),
                static_cast<int>(capped[0]), static_cast<int>(capped[1]), static_cast<int>(capped[2]),
                static_cast<int>(single[0]), static_cast<int>(single[1]), static_cast<int>(single[2]));
    EXPECT_EQ(none, (std::vector<index_t>{2, 2}));
    EXPECT_EQ(one, (std::vector<index_t>{16, 16}));
    EXPECT_EQ(two, (std::vector<index_t>{46, 46}));
    EXPECT_EQ(capped, (std::vector<index_t>{8, 8, 8}));
    EXPECT_EQ(single, (std::vector<index_t>{1, 2, 2}));
    // the capped event's elements: the corners 0 and 63, then 0's buffer in element order (1, 4,
    // 5, 16, 17, 20; the box numbers elements x fastest)
    std::vector<index_t> in;
    for (std::size_t e = 0; e < rkc.size(); ++e)
        if (rkc[e])
            in.push_back(static_cast<index_t>(e));
    EXPECT_EQ(in, (std::vector<index_t>{0, 1, 4, 5, 16, 17, 20, 63}));
    EXPECT_EQ(std::count(rk1.begin(), rk1.end(), char{1}), 16);
}

TEST(ConversionTriggers, DeckErrorsNameTheKey)
{
    auto error_of = [](const std::string& conversion)
    { return test::model_error(driven_block("{x: 10 m/s}", conversion), {}); };
    EXPECT_NE(error_of("{scaled_jacobian: 1.2}").find("parts.b.conversion.scaled_jacobian"), std::string::npos);
    EXPECT_NE(error_of("{aspect_ratio: 0.5}").find("parts.b.conversion.aspect_ratio: is not above 1"),
              std::string::npos);
    EXPECT_NE(error_of("{aspect_ratio: 2, buffer: -1}").find("parts.b.conversion.buffer"), std::string::npos);
    EXPECT_NE(error_of("{aspect_ratio: 2, max_per_event: -3}").find("parts.b.conversion.max_per_event"),
              std::string::npos);
    EXPECT_NE(error_of("{buffer: 1}").find("has no criterion"), std::string::npos);
    EXPECT_EQ(error_of("{aspect_ratio: 2, scaled_jacobian: 0.3, buffer: 1, max_per_event: 100}"), "");
}

// RK back to FE (issue #49, seed Table 1 feature 4 "in both directions"): the same tables-only
// event the other way. A box under a linear velocity field converts its upper half after step 3
// and reverts all of it after step 6: every point's stress stays that of the run that never
// converts, to round-off, and at the end no particle is left (every element FE again, the
// kinematic map the identity). A free column converted and reverted keeps the momentum of its
// unknowns exactly (the state moves with no interpolation).
TEST(ConversionReversion, ABoxConvertedAndBackKeepsItsUniformStress)
{
    const real_t A[3][3] = {{1.0, 0.3, -0.2}, {0.1, -0.5, 0.4}, {0.25, 0.2, 0.7}}; // 1/s
    const real_t dt = 1e-8;
    Model plain = test::model_from(box), conv = test::model_from(box);
    for (int step = 1; step <= 9; ++step)
    {
        if (step == 4)
        {
            ASSERT_EQ(conv.convert_elements(0, elements_above(conv, 3e-3)), 48);
        }
        if (step == 7)
        {
            ASSERT_EQ(conv.revert_elements(0, std::vector<char>(96, 1)), 48);
            EXPECT_EQ(conv.revert_elements(0, std::vector<char>(96, 1)), 0); // nothing left to revert
        }
        for (Model* m : {&plain, &conv})
        {
            test::linear_velocity_step(m->nodes, A, dt);
            m->compute_forces(step * dt, dt, step);
            m->commit();
        }
    }
    EXPECT_EQ(conv.reverted_elements(), 48);
    const NodalBlock &p = *plain.nodal_block(0), &c = *conv.nodal_block(0);
    real_t smax = 0.0, ds = 0.0, df = 0.0, fmax = 0.0;
    for (int k = 0; k < 6; ++k)
        for (index_t q = 0; q < p.n_points(); ++q)
        {
            const std::size_t j = k * p.stress_stride + q;
            smax = std::max(smax, std::abs(p.stress[j]));
            ds = std::max(ds, std::abs(p.stress[j] - c.stress[j]));
        }
    for (std::size_t j = 0; j < plain.nodes.f_int.size(); ++j)
    {
        fmax = std::max(fmax, std::abs(plain.nodes.f_int[j]));
        df = std::max(df, std::abs(plain.nodes.f_int[j] - conv.nodes.f_int[j]));
    }
    index_t particles = 0, zones[3] = {0, 0, 0};
    for (index_t i = 0; i < conv.nodes.size(); ++i)
        particles += conv.carries_coefficients(i);
    for (index_t e = 0; e < conv.meshes[0].n_elements(); ++e)
        ++zones[conv.element_zone(0, e)];
    std::printf("converted after step 3, reverted after step 6: stress change %.2e of the largest, internal forces "
                "%.2e of the largest, %d particles left\n",
                ds / smax, df / fmax, static_cast<int>(particles));
    EXPECT_LT(ds / smax, 1e-12);
    EXPECT_LT(df / fmax, 1e-12);
    EXPECT_EQ(particles, 0);
    EXPECT_EQ(zones[0], 96);
}

TEST(ConversionReversion, AFreeColumnKeepsItsMomentumThroughBothEvents)
{
    const FreeColumnRun run =
        free_column_run({}, 300, {100, 200},
                        [](int k, Model& m)
                        {
                            if (k == 100)
                            {
                                EXPECT_EQ(m.convert_elements(0, elements_above(m, 20e-3)), 3 * 3 * 20);
                            }
                            else
                            {
                                EXPECT_EQ(m.revert_elements(0, elements_above(m, 30e-3)), 3 * 3 * 10);
                            }
                        });
    std::printf("free column, converted at step 100, its top quarter reverted at 200: momentum jump at the events "
                "%.2e, |p - p0| / sum m|v| %.2e over 300 steps\n",
                run.jump, run.momentum_error);
    EXPECT_EQ(run.jump, 0.0);
    EXPECT_LT(run.momentum_error, 1e-12);
    EXPECT_EQ(run.reverted, 90);
}

// By the deck (conversion.revert, studies/decks/shear_and_back_reversion.yaml): the block of the
// distortion trigger test sheared at 10 m/s
// until 200 us (gamma = 2) and back at -10 m/s: it converts at gamma = sqrt 3 (scaled Jacobian
// 0.5) and reverts when the scaled Jacobian 1 / sqrt(1 + gamma^2) is back at 0.7, gamma =
// sqrt(1 / 0.49 - 1) = 1.0202: at the first step end where the top's displacement says so, all
// nine elements at once, none before (about t = 200 + (2 - 1.0202) / 1e4 s = 297.98 us; the
// central difference takes the reversal at 200 us within one step, so gamma, not t, is the measure).
TEST(ConversionReversion, ARevertMeasureFiresAtItsValueAndNotBefore)
{
    Model m = Model::build(read_deck(std::string(RKFEM_SOURCE_DIR) + "/studies/decks/shear_and_back_reversion.yaml"));
    index_t top = 0; // a node of the top face: its x displacement over the height is gamma
    for (index_t i = 0; i < m.nodes.size(); ++i)
        if (m.nodes.x0[3 * i + 2] > 0.999e-3)
            top = i;
    real_t t_convert = -1.0, t_revert = -1.0, t_before = -1.0, g_revert = 0.0, g_before = 0.0;
    RunOptions opt;
    opt.progress = false;
    const RunSummary s = run_simulation(m, opt,
                                        [&](const Model& mm, real_t t, real_t, std::int64_t)
                                        {
                                            const real_t gamma = mm.physical(mm.nodes.u, top)[0] / 1e-3;
                                            if (mm.converted_elements() > 0 && t_convert < 0.0)
                                                t_convert = t;
                                            if (mm.reverted_elements() > 0 && t_revert < 0.0)
                                            {
                                                t_revert = t;
                                                g_revert = gamma;
                                            }
                                            else if (mm.reverted_elements() == 0)
                                            {
                                                t_before = t;
                                                g_before = gamma;
                                            }
                                        });
    ASSERT_EQ(s.status, "completed") << s.message;
    const real_t gamma_back = std::sqrt(1.0 / 0.49 - 1.0);
    std::printf("sheared and back: converted at %.4f us (theory 173.2051), reverted %d elements at %.4f us with gamma "
                "%.5f, the step before at %.4f us with gamma %.5f (theory: gamma %.5f, about %.2f us)\n",
                1e6 * t_convert, static_cast<int>(m.reverted_elements()), 1e6 * t_revert, g_revert, 1e6 * t_before,
                g_before, gamma_back, 1e6 * (200e-6 + (2.0 - gamma_back) * 1e-4));
    EXPECT_NEAR(t_convert, std::sqrt(3.0) * 1e-4, 1e-6);
    EXPECT_EQ(m.reverted_elements(), 9);
    // the history's running totals of the events (history.csv, results.h5): the last row's are
    // the model's (9 converted, 9 back)
    const auto col = [&](const char* name)
    {
        const auto it = std::find(s.history_columns.begin(), s.history_columns.end(), name);
        EXPECT_NE(it, s.history_columns.end()) << name;
        return s.history[s.history.size() - s.history_columns.size() +
                         static_cast<std::size_t>(it - s.history_columns.begin())];
    };
    EXPECT_EQ(col("converted_elements"), static_cast<real_t>(m.converted_elements()));
    EXPECT_EQ(col("reverted_elements"), 9.0);
    EXPECT_LE(g_revert, gamma_back);
    EXPECT_GT(g_before, gamma_back);
    for (index_t e = 0; e < m.meshes[0].n_elements(); ++e)
        EXPECT_EQ(m.element_zone(0, e), 0);
}

TEST(ConversionReversion, DeckErrorsNameTheKey)
{
    auto err = [](const std::string& conversion)
    { return test::model_error(driven_block("{x: 10 m/s, y: 0, z: 0}", conversion), {}); };
    EXPECT_NE(err("{scaled_jacobian: 0.5, revert: {scaled_jacobian: 0.4}}")
                  .find("parts.b.conversion.revert.scaled_jacobian: is not above the conversion's"),
              std::string::npos);
    EXPECT_NE(err("{aspect_ratio: 2, revert: {aspect_ratio: 2.5}}")
                  .find("parts.b.conversion.revert.aspect_ratio: is below 1 or not below the conversion's"),
              std::string::npos);
    EXPECT_NE(err("{scaled_jacobian: 0.5, revert: {}}").find("parts.b.conversion.revert"), std::string::npos);
    EXPECT_NE(err("{scaled_jacobian: 0.5, revert: {speed: 1}}").find("unknown key 'speed'"), std::string::npos);
    EXPECT_EQ(err("{scaled_jacobian: 0.5, buffer: 1, revert: {scaled_jacobian: 0.7, aspect_ratio: 1.5}}"), "");
}

// fem-1pt parts convert too (adaptivity/conversion_fe_side.cpp): the converted elements leave the
// part's 1-point block and their octants go to the points of their nodes, each new point's state
// the volume-weighted mean of the material it takes over (damage the largest), masses those of the
// new blocks with each node's momentum kept.
namespace
{
const char* box_1pt = R"(
time: {end: 1 s}
parts:
  b:
    generator: {type: box, size: [4 mm, 4 mm, 6 mm], divisions: [4, 4, 6]}
    material: {model: j2, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3, sigy: 500 GPa, etan: 1 GPa}
    formulation: fem-1pt
    bulk_viscosity: {linear: 0, quadratic: 0}
    conversion: {principal_strain: 10}
)";

/// Stress component k of part element e of a converting fem-1pt part (its FE side's point)
real_t side_stress(const Model& m, index_t e, int k)
{
    const FeSide& s = *m.fe_side(0);
    return s.block.stress[k * s.block.stress_stride + static_cast<std::size_t>(s.local[e])];
}

/// Per-element states averaged over node i's elements (their octants are equal), their largest
/// failed flag, and the node's share of their reference volume (V0 / 8 each).
struct NodeMean
{
    std::array<real_t, 6> stress{};
    real_t eps = 0.0, failed = 0.0, volume0 = 0.0;
};
NodeMean node_mean(const HexBlock& mesh, const std::vector<std::array<real_t, 6>>& s0, const std::vector<real_t>& eps0,
                   const std::vector<real_t>& failed0, index_t i)
{
    NodeMean m;
    const index_t k0 = mesh.node_elem_offsets[i], k1 = mesh.node_elem_offsets[i + 1];
    for (index_t k = k0; k < k1; ++k)
    {
        const index_t e = mesh.node_elem_slots[k] / 8;
        for (int c = 0; c < 6; ++c)
            m.stress[c] += s0[e][c] / static_cast<real_t>(k1 - k0);
        m.eps += eps0[e] / static_cast<real_t>(k1 - k0);
        m.failed = std::max(m.failed, failed0[e]);
        m.volume0 += mesh.volume0[e] / 8.0;
    }
    return m;
}

/// The point of local node i of the part's nodal block
index_t point_of_node(const NodalBlock& nb, index_t i)
{
    EXPECT_EQ(nb.owner_offsets[i + 1] - nb.owner_offsets[i], 1) << "node " << i;
    return nb.owner_points[nb.owner_offsets[i]];
}
} // namespace

TEST(ConversionFem1pt, LinearFieldKeepsItsUniformStressThroughAConversion)
{
    // the box under a linear velocity field (elastic: the J2 surface is out of reach); after step
    // 3 its upper half turns RK: every FE element's and every point's stress stays the uniform
    // stress of the run that never converts, interior FE nodes carry no force and the particles'
    // physical velocities are the linear field's
    const real_t A[3][3] = {{1.0, 0.3, -0.2}, {0.1, -0.5, 0.4}, {0.25, 0.2, 0.7}}; // 1/s
    const real_t dt = 1e-8;
    Model plain = test::model_from(box_1pt), conv = test::model_from(box_1pt);
    ASSERT_NE(conv.fe_side(0), nullptr);
    ASSERT_EQ(conv.nodal_block(0)->n_points(), 0); // no point before the first event
    for (int step = 1; step <= 6; ++step)
    {
        if (step == 4)
        {
            ASSERT_EQ(conv.convert_elements(0, elements_above(conv, 3e-3)), 48);
        }
        for (Model* m : {&plain, &conv})
        {
            test::linear_velocity_step(m->nodes, A, dt);
            m->compute_forces(step * dt, dt, step);
            m->commit();
        }
    }
    real_t smax = 0.0, ds = 0.0;
    for (int k = 0; k < 6; ++k)
        smax = std::max(smax, std::abs(side_stress(plain, 0, k)));
    const FeSide& side = *conv.fe_side(0);
    const NodalBlock& nb = *conv.nodal_block(0);
    for (int k = 0; k < 6; ++k)
    {
        const real_t uniform = side_stress(plain, 0, k);
        for (index_t q = 0; q < side.block.n_elements(); ++q)
            ds = std::max(ds, std::abs(side.block.stress[k * side.block.stress_stride + q] - uniform));
        for (index_t p = 0; p < nb.n_points(); ++p)
            ds = std::max(ds, std::abs(nb.stress[k * nb.stress_stride + p] - uniform));
    }
    const LinearFieldCheck lf = check_linear_field(conv, A);
    std::printf("fem-1pt box, upper half converted after step 3: %d FE elements and %d points, stress off the uniform "
                "%.2e of it, interior FE node forces %.2e of the largest, %d particles with velocity error %.2e\n",
                static_cast<int>(side.block.n_elements()), static_cast<int>(nb.n_points()), ds / smax, lf.residual,
                static_cast<int>(lf.particles), lf.velocity_error);
    EXPECT_EQ(side.block.n_elements(), 32); // the transition layer below the RK half is the nodal block's
    EXPECT_EQ(nb.n_points(), 5 * 5 * 5);
    EXPECT_EQ(lf.particles, 5 * 5 * 4);
    EXPECT_GE(lf.interior, 3 * 3 * 2);
    EXPECT_LT(ds / smax, 1e-10);
    EXPECT_LT(lf.residual, 1e-10);
    EXPECT_LT(lf.velocity_error, 1e-12);
}

TEST(ConversionFem1pt, PointsTakeTheVolumeWeightedMeanAndTheLargestDamage)
{
    // every element of the box a state of its own (stress, plastic strain, every fifth failed) and
    // the nodes a velocity: converted whole, each node's point holds the mean of its elements' states
    // (their octants are equal) and the largest failed flag; reverted whole, each element the mean
    // of its 8 nodes' points and their largest flag. Mass and momentum stay what they were.
    Model m = test::model_from(box_1pt);
    FeSide& side = *m.fe_side(0);
    const HexBlock& mesh = m.meshes[0];
    const index_t ne = mesh.n_elements();
    std::vector<std::array<real_t, 6>> s0(static_cast<std::size_t>(ne));
    std::vector<real_t> eps0(static_cast<std::size_t>(ne)), failed0(static_cast<std::size_t>(ne));
    for (index_t e = 0; e < ne; ++e)
    {
        const std::size_t q = static_cast<std::size_t>(side.local[e]);
        for (int k = 0; k < 6; ++k)
            s0[e][k] = side.block.stress[k * side.block.stress_stride + q] = 1e6 * (k + 1) * std::sin(0.7 * e + k);
        eps0[e] = side.block.plastic.eps_p[q] = 1e-3 * (1 + e % 7);
        failed0[e] = side.block.plastic.failed[q] = e % 5 == 0 ? 1.0 : 0.0;
    }
    for (index_t i = 0; i < m.nodes.size(); ++i)
        for (int d = 0; d < 3; ++d)
            m.nodes.v[3 * i + d] = std::cos(1.3 * i + d);
    const Vec3 p0 = test::momentum(m.nodes);
    const real_t mv = test::momentum_scale(m.nodes);
    real_t mass0 = 0.0;
    for (real_t x : m.nodes.mass)
        mass0 += x;

    ASSERT_EQ(m.convert_elements(0, std::vector<char>(static_cast<std::size_t>(ne), 1)), ne);
    EXPECT_EQ(m.fe_side(0)->block.n_elements(), 0);
    const NodalBlock& nb = *m.nodal_block(0);
    ASSERT_EQ(nb.n_points(), m.nodes.size());
    real_t ds = 0.0, deps = 0.0, smax = 0.0;
    index_t wrong_flags = 0;
    std::vector<std::array<real_t, 6>> s1(static_cast<std::size_t>(m.nodes.size()));
    std::vector<real_t> eps1(s1.size()), failed1(s1.size());
    for (index_t i = 0; i < m.nodes.size(); ++i)
    {
        const NodeMean nm = node_mean(mesh, s0, eps0, failed0, i);
        const std::array<real_t, 6>& mean = nm.stress;
        const real_t eps = nm.eps, failed = nm.failed;
        const std::size_t p = static_cast<std::size_t>(point_of_node(nb, i));
        for (int c = 0; c < 6; ++c)
        {
            s1[i][c] = nb.stress[c * nb.stress_stride + p];
            ds = std::max(ds, std::abs(s1[i][c] - mean[c]));
            smax = std::max(smax, std::abs(mean[c]));
        }
        eps1[i] = nb.plastic.eps_p[p];
        failed1[i] = nb.plastic.failed[p];
        deps = std::max(deps, std::abs(eps1[i] - eps) / eps);
        wrong_flags += failed1[i] != failed;
    }
    real_t mass1 = 0.0;
    for (real_t x : m.nodes.mass)
        mass1 += x;
    const real_t dp1 = (test::momentum(m.nodes) - p0).norm() / mv;

    ASSERT_EQ(m.revert_elements(0, std::vector<char>(static_cast<std::size_t>(ne), 1)), ne);
    EXPECT_EQ(m.nodal_block(0)->n_points(), 0);
    const FeSide& back = *m.fe_side(0);
    real_t ds2 = 0.0, deps2 = 0.0;
    index_t wrong_flags2 = 0;
    for (index_t e = 0; e < ne; ++e)
    {
        std::array<real_t, 6> mean{};
        real_t eps = 0.0, failed = 0.0;
        for (int a = 0; a < 8; ++a)
        {
            const index_t i = mesh.conn[8 * e + a];
            for (int c = 0; c < 6; ++c)
                mean[c] += s1[i][c] / 8.0;
            eps += eps1[i] / 8.0;
            failed = std::max(failed, failed1[i]);
        }
        const std::size_t q = static_cast<std::size_t>(back.local[e]);
        for (int c = 0; c < 6; ++c)
            ds2 = std::max(ds2, std::abs(back.block.stress[c * back.block.stress_stride + q] - mean[c]));
        deps2 = std::max(deps2, std::abs(back.block.plastic.eps_p[q] - eps) / eps);
        wrong_flags2 += back.block.plastic.failed[q] != failed;
    }
    real_t mass2 = 0.0;
    for (real_t x : m.nodes.mass)
        mass2 += x;
    const real_t dp2 = (test::momentum(m.nodes) - p0).norm() / mv;
    std::printf("fem-1pt box converted whole: point stress off the mean %.2e of the largest, plastic strain %.2e, %d "
                "wrong flags, mass %.2e, momentum %.2e; reverted whole: %.2e, %.2e, %d, mass %.2e, momentum %.2e\n",
                ds / smax, deps, static_cast<int>(wrong_flags), std::abs(mass1 - mass0) / mass0, dp1, ds2 / smax, deps2,
                static_cast<int>(wrong_flags2), std::abs(mass2 - mass0) / mass0, dp2);
    EXPECT_LT(ds / smax, 1e-14);
    EXPECT_LT(deps, 1e-14);
    EXPECT_EQ(wrong_flags, 0);
    EXPECT_LT(ds2 / smax, 1e-14);
    EXPECT_LT(deps2, 1e-14);
    EXPECT_EQ(wrong_flags2, 0);
    EXPECT_LT(std::abs(mass1 - mass0) / mass0, 1e-13);
    EXPECT_LT(std::abs(mass2 - mass0) / mass0, 1e-13);
    EXPECT_LT(dp1, 1e-14);
    EXPECT_LT(dp2, 1e-14);
}

TEST(ConversionFem1pt, FreeColumnConservesMomentumAndEnergyThroughConversions)
{
    // the free column of ConversionDynamics as fem-1pt (viscous hourglass control): converted from
    // the top in three events (the run loop's restart after each), its momentum stays what it was,
    // and the ledger closes as well as in the run that never converts. The step is held at 0.12 us,
    // under both discretizations' stable steps: the ledger's leapfrog correction of the kinetic
    // energy, -dt^2 / 8 sum m a.a, takes the step it is measured with, so the 5 % smaller stable
    // step of the first RK region alone moves the measured balance by 2.5e-4 (0.9 of that term)
    expect_column_conserves("fem-1pt free column", {"parts.column.formulation=fem-1pt", "time.dt_max=0.12us"});
}

TEST(ConversionFem1pt, KccHistoryTakesTheVolumeWeightedMeanTheLargestDamageAndKeepsItsCrackBand)
{
    // PlasticPoints::blend_point on K&C points: shares of volume 1 and 3; one share copies
    const KccModel model = KccModel::from_fc(45.6e6, 2400);
    PlasticPoints a, b, to;
    for (PlasticPoints* p : {&a, &b, &to})
    {
        p->set_kcc(model);
        p->resize(2);
    }
    a.kcc_state[0] = {1e-4, -1e-3, -2e-3, 1e-4, 1e-3, 2.0};
    b.kcc_state[1] = {5e-4, -3e-3, -4e-3, 3e-4, 2e-3, 3.0};
    a.eps_p[0] = 1e-3;
    b.eps_p[1] = 2e-3;
    a.failed[0] = 1e-4;
    b.failed[1] = 5e-4;
    to.kcc_state[0].tension_scale = to.kcc_state[1].tension_scale = 5.0; // the point's own length
    const PlasticPoints::Share two[2] = {{&a, 0, 1.0}, {&b, 1, 3.0}};
    to.blend_point(two, 2, 0);
    const KccState& s = to.kcc_state[0];
    EXPECT_EQ(s.lambda, 5e-4);
    EXPECT_NEAR(s.ev, -2.5e-3, 1e-18);
    EXPECT_NEAR(s.ev_min, -3.5e-3, 1e-18);
    EXPECT_NEAR(s.ev_plastic, 2.5e-4, 1e-18);
    EXPECT_NEAR(s.eps_p, 1.75e-3, 1e-18);
    EXPECT_NEAR(to.eps_p[0], 1.75e-3, 1e-18);
    EXPECT_EQ(to.failed[0], 5e-4);
    EXPECT_EQ(s.tension_scale, 5.0);
    EXPECT_EQ(to.kcc_trial[0].ev, s.ev);
    EXPECT_EQ(to.failed_trial[0], to.failed[0]);
    // a single point's shares: its values as they are
    const PlasticPoints::Share one[3] = {{&b, 1, 0.3}, {&b, 1, 0.7}, {&b, 1, 0.1}};
    to.blend_point(one, 3, 1);
    EXPECT_EQ(to.kcc_state[1].ev, -3e-3);
    EXPECT_EQ(to.kcc_state[1].ev_min, -4e-3);
    EXPECT_EQ(to.kcc_state[1].eps_p, 2e-3);
    EXPECT_EQ(to.kcc_state[1].tension_scale, 5.0);
}

// fem-1pt parts with kinematics: semi-lagrangian convert into semi-Lagrangian particles
// (adaptivity/conversion_semi_lagrangian.cpp): the converted elements' octants go to particles at
// their corners, which share the nodes with the FE elements that stay. Checked: each particle takes
// the volume-weighted mean of its octants' stress and history and the largest damage, the nodes
// keep mass and momentum exactly; the cells hold the converted elements' current volume to
// round-off; under a linear velocity field the particles' stress follows the FE elements' uniform
// stress (SNNI reproduces linear fields on any parallelepiped) and the internal forces sum to zero;
// a free column converting in three events keeps its momentum and balances as the one that never
// converts; the deck's refusals name the key.
namespace
{
const std::vector<std::string> to_sl = {"parts.b.kinematics=semi-lagrangian"};
using test::total_mass;
} // namespace

TEST(ConversionSemiLagrangian, ParticlesTakeTheVolumeWeightedMeanAndTheLargestDamage)
{
    // every element a state of its own (stress, plastic strain, every fifth failed) and the nodes a
    // velocity: converted whole, each particle holds the mean of its elements' states (their
    // octants are equal), the largest failed flag, and their reference volume; mass and momentum
    // stay what they were
    Model m = test::model_from(box_1pt, to_sl);
    HexBlock& fe = m.meshes[0];
    const HexBlock mesh = fe; // the elements before they leave
    const index_t ne = fe.n_elements();
    std::vector<std::array<real_t, 6>> s0(static_cast<std::size_t>(ne));
    std::vector<real_t> eps0(static_cast<std::size_t>(ne)), failed0(static_cast<std::size_t>(ne));
    for (index_t e = 0; e < ne; ++e)
    {
        for (int k = 0; k < 6; ++k)
            s0[e][k] = fe.stress[k * fe.stress_stride + e] = 1e6 * (k + 1) * std::sin(0.7 * e + k);
        eps0[e] = fe.plastic.eps_p[e] = 1e-3 * (1 + e % 7);
        failed0[e] = fe.plastic.failed[e] = e % 5 == 0 ? 1.0 : 0.0;
    }
    for (index_t i = 0; i < m.nodes.size(); ++i)
        for (int d = 0; d < 3; ++d)
            m.nodes.v[3 * i + d] = std::cos(1.3 * i + d);
    const Vec3 p0 = test::momentum(m.nodes);
    const real_t mv = test::momentum_scale(m.nodes), mass0 = total_mass(m.nodes);
    const SemiLagrangianForceBlock& sl = *m.semi_lagrangian_block(0);
    ASSERT_EQ(sl.active_particles(), 0); // dormant before the first event

    ASSERT_EQ(m.convert_elements(0, std::vector<char>(static_cast<std::size_t>(ne), 1)), ne);
    EXPECT_EQ(m.meshes[0].n_elements(), 0);
    EXPECT_EQ(m.rk_element_count(0), ne);
    const NodalBlock& st = *sl.nodal_points();
    ASSERT_EQ(sl.active_particles(), m.nodes.size());
    real_t ds = 0.0, deps = 0.0, smax = 0.0, dv = 0.0;
    index_t wrong_flags = 0;
    for (index_t i = 0; i < m.nodes.size(); ++i)
    {
        const NodeMean nm = node_mean(mesh, s0, eps0, failed0, i);
        const std::array<real_t, 6>& mean = nm.stress;
        const real_t eps = nm.eps, failed = nm.failed, v0 = nm.volume0;
        for (int c = 0; c < 6; ++c)
        {
            ds = std::max(ds, std::abs(st.stress[c * st.stress_stride + i] - mean[c]));
            smax = std::max(smax, std::abs(mean[c]));
        }
        deps = std::max(deps, std::abs(st.plastic.eps_p[i] - eps) / eps);
        wrong_flags += st.plastic.failed[i] != failed;
        dv = std::max(dv, std::abs(st.points.weight[i] - v0) / v0);
    }
    const real_t dp = (test::momentum(m.nodes) - p0).norm() / mv, dm = std::abs(total_mass(m.nodes) - mass0) / mass0;
    std::printf("fem-1pt box converted whole into semi-Lagrangian particles: stress off the mean %.2e of the largest, "
                "plastic strain %.2e, %d wrong flags, reference volume %.2e, mass %.2e, momentum %.2e\n",
                ds / smax, deps, static_cast<int>(wrong_flags), dv, dm, dp);
    EXPECT_LT(ds / smax, 1e-14);
    EXPECT_LT(deps, 1e-14);
    EXPECT_EQ(wrong_flags, 0);
    EXPECT_LT(dv, 1e-14);
    EXPECT_EQ(dm, 0.0); // the nodes' masses are not touched
    EXPECT_EQ(dp, 0.0);
}

TEST(ConversionSemiLagrangian, LinearFieldKeepsItsUniformStressAndTheCellsHoldTheVolume)
{
    // the box under a linear velocity field; after step 3 its upper half converts (48 elements),
    // after step 6 the next layer too (16: its particles at z = 3 mm take their lower octants and
    // blend them with what they hold). At each event the cells hold the converted elements'
    // current volume; every step after, the particles' stress is the FE elements' uniform stress
    // of the run that never converts, and the internal forces sum to zero
    const real_t A[3][3] = {{1.0, 0.3, -0.2}, {0.1, -0.5, 0.4}, {0.25, 0.2, 0.7}}; // 1/s
    const real_t dt = 1e-8;
    Model plain = test::model_from(box_1pt, to_sl), conv = test::model_from(box_1pt, to_sl);
    const SemiLagrangianForceBlock& sl = *conv.semi_lagrangian_block(0);
    real_t dvol = 0.0, ds = 0.0, smax = 0.0, fsum = 0.0;
    for (int step = 1; step <= 9; ++step)
    {
        if (step == 4 || step == 7)
        {
            // the converted elements' current volume: those above the cut, in the run that stays FE
            const real_t cut = step == 4 ? 3e-3 : 2e-3;
            const std::vector<char> above = elements_above(plain, cut);
            real_t v_elements = 0.0;
            for (index_t e = 0; e < plain.meshes[0].n_elements(); ++e)
                if (above[e])
                    v_elements += element_volume(plain.meshes[0], plain.nodes, e);
            ASSERT_EQ(conv.convert_elements(0, elements_above(conv, cut)), step == 4 ? 48 : 16);
            real_t v_cells = 0.0;
            for (index_t p = 0; p < sl.n_particles(); ++p)
                if (!sl.dormant(p))
                    v_cells += sl.volume(p);
            dvol = std::max(dvol, std::abs(v_cells - v_elements) / v_elements);
        }
        for (Model* m : {&plain, &conv})
        {
            test::linear_velocity_step(m->nodes, A, dt);
            m->compute_forces(step * dt, dt, step);
            m->commit();
        }
        if (step < 4)
            continue;
        const HexBlock& ref = plain.meshes[0];
        const NodalBlock& st = *sl.nodal_points();
        for (int k = 0; k < 6; ++k)
        {
            const real_t uniform = ref.stress[k * ref.stress_stride];
            smax = std::max(smax, std::abs(uniform));
            const HexBlock& fe = conv.meshes[0];
            for (index_t e = 0; e < fe.n_elements(); ++e)
                ds = std::max(ds, std::abs(fe.stress[k * fe.stress_stride + e] - uniform));
            for (index_t p = 0; p < sl.n_particles(); ++p)
                if (!sl.dormant(p))
                    ds = std::max(ds, std::abs(st.stress[k * st.stress_stride + p] - uniform));
        }
        Vec3 f = Vec3::Zero();
        real_t fmax = 0.0;
        for (index_t i = 0; i < conv.nodes.size(); ++i)
            for (int d = 0; d < 3; ++d)
            {
                f[d] += conv.nodes.f_int[3 * i + d];
                fmax = std::max(fmax, std::abs(conv.nodes.f_int[3 * i + d]));
            }
        fsum = std::max(fsum, f.norm() / fmax);
    }
    std::printf("fem-1pt box, upper half then one more layer into semi-Lagrangian particles: %d active, cells' "
                "volume off the elements' %.2e, stress off the uniform %.2e of it, sum of internal forces %.2e of "
                "the largest\n",
                static_cast<int>(sl.active_particles()), dvol, ds / smax, fsum);
    EXPECT_EQ(sl.active_particles(), 5 * 5 * 5);
    EXPECT_LT(dvol, 1e-13);
    EXPECT_LT(ds / smax, 1e-10);
    EXPECT_LT(fsum, 1e-12);
}

TEST(ConversionSemiLagrangian, FreeColumnConservesMomentumAndEnergyThroughConversions)
{
    // ConversionFem1pt's free column converting into semi-Lagrangian particles (the flags are per
    // element of the FE block that is left)
    expect_column_conserves(
        "fem-1pt free column into semi-Lagrangian particles",
        {"parts.column.formulation=fem-1pt", "parts.column.kinematics=semi-lagrangian", "time.dt_max=0.1us"});
}

TEST(ConversionSemiLagrangian, DeckErrorsNameTheKey)
{
    auto error = [](const std::vector<std::string>& sets)
    {
        std::vector<std::string> all = to_sl;
        all.insert(all.end(), sets.begin(), sets.end());
        return test::model_error(box_1pt, all);
    };
    EXPECT_NE(error({"parts.b.conversion.revert={damage: 0.1}"}).find("parts.b.conversion"), std::string::npos);
    EXPECT_NE(error({"parts.b.semi_lagrangian={reset_interval: 10}"}).find("reset_interval"), std::string::npos);
    EXPECT_NE(error({"parts.b.formulation=fem-nodal"}).find("parts.b.kinematics"), std::string::npos);
    EXPECT_NE(error({"parts.b.conversion=~"}).find("parts.b.kinematics"), std::string::npos);
    EXPECT_EQ(error({}), "");
}

TEST(ConversionSemiLagrangian, KernelSelfContactTakesNoDormantParticle)
{
    // the box with kernel self-contact (fragments meeting the body), squeezed along z: while its
    // particles are dormant (FE nodes) none takes part in a pair, though their cubes press into each
    // other; once the box has converted and a failed particle separates, it meets its neighbours
    Model m = test::model_from(
        box_1pt, {"parts.b.kinematics=semi-lagrangian", "parts.b.semi_lagrangian={separation_damage: 0.5}",
                  "contacts=[{type: kernel, surfaces: [b]}]", "time.stepper=central-difference"});
    for (index_t i = 0; i < m.nodes.size(); ++i)
        m.nodes.v[3 * i + 2] = -2e3 * (m.nodes.x0[3 * i + 2] - 3e-3); // 2e3 1/s toward the middle
    const auto& contact = dynamic_cast<const KernelContact&>(*m.contacts[0]);
    CentralDifference cd;
    StepReport r = cd.initialize(m, 0.0);
    real_t t = 0.0;
    index_t dormant_pairs = 0;
    for (int k = 1; k <= 5; ++k)
    {
        r = cd.step(m, t, 1e-8, k);
        t = r.t;
        dormant_pairs += contact.pairs();
    }
    m.refresh_motion();
    const index_t ne = m.meshes[0].n_elements();
    ASSERT_EQ(m.convert_elements(0, std::vector<char>(static_cast<std::size_t>(ne), 1)), ne);
    // the particle at the middle of the box fails: it separates at the next commit
    const SemiLagrangianForceBlock& sl = *m.semi_lagrangian_block(0);
    index_t middle = -1;
    for (index_t i = 0; i < m.nodes.size(); ++i)
        if (std::abs(m.nodes.x0[3 * i] - 2e-3) + std::abs(m.nodes.x0[3 * i + 1] - 2e-3) +
                std::abs(m.nodes.x0[3 * i + 2] - 3e-3) <
            1e-9)
            middle = i;
    ASSERT_GE(middle, 0);
    m.semi_lagrangian_block(0)->nodal_points()->plastic.failed[static_cast<std::size_t>(middle)] = 1.0;
    r.dt_stable = m.restart_after_event(cd, t, 1e-8);
    index_t fragment_pairs = 0;
    for (int k = 6; k <= 10; ++k)
    {
        r = cd.step(m, t, 1e-8, k);
        t = r.t;
        fragment_pairs += contact.pairs();
    }
    std::printf("kernel self-contact on a converting box: %d pairs over 5 steps while dormant, %d over 5 steps once "
                "converted with %d separated particle(s)\n",
                static_cast<int>(dormant_pairs), static_cast<int>(fragment_pairs),
                static_cast<int>(sl.free_particles()));
    EXPECT_EQ(dormant_pairs, 0);
    EXPECT_EQ(sl.free_particles(), 1);
    EXPECT_GT(fragment_pairs, 0);
}
