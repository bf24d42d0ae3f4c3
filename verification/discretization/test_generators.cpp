// Generators: element counts, exact volumes where the geometry is exact (box), positive
// Jacobians everywhere (no degenerate elements in the cylinder core), named sets on the right faces.
#include <gtest/gtest.h>

#include "../support.hpp"
#include "rkfem/approximation/fem/hex8_basis.hpp"
#include "rkfem/approximation/fem/hex8_volume_gradient.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/discretization/generators.hpp"
#include "rkfem/discretization/gmsh_mesh.hpp"
#include "rkfem/discretization/keyword_mesh.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

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

// The cylinder is numbered column by column, bottom to top (the height varies fastest): node
// n + 1 is node n raised by one layer, H / nz, within a column, and element e + 1 is element e
// one layer up (each of its nodes' ids one more). Then a column's particles are translates of
// each other with consecutive ids, which the force passes read as whole vectors.
TEST(Generators, CylinderIsNumberedColumnByColumn)
{
    const real_t R = 0.0762, H = 0.3048, h = 0.0127; // the seed's P1 cylinder at 0.5 in
    const HexMesh m = generate_cylinder(Vec3::Zero(), R, H, h, false);
    const index_t layers = 25, nz = 24; // H / h
    ASSERT_EQ(m.n_nodes() % layers, 0);
    ASSERT_EQ(m.n_elements() % nz, 0);
    for (index_t n = 0; n + 1 < m.n_nodes(); ++n)
    {
        const int k = static_cast<int>(n % layers);
        EXPECT_NEAR(m.x[3 * n + 2], H * k / nz, 1e-15) << "node " << n;
        if (k + 1 < layers)
        {
            for (int d = 0; d < 2; ++d)
            {
                ASSERT_EQ(m.x[3 * (n + 1) + d], m.x[3 * n + d]) << "node " << n << " and the one above it";
            }
        }
    }
    for (index_t e = 0; e + 1 < m.n_elements(); ++e)
        if ((e + 1) % nz != 0)
        {
            for (int a = 0; a < 8; ++a)
            {
                ASSERT_EQ(m.conn[8 * (e + 1) + a], m.conn[8 * e + a] + 1) << "element " << e;
            }
        }
}

// The disk's nodes go in a sweep across it (ascending x): an element's columns then lie within
// a few chords of the disk (about 2 R / h nodes each) of each other, a span that grows like R / h;
// in disk_mesh's block-by-block order a core edge node and the ring block beyond it were nearly a
// whole disk apart (156 of 172 columns at 0.5 in, 690 of 780 at 0.25 in).
TEST(Generators, CylinderColumnsAreNumberedInASweepAcrossTheDisk)
{
    const real_t R = 0.0762, H = 0.3048;
    for (const real_t h : {0.0127, 0.00635}) // the seed's P1 at 0.5 and 0.25 in
    {
        const HexMesh m = generate_cylinder(Vec3::Zero(), R, H, h, false);
        const index_t layers = std::lround(H / h) + 1, columns = m.n_nodes() / layers;
        for (index_t c = 0; c + 1 < columns; ++c)
            ASSERT_LE(m.x[3 * layers * c], m.x[3 * layers * (c + 1)] + 1e-9 * R) << "column " << c;
        index_t span = 0;
        for (index_t e = 0; e < m.n_elements(); ++e)
        {
            const auto [lo, hi] = std::minmax_element(m.conn.begin() + 8 * e, m.conn.begin() + 8 * e + 8);
            span = std::max(span, *hi / layers - *lo / layers);
        }
        EXPECT_LE(span, 4 * 2 * R / h) << "h " << h << ": " << columns << " columns";
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
            const Vec3 c =
                0.25 * (m.node(m.faces[f][0]) + m.node(m.faces[f][1]) + m.node(m.faces[f][2]) + m.node(m.faces[f][3]));
            EXPECT_GT((std::string(name) == "side" ? 1 : -1) * (n[0] * c[0] + n[1] * c[1]), 0.0);
            for (index_t k : m.faces[f])
                EXPECT_NEAR(std::hypot(m.x[3 * k], m.x[3 * k + 1]), std::string(name) == "side" ? R : Ri, 1e-12);
        }
}

