// RK shape functions: reproducing conditions (partition of unity, linear and gradient
// reproduction) to 1e-12 on regular and jittered clouds for every kernel and support shape,
// quadratic reproduction for the order-2 basis, direct gradients against central differences,
// zero weight on the support boundary, and a named error for a singular moment matrix.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <iterator>
#include <map>
#include <random>

#include "../support.hpp"
#include "rkfem/approximation/rk/rk_region_values.hpp"
#include "rkfem/approximation/rk/rk_shape.hpp"
#include "rkfem/discretization/generators.hpp"

using namespace rkfem;

namespace
{
struct Cloud
{
    HexMesh mesh;
    RkShapeFunctions rk;
};

Cloud make_cloud(int n, real_t h, real_t jitter, RkParams p)
{
    Cloud c{test::distorted_box(n, h, jitter), {}};
    c.rk = rk_on_mesh(c.mesh, p);
    return c;
}

std::vector<Vec3> sample_points(int count, real_t lo, real_t hi, unsigned seed)
{
    std::mt19937 gen(seed);
    std::uniform_real_distribution<real_t> u(lo, hi);
    std::vector<Vec3> pts;
    for (int i = 0; i < count; ++i)
        pts.emplace_back(u(gen), u(gen), u(gen));
    return pts;
}

struct Case
{
    KernelType kernel;
    SupportShape support;
    real_t c;
    real_t jitter;
    const char* name;
};

class Reproduction : public ::testing::TestWithParam<Case>
{
};
} // namespace

TEST_P(Reproduction, LinearAndGradientReproductionToRoundOff)
{
    const Case cs = GetParam();
    const real_t h = 0.1;
    Cloud cl = make_cloud(6, h, cs.jitter, {1, cs.kernel, cs.support, cs.c});
    RkSample s;
    real_t worst = 0.0;
    for (const Vec3& x : sample_points(200, 0.0, 0.6, 3))
    {
        cl.rk.evaluate(x, true, s);
        real_t pu = 0.0;
        Vec3 lin = Vec3::Zero(), gsum = Vec3::Zero();
        Mat3 glin = Mat3::Zero();
        for (index_t k = 0; k < s.size(); ++k)
        {
            const Vec3 xi = cl.rk.position(s.nodes[k]);
            pu += s.psi[k];
            lin += s.psi[k] * xi;
            gsum += s.grad[k];
            glin += xi * s.grad[k].transpose();
        }
        worst = std::max({worst, std::abs(pu - 1.0), (lin - x).norm() / h, gsum.norm() * h,
                          (glin - Mat3::Identity()).cwiseAbs().maxCoeff()});
    }
    std::printf("%s: worst identity error %.2e\n", cs.name, worst);
    EXPECT_LT(worst, 1e-12) << cs.name;
}

