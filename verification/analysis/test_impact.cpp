// Impact measures (analysis/impact.hpp) on a crater whose answer is known: a 4 x 4 x 4 block of
// 1 mm hexes whose 2 x 2 centre column is eroded through its top two layers (a crater 2 mm deep
// along -z under the point of impact), plus one eroded element at a bottom corner that no
// removed face joins to the surface (not crater). The struck surface node is moved 0.3 mm down;
// a projectile part moves at 100 m/s along the shot line.
#include <gtest/gtest.h>

#include "../support.hpp"
#include "rkfem/analysis/impact.hpp"
#include "rkfem/analysis/spall.hpp"
#include "rkfem/run/simulation.hpp"

using namespace rkfem;

namespace
{
const char* deck = R"(
title: crater
time: {end: 1 us}
parts:
  target:
    generator: {type: box, size: [4 mm, 4 mm, 4 mm], divisions: [4, 4, 4]}
    material: {model: j2, rho: 2000 kg/m^3, E: 30 GPa, nu: 0.2, sigy: 30 MPa, etan: 1 GPa}
    formulation: fem-1pt
    erosion: {effective_plastic_strain: 0.5}
  slug:
    generator: {type: box, origin: [1 mm, 1 mm, 5 mm], size: [2 mm, 2 mm, 2 mm], divisions: [2, 2, 2]}
    material: {model: elastic, rho: 8000 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: fem-1pt
    initial_velocity: [0, 0, -100 m/s]
impact: {target: target, projectile: slug, point: [2 mm, 2 mm, 4 mm], direction: [0, 0, -1]}
)";
} // namespace

TEST(Impact, CraterDepthsDamagedVolumeAndProjectileOfAKnownCrater)
{
    Model m = test::model_from(deck);
    const ImpactAnalysis impact(m, m.deck().impact);
    // the surface node under the point is the one at (2, 2, 4) mm
    const index_t s = impact.surface_node();
    EXPECT_NEAR(m.nodes.x0[3 * s], 2e-3, 1e-12);
    EXPECT_NEAR(m.nodes.x0[3 * s + 2], 4e-3, 1e-12);
    EXPECT_EQ(impact.actual_depth(m), 0.0); // nothing removed yet

    std::vector<char> keep(64, 1);
    for (int iz = 2; iz < 4; ++iz)
        for (int iy = 1; iy < 3; ++iy)
            for (int ix = 1; ix < 3; ++ix)
                keep[static_cast<std::size_t>(ix + 4 * iy + 16 * iz)] = 0;
    keep[0] = 0; // a bottom corner, not joined to the surface
    m.remove_elements(0, keep);
    m.nodes.u[3 * s + 2] = -0.3e-3;

    const ImpactMeasures r = impact.measure(m);
    std::printf("crater: apparent %.4f mm, actual %.4f mm, residual velocity %.1f m/s, projectile %.4f g, damaged "
                "volume %.3f mm^3, eroded mass %.4f g\n",
                1e3 * r.apparent_depth, 1e3 * r.actual_depth, r.residual_velocity, 1e3 * r.projectile_mass,
                1e9 * r.damaged_volume_threshold, 1e3 * r.eroded_mass);
    EXPECT_NEAR(r.apparent_depth, 0.3e-3, 1e-15);
    EXPECT_NEAR(r.actual_depth, 2e-3, 1e-15);
    EXPECT_NEAR(r.residual_velocity, 100.0, 1e-12);
    EXPECT_NEAR(r.projectile_mass, 8000 * 8e-9, 1e-15);
    EXPECT_NEAR(r.damaged_volume_threshold, 9e-9, 1e-20); // the 9 eroded elements
    EXPECT_NEAR(r.damaged_volume_half, 9e-9, 1e-20);
    EXPECT_NEAR(r.eroded_mass, 2000 * 9e-9, 1e-17);
    EXPECT_EQ(r.target_momentum, 0.0);

    // one more layer eroded under the column deepens the crater to 3 mm
    std::vector<char> keep2(static_cast<std::size_t>(m.meshes[0].n_elements()), 1);
    for (index_t e = 0; e < m.meshes[0].n_elements(); ++e)
    {
        Vec3 c = Vec3::Zero();
        for (int j = 0; j < 8; ++j)
            c += 0.125 * Vec3(m.nodes.x0[3 * m.meshes[0].conn[8 * e + j]],
                              m.nodes.x0[3 * m.meshes[0].conn[8 * e + j] + 1],
                              m.nodes.x0[3 * m.meshes[0].conn[8 * e + j] + 2]);
        if (c[2] > 1e-3 && c[2] < 2e-3 && c[0] > 1e-3 && c[0] < 3e-3 && c[1] > 1e-3 && c[1] < 3e-3)
            keep2[static_cast<std::size_t>(e)] = 0;
    }
    m.remove_elements(0, keep2);
    EXPECT_NEAR(impact.actual_depth(m), 3e-3, 1e-15);
}

