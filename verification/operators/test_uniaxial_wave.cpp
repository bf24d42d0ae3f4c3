// Uniaxial-strain wave in a steel column (E 200 GPa, nu 0.3, rho 7850 kg/m^3), lateral rollers,
// end driven at 10 m/s. Theory: c_p = sqrt((lambda + 2 mu)/rho) = 5856.4 m/s, plateau
// sigma_zz = -rho c_p v = -459.7 MPa, front at c_p t.
#include <gtest/gtest.h>

#include "../support.hpp"
#include "rkfem/core/state_archive.hpp"
#include "rkfem/discretization/generators.hpp"
#include "rkfem/model/nodal_block_build.hpp"
#include "rkfem/run/simulation.hpp"

using namespace rkfem;

namespace
{
const char* deck = R"(
title: wave
time: {end: 26 us}
parts:
  column:
    generator: {type: box, size: [1 mm, 1 mm, 300 mm], divisions: [1, 1, 300]}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: fem-1pt
    hourglass: {type: viscous, coefficient: 0.1}
node_sets:
  all: {select: {type: named, name: all}}
  end: {select: {type: named, name: bottom}}
boundary_conditions:
  - {node_set: all, fixed: [x, y]}
  - {node_set: end, velocity: {z: 10 m/s}}
sections:
  behind: {point: [0, 0, 50 mm], normal: [0, 0, 1]}
  ahead: {point: [0, 0, 250 mm], normal: [0, 0, 1]}
)";

void check_wave(const std::vector<std::string>& overrides)
{
    Model m = test::model_from(deck, overrides);
    const real_t h = 1e-3, v = 10.0;
    const real_t c = m.meshes[0].material.wave_speed();
    ASSERT_NEAR(c, 5856.4, 0.1);
    const real_t plateau = -7850 * c * v;
    ASSERT_NEAR(plateau, -459.7e6, 0.05e6);
    const test::RunWithBalance r = test::run_with_balance(m, 20 * h / c); // after the impulsive start's transient
    const RunSummary& s = r.summary;
    const real_t worst_balance_after_startup = r.balance;
    ASSERT_EQ(s.status, "completed") << s.message;
    const real_t t = s.end_time;
    // plateau behind the front (elements 20 .. 120 mm from the driven end)
    for (index_t e = 20; e < 120; ++e)
        EXPECT_NEAR(m.element_stress(0, e)[ZZ], plateau, 0.02 * std::abs(plateau)) << "element " << e;
    // lateral stress: lambda/(lambda + 2 mu) of the axial plateau = -197.0 MPa
    const real_t ratio = m.meshes[0].material.lambda / m.meshes[0].material.plane_wave_modulus();
    EXPECT_NEAR(m.element_stress(0, 60)[XX], ratio * plateau, 0.02 * std::abs(ratio * plateau));
    // front: first element centre where |sigma_zz| falls below half the plateau
    real_t front = -1;
    for (index_t e = 1; e < m.meshes[0].n_elements(); ++e)
    {
        const real_t s0 = m.element_stress(0, e - 1)[ZZ], s1 = m.element_stress(0, e)[ZZ];
        if (s1 > 0.5 * plateau)
        {
            const real_t z0 = (e - 0.5) * h, z1 = (e + 0.5) * h;
            front = z0 + (z1 - z0) * (0.5 * plateau - s0) / (s1 - s0);
            break;
        }
    }
    std::printf("front %.3f mm vs c t = %.3f mm; balance error after startup %.3e; plateau error %.3e\n", front * 1e3,
                c * t * 1e3, worst_balance_after_startup, m.element_stress(0, 60)[ZZ] / plateau - 1);
    EXPECT_NEAR(front, c * t, 1.5 * h);
    EXPECT_LT(worst_balance_after_startup, 0.005);
    // reactions (SPCFORC): the driven end carries rho c v A = 459.7 N into the column; the rollers'
    // lateral reactions cancel
    const Vec3 end = m.reaction(1), rollers = m.reaction(0);
    EXPECT_NEAR(end[2], -plateau * h * h, 0.005 * std::abs(plateau) * h * h);
    EXPECT_NEAR(end[0], 0.0, 1e-9 * end[2]);
    EXPECT_NEAR(rollers[0], 0.0, 1e-9 * end[2]);
    EXPECT_NEAR(rollers[1], 0.0, 1e-9 * end[2]);
    EXPECT_EQ(rollers[2], 0.0); // z is free on the rollers
    // sections (SECFORC) behind the front carry the plateau's force, rho c v A = 459.7 N; one
    // ahead of it carries nothing
    ASSERT_EQ(m.section_nodes.size(), 2u);
    EXPECT_NEAR(m.section_force(0)[2], -plateau * h * h, 0.01 * std::abs(plateau) * h * h);
    EXPECT_NEAR(m.section_force(0)[0], 0.0, 1e-9 * end[2]);
    EXPECT_NEAR(m.section_force(1)[2], 0.0, 1e-6 * end[2]);
    // the history carries them as columns reaction_end_{x,y,z}
    const auto col = std::find(s.history_columns.begin(), s.history_columns.end(), "reaction_end_z");
    ASSERT_NE(col, s.history_columns.end());
    EXPECT_EQ(s.history[s.history.size() - s.history_columns.size() + (col - s.history_columns.begin())], end[2]);
}
} // namespace

