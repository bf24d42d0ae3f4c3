// GCC 12 reports a false "may be used uninitialized" inside Eigen's AVX-512 dense kernels here
// (the eigenvalue solver), and "used uninitialized" in GCC's own AVX-512 intrinsics header (its
// "__m512d __Y = __Y" idiom), inlined from Eigen's packet transposes.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

// Voronoi cells of a jittered cloud clipped to a box or a cylinder's tangent prism (cut in doubles;
// CGAL's exact construction is their twin): volumes
// tile the body, SCNI on the cells satisfies the integration constraint to round-off and passes
// the static linear patch test.
#include <gtest/gtest.h>

#include <tuple>

#include <Eigen/Eigenvalues>

#include <cstdio>
#include <map>
#include <random>

#include <omp.h>

#include "../support.hpp"
#include "rkfem/approximation/shape_evaluator.hpp"
#include "rkfem/discretization/generators.hpp"
#include "rkfem/discretization/voronoi_cells.hpp"
#include "rkfem/integration/nodal/nodal_integration.hpp"
#include "rkfem/model/nodal_block_build.hpp"
#include "rkfem/operators/linear_static.hpp"
#include "rkfem/operators/nodal_block.hpp"

using namespace rkfem;

namespace
{
/// Random cloud: a 6^3 lattice in the unit cube with every point jittered (boundary points stay
/// inside), plus 40 uniformly random points.
std::vector<real_t> cloud()
{
    std::mt19937 gen(11);
    std::uniform_real_distribution<real_t> j(-0.3, 0.3), u(0.02, 0.98);
    std::vector<real_t> x;
    const int n = 6;
    for (int k = 0; k < n; ++k)
        for (int jj = 0; jj < n; ++jj)
            for (int i = 0; i < n; ++i)
                for (int idx : {i, jj, k})
                    x.push_back((idx + 0.5 + j(gen)) / n);
    for (int p = 0; p < 40 * 3; ++p)
        x.push_back(u(gen));
    return x;
}

struct VoronoiSetup
{
    std::vector<real_t> x;
    VoronoiCells cells;
    RkShapeFunctions rk;
    IntegrationOperator op;
};

/// RK shape functions (support 1.6 x each cell's spacing) and SCNI on the cells of `s`.
void build_scni(VoronoiSetup& s)
{
    std::vector<real_t> a = s.cells.spacing;
    for (auto& v : a)
        v *= 1.6;
    s.rk = RkShapeFunctions(s.x, a, {1, KernelType::CubicBSpline, SupportShape::Sphere, 1.6});
    s.op = build_scni_cells(s.cells, s.x, RkShapes(s.rk));
}

VoronoiSetup make_setup()
{
    VoronoiSetup s;
    s.x = cloud();
    s.cells = voronoi_cells(s.x, box_halfspaces(Vec3::Zero(), Vec3::Ones()));
    build_scni(s);
    return s;
}
} // namespace

namespace
{
/// IC1 (sum_L b_I(L) V_L = sum over body-boundary facet points of Psi_I n dA) and the SCNI
/// gradient of the linear field x: the largest errors of each.
std::pair<real_t, real_t> scni_consistency(const VoronoiSetup& s)
{
    const index_t n = s.cells.size();
    std::vector<Vec3> lhs(static_cast<std::size_t>(n), Vec3::Zero()), rhs = lhs;
    for (index_t p = 0; p < s.op.n_points(); ++p)
        for (index_t k = s.op.offsets[p]; k < s.op.offsets[p + 1]; ++k)
            lhs[s.op.nodes[k]] += s.op.weight[p] * s.op.gradient(k);
    RkSample smp;
    for (const CellFacetPoint& fp : s.cells.points)
        if (fp.neighbour < 0)
        {
            s.rk.evaluate(fp.x, false, smp);
            for (index_t k = 0; k < smp.size(); ++k)
                rhs[smp.nodes[k]] += smp.psi[k] * fp.nda;
        }
    real_t ic = 0.0, lin = 0.0;
    for (index_t i = 0; i < n; ++i)
        ic = std::max(ic, (lhs[i] - rhs[i]).norm());
    for (index_t p = 0; p < s.op.n_points(); ++p)
    {
        Mat3 g = Mat3::Zero();
        for (index_t k = s.op.offsets[p]; k < s.op.offsets[p + 1]; ++k)
            g += Vec3(s.x[3 * s.op.nodes[k]], s.x[3 * s.op.nodes[k] + 1], s.x[3 * s.op.nodes[k] + 2]) *
                 s.op.gradient(k).transpose();
        lin = std::max(lin, (g - Mat3::Identity()).cwiseAbs().maxCoeff());
    }
    return {ic, lin};
}
} // namespace