INSTANTIATE_TEST_SUITE_P(
    KernelsAndSupports, Reproduction,
    ::testing::Values(Case{KernelType::CubicBSpline, SupportShape::Box, 1.51, 0.0, "cubic_box_regular"},
                      Case{KernelType::CubicBSpline, SupportShape::Box, 1.51, 0.3, "cubic_box_jittered"},
                      Case{KernelType::CubicBSpline, SupportShape::Sphere, 2.01, 0.0, "cubic_sphere_regular"},
                      Case{KernelType::CubicBSpline, SupportShape::Sphere, 2.01, 0.3, "cubic_sphere_jittered"},
                      Case{KernelType::QuinticBSpline, SupportShape::Box, 1.51, 0.3, "quintic_box_jittered"},
                      Case{KernelType::QuinticBSpline, SupportShape::Sphere, 2.01, 0.3, "quintic_sphere_jittered"},
                      Case{KernelType::Gaussian, SupportShape::Box, 1.51, 0.3, "gaussian_box_jittered"},
                      Case{KernelType::Gaussian, SupportShape::Sphere, 2.01, 0.3, "gaussian_sphere_jittered"}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(RkShape, QuadraticBasisReproducesQuadratics)
{
    const real_t h = 0.1;
    Cloud cl = make_cloud(6, h, 0.3, {2, KernelType::CubicBSpline, SupportShape::Sphere, 2.51});
    RkSample s;
    real_t worst = 0.0;
    for (const Vec3& x : sample_points(100, 0.05, 0.55, 5))
    {
        cl.rk.evaluate(x, true, s);
        Mat3 q = Mat3::Zero();
        real_t dq = 0.0; // d/dx0 of x0 x1 reproduced: x1
        for (index_t k = 0; k < s.size(); ++k)
        {
            const Vec3 xi = cl.rk.position(s.nodes[k]);
            q += s.psi[k] * xi * xi.transpose();
            dq += s.grad[k][0] * xi[0] * xi[1];
        }
        worst = std::max({worst, (q - x * x.transpose()).cwiseAbs().maxCoeff() / (h * h), std::abs(dq - x[1]) / h});
    }
    EXPECT_LT(worst, 1e-10);
}

TEST(RkShape, DirectGradientsMatchCentralDifferences)
{
    const real_t h = 0.1;
    Cloud cl = make_cloud(6, h, 0.3, {1, KernelType::CubicBSpline, SupportShape::Box, 1.51});
    RkSample s, sp, sm;
    real_t worst = 0.0;
    for (const Vec3& x : sample_points(40, 0.1, 0.5, 11))
    {
        cl.rk.evaluate(x, true, s);
        for (int d = 0; d < 3; ++d)
        {
            const real_t step = 1e-6 * 1.51 * h;
            Vec3 xp = x, xm = x;
            xp[d] += step;
            xm[d] -= step;
            cl.rk.evaluate(xp, false, sp);
            cl.rk.evaluate(xm, false, sm);
            for (index_t k = 0; k < s.size(); ++k)
            {
                auto value = [&](const RkSample& q)
                {
                    for (index_t j = 0; j < q.size(); ++j)
                        if (q.nodes[j] == s.nodes[k])
                            return q.psi[j];
                    return 0.0;
                };
                const real_t fd = (value(sp) - value(sm)) / (2 * step);
                worst = std::max(worst, std::abs(fd - s.grad[k][d]) * h);
            }
        }
    }
    EXPECT_LT(worst, 1e-7);
}

TEST(RkShape, ParticleOnTheSupportBoundaryHasNoWeight)
{
    // lattice spacing h, spherical support exactly 1.5 h: at x = (1.5 h, 0, 0) the particles at
    // x = 0 and x = 3 h sit on the support boundary and carry no weight (phi(1) = phi'(1) = 0);
    // a step of 1e-6 h inside brings particle 0 back with a weight of order (1e-6)^3
    const real_t h = 1.0;
    HexMesh m = generate_box(Vec3::Zero(), Vec3::Constant(4 * h), {4, 4, 4});
    std::vector<real_t> a(static_cast<std::size_t>(m.n_nodes()), 1.5 * h);
    RkShapeFunctions rk(m.x, a, {1, KernelType::CubicBSpline, SupportShape::Sphere, 1.5});
    RkSample s;
    const Vec3 x(1.5 * h, 0.0, 0.0);
    rk.evaluate(x, true, s);
    ASSERT_GT(s.size(), 4);
    for (index_t k = 0; k < s.size(); ++k)
        EXPECT_LT((rk.position(s.nodes[k]) - x).norm(), 1.5 * h) << "node " << s.nodes[k] << " on the boundary";
    rk.evaluate(x - Vec3(1e-6 * h, 0, 0), true, s);
    bool found = false;
    for (index_t k = 0; k < s.size(); ++k)
        if (rk.position(s.nodes[k]).norm() == 0.0)
        {
            found = true;
            EXPECT_LT(std::abs(s.psi[k]), 1e-15);
            EXPECT_LT(s.grad[k].norm() * h, 1e-10);
        }
    EXPECT_TRUE(found);
}

TEST(RkShape, SingularMomentMatrixIsANamedError)
{
    // three collinear particles cover the point: the linear moment matrix is singular
    std::vector<real_t> x = {0, 0, 0, 1, 0, 0, 2, 0, 0, 0, 0, 5};
    std::vector<real_t> a = {1.6, 1.6, 1.6, 1.0};
    RkShapeFunctions rk(x, a, {1, KernelType::CubicBSpline, SupportShape::Sphere, 1.6});
    RkSample s;
    try
    {
        rk.evaluate(Vec3(1.0, 0.1, 0.0), false, s);
        FAIL() << "expected SingularMomentError";
    }
    catch (const SingularMomentError& e)
    {
        const std::string msg = e.what();
        EXPECT_NE(msg.find("3 particle(s) cover the point"), std::string::npos) << msg;
        EXPECT_NE(msg.find("normalized_support"), std::string::npos) << msg;
    }
    // four particles, but all in one line plus the far one out of reach: still too few
    std::vector<real_t> x2 = {0, 0, 0, 1, 0, 0, 2, 0, 0, 3, 0, 0};
    RkShapeFunctions rk2(x2, {2.5, 2.5, 2.5, 2.5}, {1, KernelType::CubicBSpline, SupportShape::Sphere, 2.5});
    EXPECT_THROW(rk2.evaluate(Vec3(1.5, 0.2, 0.0), false, s), SingularMomentError);
}

// Second derivatives (the NSNI stabilization's coefficients): the differences of the
// reproducing identities keep sum_I H_I = 0 and sum_I H_I x_I = 0 to round-off for the linear
// basis; the quadratic basis reproduces d2(x_a x_b)/dx_i dx_j = delta_ia delta_jb + delta_ib
// delta_ja to the O(delta^2) truncation error (delta = 1e-3 a); and H is exactly symmetric.
TEST(RkShape, HessiansReproduceWhatTheBasisReproduces)
{
    const real_t h = 0.1;
    std::vector<index_t> nodes;
    std::vector<Mat3> H;
    {
        Cloud cl = make_cloud(6, h, 0.3, {1, KernelType::CubicBSpline, SupportShape::Box, 1.51});
        real_t zero = 0.0, linear = 0.0, asym = 0.0, scale = 0.0, second = 0.0;
        for (const Vec3& x : sample_points(40, 0.1, 0.5, 13))
        {
            cl.rk.hessians(x, nodes, H);
            Mat3 s = Mat3::Zero();
            Mat3 sx[3] = {Mat3::Zero(), Mat3::Zero(), Mat3::Zero()};
            for (std::size_t k = 0; k < nodes.size(); ++k)
            {
                s += H[k];
                for (int a = 0; a < 3; ++a)
                    sx[a] += H[k] * cl.rk.position(nodes[k])[a];
                scale = std::max(scale, H[k].cwiseAbs().maxCoeff());
                asym = std::max(asym, (H[k] - H[k].transpose()).cwiseAbs().maxCoeff());
            }
            zero = std::max(zero, s.cwiseAbs().maxCoeff());
            for (int a = 0; a < 3; ++a)
                linear = std::max(linear, sx[a].cwiseAbs().maxCoeff());
            // d2 Psi / dx_d^2 from second differences of values, step 1e-3 h: the kernel's third
            // derivative jumps at its knots, so their error is O(step) there (about 1e-4)
            RkSample s0, sp, sm;
            cl.rk.evaluate(x, false, s0);
            for (int d = 0; d < 3; ++d)
            {
                const real_t step = 1e-3 * h;
                Vec3 xp = x, xm = x;
                xp[d] += step;
                xm[d] -= step;
                cl.rk.evaluate(xp, false, sp);
                cl.rk.evaluate(xm, false, sm);
                auto value = [](const RkSample& q, index_t n)
                {
                    for (index_t j = 0; j < q.size(); ++j)
                        if (q.nodes[j] == n)
                            return q.psi[j];
                    return 0.0;
                };
                for (std::size_t k = 0; k < nodes.size(); ++k)
                {
                    const real_t fd =
                        (value(sp, nodes[k]) - 2.0 * value(s0, nodes[k]) + value(sm, nodes[k])) / (step * step);
                    second = std::max(second, std::abs(fd - H[k](d, d)));
                }
            }
        }
        std::printf("linear basis: max |d2 Psi from second differences - H_dd| / max |H| = %.1e\n", second / scale);
        EXPECT_LT(second / scale, 1e-3);
        std::printf("linear basis: max |sum H| / max |H| = %.1e, max |sum H x| / (h max |H|) = %.1e\n", zero / scale,
                    linear / (h * scale));
        EXPECT_LT(zero / scale, 1e-11);
        EXPECT_LT(linear / (h * scale), 1e-11);
        EXPECT_EQ(asym, 0.0);
    }
    {
        Cloud cl = make_cloud(6, h, 0.3, {2, KernelType::CubicBSpline, SupportShape::Sphere, 2.51});
        real_t worst = 0.0;
        for (const Vec3& x : sample_points(40, 0.1, 0.5, 17))
        {
            cl.rk.hessians(x, nodes, H);
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b)
                {
                    Mat3 q = Mat3::Zero(); // d2 (x_a x_b) / dx_i dx_j
                    for (std::size_t k = 0; k < nodes.size(); ++k)
                        q += H[k] * (cl.rk.position(nodes[k])[a] * cl.rk.position(nodes[k])[b]);
                    Mat3 exact = Mat3::Zero();
                    exact(a, b) += 1.0;
                    exact(b, a) += 1.0;
                    worst = std::max(worst, (q - exact).cwiseAbs().maxCoeff());
                }
        }
        std::printf("quadratic basis: max |sum H x_a x_b - d2(x_a x_b)| = %.1e\n", worst);
        EXPECT_LT(worst, 1e-9);
    }
}

// prune_rk_hessians (NSNI with rk.drop_tolerance): the second derivatives left after dropping
// those below tau of the largest, corrected, still sum to zero and annihilate x_I to round-off,
// stay exactly symmetric, and move by a few tau of the largest.
TEST(RkShape, DroppedHessiansKeepTheirIdentities)
{
    const real_t h = 0.1, tau = 1e-3;
    Cloud cl = make_cloud(6, h, 0.3, {1, KernelType::CubicBSpline, SupportShape::Box, 1.51});
    std::vector<index_t> nodes, kept;
    std::vector<Mat3> H, Hk;
    real_t identities = 0.0, change = 0.0;
    std::size_t before = 0, after = 0;
    for (const Vec3& x : sample_points(40, 0.1, 0.5, 19))
    {
        cl.rk.hessians(x, nodes, H);
        kept = nodes;
        Hk = H;
        prune_rk_hessians(cl.rk, x, tau, kept, Hk);
        before += nodes.size();
        after += kept.size();
        real_t scale = 0.0;
        for (const Mat3& m : H)
            scale = std::max(scale, m.cwiseAbs().maxCoeff());
        Mat3 sum = Mat3::Zero(), sx[3] = {Mat3::Zero(), Mat3::Zero(), Mat3::Zero()};
        for (std::size_t k = 0; k < kept.size(); ++k)
        {
            sum += Hk[k];
            for (int a = 0; a < 3; ++a)
                sx[a] += Hk[k] * (cl.rk.position(kept[k])[a] - x[a]);
            EXPECT_EQ((Hk[k] - Hk[k].transpose()).cwiseAbs().maxCoeff(), 0.0);
            const auto it = std::find(nodes.begin(), nodes.end(), kept[k]);
            change = std::max(change,
                              (Hk[k] - H[static_cast<std::size_t>(it - nodes.begin())]).cwiseAbs().maxCoeff() / scale);
        }
        identities = std::max(identities, sum.cwiseAbs().maxCoeff() / scale);
        for (int a = 0; a < 3; ++a)
            identities = std::max(identities, sx[a].cwiseAbs().maxCoeff() / (h * scale));
    }
    std::printf("dropped Hessians: %zu -> %zu entries, identities %.1e, largest change / largest %.1e\n", before, after,
                identities, change);
    EXPECT_LT(after, before);
    EXPECT_LT(identities, 1e-12);
    EXPECT_LT(change, 10 * tau);
}

// RkRegionValues (the set-up's fast path) against its plain twin, evaluate + prune_rk_values: at
// points of one element of a jittered mesh, over the particles gathered for the element's box,
// the same functions (node for node) and the same values to round-off, for every kernel,
// support, order and the drop tolerance.
TEST(RkShape, RegionValuesAreThePointwiseValuesToRoundOff)
{
    const real_t h = 1e-3;
    const HexMesh mesh = rkfem::test::distorted_box(6, h, 0.3);
    struct Case
    {
        KernelType kernel;
        SupportShape support;
        int order;
        real_t a, tau;
    };
    const Case cases[] = {{KernelType::CubicBSpline, SupportShape::Box, 1, 1.51, 0.0},
                          {KernelType::CubicBSpline, SupportShape::Box, 1, 1.51, 1e-5},
                          {KernelType::CubicBSpline, SupportShape::Box, 1, 2.2, 1e-3},
                          {KernelType::QuinticBSpline, SupportShape::Sphere, 1, 2.1, 0.0},
                          {KernelType::Gaussian, SupportShape::Box, 1, 1.7, 0.0},
                          {KernelType::CubicBSpline, SupportShape::Box, 2, 2.3, 0.0}};
    std::mt19937 gen(3);
    std::uniform_real_distribution<real_t> u(0.0, 1.0);
    for (const Case& c : cases)
    {
        RkParams p;
        p.kernel = c.kernel;
        p.support = c.support;
        p.order = c.order;
        p.normalized_support = c.a;
        const RkShapeFunctions rk = rk_on_mesh(mesh, p);
        RkRegionValues region(rk, c.tau);
        real_t worst = 0.0;
        std::size_t dropped = 0;
        for (const index_t e : {0, 43, 107, 215}) // a corner, the interior, a face
        {
            Vec3 lo = Vec3::Constant(1e300), hi = -lo;
            for (int I = 0; I < 8; ++I)
            {
                lo = lo.cwiseMin(mesh.node(mesh.conn[8 * e + I]));
                hi = hi.cwiseMax(mesh.node(mesh.conn[8 * e + I]));
            }
            region.gather(lo, hi);
            for (int q = 0; q < 20; ++q)
            {
                Vec3 x;
                for (int d = 0; d < 3; ++d)
                    x[d] = lo[d] + u(gen) * (hi[d] - lo[d]);
                RkSample s;
                rk.evaluate(x, false, s);
                std::vector<index_t> nodes = s.nodes;
                std::vector<real_t> psi = s.psi;
                if (c.tau > 0.0)
                    prune_rk_values(rk, x, c.tau, nodes, psi);
                dropped += s.nodes.size() - nodes.size();
                region.evaluate(x);
                std::map<index_t, real_t> fast;
                real_t big = 0.0;
                for (std::size_t k = 0; k < region.size(); ++k)
                {
                    if (region.kept()[k] != 0.0)
                        fast[region.candidates()[k]] = region.psi()[k];
                    else
                        EXPECT_EQ(region.psi()[k], 0.0);
                }
                ASSERT_EQ(fast.size(), nodes.size()) << "element " << e << " point " << q;
                for (std::size_t k = 0; k < nodes.size(); ++k)
                {
                    ASSERT_EQ(fast.count(nodes[k]), 1u);
                    worst = std::max(worst, std::abs(fast[nodes[k]] - psi[k]));
                    big = std::max(big, std::abs(psi[k]));
                }
                EXPECT_GT(big, 0.05);
            }
        }
        std::printf("kernel %d support %d order %d a/h %.2f tau %.0e: largest difference %.2e, %zu dropped\n",
                    static_cast<int>(c.kernel), static_cast<int>(c.support), c.order, c.a, c.tau, worst, dropped);
        EXPECT_LT(worst, 1e-13);
        if (c.tau > 0.0)
        {
            EXPECT_GT(dropped, 0u); // the drop and its correction ran
        }
    }
}

// particles_near_box (runs of the bins' copy, 8 particles at a time where the CPU has AVX-512)
// against its plain twin (particle by particle through the cell list) and against the
// definition (every particle, support box against the query box): the same ascending lists.
// On a jittered mesh with random boxes of every size, and on a lattice of exact binary
// coordinates whose boxes end exactly at supports' edges (the ties the comparisons decide).
TEST(RkShape, ParticlesNearABoxAreThoseOfItsPlainTwin)
{
    const real_t h = 1.0 / 64;
    const RkShapeFunctions jittered = rk_on_mesh(rkfem::test::distorted_box(7, h, 0.3),
                                                 RkParams{1, KernelType::CubicBSpline, SupportShape::Box, 1.51});
    const RkShapeFunctions lattice = rk_on_mesh(generate_box(Vec3::Zero(), Vec3::Constant(8 * h), {8, 8, 8}),
                                                RkParams{1, KernelType::CubicBSpline, SupportShape::Box, 1.5});
    std::mt19937 gen(11);
    std::uniform_real_distribution<real_t> u(-0.2, 1.2);
    std::uniform_int_distribution<int> cell(-2, 10);
    std::size_t found = 0, ties = 0;
    for (const RkShapeFunctions* rk : {&jittered, &lattice})
    {
        std::vector<index_t> fast, plain;
        for (int q = 0; q < 400; ++q)
        {
            Vec3 lo, hi;
            for (int d = 0; d < 3; ++d)
            {
                if (rk == &lattice) // lattice boxes: corners on the lattice or half-way, 0 to 3 spacings
                {
                    lo[d] = 0.5 * h * cell(gen);
                    hi[d] = lo[d] + 0.5 * h * (cell(gen) % 7 + 2) / 2;
                }
                else
                {
                    const real_t a = u(gen) * 7 * h, b = u(gen) * 7 * h;
                    lo[d] = std::min(a, b);
                    hi[d] = q % 4 == 0 ? lo[d] : std::max(a, b); // every fourth box flat
                }
            }
            rk->particles_near_box(lo, hi, fast);
            rk->particles_near_box_plain(lo, hi, plain);
            ASSERT_EQ(fast, plain) << "box " << q;
            std::vector<index_t> expected;
            for (index_t j = 0; j < rk->size(); ++j)
            {
                const Vec3 x = rk->position(j);
                const real_t reach = rk->radius(j) * (1.0 + 1e-12);
                bool in = true;
                for (int d = 0; d < 3; ++d)
                {
                    in = in && x[d] + reach >= lo[d] && x[d] - reach <= hi[d];
                    ties += x[d] + rk->radius(j) == lo[d] || x[d] - rk->radius(j) == hi[d];
                }
                if (in)
                    expected.push_back(j);
            }
            ASSERT_EQ(fast, expected) << "box " << q;
            found += fast.size();
        }
    }
    std::printf("%zu particles found in 800 boxes; %zu support edges exactly on a box's face\n", found, ties);
    EXPECT_GT(found, 10000u);
    EXPECT_GT(ties, 100u);
}

// focus (8 region particles at a time where the CPU has AVX-512) against its plain twin and
// against the definition: the candidates are exactly the region's particles that
// particles_near_box finds for the box, ascending, with their positions and radii.
TEST(RkShape, FocusKeepsTheRegionsParticlesNearTheBox)
{
    const real_t h = 1e-3;
    const HexMesh mesh = rkfem::test::distorted_box(6, h, 0.3);
    const RkShapeFunctions rk = rk_on_mesh(mesh, RkParams{1, KernelType::CubicBSpline, SupportShape::Box, 2.0});
    RkRegionValues wide(rk, 0.0), plain(rk, 0.0);
    std::mt19937 gen(5);
    std::uniform_real_distribution<real_t> u(0.0, 1.0);
    std::size_t narrowed = 0;
    for (const index_t e : {0, 43, 107, 215})
    {
        Vec3 lo = Vec3::Constant(1e300), hi = -lo;
        for (int I = 0; I < 8; ++I)
        {
            lo = lo.cwiseMin(mesh.node(mesh.conn[8 * e + I]));
            hi = hi.cwiseMax(mesh.node(mesh.conn[8 * e + I]));
        }
        wide.gather(lo, hi);
        plain.gather(lo, hi);
        const std::vector<index_t> region = wide.region_particles();
        ASSERT_GT(region.size(), 8u); // whole vectors and a remainder
        for (int q = 0; q < 30; ++q)
        {
            // a sub-box of the element's box (a facet's), and at q = 0 the whole box
            Vec3 a, b;
            for (int d = 0; d < 3; ++d)
            {
                const real_t s = u(gen), t = q == 0 ? 1.0 : s + 0.3 * (1.0 - s) * u(gen);
                a[d] = q == 0 ? lo[d] : lo[d] + s * (hi[d] - lo[d]);
                b[d] = lo[d] + t * (hi[d] - lo[d]);
            }
            wide.focus(a, b);
            plain.focus_plain(a, b);
            std::vector<index_t> near;
            rk.particles_near_box(a, b, near);
            std::vector<index_t> expected;
            std::set_intersection(region.begin(), region.end(), near.begin(), near.end(), std::back_inserter(expected));
            ASSERT_EQ(wide.candidates(), expected) << "element " << e << " box " << q;
            ASSERT_EQ(plain.candidates(), expected);
            ASSERT_EQ(wide.slots(), plain.slots());
            for (std::size_t k = 0; k < expected.size(); ++k)
                EXPECT_EQ(region[static_cast<std::size_t>(wide.slots()[k])], expected[k]);
            narrowed += region.size() - expected.size();
            // the candidates' values are the same bits either way
            const Vec3 x = 0.5 * (a + b);
            wide.evaluate(x);
            plain.evaluate(x);
            for (std::size_t k = 0; k < expected.size(); ++k)
                ASSERT_EQ(wide.psi()[k], plain.psi()[k]);
        }
    }
    EXPECT_GT(narrowed, 0u); // the focus dropped particles
}

// A point with too few covering particles is the same named error from the fast path.
TEST(RkShape, RegionValuesNameASingularPoint)
{
    const HexMesh mesh = generate_box(Vec3::Zero(), Vec3::Constant(4e-3), {4, 4, 4});
    const RkShapeFunctions rk = rk_on_mesh(mesh, RkParams{1, KernelType::CubicBSpline, SupportShape::Box, 0.45});
    RkRegionValues region(rk, 0.0);
    region.gather(Vec3::Zero(), Vec3::Constant(1e-3));
    try
    {
        region.evaluate(Vec3(0.5e-3, 0.5e-3, 0.5e-3)); // the element centre: no particle covers it
        FAIL() << "no error";
    }
    catch (const SingularMomentError& e)
    {
        EXPECT_NE(std::string(e.what()).find("too few neighbours"), std::string::npos) << e.what();
    }
}

// The fast path's gradients (RkRegionValues::evaluate_gradients) and second derivatives
// (RkRegionValues::hessians, which NSNI builds with) against their plain twins, evaluate(x,
// true) and RkShapeFunctions::hessians: the same functions, gradients to round-off, second
// derivatives to round-off over the difference step (1e-3 of the support).
TEST(RkShape, RegionGradientsAndHessiansAreThePointwiseOnesToRoundOff)
{
    const real_t h = 0.1;
    const RkParams cases[] = {{1, KernelType::CubicBSpline, SupportShape::Box, 1.51},
                              {1, KernelType::QuinticBSpline, SupportShape::Sphere, 2.1},
                              {1, KernelType::Gaussian, SupportShape::Box, 1.7},
                              {2, KernelType::CubicBSpline, SupportShape::Sphere, 2.51}};
    for (const RkParams& p : cases)
    {
        Cloud cl = make_cloud(6, h, 0.3, p);
        RkRegionValues region(cl.rk, 0.0);
        real_t grad_err = 0.0, grad_big = 0.0, hess_err = 0.0, hess_big = 0.0;
        std::vector<index_t> nodes, plain_nodes;
        std::vector<Mat3> H, plain_H;
        std::vector<Vec3> points = sample_points(20, 0.1, 0.5, 29);
        for (index_t i = 0; i < cl.rk.size(); i += 7)
            points.push_back(cl.rk.position(i)); // NSNI evaluates at the particles
        for (const Vec3& x : points)
        {
            region.gather(x, x);
            region.evaluate_gradients(x);
            RkSample s;
            cl.rk.evaluate(x, true, s);
            std::size_t n_kept = 0;
            for (std::size_t k = 0; k < region.size(); ++k)
                n_kept += region.kept()[k] != 0.0;
            ASSERT_EQ(n_kept, s.nodes.size());
            for (index_t j = 0; j < s.size(); ++j)
            {
                const auto it = std::find(region.candidates().begin(), region.candidates().end(), s.nodes[j]);
                ASSERT_NE(it, region.candidates().end());
                const std::size_t k = static_cast<std::size_t>(it - region.candidates().begin());
                ASSERT_EQ(region.kept()[k], 1.0);
                for (int i = 0; i < 3; ++i)
                {
                    grad_err = std::max(grad_err, std::abs(region.gradient(i)[k] - s.grad[j][i]));
                    grad_big = std::max(grad_big, std::abs(s.grad[j][i]));
                }
            }
            region.hessians(x, nodes, H);
            cl.rk.hessians(x, plain_nodes, plain_H);
            ASSERT_EQ(nodes, plain_nodes);
            for (std::size_t k = 0; k < nodes.size(); ++k)
            {
                hess_err = std::max(hess_err, (H[k] - plain_H[k]).cwiseAbs().maxCoeff());
                hess_big = std::max(hess_big, plain_H[k].cwiseAbs().maxCoeff());
                EXPECT_EQ(H[k], H[k].transpose());
            }
        }
        std::printf(
            "order %d kernel %d support %d: gradients differ by %.1e, second derivatives by %.1e of the largest\n",
            p.order, static_cast<int>(p.kernel), static_cast<int>(p.support), grad_err / grad_big, hess_err / hess_big);
        EXPECT_LT(grad_err, 1e-13 * grad_big);
        EXPECT_LT(hess_err, 1e-11 * hess_big); // round-off 1e-16 over the step 1e-3 a: measured up to 7e-13
    }
}
