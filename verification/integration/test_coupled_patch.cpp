// GCC 12 reports a false "may be used uninitialized" inside Eigen's AVX-512 dense kernels here.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
// Coupled FE | transition | RK parts (approximation/coupling/coupled_shapes.hpp): the static
// linear patch test through the transition zone on a distorted mesh, SCNI (+ MSCNI) over the
// whole part's node-dual cells; the shape functions' partition of unity and linear
// reproduction at points of every element kind; FE nodes keep the Kronecker property.
#include <gtest/gtest.h>

#include <cstdio>
#include <map>

#include "nodal_common.hpp"
#include "rkfem/approximation/coupling/coupled_shapes.hpp"

using namespace rkfem;
using namespace rkfem::test;

namespace
{
const ElasticParams mat = ElasticParams::from_E_nu(1.0, 1e3, 0.3);

/// Elements whose centroid has x below `cut` are RK.
std::vector<char> rk_below(const HexMesh& mesh, real_t cut)
{
    std::vector<char> rk(static_cast<std::size_t>(mesh.n_elements()), 0);
    for (index_t e = 0; e < mesh.n_elements(); ++e)
    {
        real_t xc = 0.0;
        for (int a = 0; a < 8; ++a)
            xc += mesh.x[3 * mesh.conn[8 * e + a]] / 8.0;
        rk[e] = xc < cut;
    }
    return rk;
}

const char* name(Transition t)
{
    return t == Transition::Mixed ? "mixed" : "ramp";
}

/// The point of element e at natural coordinates xi.
Vec3 point_at(const HexMesh& mesh, index_t e, const Vec3& xi)
{
    real_t N[8];
    const real_t z[3] = {xi[0], xi[1], xi[2]};
    hex8_shape(z, N);
    Vec3 x = Vec3::Zero();
    for (int a = 0; a < 8; ++a)
        x += N[a] * mesh.node(mesh.conn[8 * e + a]);
    return x;
}

/// Prints `what`'s largest error per element kind (FE, interface, RK) and its point counts, and
/// expects points of every kind, each error below `bound`.
void expect_per_kind(Transition t, const char* what, const real_t (&err)[3], const int (&count)[3], real_t bound)
{
    std::printf("%s: %s, max error: FE %.1e (%d points), interface %.1e (%d), RK %.1e (%d)\n", name(t), what, err[0],
                count[0], err[1], count[1], err[2], count[2]);
    for (int k = 0; k < 3; ++k)
    {
        EXPECT_GT(count[k], 0);
        EXPECT_LT(err[k], bound);
    }
}

PatchResult coupled_patch(Transition t, int n, bool mscni, real_t jitter = 0.3)
{
    const real_t size = 1.0;
    const HexMesh mesh = distorted_box(n, size / n, jitter);
    const CoupledShapes shapes(mesh, rk_below(mesh, 0.5 * size), RkParams{}, t);
    Operators ops;
    ops.points = build_scni(mesh, shapes);
    if (mscni)
        ops.stabilization = build_mscni_stabilization(ops.points, build_sd_scni(mesh, shapes));
    return linear_patch(mesh, size, ops, shapes, mat, 0.5);
}
} // namespace

TEST(CoupledShapes, ReproduceLinearFieldsInEveryElementKind)
{
    // at the Gauss points of every element: sum psi = 1 and sum psi X_k = x (mixed and ramp: at
    // particle nodes X_k is the particle's position, the coefficient of a linear field)
    const HexMesh mesh = distorted_box(6, 1.0 / 6, 0.3);
    for (Transition t : {Transition::Mixed, Transition::Ramp})
    {
        const CoupledShapes shapes(mesh, rk_below(mesh, 0.5), RkParams{}, t);
        int counts[3] = {0, 0, 0};
        real_t err[3] = {0, 0, 0};
        std::vector<index_t> nodes;
        std::vector<real_t> psi;
        const real_t g = 1.0 / std::sqrt(3.0);
        for (index_t e = 0; e < mesh.n_elements(); ++e)
            for (int q = 0; q < 8; ++q)
            {
                const Vec3 xi(q & 1 ? g : -g, q & 2 ? g : -g, q & 4 ? g : -g);
                const Vec3 x = point_at(mesh, e, xi);
                shapes.values(e, xi, x, nodes, psi);
                real_t s = 0.0;
                Vec3 r = Vec3::Zero();
                for (std::size_t k = 0; k < nodes.size(); ++k)
                {
                    s += psi[k];
                    r += psi[k] * mesh.node(nodes[k]);
                }
                const int kind = static_cast<int>(shapes.kind(e));
                ++counts[kind];
                err[kind] = std::max({err[kind], std::abs(s - 1.0), (r - x).norm() * 6.0});
            }
        expect_per_kind(t, "partition of unity and linear reproduction", err, counts, 1e-12);
    }
}