TEST(VoronoiCells, VolumesTileTheBodyAndScniSatisfiesTheIntegrationConstraint)
{
    const VoronoiSetup s = make_setup();
    real_t vol = 0.0, vmin = 1e300;
    for (real_t v : s.cells.volume)
    {
        vol += v;
        vmin = std::min(vmin, v);
    }
    std::printf("%d cells, total volume - 1 = %.2e, smallest %.3e\n", s.cells.size(), vol - 1.0, vmin);
    EXPECT_NEAR(vol, 1.0, 1e-12);
    EXPECT_GT(vmin, 0.0);
    const auto [ic, lin] = scni_consistency(s);
    std::printf("IC1 error %.2e (per unit area), linear gradient error %.2e\n", ic, lin);
    EXPECT_LT(ic, 1e-12);
    EXPECT_LT(lin, 1e-11);
}

// Points clustered in one corner of a large box: the cells of the cluster's outer points reach
// the far corner, past the body planes that the first construction leaves out (those farther
// than twice the farthest Delaunay neighbour), so those cells are built again with every plane.
// They must still tile the box and stay inside it.
TEST(VoronoiCells, CellsReachingFarBodyPlanesAreRebuiltWithAllOfThem)
{
    VoronoiSetup s;
    std::mt19937 gen(11);
    std::uniform_real_distribution<real_t> u(0.01, 0.05);
    for (int i = 0; i < 40; ++i)
        s.x.insert(s.x.end(), {u(gen), u(gen), u(gen)});
    const std::vector<HalfSpace> body = box_halfspaces(Vec3::Zero(), Vec3::Ones());
    s.cells = voronoi_cells(s.x, body);
    real_t vol = 0.0;
    for (real_t v : s.cells.volume)
        vol += v;
    real_t outside = 0.0;
    for (const CellFacetPoint& p : s.cells.points)
        for (const HalfSpace& h : body)
            outside = std::max(outside, h.normal.dot(p.x) - h.offset);
    std::printf("%d of %d cells rebuilt with all body planes; total volume - 1 = %.2e, farthest facet point "
                "outside %.1e\n",
                s.cells.rebuilt_with_all_planes, s.cells.size(), vol - 1.0, outside);
    EXPECT_GT(s.cells.rebuilt_with_all_planes, 0);
    EXPECT_NEAR(vol, 1.0, 1e-12);
    EXPECT_LE(outside, 1e-12);
    // each cell is closed: sum of n dA = 0 (its facets' areas and normals from CGAL's polygons)
    real_t open = 0.0;
    for (index_t i = 0; i < s.cells.size(); ++i)
    {
        Vec3 nda = Vec3::Zero();
        for (index_t k = s.cells.offsets[i]; k < s.cells.offsets[i + 1]; ++k)
            nda += s.cells.points[k].nda;
        open = std::max(open, nda.norm());
    }
    std::printf("largest |sum n dA| of a cell %.1e\n", open);
    EXPECT_LT(open, 1e-12);
}

namespace
{
/// A jittered cloud generated in a cylinder (particles on its side and caps).
GeneratorSpec cylinder_cloud_spec()
{
    GeneratorSpec g;
    g.type = GeneratorSpec::Type::Cloud;
    g.body = GeneratorSpec::Body::Cylinder;
    g.origin = Vec3(0.1, -0.2, 0.3);
    g.radius = 0.5;
    g.height = 0.8;
    g.element_size = 0.125;
    g.jitter = 0.3;
    return g;
}
} // namespace

// A cylinder body (cloud parts with body: cylinder): the cells are clipped to the prism of planes
// tangent to the cylinder, so they tile the prism, whose volume is the cylinder's times
// sides tan(pi / sides) / pi; SCNI on them satisfies IC1. Generated (jittered, particles on the
// surface) and random clouds.
TEST(VoronoiCells, CylinderBodyCellsTileTheTangentPrism)
{
    const GeneratorSpec g = cylinder_cloud_spec();
    for (const bool random : {false, true})
    {
        VoronoiSetup s;
        s.x = generate_cloud(g).x;
        if (random) // uniform in the cylinder: rejection sampling in the bounding box
        {
            const std::size_t n = s.x.size() / 3;
            s.x.clear();
            std::mt19937 gen(5);
            std::uniform_real_distribution<real_t> u(-1.0, 1.0), w(0.0, 1.0);
            while (s.x.size() < 3 * n)
            {
                const real_t a = u(gen), b = u(gen);
                if (a * a + b * b <= 1.0)
                    s.x.insert(s.x.end(), {g.origin[0] + g.radius * a, g.origin[1] + g.radius * b,
                                           g.origin[2] + g.height * w(gen)});
            }
        }
        const index_t n = static_cast<index_t>(s.x.size() / 3);
        const std::vector<HalfSpace> body = cloud_body(g, n);
        const int sides = static_cast<int>(body.size()) - 2;
        s.cells = voronoi_cells(s.x, body);
        real_t vol = 0.0;
        for (real_t v : s.cells.volume)
            vol += v;
        const real_t cylinder = M_PI * g.radius * g.radius * g.height;
        const real_t prism = cylinder * sides * std::tan(M_PI / sides) / M_PI;
        build_scni(s);
        const auto [ic, lin] = scni_consistency(s);
        std::printf("%s cylinder cloud, %d cells, %d sides: volume / prism - 1 = %.2e (prism / cylinder - 1 = %.2e); "
                    "IC1 error %.2e, linear gradient error %.2e\n",
                    random ? "random" : "generated", n, sides, vol / prism - 1.0, prism / cylinder - 1.0, ic, lin);
        EXPECT_NEAR(vol / prism, 1.0, 1e-12);
        EXPECT_LT(prism / cylinder - 1.0, 1.1 * std::pow(M_PI / sides, 2) / 3.0);
        EXPECT_LT(ic, 1e-12);
        EXPECT_LT(lin, 1e-11);
    }
}

