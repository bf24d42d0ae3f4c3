// Adaptive refinement and coarsening of semi-Lagrangian RK parts (issue #49; the digest's
// section 6, ../shared/reference/rkpm-methods.md; deck key `refinement`). The node count is fixed
// at set-up: a refining part reserves a pool of dormant particles after its own (no mass, in no
// kernel, no set), and a split wakes seven of them. Per split of particle p (cell: centre offset
// c, half-edges e_i; SemiLagrangianForceBlock::split):
//   - the children sit at the centres of the cell's eight half-size parallelepipeds, which tile
//     the cell, so where the cells tiled the body they still do (SNNI's integration constraint
//     holds there as before);
//   - mass m / 8 each (exact: the nodes' masses are the particles'); u_k = u_p + G_u (x_k - x_p),
//     v_k = v_p + G_v (x_k - x_p) with G the particle's smoothed gradients (SNNI's b_J reproduce
//     linear fields, so a linear u or v is carried over to round-off), then the velocities
//     shifted by one vector, -G_v c, so that their momentum is m v_p exactly;
//   - intensive state (stress, face stresses, volume ratio, history) copied: a uniform state
//     stays uniform; supports, widths and step lengths halve, so the stable step halves too;
//   - the change of kinetic energy, sum 1/2 m_k v_k^2 - 1/2 m v_p^2 (zero for rigid motion, of
//     second order in G_v h), is booked as the events' (Energies::eroded), not as work.
// Coarsening merges a family (the eight children of one split, none split again) back into its
// first particle: mass and momentum summed (exact), position the centre of mass, u the mass-
// weighted mean; the kinetic energy lost to the averaging is booked the same way.
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "rkfem/core/error.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/model/nodal_block_build.hpp"
#include "rkfem/operators/semi_lagrangian_block.hpp"