TEST(CoupledShapes, FeNodesKeepTheKroneckerProperty)
{
    const HexMesh mesh = distorted_box(6, 1.0 / 6, 0.3);
    const CoupledShapes shapes(mesh, rk_below(mesh, 0.5), RkParams{}, Transition::Mixed);
    std::vector<index_t> nodes;
    std::vector<real_t> psi;
    index_t checked = 0;
    // every FE node of an interface element, evaluated in that element
    for (index_t e = 0; e < mesh.n_elements(); ++e)
    {
        if (shapes.kind(e) != CoupledShapes::Kind::Interface)
            continue;
        for (int a = 0; a < 8; ++a)
        {
            const index_t I = mesh.conn[8 * e + a];
            if (shapes.is_particle(I))
                continue;
            const Vec3 xi(hex8_nodes[a][0], hex8_nodes[a][1], hex8_nodes[a][2]);
            shapes.values(e, xi, mesh.node(I), nodes, psi);
            for (std::size_t k = 0; k < nodes.size(); ++k)
                EXPECT_NEAR(psi[k], nodes[k] == I ? 1.0 : 0.0, 1e-13) << "node " << I << ", function " << nodes[k];
            ++checked;
        }
    }
    EXPECT_GT(checked, 0);
}

TEST(CoupledShapes, FastPathMatchesItsPlainTwin)
{
    // values (one neighbour search per element and thread, focused on a box) against
    // values_plain (a search per point): the same functions to round-off at points of every
    // element kind, inside the focus box and outside it (which must fall back, not miss functions)
    const HexMesh mesh = distorted_box(6, 1.0 / 6, 0.3);
    for (Transition t : {Transition::Mixed, Transition::Ramp})
    {
        const CoupledShapes shapes(mesh, rk_below(mesh, 0.5), RkParams{}, t);
        std::vector<index_t> nodes, plain_nodes;
        std::vector<real_t> psi, plain_psi;
        real_t worst[3] = {0, 0, 0};
        int points[3] = {0, 0, 0};
        for (index_t e = 0; e < mesh.n_elements(); ++e)
        {
            auto at = [&](const Vec3& xi) { return point_at(mesh, e, xi); };
            // the focus: the box of the octant xi > 0; points in it, then the opposite corner
            const Vec3 lo = at(Vec3(0, 0, 0)).cwiseMin(at(Vec3(1, 1, 1))) - Vec3::Constant(0.2 / 6);
            const Vec3 hi = at(Vec3(0, 0, 0)).cwiseMax(at(Vec3(1, 1, 1))) + Vec3::Constant(0.2 / 6);
            shapes.focus(e, lo, hi);
            for (const Vec3& xi : {Vec3(0.5, 0.5, 0.5), Vec3(0.1, 0.9, 0.3), Vec3(1, 1, 1), Vec3(-0.9, -0.8, -1)})
            {
                const Vec3 x = at(xi);
                shapes.values(e, xi, x, nodes, psi);
                shapes.values_plain(e, xi, x, plain_nodes, plain_psi);
                std::map<index_t, real_t> fast, plain;
                for (std::size_t k = 0; k < nodes.size(); ++k)
                    fast[nodes[k]] += psi[k];
                for (std::size_t k = 0; k < plain_nodes.size(); ++k)
                    plain[plain_nodes[k]] += plain_psi[k];
                const int kind = static_cast<int>(shapes.kind(e));
                ++points[kind];
                EXPECT_EQ(fast.size(), plain.size()) << "element " << e;
                for (const auto& [n, v] : plain)
                {
                    ASSERT_TRUE(fast.count(n)) << "element " << e << " misses function " << n;
                    worst[kind] = std::max(worst[kind], std::abs(fast[n] - v));
                }
            }
        }
        expect_per_kind(t, "fast against plain values", worst, points, 1e-13);
    }
}

class CoupledPatch : public ::testing::TestWithParam<bool>
{
};

TEST_P(CoupledPatch, MixedInterpolationPassesOnADistortedMesh)
{
    const bool mscni = GetParam();
    const PatchResult r = coupled_patch(Transition::Mixed, 6, mscni);
    std::printf("mixed interpolation, SCNI%s: displacement error %.2e, strain error %.2e\n", mscni ? " + MSCNI" : "",
                r.displacement_error, r.strain_error);
    EXPECT_LT(r.displacement_error, 1e-10);
    EXPECT_LT(r.strain_error, 1e-10);
}

INSTANTIATE_TEST_SUITE_P(Stabilization, CoupledPatch, ::testing::Values(false, true),
                         [](const auto& info) { return std::string(info.param ? "mscni" : "scni"); });

TEST(CoupledPatch, RampBlendingPassesTooWithSmoothedGradients)
{
    // Finding: the ramp u = (1 - R) sum_k N_k u_k + R sum_J Psi_J d_J, with the element's particle
    // nodes in its FE part, reproduces linear fields exactly (the coefficients of a linear field
    // are its nodal values), and the smoothed gradients integrate it conformingly; so it passes
    // the linear patch test to round-off at every h rather than with an O(h) error, which would
    // need a non-conforming quadrature of the interface elements (their centre gradient).
    for (int n : {4, 6, 8})
    {
        const PatchResult r = coupled_patch(Transition::Ramp, n, true);
        std::printf("ramp blending, SCNI + MSCNI, h = 1/%d: displacement error %.2e, strain error %.2e\n", n,
                    r.displacement_error, r.strain_error);
        EXPECT_LT(r.displacement_error, 1e-10);
        EXPECT_LT(r.strain_error, 1e-10);
    }
}
