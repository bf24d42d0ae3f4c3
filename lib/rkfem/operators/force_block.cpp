#include "rkfem/operators/force_block.hpp"

#include <algorithm>
#include <sstream>

#include "rkfem/operators/nodal_force.hpp"

namespace rkfem
{
namespace
{
/// What is wrong with an element the force pass flagged, given its whole volume
std::string bad_volume(real_t volume)
{
    std::ostringstream os;
    os << "has ";
    if (volume > 0.0) // its volume is positive: one of its integration points is not
        os << "a non-positive Jacobian at an integration point (its volume " << volume << " m^3 in all)";
    else if (volume <= 0.0)
        os << "non-positive volume " << volume << " m^3";
    else
        os << "a NaN volume";
    return os.str();
}

/// The Gauss-point pass over a hex block and its forces into f_int
ForcePassResult hex_pass(HexBlock& block, NodeSet& nodes, real_t dt, bool add)
{
    const ForcePassResult r = hex_internal_force(block, nodes, dt);
    if (r.bad_element < 0)
        assemble_block_forces(block, nodes, add);
    return r;
}
} // namespace

ForcePassResult HexForceBlock::add_forces(NodeSet& nodes, real_t dt, bool add)
{
    return hex_pass(block_, nodes, dt, add);
}

PointFault HexForceBlock::fault(index_t bad, const NodeSet& nodes) const
{
    return {false, bad, -1, bad_volume(element_volume(block_, nodes, bad))};
}

void FeSideForceBlock::reset(FeSide side)
{
    side_ = std::move(side);
    const HexBlock& block = side_.block;
    const std::vector<index_t>& local = side_.local;
    part_of_.assign(static_cast<std::size_t>(block.n_elements()), static_cast<index_t>(local.size()));
    for (std::size_t e = local.size(); e-- > 0;) // the first part element that maps to it
        if (local[e] >= 0 && local[e] < block.n_elements())
            part_of_[static_cast<std::size_t>(local[e])] = static_cast<index_t>(e);
}

ForcePassResult FeSideForceBlock::add_forces(NodeSet& nodes, real_t dt, bool add)
{
    return hex_pass(side_.block, nodes, dt, add);
}

index_t FeSideForceBlock::part_element(index_t block_element) const
{
    if (block_element < 0)
        return 0;
    return block_element < static_cast<index_t>(part_of_.size()) ? part_of_[static_cast<std::size_t>(block_element)]
                                                                 : static_cast<index_t>(part_of_.size());
}

PointFault FeSideForceBlock::fault(index_t bad, const NodeSet& nodes) const
{
    return {false, part_element(bad), -1, bad_volume(element_volume(side_.block, nodes, bad))};
}

ForcePassResult NodalForceBlock::add_forces(NodeSet& nodes, real_t dt, bool add)
{
    if (block_.n_points() == 0) // a converting fem-1pt part before its first event
    {
        if (!add)
            std::fill(nodes.f_int.begin() + 3 * static_cast<std::ptrdiff_t>(block_.node_begin),
                      nodes.f_int.begin() + 3 * static_cast<std::ptrdiff_t>(block_.node_end), 0.0);
        return {};
    }
    const ForcePassResult r = nodal_internal_force(block_, nodes, dt);
    if (r.bad_element < 0)
        assemble_nodal_forces(block_, nodes, add);
    return r;
}

PointFault NodalForceBlock::fault(index_t bad, const NodeSet&) const
{
    const real_t j = block_.jacobian[static_cast<std::size_t>(bad)];
    std::ostringstream os;
    os << "has " << (j > 0.0 ? "a NaN deformation (det F = " : "non-positive det F = ") << j << (j > 0.0 ? ")" : "");
    return {true, -1, block_.points.owner[static_cast<std::size_t>(bad)], os.str()};
}
} // namespace rkfem