// A thin tube (R 10 mm, Ri 9.5 mm, 5 mm elements: the outer faces' chord centroids lie at
// R cos(pi / 12) = 9.66 mm, inside the mid-radius 9.75 mm): the faces are named by their own
// outward normal, so the outer surface is 'side' and the bore 'inner', nt x nz faces each; by
// the centroid's radius the outer surface was named 'inner' too and a bore pressure pushed the
// whole tube in.
TEST(Generators, ThinTubeFacesAreNamedByTheirNormal)
{
    const real_t R = 0.010, Ri = 0.0095, H = 0.010, h = 0.005;
    const HexMesh m = generate_tube(Vec3(0.1, -0.2, 0), R, Ri, H, h);
    const int nt = 12, nz = 2; // max(8, 4 round(pi (R + Ri) / 4 / h)) = 4 x 3
    ASSERT_EQ(m.named_faces.count("side"), 1u);
    EXPECT_EQ(m.named_faces.at("side").size(), static_cast<std::size_t>(nt * nz));
    EXPECT_EQ(m.named_faces.at("inner").size(), static_cast<std::size_t>(nt * nz));
    for (const char* name : {"side", "inner"})
        for (index_t f : m.named_faces.at(name))
            for (index_t k : m.faces[f])
                EXPECT_NEAR(std::hypot(m.x[3 * k] - 0.1, m.x[3 * k + 1] + 0.2), std::string(name) == "side" ? R : Ri,
                            1e-12)
                    << name;
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

namespace
{
std::string write_file(const std::string& name, const std::string& text)
{
    const std::string path = (std::filesystem::temp_directory_path() / name).string();
    std::ofstream(path) << text;
    return path;
}

GeneratorSpec keyword(const std::string& path, real_t unit = 1.0, std::vector<long long> pids = {})
{
    GeneratorSpec g;
    g.type = GeneratorSpec::Type::Keyword;
    g.mesh_file = path;
    g.mesh_unit = unit;
    g.mesh_pids = std::move(pids);
    g.loc = {"deck.yaml:5", "parts.a.generator"};
    return g;
}

/// The error message of reading the file (empty: read).
std::string keyword_error(const std::string& name, const std::string& text)
{
    try
    {
        read_keyword_mesh(keyword(write_file(name, text)));
    }
    catch (const DeckError& e)
    {
        return e.what();
    }
    return "";
}
} // namespace

TEST(KeywordMesh, ReadsTheBoxGeneratorsMeshBackToTheBit)
{
    // the box generator's mesh written as *NODE / *ELEMENT_SOLID (free format, 17 digits): read
    // back, the same coordinates, connectivity and boundary faces bit for bit
    const HexMesh box = generate_box(Vec3(0.1, -0.2, 0.3), Vec3(0.4, 0.25, 1.0 / 3.0), {4, 3, 5});
    std::ostringstream k;
    k << "*KEYWORD\n$ written by the test\n*NODE\n";
    char buf[128];
    for (index_t i = 0; i < box.n_nodes(); ++i)
    {
        std::snprintf(buf, sizeof buf, "%lld,%.17g,%.17g,%.17g\n", static_cast<long long>(10 + i), box.x[3 * i],
                      box.x[3 * i + 1], box.x[3 * i + 2]);
        k << buf;
    }
    k << "*ELEMENT_SOLID\n";
    for (index_t e = 0; e < box.n_elements(); ++e)
    {
        k << 100 + e << ",7";
        for (int a = 0; a < 8; ++a)
            k << "," << 10 + box.conn[8 * e + a];
        k << "\n";
    }
    k << "*END\n";
    const HexMesh m = read_keyword_mesh(keyword(write_file("rkfem_box.k", k.str())));
    EXPECT_EQ(m.x, box.x);
    EXPECT_EQ(m.conn, box.conn);
    EXPECT_EQ(m.faces, box.faces);
    EXPECT_EQ(m.named_faces.at("all").size(), box.faces.size());
}

TEST(KeywordMesh, FixedColumnsTwoCardSolidsPartIdsAndUnits)
{
    // two unit cubes side by side in millimetres, fixed columns (a coordinate field touching the
    // next), one solid on one card with PID 1 and one on two cards (R10 format) with PID 2; a
    // *PART card and comments are skipped; a node no solid uses is dropped
    const std::string text = "*KEYWORD\n"
                             "*PART\n"
                             "cube\n"
                             "         1         1\n"
                             "*NODE\n"
                             "$#   nid               x               y               z      tc      rc\n"
                             "       1             0.0             0.0             0.0\n"
                             "       2             1.0             0.0             0.0\n"
                             "       3             1.0             1.0             0.0\n"
                             "       4             0.0             1.0             0.0\n"
                             "       5             0.0             0.0             1.0\n"
                             "       6             1.0             0.0             1.0\n"
                             "       7             1.0             1.0             1.0\n"
                             "       8             0.0             1.0             1.0\n"
                             "       92.0000000000e+00             0.0             0.0\n"
                             "      102.0000000000e+00 1.000000000e+00             0.0\n"
                             "      112.0000000000e+00             0.0 1.000000000e+00\n"
                             "      122.0000000000e+001.0000000000e+001.0000000000e+00\n"
                             "      99           -50.0           -50.0           -50.0\n"
                             "*ELEMENT_SOLID\n"
                             "$#   eid     pid      n1      n2      n3      n4      n5      n6      n7      n8\n"
                             "       1       1       1       2       3       4       5       6       7       8\n"
                             "       2       2\n"
                             "       2       9      10       3       6      11      12       7       0       0\n"
                             "*END\n"
                             "this line is after *END\n";
    const std::string path = write_file("rkfem_two.k", text);
    const HexMesh both = read_keyword_mesh(keyword(path, 1e-3));
    ASSERT_EQ(both.n_elements(), 2);
    ASSERT_EQ(both.n_nodes(), 12); // node 99 is not used
    real_t volume = 0.0;
    EXPECT_GT(min_jacobian_and_volume(both, volume), 0.0);
    EXPECT_NEAR(volume, 2e-9, 1e-24);
    EXPECT_EQ(both.node(8), Vec3(2e-3, 0, 0));
    EXPECT_EQ(both.named_faces.at("all").size(), 10u); // 12 faces less the shared one (a face of each cube)
    const HexMesh second = read_keyword_mesh(keyword(path, 1e-3, {2}));
    ASSERT_EQ(second.n_elements(), 1);
    EXPECT_EQ(second.n_nodes(), 8);
    EXPECT_EQ(second.node(0), Vec3(1e-3, 0, 0)); // the file's order: node 2 first
}

TEST(HexMesh, TheWorstCornerIsTheSmallestScaledJacobian)
{
    // a unit cube: 1 at every corner; sheared by angle theta in the x-z plane (a parallelepiped):
    // sin(90 deg - theta) = cos(theta) at every corner; corner 6 pulled past the centre: negative
    HexMesh m;
    m.x = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
    m.conn = {0, 1, 2, 3, 4, 5, 6, 7};
    HexCorner c = worst_corner(m);
    EXPECT_EQ(c.element, 0);
    EXPECT_NEAR(c.scaled_jacobian, 1.0, 1e-15);
    const double theta = 0.3;
    HexMesh sheared = m;
    for (int i = 4; i < 8; ++i)
        sheared.x[3 * i] += std::tan(theta);
    EXPECT_NEAR(worst_corner(sheared).scaled_jacobian, std::cos(theta), 1e-14);
    HexMesh bad = m;
    bad.x[18] = bad.x[19] = bad.x[20] = 0.2; // node 6 at (0.2, 0.2, 0.2)
    c = worst_corner(bad);
    EXPECT_EQ(c.corner, 6);
    // edges from node 6 to 7, 5, 2: (-0.2, 0.8, 0.8), (0.8, -0.2, 0.8), (0.8, 0.8, -0.2)
    const Vec3 a(-0.2, 0.8, 0.8), b(0.8, -0.2, 0.8), d(0.8, 0.8, -0.2);
    EXPECT_NEAR(c.scaled_jacobian, -a.dot(b.cross(d)) / (a.norm() * b.norm() * d.norm()), 1e-14);
    EXPECT_LT(c.scaled_jacobian, 0.0);
    // the per-element measures the conversion and erosion triggers read: the same smallest corner,
    // and the cube's edges all 1
    real_t x[8][3];
    for (int i = 0; i < 8; ++i)
        for (int k = 0; k < 3; ++k)
            x[i][k] = sheared.x[3 * i + k];
    EXPECT_EQ(smallest_scaled_jacobian(x, sheared.conn.data()), worst_corner(sheared).scaled_jacobian);
    EXPECT_NEAR(edge_aspect_ratio(x, sheared.conn.data()), 1.0 / std::cos(theta), 1e-14); // slanted edges
    // a wedge written as a hex (0 1 3 3 4 5 7 7: the cube's half below its diagonal 1-3): the
    // collapsed corners are skipped, so its worst is the 45-degree corner, sin 45; the edge between
    // the repeated nodes is left out, so its edges run from 1 to the diagonal's sqrt 2
    const index_t wedge[8] = {0, 1, 3, 3, 4, 5, 7, 7};
    real_t w[8][3];
    for (int i = 0; i < 8; ++i)
        for (int k = 0; k < 3; ++k)
            w[i][k] = m.x[3 * static_cast<std::size_t>(wedge[i]) + k];
    EXPECT_NEAR(smallest_scaled_jacobian(w, wedge), std::sqrt(0.5), 1e-15);
    EXPECT_NEAR(edge_aspect_ratio(w, wedge), std::sqrt(2.0), 1e-15);
}

TEST(KeywordMesh, MistakesAreNamedWithTheFilesLine)
{
    const std::string nodes = "*NODE\n1,0,0,0\n2,1,0,0\n3,1,1,0\n4,0,1,0\n5,0,0,1\n6,1,0,1\n7,1,1,1\n8,0,1,1\n";
    auto expect = [](const std::string& msg, const std::string& a, const std::string& b)
    {
        EXPECT_NE(msg.find(a), std::string::npos) << msg;
        EXPECT_NE(msg.find(b), std::string::npos) << msg;
        EXPECT_NE(msg.find("parts.a.generator.file"), std::string::npos) << msg;
    };
    EXPECT_EQ(keyword_error("k_good.k", nodes + "*ELEMENT_SOLID\n1,1,1,2,3,4,5,6,7,8\n"), "");
    expect(keyword_error("k_number.k", "*NODE\n1,0,zero,0\n"), "k_number.k:2", "coordinate 'zero' is not a number");
    expect(keyword_error("k_twice.k", nodes + "3,5,5,5\n"), "k_twice.k:10",
           "node 3 is defined again (first on line 4)");
    expect(keyword_error("k_missing.k", nodes + "*ELEMENT_SOLID\n1,1,1,2,3,4,5,6,7,18\n"), "k_missing.k:11",
           "names node 18, which no *NODE card defines");
    // a wedge written as a hex (node 3 and node 7 repeated) is a solid, checked at its whole corners;
    // upside down it is refused there; three distinct nodes are no solid
    EXPECT_EQ(keyword_error("k_prism.k", nodes + "*ELEMENT_SOLID\n1,1,1,2,3,3,5,6,7,7\n"), "");
    expect(keyword_error("k_prism_inverted.k", nodes + "*ELEMENT_SOLID\n1,1,5,6,7,7,1,2,3,3\n"),
           "k_prism_inverted.k:11", "element 1 is inverted at its node");
    expect(keyword_error("k_sliver.k", nodes + "*ELEMENT_SOLID\n1,1,1,2,2,2,5,5,5,5\n"), "k_sliver.k:11",
           "element 1 has 3 distinct nodes");
    expect(keyword_error("k_inverted.k", nodes + "*ELEMENT_SOLID\n1,1,5,6,7,8,1,2,3,4\n"), "k_inverted.k:11",
           "element 1 is inverted at its node 5 (scaled Jacobian -1 there)");
    // node 7 pushed through the opposite corner: the centre stays positive, corner 7 does not
    expect(keyword_error("k_corner.k", "*NODE\n1,0,0,0\n2,1,0,0\n3,1,1,0\n4,0,1,0\n5,0,0,1\n6,1,0,1\n7,-0.5,-0.5,-0.5\n"
                                       "8,0,1,1\n*ELEMENT_SOLID\n1,1,1,2,3,4,5,6,7,8\n"),
           "k_corner.k:11", "element 1 is inverted at its node 7");
    // two nodes at one place in one solid: a corner of no volume
    expect(keyword_error("k_flat.k", nodes + "9,0,0,0\n*ELEMENT_SOLID\n7,1,1,2,3,4,9,6,7,8\n"), "k_flat.k:12",
           "element 7 is degenerate at its node 1 (scaled Jacobian 0 there)");
    expect(keyword_error("k_eid.k", nodes + "9,2,0,0\n10,2,1,0\n11,2,0,1\n12,2,1,1\n*ELEMENT_SOLID\n"
                                            "1,1,1,2,3,4,5,6,7,8\n1,1,2,9,10,3,6,11,12,7\n"),
           "k_eid.k:16", "element 1 is defined again (first on line 15)");
    expect(keyword_error("k_twin.k", nodes + "*ELEMENT_SOLID\n1,1,1,2,3,4,5,6,7,8\n2,1,2,3,4,1,6,7,8,5\n"),
           "k_twin.k:12", "element 2 has the same eight nodes as element 1 (line 11)");
    expect(keyword_error("k_none.k", nodes), "k_none.k", "has no *ELEMENT_SOLID elements");
    expect(keyword_error("k_short.k", nodes + "*ELEMENT_SOLID\n1,1,1,2,3,4\n"), "k_short.k:11", "fewer than 8 nodes");
    // *INCLUDE is followed in place, relative to the including file's folder: the nodes in one file and the
    // solids in another make one mesh; a missing file and a cycle are named at the *INCLUDE's card
    expect(keyword_error("k_inc_nodes.k", nodes), "k_inc_nodes.k", "has no *ELEMENT_SOLID elements");
    EXPECT_EQ(keyword_error("k_inc_main.k", "*INCLUDE\nk_inc_nodes.k\n*ELEMENT_SOLID\n1,1,1,2,3,4,5,6,7,8\n"), "");
    expect(keyword_error("k_include.k", "*INCLUDE\nk_absent.k\n"), "k_include.k:2", "k_absent.k cannot be opened");
    expect(keyword_error("k_cycle.k", "*INCLUDE\nk_cycle.k\n"), "k_cycle.k:2", "include cycle");
    EXPECT_NE(keyword_error("k_absent_dir/none.k", "").find("cannot be opened"), std::string::npos);
}

namespace
{
GeneratorSpec gmsh(const std::string& path, std::vector<std::string> groups = {})
{
    GeneratorSpec g;
    g.type = GeneratorSpec::Type::Gmsh;
    g.mesh_file = path;
    g.mesh_groups = std::move(groups);
    g.loc = {"deck.yaml:5", "parts.a.generator"};
    return g;
}

/// A mesh as a Gmsh file (MSH 4.1 or 2.2, 17 digits): its hexes in one volume (physical 1
/// "block"), the faces of `face_group` as quadrangles of a surface (physical 2 "bottom"), its first
/// node as a point (physical 3 "corner"); node and element tags from 1 in the mesh's order.
std::string write_msh(const std::string& name, const HexMesh& m, const std::vector<index_t>& face_group, bool v41)
{
    std::ostringstream o;
    char buf[160];
    o << "$MeshFormat\n" << (v41 ? "4.1" : "2.2") << " 0 8\n$EndMeshFormat\n";
    o << "$PhysicalNames\n3\n0 3 \"corner\"\n2 2 \"bottom\"\n3 1 \"block\"\n$EndPhysicalNames\n";
    const index_t n = m.n_nodes(), ne = m.n_elements(), nf = static_cast<index_t>(face_group.size());
    auto xyz = [&](index_t i)
    {
        std::snprintf(buf, sizeof buf, "%.17g %.17g %.17g", m.x[3 * i], m.x[3 * i + 1], m.x[3 * i + 2]);
        return std::string(buf);
    };
    if (v41)
    {
        o << "$Entities\n1 0 1 1\n1 " << xyz(0) << " 1 3\n1 0 0 0 1 1 1 1 2 0\n1 0 0 0 1 1 1 1 1 0\n$EndEntities\n";
        o << "$Nodes\n1 " << n << " 1 " << n << "\n3 1 0 " << n << "\n";
        for (index_t i = 0; i < n; ++i)
            o << i + 1 << "\n";
        for (index_t i = 0; i < n; ++i)
            o << xyz(i) << "\n";
        o << "$EndNodes\n$Elements\n3 " << 1 + nf + ne << " 1 " << 1 + nf + ne << "\n0 1 15 1\n1 1\n2 1 3 " << nf
          << "\n";
        for (index_t k = 0; k < nf; ++k)
        {
            const Quad& q = m.faces[static_cast<std::size_t>(face_group[static_cast<std::size_t>(k)])];
            o << k + 2 << " " << q[0] + 1 << " " << q[1] + 1 << " " << q[2] + 1 << " " << q[3] + 1 << "\n";
        }
        o << "3 1 5 " << ne << "\n";
        for (index_t e = 0; e < ne; ++e)
        {
            o << e + 2 + nf;
            for (int a = 0; a < 8; ++a)
                o << " " << m.conn[8 * static_cast<std::size_t>(e) + a] + 1;
            o << "\n";
        }
        o << "$EndElements\n";
    }
    else
    {
        o << "$Nodes\n" << n << "\n";
        for (index_t i = 0; i < n; ++i)
            o << i + 1 << " " << xyz(i) << "\n";
        o << "$EndNodes\n$Elements\n" << 1 + nf + ne << "\n1 15 2 3 1 1\n";
        for (index_t k = 0; k < nf; ++k)
        {
            const Quad& q = m.faces[static_cast<std::size_t>(face_group[static_cast<std::size_t>(k)])];
            o << k + 2 << " 3 2 2 1 " << q[0] + 1 << " " << q[1] + 1 << " " << q[2] + 1 << " " << q[3] + 1 << "\n";
        }
        for (index_t e = 0; e < ne; ++e)
        {
            o << e + 2 + nf << " 5 2 1 1";
            for (int a = 0; a < 8; ++a)
                o << " " << m.conn[8 * static_cast<std::size_t>(e) + a] + 1;
            o << "\n";
        }
        o << "$EndElements\n";
    }
    return write_file(name, o.str());
}

std::string gmsh_error(const std::string& name, const std::string& text, std::vector<std::string> groups = {})
{
    try
    {
        read_gmsh_mesh(gmsh(write_file(name, text), std::move(groups)));
    }
    catch (const DeckError& e)
    {
        return e.what();
    }
    return "";
}
} // namespace

TEST(GmshMesh, ReadsTheBoxGeneratorsMeshBackToTheBitInBothFormats)
{
    // the box generator's mesh written as MSH 4.1 and 2.2: read back, the same coordinates,
    // connectivity and boundary faces bit for bit; the surface group is the bottom's faces, the
    // point group the first node, and the file's numbers are kept
    const HexMesh box = generate_box(Vec3(0.1, -0.2, 0.3), Vec3(0.4, 0.25, 1.0 / 3.0), {4, 3, 5});
    std::vector<index_t> bottom = box.named_faces.at("bottom");
    std::sort(bottom.begin(), bottom.end());
    for (bool v41 : {true, false})
    {
        const HexMesh m =
            read_gmsh_mesh(gmsh(write_msh(v41 ? "rkfem_box41.msh" : "rkfem_box22.msh", box, bottom, v41)));
        EXPECT_EQ(m.x, box.x);
        EXPECT_EQ(m.conn, box.conn);
        EXPECT_EQ(m.faces, box.faces);
        EXPECT_EQ(m.named_faces.at("bottom"), bottom);
        EXPECT_EQ(m.named_nodes.at("corner"), std::vector<index_t>{0});
        EXPECT_EQ(m.node_ids.back(), box.n_nodes());
        EXPECT_EQ(m.element_ids.front(), 2 + static_cast<long long>(bottom.size()));
    }
    // a physical group asked for by name and by tag; one that is not there is named
    const std::string path = write_msh("rkfem_box_groups.msh", box, bottom, true);
    EXPECT_EQ(read_gmsh_mesh(gmsh(path, {"block"})).conn, box.conn);
    EXPECT_EQ(read_gmsh_mesh(gmsh(path, {"1"})).conn, box.conn);
    try
    {
        read_gmsh_mesh(gmsh(path, {"slab"}));
        ADD_FAILURE() << "no group 'slab'";
    }
    catch (const DeckError& e)
    {
        EXPECT_NE(std::string(e.what()).find("no volume physical group is named or tagged 'slab'"), std::string::npos);
        EXPECT_NE(std::string(e.what()).find("block"), std::string::npos);
    }
}

TEST(GmshMesh, TetrahedraPrismsAndPyramidsAreDegenerateHexes)
{
    // one tetrahedron, one prism and one pyramid (MSH 2.2), each becomes the hex LS-DYNA writes for
    // it (N1 N2 N3 N3 N4 N4 N4 N4; N1 N2 N3 N3 N4 N5 N6 N6; N1 N2 N3 N4 N5 N5 N5 N5)
    const std::string text = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n14\n"
                             "1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n"                    // tetrahedron
                             "5 2 0 0\n6 3 0 0\n7 2 1 0\n8 2 0 1\n9 3 0 1\n10 2 1 1\n" // prism
                             "11 4 0 0\n12 5 0 0\n13 5 1 0\n14 4 1 0\n"                // pyramid base
                             "$EndNodes\n$Elements\n4\n1 4 2 1 1 1 2 3 4\n2 6 2 1 1 5 6 7 8 9 10\n"
                             "3 7 2 1 1 11 12 13 14 4\n4 2 2 7 2 1 3 2\n$EndElements\n";
    // (the pyramid's apex is node 4, shared with the tetrahedron: one mesh)
    const HexMesh m = read_gmsh_mesh(gmsh(write_file("rkfem_degenerate.msh", text)));
    ASSERT_EQ(m.n_elements(), 3);
    const std::vector<index_t> tet(m.conn.begin(), m.conn.begin() + 8);
    EXPECT_EQ(tet, (std::vector<index_t>{0, 1, 2, 2, 3, 3, 3, 3}));
    const std::vector<index_t> prism(m.conn.begin() + 8, m.conn.begin() + 16);
    EXPECT_EQ(prism, (std::vector<index_t>{4, 5, 6, 6, 7, 8, 9, 9}));
    const std::vector<index_t> pyramid(m.conn.begin() + 16, m.conn.end());
    EXPECT_EQ(pyramid, (std::vector<index_t>{10, 11, 12, 13, 3, 3, 3, 3}));
    // boundary faces: 4 of the tetrahedron, 5 of the prism, 5 of the pyramid, less the faces the
    // tetrahedron and pyramid do not share (they share only a node): 14; the triangle group is the
    // tetrahedron's base
    EXPECT_EQ(m.faces.size(), 14u);
    ASSERT_EQ(m.named_faces.at("7").size(), 1u);
    const Quad& base = m.faces[static_cast<std::size_t>(m.named_faces.at("7")[0])];
    std::set<index_t> nodes(base.begin(), base.end());
    EXPECT_EQ(nodes, (std::set<index_t>{0, 1, 2}));
}

// Tetrahedra written as hexes repeat a node, and two tetrahedra write the triangle they share with
// different nodes repeated (a b d d in one, a b b d in the other): the faces are matched by their
// distinct nodes, so a box of Kuhn tetrahedra (six per cube, 3 x 3 x 3 cubes) has exactly the box's
// surface as its boundary: 2 triangles per boundary square (108), total area 6 L^2, every face on
// the surface. Matched by all four nodes (as before 2026-12-07), 216 faces: 108 of them inside.
TEST(GmshMesh, TetrahedraShareTheirTrianglesWhicheverNodeTheyRepeat)
{
    const real_t L = 0.3;
    const HexMesh m = test::split_into_tets(generate_box(Vec3::Zero(), Vec3::Constant(L), {3, 3, 3}));
    ASSERT_EQ(m.n_elements(), 6 * 27);
    EXPECT_EQ(m.faces.size(), 108u);
    real_t area = 0.0;
    Vec3 sum = Vec3::Zero();
    for (const Quad& q : m.faces)
    {
        const Vec3 n = quad_normal(m.x, q);
        area += n.norm();
        sum += n;
        const Vec3 c = 0.25 * (m.node(q[0]) + m.node(q[1]) + m.node(q[2]) + m.node(q[3]));
        const real_t to_surface = std::min({c.minCoeff(), L - c.maxCoeff()});
        EXPECT_LT(to_surface, 1e-12) << "a boundary face inside the box at " << c.transpose();
    }
    EXPECT_NEAR(area, 6 * L * L, 1e-12);
    EXPECT_LT(sum.norm(), 1e-12);
}

TEST(GmshMesh, MistakesAreNamedWithTheFilesLine)
{
    auto expect = [](const std::string& msg, const std::string& a, const std::string& b)
    {
        EXPECT_NE(msg.find(a), std::string::npos) << msg;
        EXPECT_NE(msg.find(b), std::string::npos) << msg;
        EXPECT_NE(msg.find("parts.a.generator.file"), std::string::npos) << msg;
    };
    const std::string head = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n";
    const std::string nodes = "$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n";
    EXPECT_EQ(gmsh_error("g_good.msh", head + nodes + "$Elements\n1\n1 4 2 1 1 1 2 3 4\n$EndElements\n"), "");
    expect(gmsh_error("g_binary.msh", "$MeshFormat\n4.1 1 8\n$EndMeshFormat\n"), "g_binary.msh:2",
           "is a binary MSH file");
    expect(gmsh_error("g_v3.msh", "$MeshFormat\n3.0 0 8\n$EndMeshFormat\n"), "g_v3.msh:2", "is MSH version 3.0");
    expect(gmsh_error("g_tet10.msh", head + nodes + "$Elements\n1\n1 11 2 1 1 1 2 3 4 1 2 3 4 1 2\n$EndElements\n"),
           "g_tet10.msh:13", "element 1 is of type 11");
    expect(gmsh_error("g_node.msh", head + nodes + "$Elements\n1\n1 4 2 1 1 1 2 3 9\n$EndElements\n"), "g_node.msh:13",
           "names node 9, which $Nodes does not define");
    expect(gmsh_error("g_number.msh", head + "$Nodes\n1\n1 0 zero 0\n$EndNodes\n"), "g_number.msh:6",
           "coordinate 'zero' is not a number");
    expect(gmsh_error("g_inverted.msh", head + nodes + "$Elements\n1\n1 4 2 1 1 1 3 2 4\n$EndElements\n"),
           "g_inverted.msh:13", "element 1 is inverted");
    expect(gmsh_error("g_short.msh", head + "$Nodes\n2\n1 0 0 0\n$EndNodes\n"), "g_short.msh:7",
           "a node number '$EndNodes' is not an integer");
    expect(gmsh_error("g_surface.msh", head + nodes + "$Elements\n1\n1 2 2 1 1 1 2 3\n$EndElements\n"), "g_surface.msh",
           "has no volume elements");
}

TEST(GmshMesh, ADeckOnAGmshMeshRunsAsTheGeneratorsDeck)
{
    // the column of column_wave.yaml's kind, once from the box generator and once from the same
    // mesh in a Gmsh file with the bottom as a physical surface: the same displacements bit for bit
    const HexMesh box = generate_box(Vec3::Zero(), Vec3(2e-3, 2e-3, 10e-3), {2, 2, 10});
    std::vector<index_t> bottom = box.named_faces.at("bottom");
    std::sort(bottom.begin(), bottom.end());
    const std::string path = write_msh("rkfem_column.msh", box, bottom, true);
    const std::string rest = "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n"
                             "node_sets:\n  driven: {part: column, select: {type: named, name: bottom}}\n"
                             "boundary_conditions:\n  - {node_set: driven, velocity: {z: 10 m/s}}\n";
    const std::string a = "time: {end: 2 us}\nparts:\n  column:\n    generator: {type: box, origin: [0, 0, 0], "
                          "size: [2 mm, 2 mm, 10 mm], divisions: [2, 2, 10]}\n" +
                          rest;
    const std::string b = "time: {end: 2 us}\nparts:\n  column:\n    generator: {type: gmsh, file: \"" + path +
                          "\", physical: block}\n" + rest;
    const std::vector<real_t> ua = test::displacements_on_threads(a, {}, 1);
    const std::vector<real_t> ub = test::displacements_on_threads(b, {}, 1);
    EXPECT_EQ(ua, ub);
    real_t top = 0.0;
    for (std::size_t i = 2; i < ua.size(); i += 3)
        top = std::max(top, ua[i]);
    EXPECT_GT(top, 0.0); // the wave has moved the driven end
}
