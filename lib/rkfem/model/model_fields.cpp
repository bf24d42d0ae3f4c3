// What output and probes read: physical values, stresses and histories per element and node.
#include "rkfem/model/model.hpp"
#include "rkfem/operators/semi_lagrangian_block.hpp"

#include <algorithm>

namespace rkfem
{
bool Model::carries_coefficients(index_t node) const
{
    return kinematics.carries_coefficients(node);
}

Vec3 Model::physical(const std::vector<real_t>& field, index_t node) const
{
    return kinematics.physical(field.data(), node);
}

void Model::physical_field(const std::vector<real_t>& field, std::vector<real_t>& out) const
{
    kinematics.physical_field(field, out);
}

namespace
{
/// History value h of point p.
real_t history_value(const PlasticPoints& pp, std::size_t p, Model::History h)
{
    switch (h)
    {
    case Model::History::PlasticStrain:
        return pp.eps_p[p];
    case Model::History::Damage:
        return pp.damage(p);
    case Model::History::KccDelta:
        return pp.kcc_delta(p);
    }
    return 0.0;
}
} // namespace

real_t Model::element_history(index_t b, index_t e, History h) const
{
    auto value = [h](const PlasticPoints& pp, std::size_t p) { return history_value(pp, p, h); };
    if (fe_side(b) && fe_side(b)->local[e] >= 0)
    {
        const HexBlock& fb = fe_side(b)->block;
        return fb.plastic.active() ? value(fb.plastic, static_cast<std::size_t>(fe_side(b)->local[e])) : 0.0;
    }
    if (nodal_block(b))
    {
        const NodalBlock& nb = *nodal_block(b);
        if (!nb.plastic.active())
            return 0.0;
        real_t s = 0.0;
        int count = 0;
        for (int I = 0; I < 8; ++I)
        {
            const index_t i = meshes[b].conn[8 * static_cast<std::size_t>(e) + I] - nb.node_begin;
            for (index_t k = nb.owner_offsets[i]; k < nb.owner_offsets[i + 1]; ++k, ++count)
                s += value(nb.plastic, static_cast<std::size_t>(nb.owner_points[k]));
        }
        return count ? s / count : 0.0;
    }
    const HexBlock& blk = meshes[b];
    if (!blk.plastic.active())
        return 0.0;
    const index_t npe = blk.points_per_element();
    real_t s = 0.0;
    for (index_t g = 0; g < npe; ++g)
        s += value(blk.plastic, static_cast<std::size_t>(e) * npe + g);
    return s / npe;
}

const NodalBlock* Model::particle_points(index_t node) const
{
    const index_t ip = nodes.part[node];
    const PartSpec& ps = deck_.parts[static_cast<std::size_t>(ip)];
    if (ps.converts_to_semi_lagrangian() || ps.refinement.active())
    {
        // dormant particles (not converted yet, or a refinement's pool) have no point to show
        const SemiLagrangianForceBlock* sl = semi_lagrangian_block(ip);
        return sl->dormant(node - sl->nodal_points()->node_begin) ? nullptr : sl->nodal_points();
    }
    return nodal_block(ip);
}

std::vector<index_t> Model::output_particles() const
{
    std::vector<index_t> out;
    for (index_t ip = 0; ip < static_cast<index_t>(parts.size()); ++ip)
    {
        const PartSpec& ps = deck_.parts[static_cast<std::size_t>(ip)];
        // clouds, and the particles conversion and refinement make (a refining mesh part: all
        // its particles, the mesh's elements joining only those of the start)
        const bool sleeps = ps.converts_to_semi_lagrangian() || ps.refinement.active();
        if (is_cloud(ip) || sleeps)
            for (index_t i = parts[ip].node_begin; i < parts[ip].node_end; ++i)
                if (!sleeps || particle_points(i))
                    out.push_back(i);
    }
    return out;
}

real_t Model::nodal_history(index_t node, History h) const
{
    const NodalBlock* points = particle_points(node);
    if (!points)
        return 0.0;
    const NodalBlock& nb = *points;
    if (!nb.plastic.active())
        return 0.0;
    const index_t i = node - nb.node_begin;
    real_t s = 0.0;
    const index_t k0 = nb.owner_offsets[i], k1 = nb.owner_offsets[i + 1];
    for (index_t k = k0; k < k1; ++k)
        s += history_value(nb.plastic, static_cast<std::size_t>(nb.owner_points[k]), h);
    return k1 > k0 ? s / static_cast<real_t>(k1 - k0) : 0.0;
}

bool Model::is_cloud(index_t part) const
{
    return deck_.parts[static_cast<std::size_t>(part)].generator.type == GeneratorSpec::Type::Cloud;
}

index_t Model::n_cells() const
{
    return n_elements() + static_cast<index_t>(output_particles().size());
}

index_t Model::n_work_items() const
{
    index_t n = 0;
    for (index_t b = 0; b < static_cast<index_t>(meshes.size()); ++b)
        n += deck_.parts[static_cast<std::size_t>(b)].refinement.active() &&
                     !deck_.parts[static_cast<std::size_t>(b)].converts_to_semi_lagrangian()
                 ? semi_lagrangian_block(b)->active_particles() // not the pool
             : nodal_block(b) ? nodal_block(b)->n_points()
                              : meshes[b].n_elements();
    for (index_t b = 0; b < static_cast<index_t>(meshes.size()); ++b)
        if (fe_side(b))
            n += fe_side(b)->block.n_elements();
        else if (deck_.parts[static_cast<std::size_t>(b)].converts_to_semi_lagrangian())
            n += semi_lagrangian_block(b)->active_particles(); // and the particles it has made
    return n;
}

Sym6 Model::element_stress(index_t b, index_t e) const
{
    if (fe_side(b) && fe_side(b)->local[e] >= 0)
    {
        const HexBlock& fb = fe_side(b)->block;
        Sym6 s;
        for (int k = 0; k < 6; ++k)
            s[k] = fb.stress[k * fb.stress_stride + static_cast<std::size_t>(fe_side(b)->local[e])];
        return s;
    }
    if (nodal_block(b))
    {
        Sym6 s = Sym6::Zero();
        for (int I = 0; I < 8; ++I)
            s += nodal_stress(meshes[b].conn[8 * static_cast<std::size_t>(e) + I]);
        return s / 8.0;
    }
    const HexBlock& blk = meshes[b];
    const index_t npe = blk.points_per_element();
    const std::size_t np = blk.stress_stride;
    Sym6 s = Sym6::Zero();
    for (index_t g = 0; g < npe; ++g)
        for (int k = 0; k < 6; ++k)
            s[k] += blk.stress[k * np + static_cast<std::size_t>(e) * npe + g];
    return s / static_cast<real_t>(npe);
}

Sym6 Model::nodal_stress(index_t node) const
{
    const index_t ip = nodes.part[node];
    if (const NodalBlock* points = particle_points(node))
    {
        const NodalBlock& nb = *points;
        const index_t i = node - nb.node_begin;
        const std::size_t np = nb.stress_stride;
        Sym6 s = Sym6::Zero();
        const index_t k0 = nb.owner_offsets[i], k1 = nb.owner_offsets[i + 1];
        for (index_t k = k0; k < k1; ++k)
            for (int c = 0; c < 6; ++c)
                s[c] += nb.stress[c * np + nb.owner_points[k]];
        if (k1 > k0 || !fe_side(ip))
            return k1 > k0 ? Sym6(s / static_cast<real_t>(k1 - k0)) : s;
        // a node of a coupled part's FE side that owns no point: the average of its elements
    }
    const HexBlock& blk = meshes[ip];
    const index_t i = node - blk.node_begin;
    Sym6 s = Sym6::Zero();
    const index_t k0 = blk.node_elem_offsets[i], k1 = blk.node_elem_offsets[i + 1];
    for (index_t k = k0; k < k1; ++k)
        s += element_stress(ip, blk.node_elem_slots[k] / 8);
    return k1 > k0 ? Sym6(s / static_cast<real_t>(k1 - k0)) : s;
}
} // namespace rkfem
