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

/// The semi-Lagrangian face-gradient term's default coefficient. Its stress is elastic, so where
/// the material flows it resists the flow: the Taylor bar at 0.8 mm (studies/tables/taylor_bar.yaml)
/// ends 20.44 mm long with a 5.00 mm foot at c_s 1, 21.64 / 6.11 at 0.25, 22.11 / 6.83 at 0.1
/// (the literature's 21.45 / 7.05), and goes unstable at 60 us with no term; c_s 1 with the loads
/// scaled by the material's elastic share, floored at 0.1 or 0.2, gave 6.61 and 6.49 mm. P6's
/// semi-Lagrangian target at 1 in threw the FSP back at 214 m/s at c_s 1, 185 at 0.25, 139 at 0.1.
inline constexpr real_t kFaceGradientCoefficient = 0.1;

/// Nodal integration of `fem-nodal` and `rkpm` parts.
struct NodalIntegrationSpec
{
    std::string scheme = "scni";         ///< dni | scni | sd-scni
    std::string stabilization = "mscni"; ///< none | mscni | nsni (scheme scni only; nsni: rkpm only)
    /// c_s (MSCNI: 1 = RKPM2D default; NSNI: kNsniCoefficient; face-gradient: kFaceGradientCoefficient)
    real_t stabilization_coefficient = 1.0;
    real_t dt_factor =
        0.0; ///< alpha in dt = alpha J^(1/3) l0 / c (l0: shortest edge at the node); 0: calibrated default
    /// Cloud parts: SCNI's points on the Voronoi faces, one per triangle of each face's fan
    /// (`triangles`) or one per face at its centroid (`faces`: exact for linear fields too, a
    /// cheaper set-up; merge_face_points; measurements: docs/performance.md)
    std::string facet_points = "triangles";
};
} // namespace rkfem