// The same crater made by conversion into semi-Lagrangian particles instead of erosion: the
// converted column's particles failed (damage 1), its elements count as removed by their
// particles' damage, and the measures are the eroded crater's
TEST(Impact, ElementsConvertedIntoParticlesCountByTheirParticlesDamage)
{
    const std::vector<std::string> sl = {"parts.target.erosion=~", "parts.target.conversion={principal_strain: 10}",
                                         "parts.target.kinematics=semi-lagrangian"};
    Model eroded = test::model_from(deck), converted = test::model_from(deck, sl);
    std::vector<char> column(64, 0);
    for (int iz = 2; iz < 4; ++iz)
        for (int iy = 1; iy < 3; ++iy)
            for (int ix = 1; ix < 3; ++ix)
                column[static_cast<std::size_t>(ix + 4 * iy + 16 * iz)] = 1;
    std::vector<char> keep(64, 1);
    for (std::size_t e = 0; e < 64; ++e)
        keep[e] = !column[e];
    eroded.remove_elements(0, keep);
    ASSERT_EQ(converted.convert_elements(0, column), 8);
    NodalBlock& st = *converted.semi_lagrangian_block(0)->nodal_points();
    for (index_t p = 0; p < st.n_points(); ++p)
        st.plastic.failed[static_cast<std::size_t>(p)] = 1.0; // dormant ones hold no element of the column
    const ImpactMeasures a = ImpactAnalysis(eroded, eroded.deck().impact).measure(eroded),
                         b = ImpactAnalysis(converted, converted.deck().impact).measure(converted);
    std::printf("crater by conversion: actual %.4f mm, interpolated %.4f mm, volume %.4f mm^3 (eroded: %.4f, %.4f, "
                "%.4f), damaged volume %.3f mm^3, eroded mass %.3g g\n",
                1e3 * b.actual_depth, 1e3 * b.crater_depth, 1e9 * b.crater_volume, 1e3 * a.actual_depth,
                1e3 * a.crater_depth, 1e9 * a.crater_volume, 1e9 * b.damaged_volume_threshold, 1e3 * b.eroded_mass);
    EXPECT_NEAR(b.actual_depth, 2e-3, 1e-15);
    EXPECT_NEAR(b.crater_depth, a.crater_depth, 1e-15);
    EXPECT_NEAR(b.crater_volume, a.crater_volume, 1e-20);
    EXPECT_NEAR(b.damaged_volume_threshold, 8e-9, 1e-20);
    EXPECT_EQ(b.eroded_mass, 0.0); // converted material is not gone
}

TEST(Impact, DeckErrorsNameTheKey)
{
    EXPECT_THROW(test::model_from(deck, {"impact.target=nothing"}), DeckError);
    EXPECT_THROW(test::model_from(deck, {"impact.direction=[0, 0, 0]"}), DeckError);
    EXPECT_THROW(test::model_from(deck, {"impact.projectile=target"}), DeckError);
    // a point off the target's surface plane
    Model m = test::model_from(deck, {"impact.point=[2 mm, 2 mm, 3.5 mm]"});
    try
    {
        const ImpactAnalysis a(m, m.deck().impact);
        ADD_FAILURE() << "no error for a point off the surface";
    }
    catch (const DeckError& e)
    {
        EXPECT_NE(std::string(e.what()).find("impact.point"), std::string::npos) << e.what();
    }
}

