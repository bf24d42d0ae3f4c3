#pragma once
/// @file force_block.hpp
/// The one interface through which the step sees an integration block: a pass over its points
/// that updates their material state (trial) and adds the block's nodal forces into f_int, the
/// commit of that state, and where a point the pass flagged sits, for the message.
///
/// Four implementations: a block of Gauss-point hexes (fem-1pt, fem-2x2x2; the part's mesh block,
/// which the model owns), a nodal block (fem-nodal, rkpm, the nodal side of a coupled part) and a
/// coupled part's fem-1pt FE side (a hex block over some of the part's elements); the last two own
/// their block. The model keeps them in one list in the order of the parts (for each part its
/// nodal block, then its FE side), so its force evaluation and commit are loops over that list.
/// The fourth, semi-Lagrangian RK particles (semi_lagrangian_block.hpp), takes a nodal block's
/// place in that list.
///
/// Invariants: a pass either returns a bad point (bad_element >= 0) and leaves f_int as it was,
/// or adds (writes, when the block is alone on its nodes: `add` false) every node of its range.
/// A block never touches another block's state; blocks share nodes only through f_int.
#include <string>
#include <utility>
#include <vector>

#include "rkfem/discretization/node_set.hpp"
#include "rkfem/operators/hex_block.hpp"
#include "rkfem/operators/nodal_block.hpp"

namespace rkfem
{
/// Where a point a force pass flagged sits: an element of the part (part-local index) or the
/// stress point of a node (global id); `what` says what is wrong ("has non-positive volume ...").
struct PointFault
{
    bool at_node = false;
    index_t element = -1; ///< part-local element (at_node false)
    index_t node = -1;    ///< global node id (at_node true)
    std::string what;
};

class ForceBlock
{
  public:
    virtual ~ForceBlock() = default;
    /// The force pass over the block's points: material update into trial state, the block's
    /// nodal forces into nodes.f_int over its node range (added with `add`, written otherwise).
    /// On a bad point (bad_element >= 0) it returns before touching f_int.
    virtual ForcePassResult add_forces(NodeSet& nodes, real_t dt, bool add) = 0;
    /// Trial state becomes committed state.
    virtual void commit() = 0;
    /// The part-local element of an element index a pass returned (dt_element), for messages and
    /// the step's controlling element; nodal blocks name the part's first element.
    virtual index_t part_element(index_t block_element) const = 0;
    /// What is wrong at the point a pass returned as bad_element.
    virtual PointFault fault(index_t bad, const NodeSet& nodes) const = 0;
    /// The state of a block whose points sit at nodes (nodal and semi-Lagrangian blocks: one
    /// NodalBlock, which output, probes and checkpoints read); null for Gauss-point blocks.
    virtual NodalBlock* nodal_points() { return nullptr; }
    virtual const NodalBlock* nodal_points() const { return nullptr; }
};

/// Gauss-point hexes: hex_internal_force and assemble_block_forces over one HexBlock, the part's
/// mesh block (Model::meshes), which the model owns: the part's mesh and its integration are one
/// object for fem-1pt and fem-2x2x2 parts.
class HexForceBlock final : public ForceBlock
{
  public:
    explicit HexForceBlock(HexBlock& block) : block_(block) {}
    ForcePassResult add_forces(NodeSet& nodes, real_t dt, bool add) override;
    void commit() override { block_.commit(); }
    index_t part_element(index_t block_element) const override { return block_element; }
    PointFault fault(index_t bad, const NodeSet& nodes) const override;

  private:
    HexBlock& block_;
};

/// A coupled part's fem-1pt FE side: a 1-point block over the part's FE elements (local maps a
/// part element to the block's, -1 where the element is not FE), integrated beside the part's
/// nodal block, whose nodes it shares.
struct FeSide
{
    HexBlock block;
    std::vector<index_t> local; ///< element of the part -> element of `block`, -1 if not FE
};

/// The FE side's Gauss-point pass, with the block's elements named by the part's. It owns the side.
class FeSideForceBlock final : public ForceBlock
{
  public:
    explicit FeSideForceBlock(FeSide side) { reset(std::move(side)); }
    /// A new side (a conversion event changed the part's FE elements).
    void reset(FeSide side);
    ForcePassResult add_forces(NodeSet& nodes, real_t dt, bool add) override;
    void commit() override { side_.block.commit(); }
    index_t part_element(index_t block_element) const override;
    PointFault fault(index_t bad, const NodeSet& nodes) const override;
    FeSide& side() { return side_; }
    const FeSide& side() const { return side_; }

  private:
    FeSide side_;
    std::vector<index_t> part_of_; ///< block element -> part element (the inverse of local)
};

/// Points at nodes (fem-nodal, rkpm, a coupled part's nodal side): nodal_internal_force and
/// assemble_nodal_forces over the NodalBlock it owns.
class NodalForceBlock final : public ForceBlock
{
  public:
    explicit NodalForceBlock(NodalBlock block) : block_(std::move(block)) {}
    ForcePassResult add_forces(NodeSet& nodes, real_t dt, bool add) override;
    void commit() override { block_.commit(); }
    index_t part_element(index_t) const override { return 0; }
    PointFault fault(index_t bad, const NodeSet& nodes) const override;
    NodalBlock* nodal_points() override { return &block_; }
    const NodalBlock* nodal_points() const override { return &block_; }
    NodalBlock& nodal() { return block_; }
    const NodalBlock& nodal() const { return block_; }

  private:
    NodalBlock block_;
};
} // namespace rkfem
