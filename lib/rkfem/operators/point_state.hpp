#pragma once
/// @file point_state.hpp
/// The material state of a block's integration points, seen the same way for every block kind:
/// the committed and trial stress (component-major with a stride) and the history of the
/// point's model. State moves between blocks through it (an FE element's points to the RK
/// particles that replace it), and within a block by gather (removed points).
#include <vector>

#include "rkfem/materials/point_history.hpp"
#include "rkfem/operators/hex_block.hpp"
#include "rkfem/operators/nodal_block.hpp"

namespace rkfem
{
struct PointState
{
    real_t* stress = nullptr;       ///< committed, component k of point p at [k stride + p]
    real_t* stress_trial = nullptr; ///< trial, same layout
    std::size_t stride = 0;
    PlasticPoints* history = nullptr; ///< null or inactive for elastic blocks
    std::size_t n_points = 0;
};

inline PointState point_state(HexBlock& b)
{
    return {b.stress.data(), b.stress_trial.data(), b.stress_stride, &b.plastic,
            static_cast<std::size_t>(b.n_points())};
}
inline PointState point_state(NodalBlock& b)
{
    return {b.stress.data(), b.stress_trial.data(), b.stress_stride, &b.plastic,
            static_cast<std::size_t>(b.n_points())};
}

/// Point `to` of dst takes the committed stress and history of point `from` of src (trial =
/// committed). The two blocks must have the same material model.
void copy_point_state(const PointState& src, std::size_t from, const PointState& dst, std::size_t to);
} // namespace rkfem
