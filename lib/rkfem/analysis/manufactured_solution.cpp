#include "rkfem/analysis/manufactured_solution.hpp"

#include <chrono>
#include <cmath>
#include <sstream>

#include "rkfem/approximation/fem/hex8_basis.hpp"
#include "rkfem/approximation/shape_evaluator.hpp"
#include "rkfem/config/deck.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/discretization/generators.hpp"
#include "rkfem/integration/hex_gauss.hpp"
#include "rkfem/integration/nodal/nodal_integration.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/operators/linear_static.hpp"
#include "rkfem/operators/semi_lagrangian_block.hpp"

namespace rkfem
{
namespace
{
struct Exact
{
    real_t lambda, mu;
    Vec3 u(const Vec3& x) const
    {
        const real_t s = std::sin(M_PI * x[0]) * std::sin(M_PI * x[1]) * std::sin(M_PI * x[2]);
        return Vec3::Constant(s);
    }
    /// grad s (the gradient of every component)
    Vec3 grad_s(const Vec3& x) const
    {
        const real_t sx = std::sin(M_PI * x[0]), sy = std::sin(M_PI * x[1]), sz = std::sin(M_PI * x[2]);
        const real_t cx = std::cos(M_PI * x[0]), cy = std::cos(M_PI * x[1]), cz = std::cos(M_PI * x[2]);
        return M_PI * Vec3(cx * sy * sz, sx * cy * sz, sx * sy * cz);
    }
    /// du_i/dx_j
    Mat3 grad_u(const Vec3& x) const
    {
        const Vec3 g = grad_s(x);
        Mat3 G;
        for (int i = 0; i < 3; ++i)
            G.row(i) = g.transpose();
        return G;
    }
    Mat3 stress(const Vec3& x) const
    {
        const Mat3 G = grad_u(x);
        const Mat3 eps = 0.5 * (G + G.transpose());
        return lambda * eps.trace() * Mat3::Identity() + 2.0 * mu * eps;
    }
    /// b = -div sigma = -[(lambda + mu) grad(div u) + mu lap u]
    Vec3 body_force(const Vec3& x) const
    {
        const real_t s[3] = {std::sin(M_PI * x[0]), std::sin(M_PI * x[1]), std::sin(M_PI * x[2])};
        const real_t c[3] = {std::cos(M_PI * x[0]), std::cos(M_PI * x[1]), std::cos(M_PI * x[2])};
        const real_t sss = s[0] * s[1] * s[2];
        Mat3 H; // second derivatives of s
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
            {
                if (i == j)
                    H(i, j) = -M_PI * M_PI * sss;
                else
                {
                    const int k = 3 - i - j;
                    H(i, j) = M_PI * M_PI * c[i] * c[j] * s[k];
                }
            }
        Vec3 b;
        for (int j = 0; j < 3; ++j)
            b[j] = -((lambda + mu) * H.row(j).sum() + mu * (-3.0 * M_PI * M_PI * sss));
        return b;
    }
};

void gauss(int n, real_t* x, real_t* w)
{
    if (n == 3)
    {
        const real_t a = std::sqrt(0.6);
        x[0] = -a, x[1] = 0, x[2] = a;
        w[0] = w[2] = 5.0 / 9.0, w[1] = 8.0 / 9.0;
    }
    else // 4
    {
        const real_t a = std::sqrt(3.0 / 7.0 - 2.0 / 7.0 * std::sqrt(1.2)),
                     b = std::sqrt(3.0 / 7.0 + 2.0 / 7.0 * std::sqrt(1.2));
        const real_t wa = (18.0 + std::sqrt(30.0)) / 36.0, wb = (18.0 - std::sqrt(30.0)) / 36.0;
        x[0] = -b, x[1] = -a, x[2] = a, x[3] = b;
        w[0] = w[3] = wb, w[1] = w[2] = wa;
    }
}

template <class F> void for_each_gauss_point(const HexMesh& mesh, int ng, F&& f)
{
    real_t gx[4], gw[4];
    gauss(ng, gx, gw);
    for (index_t e = 0; e < mesh.n_elements(); ++e)
    {
        real_t xe[8][3];
        for (int I = 0; I < 8; ++I)
            for (int d = 0; d < 3; ++d)
                xe[I][d] = mesh.x[3 * mesh.conn[8 * e + I] + d];
        for (int i = 0; i < ng; ++i)
            for (int j = 0; j < ng; ++j)
                for (int k = 0; k < ng; ++k)
                {
                    const real_t xi[3] = {gx[i], gx[j], gx[k]};
                    real_t N[8], dNdx[8][3];
                    hex8_shape(xi, N);
                    const real_t detJ = hex8_gradients(xe, xi, dNdx);
                    Vec3 x = Vec3::Zero();
                    for (int I = 0; I < 8; ++I)
                        x += N[I] * Vec3(xe[I][0], xe[I][1], xe[I][2]);
                    f(e, Vec3(xi[0], xi[1], xi[2]), x, gw[i] * gw[j] * gw[k] * detJ, N, dNdx);
                }
    }
}
/// SNNI's tables on the cube's nodes, from the semi-Lagrangian block itself (its cells: the boxes
/// of the nodes' dual cells, which tile the cube; operators/semi_lagrangian_block.hpp,
/// snni_operators): the points, and the face-gradient term's sub-points (snni) or the sub-cells'
/// (sd-snni). The block's particles are the mesh's nodes in the same order (checked).
void snni_tables(const MmsCase& c, const HexMesh& mesh, IntegrationOperator& op, IntegrationOperator& stab)
{
    const char* kernel = c.rk.kernel == KernelType::QuinticBSpline ? "quintic-bspline"
                         : c.rk.kernel == KernelType::Gaussian     ? "gaussian"
                                                                   : "cubic-bspline";
    std::ostringstream deck;
    deck.precision(17);
    deck << "title: manufactured solution, " << c.scheme << "\ntime: {end: 1 s}\nparts:\n  cube:\n"
         << "    generator: {type: box, size: [1 m, 1 m, 1 m], divisions: [" << c.n << ", " << c.n << ", " << c.n
         << "]}\n    material: {model: elastic, rho: 1 kg/m^3, E: " << c.E << " Pa, nu: " << c.nu << "}\n"
         << "    formulation: rkpm\n    kinematics: semi-lagrangian\n"
         << "    rk: {order: " << c.rk.order << ", kernel: " << kernel
         << ", support: " << (c.rk.support == SupportShape::Sphere ? "sphere" : "box")
         << ", normalized_support: " << c.rk.normalized_support << "}\n";
    Model m = Model::build(parse_deck(deck.str(), "manufactured_solution.yaml"));
    SemiLagrangianForceBlock* sl = nullptr;
    for (index_t k = 0; k < m.n_blocks() && !sl; ++k)
        sl = dynamic_cast<SemiLagrangianForceBlock*>(&m.block(k));
    RKFEM_REQUIRE(sl && m.nodes.size() == mesh.n_nodes(),
                  "manufactured solution: the " << c.scheme
                                                << " model has no semi-Lagrangian block of the mesh's nodes");
    for (std::size_t k = 0; k < mesh.x.size(); ++k)
        RKFEM_REQUIRE(std::abs(m.nodes.x[k] - mesh.x[k]) < 1e-12,
                      "manufactured solution: the " << c.scheme << " model's particles are not the mesh's nodes");
    const auto sub = c.scheme == "sd-snni" ? SemiLagrangianForceBlock::SubPoints::SubCells
                                           : SemiLagrangianForceBlock::SubPoints::FaceCentres;
    RKFEM_REQUIRE(sl->snni_operators(m.nodes.x, sub, op, stab),
                  "manufactured solution: a smoothing cell's face centre is not covered");
}
} // namespace

std::string MmsCase::label() const
{
    std::string s = formulation == Formulation::Rkpm ? "rkpm " : "fem-nodal ";
    s += scheme;
    if (scheme == "scni" && stabilization > 0)
        s += "+mscni";
    if (scheme == "snni" && stabilization > 0)
        s += "+face-gradient";
    if (boundary == MmsBoundary::Dirichlet)
        s += " dirichlet";
    return s;
}

std::string MmsCase::table_name() const
{
    std::ostringstream s;
    s << label();
    if ((scheme == "scni" || scheme == "snni") && stabilization > 0 && stabilization != 1)
        s << " cs" << stabilization;
    if (formulation == Formulation::Rkpm)
    {
        s << " a" << std::to_string(rk.normalized_support).substr(0, 4);
        if (rk.kernel == KernelType::QuinticBSpline)
            s << " quintic";
        else if (rk.kernel == KernelType::Gaussian)
            s << " gaussian";
        if (rk.support == SupportShape::Sphere)
            s << " sphere";
        if (rk.order == 2)
            s << " quadratic";
    }
    if (solver != MmsSolver::Auto)
        s << (solver == MmsSolver::Direct ? " direct" : " pcg");
    std::string name = s.str();
    for (auto& ch : name)
        if (ch == ' ' || ch == '+')
            ch = '_';
    return name;
}

MmsResult solve_mms(const MmsCase& c)
{
    const auto t0 = std::chrono::steady_clock::now();
    RKFEM_REQUIRE(is_nodal(c.formulation), "manufactured solution: formulation must be rkpm or fem-nodal");
    const HexMesh mesh = generate_box(Vec3::Zero(), Vec3::Ones(), {c.n, c.n, c.n});
    const index_t nn = mesh.n_nodes();
    const ElasticParams mat = ElasticParams::from_E_nu(1.0, c.E, c.nu);
    const Exact ex{mat.lambda, mat.mu};

    const RkShapeFunctions rk = rk_on_mesh(mesh, c.rk);
    const RkShapes rks(rk);
    const FemShapes fes(mesh);
    const bool is_rk = c.formulation == Formulation::Rkpm;
    const ShapeEvaluator& shapes = is_rk ? static_cast<const ShapeEvaluator&>(rks) : fes;

    const bool snni = c.scheme == "snni" || c.scheme == "sd-snni";
    RKFEM_REQUIRE(!snni || is_rk, "manufactured solution: scheme " << c.scheme << " needs formulation rkpm");
    IntegrationOperator op, stab;
    // SD-SNNI: the sub-cells' term at c_s = 1 (with it the stiffness is SD-SNNI's)
    const real_t c_stab = c.scheme == "sd-snni" ? 1.0 : c.stabilization;
    if (snni)
        snni_tables(c, mesh, op, stab);
    else
    {
        const NodalScheme scheme = c.scheme == "dni"       ? NodalScheme::Dni
                                   : c.scheme == "sd-scni" ? NodalScheme::SdScni
                                                           : NodalScheme::Scni;
        op = build_nodal(scheme, mesh, shapes);
        if (scheme == NodalScheme::Scni && c.stabilization > 0)
            stab = build_mscni_stabilization(op, build_sd_scni(mesh, shapes));
    }
    const bool stabilized = c_stab > 0 && stab.n_points() > 0;

    // loads: body force with 3^3 Gauss points per element, exact traction on the boundary facets
    std::vector<real_t> f(3 * static_cast<std::size_t>(nn), 0.0);
    std::vector<index_t> nodes;
    std::vector<real_t> psi;
    for_each_gauss_point(mesh, 3,
                         [&](index_t e, const Vec3& xi, const Vec3& x, real_t w, const real_t*, const real_t(*)[3])
                         {
                             shapes.values(e, xi, x, nodes, psi);
                             const Vec3 b = ex.body_force(x) * w;
                             for (std::size_t k = 0; k < nodes.size(); ++k)
                                 for (int d = 0; d < 3; ++d)
                                     f[3 * nodes[k] + d] += psi[k] * b[d];
                         });
    const bool dirichlet = c.boundary == MmsBoundary::Dirichlet;
    for (const BoundaryPoint& bp : dirichlet ? std::vector<BoundaryPoint>{} : boundary_quadrature(mesh))
    {
        shapes.values(bp.element, bp.point.xi, bp.point.x, nodes, psi);
        const Vec3 t = ex.stress(bp.point.x) * bp.point.nda;
        for (std::size_t k = 0; k < nodes.size(); ++k)
            for (int d = 0; d < 3; ++d)
                f[3 * nodes[k] + d] += psi[k] * t[d];
    }
    // rigid-body dofs at three corners (u = 0 there)
    auto corner = [&](const Vec3& p)
    {
        for (index_t i = 0; i < nn; ++i)
            if ((mesh.node(i) - p).norm() < 1e-12)
                return i;
        throw Error("manufactured solution: corner not found");
    };
    const index_t c0 = corner(Vec3(0, 0, 0)), c1 = corner(Vec3(1, 0, 0)), c2 = corner(Vec3(0, 1, 0));
    std::vector<index_t> pinned = {3 * c0, 3 * c0 + 1, 3 * c0 + 2, 3 * c1 + 1, 3 * c1 + 2, 3 * c2 + 2};
    // Dirichlet: the boundary particles' collocation rows u_h(X_b) = sum_J Psi_J(X_b) d_J = 0 (RK),
    // or their dofs pinned (FE shape functions interpolate)
    std::vector<Eigen::Triplet<real_t, int>> collocation;
    int n_rows = 0;
    if (dirichlet)
    {
        pinned.clear();
        RkSample smp;
        for (index_t i = 0; i < nn; ++i)
        {
            const Vec3 x = mesh.node(i);
            if ((x.array() > 1e-12).all() && (x.array() < 1 - 1e-12).all())
                continue;
            if (!is_rk)
            {
                for (int dd = 0; dd < 3; ++dd)
                    pinned.push_back(3 * i + dd);
                continue;
            }
            rk.evaluate(x, false, smp);
            for (int dd = 0; dd < 3; ++dd, ++n_rows)
                for (index_t k = 0; k < smp.size(); ++k)
                    collocation.emplace_back(n_rows, static_cast<int>(3 * smp.nodes[k] + dd), smp.psi[k]);
        }
    }
    SparseMatrix C(n_rows, 3 * nn);
    C.setFromTriplets(collocation.begin(), collocation.end());
    MmsResult r;
    std::vector<real_t> d;
    if (c.solver == MmsSolver::Pcg || (c.solver == MmsSolver::Auto && 3 * nn > MmsCase::pcg_above_dofs))
    {
        std::vector<StiffnessTerm> terms{{&op, 1.0}};
        if (stabilized)
            terms.push_back({&stab, c_stab});
        const MatrixFreeStiffness K(terms, mat, nn);
        const SparseMatrix fe = assemble_stiffness(build_hex_gauss(mesh, 2), mat, nn);
        PcgResult pr = solve_static_pcg(K, f, pinned, fe, c.pcg_rtol, c.pcg_max_iterations, &C);
        d = std::move(pr.u);
        r.iterations = pr.iterations;
    }
    else
    {
        SparseMatrix K = assemble_stiffness(op, mat, nn);
        if (stabilized)
            K += assemble_stiffness(stab, mat, nn, c_stab);
        if (n_rows > 0)
            d = solve_static_constrained(K, f, C, std::vector<real_t>(static_cast<std::size_t>(n_rows), 0.0));
        else
            d = solve_static(K, f, pinned, std::vector<real_t>(pinned.size(), 0.0));
    }

    // errors
    real_t e2 = 0, u2 = 0, g2 = 0, gu2 = 0;
    RkSample smp;
    for_each_gauss_point(mesh, 4,
                         [&](index_t e, const Vec3&, const Vec3& x, real_t w, const real_t* N, const real_t(*dNdx)[3])
                         {
                             Vec3 uh = Vec3::Zero();
                             Mat3 gh = Mat3::Zero();
                             if (is_rk)
                             {
                                 rk.evaluate(x, true, smp);
                                 for (index_t k = 0; k < smp.size(); ++k)
                                 {
                                     const index_t J = smp.nodes[k];
                                     const Vec3 dj(d[3 * J], d[3 * J + 1], d[3 * J + 2]);
                                     uh += smp.psi[k] * dj;
                                     gh += dj * smp.grad[k].transpose();
                                 }
                             }
                             else
                                 for (int I = 0; I < 8; ++I)
                                 {
                                     const index_t J = mesh.conn[8 * e + I];
                                     const Vec3 dj(d[3 * J], d[3 * J + 1], d[3 * J + 2]);
                                     uh += N[I] * dj;
                                     gh += dj * Vec3(dNdx[I][0], dNdx[I][1], dNdx[I][2]).transpose();
                                 }
                             const Vec3 ue = ex.u(x);
                             const Mat3 ge = ex.grad_u(x);
                             e2 += w * (uh - ue).squaredNorm();
                             u2 += w * ue.squaredNorm();
                             g2 += w * (gh - ge).squaredNorm();
                             gu2 += w * ge.squaredNorm();
                         });
    r.n = c.n;
    r.h = 1.0 / c.n;
    r.dofs = 3 * nn;
    r.l2 = std::sqrt(e2 / u2);
    r.h1 = std::sqrt(g2 / gu2);
    r.seconds = std::chrono::duration<real_t>(std::chrono::steady_clock::now() - t0).count();
    return r;
}
} // namespace rkfem