TEST(UniaxialWave, OnePointViscousHourglassMatchesTheory)
{
    check_wave({});
}

// The rollers hold mesh nodes at rest: their reactions are not stored each step but read from
// the forces when asked for (Model::plan_conditions). They are the plain sum over the set's dofs
// of f_int - f_ext - f_contact, in the conditions' order, to the bit; a model restored from a
// checkpoint, whose forces are not restored, gives the same from the stored values.
// The same column read from an LS-DYNA keyword file with each hex split into two wedges written as
// degenerate hexes (N1 N2 N3 N3 N4 N5 N6 N6, as pre-processors write them): the same plateau behind
// the front within 2 % and the ledger closed. The nodes of that mesh, and of one of tetrahedra (six
// per hex, Kuhn's split), serve as RK particles (rkpm) and as nodal FE (fem-nodal): over the same
// 100 mm the layers' mean stress within 0.5 % of the plateau, each layer within 10 %, the ledger
// closed (the step factor measured: the defaults are calibrated on hexahedra).
TEST(UniaxialWave, WedgesFromAKeywordMeshMatchTheory)
{
    const HexMesh wedges = test::split_into_wedges(generate_box(Vec3::Zero(), Vec3(1e-3, 1e-3, 0.3), {1, 1, 300}));
    const std::string file = test::write_keyword_mesh("rkfem_wedge_column.k", wedges.x, wedges.conn);
    const std::string wedge_deck = R"(
title: wave in wedges
time: {end: 26 us}
parts:
  column:
    generator: {type: keyword, file: )" +
                                   file + R"(}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: fem-1pt
    hourglass: {type: viscous, coefficient: 0.1}
node_sets:
  all: {select: {type: named, name: all}}
  end: {select: {type: plane, point: [0, 0, 0], normal: [0, 0, 1]}}
boundary_conditions:
  - {node_set: all, fixed: [x, y]}
  - {node_set: end, velocity: {z: 10 m/s}}
)";
    Model m = test::model_from(wedge_deck);
    ASSERT_EQ(m.meshes[0].n_elements(), 600);
    const real_t h = 1e-3, v = 10.0, c = m.meshes[0].material.wave_speed(), plateau = -7850 * c * v;
    const test::RunWithBalance r = test::run_with_balance(m, 20 * h / c);
    ASSERT_EQ(r.summary.status, "completed") << r.summary.message;
    real_t worst = 0.0;
    for (index_t e = 40; e < 240; ++e) // layers 20 .. 120 mm from the driven end, two wedges each
        worst = std::max(worst, std::abs(m.element_stress(0, e)[ZZ] / plateau - 1));
    std::printf("wedge column: plateau within %.2e of -rho c v, balance error after startup %.2e\n", worst, r.balance);
    EXPECT_LT(worst, 0.02);
    EXPECT_LT(r.balance, 0.005);
    const HexMesh tets = test::split_into_tets(generate_box(Vec3::Zero(), Vec3(1e-3, 1e-3, 0.3), {1, 1, 300}));
    const std::string tet_file = test::write_keyword_mesh("rkfem_tet_column.k", tets.x, tets.conn);
    for (const char* solids : {"wedges", "tetrahedra"})
        for (const char* formulation : {"rkpm", "fem-nodal"})
        {
            const bool tet = std::string(solids) == "tetrahedra";
            Model n = test::model_from(
                wedge_deck, {std::string("parts.column.formulation=") + formulation, "parts.column.hourglass=~",
                             std::string("parts.column.generator.file=") + (tet ? tet_file : file)});
            const int per_layer = tet ? 6 : 2;
            ASSERT_EQ(n.meshes[0].n_elements(), 300 * per_layer);
            const test::RunWithBalance rn = test::run_with_balance(n, 20 * h / c);
            ASSERT_EQ(rn.summary.status, "completed") << rn.summary.message;
            real_t off = 0.0, layer_off = 0.0, mean = 0.0;
            for (index_t l = 20; l < 120; ++l)
            {
                real_t layer = 0.0;
                for (index_t e = l * per_layer; e < (l + 1) * per_layer; ++e)
                {
                    off = std::max(off, std::abs(n.element_stress(0, e)[ZZ] / plateau - 1));
                    layer += n.element_stress(0, e)[ZZ] / per_layer;
                }
                layer_off = std::max(layer_off, std::abs(layer / plateau - 1));
                mean += layer / 100;
            }
            std::printf("%s column, %s: plateau within %.2e of -rho c v (layers %.2e, mean %.2e), balance error after "
                        "startup %.2e\n",
                        solids, formulation, off, layer_off, mean / plateau - 1, rn.balance);
            // the mean over the 100 layers is momentum's rho c v; layers ring about it behind the
            // impulsive front more than on hexahedra (2026-12-07: 5.4 / 2.6 % on wedges, 8.4 / 2.4 %
            // on tetrahedra, rkpm / fem-nodal, against 2 % on hexahedra): the RK supports are a / h
            // times the longest edge at the node, here a face or body diagonal (sqrt 2, sqrt 3 of
            // the hexahedra's), and a / h 1.01 rings 1.3 / 5.5 %
            EXPECT_LT(std::abs(mean / plateau - 1), 0.005) << solids << " " << formulation;
            EXPECT_LT(layer_off, 0.1) << solids << " " << formulation;
            EXPECT_LT(rn.balance, 0.005) << solids << " " << formulation;
        }
}