namespace rkfem
{
namespace
{
Vec3 node_vec(const std::vector<real_t>& a, index_t i)
{
    const std::size_t k = 3 * static_cast<std::size_t>(i);
    return {a[k], a[k + 1], a[k + 2]};
}

void set_node_vec(std::vector<real_t>& a, index_t i, const Vec3& v)
{
    const std::size_t k = 3 * static_cast<std::size_t>(i);
    for (int d = 0; d < 3; ++d)
        a[k + d] = v[d];
}

Vec3 times(const real_t* G, const Vec3& r)
{
    return {G[0] * r[0] + G[1] * r[1] + G[2] * r[2], G[3] * r[0] + G[4] * r[1] + G[5] * r[2],
            G[6] * r[0] + G[7] * r[1] + G[8] * r[2]};
}
} // namespace

index_t Model::refine_particles(index_t part, const std::vector<char>& split)
{
    const PartSpec& ps = deck_.parts[static_cast<std::size_t>(part)];
    SemiLagrangianForceBlock* sl = semi_lagrangian_block(part);
    RKFEM_REQUIRE(sl && ps.refinement.active(), "refinement: part '" << ps.name << "' has no refinement");
    const PartInfo& info = parts[static_cast<std::size_t>(part)];
    const index_t begin = info.node_begin, n = info.node_end - begin, first_spare = info.mesh_node_end - begin;
    RKFEM_REQUIRE(static_cast<index_t>(split.size()) == n,
                  "refinement: " << split.size() << " flags for " << n << " particles of part '" << ps.name << "'");
    // the pool, and the particles that split (in order, while seven spares are left for each)
    std::vector<index_t> spares;
    for (index_t p = n - 1; p >= first_spare; --p)
        if (sl->dormant(p))
            spares.push_back(p); // taken from the back: the lowest first
    // a converting part's particles that are still nodes of FE elements stay (a split moves the
    // particle, which would move the elements' corner)
    std::vector<char> fe_node;
    if (ps.converts_to_semi_lagrangian())
    {
        const HexBlock& blk = meshes[static_cast<std::size_t>(part)];
        fe_node.assign(static_cast<std::size_t>(n), 0);
        for (const index_t g : blk.conn)
            fe_node[static_cast<std::size_t>(g - begin)] = 1;
    }
    std::vector<index_t> splitting;
    for (index_t p = 0; p < n && spares.size() >= 7 * (splitting.size() + 1); ++p)
        if (split[static_cast<std::size_t>(p)] && !sl->dormant(p) && !sl->separated(p) &&
            sl->level(p) < ps.refinement.max_level && (fe_node.empty() || !fe_node[static_cast<std::size_t>(p)]))
            splitting.push_back(p);
    if (splitting.empty())
        return 0;
    // the smoothed gradients of u and v at each, all from the state before the event
    std::vector<real_t> G;
    if (!sl->field_gradients(splitting, nodes.x, {&nodes.v, &nodes.u}, G))
        throw Error("refinement: part '" + ps.name +
                    "': a particle that splits has a cell its neighbours do not cover");
    real_t kinetic = 0.0;
    for (std::size_t k = 0; k < splitting.size(); ++k)
    {
        const index_t p = splitting[k], gp = begin + p;
        index_t spare[7];
        for (int c = 0; c < 7; ++c)
        {
            spare[c] = spares.back();
            spares.pop_back();
        }
        const Vec3 xp = node_vec(nodes.x, gp), vp = node_vec(nodes.v, gp), up = node_vec(nodes.u, gp);
        const real_t mp = nodes.mass[static_cast<std::size_t>(gp)];
        Vec3 x[8];
        sl->split(p, spare, xp, x);
        const real_t* Gv = &G[18 * k];
        const real_t* Gu = &G[18 * k + 9];
        Vec3 v[8], mean = Vec3::Zero();
        for (int c = 0; c < 8; ++c)
        {
            v[c] = vp + times(Gv, x[c] - xp);
            mean += v[c] / 8.0;
        }
        const Vec3 shift = vp - mean; // the momentum of the particle, exactly
        kinetic -= 0.5 * mp * vp.squaredNorm();
        for (int c = 0; c < 8; ++c)
        {
            const index_t g = begin + (c == 0 ? p : spare[c - 1]);
            const Vec3 u = up + times(Gu, x[c] - xp), vc = v[c] + shift;
            set_node_vec(nodes.x, g, x[c]);
            set_node_vec(nodes.u, g, u);
            set_node_vec(nodes.x0, g, x[c] - u);
            set_node_vec(nodes.v, g, vc);
            set_node_vec(nodes.a, g, node_vec(nodes.a, gp));
            nodes.mass[static_cast<std::size_t>(g)] = mp / 8.0;
            kinetic += 0.5 * (mp / 8.0) * vc.squaredNorm();
        }
        families_[static_cast<std::size_t>(part)].push_back(
            {p, spare[0], spare[1], spare[2], spare[3], spare[4], spare[5], spare[6]});
    }
    event_kinetic_ += kinetic;
    refined_particles_ += static_cast<index_t>(splitting.size());
    refresh_refined_conditions();
    ++topology_version_;
    return static_cast<index_t>(splitting.size());
}

index_t Model::coarsen_particles(index_t part, const std::vector<char>& merge)
{
    const PartSpec& ps = deck_.parts[static_cast<std::size_t>(part)];
    SemiLagrangianForceBlock* sl = semi_lagrangian_block(part);
    RKFEM_REQUIRE(sl && ps.refinement.active(), "coarsening: part '" << ps.name << "' has no refinement");
    const index_t begin = parts[static_cast<std::size_t>(part)].node_begin;
    std::vector<std::array<index_t, 8>>& fam = families_[static_cast<std::size_t>(part)];
    index_t merged = 0;
    real_t kinetic = 0.0;
    // the latest splits first: a family whose members split again waits for theirs to merge
    for (std::size_t f = fam.size(); f-- > 0;)
    {
        const std::array<index_t, 8>& family = fam[f];
        bool ok = true;
        for (const index_t p : family)
            ok = ok && merge[static_cast<std::size_t>(p)] && !sl->dormant(p) && !sl->separated(p) &&
                 sl->level(p) == sl->level(family[0]);
        if (!ok)
            continue;
        real_t m = 0.0;
        Vec3 mx = Vec3::Zero(), mv = Vec3::Zero(), mu = Vec3::Zero(), x[8];
        for (int c = 0; c < 8; ++c)
        {
            const index_t g = begin + family[c];
            const real_t mc = nodes.mass[static_cast<std::size_t>(g)];
            x[c] = node_vec(nodes.x, g);
            m += mc;
            mx += mc * x[c];
            mv += mc * node_vec(nodes.v, g);
            mu += mc * node_vec(nodes.u, g);
            kinetic -= 0.5 * mc * node_vec(nodes.v, g).squaredNorm();
        }
        const Vec3 xs = mx / m, vs = mv / m, us = mu / m;
        const index_t kept[8] = {family[0], family[1], family[2], family[3],
                                 family[4], family[5], family[6], family[7]};
        sl->merge(kept, xs, x);
        const index_t g0 = begin + family[0];
        set_node_vec(nodes.x, g0, xs);
        set_node_vec(nodes.u, g0, us);
        set_node_vec(nodes.x0, g0, xs - us);
        set_node_vec(nodes.v, g0, vs);
        nodes.mass[static_cast<std::size_t>(g0)] = m;
        kinetic += 0.5 * m * vs.squaredNorm();
        // the others back to the pool: no mass, no motion, parked on the merged particle
        for (int c = 1; c < 8; ++c)
        {
            const index_t g = begin + family[c];
            set_node_vec(nodes.x, g, xs);
            set_node_vec(nodes.x0, g, xs);
            set_node_vec(nodes.u, g, Vec3::Zero());
            set_node_vec(nodes.v, g, Vec3::Zero());
            set_node_vec(nodes.a, g, Vec3::Zero());
            nodes.mass[static_cast<std::size_t>(g)] = 0.0;
        }
        fam.erase(fam.begin() + static_cast<std::ptrdiff_t>(f));
        ++merged;
    }
    if (merged == 0)
        return 0;
    event_kinetic_ += kinetic;
    coarsened_particles_ += merged;
    refresh_refined_conditions();
    ++topology_version_;
    return merged;
}

void Model::refresh_refined_conditions()
{
    // the per-condition state, by dof
    std::map<index_t, std::array<real_t, 3>> kept;
    for (std::size_t k = 0; k < conditions.size(); ++k)
        kept[conditions[k].dof] = {k < reaction_prev_.size() ? reaction_prev_[k] : 0.0,
                                   k < reaction_inertia_.size() ? reaction_inertia_[k] : 0.0,
                                   k < bc_v_prev_.size() ? bc_v_prev_[k] : 0.0};
    conditions = base_conditions_;
    std::map<index_t, std::vector<std::size_t>> of_node;
    for (std::size_t k = 0; k < conditions.size(); ++k)
        of_node[conditions[k].dof / 3].push_back(k);
    for (index_t ip = 0; ip < static_cast<index_t>(parts.size()); ++ip)
    {
        const index_t begin = parts[static_cast<std::size_t>(ip)].node_begin;
        for (const std::array<index_t, 8>& f : families_[static_cast<std::size_t>(ip)])
        {
            const auto it = of_node.find(begin + f[0]);
            if (it == of_node.end())
                continue;
            const std::vector<std::size_t> parent = it->second;
            for (int c = 1; c < 8; ++c)
                for (const std::size_t k : parent)
                {
                    DofCondition d = conditions[k];
                    d.dof = 3 * (begin + f[c]) + d.dof % 3;
                    of_node[begin + f[c]].push_back(conditions.size());
                    conditions.push_back(d);
                }
        }
    }
    const std::size_t n = conditions.size();
    reaction_prev_.assign(n, 0.0);
    reaction_inertia_.assign(n, 0.0);
    const bool had_v = !bc_v_prev_.empty();
    if (had_v)
        bc_v_prev_.assign(n, 0.0);
    for (std::size_t k = 0; k < n; ++k)
        if (const auto it = kept.find(conditions[k].dof); it != kept.end())
        {
            reaction_prev_[k] = it->second[0];
            reaction_inertia_[k] = it->second[1];
            if (had_v)
                bc_v_prev_[k] = it->second[2];
        }
    collect_constrained_dofs();
    plan_conditions();
}

bool Model::refinement_events(index_t part, real_t t)
{
    const RefinementSpec& r = deck_.parts[static_cast<std::size_t>(part)].refinement;
    if (!check_due(next_refinement_check_[static_cast<std::size_t>(part)], t, r.interval))
        return false;
    const SemiLagrangianForceBlock* sl = semi_lagrangian_block(part);
    const NodalBlock& st = *sl->nodal_points();
    const index_t begin = parts[static_cast<std::size_t>(part)].node_begin, n = sl->n_particles();
    // each active particle's indicator, from its committed state
    auto indicator = [&](index_t p) -> real_t
    {
        const std::size_t q = static_cast<std::size_t>(p);
        switch (r.indicator)
        {
        case RefinementSpec::Indicator::Damage:
            return st.plastic.active() ? st.plastic.damage(q) : 0.0;
        case RefinementSpec::Indicator::EffectivePlasticStrain:
            return st.plastic.active() && !st.plastic.eps_p.empty() ? st.plastic.eps_p[q] : 0.0;
        case RefinementSpec::Indicator::Pressure:
        case RefinementSpec::Indicator::VonMises:
        {
            real_t s[6];
            for (int k = 0; k < 6; ++k)
                s[k] = st.stress[k * st.stress_stride + q];
            const real_t p_mean = -(s[0] + s[1] + s[2]) / 3.0;
            if (r.indicator == RefinementSpec::Indicator::Pressure)
                return std::abs(p_mean);
            const real_t d0 = s[0] + p_mean, d1 = s[1] + p_mean, d2 = s[2] + p_mean;
            return std::sqrt(1.5 * (d0 * d0 + d1 * d1 + d2 * d2) + 3.0 * (s[3] * s[3] + s[4] * s[4] + s[5] * s[5]));
        }
        }
        return 0.0;
    };
    std::vector<char> split(static_cast<std::size_t>(n), 0), merge(static_cast<std::size_t>(n), 0);
    bool any_split = false, any_merge = false;
    for (index_t p = 0; p < n; ++p)
    {
        if (sl->dormant(p) || sl->separated(p))
            continue;
        const real_t value = indicator(p);
        if (value >= r.threshold && sl->level(p) < r.max_level)
        {
            bool inside = r.region.empty();
            for (const SelectorSpec& s : r.region)
                inside = inside || inside_region(s, node_vec(nodes.x, begin + p));
            split[static_cast<std::size_t>(p)] = inside;
            any_split = any_split || inside;
        }
        if (r.coarsen_below >= 0.0 && value < r.coarsen_below && sl->level(p) > 0)
        {
            merge[static_cast<std::size_t>(p)] = 1;
            any_merge = true;
        }
    }
    if (!any_split && !any_merge)
        return false;
    refresh_motion(); // the motion of the step, before the model changes
    bool changed = false;
    if (any_merge)
        changed = coarsen_particles(part, merge) > 0;
    if (any_split)
        changed = refine_particles(part, split) > 0 || changed;
    if (changed)
        refresh_contact_surfaces(); // the particles' spheres: the children's, of their own volumes
    return changed;
}
} // namespace rkfem
