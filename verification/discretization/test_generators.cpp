// Generators: element counts, exact volumes where the geometry is exact (box), positive
// Jacobians everywhere (no degenerate elements in the cylinder core), named sets on the right faces.
#include <gtest/gtest.h>

#include "rkfem/approximation/fem/hex8_basis.hpp"
#include "rkfem/approximation/fem/hex8_volume_gradient.hpp"
#include "rkfem/discretization/generators.hpp"

using namespace rkfem;

namespace
{
real_t min_jacobian_and_volume(const HexMesh& m, real_t& volume)
{
    real_t jmin = 1e300;
    volume = 0.0;
    const real_t g = 1.0 / std::sqrt(3.0);
    for (index_t e = 0; e < m.n_elements(); ++e)
    {
        real_t xe[8][3], b[8][3];
        for (int I = 0; I < 8; ++I)
            for (int d = 0; d < 3; ++d)
                xe[I][d] = m.x[3 * m.conn[8 * e + I] + d];
        volume += hex8_volume_gradient(xe, b);
        for (const auto& n : hex8_nodes)
        {
            const real_t xi[3] = {g * n[0], g * n[1], g * n[2]};
            real_t dNdx[8][3];
            jmin = std::min(jmin, hex8_gradients(xe, xi, dNdx));
        }
    }
    return jmin;
}
} // namespace

TEST(Generators, BoxHasExactVolumeAndNamedFaces)
{
    const HexMesh m = generate_box(Vec3(1, 2, 3), Vec3(0.4, 0.2, 1.0), {4, 2, 10});
    EXPECT_EQ(m.n_elements(), 80);
    EXPECT_EQ(m.n_nodes(), 5 * 3 * 11);
    real_t vol;
    EXPECT_GT(min_jacobian_and_volume(m, vol), 0.0);
    EXPECT_NEAR(vol, 0.4 * 0.2 * 1.0, 1e-14);
    EXPECT_EQ(m.faces.size(), 2u * (4 * 2 + 4 * 10 + 2 * 10));
    EXPECT_EQ(m.named_faces.at("top").size(), 8u);
    EXPECT_EQ(m.named_faces.at("side").size(), 2u * (4 * 10 + 2 * 10));
    for (index_t f : m.named_faces.at("top"))
        for (index_t n : m.faces[f])
            EXPECT_DOUBLE_EQ(m.x[3 * n + 2], 4.0);
}

TEST(Generators, CylinderCoresHaveNoDegenerateElementsAndConvergeToTheVolume)
{
    for (bool ogrid : {false, true})
    {
        const real_t R = 0.3048, H = 0.3048; // the seed's 12 in x 12 in target
        real_t prev_err = 1.0;
        for (real_t h : {0.0508, 0.0254, 0.0127})
        {
            const HexMesh m = generate_cylinder(Vec3::Zero(), R, H, h, ogrid);
            real_t vol;
            const real_t jmin = min_jacobian_and_volume(m, vol);
            EXPECT_GT(jmin, 0.0) << (ogrid ? "ogrid" : "butterfly") << " h=" << h;
            // every boundary face named top, bottom or side; side nodes on the circle
            std::size_t named = 0;
            for (const auto& [name, ids] : m.named_faces)
                named += ids.size();
            EXPECT_EQ(named, m.faces.size());
            for (index_t f : m.named_faces.at("side"))
                for (index_t n : m.faces[f])
                    EXPECT_NEAR(std::hypot(m.x[3 * n], m.x[3 * n + 1]), R, 1e-12);
            // polygonal (chordal) approximation: error falls like h^2
            const real_t err = std::abs(vol - M_PI * R * R * H) / (M_PI * R * R * H);
            EXPECT_LT(err, prev_err);
            prev_err = err;
        }
        EXPECT_LT(prev_err, 2e-3);
    }
}

TEST(Generators, TubeHasThePolygonalAnnulusVolumeAndNamedFaces)
{
    // the seed's P2 tube (studies/decks/p2_implosion.yaml): 16 in OD, 1.6 in wall, 16 in high
    const real_t R = 0.2032, Ri = 0.16256, H = 0.4064, h = 0.02032;
    const HexMesh m = generate_tube(Vec3(0, 0, 0), R, Ri, H, h);
    const int nr = 2, nz = 20, nt = 56; // (R - Ri) / h, H / h, 4 round(pi (R + Ri) / 4 / h)
    EXPECT_EQ(m.n_elements(), nr * nt * nz);
    EXPECT_EQ(m.n_nodes(), (nr + 1) * nt * (nz + 1));
    real_t vol;
    EXPECT_GT(min_jacobian_and_volume(m, vol), 0.0);
    // a regular nt-gon annulus: area (nt / 2) sin(2 pi / nt) (R^2 - Ri^2), exactly
    EXPECT_NEAR(vol, 0.5 * nt * std::sin(2 * M_PI / nt) * (R * R - Ri * Ri) * H, 1e-14);
    EXPECT_EQ(m.named_faces.at("top").size(), static_cast<std::size_t>(nr * nt));
    EXPECT_EQ(m.named_faces.at("bottom").size(), static_cast<std::size_t>(nr * nt));
    EXPECT_EQ(m.named_faces.at("side").size(), static_cast<std::size_t>(nt * nz));
    EXPECT_EQ(m.named_faces.at("inner").size(), static_cast<std::size_t>(nt * nz));
    EXPECT_EQ(m.faces.size(), static_cast<std::size_t>(2 * nr * nt + 2 * nt * nz)); // closed in theta
    for (const char* name : {"side", "inner"})
        for (index_t f : m.named_faces.at(name))
        {
            // outward: away from the axis on the outer surface, towards it in the bore
            const Vec3 n = quad_normal(m.x, m.faces[f]);
            const Vec3 c = 0.25 * (m.node(m.faces[f][0]) + m.node(m.faces[f][1]) + m.node(m.faces[f][2]) + m.node(m.faces[f][3]));
            EXPECT_GT((std::string(name) == "side" ? 1 : -1) * (n[0] * c[0] + n[1] * c[1]), 0.0);
            for (index_t k : m.faces[f])
                EXPECT_NEAR(std::hypot(m.x[3 * k], m.x[3 * k + 1]), std::string(name) == "side" ? R : Ri, 1e-12);
        }
}

TEST(Generators, ProjectileNamesNoseAndTail)
{
    GeneratorSpec g;
    g.type = GeneratorSpec::Type::Projectile;
    g.origin = Vec3(0, 0, 0.01);
    g.radius = 0.00635;
    g.height = 0.02;
    g.element_size = 0.002;
    g.direction = -1;
    const HexMesh m = generate(g);
    for (index_t f : m.named_faces.at("nose"))
        for (index_t n : m.faces[f])
            EXPECT_NEAR(m.x[3 * n + 2], 0.01, 1e-15);
    for (index_t f : m.named_faces.at("tail"))
        for (index_t n : m.faces[f])
            EXPECT_NEAR(m.x[3 * n + 2], 0.03, 1e-15);
}
