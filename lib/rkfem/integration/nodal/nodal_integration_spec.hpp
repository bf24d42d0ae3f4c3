#pragma once
/// @file nodal_integration_spec.hpp
/// The settings of a nodal part's integration (deck key `nodal_integration`).
#include <string>

#include "rkfem/core/types.hpp"
#include "rkfem/discretization/generator_spec.hpp"

namespace rkfem
{
/// The NSNI stabilization's default coefficient: the largest power of 2 that keeps the critical
/// step factor of a regular free block above rkpm's default alpha of 1 (1.039 at 0.25; 0.865 at
/// 0.5, 0.640 at 1; verification/operators/test_nodal_dynamics.cpp prints them), so NSNI costs
/// no step; it matches the P3 cantilever's Timoshenko peak as MSCNI does.
inline constexpr real_t kNsniCoefficient = 0.25;

/// The semi-Lagrangian face-gradient term's default coefficient: 1, the material's stiffness.
/// Its stress is elastic, so where a metal flows it resists the flow: the Taylor bar at 0.8 mm
/// (studies/tables/taylor_bar.yaml) ends 20.44 mm long with a 5.00 mm foot at c_s 1, 21.64 / 6.11
/// at 0.25, 22.11 / 6.83 at 0.1 (the literature's 21.45 / 7.05), and goes unstable at 60 us with
/// no term; c_s 1 with the loads scaled by the material's elastic share, floored at 0.1 or 0.2,
/// gave 6.61 and 6.49 mm (at 0.05 unstable). Elastic bars on a jittered cloud keep 4.1 % of the
/// speed in the striker at 0.1 against 2.7 % at 1. So the default stays 1 and metal-forming runs
/// set 0.1. (P6's case 2.1 at c_s 0.1 let the FSP through, 2.64 in at 100 us, only while the
/// particles behind the target's surface took no part in contact; since they do: nose 0.99 in,
/// apparent 1.50 in, out at 87 m/s; concrete runs take plastic_scaling, semi_lagrangian_block.hpp.)
inline constexpr real_t kFaceGradientCoefficient = 1.0;

/// Cloud parts' defaults (issue #48's decision; studies/tables/cloud_quadrature.yaml, the jittered
/// column wave): the box support at a/h 1.35 (meshes keep 1.51) and SCNI's points one per Voronoi
/// face (`faces`): plateau within 0.1 % at 1 and 0.5 mm, as a/h 1.35 with the triangles (0.1 %,
/// 0.1 %) and better than the old 1.51 with the triangles (1.3 %, 0.0 %), with 63 SCNI and 32 NSNI
/// entries per particle against 71 and 49 and a set-up of about 0.8x.
/// The support on lattices jittered by at least kCloudJitterForSmallSupport and on clouds read
/// from points files: a cloud's h is its particle's longest distance to a facet neighbour, 1.4
/// spacings on average at jitter 0.25, so a is 1.9 spacings. On a lattice with little jitter h is
/// near one spacing: a / h 1.35 then leaves the points of the body's faces (half a spacing outside
/// the first layer) with one layer of particles in reach, which spans no linear field; and one
/// point per face puts the points of its surface particles' outer faces on the particles, where
/// the RK drop tolerance leaves functions of one layer only (`rkfem check` of
/// studies/decks/rk_bars_kernel_contact.yaml failed so, at 1.51 too). Such a cloud keeps the
/// meshes' 1.51 and the triangles.
inline constexpr real_t kCloudNormalizedSupport = 1.35;
inline constexpr real_t kCloudJitterForSmallSupport = 0.2;
inline constexpr const char* kCloudFacetPoints = "faces";

/// A lattice cloud jittered by at least kCloudJitterForSmallSupport: where the clouds' defaults
/// are calibrated for the step (operators/nodal_step_estimate.hpp, nodal_step_calibrated).
inline bool jittered_lattice_cloud(const GeneratorSpec& g)
{
    return g.type == GeneratorSpec::Type::Cloud && g.points_file.empty() && g.jitter >= kCloudJitterForSmallSupport;
}

/// A cloud that takes the clouds' defaults (kCloudNormalizedSupport, kCloudFacetPoints): a
/// jittered lattice or a points file.
inline bool takes_cloud_defaults(const GeneratorSpec& g)
{
    return jittered_lattice_cloud(g) || (g.type == GeneratorSpec::Type::Cloud && !g.points_file.empty());
}

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
    /// Materials with history: the stabilization stresses' loads (MSCNI sub-cells, NSNI
    /// sub-points) take the share of the step the parent point's material took elastically
    /// (assumed_strain_tangent_share), so a point that flows or softens stores no elastic
    /// stabilization energy its material cannot hold; unloads give back what was stored
    /// (scaled_hourglass_update). LS-DYNA's IHQ 6 scales its hourglass stiffness the same way.
    bool plastic_scaling = false;
};
} // namespace rkfem