// The crater of the interpolated damage on a known field: a 6 x 6 x 4 block of 1 mm hexes whose
// 4 x 4 centre column (x, y in [1, 5] mm) is eroded through its top two layers (z in [2, 4] mm).
// Nodal damage is the fraction of the node's elements eroded: 1 at the column's inner nodes
// (x, y in [2, 4], z in [2, 4] except z = 2), 1/2 on its sides and at z = 2 under it. The
// threshold 0.95 then lies a tenth of an element from the inner nodes: depth 1 + 0.1 = 1.1 mm
// (the element-based depth is the column's 2 mm); on the surface the farthest crossing is on the
// edge from (2, 2) to (1, 2) mm at (1.9, 2), so the diameter is 2 sqrt(1.1^2 + 1^2) mm; the
// volume is the four top elements inside the inner nodes, 4 mm^3 (the rest of the field stays
// below 0.95 at every sample point: it reaches it only within a tenth of an element of a node).
TEST(Impact, InterpolatedCraterOfAKnownDamageField)
{
    Model m = test::model_from(deck, {"parts.target.generator.size=[6 mm, 6 mm, 4 mm]",
                                      "parts.target.generator.divisions=[6, 6, 4]", "impact.point=[3 mm, 3 mm, 4 mm]"});
    const ImpactAnalysis impact(m, m.deck().impact);
    EXPECT_EQ(impact.crater(m).depth, 0.0);
    std::vector<char> keep(static_cast<std::size_t>(m.meshes[0].n_elements()), 1);
    for (index_t e = 0; e < m.meshes[0].n_elements(); ++e)
    {
        Vec3 c = Vec3::Zero();
        for (int j = 0; j < 8; ++j)
        {
            const index_t n = m.meshes[0].conn[8 * e + j];
            c += 0.125 * Vec3(m.nodes.x0[3 * n], m.nodes.x0[3 * n + 1], m.nodes.x0[3 * n + 2]);
        }
        if (c[0] > 1e-3 && c[0] < 5e-3 && c[1] > 1e-3 && c[1] < 5e-3 && c[2] > 2e-3)
            keep[static_cast<std::size_t>(e)] = 0;
    }
    m.remove_elements(0, keep);
    const ImpactAnalysis::Crater c = impact.crater(m);
    const ImpactMeasures r = impact.measure(m);
    std::printf("interpolated crater: depth %.6f mm, diameter %.6f mm, volume %.6f mm^3; element-based depth %.4f mm\n",
                1e3 * c.depth, 1e3 * c.diameter, 1e9 * c.volume, 1e3 * r.actual_depth);
    EXPECT_NEAR(c.depth, 1.1e-3, 1e-15);
    EXPECT_NEAR(c.diameter, 2.0 * std::sqrt(1.1 * 1.1 + 1.0) * 1e-3, 1e-15);
    EXPECT_NEAR(c.volume, 4e-9, 1e-21);
    EXPECT_NEAR(r.actual_depth, 2e-3, 1e-15);
    EXPECT_EQ(r.crater_depth, c.depth);
    EXPECT_EQ(r.crater_volume, c.volume);
}

