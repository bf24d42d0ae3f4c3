// Events between steps that change the discretization (erosion), and the assembly plan
// they keep up to date.
#include "rkfem/model/model.hpp"

#include <algorithm>

#include "rkfem/core/error.hpp"

namespace rkfem
{
void Model::remove_elements(index_t block, const std::vector<char>& keep)
{
    RKFEM_REQUIRE(block >= 0 && block < static_cast<index_t>(blocks.size()), "remove_elements: no block " << block);
    RKFEM_REQUIRE(part_nodal[block] < 0, "remove_elements: part '" << parts[block].name
                                                                   << "' is integrated at its nodes; only Gauss-point "
                                                                      "FE parts lose elements");
    eroded_.resize(blocks.size());
    ErodedElements& gone = eroded_[static_cast<std::size_t>(block)];
    const HexBlock& blk = blocks[block];
    for (index_t e = 0; e < blk.n_elements(); ++e)
        if (!keep[static_cast<std::size_t>(e)])
        {
            gone.conn.insert(gone.conn.end(), blk.conn.begin() + 8 * e, blk.conn.begin() + 8 * e + 8);
            gone.volume0.push_back(blk.volume0[static_cast<std::size_t>(e)]);
        }
    blocks[block].remove_elements(keep, nodes);
    index_t offset = 0;
    for (std::size_t ip = 0; ip < parts.size(); ++ip)
    {
        parts[ip].element_offset = offset;
        offset += blocks[ip].n_elements();
    }
    plan_assembly();
    refresh_contact_surfaces(); // eroding contact: the newly exposed faces join the surfaces
    ++topology_version_;
}

bool Model::apply_events(real_t, std::int64_t)
{
    bool changed = false;
    for (index_t b = 0; b < static_cast<index_t>(blocks.size()); ++b)
    {
        const ErosionSpec& er = deck_.parts[static_cast<std::size_t>(b)].erosion;
        if (!er.active() || part_nodal[b] >= 0)
            continue;
        const index_t ne = blocks[b].n_elements();
        std::vector<char> keep(static_cast<std::size_t>(ne), 1);
        index_t removed = 0;
        for (index_t e = 0; e < ne; ++e)
        {
            const bool erode = (er.plastic_strain > 0 && element_history(b, e, History::PlasticStrain) >= er.plastic_strain) ||
                               (er.damage > 0 && element_history(b, e, History::Damage) >= er.damage);
            keep[e] = !erode;
            removed += erode;
        }
        if (removed == 0)
            continue;
        remove_elements(b, keep);
        eroded_elements_ += removed;
        changed = true;
    }
    return changed;
}

void Model::plan_assembly()
{
    // each block's node range (nodal parts: the nodal block's)
    std::vector<std::pair<index_t, index_t>> range;
    for (std::size_t ib = 0; ib < blocks.size(); ++ib)
        if (part_nodal[ib] >= 0)
            range.emplace_back(nodal_blocks[part_nodal[ib]].node_begin, nodal_blocks[part_nodal[ib]].node_end);
        else
            range.emplace_back(blocks[ib].node_begin, blocks[ib].node_end);
    block_adds_.assign(blocks.size(), 0);
    for (std::size_t a = 0; a < range.size(); ++a)
    {
        // a coupled part's FE side shares the part's nodes with its nodal block: both add
        if (part_fe_side[a] >= 0)
            block_adds_[a] = 1;
        for (std::size_t b = 0; b < range.size(); ++b)
            if (a != b && range[a].first < range[b].second && range[b].first < range[a].second)
                block_adds_[a] = 1;
    }
    // the union of the adding blocks' ranges, as disjoint sorted intervals
    std::vector<std::pair<index_t, index_t>> shared;
    for (std::size_t a = 0; a < range.size(); ++a)
        if (block_adds_[a])
            shared.push_back(range[a]);
    std::sort(shared.begin(), shared.end());
    shared_node_ranges_.clear();
    for (const auto& r : shared)
        if (!shared_node_ranges_.empty() && r.first <= shared_node_ranges_.back().second)
            shared_node_ranges_.back().second = std::max(shared_node_ranges_.back().second, r.second);
        else
            shared_node_ranges_.push_back(r);
}
} // namespace rkfem
