// Adaptive refinement and coarsening of semi-Lagrangian RK particles (issue #49; deck key
// parts.*.refinement; Model::refine_particles, Model::coarsen_particles): a particle splits into
// the eight half-size parallelepipeds of its cell, taking seven dormant particles of the part's
// pool; eight siblings merge back. What theory says, measured here:
//   - mass is conserved exactly and momentum to round-off, through splits and merges;
//   - a linear displacement and velocity field carries over to the children to round-off (their
//     u and v come from the particle's smoothed gradients, which reproduce linear fields);
//   - a uniform stress stays uniform: the children's cells tile the parent's, so the integration
//     constraint holds where it held, and the interior's internal forces stay zero to round-off;
//   - a split undone by a merge with no motion between gives the particle back exactly;
//   - a uniaxial-strain wave refined as it crosses a region keeps its plateau (within 1 %),
//     reflects under 1 % of its amplitude and keeps the ledger within 0.5 %.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "../support.hpp"
#include "rkfem/operators/semi_lagrangian_block.hpp"
#include "rkfem/run/simulation.hpp"

using namespace rkfem;

namespace
{
/// An 8 x 8 x 8 mm elastic box of semi-Lagrangian particles (1 mm spacing) with a pool for 28
/// splits.
const char* box = R"(
time: {end: 1 s}
parts:
  b:
    generator: {type: box, size: [8 mm, 8 mm, 8 mm], divisions: [8, 8, 8]}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: rkpm
    kinematics: semi-lagrangian
    nodal_integration: {scheme: snni}
    bulk_viscosity: {linear: 0, quadratic: 0}
    refinement: {pressure: 1 GPa, max_level: 2, max_new_particles: 196}
)";

Vec3 at(const std::vector<real_t>& a, index_t i)
{
    return {a[3 * i], a[3 * i + 1], a[3 * i + 2]};
}

using test::total_mass;

/// Flags for the particles (of the part's start) whose reference position lies within `half`
/// of the box's centre along each axis.
std::vector<char> central(const Model& m, real_t half)
{
    const PartInfo& p = m.parts[0];
    std::vector<char> f(static_cast<std::size_t>(p.node_end - p.node_begin), 0);
    for (index_t i = p.node_begin; i < p.mesh_node_end; ++i)
        f[static_cast<std::size_t>(i - p.node_begin)] =
            (at(m.nodes.x0, i) - Vec3(4e-3, 4e-3, 4e-3)).cwiseAbs().maxCoeff() <= half + 1e-9;
    return f;
}
} // namespace

