// Timoshenko-Goodier cantilever (../shared/reference/rkpm-methods.md section 9.4) in plane strain:
// L = 48, D = 12, one cell thick with w = 0, 3-D material E' = E(1+2nu)/(1+nu)^2, nu' = nu/(1+nu)
// so that plane strain reproduces the plane-stress solution with E = 3e7, nu = 0.3, P = 1000:
// tip deflection u_y(L, 0) = P L^3/(3EI) + (4+5nu) P L/(2ED) = 8.900e-3. The exact displacement is
// imposed on x = 0 (physical values: RK collocation constraints), the parabolic shear traction on
// x = L through the boundary facet quadrature. Static solve (UMFPACK on the saddle-point system).
#include <gtest/gtest.h>

#include <cstdio>
#include <memory>

#include "rkfem/analysis/manufactured_solution.hpp"
#include "rkfem/approximation/coupling/coupled_shapes.hpp"
#include "rkfem/approximation/shape_evaluator.hpp"
#include "rkfem/discretization/generators.hpp"
#include "rkfem/integration/nodal/nodal_integration.hpp"
#include "rkfem/operators/linear_static.hpp"

using namespace rkfem;

namespace
{
constexpr real_t L = 48, D = 12, E = 3.0e7, nu = 0.3, P = 1000, I = D * D * D / 12;

Vec3 exact_u(const Vec3& x)
{
    const real_t X = x[0], y = x[1];
    return {-(P * y / (6 * E * I)) * ((6 * L - 3 * X) * X + (2 + nu) * (y * y - D * D / 4)),
            (P / (6 * E * I)) * (3 * nu * y * y * (L - X) + (4 + 5 * nu) * D * D * X / 4 + (3 * L - X) * X * X), 0.0};
}

/// The approximation of the beam: FE, RK, or FE for x < L/2 and RK beyond (coupled).
enum class Beam
{
    Fe,
    Rk,
    CoupledMixed,
    CoupledRamp,
};

real_t tip_deflection(Beam kind, int nx, int ny, real_t stab)
{
    const HexMesh mesh = generate_box(Vec3(0, -D / 2, 0), Vec3(L, D, 1.0), {nx, ny, 1});
    const index_t nn = mesh.n_nodes();
    const real_t E3 = E * (1 + 2 * nu) / ((1 + nu) * (1 + nu)), nu3 = nu / (1 + nu);
    const ElasticParams mat = ElasticParams::from_E_nu(1.0, E3, nu3);
    const RkShapeFunctions rk = rk_on_mesh(mesh, RkParams{});
    const RkShapes rks(rk);
    const FemShapes fes(mesh);
    std::vector<char> rk_elements(static_cast<std::size_t>(mesh.n_elements()), 0);
    for (index_t e = 0; e < mesh.n_elements(); ++e)
        rk_elements[e] = mesh.node(mesh.conn[8 * e])[0] >= 0.5 * L - 1e-9;
    const bool coupled = kind == Beam::CoupledMixed || kind == Beam::CoupledRamp;
    std::unique_ptr<CoupledShapes> cs;
    if (coupled)
        cs = std::make_unique<CoupledShapes>(mesh, rk_elements, RkParams{},
                                             kind == Beam::CoupledMixed ? Transition::Mixed : Transition::Ramp);
    const bool is_rk = kind == Beam::Rk;
    const ShapeEvaluator& shapes = coupled ? static_cast<const ShapeEvaluator&>(*cs)
                                   : is_rk ? static_cast<const ShapeEvaluator&>(rks)
                                           : fes;
    // the physical value at node i: sum over (nodes, values) of the unknowns
    auto physical_row = [&](index_t i, std::vector<index_t>& nodes, std::vector<real_t>& values)
    {
        nodes.clear();
        values.clear();
        if (coupled)
            return cs->node_row(i, nodes, values);
        if (!is_rk)
        {
            nodes.push_back(i);
            values.push_back(1.0);
            return;
        }
        RkSample s;
        rk.evaluate(mesh.node(i), false, s);
        nodes = s.nodes;
        values = s.psi;
    };
    const IntegrationOperator op = build_scni(mesh, shapes);
    SparseMatrix K = assemble_stiffness(op, mat, nn);
    if (stab > 0)
        K += assemble_stiffness(build_mscni_stabilization(op, build_sd_scni(mesh, shapes)), mat, nn, stab);
    // traction on x = L: t_y = P/(2I) (D^2/4 - y^2) per unit thickness
    std::vector<real_t> f(3 * static_cast<std::size_t>(nn), 0.0);
    std::vector<index_t> nodes;
    std::vector<real_t> psi;
    for (const BoundaryPoint& b : boundary_quadrature(mesh))
    {
        if (std::abs(b.point.x[0] - L) > 1e-9)
            continue;
        const real_t y = b.point.x[1];
        const real_t ty = P / (2 * I) * (D * D / 4 - y * y) * b.point.nda.norm();
        shapes.values(b.element, b.point.xi, b.point.x, nodes, psi);
        for (std::size_t k = 0; k < nodes.size(); ++k)
            f[3 * nodes[k] + 1] += psi[k] * ty;
    }
    // constraints: physical u_x, u_y = exact on x = 0; every coefficient d_z = 0 (plane strain)
    std::vector<Eigen::Triplet<real_t, int>> t;
    std::vector<real_t> g;
    std::vector<index_t> row_nodes;
    std::vector<real_t> row_values;
    for (index_t i = 0; i < nn; ++i)
    {
        t.emplace_back(static_cast<int>(g.size()), 3 * i + 2, 1.0);
        g.push_back(0.0);
        const Vec3 X = mesh.node(i);
        if (std::abs(X[0]) > 1e-9)
            continue;
        const Vec3 ue = exact_u(X);
        physical_row(i, row_nodes, row_values);
        for (int d = 0; d < 2; ++d)
        {
            for (std::size_t k = 0; k < row_nodes.size(); ++k)
                t.emplace_back(static_cast<int>(g.size()), 3 * row_nodes[k] + d, row_values[k]);
            g.push_back(ue[d]);
        }
    }
    SparseMatrix C(static_cast<int>(g.size()), 3 * nn);
    C.setFromTriplets(t.begin(), t.end());
    const std::vector<real_t> d = solve_static_constrained(K, f, C, g);
    // physical u_y at (L, 0, z) averaged over the two z nodes
    real_t uy = 0.0;
    int count = 0;
    for (index_t i = 0; i < nn; ++i)
    {
        const Vec3 X = mesh.node(i);
        if (std::abs(X[0] - L) > 1e-9 || std::abs(X[1]) > 1e-9)
            continue;
        physical_row(i, row_nodes, row_values);
        for (std::size_t k = 0; k < row_nodes.size(); ++k)
            uy += row_values[k] * d[3 * row_nodes[k] + 1];
        ++count;
    }
    return uy / count;
}
} // namespace

