// Timoshenko-Goodier cantilever (../shared/reference/rkpm-methods.md section 9.4) in plane strain:
// L = 48, D = 12, one cell thick with w = 0, 3-D material E' = E(1+2nu)/(1+nu)^2, nu' = nu/(1+nu)
// so that plane strain reproduces the plane-stress solution with E = 3e7, nu = 0.3, P = 1000:
// tip deflection u_y(L, 0) = P L^3/(3EI) + (4+5nu) P L/(2ED) = 8.900e-3. The exact displacement is
// imposed on x = 0 (physical values: RK collocation constraints), the parabolic shear traction on
// x = L through the boundary facet quadrature. Static solve (UMFPACK on the saddle-point system).
#include <gtest/gtest.h>

#include <cstdio>

#include "rkfem/analysis/manufactured_solution.hpp"
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

real_t tip_deflection(Formulation form, int nx, int ny, real_t stab)
{
    const HexMesh mesh = generate_box(Vec3(0, -D / 2, 0), Vec3(L, D, 1.0), {nx, ny, 1});
    const index_t nn = mesh.n_nodes();
    const real_t E3 = E * (1 + 2 * nu) / ((1 + nu) * (1 + nu)), nu3 = nu / (1 + nu);
    const ElasticParams mat = ElasticParams::from_E_nu(1.0, E3, nu3);
    const RkShapeFunctions rk = rk_on_mesh(mesh, RkParams{});
    const RkShapes rks(rk);
    const FemShapes fes(mesh);
    const bool is_rk = form == Formulation::Rkpm;
    const ShapeEvaluator& shapes = is_rk ? static_cast<const ShapeEvaluator&>(rks) : fes;
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
    RkSample s;
    for (index_t i = 0; i < nn; ++i)
    {
        t.emplace_back(static_cast<int>(g.size()), 3 * i + 2, 1.0);
        g.push_back(0.0);
        const Vec3 X = mesh.node(i);
        if (std::abs(X[0]) > 1e-9)
            continue;
        const Vec3 ue = exact_u(X);
        for (int d = 0; d < 2; ++d)
        {
            if (is_rk)
            {
                rk.evaluate(X, false, s);
                for (index_t k = 0; k < s.size(); ++k)
                    t.emplace_back(static_cast<int>(g.size()), 3 * s.nodes[k] + d, s.psi[k]);
            }
            else
                t.emplace_back(static_cast<int>(g.size()), 3 * i + d, 1.0);
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
        if (is_rk)
        {
            rk.evaluate(X, false, s);
            for (index_t k = 0; k < s.size(); ++k)
                uy += s.psi[k] * d[3 * s.nodes[k] + 1];
        }
        else
            uy += d[3 * i + 1];
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
        Formulation f;
        real_t stab;
        int nx; ///< elements along the beam at the resolution that is asserted (ny = nx / 4)
    };
    // plain SCNI is soft on coarse clouds (its low-energy modes): +1.5 % at 33 x 9 nodes, so its
    // 1 % check is made at 65 x 17 nodes
    for (const Row& r : {Row{"rkpm scni", Formulation::Rkpm, 0.0, 64}, Row{"rkpm scni+mscni", Formulation::Rkpm, 1.0, 32},
                         Row{"fem-nodal scni+mscni", Formulation::FemNodal, 1.0, 32}})
    {
        const real_t coarse = tip_deflection(r.f, r.nx / 2, r.nx / 8, r.stab), fine = tip_deflection(r.f, r.nx, r.nx / 4, r.stab);
        std::printf("%-22s tip u_y: %dx%d nodes %.5e (%+.2f%%), %dx%d nodes %.5e (%+.2f%%); exact %.5e\n", r.name,
                    r.nx / 2 + 1, r.nx / 8 + 1, coarse, 100 * (coarse / exact - 1), r.nx + 1, r.nx / 4 + 1, fine,
                    100 * (fine / exact - 1), exact);
        EXPECT_NEAR(fine, exact, 0.01 * exact) << r.name;
        EXPECT_LT(std::abs(fine - exact), std::abs(coarse - exact)) << r.name << ": refinement must help";
    }
}