// A body thinner than its spacing (a plate one layer of particles thick, with the in-plane
// spacing 80x its thickness): the start point pushed off the faces would leave the body, which
// made CGAL's hull free an invalid pointer (box thin in z) or never return (thin in x). The cells
// start from their deepest point instead; they must tile the plate, stay closed, and SCNI on them
// must satisfy IC1. Box and cylinder bodies.
TEST(VoronoiCells, PlatesThinnerThanTheSpacingTileTheBody)
{
    for (int body_kind = 0; body_kind < 3; ++body_kind)
    {
        GeneratorSpec g;
        g.type = GeneratorSpec::Type::Cloud;
        g.element_size = 1e-3;
        g.jitter = 0.25;
        g.seed = 1;
        real_t body_volume = 0.0;
        if (body_kind < 2) // box thin in z, then in x
        {
            g.size = body_kind == 0 ? Vec3(4e-3, 4e-3, 12e-6) : Vec3(12e-6, 4e-3, 4e-3);
            body_volume = g.size.prod();
        }
        else
        {
            g.body = GeneratorSpec::Body::Cylinder;
            g.radius = 3e-3;
            g.height = 12e-6;
        }
        VoronoiSetup s;
        s.x = generate_cloud(g).x;
        const index_t n = static_cast<index_t>(s.x.size() / 3);
        const std::vector<HalfSpace> body = cloud_body(g, n);
        if (body_kind == 2) // the tangent prism
        {
            const int sides = static_cast<int>(body.size()) - 2;
            body_volume = M_PI * g.radius * g.radius * g.height * sides * std::tan(M_PI / sides) / M_PI;
        }
        s.cells = voronoi_cells(s.x, body);
        real_t vol = 0.0, vmin = 1e300, open = 0.0, outside = 0.0;
        for (index_t i = 0; i < s.cells.size(); ++i)
        {
            vol += s.cells.volume[i];
            vmin = std::min(vmin, s.cells.volume[i]);
            Vec3 nda = Vec3::Zero();
            for (index_t k = s.cells.offsets[i]; k < s.cells.offsets[i + 1]; ++k)
                nda += s.cells.points[k].nda;
            open = std::max(open, nda.norm() / std::pow(s.cells.volume[i], 2.0 / 3.0));
        }
        for (const CellFacetPoint& p : s.cells.points)
            for (const HalfSpace& h : body)
                outside = std::max(outside, h.normal.dot(p.x) - h.offset);
        build_scni(s);
        const auto [ic, lin] = scni_consistency(s);
        std::printf("plate %d: %d cells, volume / body - 1 = %.2e, smallest cell %.2e of the mean, largest "
                    "|sum n dA| / V^(2/3) %.1e, farthest outside %.1e m; IC1 %.2e, linear gradient %.2e\n",
                    body_kind, n, vol / body_volume - 1.0, vmin * n / vol, open, outside, ic, lin);
        EXPECT_NEAR(vol / body_volume, 1.0, 1e-12);
        EXPECT_GT(vmin, 0.0);
        EXPECT_LT(open, 1e-12);
        EXPECT_LE(outside, 1e-15);
        EXPECT_LT(ic, 1e-12 * g.element_size * g.element_size);
        EXPECT_LT(lin, 1e-11);
    }
}

// The cells are the same bits from one construction to the next: CGAL lists a cell's vertices
// and facets in an order that follows heap addresses, and a vertex's double depended on the
// planes CGAL used for it, so runs differed at round-off (address-space randomization; a restart
// from a checkpoint did not reproduce the run). Two constructions with the heap shifted between
// them must agree exactly.
TEST(VoronoiCells, CellsAreTheSameBitsWhateverTheHeapAddresses)
{
    GeneratorSpec g;
    g.type = GeneratorSpec::Type::Cloud;
    g.size = Vec3(4e-3, 4e-3, 12e-3);
    g.element_size = 1e-3;
    g.jitter = 0.25;
    g.seed = 1;
    const std::vector<real_t> x = generate_cloud(g).x;
    const std::vector<HalfSpace> body = cloud_body(g, static_cast<index_t>(x.size() / 3));
    const VoronoiCells a = voronoi_cells(x, body);
    std::vector<std::vector<real_t>> shift; // other allocations: the second construction's nodes land elsewhere
    for (int k = 1; k < 200; ++k)
        shift.emplace_back(static_cast<std::size_t>(k * 37 % 101 + 1), 1.0);
    const VoronoiCells b = voronoi_cells(x, body);
    ASSERT_EQ(a.points.size(), b.points.size());
    ASSERT_EQ(a.sub_points.size(), b.sub_points.size());
    std::size_t differ = 0;
    for (std::size_t k = 0; k < a.points.size(); ++k)
        differ += a.points[k].x != b.points[k].x || a.points[k].nda != b.points[k].nda ||
                  a.points[k].neighbour != b.points[k].neighbour;
    for (std::size_t k = 0; k < a.sub_points.size(); ++k)
        differ += a.sub_points[k].x != b.sub_points[k].x || a.sub_points[k].nda != b.sub_points[k].nda;
    for (std::size_t i = 0; i < a.volume.size(); ++i)
        differ += a.volume[i] != b.volume[i];
    std::printf("%zu facet points, %zu sub-cell points, %zu cells: %zu values differ\n", a.points.size(),
                a.sub_points.size(), a.volume.size(), differ);
    EXPECT_EQ(differ, 0u);
}

