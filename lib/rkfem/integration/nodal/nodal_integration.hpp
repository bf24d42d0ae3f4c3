#pragma once
/// @file nodal_integration.hpp
/// Builders of nodal integration operators on the conforming hex-dual cells (hex_dual_cells.hpp;
/// Beissel & Belytschko 1996, CMAME 139; Chen, Wu, Yoon & You 2001, IJNME 50; review: Chen,
/// Hillman & Chi 2017, J Eng Mech 143), for any ShapeEvaluator:
///   DNI     one point per node, gradient grad Psi_I(x_L) (negative control: fails the patch test
///           on irregular clouds and has spurious zero-energy modes);
///   SCNI    one point per node, smoothed gradient b_I(L) = (1/V_L) int_{dOmega_L} Psi_I n dA;
///   SD-SCNI one point per sub-hex (node, element), smoothed over the sub-hex;
///   MSCNI   stabilization operator: one sub-point per sub-hex with gradient b_I(s) - b_I(L) and
///           parent = the SCNI point of its node (Puso, Chen, Zywicz & Elmer 2008);
///   NSNI    stabilization operator (the naturally stabilized term of Hillman & Chen 2016 on SCNI
///           points, RK shapes): three sub-points per node, one per direction i, with gradient
///           d/dx_i grad Psi_I(x_L) and weight M_iL = int_{Omega_L} (x_i - x_Li)^2 dOmega.
/// Points of DNI/SCNI are in node order (point p belongs to node p); SD-SCNI and MSCNI points are
/// in element order, 8 e + a. Positions and gradients are in the mesh's (reference) configuration.
#include <vector>

#include "rkfem/approximation/rk/rk_translates.hpp"
#include "rkfem/approximation/shape_evaluator.hpp"
#include "rkfem/discretization/voronoi_cells.hpp"
#include "rkfem/integration/integration_operator.hpp"
#include "rkfem/integration/nodal/hex_dual_cells.hpp"
#include "rkfem/integration/stencil_table.hpp"

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
/// SCNI and, when sd is not null, SD-SCNI in one pass that evaluates the shapes once per facet
/// point of every sub-hex (build_scni evaluates the facets of the nodal cells' boundaries again):
/// the same entries, bit for bit, as build_scni and build_sd_scni, about two thirds of their
/// evaluations. MSCNI (build_mscni_stabilization) needs both.
void build_scni_sd(const HexMesh& mesh, const ShapeEvaluator& shapes, IntegrationOperator& scni,
                   IntegrationOperator* sd);
/// SCNI of RK functions on a mesh's nodal cells: the operator of build_scni with
/// RkShapes(rk, drop_tolerance), to round-off, built by elements. Each element gathers the
/// particles near it once (RkRegionValues) and evaluates each of its facet points once, for
/// both nodal cells an internal facet bounds (build_scni, node by node, evaluates it from each
/// side). Elements of one colour share no node, so they add into their nodes' rows in parallel,
/// colour after colour: the rows are the same bits on any number of threads.
/// With sd, also the SD-SCNI sub-cells that MSCNI needs (build_scni_sd's sd, to round-off): every
/// sub-hex facet point once, the external facets inside the body for the sub-cells alone.
/// With share_translates, an element whose shape, boundary faces and particles around it are a
/// translate of an earlier element's (rk_translates.hpp: the layers of an extruded mesh, the
/// interior of a structured block) takes that element's facet sums instead of evaluating its
/// own; without, every element evaluates its own (the plain build: each element's sums as the
/// shared build computes its sources'). One progress count per element.
/// With `shared`, the rows go straight into shared stencils (StencilSharer, share_stencils'
/// classes) where sharing pays: the operator then comes back without entries (offsets, weights,
/// positions and owners only) and *shared holds them, the table share_stencils would find on
/// the whole operator. Where sharing does not pay, *shared is empty and the operator whole.
IntegrationOperator build_scni_rk(const HexMesh& mesh, const RkShapeFunctions& rk, real_t drop_tolerance,
                                  IntegrationOperator* sd = nullptr, bool share_translates = true,
                                  StencilTable* shared = nullptr);

/// Greedy colouring of a mesh's elements: no two elements that share a node have one colour.
/// Returns the elements by colour as CSR (colour c: elements[offsets[c] .. offsets[c + 1]),
/// ascending), with as few colours as the greedy order finds (8 on a structured mesh).
void colour_elements(const HexMesh& mesh, std::vector<index_t>& offsets, std::vector<index_t>& elements);

IntegrationOperator build_nodal(NodalScheme scheme, const HexMesh& mesh, const ShapeEvaluator& shapes);

/// SCNI on the cells of a cloud that does not come from a mesh (Voronoi cells clipped to the
/// body, discretization/voronoi_cells.hpp); x: particle positions. RK shapes only (element-free).
IntegrationOperator build_scni_cells(const VoronoiCells& cells, const std::vector<real_t>& x,
                                     const ShapeEvaluator& shapes);

