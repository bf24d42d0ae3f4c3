// The model's state between steps, into and out of a checkpoint (StateArchive). What is built
// from the deck (tables, masses' layout, conditions) is built again; what a run changed is saved:
// nodal kinematics and masses, committed material state, the ledger and its previous-step terms,
// the elements erosion removed and those conversion made RK.
#include <algorithm>
#include <string>

#include "rkfem/core/error.hpp"
#include "rkfem/core/state_archive.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/operators/semi_lagrangian_block.hpp"

namespace rkfem
{
namespace
{
void save_plastic(StateArchive& a, const std::string& prefix, const PlasticPoints& p)
{
    int k = 0;
    p.each_array([&](const auto& committed, const auto&)
                 { a.put(prefix + "plastic." + std::to_string(k++), committed); });
}

void load_plastic(const StateArchive& a, const std::string& prefix, PlasticPoints& p)
{
    int k = 0;
    p.each_array(
        [&](auto& committed, auto& trial)
        {
            a.get_same_size(prefix + "plastic." + std::to_string(k++), committed);
            trial = committed;
        });
}

/// A HexBlock's committed state (the tables are rebuilt from the deck).
void save_hex(StateArchive& a, const std::string& prefix, const HexBlock& b)
{
    a.put(prefix + "conn", b.conn);
    a.put(prefix + "stress", b.stress);
    a.put(prefix + "hg_force", b.hg_force);
    save_plastic(a, prefix, b.plastic);
}

void load_hex_state(const StateArchive& a, const std::string& prefix, HexBlock& b)
{
    a.get_same_size(prefix + "stress", b.stress);
    b.stress_trial = b.stress;
    // a checkpoint from before the assumed-strain form kept its frame sizes holds the 12 force rows
    // only: the sizes start at 0, as on a block's first step (assumed_strain_keep keeps the forces)
    const std::size_t rows12 = 12 * static_cast<std::size_t>(b.n_elements());
    std::vector<real_t> hg;
    a.get(prefix + "hg_force", hg);
    if (hg.size() == rows12 && b.hg_force.size() > rows12)
        std::copy(hg.begin(), hg.end(), b.hg_force.begin());
    else
        a.get_same_size(prefix + "hg_force", b.hg_force);
    b.hg_force_trial = b.hg_force;
    load_plastic(a, prefix, b.plastic);
}

/// The elements of `built` (as the deck builds them) that remain in `saved` (a block after
/// erosion): removal keeps the order, so one pass matches them.
std::vector<char> kept_elements(const std::vector<index_t>& built, const std::vector<index_t>& saved,
                                const std::string& what)
{
    const std::size_t ne = built.size() / 8;
    std::vector<char> keep(ne, 0);
    std::size_t s = 0;
    for (std::size_t e = 0; e < ne && s < saved.size() / 8; ++e)
        if (std::equal(built.begin() + 8 * e, built.begin() + 8 * e + 8, saved.begin() + 8 * s))
        {
            keep[e] = 1;
            ++s;
        }
    if (s != saved.size() / 8)
        throw Error("checkpoint: " + what +
                    "'s elements are not those of the deck's mesh (a checkpoint of another deck)");
    return keep;
}
} // namespace

void Model::save_state(StateArchive& a) const
{
    a.put("nodes.u", nodes.u);
    a.put("nodes.v", nodes.v);
    a.put("nodes.a", nodes.a);
    a.put("nodes.mass", nodes.mass);
    for (std::size_t b = 0; b < meshes.size(); ++b)
        save_hex(a, "block." + std::to_string(b) + ".", meshes[b]);
    // FE sides and nodal blocks numbered in the order of their parts
    for (index_t ip = 0, b = 0; ip < static_cast<index_t>(parts.size()); ++ip)
        if (const FeSide* side = fe_side(ip))
            save_hex(a, "fe_side." + std::to_string(b++) + ".", side->block);
    for (index_t ip = 0, b = 0; ip < static_cast<index_t>(parts.size()); ++ip)
    {
        if (!nodal_block(ip))
            continue;
        const NodalBlock& nb = *nodal_block(ip);
        const std::string prefix = "nodal." + std::to_string(b++) + ".";
        a.put(prefix + "stress", nb.stress);
        a.put(prefix + "stab_stress", nb.stab_stress);
        a.put(prefix + "jacobian", nb.jacobian);
        if (!nb.cells.empty())
            a.put(prefix + "cells", nb.cells);
        if (!nb.reference.empty())
            a.put(prefix + "reference", nb.reference);
        save_plastic(a, prefix, nb.plastic);
    }
    // semi-Lagrangian conversion: the particles' state and activation, the elements they took
    for (index_t ip = 0; ip < static_cast<index_t>(parts.size()); ++ip)
    {
        if (!deck_.parts[static_cast<std::size_t>(ip)].converts_to_semi_lagrangian())
            continue;
        const SemiLagrangianForceBlock& sl = *semi_lagrangian_block(ip);
        const NodalBlock& nb = *sl.nodal_points();
        const std::string prefix = "sl_conversion." + std::to_string(ip) + ".";
        a.put(prefix + "stress", nb.stress);
        a.put(prefix + "stab_stress", nb.stab_stress);
        a.put(prefix + "jacobian", nb.jacobian);
        a.put(prefix + "cells", nb.cells);
        a.put(prefix + "weight", nb.points.weight);
        a.put(prefix + "dormant", sl.dormant_flags());
        a.put(prefix + "width0", sl.widths0());
        save_plastic(a, prefix, nb.plastic);
        a.put(prefix + "converted.conn", converted_[static_cast<std::size_t>(ip)].conn);
        a.put(prefix + "converted.volume0", converted_[static_cast<std::size_t>(ip)].volume0);
    }
    // refinement: the particles' reference positions, volumes, activation, supports, lengths,
    // levels and families (the state itself is the nodal block's, above)
    for (index_t ip = 0; ip < static_cast<index_t>(parts.size()); ++ip)
    {
        if (!deck_.parts[static_cast<std::size_t>(ip)].refinement.active())
            continue;
        const SemiLagrangianForceBlock& sl = *semi_lagrangian_block(ip);
        const NodalBlock& nb = *sl.nodal_points();
        const std::string prefix = "sl_refinement." + std::to_string(ip) + ".";
        const PartInfo& info = parts[static_cast<std::size_t>(ip)];
        a.put(prefix + "x0", std::vector<real_t>(nodes.x0.begin() + 3 * static_cast<std::ptrdiff_t>(info.node_begin),
                                                 nodes.x0.begin() + 3 * static_cast<std::ptrdiff_t>(info.node_end)));
        if (!deck_.parts[static_cast<std::size_t>(ip)].converts_to_semi_lagrangian()) // else sl_conversion's
        {
            a.put(prefix + "weight", nb.points.weight);
            a.put(prefix + "dormant", sl.dormant_flags());
            a.put(prefix + "width0", sl.widths0());
        }
        a.put(prefix + "radius0", sl.radii0());
        a.put(prefix + "length0", nb.length0);
        a.put(prefix + "levels", sl.levels());
        std::vector<index_t> flat;
        for (const auto& f : families_[static_cast<std::size_t>(ip)])
            flat.insert(flat.end(), f.begin(), f.end());
        a.put(prefix + "families", flat);
    }
    a.put_value("refined_particles", refined_particles_);
    a.put_value("coarsened_particles", coarsened_particles_);
    a.put("next_refinement_check", next_refinement_check_);
    a.put_value("energy", energy);
    a.put("part_energy", part_energy_);
    a.put("f_ext_prev", f_ext_prev_);
    std::vector<real_t> reaction = reaction_prev_; // the still conditions' from the current forces
    if (forces_current_)
        fill_still_reactions(reaction);
    a.put("reaction_prev", reaction);
    a.put("reaction_inertia", reaction_inertia_);
    a.put("bc_v_prev", bc_v_prev_);
    a.put_value("dt_critical", dt_critical_);
    a.put_value("topology_version", topology_version_);
    a.put_value("eroded_elements", eroded_elements_);
    a.put_value("converted_elements", converted_elements_);
    a.put_value("reverted_elements", reverted_elements_);
    a.put("next_conversion_check", next_conversion_check_);
    for (std::size_t p = 0; p < rk_elements_.size(); ++p)
        if (!rk_elements_[p].empty())
            a.put("rk_elements." + std::to_string(p), rk_elements_[p]);
    a.put_value("eroded_blocks", static_cast<index_t>(eroded_.size()));
    for (std::size_t b = 0; b < eroded_.size(); ++b)
    {
        a.put("eroded." + std::to_string(b) + ".conn", eroded_[b].conn);
        a.put("eroded." + std::to_string(b) + ".volume0", eroded_[b].volume0);
    }
    contact.save_state(a);
    for (std::size_t k = 0; k < contacts.size(); ++k)
        contacts[k]->save_state(a, "contact." + std::to_string(k) + ".");
}

void Model::load_state(const StateArchive& a)
{
    // erosion first: the mesh blocks take the saved element lists, then their state
    bool eroded_any = false;
    for (std::size_t b = 0; b < meshes.size(); ++b)
    {
        std::vector<index_t> conn;
        a.get("block." + std::to_string(b) + ".conn", conn);
        if (conn == meshes[b].conn)
            continue;
        const std::vector<char> keep = kept_elements(meshes[b].conn, conn, "part '" + parts[b].name + "'");
        meshes[b].remove_elements(keep, nodes);
        eroded_any = true;
    }
    if (eroded_any)
    {
        index_t offset = 0;
        for (std::size_t ip = 0; ip < parts.size(); ++ip)
        {
            parts[ip].element_offset = offset;
            offset += meshes[ip].n_elements();
        }
        plan_assembly();
        refresh_contact_surfaces(); // the faces erosion exposed (their state is loaded below)
    }
    // conversion: the parts' RK elements, then the points' state below (the points are the same)
    for (std::size_t p = 0; p < rk_elements_.size(); ++p)
    {
        if (rk_elements_[p].empty())
            continue;
        std::vector<char> rk;
        a.get("rk_elements." + std::to_string(p), rk);
        if (rk.size() != rk_elements_[p].size())
            throw Error("checkpoint: part '" + parts[p].name + "' has " + std::to_string(rk.size()) +
                        " RK element flags for " + std::to_string(rk_elements_[p].size()) + " elements");
        if (rk != rk_elements_[p])
            set_rk_elements(static_cast<index_t>(p), rk);
    }
    a.get_same_size("nodes.u", nodes.u);
    a.get_same_size("nodes.v", nodes.v);
    a.get_same_size("nodes.a", nodes.a);
    a.get_same_size("nodes.mass", nodes.mass);
    update_coordinates();
    for (std::size_t b = 0; b < meshes.size(); ++b)
        load_hex_state(a, "block." + std::to_string(b) + ".", meshes[b]);
    for (index_t ip = 0, b = 0; ip < static_cast<index_t>(parts.size()); ++ip)
        if (FeSide* side = fe_side(ip))
            load_hex_state(a, "fe_side." + std::to_string(b++) + ".", side->block);
    for (index_t ip = 0, b = 0; ip < static_cast<index_t>(parts.size()); ++ip)
    {
        if (!nodal_block(ip))
            continue;
        NodalBlock& nb = *nodal_block(ip);
        const std::string prefix = "nodal." + std::to_string(b++) + ".";
        a.get_same_size(prefix + "stress", nb.stress);
        nb.stress_trial = nb.stress;
        a.get_same_size(prefix + "stab_stress", nb.stab_stress);
        nb.stab_stress_trial = nb.stab_stress;
        a.get_same_size(prefix + "jacobian", nb.jacobian);
        if (!nb.cells.empty())
        {
            a.get_same_size(prefix + "cells", nb.cells);
            nb.cells_trial = nb.cells;
        }
        if (!nb.reference.empty())
            a.get_same_size(prefix + "reference", nb.reference);
        load_plastic(a, prefix, nb.plastic);
    }
    for (index_t ip = 0; ip < static_cast<index_t>(parts.size()); ++ip)
    {
        if (!deck_.parts[static_cast<std::size_t>(ip)].converts_to_semi_lagrangian())
            continue;
        SemiLagrangianForceBlock& sl = *semi_lagrangian_block(ip);
        NodalBlock& nb = *sl.nodal_points();
        const std::string prefix = "sl_conversion." + std::to_string(ip) + ".";
        a.get_same_size(prefix + "stress", nb.stress);
        nb.stress_trial = nb.stress;
        a.get_same_size(prefix + "stab_stress", nb.stab_stress);
        nb.stab_stress_trial = nb.stab_stress;
        a.get_same_size(prefix + "jacobian", nb.jacobian);
        a.get_same_size(prefix + "cells", nb.cells);
        nb.cells_trial = nb.cells;
        a.get_same_size(prefix + "weight", nb.points.weight);
        load_plastic(a, prefix, nb.plastic);
        std::vector<real_t> dormant, width0;
        a.get(prefix + "dormant", dormant);
        a.get(prefix + "width0", width0);
        sl.restore_activation(dormant, width0);
        ErodedElements& took = converted_[static_cast<std::size_t>(ip)];
        a.get(prefix + "converted.conn", took.conn);
        a.get(prefix + "converted.volume0", took.volume0);
    }
    for (index_t ip = 0; ip < static_cast<index_t>(parts.size()); ++ip)
    {
        if (!deck_.parts[static_cast<std::size_t>(ip)].refinement.active())
            continue;
        SemiLagrangianForceBlock& sl = *semi_lagrangian_block(ip);
        NodalBlock& nb = *sl.nodal_points();
        const std::string prefix = "sl_refinement." + std::to_string(ip) + ".";
        const PartInfo& info = parts[static_cast<std::size_t>(ip)];
        std::vector<real_t> x0, radius0, length0, levels;
        a.get(prefix + "x0", x0);
        if (x0.size() != 3 * static_cast<std::size_t>(info.node_end - info.node_begin))
            throw Error("checkpoint: part '" + info.name + "' has " + std::to_string(x0.size() / 3) +
                        " refining particles' positions for " + std::to_string(info.node_end - info.node_begin));
        std::copy(x0.begin(), x0.end(), nodes.x0.begin() + 3 * static_cast<std::ptrdiff_t>(info.node_begin));
        if (!deck_.parts[static_cast<std::size_t>(ip)].converts_to_semi_lagrangian()) // else loaded above
        {
            std::vector<real_t> dormant, width0;
            a.get_same_size(prefix + "weight", nb.points.weight);
            a.get(prefix + "dormant", dormant);
            a.get(prefix + "width0", width0);
            sl.restore_activation(dormant, width0);
        }
        a.get(prefix + "radius0", radius0);
        a.get(prefix + "length0", length0);
        a.get(prefix + "levels", levels);
        sl.restore_refinement(radius0, length0, levels);
        std::vector<index_t> flat;
        a.get(prefix + "families", flat);
        auto& fam = families_[static_cast<std::size_t>(ip)];
        fam.clear();
        for (std::size_t k = 0; k + 8 <= flat.size(); k += 8)
            fam.push_back(
                {flat[k], flat[k + 1], flat[k + 2], flat[k + 3], flat[k + 4], flat[k + 5], flat[k + 6], flat[k + 7]});
    }
    if (std::any_of(deck_.parts.begin(), deck_.parts.end(), [](const PartSpec& p) { return p.refinement.active(); }))
    {
        update_coordinates();         // the reference positions loaded
        refresh_refined_conditions(); // the children's conditions (their state loads below)
        refresh_contact_surfaces();   // the particles' spheres of the volumes loaded
    }
    refined_particles_ = a.has("refined_particles") ? a.value<index_t>("refined_particles") : 0;
    coarsened_particles_ = a.has("coarsened_particles") ? a.value<index_t>("coarsened_particles") : 0;
    if (a.has("next_refinement_check"))
        a.get("next_refinement_check", next_refinement_check_);
    energy = a.value<Energies>("energy");
    a.get("part_energy", part_energy_);
    a.get("f_ext_prev", f_ext_prev_);
    a.get("reaction_prev", reaction_prev_);
    forces_current_ = false; // the forces are not restored: reactions() reads reaction_prev_
    a.get("reaction_inertia", reaction_inertia_);
    a.get("bc_v_prev", bc_v_prev_);
    dt_critical_ = a.value<real_t>("dt_critical");
    topology_version_ = a.value<int>("topology_version");
    eroded_elements_ = a.value<index_t>("eroded_elements");
    converted_elements_ = a.value<index_t>("converted_elements");
    reverted_elements_ = a.has("reverted_elements") ? a.value<index_t>("reverted_elements") : 0;
    a.get("next_conversion_check", next_conversion_check_);
    eroded_.assign(static_cast<std::size_t>(a.value<index_t>("eroded_blocks")), ErodedElements{});
    for (std::size_t b = 0; b < eroded_.size(); ++b)
    {
        a.get("eroded." + std::to_string(b) + ".conn", eroded_[b].conn);
        a.get("eroded." + std::to_string(b) + ".volume0", eroded_[b].volume0);
    }
    contact.load_state(a);
    for (std::size_t k = 0; k < contacts.size(); ++k)
        contacts[k]->load_state(a, "contact." + std::to_string(k) + ".");
}
} // namespace rkfem