namespace
{
/// Static linear patch test with the stiffness of `op` on the cloud of `s`: the error of the
/// solution against the exact linear field, relative to its size.
real_t voronoi_patch_error(const VoronoiSetup& s, const IntegrationOperator& op, const char* name)
{
    const index_t n = s.cells.size();
    const ElasticParams mat = ElasticParams::from_E_nu(1.0, 1e3, 0.3);
    const SparseMatrix K = assemble_stiffness(op, mat, n);
    Mat3 ge;
    ge << 0.2, 0.3, 0.1, 0.1, -0.2, 0.15, 0.05, 0.1, -0.3;
    const Mat3 eps = 0.5 * (ge + ge.transpose());
    const Mat3 sigma = mat.lambda * eps.trace() * Mat3::Identity() + 2.0 * mat.mu * eps;
    // traction on all body facets; rigid modes removed by prescribing the exact field at the
    // particles of cells that touch the boundary
    std::vector<real_t> f(3 * static_cast<std::size_t>(n), 0.0);
    RkSample smp;
    std::vector<char> touches(static_cast<std::size_t>(n), 0);
    for (index_t i = 0; i < n; ++i)
        for (index_t q = s.cells.offsets[i]; q < s.cells.offsets[i + 1]; ++q)
        {
            const CellFacetPoint& fp = s.cells.points[q];
            if (fp.neighbour >= 0)
                continue;
            touches[i] = 1;
            s.rk.evaluate(fp.x, false, smp);
            const Vec3 t = sigma * fp.nda;
            for (index_t k = 0; k < smp.size(); ++k)
                for (int d = 0; d < 3; ++d)
                    f[3 * smp.nodes[k] + d] += smp.psi[k] * t[d];
        }
    auto exact = [&](index_t i)
    { return Vec3(ge * Vec3(s.x[3 * i], s.x[3 * i + 1], s.x[3 * i + 2]) + Vec3(0.1, -0.05, 0.2)); };
    std::vector<index_t> dofs;
    std::vector<real_t> vals;
    for (index_t i = 0; i < n; ++i)
        if (touches[i])
            for (int d = 0; d < 3; ++d)
            {
                dofs.push_back(3 * i + d);
                vals.push_back(exact(i)[d]);
            }
    const std::vector<real_t> u = solve_static(K, f, dofs, vals);
    real_t err = 0.0, umax = 0.0;
    for (index_t i = 0; i < n; ++i)
    {
        err = std::max(err, (Vec3(u[3 * i], u[3 * i + 1], u[3 * i + 2]) - exact(i)).norm());
        umax = std::max(umax, exact(i).norm());
    }
    std::printf("Voronoi %s patch test: %zu free particles, displacement error %.2e\n", name,
                static_cast<std::size_t>(n) - dofs.size() / 3, err / umax);
    return err / umax;
}
} // namespace

TEST(VoronoiCells, ScniOnVoronoiCellsPassesTheLinearPatchTest)
{
    const VoronoiSetup s = make_setup();
    EXPECT_LT(voronoi_patch_error(s, s.op, "SCNI"), 1e-10);
}

// SD-SCNI on a cloud (scheme sd-scni on cloud parts): every pyramid sub-cell of a Voronoi cell is
// a stress point; the sub-cells tile the body and their smoothed gradients reproduce linear
// fields, so it passes the patch test too.
TEST(VoronoiCells, SdScniOnVoronoiSubCellsPassesTheLinearPatchTest)
{
    const VoronoiSetup s = make_setup();
    const IntegrationOperator sd = build_sd_cells(s.cells, RkShapes(s.rk));
    EXPECT_GT(sd.n_points(), 3 * s.cells.size());
    EXPECT_LT(voronoi_patch_error(s, sd, "SD-SCNI"), 1e-10);
}