/// The same for RK functions (build_scni_cells with RkShapes(rk, drop_tolerance), to round-off):
/// each cell gathers the particles near it once (RkRegionValues) and sums its facet points over
/// them in flat arrays, `block` cells at a time. A face between two cells at most `block` apart
/// in the particle order is evaluated once, by the first, which hands its sums to the second
/// (the second evaluates it where the first has no such face); faces of cells farther apart are
/// evaluated from both sides.
IntegrationOperator build_scni_cells_rk(const VoronoiCells& cells, const std::vector<real_t>& x,
                                        const RkShapeFunctions& rk, real_t drop_tolerance, index_t block = 2048);

/// Sub-cell smoothing on the pyramids of a cloud's Voronoi cells (VoronoiCells::sub_cells): one
/// point per sub-cell, owner = its cell's particle; the SD operator that MSCNI stabilizes with.
IntegrationOperator build_sd_cells(const VoronoiCells& cells, const ShapeEvaluator& shapes);

/// DNI on a cloud: one point per particle with weight volume[i] and gradient grad Psi_I(x_i).
IntegrationOperator build_dni_cells(const std::vector<real_t>& volume, const std::vector<real_t>& x,
                                    const ShapeEvaluator& shapes);

/// MSCNI stabilization from an SCNI operator and the SD-SCNI operator of the same mesh.
IntegrationOperator build_mscni_stabilization(const IntegrationOperator& scni, const IntegrationOperator& sd);

/// The NSNI stabilization of node-ordered points (point p at particle p, as build_scni and
/// build_scni_cells make them): sub-point 3 p + i has parent p, weight moments[3 p + i] and the
/// entries (J, d/dx_i grad Psi_J(x_p)) (RkShapeFunctions::hessians). Its strain is the gradient
/// of the strain along x_i, so for linear fields it vanishes (patch test kept) and its
/// quadratic form sum_i M_i eps_,i : C : eps_,i stiffens the modes SCNI leaves soft. Entries
/// cover the particles around x_p only (27 on a lattice with support 1.51 h), about a fifth of
/// MSCNI's (8 sub-cells of about 125 entries).
/// With drop_tolerance > 0 the second derivatives go through prune_rk_hessians. A point whose
/// particle's neighbourhood is a translate of an earlier particle's (particle_translates)
/// takes that point's matrices instead of evaluating its own; with share_translates false every
/// point evaluates its own.
IntegrationOperator build_nsni_stabilization(const IntegrationOperator& points, const RkShapeFunctions& rk,
                                             const std::vector<real_t>& moments, real_t drop_tolerance = 0.0,
                                             bool share_translates = true);
/// The same with the particles' translates given (particle_translates(rk)); the points must be
/// node-ordered (point p at particle p).
IntegrationOperator build_nsni_stabilization(const IntegrationOperator& points, const RkShapeFunctions& rk,
                                             const std::vector<real_t>& moments, real_t drop_tolerance,
                                             const RkTranslates& particles);

/// NSNI as a compact block keeps it (NodalBlock::stab_in_triplets): the sub-points' frame (the
/// operator's offsets, weights, owners and parents; no positions, nodes or gradients) and their
/// triplets (integration/stencil_table.hpp: per point one stencil of nodes and six Hessian
/// values per entry), the same numbers as build_nsni_stabilization's entries. One stencil per
/// source particle, which its translates read from their own first node where their particles
/// are the source's plus one number (a mesh numbered along the translation), then stencils whose
/// offsets agree and whose values agree within the sharing's tolerance merged (share_triplets):
/// the 172 MB of sub-point entries of P1 at 0.25 in are never formed.
struct NsniTriplets
{
    IntegrationOperator frame;
    TripletTable table;
};
NsniTriplets build_nsni_triplets(const IntegrationOperator& points, const RkShapeFunctions& rk,
                                 const std::vector<real_t>& moments, real_t drop_tolerance,
                                 const RkTranslates& particles);

/// The particles of rk grouped into translates (rk_translates.hpp) by their neighbourhoods:
/// particle p's region is the particles whose supports reach the box x_p -+
/// RkRegionValues::hessian_reach(), the particles NSNI's second derivatives at x_p read (and
/// a superset of those that cover x_p). With share false, every particle is its own source.
RkTranslates particle_translates(const RkShapeFunctions& rk, bool share = true);

/// Second moments of the nodal (hex-dual) cells about their nodes, 3 per node:
/// M_iL = int_{Omega_L} (x_i - X_Li)^2 dOmega, by 2 x 2 x 2 Gauss points on each sub-hex (exact
/// on parallelepiped elements).
std::vector<real_t> nodal_second_moments(const HexMesh& mesh);
/// Its plain twin, Gauss point by Gauss point: the same moments to round-off.
std::vector<real_t> nodal_second_moments_plain(const HexMesh& mesh);

/// Second moments of cells known by their volume only (Voronoi cells of a cloud), as cubes of
/// the same volume centred on the particle: M_i = V s^2 / 12, s = V^(1/3).
std::vector<real_t> cube_second_moments(const std::vector<real_t>& volume);

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
