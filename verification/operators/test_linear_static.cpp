// The static solvers behind the patch tests and the manufactured-solution studies:
// - the hex Gauss operators reproduce linear fields and the volume, and their stiffness has the
//   null space theory gives (2x2x2: the 6 rigid modes; 1 point on one element: 6 + 12 hourglass);
// - the matrix-free stiffness product equals the assembled K times u, independent of threads;
// - conjugate gradients preconditioned with the trilinear FE stiffness reach CHOLMOD's solution
//   for plain RK SCNI (the worst-conditioned nodal scheme: its low-energy modes) and for MSCNI.
// GCC 12 reports a false "may be used uninitialized" inside Eigen's AVX-512 dense kernels
// (the dense eigen solves), as in test_nodal_patch.cpp.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cstdio>
#include <random>

#include "../integration/nodal_common.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/integration/hex_gauss.hpp"
#include "rkfem/operators/linear_static.hpp"

using namespace rkfem;
using namespace rkfem::test;

namespace
{
constexpr real_t h = 0.25;
const ElasticParams mat = ElasticParams::from_E_nu(1.0, 1e3, 0.3);

std::vector<real_t> random_vector(std::size_t n, unsigned seed)
{
    std::mt19937 gen(seed);
    std::uniform_real_distribution<real_t> u(-1.0, 1.0);
    std::vector<real_t> v(n);
    for (auto& x : v)
        x = u(gen);
    return v;
}

/// ||a - b|| / ||b||
real_t relative_difference(const std::vector<real_t>& a, const std::vector<real_t>& b)
{
    real_t d2 = 0.0, b2 = 0.0;
    for (std::size_t i = 0; i < b.size(); ++i)
    {
        d2 += (a[i] - b[i]) * (a[i] - b[i]);
        b2 += b[i] * b[i];
    }
    return std::sqrt(d2 / b2);
}

int zero_modes(const SparseMatrix& K)
{
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Eigen::MatrixXd(K), Eigen::EigenvaluesOnly);
    const Eigen::VectorXd lam = es.eigenvalues();
    int n = 0;
    for (Eigen::Index i = 0; i < lam.size(); ++i)
        n += lam[i] < 1e-10 * lam[lam.size() - 1];
    return n;
}

/// The six dofs that pin rigid motion: all of node a, y and z of node b, z of node c.
std::vector<index_t> rigid_pins(index_t a, index_t b, index_t c)
{
    return {3 * a, 3 * a + 1, 3 * a + 2, 3 * b + 1, 3 * b + 2, 3 * c + 2};
}
} // namespace

TEST(HexGauss, ReproducesLinearFieldsAndTheVolume)
{
    // boundary nodes stay on the box, so the volume is (4 h)^3; 2x2x2 integrates det J of a
    // trilinear hex exactly, and every point's gradients satisfy sum g_a = 0, sum x_a g_a^T = I
    const HexMesh mesh = distorted_box(4, h, 0.3);
    for (int n : {1, 2})
    {
        const IntegrationOperator op = build_hex_gauss(mesh, n);
        ASSERT_EQ(op.n_points(), mesh.n_elements() * n * n * n);
        real_t volume = 0.0, completeness = 0.0;
        for (index_t p = 0; p < op.n_points(); ++p)
        {
            volume += op.weight[p];
            Vec3 g0 = Vec3::Zero();
            Mat3 g1 = Mat3::Zero();
            for (index_t k = op.offsets[p]; k < op.offsets[p + 1]; ++k)
            {
                g0 += op.gradient(k);
                g1 += mesh.node(op.nodes[k]) * op.gradient(k).transpose();
                if (k > op.offsets[p])
                {
                    ASSERT_LT(op.nodes[k - 1], op.nodes[k]) << "entries of a point are in node order";
                }
            }
            completeness = std::max({completeness, g0.norm() * h, (g1 - Mat3::Identity()).norm()});
        }
        const real_t exact = std::pow(4 * h, 3);
        std::printf("%d^3 Gauss: volume error %.1e, linear completeness %.1e\n", n, std::abs(volume - exact) / exact,
                    completeness);
        if (n == 2)
        {
            EXPECT_LT(std::abs(volume - exact), 1e-14 * exact);
        }
        EXPECT_LT(completeness, 1e-12);
    }
}