// MSCNI's sub-cells on Voronoi cells (pyramids over the facets): they tile each cell, and the
// sub-cell smoothed gradients reproduce linear fields, so the stabilization g_s = b_s - b_L
// vanishes on them (the patch test survives the stabilization).
TEST(VoronoiCells, SubCellsTileTheCellsAndReproduceLinearGradients)
{
    const VoronoiSetup s = make_setup();
    std::vector<real_t> sum(s.cells.volume.size(), 0.0);
    for (const auto& sc : s.cells.sub_cells)
    {
        EXPECT_GT(sc.volume, 0.0);
        sum[sc.cell] += sc.volume;
    }
    real_t tile = 0.0;
    for (std::size_t i = 0; i < sum.size(); ++i)
        tile = std::max(tile, std::abs(sum[i] - s.cells.volume[i]) / s.cells.volume[i]);
    const IntegrationOperator sd = build_sd_cells(s.cells, RkShapes(s.rk));
    const IntegrationOperator st = build_mscni_stabilization(s.op, sd);
    // error of sum_I x_I (x) g_I against the target, relative to the size of the terms summed
    // (max |x_I| |g_I|)
    auto linear_error = [&](const IntegrationOperator& op, const Mat3& target)
    {
        real_t e = 0.0;
        for (index_t p = 0; p < op.n_points(); ++p)
        {
            Mat3 g = Mat3::Zero();
            real_t scale = 0.0;
            for (index_t k = op.offsets[p]; k < op.offsets[p + 1]; ++k)
            {
                const Vec3 xk(s.x[3 * op.nodes[k]], s.x[3 * op.nodes[k] + 1], s.x[3 * op.nodes[k] + 2]);
                g += xk * op.gradient(k).transpose();
                scale = std::max(scale, xk.norm() * op.gradient(k).norm());
            }
            e = std::max(e, (g - target).cwiseAbs().maxCoeff() / scale);
        }
        return e;
    };
    const real_t sd_err = linear_error(sd, Mat3::Identity()), st_err = linear_error(st, Mat3::Zero());
    std::printf("%zu sub-cells: volumes tile the cells to %.2e; linear gradient error %.2e (sub-cells), %.2e (MSCNI), "
                "relative to the terms\n",
                s.cells.sub_cells.size(), tile, sd_err, st_err);
    EXPECT_LT(tile, 1e-12);
    EXPECT_LT(sd_err, 1e-12); // round-off of ~100 boundary terms per sub-cell
    EXPECT_LT(st_err, 1e-12);
}

// On a cloud too, SD-SCNI's stiffness is SCNI's plus MSCNI's with c_s = 1 (Puso et al. 2008: the
// sub-cells' volume-weighted gradients add up to the cell's), and it has exactly the six rigid
// body modes of a free body.
TEST(VoronoiCells, SdScniIsMscniWithUnitCoefficientAndHasOnlyRigidModes)
{
    const VoronoiSetup s = make_setup();
    const index_t n = s.cells.size();
    const ElasticParams mat = ElasticParams::from_E_nu(1.0, 1e3, 0.3);
    const IntegrationOperator sd = build_sd_cells(s.cells, RkShapes(s.rk));
    const Eigen::MatrixXd Ks(assemble_stiffness(sd, mat, n));
    const Eigen::MatrixXd Km(assemble_stiffness(s.op, mat, n) +
                             assemble_stiffness(build_mscni_stabilization(s.op, sd), mat, n, 1.0));
    const real_t rel = (Km - Ks).cwiseAbs().maxCoeff() / Ks.cwiseAbs().maxCoeff();
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Ks, Eigen::EigenvaluesOnly);
    const Eigen::VectorXd lam = es.eigenvalues();
    int zero = 0;
    for (Eigen::Index i = 0; i < lam.size(); ++i)
        zero += lam[i] < 1e-8 * lam[lam.size() - 1];
    std::printf("cloud: |K_scni + K_mscni(c_s = 1) - K_sd_scni| / max|K| = %.2e; SD-SCNI zero-energy modes %d, "
                "first deformation mode / max %.2e\n",
                rel, zero, lam[6] / lam[lam.size() - 1]);
    EXPECT_LT(rel, 1e-12);
    EXPECT_EQ(zero, 6);
}

// One SCNI point per Voronoi face (merge_face_points, deck key nodal_integration.facet_points:
// faces): the face's area centroid and n dA. The cells' volumes from the face points are the
// triangles' to round-off, the integration constraint and the gradient of x hold as with the
// triangles, the static linear patch test passes (its tractions on the same face points), and
// the build by regions is the pointwise one to round-off; with about a fifth of the points.
TEST(VoronoiCells, OnePointPerFaceKeepsScniExactForLinearFields)
{
    VoronoiSetup s = make_setup();
    const std::size_t triangles = s.cells.points.size();
    merge_face_points(s.cells);
    real_t worst_volume = 0.0;
    for (index_t i = 0; i < s.cells.size(); ++i)
    {
        real_t v = 0.0;
        for (index_t q = s.cells.offsets[i]; q < s.cells.offsets[i + 1]; ++q)
            v += s.cells.points[q].x.dot(s.cells.points[q].nda) / 3.0;
        worst_volume = std::max(worst_volume, std::abs(v - s.cells.volume[i]) / s.cells.volume[i]);
    }
    build_scni(s);
    const auto [ic, lin] = scni_consistency(s);
    const real_t patch = voronoi_patch_error(s, s.op, "SCNI, one point per face");
    const IntegrationOperator fast = build_scni_cells_rk(s.cells, s.x, s.rk, 0.0);
    const real_t by_regions = rkfem::test::gradient_difference(fast, s.op);
    std::printf("%zu face points for %zu triangles; volumes to %.2e, IC1 %.2e, linear gradient %.2e, "
                "by regions %.2e\n",
                s.cells.points.size(), triangles, worst_volume, ic, lin, by_regions);
    EXPECT_LT(5 * s.cells.points.size(), 2 * triangles) << "at most 40 % of the points";
    EXPECT_LT(worst_volume, 1e-13);
    EXPECT_LT(ic, 1e-12);
    EXPECT_LT(lin, 1e-11);
    EXPECT_LT(patch, 1e-10);
    EXPECT_LT(by_regions, 1e-13);
}

