// Evolutionary coupling of fem-1pt parts (LS-DYNA-style models): a converting part's FE elements
// are a 1-point block (its FE side) and its transition and RK elements a nodal block whose points
// sit at their nodes. An event builds both again for the new RK elements (the nodal block's rows
// where the approximation changed, the others taken from the old block: update_fe_side_block)
// and hands the material over octant by octant:
//   - every element is cut into its 8 corner octants (reference volume V0 / 8 each); an octant
//     belongs to its element's Gauss point while the element is FE, and to the point of its
//     corner node while it is not (that node's SCNI cell is the union of such octants);
//   - a point of the new blocks whose octants all come from one old point takes that point's
//     state as it is; otherwise the volume-weighted mean over its octants' old points of the
//     stress, det F and each history measure, except the damage measures, which take the largest
//     (PlasticPoints::blend_point);
//   - MSCNI sub-cells are the octants of the nodal block's elements: one that stays keeps its
//     stabilization stress, a new one starts at zero, as do the hourglass forces of an element that
//     becomes FE (an element that stays FE keeps its own);
//   - the nodes' masses become the new blocks' (rho V0 / 8 per FE element, rho times the cell's
//     volume per point) with each node's momentum kept; the kinetic energy that costs is booked as
//     the event's (Energies::eroded).
#include <algorithm>
#include <memory>
#include <string>
#include <vector>

#include "rkfem/core/error.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/model/nodal_block_build.hpp"