TEST(HexGauss, StiffnessHasTheNullSpaceTheoryGives)
{
    // one distorted element: 24 dofs; 2x2x2 has rank 18 (6 rigid modes), 1 point has rank 6
    // (6 rigid + 12 hourglass modes: the uniform strain sees only the 6 strain components)
    HexMesh one = generate_box(Vec3::Zero(), Vec3::Constant(h), {1, 1, 1});
    one.x[3 * 6] += 0.1 * h, one.x[3 * 6 + 1] -= 0.05 * h, one.x[3 * 2 + 2] += 0.08 * h;
    EXPECT_EQ(zero_modes(assemble_stiffness(build_hex_gauss(one, 2), mat, one.n_nodes())), 6);
    EXPECT_EQ(zero_modes(assemble_stiffness(build_hex_gauss(one, 1), mat, one.n_nodes())), 18);
    // a 3^3 block: full integration keeps only the rigid modes
    const HexMesh block = distorted_box(3, h, 0.2);
    EXPECT_EQ(zero_modes(assemble_stiffness(build_hex_gauss(block, 2), mat, block.n_nodes())), 6);
}

TEST(MatrixFreeStiffness, EqualsTheAssembledStiffnessAndIgnoresThreads)
{
    const HexMesh mesh = distorted_box(4, h, 0.3);
    const RkShapeFunctions rk = rk_on_mesh(mesh);
    const Operators ops = build(Scheme::RkMscni, mesh, rk);
    const index_t n = mesh.n_nodes();
    const real_t cs = 0.5;
    SparseMatrix K = assemble_stiffness(ops.points, mat, n);
    K += assemble_stiffness(ops.stabilization, mat, n, cs);
    const SparseMatrix Kt = K.transpose();
    const SparseMatrix D = K - Kt;
    const real_t asym = D.coeffs().cwiseAbs().maxCoeff() / K.coeffs().cwiseAbs().maxCoeff();
    EXPECT_LT(asym, 1e-15) << "the assembled stiffness is symmetric";

    const MatrixFreeStiffness A({{&ops.points, 1.0}, {&ops.stabilization, cs}}, mat, n);
    const std::vector<real_t> u = random_vector(3 * static_cast<std::size_t>(n), 3);
    const Eigen::VectorXd Ku = K * Eigen::Map<const Eigen::VectorXd>(u.data(), 3 * n);
    std::vector<real_t> one(u.size()), two(u.size());
    omp_set_num_threads(1);
    A.apply(u.data(), one.data());
    omp_set_num_threads(2);
    A.apply(u.data(), two.data());
    omp_set_num_threads(1);
    real_t diff = 0.0;
    for (std::size_t i = 0; i < u.size(); ++i)
        diff = std::max(diff, std::abs(one[i] - Ku[static_cast<Eigen::Index>(i)]));
    const real_t rel = diff / Ku.cwiseAbs().maxCoeff();
    std::printf("|K u (matrix-free) - K u (assembled)| / max|K u| = %.1e\n", rel);
    EXPECT_LT(rel, 1e-13);
    EXPECT_EQ(one, two) << "the transpose gather sums in one order whatever the thread count";
}

namespace
{
struct SolveComparison
{
    real_t difference = 0.0; ///< ||u_pcg - u_direct|| / ||u_direct||
    int iterations = 0;
};

SolveComparison compare_solvers(Scheme scheme, real_t support, real_t rtol)
{
    const HexMesh mesh = distorted_box(5, h, 0.25);
    RkParams p;
    p.normalized_support = support;
    const RkShapeFunctions rk = rkfem::rk_on_mesh(mesh, p);
    const Operators ops = build(scheme, mesh, rk);
    const index_t n = mesh.n_nodes();
    const real_t cs = 0.5;
    std::vector<StiffnessTerm> terms{{&ops.points, 1.0}};
    SparseMatrix K = assemble_stiffness(ops.points, mat, n);
    if (ops.stabilization.n_points() > 0)
    {
        terms.push_back({&ops.stabilization, cs});
        K += assemble_stiffness(ops.stabilization, mat, n, cs);
    }
    // a random load, rigid motion pinned at three corners (nodes 0, 5 along x, 30 along y)
    const std::vector<real_t> f = random_vector(3 * static_cast<std::size_t>(n), 11);
    const std::vector<index_t> pins = rigid_pins(0, 5, 30);
    const std::vector<real_t> direct = solve_static(K, f, pins, std::vector<real_t>(pins.size(), 0.0));
    const PcgResult pcg = solve_static_pcg(MatrixFreeStiffness(terms, mat, n), f, pins,
                                           assemble_stiffness(build_hex_gauss(mesh, 2), mat, n), rtol, 2000);
    EXPECT_LE(pcg.relative_residual, rtol);
    return {relative_difference(pcg.u, direct), pcg.iterations};
}
} // namespace