// build_scni_cells_rk (each cell's particles gathered once, RkRegionValues; a face between cells
// at most a block apart evaluated once, by the first, and handed to the second) against
// build_scni_cells with RkShapes (the plain twin, every cell's every point): the same stencils
// and weights, gradients to round-off, with and without the drop tolerance, on the random
// cloud's cells. With blocks of 2,048 cells every shared face is evaluated once; with blocks of
// 7 most are evaluated from both sides (cells further apart) and the rows cross many blocks;
// with a third of the faces hidden from their first cell (its neighbour -1, so it evaluates
// the face as its own and hands nothing on) the second cell evaluates them itself.
TEST(VoronoiCells, ScniOfRkFunctionsByRegionsIsThePointwiseBuildToRoundOff)
{
    const VoronoiSetup s = make_setup();
    VoronoiCells hidden = s.cells;
    index_t n_hidden = 0;
    for (index_t i = 0; i < hidden.size(); ++i)
        for (index_t q = hidden.offsets[i]; q < hidden.offsets[i + 1]; ++q)
        {
            CellFacetPoint& fp = hidden.points[q];
            if (fp.neighbour > i && fp.neighbour % 3 == 0)
            {
                n_hidden += fp.starts_face;
                fp.neighbour = -1;
            }
        }
    ASSERT_GT(n_hidden, 10);
    for (const real_t tau : {0.0, 1e-5})
    {
        const IntegrationOperator plain = build_scni_cells(s.cells, s.x, RkShapes(s.rk, tau));
        for (const auto& [cells, block, what] :
             {std::tuple{&s.cells, 2048, "blocks of 2048"}, std::tuple{&s.cells, 7, "blocks of 7"},
              std::tuple{static_cast<const VoronoiCells*>(&hidden), 2048, "faces hidden from their first cell"}})
        {
            const IntegrationOperator fast = build_scni_cells_rk(*cells, s.x, s.rk, tau, block);
            EXPECT_EQ(fast.weight, plain.weight);
            const real_t difference = rkfem::test::gradient_difference(fast, plain);
            std::printf("tau %.0e, %s: %d entries, largest gradient difference %.2e of the largest\n", tau, what,
                        plain.n_entries(), difference);
            EXPECT_LT(difference, 1e-13) << what; // measured up to 3.4e-15 with every face from both sides
        }
    }
}

// The cells are built in parallel, each into a part of its own joined in point order: the same
// cells, bit for bit, on 1 and 2 threads.
namespace
{
// Two builds of one cloud's cells: the same volumes, spacings and facet points, bit for bit.
void expect_same_cells(const VoronoiCells& a, const VoronoiCells& b)
{
    EXPECT_EQ(a.volume, b.volume);
    EXPECT_EQ(a.spacing, b.spacing);
    EXPECT_EQ(a.offsets, b.offsets);
    ASSERT_EQ(a.points.size(), b.points.size());
    for (std::size_t q = 0; q < a.points.size(); ++q)
    {
        EXPECT_EQ(a.points[q].x, b.points[q].x);
        EXPECT_EQ(a.points[q].nda, b.points[q].nda);
        EXPECT_EQ(a.points[q].neighbour, b.points[q].neighbour);
    }
}
} // namespace

TEST(VoronoiCells, CellsAreTheSameBitsOnAnyNumberOfThreads)
{
    const std::vector<real_t> x = cloud();
    const auto body = box_halfspaces(Vec3::Zero(), Vec3::Ones());
    const int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    const VoronoiCells one = voronoi_cells(x, body);
    omp_set_num_threads(2);
    const VoronoiCells two = voronoi_cells(x, body);
    omp_set_num_threads(threads);
    expect_same_cells(one, two);
    ASSERT_EQ(one.sub_cells.size(), two.sub_cells.size());
    for (std::size_t s = 0; s < one.sub_cells.size(); ++s)
    {
        EXPECT_EQ(one.sub_cells[s].cell, two.sub_cells[s].cell);
        EXPECT_EQ(one.sub_cells[s].volume, two.sub_cells[s].volume);
        EXPECT_EQ(one.sub_cells[s].begin, two.sub_cells[s].begin);
        EXPECT_EQ(one.sub_cells[s].end, two.sub_cells[s].end);
    }
    ASSERT_EQ(one.sub_points.size(), two.sub_points.size());
    for (std::size_t q = 0; q < one.sub_points.size(); ++q)
        EXPECT_EQ(one.sub_points[q].nda, two.sub_points[q].nda);
    EXPECT_EQ(one.rebuilt_with_all_planes, two.rebuilt_with_all_planes);
}