TEST(UniaxialWave, RollerReactionsAreTheForcesAtTheirDofsAlsoAfterACheckpoint)
{
    Model m = test::model_from(deck, {"time.end=10us"});
    ASSERT_EQ(test::run_with_balance(m, 0.0).summary.status, "completed");
    Vec3 plain = Vec3::Zero();
    real_t magnitude = 0.0;
    for (const DofCondition& c : m.conditions)
        if (c.source == 0)
        {
            plain[c.dof % 3] +=
                m.nodes.f_int[c.dof] - m.nodes.f_ext[c.dof] - m.contact.force(static_cast<std::size_t>(c.dof));
            magnitude += std::abs(m.nodes.f_int[c.dof]);
        }
    EXPECT_GT(magnitude, 100.0); // the lateral stress behind the front pushes on the rollers [N]
    const Vec3 lazy = m.reaction(0);
    StateArchive archive;
    m.save_state(archive);
    Model restored = test::model_from(deck, {"time.end=10us"});
    restored.load_state(archive);
    const Vec3 stored = restored.reaction(0);
    for (int k = 0; k < 3; ++k)
    {
        EXPECT_EQ(lazy[k], plain[k]) << k;
        EXPECT_EQ(stored[k], plain[k]) << k;
    }
    EXPECT_EQ(restored.reaction(1)[2], m.reaction(1)[2]); // the driven end: stored either way
}

TEST(UniaxialWave, OnePointStiffnessHourglassMatchesTheory)
{
    check_wave({"parts.column.hourglass.type=stiffness", "parts.column.hourglass.coefficient=0.05"});
}

TEST(UniaxialWave, FullyIntegratedMatchesTheory)
{
    check_wave({"parts.column.formulation=fem-2x2x2", "parts.column.hourglass=~"});
}

TEST(UniaxialWave, RkParticlesMatchTheory)
{
    check_wave({"parts.column.formulation=rkpm", "parts.column.hourglass=~"});
}

TEST(UniaxialWave, NodalIntegratedFemMatchesTheory)
{
    check_wave({"parts.column.formulation=fem-nodal", "parts.column.hourglass=~"});
}

TEST(UniaxialWave, ResultsDoNotDependOnThreadCount)
{
    const auto u1 = test::displacements_on_threads(deck, {}, 1), u2 = test::displacements_on_threads(deck, {}, 2);
    ASSERT_EQ(u1.size(), u2.size());
    for (std::size_t i = 0; i < u1.size(); ++i)
        ASSERT_EQ(u1[i], u2[i]) << "dof " << i; // bitwise: deterministic assembly
}