TEST(NodalCantilever, TipDeflectionWithinOnePercentOfTimoshenko)
{
    const real_t exact = P * L * L * L / (3 * E * I) + (4 + 5 * nu) * P * L / (2 * E * D);
    ASSERT_NEAR(exact, 8.900e-3, 1e-6);
    struct Row
    {
        const char* name;
        Beam f;
        real_t stab;
        int nx; ///< elements along the beam at the resolution that is asserted (ny = nx / 4)
    };
    // plain SCNI is soft on coarse clouds (its low-energy modes): +1.5 % at 33 x 9 nodes, so its
    // 1 % check is made at 65 x 17 nodes
    for (const Row& r : {Row{"rkpm scni", Beam::Rk, 0.0, 64}, Row{"rkpm scni+mscni", Beam::Rk, 1.0, 32},
                         Row{"fem-nodal scni+mscni", Beam::Fe, 1.0, 32}})
    {
        const real_t coarse = tip_deflection(r.f, r.nx / 2, r.nx / 8, r.stab),
                     fine = tip_deflection(r.f, r.nx, r.nx / 4, r.stab);
        std::printf("%-22s tip u_y: %dx%d nodes %.5e (%+.2f%%), %dx%d nodes %.5e (%+.2f%%); exact %.5e\n", r.name,
                    r.nx / 2 + 1, r.nx / 8 + 1, coarse, 100 * (coarse / exact - 1), r.nx + 1, r.nx / 4 + 1, fine,
                    100 * (fine / exact - 1), exact);
        EXPECT_NEAR(fine, exact, 0.01 * exact) << r.name;
        EXPECT_LT(std::abs(fine - exact), std::abs(coarse - exact)) << r.name << ": refinement must help";
    }
}

TEST(NodalCantilever, SplitFeRkBeamMatchesTheAllFeBeam)
{
    // FE (fem-nodal) for x < L/2, RK beyond, through one transition layer; clamped on the FE
    // end, loaded on the RK end: the tip deflection within 1 % of the all-FE beam of the same mesh
    const real_t exact = P * L * L * L / (3 * E * I) + (4 + 5 * nu) * P * L / (2 * E * D);
    const real_t fe = tip_deflection(Beam::Fe, 32, 8, 1.0);
    for (Beam b : {Beam::CoupledMixed, Beam::CoupledRamp})
    {
        const real_t c = tip_deflection(b, 32, 8, 1.0);
        std::printf("%s, 33x9 nodes: tip u_y %.5e, all-FE %.5e (%+.3f%%), exact %.5e (%+.3f%%)\n",
                    b == Beam::CoupledMixed ? "FE | mixed | RK" : "FE | ramp | RK", c, fe, 100 * (c / fe - 1), exact,
                    100 * (c / exact - 1));
        EXPECT_NEAR(c, fe, 0.01 * fe);
    }
}