// The cut cells (VoronoiHull::Clip, in doubles) against CGAL's exact construction, their plain
// twin: both solve each vertex again from the planes through it (corner_point), so where the
// two find the same polygons the facet points, normals, areas, neighbours, volumes and spacings
// are the same bits; on a jittered box cloud with random points, a generated cylinder cloud
// (particles on the faceted surface) and a plate thinner than its spacing they are. (Where more
// than three planes meet at a vertex, as on an exact lattice, they are not: see
// LatticeCellsAreCubesOfSixSquares.)
// Cells without their sub-cells (what a cloud that integrates on no sub-cell builds): the same
// facet points, volumes and spacings bit for bit, no sub-cell, and under half the facet data.
TEST(VoronoiCells, CellsWithoutSubCellsAreTheSameCells)
{
    const std::vector<real_t> x = cloud();
    const std::vector<HalfSpace> body = box_halfspaces(Vec3::Zero(), Vec3::Ones());
    const VoronoiCells full = voronoi_cells(x, body);
    const VoronoiCells bare = voronoi_cells(x, body, VoronoiHull::Clip, false);
    ASSERT_FALSE(full.sub_cells.empty());
    EXPECT_TRUE(bare.sub_cells.empty());
    EXPECT_TRUE(bare.sub_points.empty());
    EXPECT_EQ(full.sub_points.size(), 2 * full.points.size()); // a base and a side per facet point
    expect_same_cells(bare, full);
}

TEST(VoronoiCells, CutCellsAreTheExactConstructionsBits)
{
    struct Case
    {
        const char* name;
        std::vector<real_t> x;
        std::vector<HalfSpace> body;
    };
    std::vector<Case> cases;
    cases.push_back({"box", cloud(), box_halfspaces(Vec3::Zero(), Vec3::Ones())});
    {
        const GeneratorSpec g = cylinder_cloud_spec();
        std::vector<real_t> x = generate_cloud(g).x;
        std::vector<HalfSpace> body = cloud_body(g, static_cast<index_t>(x.size() / 3));
        cases.push_back({"cylinder", std::move(x), std::move(body)});
    }
    {
        GeneratorSpec g;
        g.type = GeneratorSpec::Type::Cloud;
        g.element_size = 1e-3;
        g.jitter = 0.25;
        g.size = Vec3(4e-3, 4e-3, 12e-6);
        std::vector<real_t> x = generate_cloud(g).x;
        std::vector<HalfSpace> body = cloud_body(g, static_cast<index_t>(x.size() / 3));
        cases.push_back({"plate", std::move(x), std::move(body)});
    }
    for (const Case& c : cases)
    {
        const VoronoiCells cut = voronoi_cells(c.x, c.body, VoronoiHull::Clip);
        const VoronoiCells exact = voronoi_cells(c.x, c.body, VoronoiHull::Exact);
        ASSERT_EQ(cut.size(), exact.size());
        ASSERT_EQ(cut.offsets, exact.offsets) << c.name << ": the cells have other facets";
        ASSERT_EQ(cut.sub_cells.size(), exact.sub_cells.size()) << c.name;
        real_t h = 0.0; // the largest spacing: the length scale
        for (real_t s : exact.spacing)
            h = std::max(h, s);
        real_t dx = 0.0, dn = 0.0, dv = 0.0, ds = 0.0, dsub = 0.0;
        int neighbours_differ = 0;
        for (std::size_t k = 0; k < exact.points.size(); ++k)
        {
            dx = std::max(dx, (cut.points[k].x - exact.points[k].x).norm() / h);
            dn = std::max(dn, (cut.points[k].nda - exact.points[k].nda).norm() / (h * h));
            neighbours_differ += cut.points[k].neighbour != exact.points[k].neighbour;
        }
        for (index_t i = 0; i < exact.size(); ++i)
        {
            dv = std::max(dv, std::abs(cut.volume[i] - exact.volume[i]) / exact.volume[i]);
            ds = std::max(ds, std::abs(cut.spacing[i] - exact.spacing[i]) / h);
        }
        for (std::size_t k = 0; k < exact.sub_cells.size(); ++k)
            dsub = std::max(dsub, std::abs(cut.sub_cells[k].volume - exact.sub_cells[k].volume) /
                                      exact.volume[exact.sub_cells[k].cell]);
        std::printf("%s: %d cells, %zu facet points; cut against exact: points %.1e h, n dA %.1e h^2, volumes %.1e, "
                    "spacings %.1e h, sub-cell volumes %.1e; rebuilt with all planes %d / %d\n",
                    c.name, exact.size(), exact.points.size(), dx, dn, dv, ds, dsub, cut.rebuilt_with_all_planes,
                    exact.rebuilt_with_all_planes);
        EXPECT_EQ(neighbours_differ, 0) << c.name;
        EXPECT_EQ(dx, 0.0) << c.name;
        EXPECT_EQ(dn, 0.0) << c.name;
        EXPECT_EQ(dv, 0.0) << c.name;
        EXPECT_EQ(ds, 0.0) << c.name;
        EXPECT_EQ(dsub, 0.0) << c.name;
    }
}