namespace
{
void check_pressure_wave(const std::vector<std::string>& overrides)
{
    // A pressure step p on the free end of a laterally confined column: sigma_zz = -p behind the
    // front (elastic, uniaxial strain), front at c_p t from the loaded end.
    const std::string d = R"(
title: pressure wave
time: {end: 20 us}
parts:
  column:
    generator: {type: box, size: [1 mm, 1 mm, 300 mm], divisions: [1, 1, 300]}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
node_sets:
  all: {select: {type: named, name: all}}
face_sets:
  loaded: {select: {type: plane, point: [0, 0, 300 mm], normal: [0, 0, 1]}}
boundary_conditions:
  - {node_set: all, fixed: [x, y]}
loads:
  - {type: pressure, face_set: loaded, pressure: {curve: [[0 s, 14503.77 psi], [1 s, 14503.77 psi]]}}
)";
    Model m = test::model_from(d, overrides);
    RunOptions opt;
    opt.progress = false;
    const RunSummary s = run_simulation(m, opt);
    ASSERT_EQ(s.status, "completed") << s.message;
    const real_t p = 100e6; // 14503.77 psi
    const index_t ne = m.meshes[0].n_elements();
    for (index_t e = ne - 90; e < ne - 10; ++e) // 10 .. 90 mm from the loaded end; front at 117 mm
        EXPECT_NEAR(m.element_stress(0, e)[ZZ], -p, 0.02 * p) << "element " << e;
    EXPECT_NEAR(m.element_stress(0, ne - 200)[ZZ], 0.0, 1e-6 * p); // ahead of the front
    // the load's resultant is -p A n whatever the approximation (partition of unity)
    real_t fz = 0.0;
    for (index_t n = 0; n < m.nodes.size(); ++n)
        fz += m.nodes.f_ext[3 * n + 2];
    const real_t area = 1e-6;                    // 1 mm^2, laterally fixed
    EXPECT_NEAR(fz, -p * area, 1e-6 * p * area); // 14503.77 psi is 100 MPa to 2.6e-7
}
} // namespace

TEST(UniaxialWave, PressureStepOnAFaceSetGivesMinusPBehindTheFront)
{
    check_pressure_wave({});
}

TEST(UniaxialWave, PressureStepOnRkParticles)
{
    check_pressure_wave({"parts.column.formulation=rkpm"});
}

TEST(UniaxialWave, RunawayLoadStopsWithWhereAndWhen)
{
    // A pressure far beyond anything the mesh can carry inverts the loaded elements: the run must
    // stop with a message naming the element, time and step, not produce NaNs.
    const std::string d = R"(
title: crush
time: {end: 20 us}
parts:
  column:
    generator: {type: box, size: [1 mm, 1 mm, 10 mm], divisions: [1, 1, 10]}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
face_sets:
  loaded: {select: {type: named, name: top}}
loads:
  - {type: pressure, face_set: loaded, pressure: 1e16 Pa}
)";
    Model m = test::model_from(d);
    RunOptions opt;
    opt.progress = false;
    const RunSummary s = run_simulation(m, opt);
    EXPECT_EQ(s.status, "unstable");
    EXPECT_NE(s.message.find("step"), std::string::npos) << s.message;
    EXPECT_NE(s.message.find("t = "), std::string::npos) << s.message;
    EXPECT_TRUE(s.message.find("element") != std::string::npos || s.message.find("node") != std::string::npos ||
                s.message.find("energy") != std::string::npos)
        << s.message;
    std::printf("unstable run message: %s\n", s.message.c_str());
}

