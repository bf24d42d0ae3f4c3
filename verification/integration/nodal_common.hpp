#pragma once
// Shared set-up for nodal-integration tests: a jittered hex mesh, RK functions over its nodes,
// and the operators every scheme builds on it.
#include <algorithm>
#include <memory>

#include "../support.hpp"
#include "rkfem/approximation/shape_evaluator.hpp"
#include "rkfem/integration/nodal/nodal_integration.hpp"
#include "rkfem/operators/linear_static.hpp"

namespace rkfem::test
{
/// RK functions with the default parameters over a mesh's nodes.
inline RkShapeFunctions rk_on_mesh(const HexMesh& mesh)
{
    return rkfem::rk_on_mesh(mesh, RkParams{});
}

enum class Scheme
{
    RkDni,
    RkScni,
    RkSdScni,
    RkMscni, ///< SCNI points plus the MSCNI stabilization operator
    RkNsni,  ///< SCNI points plus the NSNI stabilization operator (second moments of the cells)
    FemScni,
    FemSdScni,
    FemMscni,
};

inline const char* scheme_name(Scheme s)
{
    switch (s)
    {
    case Scheme::RkDni:
        return "rkpm_dni";
    case Scheme::RkScni:
        return "rkpm_scni";
    case Scheme::RkSdScni:
        return "rkpm_sd_scni";
    case Scheme::RkMscni:
        return "rkpm_mscni";
    case Scheme::RkNsni:
        return "rkpm_nsni";
    case Scheme::FemScni:
        return "fem_nodal_scni";
    case Scheme::FemSdScni:
        return "fem_nodal_sd_scni";
    case Scheme::FemMscni:
        return "fem_nodal_mscni";
    }
    return "?";
}

/// Linear completeness of an operator on a mesh's nodes with spacing h: the max over points of
/// |sum_I X_I (x) g_I - 1| and |sum_I g_I| h.
inline real_t linear_gradient_error(const HexMesh& mesh, const IntegrationOperator& op, real_t h)
{
    real_t err = 0.0;
    for (index_t p = 0; p < op.n_points(); ++p)
    {
        Mat3 g = Mat3::Zero();
        Vec3 s = Vec3::Zero();
        for (index_t k = op.offsets[p]; k < op.offsets[p + 1]; ++k)
        {
            g += mesh.node(op.nodes[k]) * op.gradient(k).transpose();
            s += op.gradient(k);
        }
        err = std::max({err, (g - Mat3::Identity()).cwiseAbs().maxCoeff(), s.norm() * h});
    }
    return err;
}

/// The stress-point operator and (for MSCNI) the stabilization operator of a scheme.
struct Operators
{
    IntegrationOperator points;
    IntegrationOperator stabilization;
};

inline Operators build(Scheme s, const HexMesh& mesh, const RkShapeFunctions& rk)
{
    RkShapes rks(rk);
    FemShapes fes(mesh);
    Operators ops;
    switch (s)
    {
    case Scheme::RkDni:
        ops.points = build_dni(mesh, rks);
        break;
    case Scheme::RkScni:
        ops.points = build_scni(mesh, rks);
        break;
    case Scheme::RkSdScni:
        ops.points = build_sd_scni(mesh, rks);
        break;
    case Scheme::RkMscni:
        ops.points = build_scni(mesh, rks);
        ops.stabilization = build_mscni_stabilization(ops.points, build_sd_scni(mesh, rks));
        break;
    case Scheme::RkNsni:
        ops.points = build_scni(mesh, rks);
        ops.stabilization = build_nsni_stabilization(ops.points, rk, nodal_second_moments(mesh));
        break;
    case Scheme::FemScni:
        ops.points = build_scni(mesh, fes);
        break;
    case Scheme::FemSdScni:
        ops.points = build_sd_scni(mesh, fes);
        break;
    case Scheme::FemMscni:
        ops.points = build_scni(mesh, fes);
        ops.stabilization = build_mscni_stabilization(ops.points, build_sd_scni(mesh, fes));
        break;
    }
    return ops;
}

/// K of the stress points plus c_s times that of the stabilization operator (if any).
inline SparseMatrix operator_stiffness(const Operators& ops, const ElasticParams& mat, index_t n, real_t cs)
{
    SparseMatrix K = assemble_stiffness(ops.points, mat, n);
    if (ops.stabilization.n_points() > 0)
        K += assemble_stiffness(ops.stabilization, mat, n, cs);
    return K;
}

/// The linear field of the static patch tests.
inline Vec3 patch_field(const Vec3& x)
{
    return {0.1 + 0.2 * x[0] + 0.3 * x[1] + 0.1 * x[2], 0.05 + 0.1 * x[0] - 0.2 * x[1] + 0.15 * x[2],
            -0.1 + 0.05 * x[0] + 0.1 * x[1] - 0.3 * x[2]};
}

struct PatchResult
{
    real_t displacement_error = 0.0; ///< max |d - u(x)| / max |u| over nodes
    real_t strain_error = 0.0;       ///< max |eps - eps_exact| / |eps_exact| over points
};

/// Static linear patch test on a box mesh [0, size]^3: the unknowns of the boundary nodes are
/// prescribed to patch_field (for RK functions, which reproduce linear fields, the coefficients
/// of a linear field are its nodal values), the exact traction sigma n acts through the boundary
/// quadrature (RK test functions of interior nodes do not vanish on the boundary, so their
/// equations carry it; zero for FE), and the solve (CHOLMOD) must give every unknown and every
/// point's strain.
inline PatchResult linear_patch(const HexMesh& mesh, real_t size, const Operators& ops, const ShapeEvaluator& shapes,
                                const ElasticParams& mat, real_t cs)
{
    const index_t n = mesh.n_nodes();
    const SparseMatrix K = operator_stiffness(ops, mat, n, cs);
    std::vector<index_t> dofs;
    std::vector<real_t> values;
    for (index_t i = 0; i < n; ++i)
        if (!is_interior(mesh, i, 1e-9 * size, size * (1 - 1e-9)))
            for (int d = 0; d < 3; ++d)
            {
                dofs.push_back(3 * i + d);
                values.push_back(patch_field(mesh.node(i))[d]);
            }
    Mat3 ge;
    ge << 0.2, 0.3, 0.1, 0.1, -0.2, 0.15, 0.05, 0.1, -0.3;
    const Mat3 eps_exact = 0.5 * (ge + ge.transpose());
    const Mat3 sigma = mat.lambda * eps_exact.trace() * Mat3::Identity() + 2.0 * mat.mu * eps_exact;
    std::vector<real_t> f(3 * static_cast<std::size_t>(n), 0.0);
    std::vector<index_t> nodes;
    std::vector<real_t> psi;
    for (const BoundaryPoint& b : boundary_quadrature(mesh))
    {
        shapes.values(b.element, b.point.xi, b.point.x, nodes, psi);
        const Vec3 t = sigma * b.point.nda;
        for (std::size_t k = 0; k < nodes.size(); ++k)
            for (int d = 0; d < 3; ++d)
                f[3 * nodes[k] + d] += psi[k] * t[d];
    }
    const std::vector<real_t> u = solve_static(K, f, dofs, values);
    PatchResult r;
    real_t umax = 0.0;
    for (index_t i = 0; i < n; ++i)
    {
        const Vec3 ue = patch_field(mesh.node(i));
        umax = std::max(umax, ue.norm());
        r.displacement_error = std::max(r.displacement_error, (Vec3(u[3 * i], u[3 * i + 1], u[3 * i + 2]) - ue).norm());
    }
    r.displacement_error /= umax;
    for (index_t p = 0; p < ops.points.n_points(); ++p)
    {
        Mat3 g = Mat3::Zero();
        for (index_t k = ops.points.offsets[p]; k < ops.points.offsets[p + 1]; ++k)
        {
            const index_t I = ops.points.nodes[k];
            g += Vec3(u[3 * I], u[3 * I + 1], u[3 * I + 2]) * ops.points.gradient(k).transpose();
        }
        r.strain_error = std::max(r.strain_error, (0.5 * (g + g.transpose()) - eps_exact).norm() / eps_exact.norm());
    }
    return r;
}
} // namespace rkfem::test