namespace rkfem
{
namespace
{
/// Who integrates an octant: the Gauss point of FE element `index` of the side (fe), or nodal
/// point `index` of the block.
struct Carrier
{
    bool fe;
    index_t index;
    bool operator==(const Carrier&) const = default;
};

/// One octant's share of a new point: its old carrier and volume.
struct OctantShare
{
    Carrier from;
    real_t weight;
};

/// The nodal point of local node i (a coupled block has one per node of its elements).
index_t point_of(const NodalBlock& nb, index_t i)
{
    const index_t k0 = nb.owner_offsets[i], k1 = nb.owner_offsets[i + 1];
    RKFEM_REQUIRE(k1 - k0 == 1, "fem-1pt conversion: node " << i << " owns " << k1 - k0 << " points, expected 1");
    return nb.owner_points[k0];
}

} // namespace

bool Model::rebuild_fe_side_part(index_t part, const HexMesh& mesh, const std::vector<char>& rk, ChangedRows& changed)
{
    const PartSpec& ps = deck_.parts[static_cast<std::size_t>(part)];
    const HexBlock& shape = meshes[static_cast<std::size_t>(part)]; // conn, volume0, node -> elements
    NodalBlock& nb = *nodal_block(part);
    auto& side_block = static_cast<FeSideForceBlock&>(*blocks_[static_cast<std::size_t>(part_fe_side_[part])].block);
    const FeSide& side = side_block.side();
    const index_t begin = parts[part].node_begin, n = parts[part].node_end - begin, ne = shape.n_elements();

    // the nodal block where the approximation changed (the others' rows as they were; whole,
    // every row with it, where asked or where no element is RK), its crack-band scales those
    // solved before
    const std::shared_ptr<KccScaleCache> scales = nb.plastic.kcc_scales;
    const bool whole = rebuild_whole_part_ || std::find(rk.begin(), rk.end(), char{1}) == rk.end();
    NodalBlock fresh = whole ? build_coupled_block(ps, mesh, begin, &rk, scales)
                             : update_fe_side_block(ps, mesh, begin, rk_elements_[part], rk, nb, changed, scales);
    fresh.part = nb.part;
    FeSide fresh_side = build_fe_side(ps, mesh, shape, fresh);
    const HexBlock& old_fb = side.block;
    HexBlock& new_fb = fresh_side.block;

    // the old carrier of octant (e, a)
    auto old_carrier = [&](index_t e, int a) -> Carrier
    {
        if (side.local[e] >= 0)
            return {true, side.local[e]};
        return {false, point_of(nb, shape.conn[8 * static_cast<std::size_t>(e) + a] - begin)};
    };
    auto stress_of = [&](const Carrier& c, int k)
    {
        return c.fe ? old_fb.stress[k * old_fb.stress_stride + static_cast<std::size_t>(c.index)]
                    : nb.stress[k * nb.stress_stride + static_cast<std::size_t>(c.index)];
    };
    auto jacobian_of = [&](const Carrier& c)
    { return c.fe ? element_volume(old_fb, nodes, c.index) / old_fb.volume0[c.index] : nb.jacobian[c.index]; };
    std::vector<OctantShare> shares;
    std::vector<PlasticPoints::Share> history;
    // point `to` of a new block (stress with its stride, history) from `shares`
    auto blend = [&](real_t* stress, std::size_t stride, PlasticPoints& plastic, std::size_t to)
    {
        RKFEM_REQUIRE(!shares.empty(), "fem-1pt conversion: a point of part '" << ps.name << "' takes no octant");
        const bool one =
            std::all_of(shares.begin(), shares.end(), [&](const OctantShare& s) { return s.from == shares[0].from; });
        real_t total = 0.0;
        for (const OctantShare& s : shares)
            total += s.weight;
        for (int k = 0; k < 6; ++k)
        {
            real_t v = stress_of(shares[0].from, k);
            if (!one)
            {
                v = 0.0;
                for (const OctantShare& s : shares)
                    v += s.weight * stress_of(s.from, k);
                v /= total;
            }
            stress[k * stride + to] = v;
        }
        if (!plastic.active())
            return;
        history.clear();
        for (const OctantShare& s : shares)
            history.push_back(
                {s.from.fe ? &old_fb.plastic : &nb.plastic, static_cast<std::size_t>(s.from.index), s.weight});
        plastic.blend_point(history.data(), history.size(), to);
    };

    // the FE side's elements: their 8 octants
    for (index_t e = 0; e < ne; ++e)
    {
        const index_t q = fresh_side.local[e];
        if (q < 0)
            continue;
        shares.clear();
        for (int a = 0; a < 8; ++a)
            shares.push_back({old_carrier(e, a), shape.volume0[e] / 8.0});
        blend(new_fb.stress.data(), new_fb.stress_stride, new_fb.plastic, static_cast<std::size_t>(q));
        // an element that stays FE keeps its hourglass forces
        if (side.local[e] >= 0)
            for (int r = 0; r < new_fb.hg_rows(); ++r)
                new_fb.hg_force[static_cast<std::size_t>(r) * new_fb.n_elements() + q] =
                    old_fb.hg_force[static_cast<std::size_t>(r) * old_fb.n_elements() + side.local[e]];
    }
    new_fb.stress_trial = new_fb.stress;
    new_fb.hg_force_trial = new_fb.hg_force;

    // the nodal points: the octants of their node in the block's elements
    for (index_t i = 0; i < n; ++i)
        for (index_t k = fresh.owner_offsets[i]; k < fresh.owner_offsets[i + 1]; ++k)
        {
            const index_t p = fresh.owner_points[k];
            shares.clear();
            for (index_t s = shape.node_elem_offsets[i]; s < shape.node_elem_offsets[i + 1]; ++s)
            {
                const index_t e = shape.node_elem_slots[s] / 8;
                if (!fresh.fe_element[e])
                    shares.push_back(
                        {old_carrier(e, static_cast<int>(shape.node_elem_slots[s] % 8)), shape.volume0[e] / 8.0});
            }
            blend(fresh.stress.data(), fresh.stress_stride, fresh.plastic, static_cast<std::size_t>(p));
            const bool one = std::all_of(shares.begin(), shares.end(),
                                         [&](const OctantShare& o) { return o.from == shares[0].from; });
            real_t J = jacobian_of(shares[0].from);
            if (!one)
            {
                real_t total = 0.0;
                J = 0.0;
                for (const OctantShare& o : shares)
                {
                    J += o.weight * jacobian_of(o.from);
                    total += o.weight;
                }
                J /= total;
            }
            fresh.jacobian[p] = J;
        }
    fresh.stress_trial = fresh.stress;

    // MSCNI: sub-cell 8 rank + a of each non-FE element; one that was there keeps its stress
    if (fresh.n_stab() > 0)
    {
        const std::vector<index_t> rank_old = coupled_sub_cell_ranks(nb.fe_element),
                                   rank_new = coupled_sub_cell_ranks(fresh.fe_element);
        const std::size_t ns_old = static_cast<std::size_t>(nb.n_stab()),
                          ns_new = static_cast<std::size_t>(fresh.n_stab());
        for (index_t e = 0; e < ne; ++e)
        {
            if (rank_new[e] < 0)
                continue;
            for (int a = 0; a < 8; ++a)
            {
                const std::size_t to = 8 * static_cast<std::size_t>(rank_new[e]) + a;
                RKFEM_REQUIRE(fresh.stabilization.owner[to] == shape.conn[8 * static_cast<std::size_t>(e) + a],
                              "fem-1pt conversion: MSCNI sub-cell " << to << " is not corner " << a << " of element "
                                                                    << e);
                if (rank_old[e] < 0 || ns_old == 0)
                    continue;
                const std::size_t from = 8 * static_cast<std::size_t>(rank_old[e]) + a;
                for (int k = 0; k < 6; ++k)
                    fresh.stab_stress[k * ns_new + to] = nb.stab_stress[k * ns_old + from];
            }
        }
        fresh.stab_stress_trial = fresh.stab_stress;
    }

    // masses: the new blocks', each node's momentum kept
    NodeSet before, after;
    before.mass.assign(nodes.mass.size(), 0.0);
    after.mass.assign(nodes.mass.size(), 0.0);
    add_lumped_mass(old_fb, before);
    add_nodal_mass(nb, before);
    add_lumped_mass(new_fb, after);
    add_nodal_mass(fresh, after);
    for (index_t i = begin; i < begin + n; ++i) // every node checked before any changes
        RKFEM_REQUIRE(nodes.mass[i] - before.mass[i] + after.mass[i] > 0.0,
                      "fem-1pt conversion: node " << i << " of part '" << ps.name << "' would be left with mass "
                                                  << nodes.mass[i] - before.mass[i] + after.mass[i] << " kg");
    real_t kinetic_change = 0.0;
    for (index_t i = begin; i < begin + n; ++i)
    {
        if (before.mass[i] == after.mass[i])
            continue;
        const real_t m_old = nodes.mass[i], m_new = m_old - before.mass[i] + after.mass[i];
        for (int d = 0; d < 3; ++d)
        {
            real_t& v = nodes.v[3 * static_cast<std::size_t>(i) + d];
            const real_t v_new = v * m_old / m_new;
            kinetic_change += 0.5 * (m_new * v_new * v_new - m_old * v * v);
            v = v_new;
        }
        nodes.mass[i] = m_new;
    }
    energy.kinetic += kinetic_change;
    energy.eroded -= kinetic_change;

    nb = std::move(fresh);
    side_block.reset(std::move(fresh_side));
    return whole;
}
} // namespace rkfem
