// The fast kernels against their plain scalar twins (operators/kernels/*_reference.hpp), to
// round-off, from a random committed state and random motion: the batched 1-point hex kernel
// (mode basis, lane vectors, chunked scatter) against hex1pt_reference element by element for
// every hourglass form, elastic and with each inelastic model (J2, K&C, CSCM: the point update
// and the stiffness forms' plastic scaling); the nodal force pass (SCNI + MSCNI or NSNI, own and shared stencils,
// whole-vector rows) against nodal_reference for RK and FE functions; both with bulk viscosity, scatter and gather
// assembly.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "../support.hpp"
#include "rkfem/model/material_from_deck.hpp"
#include "rkfem/model/nodal_block_build.hpp"
#include "rkfem/operators/kernels/hex1pt_reference.hpp"
#include "rkfem/operators/kernels/nodal_reference.hpp"
#include "rkfem/operators/nodal_force.hpp"

using namespace rkfem;

namespace
{
/// Random small displacements (x = x0 + u, |u| up to u_max) and velocities up to 20 m/s.
void random_motion(NodeSet& nodes, std::mt19937& gen, real_t u_max)
{
    std::uniform_real_distribution<real_t> rnd(-1.0, 1.0);
    for (std::size_t j = 0; j < nodes.u.size(); ++j)
    {
        nodes.u[j] = u_max * rnd(gen);
        nodes.x[j] = nodes.x0[j] + nodes.u[j];
        nodes.v[j] = 20.0 * rnd(gen);
    }
}

struct Compared
{
    real_t force = 0.0, stress = 0.0, hourglass = 0.0, energy = 0.0, dt = 0.0; ///< max relative differences
    real_t history = 0.0;  ///< inelastic blocks: the trial plastic strain and damage, max relative difference
    index_t inelastic = 0; ///< elements whose update left the elastic path (plastic strain grew)
};

/// The scale of the random committed stresses for a model (test::block_material's): about half
/// the inelastic points flow in the step.
real_t stress_draw(const std::string& model)
{
    return model == "elastic" ? 1e8 : model == "j2" ? 3e8 : model == "kcc" ? 5e6 : 3e7;
}

/// The CSCM returns its own undamaged stress: its committed one is the block's drawn stress
/// (as the damaged one, undamaged). Nothing for other models.
void cscm_stress_from_block(PlasticPoints& pp, const real_t* stress, std::size_t stride)
{
    for (std::size_t p = 0; p < pp.cscm_state.size(); ++p)
        for (int k = 0; k < 6; ++k)
            pp.cscm_state[p].svp[k] = stress[k * stride + p];
}

/// The trial plastic strain and damage of `ref` (the plain twin's) against `fast`'s over n
/// points: the larger of their max relative differences; `flowing` counts the points whose
/// plastic strain grew.
real_t history_difference(const PlasticPoints& ref, const PlasticPoints& fast, std::size_t n, index_t& flowing)
{
    real_t e_max = 0.0, d_max = 0.0, e_diff = 0.0, d_diff = 0.0;
    for (std::size_t p = 0; p < n; ++p)
    {
        e_max = std::max(e_max, std::abs(ref.eps_p_trial[p]));
        d_max = std::max(d_max, std::abs(ref.failed_trial[p]));
        e_diff = std::max(e_diff, std::abs(ref.eps_p_trial[p] - fast.eps_p_trial[p]));
        d_diff = std::max(d_diff, std::abs(ref.failed_trial[p] - fast.failed_trial[p]));
        flowing += ref.eps_p_trial[p] > ref.eps_p[p] ? 1 : 0;
    }
    return std::max(e_max > 0 ? e_diff / e_max : 0.0, d_max > 0 ? d_diff / d_max : 0.0);
}

Compared compare_hex1pt(HourglassType hg, Assembly assembly, const std::string& model = "elastic")
{
    // 5^3 = 125 elements: 15 full batches of 8 and a partial one
    const HexMesh mesh = test::distorted_box(5, 0.01, 0.25);
    NodeSet nodes;
    const MaterialSpec ms = test::block_material(model);
    HexBlock blk = test::make_block(mesh, nodes, Formulation::Fem1pt, {hg, 0.1},
                                    ElasticParams::from_E_nu(ms.rho, ms.E, ms.nu), {0.06, 1.5});
    configure_points(blk.plastic, ms);
    blk.initialize(nodes, assembly);
    std::mt19937 gen(17);
    std::uniform_real_distribution<real_t> rnd(-1.0, 1.0);
    random_motion(nodes, gen, 4e-4);
    const std::size_t ne = static_cast<std::size_t>(blk.n_elements());
    const real_t s_draw = stress_draw(model);
    for (int k = 0; k < 6; ++k)
        for (std::size_t e = 0; e < ne; ++e)
            blk.stress[k * blk.stress_stride + e] = s_draw * rnd(gen);
    cscm_stress_from_block(blk.plastic, blk.stress.data(), blk.stress_stride);
    for (auto& q : blk.hg_force)
        q = 1e3 * rnd(gen);
    // assumed strain: the frame sizes the forces were stored at, about the elements' own (4 x 2 mm)
    // but off by up to half, so that assumed_strain_keep scales some forces down
    for (std::size_t k = 12 * ne; k < blk.hg_force.size(); ++k)
        blk.hg_force[k] = 8e-3 * (1.0 + 0.5 * rnd(gen));
    const real_t dt = 1e-8;
    PlasticPoints history = blk.plastic; // the reference's own trial history
    const ForcePassResult fast = hex_internal_force(blk, nodes, dt);
    std::fill(nodes.f_int.begin(), nodes.f_int.end(), 0.0);
    assemble_block_forces(blk, nodes);

    std::vector<real_t> f_ref(nodes.f_int.size(), 0.0);
    real_t d_int = 0.0, d_hg = 0.0, d_bv = 0.0, dt_min = 1e300;
    Compared c;
    real_t s_scale = 0.0, q_scale = 0.0;
    for (std::size_t e = 0; e < ne; ++e)
    {
        const Hex1ptElement r = hex1pt_reference(blk, nodes, static_cast<index_t>(e), dt, &history);
        for (int I = 0; I < 8; ++I)
            for (int d = 0; d < 3; ++d)
                f_ref[3 * static_cast<std::size_t>(blk.conn[8 * e + I]) + d] += r.f[I][d];
        for (int k = 0; k < 6; ++k)
        {
            s_scale = std::max(s_scale, std::abs(r.stress[k]));
            c.stress = std::max(c.stress, std::abs(blk.stress_trial[k * blk.stress_stride + e] - r.stress[k]));
        }
        if (hg == HourglassType::AssumedStrain)
        {
            for (int i = 0; i < 3; ++i)
            {
                EXPECT_NEAR(blk.hg_force_trial[(HexBlock::kHgSizeRow + i) * ne + e], r.hg_size[i], 1e-14 * r.hg_size[i])
                    << "element " << e;
            }
        }
        if (hg == HourglassType::Stiffness || hg == HourglassType::AssumedStrain)
            for (int a = 0; a < 4; ++a)
                for (int i = 0; i < 3; ++i)
                {
                    q_scale = std::max(q_scale, std::abs(r.hg_force[a][i]));
                    c.hourglass =
                        std::max(c.hourglass, std::abs(blk.hg_force_trial[(3 * a + i) * ne + e] - r.hg_force[a][i]));
                }
        d_int += r.d_internal;
        d_hg += r.d_hourglass;
        d_bv += r.d_bulk_viscosity;
        dt_min = std::min(dt_min, r.dt_stable);
    }
    c.stress /= s_scale;
    c.hourglass = q_scale > 0 ? c.hourglass / q_scale : 0.0;
    if (blk.plastic.active())
        c.history = history_difference(history, blk.plastic, ne, c.inelastic);
    real_t f_scale = 0.0;
    for (std::size_t j = 0; j < f_ref.size(); ++j)
    {
        f_scale = std::max(f_scale, std::abs(f_ref[j]));
        c.force = std::max(c.force, std::abs(nodes.f_int[j] - f_ref[j]));
    }
    c.force /= f_scale;
    const real_t e_scale = std::abs(d_int) + std::abs(d_hg) + std::abs(d_bv);
    c.energy = (std::abs(fast.d_internal - d_int) + std::abs(fast.d_hourglass - d_hg) +
                std::abs(fast.d_bulk_viscosity - d_bv)) /
               e_scale;
    c.dt = std::abs(fast.dt_stable - dt_min) / dt_min;
    EXPECT_GT(std::abs(d_bv), 0.0); // some elements compress: bulk viscosity acts
    if (hg != HourglassType::None)
    {
        EXPECT_GT(std::abs(d_hg), 0.0);
    }
    return c;
}

const char* name(HourglassType t)
{
    switch (t)
    {
    case HourglassType::None:
        return "none";
    case HourglassType::Viscous:
        return "viscous";
    case HourglassType::Stiffness:
        return "stiffness";
    case HourglassType::ViscousPlain:
        return "viscous-plain";
    case HourglassType::AssumedStrain:
        return "assumed-strain";
    }
    return "?";
}
} // namespace