TEST(Refinement, SplitsConserveMassAndMomentumAndCarryALinearField)
{
    // u = A X and v = B x + c on the box (x = X + u), then the 27 central particles split: each
    // child's u is A X_k of its own reference position and its v the field at its position, to
    // round-off; the total mass is what it was exactly and the momentum to round-off
    Model m = test::model_from(box);
    const real_t A[3][3] = {{0.02, 0.01, -0.005}, {0.003, -0.01, 0.008}, {0.006, 0.004, 0.015}};
    const real_t B[3][3] = {{300, -120, 50}, {80, 200, -60}, {-40, 90, -250}}; // 1/s
    const Vec3 c(3.0, -2.0, 1.0);                                              // m/s
    auto v_field = [&](const Vec3& x)
    {
        Vec3 v = c;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                v[i] += B[i][j] * x[j];
        return v;
    };
    const PartInfo& part = m.parts[0];
    for (index_t i = part.node_begin; i < part.mesh_node_end; ++i)
        for (int d = 0; d < 3; ++d)
        {
            real_t u = 0.0;
            for (int j = 0; j < 3; ++j)
                u += A[d][j] * m.nodes.x0[3 * i + j];
            m.nodes.u[3 * i + d] = u;
            m.nodes.x[3 * i + d] = m.nodes.x0[3 * i + d] + u;
        }
    for (index_t i = part.node_begin; i < part.mesh_node_end; ++i)
    {
        const Vec3 v = v_field(at(m.nodes.x, i));
        for (int d = 0; d < 3; ++d)
            m.nodes.v[3 * i + d] = v[d];
    }
    const real_t mass0 = total_mass(m.nodes);
    const Vec3 p0 = test::momentum(m.nodes);
    const real_t scale = test::momentum_scale(m.nodes);
    const SemiLagrangianForceBlock& sl = *m.semi_lagrangian_block(0);
    const index_t active0 = sl.active_particles();
    ASSERT_EQ(m.refine_particles(0, central(m, 1e-3)), 27);
    EXPECT_EQ(sl.active_particles(), active0 + 27 * 7);
    EXPECT_EQ(m.refined_particles(), 27);
    real_t du = 0.0, dv = 0.0, umax = 0.0, vmax = 0.0, dvol = 0.0;
    for (const auto& f : m.families(0))
    {
        real_t vol = 0.0;
        for (const index_t p : f)
        {
            const index_t g = part.node_begin + p;
            EXPECT_EQ(sl.level(p), 1);
            const Vec3 X = at(m.nodes.x0, g), x = at(m.nodes.x, g);
            Vec3 u_exact = Vec3::Zero();
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    u_exact[i] += A[i][j] * X[j];
            du = std::max(du, (at(m.nodes.u, g) - u_exact).cwiseAbs().maxCoeff());
            dv = std::max(dv, (at(m.nodes.v, g) - v_field(x)).cwiseAbs().maxCoeff());
            umax = std::max(umax, u_exact.cwiseAbs().maxCoeff());
            vmax = std::max(vmax, v_field(x).cwiseAbs().maxCoeff());
            vol += sl.volume(p);
        }
        // the children's cells tile the parent's, an interior dual box of 1 mm^3 (no step has
        // moved the cells)
        dvol = std::max(dvol, std::abs(vol / 1e-9 - 1.0));
    }
    // each family's masses sum to its parent's exactly (m / 8 is exact in binary); the total, summed
    // in another order, to round-off
    for (const auto& f : m.families(0))
    {
        real_t s = 0.0;
        for (const index_t p : f)
            s += m.nodes.mass[part.node_begin + p];
        EXPECT_EQ(s, 8.0 * m.nodes.mass[part.node_begin + f[0]]);
    }
    const real_t dm = std::abs(total_mass(m.nodes) - mass0) / mass0, dp = (test::momentum(m.nodes) - p0).norm() / scale;
    std::printf("27 central particles of the box split under u = A X, v = B x + c: children's u off A X %.2e and v "
                "off the field %.2e of the largest, cells' volume off the parent's %.2e, mass %.2e, momentum %.2e\n",
                du / umax, dv / vmax, dvol, dm, dp);
    EXPECT_LT(du / umax, 1e-12);
    EXPECT_LT(dv / vmax, 1e-12);
    EXPECT_LT(dvol, 1e-12);
    EXPECT_LT(dm, 1e-13);
    EXPECT_LT(dp, 1e-14);
    // a second level: one child splits again; a third is refused by max_level 2
    std::vector<char> again(static_cast<std::size_t>(part.node_end - part.node_begin), 0);
    const index_t child = m.families(0)[13][3];
    again[static_cast<std::size_t>(child)] = 1;
    ASSERT_EQ(m.refine_particles(0, again), 1);
    EXPECT_EQ(sl.level(child), 2);
    EXPECT_EQ(m.refine_particles(0, again), 0);
    EXPECT_LT((test::momentum(m.nodes) - p0).norm() / scale, 1e-14);
}

TEST(Refinement, AUniformStressStaysUniformAndTheInteriorFeelsNoForce)
{
    // a uniform stress in every particle, at rest: after the central 27 split, every particle
    // holds it still, and the internal forces on the particles whose supports reach no boundary
    // (the children among them) are zero to round-off: the children's cells tile their parents'
    Model m = test::model_from(box);
    NodalBlock& st = *m.semi_lagrangian_block(0)->nodal_points();
    const real_t sigma[6] = {-120e6, 80e6, -40e6, 30e6, -25e6, 15e6};
    for (index_t p = 0; p < st.n_points(); ++p)
        for (int k = 0; k < 6; ++k)
            st.stress[k * st.stress_stride + p] = st.stress_trial[k * st.stress_stride + p] = sigma[k];
    ASSERT_EQ(m.refine_particles(0, central(m, 1e-3)), 27);
    m.compute_forces(0.0, 0.0, 0);
    const SemiLagrangianForceBlock& sl = *m.semi_lagrangian_block(0);
    const PartInfo& part = m.parts[0];
    real_t f_interior = 0.0, f_interface = 0.0, f_all = 0.0, ds = 0.0;
    index_t interior = 0;
    for (index_t p = 0; p < sl.n_particles(); ++p)
    {
        if (sl.dormant(p))
            continue;
        const index_t g = part.node_begin + p;
        const real_t f = at(m.nodes.f_int, g).cwiseAbs().maxCoeff();
        f_all = std::max(f_all, f);
        const real_t r = (at(m.nodes.x, g) - Vec3(4e-3, 4e-3, 4e-3)).cwiseAbs().maxCoeff();
        if (r < 0.5e-3)
        {
            ++interior;
            f_interior = std::max(f_interior, f);
        }
        else if (r < 1.6e-3)
            f_interface = std::max(f_interface, f);
        for (int k = 0; k < 6; ++k)
            ds = std::max(ds, std::abs(st.stress[k * st.stress_stride + p] - sigma[k]) / 120e6);
    }
    const real_t traction = 120e6 * 1e-6; // the largest stress on a 1 mm^2 face [N]
    std::printf("uniform stress through 27 splits: the %d children inside the refined block (all their neighbours' "
                "cells refined) feel %.2e of a face's traction, those at the interface with unrefined cells %.2e, "
                "the boundary's %.2e; stress off the uniform %.2e\n",
                static_cast<int>(interior), f_interior / traction, f_interface / traction, f_all / traction, ds);
    EXPECT_EQ(interior, 8);
    EXPECT_LT(f_interior / traction, 1e-10);
    // where a coarse cell meets four fine ones its face's one centre point does not integrate the
    // fine particles' functions as the fine faces' four do: the constraint is not kept there
    // (2.2 % of a face's traction measured; a band, not theory: it guards against a change)
    EXPECT_LT(f_interface / traction, 0.05);
    EXPECT_GT(f_all / traction, 0.1); // the boundary's are the traction's: the measure can see a force
    EXPECT_LT(ds, 1e-15);
}