TEST(UniaxialWave, RkDrivenEndMovesWithThePrescribedPhysicalVelocity)
{
    // mixed transformation: the physical velocity u^h_t(X_b) of every driven particle follows the
    // prescribed quadratic ramp v = t^2 (m/s, t in us); the generalized coefficients differ from it
    // because the velocity field near the end is quadratic in z (RK reproduces only linear fields);
    // a / h = 2.3 so that three particles cover the end along z (with 1.51 only two do, and RK is
    // then interpolatory at the end). At that support the set-up would measure the free column's
    // critical step factor, 0.82 (its lateral modes, which the rollers hold), and step at 0.78;
    // the deck's dt_factor 1 keeps the step this test was written for (the run is stable there)
    Model m = test::model_from(deck, {"parts.column.formulation=rkpm", "parts.column.hourglass=~", "time.end=5 us",
                                      "parts.column.rk={normalized_support: 2.3}",
                                      "parts.column.nodal_integration={dt_factor: 1}",
                                      "boundary_conditions.1.velocity.z={curve: [[0, 0], [1 us, 1 m/s], [2 us, 4 m/s], "
                                      "[3 us, 9 m/s], [4 us, 16 m/s], [5 us, 25 m/s], [6 us, 36 m/s]]}"});
    RunOptions opt;
    opt.progress = false;
    const RunSummary s = run_simulation(m, opt);
    ASSERT_EQ(s.status, "completed") << s.message;
    real_t worst = 0.0, coef_dev = 0.0;
    for (index_t n = 0; n < m.nodes.size(); ++n)
        if (m.nodes.x0[3 * n + 2] < 1e-12)
        {
            worst = std::max(worst, std::abs(m.physical(m.nodes.v, n)[2] - 25.0));
            coef_dev = std::max(coef_dev, std::abs(m.nodes.v[3 * n + 2] - 25.0));
        }
    std::printf("driven end: physical velocity error %.2e m/s, coefficient deviation %.2e m/s\n", worst, coef_dev);
    EXPECT_LT(worst, 1e-10);
    EXPECT_GT(coef_dev, 1e-4); // 1.4e-4 m/s: imposing the coefficients would miss the target by this much
}

// The column wave on a cloud part: 1 mm lattice jittered by +-0.25 mm, no mesh; RK particles
// integrated by SCNI on their Voronoi cells clipped to the box. The cells tile the column; the
// particle stresses average to the plateau (each 10 mm slab within 2%, the whole plateau within
// 1%) and the front sits at c t.
namespace
{
/// Mean of nodal stress component `comp` over the particles in n bins [start + k width, start +
/// (k + 1) width) of distance along z from z = 0, or from z = top when top > 0.
std::vector<real_t> bin_means(const Model& m, real_t start, real_t width, int n, int comp, real_t top = 0.0)
{
    std::vector<real_t> sum(static_cast<std::size_t>(n), 0.0);
    std::vector<int> count(static_cast<std::size_t>(n), 0);
    for (index_t i = 0; i < m.nodes.size(); ++i)
    {
        const real_t z = m.nodes.x0[3 * i + 2];
        const real_t d = (top > 0.0 ? top - z : z) - start;
        const int k = static_cast<int>(std::floor(d / width));
        if (d > 0.0 && k < n)
        {
            sum[k] += m.nodal_stress(i)[comp];
            ++count[k];
        }
    }
    for (int k = 0; k < n; ++k)
        sum[k] /= count[k];
    return sum;
}

void check_cloud_wave(const std::string& stabilization, const std::string& scheme = "scni")
{
    Model m = test::model_from(R"(
title: cloud wave
time: {end: 20 us}
parts:
  column:
    generator: {type: cloud, size: [3 mm, 3 mm, 140 mm], spacing: 1 mm, jitter: 0.25, seed: 3}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: rkpm
node_sets:
  all: {select: {type: named, name: all}}
  end: {select: {type: named, name: bottom}}
boundary_conditions:
  - {node_set: all, fixed: [x, y]}
  - {node_set: end, velocity: {z: 10 m/s}}
)",
                               {"parts.column.nodal_integration.stabilization=" + stabilization,
                                "parts.column.nodal_integration.scheme=" + scheme});
    ASSERT_NE(m.nodal_block(0), nullptr);
    const NodalBlock& nb = *m.nodal_block(0);
    EXPECT_EQ(nb.n_stab() > 0, stabilization == "mscni");
    real_t vol = 0.0;
    for (real_t w : nb.points.weight)
        vol += w;
    EXPECT_NEAR(vol, 3e-3 * 3e-3 * 140e-3, 1e-12 * 3e-3 * 3e-3 * 140e-3); // the cells tile the body
    const real_t c = nb.material.wave_speed(), plateau = -7850 * c * 10.0;
    RunOptions opt;
    opt.progress = false;
    const RunSummary s = run_simulation(m, opt, {});
    ASSERT_EQ(s.status, "completed") << s.message;
    // rollers on every particle: the mixed transformation's right-hand side is 0 in x and y, so
    // are the lateral coefficients, exactly (no collocation system is solved for them), and so
    // is the physical lateral velocity at every particle
    for (index_t i = 0; i < m.nodes.size(); ++i)
        for (int k = 0; k < 2; ++k)
        {
            ASSERT_EQ(m.nodes.v[3 * i + k], 0.0) << "particle " << i;
            ASSERT_EQ(m.physical(m.nodes.v, i)[k], 0.0) << "particle " << i;
        }
    const real_t mean = bin_means(m, 15e-3, 80e-3, 1, ZZ)[0], lateral = bin_means(m, 15e-3, 80e-3, 1, XX)[0];
    const real_t ratio = nb.material.lambda / nb.material.plane_wave_modulus();
    std::printf("cloud: %d particles, plateau %.2f MPa (theory %.2f, error %.2e), lateral error %.2e\n", m.nodes.size(),
                mean / 1e6, plateau / 1e6, mean / plateau - 1, lateral / (ratio * plateau) - 1);
    EXPECT_NEAR(mean, plateau, 0.01 * std::abs(plateau));
    EXPECT_NEAR(lateral, ratio * plateau, 0.01 * std::abs(ratio * plateau));
    const std::vector<real_t> slab = bin_means(m, 15e-3, 10e-3, 8, ZZ);
    for (int k = 0; k < 8; ++k)
    {
        std::printf("  slab %d-%d mm: %.4f of the plateau\n", 15 + 10 * k, 25 + 10 * k, slab[k] / plateau);
        EXPECT_NEAR(slab[k], plateau, 0.02 * std::abs(plateau)) << "slab " << k;
    }
    // front: the first 1 mm bin from 100 mm on where |sigma_zz| falls below half the plateau
    const std::vector<real_t> bins = bin_means(m, 99.5e-3, 1e-3, 40, ZZ);
    real_t front = -1.0;
    for (int f = 0; f < 40 && front < 0; ++f)
        if (bins[f] > 0.5 * plateau)
            front = (100 + f) * 1e-3;
    std::printf("  front %.1f mm vs c t = %.2f mm\n", front * 1e3, c * s.end_time * 1e3);
    EXPECT_NEAR(front, c * s.end_time, 1.5e-3);
}
} // namespace