TEST(StaticPcg, ReachesTheDirectSolutionForPlainAndStabilizedScni)
{
    // relative residual 1e-13: the solution error is at most cond(K) times that, and 1e-10 allows
    // cond(K) up to 1e3 on these 6^3-node blocks (plain SCNI's low-energy modes make it the worst)
    for (auto [scheme, support] : {std::pair{Scheme::RkScni, 1.51}, std::pair{Scheme::RkMscni, 1.51},
                                   std::pair{Scheme::RkScni, 1.25}, std::pair{Scheme::FemMscni, 1.51}})
    {
        const SolveComparison c = compare_solvers(scheme, support, 1e-13);
        std::printf("%-16s a/h %.2f: |u_pcg - u_cholmod| / |u| = %.1e after %d iterations\n", scheme_name(scheme),
                    support, c.difference, c.iterations);
        EXPECT_LT(c.difference, 1e-10) << scheme_name(scheme);
    }
}

TEST(StaticPcg, ReachesTheSaddlePointSolutionUnderCollocationConstraints)
{
    // u_h(X_b) = sum_J Psi_J(X_b) d_J = 0 at every boundary particle (RK is not interpolating, so
    // these are constraints, not pinned dofs): projected PCG against UMFPACK on [K C^T; C 0]
    const HexMesh mesh = distorted_box(5, h, 0.25);
    RkParams prm;
    prm.normalized_support = 1.51;
    const RkShapeFunctions rk = rkfem::rk_on_mesh(mesh, prm);
    const Operators ops = build(Scheme::RkScni, mesh, rk);
    const index_t n = mesh.n_nodes();
    std::vector<Eigen::Triplet<real_t, int>> t;
    int rows = 0;
    RkSample smp;
    for (index_t i = 0; i < n; ++i)
    {
        if (is_interior(mesh, i, 1e-9, 5 * h - 1e-9))
            continue;
        rk.evaluate(mesh.node(i), false, smp);
        for (int d = 0; d < 3; ++d, ++rows)
            for (index_t k = 0; k < smp.size(); ++k)
                t.emplace_back(rows, static_cast<int>(3 * smp.nodes[k] + d), smp.psi[k]);
    }
    SparseMatrix C(rows, 3 * n);
    C.setFromTriplets(t.begin(), t.end());
    const std::vector<real_t> f = random_vector(3 * static_cast<std::size_t>(n), 13);
    const std::vector<real_t> direct =
        solve_static_constrained(assemble_stiffness(ops.points, mat, n), f, C, std::vector<real_t>(rows, 0.0));
    const PcgResult pcg = solve_static_pcg(MatrixFreeStiffness({{&ops.points, 1.0}}, mat, n), f, {},
                                           assemble_stiffness(build_hex_gauss(mesh, 2), mat, n), 1e-13, 2000, &C);
    const real_t diff = relative_difference(pcg.u, direct);
    const Eigen::VectorXd Cu = C * Eigen::Map<const Eigen::VectorXd>(pcg.u.data(), 3 * n);
    std::printf("%d constraints: |u_pcg - u_umfpack| / |u| = %.1e after %d iterations, max |C u| / max |u| = %.1e\n",
                rows, diff, pcg.iterations,
                Cu.cwiseAbs().maxCoeff() /
                    Eigen::Map<const Eigen::VectorXd>(pcg.u.data(), 3 * n).cwiseAbs().maxCoeff());
    EXPECT_LT(diff, 1e-10);
    EXPECT_LT(Cu.cwiseAbs().maxCoeff(),
              1e-13 * Eigen::Map<const Eigen::VectorXd>(pcg.u.data(), 3 * n).cwiseAbs().maxCoeff());
}

TEST(StaticPcg, SaysWhenItDoesNotConverge)
{
    const HexMesh mesh = distorted_box(3, h, 0.2);
    const RkShapeFunctions rk = rk_on_mesh(mesh);
    const Operators ops = build(Scheme::RkScni, mesh, rk);
    const index_t n = mesh.n_nodes();
    const std::vector<real_t> f = random_vector(3 * static_cast<std::size_t>(n), 5);
    try
    {
        solve_static_pcg(MatrixFreeStiffness({{&ops.points, 1.0}}, mat, n), f, rigid_pins(0, 3, 12),
                         assemble_stiffness(build_hex_gauss(mesh, 2), mat, n), 1e-14, 2);
        FAIL() << "two iterations cannot reach 1e-14";
    }
    catch (const Error& e)
    {
        EXPECT_NE(std::string(e.what()).find("after 2 iterations"), std::string::npos) << e.what();
    }
}