// On a semi-Lagrangian RK target the apparent depth reads the surface node under the point of
// impact while its particle is in the body, and the nearest surface node on the plane whose
// particle has not separated once it has left (a fragment is not the crater's floor).
TEST(Impact, ApparentDepthOnASemiLagrangianTargetSkipsSeparatedParticles)
{
    Model m = test::model_from(R"(
title: RK crater
time: {end: 1 us}
parts:
  target:
    generator: {type: box, size: [4 mm, 4 mm, 4 mm], divisions: [4, 4, 4]}
    material: {model: elastic, rho: 2000 kg/m^3, E: 30 GPa, nu: 0.2}
    formulation: rkpm
    kinematics: semi-lagrangian
impact: {target: target, point: [2 mm, 2 mm, 4 mm], direction: [0, 0, -1]}
)");
    const ImpactAnalysis impact(m, m.deck().impact);
    const index_t s = impact.surface_node();
    EXPECT_EQ(impact.attached_surface_node(m), s);
    // the node under the point 0.3 mm down, the rest of the surface 0.1 mm
    std::vector<index_t> plane;
    for (index_t i = 0; i < m.nodes.size(); ++i)
        if (std::abs(m.nodes.x0[3 * i + 2] - 4e-3) < 1e-12)
        {
            plane.push_back(i);
            m.nodes.u[3 * i + 2] = i == s ? -0.3e-3 : -0.1e-3;
        }
    ASSERT_EQ(plane.size(), 25u);
    EXPECT_NEAR(impact.apparent_depth(m), 0.3e-3, 1e-15);
    // the particle under the point separates (its committed cell and volume ratio emptied)
    std::vector<real_t>& ratio = test::sl_block(m).nodal_points()->jacobian;
    ratio[static_cast<std::size_t>(s)] = 0.0;
    const index_t next = impact.attached_surface_node(m);
    ASSERT_GE(next, 0);
    EXPECT_NE(next, s);
    const Vec3 r(m.nodes.x0[3 * next] - 2e-3, m.nodes.x0[3 * next + 1] - 2e-3, m.nodes.x0[3 * next + 2] - 4e-3);
    EXPECT_NEAR(r.norm(), 1e-3, 1e-12); // one of its four neighbours at 1 mm
    EXPECT_NEAR(impact.apparent_depth(m), 0.1e-3, 1e-15);
    // the whole surface gone: no depth to read
    for (const index_t i : plane)
        ratio[static_cast<std::size_t>(i)] = 0.0;
    EXPECT_EQ(impact.attached_surface_node(m), -1);
    EXPECT_EQ(impact.apparent_depth(m), 0.0);
}

// Spall measures (analysis/spall.hpp). A known crack: a 1 x 1 x 10 mm J2 column (fem-1pt) whose
// fifth element from the back face (z = 0) has failed, the layer below it moving out of the back
// face at 3 m/s and the rest at 1 m/s into the part.
namespace
{
const char* spall_column = R"(
time: {end: 1 us}
parts:
  c:
    generator: {type: box, size: [1 mm, 1 mm, 10 mm], divisions: [1, 1, 10]}
    material: {model: j2, rho: 2000 kg/m^3, E: 30 GPa, nu: 0.2, sigy: 30 MPa, etan: 1 GPa, fail: 0.5}
    formulation: fem-1pt
spall: {part: c, point: [0, 0, 0], direction: [0, 0, 1]}
)";
} // namespace