TEST(UniaxialWave, RkParticlesOnAVoronoiCloudMatchTheory)
{
    check_cloud_wave("none");
}

TEST(UniaxialWave, RkParticlesOnAVoronoiCloudWithMscniMatchTheory)
{
    check_cloud_wave("mscni");
}

// SD-SCNI on the cloud: every pyramid sub-cell of a Voronoi cell is a stress point
TEST(UniaxialWave, RkParticlesOnAVoronoiCloudWithSdScniMatchTheory)
{
    check_cloud_wave("none", "sd-scni");
}

namespace
{
/// A pressure step of 100 MPa on the top of a laterally held cloud column of height `height`
/// (generator: the deck's generator mapping) whose top facets have area `area(model)`: the
/// load's resultant is -p A to round-off (partition of unity, the facets tile the face), and in
/// the `slabs` 10 mm slabs from 10 mm below the loaded end sigma_zz = -p within 2%.
template <class Area>
void check_cloud_pressure_step(const std::string& generator, real_t height, const std::string& end_time, int slabs,
                               Area&& area)
{
    Model m = test::model_from(R"(
title: cloud pressure wave
time: {end: )" + end_time + R"(}
parts:
  column:
    generator: )" + generator + R"(
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: rkpm
node_sets:
  all: {select: {type: named, name: all}}
face_sets:
  loaded: {select: {type: named, name: top}}
boundary_conditions:
  - {node_set: all, fixed: [x, y]}
loads:
  - {type: pressure, face_set: loaded, pressure: 100 MPa}
)");
    RunOptions opt;
    opt.progress = false;
    const RunSummary s = run_simulation(m, opt, {});
    ASSERT_EQ(s.status, "completed") << s.message;
    const real_t p = 100e6, a = area(m);
    real_t fz = 0.0;
    for (index_t n = 0; n < m.nodes.size(); ++n)
        fz += m.nodes.f_ext[3 * n + 2];
    std::printf("%d particles: resultant / (-p A) - 1 = %.2e\n", m.nodes.size(), fz / (-p * a) - 1.0);
    EXPECT_NEAR(fz, -p * a, 1e-12 * p * a);
    const std::vector<real_t> slab = bin_means(m, 10e-3, 10e-3, slabs, ZZ, height); // from the loaded end
    for (int k = 0; k < slabs; ++k)
    {
        std::printf("  %d-%d mm from the loaded end: sigma_zz = %.4f p\n", 10 + 10 * k, 20 + 10 * k, slab[k] / -p);
        EXPECT_NEAR(slab[k], -p, 0.02 * p) << "slab " << k;
    }
}
} // namespace

