// Impact measures (analysis/impact.hpp) on a crater whose answer is known: a 4 x 4 x 4 block of
// 1 mm hexes whose 2 x 2 centre column is eroded through its top two layers (a crater 2 mm deep
// along -z under the point of impact), plus one eroded element at a bottom corner that no
// removed face joins to the surface (not crater). The struck surface node is moved 0.3 mm down;
// a projectile part moves at 100 m/s along the shot line.
#include <gtest/gtest.h>

#include "../support.hpp"
#include "rkfem/analysis/impact.hpp"

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