TEST(Spall, ThicknessAndFlyOffVelocityOfAKnownCrack)
{
    Model m = test::model_from(spall_column);
    const SpallAnalysis spall(m, m.deck().spall);
    ASSERT_EQ(spall.column().size(), 11u);
    EXPECT_EQ(spall.measure(m).thickness, 0.0); // no crack
    HexBlock& b = m.meshes[0];
    index_t cracked = -1;
    for (index_t e = 0; e < b.n_elements(); ++e)
    {
        real_t z = 0.0;
        for (int a = 0; a < 8; ++a)
            z += m.nodes.x0[3 * b.conn[8 * e + a] + 2] / 8.0;
        if (std::abs(z - 4.5e-3) < 1e-9)
            cracked = e;
    }
    ASSERT_GE(cracked, 0);
    b.plastic.failed[static_cast<std::size_t>(cracked)] = 1.0;
    for (index_t i = 0; i < m.nodes.size(); ++i)
        m.nodes.v[3 * i + 2] = m.nodes.x0[3 * i + 2] < 4.5e-3 ? -3.0 : 1.0;
    const SpallMeasures r = spall.measure(m);
    std::printf("spall of a known crack: thickness %.4f mm, fly-off %.3f m/s, back face %.3f m/s\n", 1e3 * r.thickness,
                r.fly_off_velocity, r.back_face_velocity);
    EXPECT_NEAR(r.thickness, 4.5e-3, 1e-15); // the cracked element's middle
    EXPECT_NEAR(r.fly_off_velocity, 3.0, 1e-14);
    EXPECT_NEAR(r.back_face_velocity, 3.0, 1e-14);
    // the element eroded: nothing holds the segment, which counts as cracked
    std::vector<char> keep(static_cast<std::size_t>(b.n_elements()), 1);
    keep[static_cast<std::size_t>(cracked)] = 0;
    m.remove_elements(0, keep);
    EXPECT_NEAR(spall.measure(m).thickness, 4.5e-3, 1e-15);
    // a point on no line of nodes
    const Model off = test::model_from(spall_column, {"spall.point=[0.5 mm, 0, 0]"});
    std::string what;
    try
    {
        SpallAnalysis(off, off.deck().spall);
    }
    catch (const DeckError& e)
    {
        what = e.what();
    }
    EXPECT_NE(what.find("spall.point"), std::string::npos) << what;
    EXPECT_NE(test::model_error(spall_column, {"spall.part=d"}).find("spall.part"), std::string::npos);
}

// A rectangular compressive pulse of length L = c0 T (T = 30 us) and amplitude rho c0 v0 = 16.9 MPa,
// 4.7 times the K&C tensile strength, driven into the top of a 300 mm K&C bar (f'c 40 MPa, crack
// band regularized, no rate effects): reflected from the free bottom as tension, it first meets
// the tensile strength at the depth L / 2 = 52.8 mm, and the layer there takes the pulse's
// momentum and flies off at 2 v0 = 4 m/s, less what the crack's fracture energy takes. The
// discrete pulse's edges spread over a few elements as it travels (the tension then meets the
// strength a little before the tail has passed): the crack comes out 4-8 % shallow, and the layer
// flies off at 82-89 % of 2 v0 (2.5 and 1.25 mm elements).
TEST(Spall, ARectangularPulseSpallsABarAtHalfItsLength)
{
    const std::string bar = R"(
time: {end: 160 us, stepper: central-difference}
parts:
  bar:
    generator: {type: box, size: [5 mm, 5 mm, 300 mm], divisions: [1, 1, 120]}
    material: {model: kcc, rho: 2400 kg/m^3, fc: 40 MPa, rate_effects: false, fracture_energy: auto}
    formulation: fem-1pt
node_sets:
  struck: {part: bar, select: {type: named, name: top}}
boundary_conditions:
  - {node_set: struck, velocity: {z: {curve: [[0, -2 m/s], [30 us, -2 m/s], [30.001 us, 0]]}}}
spall: {part: bar, point: [0, 0, 0], direction: [0, 0, 1]}
)";
    for (const int n : {120, 240})
    {
        Model m = test::model_from(bar, {"parts.bar.generator.divisions=[1, 1, " + std::to_string(n) + "]"});
        const MaterialSpec& mat = m.deck().parts[0].material;
        const real_t c0 = std::sqrt(mat.E / mat.rho), half = 0.5 * c0 * 30e-6;
        RunOptions opt;
        opt.progress = false;
        const RunSummary s = run_simulation(m, opt);
        ASSERT_EQ(s.status, "completed") << s.message;
        const SpallMeasures r = SpallAnalysis(m, m.deck().spall).measure(m);
        std::printf("K&C bar, %d elements: spall %.2f mm deep (L / 2 = %.2f mm), fly-off %.3f m/s (2 v0 = 4)\n", n,
                    1e3 * r.thickness, 1e3 * half, r.fly_off_velocity);
        EXPECT_NEAR(r.thickness, half, 0.1 * half);
        EXPECT_GT(r.fly_off_velocity, 0.8 * 4.0);
        EXPECT_LT(r.fly_off_velocity, 4.0);
    }
}
