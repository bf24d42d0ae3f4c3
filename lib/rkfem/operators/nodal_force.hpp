#pragma once
/// @file nodal_force.hpp
/// The force pass of a nodal block (nodal_block.hpp): per stress point F, Fdot, L, the material
/// update and V0 P, scattered to the nodes in a fixed order; the MSCNI stabilization; assembly
/// into f_int.
#include "rkfem/discretization/node_set.hpp"
#include "rkfem/operators/hex_block.hpp"
#include "rkfem/operators/nodal_block.hpp"

namespace rkfem
{
/// Internal force pass (material update into trial state, per-point tensors); assembly is
/// separate (assemble_nodal_forces). d_hourglass carries the stabilization work. `u`: the
/// displacements F is formed from (3 per node, indexed by global node id), nodes.u where null
/// (a block with reference resets passes those since its last reset).
ForcePassResult nodal_internal_force(NodalBlock& blk, const NodeSet& nodes, real_t dt, const real_t* u = nullptr);

/// f_int[node] = sum over the node's entries, for the block's node range. Once per force pass:
/// with the chunked scatter it consumes the chunk sums (ChunkedScatter::reduce). With `add` the
/// sums are added to f_int (assemble_block_forces).
void assemble_nodal_forces(NodalBlock& blk, NodeSet& nodes, bool add = false);
} // namespace rkfem