class Hex1ptReference : public ::testing::TestWithParam<HourglassType>
{
};

TEST_P(Hex1ptReference, FastKernelEqualsThePlainOneToRoundOff)
{
    for (Assembly a : {Assembly::Scatter, Assembly::Gather})
    {
        const Compared c = compare_hex1pt(GetParam(), a);
        std::printf("hourglass %-13s %s: max relative difference force %.1e, stress %.1e, hourglass force %.1e, "
                    "energies %.1e, stable step %.1e\n",
                    name(GetParam()), a == Assembly::Scatter ? "scatter" : "gather ", c.force, c.stress, c.hourglass,
                    c.energy, c.dt);
        EXPECT_LT(c.force, 1e-12);
        EXPECT_LT(c.stress, 1e-12);
        EXPECT_LT(c.hourglass, 1e-12);
        EXPECT_LT(c.energy, 1e-12);
        EXPECT_LT(c.dt, 1e-12);
    }
}

// The plastic twins: each inelastic model in a block with the stiffness forms (whose increments
// it scales where the material flows) and the viscous form. Round-off in the strain rate
// (the fast kernel forms it in the mode basis) moves the return mapping by about as much: the
// bound is the elastic one, 1e-12. The CSCM's return iterates until the yield function is below
// 1e-8 J2 (materials/cscm_concrete.cpp), so a round-off change in the strain rate can stop it an
// iterate apart: its bound is that tolerance, 1e-8. Only J2 has an elastic fast path
// (j2_elastic_lanes): its draw leaves some points elastic.
class Hex1ptReferenceInelastic : public ::testing::TestWithParam<std::tuple<std::string, HourglassType>>
{
};