TEST(Refinement, AMergeUndoesASplitExactly)
{
    // the 27 central particles split and merge back with no motion between: mass, momentum,
    // positions, cells' volumes and stresses are what they were (to round-off), the pool is whole
    Model m = test::model_from(box);
    test::deforming_column_velocity(m.nodes);
    const PartInfo& part = m.parts[0];
    for (index_t i = part.mesh_node_end; i < part.node_end; ++i)
        for (int d = 0; d < 3; ++d)
            m.nodes.v[3 * i + d] = 0.0; // the pool has no motion
    SemiLagrangianForceBlock& sl = *m.semi_lagrangian_block(0);
    NodalBlock& st = *sl.nodal_points();
    for (index_t p = 0; p < st.n_points(); ++p)
        for (int k = 0; k < 6; ++k)
            st.stress[k * st.stress_stride + p] = 1e6 * std::sin(0.3 * p + k);
    const std::vector<real_t> x0 = m.nodes.x, mass0 = m.nodes.mass;
    std::vector<real_t> s0(st.stress.begin(), st.stress.end());
    std::vector<real_t> vol0(static_cast<std::size_t>(sl.n_particles()));
    for (index_t p = 0; p < sl.n_particles(); ++p)
        vol0[p] = sl.dormant(p) ? 0.0 : sl.volume(p);
    const Vec3 p0 = test::momentum(m.nodes);
    const real_t scale = test::momentum_scale(m.nodes);
    ASSERT_EQ(m.refine_particles(0, central(m, 1e-3)), 27);
    std::vector<char> all(static_cast<std::size_t>(sl.n_particles()), 1);
    ASSERT_EQ(m.coarsen_particles(0, all), 27);
    EXPECT_EQ(m.families(0).size(), 0u);
    real_t dx = 0.0, dvol = 0.0, ds = 0.0;
    index_t awake = 0;
    for (index_t p = 0; p < sl.n_particles(); ++p)
    {
        awake += !sl.dormant(p);
        if (sl.dormant(p))
            continue;
        const index_t g = part.node_begin + p;
        dx = std::max(dx, (at(m.nodes.x, g) - at(x0, g)).cwiseAbs().maxCoeff());
        dvol = std::max(dvol, std::abs(sl.volume(p) - vol0[p]) / vol0[p]);
        for (int k = 0; k < 6; ++k)
            ds = std::max(ds, std::abs(st.stress[k * st.stress_stride + p] - s0[k * st.stress_stride + p]) / 1e6);
        EXPECT_EQ(m.nodes.mass[g], mass0[g]);
    }
    const real_t dp = (test::momentum(m.nodes) - p0).norm() / scale;
    std::printf("27 splits merged back: positions off %.2e m, cells' volumes %.2e, stresses %.2e, momentum %.2e\n", dx,
                dvol, ds, dp);
    EXPECT_EQ(awake, part.mesh_node_end - part.node_begin);
    EXPECT_LT(dx, 1e-18);
    EXPECT_LT(dvol, 1e-14);
    EXPECT_LT(ds, 1e-14);
    EXPECT_LT(dp, 1e-14);
}