// An exact lattice (jitter 0): more than three bisectors meet at each vertex. Its Voronoi cells
// are cubes, so the cut cells are 6 squares fanned from their centres, 24 facet points a cell of
// the body's volume over the particles', each face's n dA the square's area on its axis. CGAL's
// exact construction represents such a vertex by several coincident ones, which moved its fans'
// centres (the average of a polygon's vertices, a duplicate counted twice): the same cells and
// the same area per neighbour, other quadrature points; the cut cells' are the cubes'.
TEST(VoronoiCells, LatticeCellsAreCubesOfSixSquares)
{
    GeneratorSpec g;
    g.type = GeneratorSpec::Type::Cloud;
    g.element_size = 1e-3;
    g.jitter = 0.0;
    g.size = Vec3(4e-3, 4e-3, 8e-3);
    const std::vector<real_t> x = generate_cloud(g).x;
    const std::vector<HalfSpace> body = cloud_body(g, static_cast<index_t>(x.size() / 3));
    const VoronoiCells cut = voronoi_cells(x, body, VoronoiHull::Clip);
    const VoronoiCells exact = voronoi_cells(x, body, VoronoiHull::Exact);
    ASSERT_EQ(cut.size(), exact.size());
    real_t volume = 0.0, dv = 0.0, darea = 0.0, dcentre = 0.0;
    int not_24 = 0, exact_not_24 = 0;
    for (index_t i = 0; i < cut.size(); ++i)
    {
        volume += cut.volume[i];
        dv = std::max(dv, std::abs(cut.volume[i] - exact.volume[i]) / exact.volume[i]);
        not_24 += cut.offsets[i + 1] - cut.offsets[i] != 24;
        exact_not_24 += exact.offsets[i + 1] - exact.offsets[i] != 24;
        // per face (6 of them, 4 triangles each): its n dA, and its points' mean at the square's centre
        Vec3 face_nda[6], face_x[6];
        for (int f = 0; f < 6; ++f)
            face_nda[f] = face_x[f] = Vec3::Zero();
        for (index_t k = cut.offsets[i]; k < cut.offsets[i + 1]; ++k)
        {
            const Vec3& n = cut.points[k].nda;
            int axis = 0;
            n.cwiseAbs().maxCoeff(&axis);
            const int f = 2 * axis + (n[axis] > 0 ? 1 : 0);
            face_nda[f] += n;
            face_x[f] += 0.25 * cut.points[k].x;
        }
        // against the exact construction: the same n dA per neighbour (or body face)
        std::map<std::pair<index_t, int>, Vec3> by_cut, by_exact;
        for (const auto& [cells, into] : {std::pair{&cut, &by_cut}, std::pair{&exact, &by_exact}})
            for (index_t k = cells->offsets[i]; k < cells->offsets[i + 1]; ++k)
            {
                const Vec3& n = cells->points[k].nda;
                int axis = 0;
                n.cwiseAbs().maxCoeff(&axis);
                into->emplace(std::pair{cells->points[k].neighbour, 2 * axis + (n[axis] > 0 ? 1 : 0)}, Vec3::Zero())
                    .first->second += n;
            }
        for (const auto& [key, n] : by_exact)
        {
            const auto it = by_cut.find(key);
            const Vec3 c = it == by_cut.end() ? Vec3::Zero() : it->second;
            darea = std::max(darea, (c - n).norm() / (g.element_size * g.element_size));
        }
        // the cell is the box of half a spacing around the particle, clipped to the body; a
        // face's centre is the box's, moved to the face along its axis
        const Vec3 xi(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
        const Vec3 lo = (xi - Vec3::Constant(0.5 * g.element_size)).cwiseMax(Vec3::Zero());
        const Vec3 hi = (xi + Vec3::Constant(0.5 * g.element_size)).cwiseMin(g.size);
        for (int f = 0; f < 6; ++f)
        {
            const int axis = f / 2;
            Vec3 c = 0.5 * (lo + hi);
            c[axis] = f % 2 ? hi[axis] : lo[axis];
            dcentre = std::max(dcentre, (face_x[f] - c).norm() / g.element_size);
        }
    }
    std::printf("lattice: %d cells, %d cut cells and %d exact ones not of 24 facet points; volume / body - 1 = %.1e; "
                "cut against exact: volumes %.1e, n dA per neighbour %.1e h^2; faces' point means off their "
                "centres by %.1e h\n",
                cut.size(), not_24, exact_not_24, volume / g.size.prod() - 1.0, dv, darea, dcentre);
    EXPECT_EQ(not_24, 0);
    EXPECT_NEAR(volume / g.size.prod(), 1.0, 1e-13);
    EXPECT_LT(dv, 1e-14);
    EXPECT_LT(darea, 1e-14);
    EXPECT_LT(dcentre, 1e-13);
}
