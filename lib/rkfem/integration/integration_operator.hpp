#pragma once
/// @file integration_operator.hpp
/// What every integration scheme produces (docs/architecture.md): a list of
/// integration points, each with a weight (reference volume), a position, the node that owns it,
/// and the nodes it touches with one gradient vector per node, as CSR. The force loop, the
/// material update and the stepper never ask which scheme built it.
///
/// Entries of point p are [offsets[p], offsets[p + 1]); entry k touches node nodes[k] with
/// gradient (grad[3k], grad[3k + 1], grad[3k + 2]). Nodes within a point are ascending.
#include <vector>

#include "rkfem/core/types.hpp"

namespace rkfem
{
struct IntegrationOperator
{
    std::vector<real_t> weight;   ///< n_points, reference volume [m^3]
    std::vector<real_t> position; ///< n_points x 3, reference position of the point [m]
    std::vector<index_t> owner;   ///< n_points, node that owns the point's state (-1: none)
    std::vector<index_t> parent;  ///< stabilization operators: point stabilized (else empty)
    std::vector<index_t> offsets{0};
    std::vector<index_t> nodes;
    std::vector<real_t> grad; ///< 3 per entry [1/m]

    index_t n_points() const { return static_cast<index_t>(weight.size()); }
    index_t n_entries() const { return static_cast<index_t>(nodes.size()); }
    Vec3 gradient(index_t k) const { return {grad[3 * k], grad[3 * k + 1], grad[3 * k + 2]}; }
    Vec3 point(index_t p) const { return {position[3 * p], position[3 * p + 1], position[3 * p + 2]}; }

    /// Appends the operator `other` (points, entries), shifting its parent indices.
    void append(const IntegrationOperator& other);
};

/// A table that lives as long as its block (an entry index and its values, reserved together
/// from an estimate by its builder) returns its spare room where that passes 1/16 of its
/// entries: a copy, so not for the last few percent (the builders reserve about that margin).
template <class I, class V> void return_spare_room(std::vector<I>& index, std::vector<V>& values)
{
    if (index.capacity() > index.size() + index.size() / 16)
    {
        index.shrink_to_fit();
        values.shrink_to_fit();
    }
}
} // namespace rkfem