TEST(Refinement, AConvertingPartSplitsTheParticlesItMade)
{
    // the box as fem-1pt converting into semi-Lagrangian particles: converted whole, its 27
    // central particles split; momentum carries over, and the children's internal forces are the
    // same at a second evaluation of the same state (the pool's nodes lie past the FE mesh's:
    // once, their forces were never zeroed and added up step after step, which threw P6's
    // children out at 340 m/s)
    Model m = test::model_from(box, {"parts.b.formulation=fem-1pt", "parts.b.conversion={principal_strain: 10}"});
    const index_t ne = m.meshes[0].n_elements();
    ASSERT_EQ(m.convert_elements(0, std::vector<char>(static_cast<std::size_t>(ne), 1)), ne);
    test::deforming_column_velocity(m.nodes);
    const PartInfo& part = m.parts[0];
    for (index_t i = part.mesh_node_end; i < part.node_end; ++i)
        for (int d = 0; d < 3; ++d)
            m.nodes.v[3 * i + d] = 0.0;
    const Vec3 p0 = test::momentum(m.nodes);
    const real_t scale = test::momentum_scale(m.nodes);
    ASSERT_EQ(m.refine_particles(0, central(m, 1e-3)), 27);
    EXPECT_LT((test::momentum(m.nodes) - p0).norm() / scale, 1e-14);
    m.compute_forces(0.0, 1e-9, 1);
    const std::vector<real_t> f1 = m.nodes.f_int;
    m.compute_forces(0.0, 1e-9, 1);
    real_t df = 0.0, fmax = 0.0;
    for (const auto& f : m.families(0))
        for (const index_t p : f)
            for (int d = 0; d < 3; ++d)
            {
                const std::size_t j = 3 * static_cast<std::size_t>(part.node_begin + p) + d;
                df = std::max(df, std::abs(m.nodes.f_int[j] - f1[j]));
                fmax = std::max(fmax, std::abs(f1[j]));
            }
    std::printf("converted box, 27 particles split: children's internal forces at a second evaluation off the first "
                "by %.2e of the largest (%.2e N)\n",
                df / fmax, fmax);
    EXPECT_GT(fmax, 0.0);
    EXPECT_EQ(df, 0.0);
}

TEST(Refinement, AWaveRefinedAsItCrossesARegionKeepsItsPlateau)
{
    // the uniaxial-strain column wave (studies/decks/column_wave_rkpm.yaml: 10 m/s driven end,
    // plateau rho c v = 459.7 MPa) on semi-Lagrangian particles, its particles between 40 and
    // 70 mm splitting as the front's pressure passes 100 MPa there; at 16 us (front near 94 mm) the
    // refined region's mean velocity is the driven 10 m/s within 1 %, the column behind it differs
    // from the same run unrefined by under 1 % of it (the reflection), and the ledger holds
    const std::string deck = std::string(RKFEM_SOURCE_DIR) + "/studies/decks/column_wave_rkpm.yaml";
    const std::vector<std::string> sl = {"parts.column.generator.size=[4mm,4mm,120mm]", "time.end=16us",
                                         "time.stepper=central-difference", "parts.column.kinematics=semi-lagrangian",
                                         "parts.column.nodal_integration={scheme: snni}"};
    std::vector<std::string> refined = sl;
    refined.push_back("parts.column.refinement={pressure: 100 MPa, max_new_particles: 5600, region: [{select: {type: "
                      "box, min: [-1 mm, -1 mm, 40 mm], max: [5 mm, 5 mm, 70 mm]}}]}");
    struct Measure
    {
        real_t upstream = 0.0, region = 0.0, balance = 0.0;
        index_t refined = 0;
    };
    auto measure = [&](const std::vector<std::string>& sets)
    {
        Model m = Model::build(read_deck(deck, sets));
        const test::RunWithBalance r = test::run_with_balance(m, 1e-6);
        Measure out;
        out.balance = r.balance;
        out.refined = m.refined_particles();
        real_t up = 0.0, in = 0.0;
        index_t n_up = 0, n_in = 0;
        const PartInfo& part = m.parts[0];
        for (index_t i = part.node_begin; i < part.node_end; ++i)
        {
            if (m.nodes.mass[i] == 0.0) // the pool
                continue;
            const real_t z = m.nodes.x[3 * i + 2], v = m.nodes.v[3 * i + 2];
            if (z >= 5e-3 && z <= 35e-3)
                up += v, ++n_up;
            if (z >= 42e-3 && z <= 68e-3)
                in += v, ++n_in;
        }
        out.upstream = up / n_up;
        out.region = in / n_in;
        return out;
    };
    const Measure plain = measure(sl), ref = measure(refined);
    std::printf("column wave refined as it crosses 40-70 mm: %d particles split; mean velocity there %.4f m/s "
                "(driven 10), behind it %.4f against %.4f unrefined (reflection %.2f %% of 10 m/s); balance %.2e "
                "(unrefined %.2e)\n",
                static_cast<int>(ref.refined), ref.region, ref.upstream, plain.upstream,
                100.0 * std::abs(ref.upstream - plain.upstream) / 10.0, ref.balance, plain.balance);
    EXPECT_EQ(ref.refined, 30 * 25); // every particle of the 30 layers inside 40-70 mm when the front passed
    EXPECT_LT(std::abs(ref.region - 10.0) / 10.0, 0.01);
    EXPECT_LT(std::abs(ref.upstream - plain.upstream) / 10.0, 0.01);
    EXPECT_LT(ref.balance, 0.005);
}

