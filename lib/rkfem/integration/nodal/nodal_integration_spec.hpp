#pragma once
/// @file nodal_integration_spec.hpp
/// The settings of a nodal part's integration (deck key `nodal_integration`).
#include <string>

#include "rkfem/core/types.hpp"

namespace rkfem
{
/// The NSNI stabilization's default coefficient: the largest power of 2 that keeps the critical
/// step factor of a regular free block above rkpm's default alpha of 1 (1.039 at 0.25; 0.865 at
/// 0.5, 0.640 at 1; verification/operators/test_nodal_dynamics.cpp prints them), so NSNI costs
/// no step; it matches the P3 cantilever's Timoshenko peak as MSCNI does.
inline constexpr real_t kNsniCoefficient = 0.25;

/// Nodal integration of `fem-nodal` and `rkpm` parts.
struct NodalIntegrationSpec
{
    std::string scheme = "scni";            ///< dni | scni | sd-scni
    std::string stabilization = "mscni";    ///< none | mscni | nsni (scheme scni only; nsni: rkpm only)
    real_t stabilization_coefficient = 1.0; ///< c_s (MSCNI: 1 = RKPM2D default; NSNI: kNsniCoefficient)
    real_t dt_factor =
        0.0; ///< alpha in dt = alpha J^(1/3) l0 / c (l0: shortest edge at the node); 0: calibrated default
    /// Cloud parts: SCNI's points on the Voronoi faces, one per triangle of each face's fan
    /// (`triangles`) or one per face at its centroid (`faces`: exact for linear fields too, a
    /// cheaper set-up; merge_face_points; measurements: docs/performance.md)
    std::string facet_points = "triangles";
};
} // namespace rkfem
