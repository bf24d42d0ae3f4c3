#include "rkfem/integration/stencil_table.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>

namespace rkfem
{
namespace
{
/// FNV-1a over the entry count and the node offsets of a stencil.
std::uint64_t offsets_hash(const index_t* nodes, index_t size)
{
    std::uint64_t h = 1469598103934665603ull;
    auto mix = [&](std::uint32_t x)
    {
        h ^= x;
        h *= 1099511628211ull;
    };
    mix(static_cast<std::uint32_t>(size));
    for (index_t k = 1; k < size; ++k)
        mix(static_cast<std::uint32_t>(nodes[k] - nodes[0]));
    return h;
}
} // namespace

StencilTable share_stencils(IntegrationOperator& op, const StencilSharing& opts)
{
    const index_t np = op.n_points();
    StencilTable t;
    if (np == 0)
        return t;
    t.point_stencil.resize(static_cast<std::size_t>(np));
    t.point_base.resize(static_cast<std::size_t>(np));
    std::unordered_map<std::uint64_t, std::vector<index_t>> by_offsets;
    std::vector<real_t> scale; // per stored stencil: its largest |gradient component|
    const std::size_t budget = static_cast<std::size_t>(opts.max_entry_fraction * static_cast<real_t>(op.n_entries()));

    for (index_t p = 0; p < np; ++p)
    {
        const index_t k0 = op.offsets[static_cast<std::size_t>(p)];
        const index_t n = op.offsets[static_cast<std::size_t>(p) + 1] - k0;
        const index_t* nodes = op.nodes.data() + k0;
        const real_t* g = op.grad.data() + 3 * static_cast<std::size_t>(k0);
        t.point_base[static_cast<std::size_t>(p)] = n > 0 ? nodes[0] : 0;
        std::vector<index_t>& candidates = by_offsets[offsets_hash(nodes, n)];
        // does stored stencil s have this point's node offsets and, within the tolerance of
        // its largest gradient, its gradients? (written so that a NaN on either side differs)
        auto matches = [&](index_t s)
        {
            const index_t j0 = t.offsets[static_cast<std::size_t>(s)];
            if (t.offsets[static_cast<std::size_t>(s) + 1] - j0 != n)
                return false;
            for (index_t k = 1; k < n; ++k)
                if (t.node_offset[static_cast<std::size_t>(j0 + k)] != nodes[k] - nodes[0])
                    return false;
            const real_t* gs = t.grad.data() + 3 * static_cast<std::size_t>(j0);
            const real_t bound = opts.relative_tolerance * scale[static_cast<std::size_t>(s)];
            for (index_t k = 0; k < 3 * n; ++k)
                if (!(std::abs(gs[k] - g[k]) <= bound))
                    return false;
            return true;
        };
        index_t found = -1;
        const int searched = std::min<int>(static_cast<int>(candidates.size()), opts.max_candidates);
        for (int c = 0; c < searched && found < 0; ++c)
            if (matches(candidates[static_cast<std::size_t>(c)]))
                found = candidates[static_cast<std::size_t>(c)];
        if (found < 0)
        {
            found = t.n_stencils();
            for (index_t k = 0; k < n; ++k)
                t.node_offset.push_back(nodes[k] - nodes[0]);
            t.grad.insert(t.grad.end(), g, g + 3 * n);
            t.offsets.push_back(static_cast<index_t>(t.node_offset.size()));
            real_t largest = 0.0;
            for (index_t k = 0; k < 3 * n; ++k)
                largest = std::max(largest, std::abs(g[k]));
            scale.push_back(largest);
            candidates.push_back(found);
            if (t.node_offset.size() > budget)
                return {}; // sharing does not pay: the operator stays as it was
        }
        t.point_stencil[static_cast<std::size_t>(p)] = found;
    }

    // snap: every point takes its stencil's gradients
    for (index_t p = 0; p < np; ++p)
    {
        const StencilView s = t.view(p);
        std::copy(s.grad, s.grad + 3 * s.size, op.grad.begin() + 3 * static_cast<std::ptrdiff_t>(op.offsets[p]));
    }
    return t;
}
} // namespace rkfem
