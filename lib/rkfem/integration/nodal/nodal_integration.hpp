#pragma once
/// @file nodal_integration.hpp
/// Builders of nodal integration operators on the conforming hex-dual cells
/// (../shared/reference/rkpm-methods.md sections 2.2-2.5), for any ShapeEvaluator:
///   DNI     one point per node, gradient grad Psi_I(x_L) (negative control: fails the patch test
///           on irregular clouds and has spurious zero-energy modes);
///   SCNI    one point per node, smoothed gradient b_I(L) = (1/V_L) int_{dOmega_L} Psi_I n dA;
///   SD-SCNI one point per sub-hex (node, element), smoothed over the sub-hex;
///   MSCNI   stabilization operator: one sub-point per sub-hex with gradient b_I(s) - b_I(L) and
///           parent = the SCNI point of its node (Puso, Chen, Zywicz & Elmer 2008).
/// Points of DNI/SCNI are in node order (point p belongs to node p); SD-SCNI and MSCNI points are
/// in element order, 8 e + a. Positions and gradients are in the mesh's (reference) configuration.
#include <vector>

#include "rkfem/approximation/shape_evaluator.hpp"
#include "rkfem/integration/integration_operator.hpp"
#include "rkfem/discretization/voronoi_cells.hpp"
#include "rkfem/integration/nodal/hex_dual_cells.hpp"

namespace rkfem
{
enum class NodalScheme
{
    Dni,
    Scni,
    SdScni,
};

IntegrationOperator build_dni(const HexMesh& mesh, const ShapeEvaluator& shapes);
IntegrationOperator build_scni(const HexMesh& mesh, const ShapeEvaluator& shapes);
IntegrationOperator build_sd_scni(const HexMesh& mesh, const ShapeEvaluator& shapes);
IntegrationOperator build_nodal(NodalScheme scheme, const HexMesh& mesh, const ShapeEvaluator& shapes);

/// SCNI on the cells of a cloud that does not come from a mesh (Voronoi cells clipped to the
/// body, discretization/voronoi_cells.hpp); x: particle positions. RK shapes only (element-free).
IntegrationOperator build_scni_cells(const VoronoiCells& cells, const std::vector<real_t>& x,
                                     const ShapeEvaluator& shapes);

/// Sub-cell smoothing on the pyramids of a cloud's Voronoi cells (VoronoiCells::sub_cells): one
/// point per sub-cell, owner = its cell's particle; the SD operator that MSCNI stabilizes with.
IntegrationOperator build_sd_cells(const VoronoiCells& cells, const ShapeEvaluator& shapes);

/// DNI on a cloud: one point per particle with weight volume[i] and gradient grad Psi_I(x_i).
IntegrationOperator build_dni_cells(const std::vector<real_t>& volume, const std::vector<real_t>& x,
                                    const ShapeEvaluator& shapes);

/// MSCNI stabilization from an SCNI operator and the SD-SCNI operator of the same mesh.
IntegrationOperator build_mscni_stabilization(const IntegrationOperator& scni, const IntegrationOperator& sd);

/// Facet quadrature of the mesh boundary (external facets of sub-hexes on boundary faces):
/// the boundary integral that IC1 balances and that tractions use.
struct BoundaryPoint
{
    index_t element = 0;
    index_t node = 0; ///< owner of the sub-hex the facet belongs to
    FacetPoint point;
};
std::vector<BoundaryPoint> boundary_quadrature(const HexMesh& mesh);

/// Nodal cell volumes V_L = sum of the node's sub-hex volumes.
std::vector<real_t> nodal_volumes(const HexMesh& mesh);
} // namespace rkfem
