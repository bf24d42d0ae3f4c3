#pragma once
// Shared set-up for nodal-integration tests: a jittered hex mesh, RK functions over its nodes,
// and the operators every scheme builds on it.
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
