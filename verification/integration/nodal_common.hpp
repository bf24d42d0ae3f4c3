#pragma once
// Shared set-up for nodal-integration tests: a jittered hex mesh, RK functions over its nodes,
// and the operators every scheme builds on it.
#include <algorithm>
#include <memory>

#include "rkfem/approximation/shape_evaluator.hpp"
#include "rkfem/integration/nodal/nodal_integration.hpp"
#include "../support.hpp"

namespace rkfem::test
{
/// RK functions with the default parameters over a mesh's nodes.
inline RkShapeFunctions rk_on_mesh(const HexMesh& mesh) { return rkfem::rk_on_mesh(mesh, RkParams{}); }

enum class Scheme
{
    RkDni,
    RkScni,
    RkSdScni,
    RkMscni, ///< SCNI points plus the MSCNI stabilization operator
    FemScni,
    FemSdScni,
    FemMscni,
};

inline const char* scheme_name(Scheme s)
{
    switch (s)
    {
    case Scheme::RkDni: return "rkpm_dni";
    case Scheme::RkScni: return "rkpm_scni";
    case Scheme::RkSdScni: return "rkpm_sd_scni";
    case Scheme::RkMscni: return "rkpm_mscni";
    case Scheme::FemScni: return "fem_nodal_scni";
    case Scheme::FemSdScni: return "fem_nodal_sd_scni";
    case Scheme::FemMscni: return "fem_nodal_mscni";
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
    case Scheme::RkDni: ops.points = build_dni(mesh, rks); break;
    case Scheme::RkScni: ops.points = build_scni(mesh, rks); break;
    case Scheme::RkSdScni: ops.points = build_sd_scni(mesh, rks); break;
    case Scheme::RkMscni:
        ops.points = build_scni(mesh, rks);
        ops.stabilization = build_mscni_stabilization(ops.points, build_sd_scni(mesh, rks));
        break;
    case Scheme::FemScni: ops.points = build_scni(mesh, fes); break;
    case Scheme::FemSdScni: ops.points = build_sd_scni(mesh, fes); break;
    case Scheme::FemMscni:
        ops.points = build_scni(mesh, fes);
        ops.stabilization = build_mscni_stabilization(ops.points, build_sd_scni(mesh, fes));
        break;
    }
    return ops;
}
} // namespace rkfem::test