TEST_P(Hex1ptReferenceInelastic, FastKernelEqualsThePlainOneToRoundOff)
{
    const auto& [model, hg] = GetParam();
    for (Assembly a : {Assembly::Scatter, Assembly::Gather})
    {
        const Compared c = compare_hex1pt(hg, a, model);
        std::printf("%-4s hourglass %-13s %s: %d of 125 elements flow; max relative difference force %.1e, stress "
                    "%.1e, hourglass force %.1e, energies %.1e, stable step %.1e, history %.1e\n",
                    model.c_str(), name(hg), a == Assembly::Scatter ? "scatter" : "gather ",
                    static_cast<int>(c.inelastic), c.force, c.stress, c.hourglass, c.energy, c.dt, c.history);
        EXPECT_GT(c.inelastic, 10) << "the comparison should exercise the inelastic return";
        if (model == "j2")
        {
            EXPECT_LT(c.inelastic, 125) << "and the elastic lanes";
        }
        const real_t bound = model == "cscm" ? 1e-8 : 1e-12;
        EXPECT_LT(c.force, bound);
        EXPECT_LT(c.stress, bound);
        EXPECT_LT(c.hourglass, bound);
        EXPECT_LT(c.energy, bound);
        EXPECT_LT(c.dt, 1e-12);
        EXPECT_LT(c.history, bound);
    }
}

INSTANTIATE_TEST_SUITE_P(Models, Hex1ptReferenceInelastic,
                         ::testing::Combine(::testing::Values("j2", "kcc", "cscm"),
                                            ::testing::Values(HourglassType::Viscous, HourglassType::Stiffness,
                                                              HourglassType::AssumedStrain)),
                         [](const auto& info)
                         {
                             std::string s = std::get<0>(info.param) + std::string("_") + name(std::get<1>(info.param));
                             for (char& ch : s)
                                 if (ch == '-')
                                     ch = '_';
                             return s;
                         });

