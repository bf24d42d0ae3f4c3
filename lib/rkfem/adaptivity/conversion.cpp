// Evolutionary coupling (seed Table 1, feature 4): elements of a fem-nodal part turn into RK
// between steps. The state stays where it is integrated (at the nodes), so an event rebuilds
// tables only. fem-1pt parts move their state too: conversion_fe_side.cpp.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/model/nodal_block_build.hpp"

namespace rkfem
{
HexMesh Model::part_mesh(index_t part) const
{
    const PartInfo& info = parts[static_cast<std::size_t>(part)];
    HexMesh mesh;
    mesh.x.assign(nodes.x0.begin() + 3 * static_cast<std::ptrdiff_t>(info.node_begin),
                  nodes.x0.begin() + 3 * static_cast<std::ptrdiff_t>(info.node_end));
    mesh.conn = meshes[static_cast<std::size_t>(part)].conn;
    for (index_t& n : mesh.conn)
        n -= info.node_begin;
    mesh.faces = extract_boundary_faces(mesh.conn);
    return mesh;
}

void Model::set_rk_elements(index_t part, const std::vector<char>& rk)
{
    const PartSpec& ps = deck_.parts[static_cast<std::size_t>(part)];
    NodalBlock& nb = *nodal_block(part);
    const HexMesh mesh = part_mesh(part);
    const index_t begin = parts[part].node_begin, n = parts[part].node_end - begin;
    ChangedRows changed;
    try
    {
        // every element FE again (all reverted): the block a converting part starts with, built whole
        const bool all_fe = std::find(rk.begin(), rk.end(), char{1}) == rk.end();
        // the whole block's rows of the kinematic map, moved out of it
        auto take_rows = [&](NodalBlock& from)
        {
            for (index_t i = 0; i < n; ++i)
            {
                changed.node.push_back(i);
                for (index_t k = from.interp_offsets[i]; k < from.interp_offsets[i + 1]; ++k)
                {
                    changed.columns.push_back(from.interp_nodes[k]);
                    changed.values.push_back(from.interp_values[k]);
                }
                changed.offsets.push_back(static_cast<index_t>(changed.columns.size()));
            }
            std::vector<index_t>().swap(from.interp_offsets);
            std::vector<index_t>().swap(from.interp_nodes);
            std::vector<real_t>().swap(from.interp_values);
        };
        if (fe_side(part))
        {
            if (rebuild_fe_side_part(part, mesh, rk, changed))
                take_rows(nb);
        }
        else if (rebuild_whole_part_ || all_fe)
        {
            // the plain way: the whole block again, the state handed over point for point
            NodalBlock fresh = build_coupled_block(ps, mesh, begin, &rk);
            auto same_points = [](const IntegrationOperator& a, const IntegrationOperator& b)
            {
                if (a.n_points() != b.n_points())
                    return false;
                for (index_t p = 0; p < a.n_points(); ++p)
                    if (a.owner[p] != b.owner[p] || std::abs(a.weight[p] - b.weight[p]) > 1e-12 * std::abs(b.weight[p]))
                        return false;
                return true;
            };
            RKFEM_REQUIRE(same_points(fresh.points, nb.points) && same_points(fresh.stabilization, nb.stabilization),
                          "conversion in part '" << ps.name
                                                 << "': the rebuilt block's points differ from the old ones");
            fresh.part = nb.part;
            fresh.stress = std::move(nb.stress);
            fresh.stress_trial = std::move(nb.stress_trial);
            fresh.stab_stress = std::move(nb.stab_stress);
            fresh.stab_stress_trial = std::move(nb.stab_stress_trial);
            fresh.jacobian = std::move(nb.jacobian);
            fresh.plastic = std::move(nb.plastic);
            take_rows(fresh);
            nb = std::move(fresh);
        }
        else
            changed = update_coupled_block(ps, mesh, begin, rk_elements_[static_cast<std::size_t>(part)], rk, nb);
    }
    catch (const DeckError& e)
    {
        throw Error("converting elements of part '" + ps.name + "' to RK: " + e.what() +
                    " (a larger rk.normalized_support covers the new particles better)");
    }
    // the part's rows of the kinematic map: the changed ones, the others as they were
    std::vector<index_t> offsets{0}, columns;
    std::vector<real_t> values;
    std::size_t c = 0;
    for (index_t i = 0; i < n; ++i)
    {
        if (c < changed.node.size() && changed.node[c] == i)
        {
            for (index_t k = changed.offsets[c]; k < changed.offsets[c + 1]; ++k)
            {
                columns.push_back(changed.columns[k]);
                values.push_back(changed.values[k]);
            }
            ++c;
        }
        else
            kinematics.for_row(begin + i,
                               [&](index_t j, real_t w)
                               {
                                   columns.push_back(j);
                                   values.push_back(w);
                               });
        offsets.push_back(static_cast<index_t>(columns.size()));
    }
    kinematics.set_rows(begin, begin + n, offsets, columns, values, &nb.particle);
    rk_elements_[static_cast<std::size_t>(part)] = rk;
    // conditions on new particles act through the map; loads reach the coefficients through it
    rk_constraints_.clear();
    build_rk_constraints();
    collect_loaded_dofs();
    plan_conditions();
    plan_assembly();
}

index_t Model::flip_elements(index_t part, const std::vector<char>& flags, bool to_rk, const char* caller)
{
    RKFEM_REQUIRE(part >= 0 && part < static_cast<index_t>(parts.size()), caller << ": no part " << part);
    const PartSpec& ps = deck_.parts[static_cast<std::size_t>(part)];
    RKFEM_REQUIRE(ps.coupled() && (ps.formulation == Formulation::FemNodal || ps.formulation == Formulation::Fem1pt),
                  caller << ": part '" << ps.name << "' is not a fem-nodal or fem-1pt part with regions or conversion");
    std::vector<char> rk = rk_elements_[static_cast<std::size_t>(part)];
    RKFEM_REQUIRE(flags.size() == rk.size(), caller << ": " << flags.size() << " flags for " << rk.size()
                                                    << " elements of part '" << ps.name << "'");
    index_t changed = 0;
    for (std::size_t e = 0; e < rk.size(); ++e)
        if (flags[e] && bool(rk[e]) != to_rk)
        {
            rk[e] = to_rk ? 1 : 0;
            ++changed;
        }
    if (changed > 0)
        set_rk_elements(part, rk);
    return changed;
}

index_t Model::convert_elements(index_t part, const std::vector<char>& convert)
{
    RKFEM_REQUIRE(part >= 0 && part < static_cast<index_t>(parts.size()), "convert_elements: no part " << part);
    // the flags are per element of the part's FE block now; the conversion counts its own
    if (deck_.parts[static_cast<std::size_t>(part)].converts_to_semi_lagrangian())
        return convert_to_semi_lagrangian(part, convert);
    const index_t added = flip_elements(part, convert, true, "convert_elements");
    converted_elements_ += added;
    return added;
}

index_t Model::revert_elements(index_t part, const std::vector<char>& revert)
{
    const index_t back = flip_elements(part, revert, false, "revert_elements");
    reverted_elements_ += back;
    return back;
}

namespace
{
/// One layer of node neighbours: each element for which `take(e)` says yes and that shares a node with an
/// element of `from` (flags per element of the part) is handed to `mark(e)`; `marked` is scratch.
template <class Take, class Mark>
void node_neighbour_layer(const std::vector<index_t>& conn, index_t node_begin, index_t n_nodes,
                          const std::vector<char>& from, std::vector<char>& marked, Take&& take, Mark&& mark)
{
    const std::size_t ne = from.size();
    marked.assign(static_cast<std::size_t>(n_nodes), 0);
    for (std::size_t e = 0; e < ne; ++e)
        if (from[e])
            for (int a = 0; a < 8; ++a)
                marked[static_cast<std::size_t>(conn[8 * e + a] - node_begin)] = 1;
    for (std::size_t e = 0; e < ne; ++e)
        if (take(e))
            for (int a = 0; a < 8; ++a)
                if (marked[static_cast<std::size_t>(conn[8 * e + a] - node_begin)])
                {
                    mark(e);
                    break;
                }
}
} // namespace

void Model::reversion_flags(index_t part, std::vector<char>& revert) const
{
    const PartSpec& ps = deck_.parts[static_cast<std::size_t>(part)];
    const ElementCriteria& c = ps.conversion;
    const std::vector<char>& rk = rk_elements_[static_cast<std::size_t>(part)];
    const std::vector<index_t>& conn = meshes[static_cast<std::size_t>(part)].conn;
    const PartInfo& info = parts[static_cast<std::size_t>(part)];
    const std::size_t ne = rk.size();
    // elements RK by a region of the deck stay RK
    const std::vector<char>& region = region_elements_[static_cast<std::size_t>(part)];
    // benign: RK, by a conversion, meeting none of its criteria and every revert measure
    revert.assign(ne, 0);
    parallel_for_any("rkfem::reversion_criteria", static_cast<index_t>(ne),
                     [&](index_t e)
                     {
                         if (!rk[e] || (!region.empty() && region[e]) || meets(c, part, e) ||
                             !benign(c.revert, part, e))
                             return false;
                         revert[e] = 1;
                         return true;
                     });
    // kept: the RK elements that are not benign, and the buffer's layers of node neighbours around them
    std::vector<char> keep(ne, 0);
    for (std::size_t e = 0; e < ne; ++e)
        keep[e] = rk[e] && !revert[e];
    std::vector<char> marked;
    for (int layer = 0; layer < c.buffer; ++layer)
        node_neighbour_layer(
            conn, info.node_begin, info.node_end - info.node_begin, keep, marked,
            [&](std::size_t e) { return revert[e] && !keep[e]; }, [&](std::size_t e) { keep[e] = 1; });
    for (std::size_t e = 0; e < ne; ++e)
        revert[e] = revert[e] && !keep[e];
}

void Model::buffer_and_cap(index_t part, const ElementCriteria& c, std::vector<char>& convert) const
{
    if (c.buffer == 0 && c.max_per_event == 0)
        return;
    const std::vector<char>& rk = rk_elements_[static_cast<std::size_t>(part)];
    const std::vector<index_t>& conn = meshes[static_cast<std::size_t>(part)].conn;
    const PartInfo& info = parts[static_cast<std::size_t>(part)];
    const std::size_t ne = convert.size();
    // the buffer: layer by layer, the elements (not RK yet) sharing a node with those flagged
    // (1: triggered, 2: buffer)
    std::vector<char> marked;
    for (int layer = 0; layer < c.buffer; ++layer)
        node_neighbour_layer(
            conn, info.node_begin, info.node_end - info.node_begin, convert, marked,
            [&](std::size_t e) { return !convert[e] && (rk.empty() || !rk[e]); },
            [&](std::size_t e) { convert[e] = 2; });
    // the cap: the triggered ones first, then the buffer's, each in element order
    std::int64_t left = c.max_per_event > 0 ? c.max_per_event : std::numeric_limits<std::int64_t>::max();
    for (const char kind : {char{1}, char{2}})
        for (std::size_t e = 0; e < ne; ++e)
            if (convert[e] == kind)
            {
                if (left > 0)
                    --left;
                else
                    convert[e] = 0;
            }
}

int Model::element_zone(index_t block, index_t e) const
{
    if (!nodal_block(block))
        return 0;
    if (deck_.parts[static_cast<std::size_t>(block)].formulation == Formulation::Rkpm)
        return 2;
    const std::vector<char>& rk = rk_elements_[static_cast<std::size_t>(block)];
    if (rk.empty())
        return 0;
    if (rk[static_cast<std::size_t>(e)])
        return 2;
    const HexBlock& blk = meshes[static_cast<std::size_t>(block)];
    for (int a = 0; a < 8; ++a)
        if (kinematics.carries_coefficients(blk.conn[8 * static_cast<std::size_t>(e) + a]))
            return 1;
    return 0;
}
} // namespace rkfem
