#pragma once
/// @file analysis_detail.hpp
/// What the measures along a line (impact.hpp, spall.hpp) share: a part by name, a node's
/// reference position, and the tolerance a node lies on a plane or line within.
#include <string>

#include "rkfem/model/model.hpp"

namespace rkfem::analysis_detail
{
/// The index of the part named `name` (-1: none).
inline index_t part_index(const Model& m, const std::string& name)
{
    for (std::size_t i = 0; i < m.parts.size(); ++i)
        if (m.parts[i].name == name)
            return static_cast<index_t>(i);
    return -1;
}

/// Node i's reference position.
inline Vec3 reference(const Model& m, index_t i)
{
    return {m.nodes.x0[3 * i], m.nodes.x0[3 * i + 1], m.nodes.x0[3 * i + 2]};
}

/// 1e-6 of the part's size (its nodes' bounding box's diagonal, reference).
inline real_t on_line_tolerance(const Model& m, index_t part)
{
    const PartInfo& p = m.parts[static_cast<std::size_t>(part)];
    Vec3 lo = Vec3::Constant(kNoLimit), hi = Vec3::Constant(-kNoLimit);
    for (index_t i = p.node_begin; i < p.mesh_node_end; ++i) // not a refining part's pool
    {
        lo = lo.cwiseMin(reference(m, i));
        hi = hi.cwiseMax(reference(m, i));
    }
    return 1e-6 * (hi - lo).norm();
}
} // namespace rkfem::analysis_detail