INSTANTIATE_TEST_SUITE_P(Forms, Hex1ptReference,
                         ::testing::Values(HourglassType::None, HourglassType::Viscous, HourglassType::Stiffness,
                                           HourglassType::ViscousPlain, HourglassType::AssumedStrain),
                         [](const auto& info)
                         {
                             std::string s = name(info.param);
                             for (char& ch : s)
                                 if (ch == '-')
                                     ch = '_';
                             return s;
                         });

namespace
{
struct NodalCompared
{
    real_t force = 0.0, stress = 0.0, stab_stress = 0.0, energy = 0.0, dt = 0.0;
    real_t history = 0.0;   ///< inelastic blocks: the trial plastic strain and damage, max relative difference
    index_t inelastic = 0;  ///< points whose plastic strain grew
    real_t stab_work = 0.0; ///< the reference's stabilization work of the step
};

/// An rkpm block (SCNI + MSCNI) on a jittered (own stencils) or regular (shared stencils,
/// whole-vector batches along rows) mesh, a random committed state and motion.
NodalCompared compare_nodal(Formulation form, real_t jitter, Assembly assembly, real_t bulk_linear,
                            real_t bulk_quadratic, const std::string& stab = "mscni",
                            const std::string& model = "elastic", bool plastic_scaling = false)
{
    PartSpec ps = test::steel_nodal_part(form, "scni", stab);
    ps.nodal.plastic_scaling = plastic_scaling;
    if (model != "elastic")
        ps.material = test::block_material(model);
    ps.nodal.stabilization_coefficient = stab == "nsni" ? 0.25 : 1.0;
    // jittered: the default drop tolerance (27-entry stencils of their own); regular: full
    // stencils, which this 7^3 box shares (with the drop, its boundary layers leave too many
    // classes for sharing to pay)
    ps.rk.drop_tolerance = jitter > 0 ? 1e-5 : 0.0;
    ps.bulk_viscosity = {bulk_linear, bulk_quadratic};
    const HexMesh mesh = test::distorted_box(7, 0.01, jitter);
    NodeSet nodes;
    nodes.resize(mesh.n_nodes());
    nodes.x0 = nodes.x = mesh.x;
    NodalBlock blk = build_nodal_block(ps, mesh, 0);
    blk.initialize(assembly);
    std::mt19937 gen(23);
    std::uniform_real_distribution<real_t> rnd(-1.0, 1.0);
    random_motion(nodes, gen, 2e-4);
    const real_t s_draw = stress_draw(model);
    for (int k = 0; k < 6; ++k)
    {
        for (index_t p = 0; p < blk.n_points(); ++p)
            blk.stress[k * blk.stress_stride + p] = s_draw * rnd(gen);
        for (index_t s = 0; s < blk.n_stab(); ++s)
            blk.stab_stress[k * blk.n_stab() + s] = 0.1 * s_draw * rnd(gen);
    }
    cscm_stress_from_block(blk.plastic, blk.stress.data(), blk.stress_stride);
    const real_t dt = 1e-8;
    PlasticPoints history = blk.plastic; // the reference's own trial history
    const ForcePassResult fast = nodal_internal_force(blk, nodes, dt);
    std::fill(nodes.f_int.begin(), nodes.f_int.end(), 0.0);
    assemble_nodal_forces(blk, nodes);
    const NodalPass ref = nodal_reference(blk, nodes, dt, &history);
    NodalCompared c;
    if (blk.plastic.active())
        c.history = history_difference(history, blk.plastic, static_cast<std::size_t>(blk.n_points()), c.inelastic);
    auto rel = [](auto get_fast, const std::vector<real_t>& r, std::size_t n)
    {
        real_t scale = 0.0, diff = 0.0;
        for (std::size_t i = 0; i < n; ++i)
        {
            scale = std::max(scale, std::abs(r[i]));
            diff = std::max(diff, std::abs(get_fast(i) - r[i]));
        }
        return diff / scale;
    };
    c.force = rel([&](std::size_t i) { return nodes.f_int[i]; }, ref.f, ref.f.size());
    c.stress = rel([&](std::size_t i) { return blk.stress_trial[(i % 6) * blk.stress_stride + i / 6]; }, ref.stress,
                   ref.stress.size());
    c.stab_stress = rel([&](std::size_t i) { return blk.stab_stress_trial[(i % 6) * blk.n_stab() + i / 6]; },
                        ref.stab_stress, ref.stab_stress.size());
    c.energy = (std::abs(fast.d_internal - ref.d_internal) + std::abs(fast.d_hourglass - ref.d_stabilization) +
                std::abs(fast.d_bulk_viscosity - ref.d_bulk_viscosity)) /
               (std::abs(ref.d_internal) + std::abs(ref.d_stabilization) + std::abs(ref.d_bulk_viscosity));
    c.dt = std::abs(fast.dt_stable - ref.dt_stable) / ref.dt_stable;
    c.stab_work = ref.d_stabilization;
    EXPECT_EQ(blk.point_stencils.empty(), jitter > 0); // the shared-stencil path is exercised on the regular mesh
    return c;
}
} // namespace