// A pressure step on the top of a cloud column (the facets of the Voronoi cells on the body's
// surface carry -p Psi_I n dA): the resultant is -p A, and behind the front sigma_zz = -p.
TEST(UniaxialWave, PressureStepOnACloud)
{
    check_cloud_pressure_step("{type: cloud, size: [3 mm, 3 mm, 140 mm], spacing: 1 mm, jitter: 0.25, seed: 4}", 140e-3,
                              "20 us", 8, [](const Model&) { return 9e-6; });
}

// The same on a cylinder cloud (body: cylinder; the cells are clipped to the planes tangent to
// the cylinder): the top facets tile the prism's cap, of area sides R^2 tan(pi / sides).
TEST(UniaxialWave, PressureStepOnACylinderCloud)
{
    check_cloud_pressure_step(
        "{type: cloud, body: cylinder, radius: 2 mm, height: 100 mm, spacing: 1 mm, jitter: 0.25, seed: 4}", 100e-3,
        "14 us", 5,
        [](const Model& m)
        {
            const GeneratorSpec& g = m.deck().parts[0].generator;
            const int sides = static_cast<int>(cloud_body(g, m.nodes.size()).size()) - 2;
            std::printf("cylinder cloud: %d sides\n", sides);
            return sides * g.radius * g.radius * std::tan(M_PI / sides);
        });
}

TEST(UniaxialWave, PressureOnACloudFollowsTheDeformedFacets)
{
    // A pressure on cloud facets acts on the current facets (Nanson, n da = J F^-T N dA with F of
    // the RK approximation at each facet point). Under a homogeneous motion x = A X the
    // approximation is exact (linear reproduction), so the resultant on the top face (N = e_z,
    // area A0) is exactly -p J A^-T e_z A0: a rigid rotation turns it with the body, an in-plane
    // stretch by s scales it by s^2.
    Model m = test::model_from(R"(
title: cloud pressure on deformed facets
time: {end: 1 us}
parts:
  block:
    generator: {type: cloud, size: [4 mm, 3 mm, 5 mm], spacing: 1 mm, jitter: 0.3, seed: 2}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: rkpm
face_sets:
  loaded: {select: {type: named, name: top}}
loads:
  - {type: pressure, face_set: loaded, pressure: 100 MPa}
)");
    const real_t p = 100e6, area = 12e-6;
    auto resultant = [&](const Mat3& A)
    {
        for (index_t n = 0; n < m.nodes.size(); ++n)
        {
            const Vec3 X(m.nodes.x0[3 * n], m.nodes.x0[3 * n + 1], m.nodes.x0[3 * n + 2]);
            const Vec3 u = A * X - X; // coefficients of a linear field are its nodal values
            for (int d = 0; d < 3; ++d)
                m.nodes.u[3 * n + d] = u[d];
        }
        m.update_coordinates();
        m.compute_forces(0.0, 0.0, 0);
        Vec3 f = Vec3::Zero();
        for (index_t n = 0; n < m.nodes.size(); ++n)
            f += Vec3(m.nodes.f_ext[3 * n], m.nodes.f_ext[3 * n + 1], m.nodes.f_ext[3 * n + 2]);
        return f;
    };
    const Mat3 R = Eigen::AngleAxisd(0.7, Vec3(1, 2, 0.5).normalized()).toRotationMatrix();
    const Mat3 S = Vec3(1.3, 1.3, 0.8).asDiagonal();
    for (const auto& [name, A] : {std::pair<const char*, Mat3>{"undeformed", Mat3::Identity()},
                                  {"rotated", R},
                                  {"stretched", S},
                                  {"stretched and rotated", R * S}})
    {
        const Vec3 expect = -p * area * A.determinant() * (A.inverse().transpose() * Vec3::UnitZ());
        const Vec3 f = resultant(A);
        std::printf("%-22s resultant (%.6e, %.6e, %.6e) N, |error| / pA = %.2e\n", name, f[0], f[1], f[2],
                    (f - expect).norm() / (p * area));
        EXPECT_LT((f - expect).norm(), 1e-11 * p * area) << name;
    }
}