TEST(Refinement, APulseRefinedAndCoarsenedAsItPassesKeepsTheLedger)
{
    // a 2 us pulse (10 m/s at the driven end, then held still) crosses 15-40 mm of a 60 mm column:
    // its particles split as the pulse's pressure passes 100 MPa and merge back once it has
    // fallen under 25 MPa behind it. Where levels meet, the step is halved (without, a longer
    // column merging at 10 MPa went unstable at 12 us); the ledger holds, and by 12 us every
    // family has merged
    const std::string deck = std::string(RKFEM_SOURCE_DIR) + "/studies/decks/column_wave_rkpm.yaml";
    Model m = Model::build(read_deck(
        deck, {"parts.column.generator.size=[4mm,4mm,60mm]", "time.end=12us", "time.stepper=central-difference",
               "parts.column.kinematics=semi-lagrangian", "parts.column.nodal_integration={scheme: snni}",
               "boundary_conditions.1.velocity={z: {curve: [[0, 10 m/s], [2 us, 10 m/s], [2.5 us, 0], [1 s, 0]]}}",
               "parts.column.refinement={pressure: 100 MPa, coarsen_fraction: 0.25, max_new_particles: 4550, region: "
               "[{select: {type: box, min: [-1 mm, -1 mm, 15 mm], max: [5 mm, 5 mm, 40 mm]}}]}"}));
    const test::RunWithBalance r = test::run_with_balance(m, 1e-6);
    std::printf("2 us pulse through 15-40 mm: %d splits, %d merges, %d families left; balance %.2e; run %s\n",
                static_cast<int>(m.refined_particles()), static_cast<int>(m.coarsened_particles()),
                static_cast<int>(m.families(0).size()), r.balance, r.summary.status.c_str());
    EXPECT_EQ(r.summary.status, "completed");
    EXPECT_EQ(m.refined_particles(), 25 * 25); // every particle of the 25 layers inside 15-40 mm
    EXPECT_EQ(m.coarsened_particles(), m.refined_particles());
    EXPECT_EQ(m.families(0).size(), 0u);
    EXPECT_LT(r.balance, 0.005);
}

TEST(Refinement, DeckErrorsNameTheKey)
{
    auto error = [](const std::vector<std::string>& sets) { return test::model_error(box, sets); };
    EXPECT_NE(error({"parts.b.kinematics=lagrangian"}).find("parts.b.refinement"), std::string::npos);
    EXPECT_NE(error({"parts.b.refinement={pressure: 1 GPa, damage: 0.5}"}).find("pressure"), std::string::npos);
    EXPECT_NE(error({"parts.b.refinement={max_level: 1}"}).find("damage"), std::string::npos);
    EXPECT_NE(error({"parts.b.refinement={damage: 0.5, max_level: 3}"}).find("max_level"), std::string::npos);
    EXPECT_NE(error({"parts.b.refinement={damage: 0.5, coarsen_fraction: 1}"}).find("coarsen_fraction"),
              std::string::npos);
    EXPECT_NE(error({"parts.b.refinement={damage: 0.5, max_new_particles: 10}"}).find("max_new_particles"),
              std::string::npos);
    EXPECT_NE(error({"parts.b.semi_lagrangian={reset_interval: 4}"}).find("reset_interval"), std::string::npos);
    EXPECT_EQ(error({"parts.b.formulation=fem-1pt", "parts.b.conversion={principal_strain: 10}"}), ""); // converting
    EXPECT_EQ(error({}), "");
}