TEST(NodalReference, FastPassEqualsThePlainOneToRoundOff)
{
    // the same algebra, with bulk viscosity; the fast pass takes J^(1/3) from two Newton steps
    // where |J - 1| < 0.25 (relative error below 1e-7 there, far less at these strains), so the
    // stable step is compared at 1e-6
    // NSNI: the fast pass forms a point's three sub-points in its batch from the six distinct
    // Hessian entries (nsni_batch), the plain one each sub-point by itself
    struct Case
    {
        Formulation form;
        const char* stab;
    };
    for (const Case& k :
         {Case{Formulation::Rkpm, "mscni"}, Case{Formulation::Rkpm, "nsni"}, Case{Formulation::FemNodal, "mscni"}})
        for (real_t jitter : {0.3, 0.0})
            for (Assembly a : {Assembly::Scatter, Assembly::Gather})
            {
                const NodalCompared c = compare_nodal(k.form, jitter, a, 0.06, 1.5, k.stab);
                std::printf("%s + %s, %s, %s: max relative difference force %.1e, stress %.1e, sub-cell stress %.1e, "
                            "energies %.1e, stable step %.1e\n",
                            k.form == Formulation::Rkpm ? "rkpm     " : "fem-nodal", k.stab,
                            jitter > 0 ? "jittered" : "regular ", a == Assembly::Scatter ? "scatter" : "gather ",
                            c.force, c.stress, c.stab_stress, c.energy, c.dt);
                EXPECT_LT(c.force, 1e-12);
                EXPECT_LT(c.stress, 1e-12);
                // round-off of sums over 50-200 entries (at most 4e-16 seen): NSNI's sub-points
                // on shared stencils once differed from the plain pass by 3.2e-14, when their
                // gradients were snapped one class at a time and lost their symmetry
                EXPECT_LT(c.stab_stress, 1e-14);
                EXPECT_LT(c.energy, 1e-12);
                EXPECT_LT(c.dt, 1e-6);
            }
}

TEST(BlockTables, RebuildingThemKeepsTheState)
{
    // tables are separate from state: after build_tables() the same committed state and motion
    // give the same bits, for a 1-point hex block and a nodal block
    std::mt19937 gen(29);
    std::uniform_real_distribution<real_t> rnd(-1.0, 1.0);
    const HexMesh mesh = test::distorted_box(5, 0.01, 0.25);
    {
        NodeSet nodes;
        HexBlock blk = test::make_block(mesh, nodes, Formulation::Fem1pt, {HourglassType::Stiffness, 0.05},
                                        ElasticParams::from_E_nu(7850, 200e9, 0.3));
        random_motion(nodes, gen, 2e-4);
        for (auto& q : blk.hg_force)
            q = 1e3 * rnd(gen);
        for (std::size_t k = 0; k < blk.stress.size(); ++k)
            blk.stress[k] = 1e8 * rnd(gen);
        const auto stress = blk.stress;
        hex_internal_force(blk, nodes, 1e-8);
        assemble_block_forces(blk, nodes);
        const std::vector<real_t> f1 = nodes.f_int;
        blk.build_tables(nodes);
        EXPECT_TRUE(blk.stress == stress);
        hex_internal_force(blk, nodes, 1e-8);
        assemble_block_forces(blk, nodes);
        EXPECT_TRUE(nodes.f_int == f1) << "hex block";
    }
    {
        NodeSet nodes;
        nodes.resize(mesh.n_nodes());
        nodes.x0 = nodes.x = mesh.x;
        NodalBlock blk = build_nodal_block(test::steel_nodal_part(Formulation::Rkpm), mesh, 0);
        random_motion(nodes, gen, 2e-4);
        for (std::size_t k = 0; k < blk.stress.size(); ++k)
            blk.stress[k] = 1e8 * rnd(gen);
        for (auto& s : blk.stab_stress)
            s = 1e7 * rnd(gen);
        const auto stress = blk.stress;
        const auto stab = blk.stab_stress;
        nodal_internal_force(blk, nodes, 1e-8);
        assemble_nodal_forces(blk, nodes);
        const std::vector<real_t> f1 = nodes.f_int;
        blk.build_tables();
        EXPECT_TRUE(blk.stress == stress && blk.stab_stress == stab);
        nodal_internal_force(blk, nodes, 1e-8);
        assemble_nodal_forces(blk, nodes);
        EXPECT_TRUE(nodes.f_int == f1) << "nodal block";
    }
}

