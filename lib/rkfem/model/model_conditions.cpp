// GCC 12 reports a false "may be used uninitialized" inside Eigen's AVX-512 kernels (dense LU
// here); every value is initialised.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

// Prescribed motion: velocities of constrained dofs, and on RK particles the physical
// velocity through the mixed transformation (Chen & Wang 2000).
#include "rkfem/model/model.hpp"

#include <Eigen/KLUSupport>
#include <algorithm>
#include <memory>

#include "rkfem/core/error.hpp"
#include "rkfem/operators/linear_static.hpp"

namespace rkfem
{
struct RkVelocityConstraint
{
    index_t block = 0; ///< the part whose nodal block it constrains
    int component = 0;
    std::vector<index_t> condition; ///< index into Model::conditions, per constrained node
    std::vector<index_t> node;      ///< global node per constrained node
    std::vector<index_t> slot;      ///< global node -> position in `node`, -1 if free (block range)
    /// Every condition holds its particle fixed and no row reaches a free particle: the
    /// right-hand side is 0 at every step, and so is the solution (no factor is kept). A column
    /// with rollers on every particle (uniaxial strain) is one.
    bool at_rest = false;
    /// Lambda_bb (not factored when at_rest), by SuiteSparse's KLU: its factor holds L and U
    /// alone (Eigen's SparseLU kept about 20x the matrix's entries of workspace: 611 bytes per
    /// particle of the P1 cylinder), and its solve allocates nothing
    Eigen::KLU<SparseMatrix> lu;
    Eigen::VectorXd rhs, x;
    /// per constrained node q: its row's entries on free particles, in row order (the dof
    /// 3 J + component and Lambda_qJ), [free_offsets[q], free_offsets[q + 1]): what the step's
    /// right-hand side subtracts, read as flat arrays rather than searched row by row
    std::vector<index_t> free_offsets, free_dof;
    std::vector<real_t> free_w;
};

void Model::impose_velocity(real_t t, real_t dt, bool half_step)
{
    impose_velocity(t, dt, half_step, nodes.v.data());
}

void Model::collect_constrained_dofs()
{
    constrained_dofs_.clear();
    for (const DofCondition& c : conditions)
        constrained_dofs_.push_back(c.dof);
    std::sort(constrained_dofs_.begin(), constrained_dofs_.end());
}

void Model::plan_conditions()
{
    still_conditions_.clear();
    still_dofs_.clear();
    moving_conditions_.clear();
    for (index_t k = 0; k < static_cast<index_t>(conditions.size()); ++k)
    {
        const DofCondition& c = conditions[k];
        if (c.kind == BoundarySpec::Kind::Fixed && !kinematics.carries_coefficients(c.dof / 3))
        {
            still_conditions_.push_back(k);
            still_dofs_.push_back(c.dof);
        }
        else
            moving_conditions_.push_back(k);
    }
    std::sort(still_dofs_.begin(), still_dofs_.end());
    reaction_terms_.assign(conditions.size(), ReactionTerm{});
    for (std::size_t k = 0; k < conditions.size(); ++k)
        reaction_terms_[k] = {conditions[k].dof, 3 * static_cast<int>(conditions[k].source) + conditions[k].dof % 3, 0};
    for (const index_t k : still_conditions_)
        reaction_terms_[k].still =
            std::binary_search(loaded_dofs_.begin(), loaded_dofs_.end(), conditions[k].dof) ? 2 : 1;
}

real_t Model::still_reaction(const ReactionTerm& c) const
{
    // f_int - f_ext - f_contact (its m a_p is 0): f_ext is zero off the loaded dofs, and the
    // contact channel's forces off the nodes of its pass
    real_t r = nodes.f_int[c.dof];
    if (c.still == 2)
        r -= nodes.f_ext[c.dof];
    if (!contact.nodes().empty())
        r -= contact.f[c.dof];
    return r;
}

void Model::fill_still_reactions(std::vector<real_t>& reaction) const
{
    for (const index_t k : still_conditions_)
        reaction[k] = still_reaction(reaction_terms_[k]);
}

void Model::impose_velocity(real_t t, real_t dt, bool half_step, real_t* vel)
{
    for (const index_t j : still_dofs_)
        vel[j] = 0.0;
    for (const index_t k : moving_conditions_)
    {
        const DofCondition& c = conditions[k];
        real_t v = 0.0;
        switch (c.kind)
        {
        case BoundarySpec::Kind::Fixed:
            v = 0.0;
            break;
        case BoundarySpec::Kind::Velocity:
            v = (*c.value)(half_step ? t + 0.5 * dt : t);
            break;
        case BoundarySpec::Kind::Displacement:
            if (half_step)
                v = dt > 0 ? ((*c.value)(t + dt) - nodes.u[c.dof]) / dt : 0.0;
            else
            {
                const real_t h = dt > 0 ? dt : 1e-9;
                v = ((*c.value)(t + h) - (*c.value)(t)) / h;
            }
            break;
        }
        vel[c.dof] = v;
    }
    // rkpm parts: the values just set are targets for the physical velocity
    for (auto& rc : rk_constraints_)
    {
        const int k = rc->component;
        const index_t nb_count = static_cast<index_t>(rc->node.size());
        if (rc->at_rest)
        {
            for (index_t q = 0; q < nb_count; ++q)
                vel[3 * rc->node[q] + k] = 0.0;
            continue;
        }
        for (index_t q = 0; q < nb_count; ++q)
        {
            real_t r = vel[3 * rc->node[q] + k];
            if (conditions[rc->condition[q]].kind == BoundarySpec::Kind::Displacement && half_step)
            {
                // target from the physical displacement: (g(t + dt) - u^h(X_b)) / dt
                const DofCondition& c = conditions[rc->condition[q]];
                const real_t uh = physical(nodes.u, rc->node[q])[k];
                r = dt > 0 ? ((*c.value)(t + dt) - uh) / dt : 0.0;
            }
            for (index_t e = rc->free_offsets[q]; e < rc->free_offsets[q + 1]; ++e)
                r -= rc->free_w[e] * vel[rc->free_dof[e]];
            rc->rhs[q] = r;
        }
        rc->x = rc->lu.solve(rc->rhs);
        for (index_t q = 0; q < nb_count; ++q)
            vel[3 * rc->node[q] + k] = rc->x[q];
    }
}

void Model::build_rk_constraints()
{
    for (index_t ip = 0; ip < static_cast<index_t>(parts.size()); ++ip)
    {
        if (!nodal_block(ip))
            continue;
        const NodalBlock& nb = *nodal_block(ip);
        bool any = false;
        for (index_t i = nb.node_begin; i < nb.node_end && !any; ++i)
            any = kinematics.carries_coefficients(i);
        if (!any)
            continue;
        for (int k = 0; k < 3; ++k)
        {
            auto rc = std::make_shared<RkVelocityConstraint>();
            rc->block = ip;
            rc->component = k;
            rc->slot.assign(static_cast<std::size_t>(nb.node_end - nb.node_begin), -1);
            for (index_t ci = 0; ci < static_cast<index_t>(conditions.size()); ++ci)
            {
                const index_t n = conditions[ci].dof / 3;
                if (conditions[ci].dof % 3 != k || n < nb.node_begin || n >= nb.node_end)
                    continue;
                rc->slot[n - nb.node_begin] = static_cast<index_t>(rc->node.size());
                rc->node.push_back(n);
                rc->condition.push_back(ci);
            }
            if (rc->node.empty())
                continue;
            const index_t m = static_cast<index_t>(rc->node.size());
            std::vector<Eigen::Triplet<real_t, int>> t;
            // the rows' entries on constrained particles make Lambda_bb; those on free ones, in
            // row order, are what the step's right-hand side subtracts
            rc->free_offsets.assign(1, 0);
            for (index_t q = 0; q < m; ++q)
            {
                kinematics.for_row(rc->node[q],
                                   [&](index_t J, real_t w)
                                   {
                                       const index_t col = rc->slot[J - nb.node_begin];
                                       if (col >= 0)
                                           t.emplace_back(q, col, w);
                                       else
                                       {
                                           rc->free_dof.push_back(3 * J + k);
                                           rc->free_w.push_back(w);
                                       }
                                   });
                rc->free_offsets.push_back(static_cast<index_t>(rc->free_dof.size()));
            }
            const bool reaches_free = !rc->free_dof.empty();
            rc->at_rest = !reaches_free &&
                          std::all_of(rc->condition.begin(), rc->condition.end(),
                                      [&](index_t ci) { return conditions[ci].kind == BoundarySpec::Kind::Fixed; });
            if (rc->at_rest)
            {
                rk_constraints_.push_back(std::move(rc));
                continue;
            }
            SparseMatrix A(m, m);
            A.setFromTriplets(t.begin(), t.end());
            rc->lu.compute(A);
            if (rc->lu.info() != Eigen::Success)
            {
                const auto& bc = deck_.boundary_conditions;
                const std::string where = bc.empty() ? deck_.path : bc.front().loc.where;
                throw DeckError(
                    {where, "boundary_conditions"},
                    "the RK interpolation matrix of the " + std::to_string(m) + " particles constrained in component " +
                        std::to_string(k) + " of part '" + parts[nb.part].name + "' is singular",
                    "expected constrained particle sets whose kernel functions are independent (e.g. whole faces)");
            }
            rc->rhs.resize(m);
            rc->x.resize(m);
            rk_constraints_.push_back(std::move(rc));
        }
    }
}
} // namespace rkfem
