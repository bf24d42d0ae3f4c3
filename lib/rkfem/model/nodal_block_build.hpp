#pragma once
/// @file nodal_block_build.hpp
/// Nodal blocks from deck parts: fem-nodal and rkpm parts on meshes, cloud parts on Voronoi
/// cells, coupled FE-RK parts; their lumped mass.
#include <memory>
#include <vector>

#include "rkfem/config/deck.hpp"
#include "rkfem/discretization/hex_mesh.hpp"
#include "rkfem/discretization/node_set.hpp"
#include "rkfem/discretization/voronoi_cells.hpp"
#include "rkfem/operators/nodal_block.hpp"

namespace rkfem
{
/// The RK approximation settings of a deck's `rk` section.
RkParams rk_params(const RkSpec& spec);

/// Builds the block of a fem-nodal or rkpm part from its mesh (local numbering; node ids are
/// shifted by `offset`): approximation, nodal integration, stabilization, RK interpolation at
/// the nodes. A singular RK moment matrix becomes a DeckError naming rk.normalized_support.
NodalBlock build_nodal_block(const PartSpec& ps, const HexMesh& mesh, index_t offset);

/// Per element of a part's mesh: 1 if its centroid lies in one of the part's RK regions.
std::vector<char> rk_region_elements(const PartSpec& ps, const HexMesh& mesh);
/// Is point c inside region r (box, within radius of a cylinder's axis, sphere)?
bool inside_region(const SelectorSpec& r, const Vec3& c);

/// Builds the block of a coupled FE-RK part (a fem-nodal part with regions or conversion): the
/// mixed or ramp approximation of approximation/coupling/coupled_shapes.hpp over the whole mesh,
/// SCNI on its node-dual cells (+ MSCNI), physical values at the nodes (identity at FE nodes).
/// `rk_elements` (per element, 1: RK) overrides the part's regions: a conversion event's set,
/// which may hold no element (all FE) or every element. With a fem-nodal FE side the points
/// (one per node, then MSCNI's sub-cells) and their weights do not depend on the set, so a
/// block rebuilt for another set takes over the state of the old one point for point.
/// `scales`: the K&C crack-band scales the block's points take up (a converting part's, shared
/// by the blocks it builds again at each event; null: the block's own).
NodalBlock build_coupled_block(const PartSpec& ps, const HexMesh& mesh, index_t offset,
                               const std::vector<char>* rk_elements = nullptr,
                               std::shared_ptr<KccScaleCache> scales = nullptr);

/// A coupled block (fem-nodal FE side, built by build_coupled_block for `rk_old`) brought to the
/// RK set `rk_new` in place, where the approximation changed only: elements whose kind changes
/// and elements of the transition and RK regions that the support of a particle that appears,
/// disappears or changes its radius reaches (both radii). The points of the nodes of those
/// elements (SCNI), and their MSCNI sub-cells, are built again on the sub-mesh of every element
/// around them (so their cells are whole) and take the place of the old ones; the other points
/// keep their entries. The same operators as a whole rebuild (verification/operators/
/// test_conversion). Material state is not touched; tables are rebuilt (NodalBlock::build_tables).
/// Returns the nodes (local) whose physical-value rows changed, with those rows (CSR over the
/// returned nodes; columns global); the block's particle and fe_element flags are updated.
struct ChangedRows
{
    std::vector<index_t> node;
    std::vector<index_t> offsets{0};
    std::vector<index_t> columns;
    std::vector<real_t> values;
};
ChangedRows update_coupled_block(const PartSpec& ps, const HexMesh& mesh, index_t offset,
                                 const std::vector<char>& rk_old, const std::vector<char>& rk_new, NodalBlock& nb);

/// Per element of a coupled block with a fem-1pt FE side: its rank among the transition and RK
/// elements (fe_element 0), whose MSCNI sub-cells are 8 rank + corner; -1 for FE elements.
std::vector<index_t> coupled_sub_cell_ranks(const std::vector<char>& fe_element);

/// The nodal block of a coupled part with a fem-1pt FE side (`old`, built by build_coupled_block
/// for `rk_old`) for the RK set `rk_new`, built where the approximation changed only: the nodes
/// update_coupled_block rebuilds (those of elements whose kind changes or that a changed
/// particle's support reaches) take new SCNI rows and MSCNI sub-cells, built on the sub-mesh of
/// the transition and RK elements around them; every other point and sub-cell takes its row
/// from `old`. The points come in build_coupled_block's order (one per node of the transition
/// and RK elements, in the order the elements first name them), with the same operators to
/// round-off (verification/operators/test_conversion). A new block: zero stress, fresh history,
/// crack bands set (through `scales`, as build_coupled_block); `old` is not touched. `rows`
/// gets the physical-value rows of the nodes whose rows changed, as update_coupled_block
/// returns them. `rk_new` holds an RK element (an all-FE set is build_coupled_block's).
NodalBlock update_fe_side_block(const PartSpec& ps, const HexMesh& mesh, index_t offset,
                                const std::vector<char>& rk_old, const std::vector<char>& rk_new, const NodalBlock& old,
                                ChangedRows& rows, std::shared_ptr<KccScaleCache> scales = nullptr);

/// The convex body a cloud part's Voronoi cells are clipped to: its box, or the prism of planes
/// tangent to its cylinder (at least 128, about 8 pi radius / mean spacing of n_particles).
std::vector<HalfSpace> cloud_body(const GeneratorSpec& g, index_t n_particles);

/// Builds the block of a cloud part (generator type cloud; rkpm only): Voronoi cells of the
/// particles clipped to the body (cloud_body), RK support a_I = normalized_support x the longest distance
/// to a neighbour across a facet of at least 10% of the cell's largest, SCNI on the cells (or
/// DNI with the cell volumes) with optional MSCNI on the cells' pyramids (VoronoiCells::
/// sub_cells), stable-step length l0 = that same distance, crack band
/// = V^(1/3). Throws DeckError for coincident particles or a singular moment matrix.
NodalBlock build_cloud_block(const PartSpec& ps, const HexMesh& cloud, index_t offset);

/// Lumped mass rho V0_p to each point's owner node.
void add_nodal_mass(const NodalBlock& blk, NodeSet& nodes);
} // namespace rkfem