// The nodal pass's plastic twins: each inelastic model on the jittered RK block (own stencils)
// with MSCNI and on the regular one (shared stencils, whole-vector rows) with NSNI, scatter
// and gather. Bounds as for the hexahedra (CSCM: its return's yield tolerance, 1e-8).
TEST(NodalReference, InelasticFastPassEqualsThePlainOne)
{
    for (const std::string model : {"j2", "kcc", "cscm"})
        for (const auto& [jitter, stab] : {std::pair<real_t, std::string>{0.25, "mscni"}, {0.0, "nsni"}})
            for (Assembly a : {Assembly::Scatter, Assembly::Gather})
            {
                const NodalCompared c = compare_nodal(Formulation::Rkpm, jitter, a, 0.06, 1.5, stab, model);
                std::printf("%-4s %s %s %s: %d points flow; max relative difference force %.1e, stress %.1e, "
                            "sub-cell stress %.1e, energies %.1e, history %.1e\n",
                            model.c_str(), jitter > 0 ? "jittered" : "regular ", stab.c_str(),
                            a == Assembly::Scatter ? "scatter" : "gather ", static_cast<int>(c.inelastic), c.force,
                            c.stress, c.stab_stress, c.energy, c.history);
                EXPECT_GT(c.inelastic, 10) << model;
                const real_t bound = model == "cscm" ? 1e-8 : 1e-12;
                EXPECT_LT(c.force, bound) << model;
                EXPECT_LT(c.stress, bound) << model;
                EXPECT_LT(c.stab_stress, 1e-12) << model;
                EXPECT_LT(c.energy, bound) << model;
                EXPECT_LT(c.history, bound) << model;
            }
}

// The stabilization's plastic scaling (nodal_integration.plastic_scaling): the fast pass's shares
// (in the points' batches, NSNI's sub-points in the same batch or the own pass's sub-cells) against
// the plain twin's, to the bounds above; and the scaling changes the step's stabilization work
// where points flow (at least 1e-3 of it), so the comparison is not of two unscaled passes.
TEST(NodalReference, PlasticScalingOfTheStabilizationEqualsThePlainOne)
{
    for (const std::string model : {"j2", "kcc"})
        for (const auto& [jitter, stab] : {std::pair<real_t, std::string>{0.25, "mscni"}, {0.0, "nsni"}})
            for (Assembly a : {Assembly::Scatter, Assembly::Gather})
            {
                const NodalCompared c = compare_nodal(Formulation::Rkpm, jitter, a, 0.06, 1.5, stab, model, true);
                const NodalCompared off = compare_nodal(Formulation::Rkpm, jitter, a, 0.06, 1.5, stab, model, false);
                const real_t change = std::abs(c.stab_work - off.stab_work) / std::abs(off.stab_work);
                std::printf("%-4s %s %s %s, scaled: %d points flow; max relative difference force %.1e, stress %.1e, "
                            "sub-cell stress %.1e, energies %.1e; stabilization work %.3e J against %.3e unscaled\n",
                            model.c_str(), jitter > 0 ? "jittered" : "regular ", stab.c_str(),
                            a == Assembly::Scatter ? "scatter" : "gather ", static_cast<int>(c.inelastic), c.force,
                            c.stress, c.stab_stress, c.energy, c.stab_work, off.stab_work);
                EXPECT_GT(c.inelastic, 10) << model;
                EXPECT_LT(c.force, 1e-12) << model;
                EXPECT_LT(c.stress, 1e-12) << model;
                EXPECT_LT(c.stab_stress, 1e-12) << model;
                EXPECT_LT(c.energy, 1e-12) << model;
                EXPECT_GT(change, 1e-3) << model << ": the scaling changed nothing";
            }
}
