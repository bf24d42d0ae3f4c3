// The explicit operator's phases (time/explicit_operator.hpp): state, forces, accelerations,
// checks, commit and energies.
#include "rkfem/model/model.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/operators/nodal_force.hpp"

namespace rkfem
{
void Model::update_coordinates()
{
    const index_t n3 = 3 * nodes.size();
    // u - u is 0 for finite u and NaN otherwise: the pass flags a value that is not (check())
    nonfinite_u_ = parallel_for_any("rkfem::coordinates", n3,
                                    [&](index_t i)
                                    {
                                        const real_t u = nodes.u[i];
                                        nodes.x[i] = nodes.x0[i] + u;
                                        return !(u - u == 0.0);
                                    });
}

void Model::set_state(const real_t* u, const real_t* v)
{
    const index_t n3 = 3 * nodes.size();
    nonfinite_u_ = parallel_for_any("rkfem::set_state", n3,
                                    [&](index_t i)
                                    {
                                        nodes.u[i] = u[i];
                                        nodes.v[i] = v[i];
                                        nodes.x[i] = nodes.x0[i] + u[i];
                                        return !(u[i] - u[i] == 0.0);
                                    });
}

ForceReport Model::internal_forces(real_t t, real_t dt, std::int64_t step)
{
    ForceReport rep;
    pending_int_ = pending_hg_ = pending_bv_ = 0.0;
    // energy increments and the controlling stable step of one block's pass
    std::fill(part_pending_.begin(), part_pending_.end(), PartEnergy{});
    auto book = [&](const ForcePassResult& r, index_t dt_element, std::size_t part)
    {
        pending_int_ += r.d_internal;
        pending_hg_ += r.d_hourglass;
        pending_bv_ += r.d_bulk_viscosity;
        part_pending_[part].internal += r.d_internal;
        part_pending_[part].hourglass += r.d_hourglass;
        part_pending_[part].bulk_viscosity += r.d_bulk_viscosity;
        if (r.dt_stable < rep.dt_stable)
        {
            rep.dt_stable = r.dt_stable;
            rep.dt_element = dt_element;
        }
    };
    // blocks whose node ranges overlap add into f_int, zeroed once here over those ranges; a
    // block alone on its nodes writes them (no clearing pass)
    for (const auto& [lo, hi] : shared_node_ranges_)
        std::fill(nodes.f_int.begin() + 3 * static_cast<std::ptrdiff_t>(lo),
                  nodes.f_int.begin() + 3 * static_cast<std::ptrdiff_t>(hi), 0.0);
    for (const PlannedBlock& pb : blocks_)
    {
        const ForcePassResult r = pb.block->add_forces(nodes, dt, pb.add);
        const PartInfo& part = parts[static_cast<std::size_t>(pb.part)];
        if (r.bad_element >= 0)
        {
            const PointFault f = pb.block->fault(r.bad_element, nodes);
            std::ostringstream os;
            if (f.at_node)
                os << "the integration point of " << part.node_name(f.node - part.node_begin);
            else
                os << part.element_name(f.element);
            os << " " << f.what << " at t = " << t << " s, step " << step;
            throw InstabilityError(os.str(), t);
        }
        book(r, part.element_offset + pb.block->part_element(r.dt_element), static_cast<std::size_t>(pb.part));
    }
    dt_critical_ = rep.dt_stable;
    dt_last_ = dt;
    return rep;
}

real_t Model::contact_step() const
{
    // contact bounds the step too (dt_element still names the element with the smallest)
    real_t dt = kNoLimit;
    for (const auto& c : contacts)
        dt = std::min(dt, c->stable_step());
    return dt;
}

void Model::external_forces(real_t t)
{
    apply_external_forces(t);
    if (contacts.empty())
        return;
    contact.clear();
    const PhysicalNodes physical_nodes(nodes, kinematics);
    const ContactClock clock{t, dt_critical_, dt_last_};
    for (auto& c : contacts)
        c->add_forces(physical_nodes, clock, contact);
}

void Model::accelerations()
{
    const real_t c = deck_.time.mass_damping;
    const index_t n = nodes.size();
    // a - a is 0 for finite a and NaN otherwise: the pass flags a value that is not (check())
    nonfinite_a_ = parallel_for_any("rkfem::accelerations", n,
                                    [&](index_t i)
                                    {
                                        // a refining part's pool of dormant particles has no mass
                                        const real_t m = nodes.mass[i];
                                        const real_t inv_m = m > 0.0 ? 1.0 / m : 0.0;
                                        real_t flag = 0.0;
                                        for (int k = 0; k < 3; ++k)
                                        {
                                            const std::size_t j = 3 * static_cast<std::size_t>(i) + k;
                                            const real_t a = (nodes.f_ext[j] - nodes.f_int[j]) * inv_m - c * nodes.v[j];
                                            nodes.a[j] = a;
                                            flag += a - a;
                                        }
                                        return !(flag == 0.0);
                                    });
    // contact forces: only on the nodes in contact this pass
    for (index_t i : contact.nodes())
    {
        const real_t inv_m = 1.0 / nodes.mass[i];
        for (int k = 0; k < 3; ++k)
        {
            real_t& a = nodes.a[3 * static_cast<std::size_t>(i) + k];
            a += contact.f[3 * static_cast<std::size_t>(i) + k] * inv_m;
            nonfinite_a_ = nonfinite_a_ || !(a - a == 0.0);
        }
    }
    for (const index_t j : constrained_dofs_)
        nodes.a[j] = 0.0;
}

void Model::commit()
{
    for (const PlannedBlock& pb : blocks_)
        pb.block->commit();
    energy.internal += pending_int_;
    energy.hourglass += pending_hg_;
    energy.bulk_viscosity += pending_bv_;
    pending_int_ = pending_hg_ = pending_bv_ = 0.0;
    for (std::size_t p = 0; p < part_pending_.size(); ++p)
    {
        part_energy_[p].internal += part_pending_[p].internal;
        part_energy_[p].hourglass += part_pending_[p].hourglass;
        part_energy_[p].bulk_viscosity += part_pending_[p].bulk_viscosity;
        part_pending_[p] = PartEnergy{};
    }
}

Model::PartSummary Model::part_summary(index_t part) const
{
    PartSummary s;
    s.internal = part_energy_[part].internal;
    s.hourglass = part_energy_[part].hourglass;
    s.bulk_viscosity = part_energy_[part].bulk_viscosity;
    // the last energy update's sums (a history row per step costs no pass); before any, a pass
    const std::array<real_t, 6> sum = static_cast<std::size_t>(part) < part_motion_.size()
                                          ? part_motion_[static_cast<std::size_t>(part)]
                                          : part_motion(part);
    s.kinetic = sum[0];
    s.mass = sum[2];
    s.momentum = Vec3(sum[3], sum[4], sum[5]);
    return s;
}

std::array<real_t, 6> Model::part_motion(index_t part) const
{
    const index_t b = parts[static_cast<std::size_t>(part)].node_begin;
    return parallel_reduce_sums<6>("rkfem::part_motion", parts[static_cast<std::size_t>(part)].node_end - b,
                                   [&](index_t k, std::array<real_t, 6>& out)
                                   {
                                       const index_t i = b + k;
                                       const std::size_t j = 3 * static_cast<std::size_t>(i);
                                       const real_t m = nodes.mass[i];
                                       const real_t vx = nodes.v[j], vy = nodes.v[j + 1], vz = nodes.v[j + 2];
                                       out[0] += 0.5 * m * (vx * vx + vy * vy + vz * vz);
                                       out[1] += m * (nodes.a[j] * nodes.a[j] + nodes.a[j + 1] * nodes.a[j + 1] +
                                                      nodes.a[j + 2] * nodes.a[j + 2]);
                                       out[2] += m;
                                       out[3] += m * vx;
                                       out[4] += m * vy;
                                       out[5] += m * vz;
                                   });
}

void Model::compute_motion(real_t dt)
{
    // One pass over the nodes, part by part (build() gives each part a contiguous node range, and
    // together they are the nodes): kinetic energy, the leapfrog correction's sum of m |a|^2, and
    // each part's mass and momentum, which history rows then read (part_summary).
    part_motion_.resize(parts.size());
    real_t kinetic = 0.0, m_a2 = 0.0;
    for (std::size_t p = 0; p < parts.size(); ++p)
    {
        part_motion_[p] = part_motion(static_cast<index_t>(p));
        kinetic += part_motion_[p][0];
        m_a2 += part_motion_[p][1];
    }
    energy.kinetic = kinetic;
    energy.kinetic_correction = -0.125 * dt * dt * m_a2;
    motion_stale_ = false;
}

void Model::refresh_motion()
{
    if (motion_stale_)
        compute_motion(motion_dt_);
}

void Model::update_energies(const real_t* u_prev, real_t dt)
{
    // the nodes' motion now, or when read (defer_motion); mass damping books 2 c E_kin dt
    if (dt > 0 && defer_motion_ && !(deck_.time.mass_damping > 0))
    {
        motion_stale_ = true;
        motion_dt_ = dt;
    }
    else
        compute_motion(dt);
    const index_t n_loaded = static_cast<index_t>(loaded_dofs_.size());
    auto keep_f_ext = [&]
    {
        for (index_t q = 0; q < n_loaded; ++q)
            f_ext_prev_[q] = nodes.f_ext[loaded_dofs_[q]];
    };
    if (dt <= 0)
    {
        // a (re)start: the forces of this state open the next step's trapezoids; after an event
        // the reactions are those of the new discretization, with the last step's inertia term
        // m a_p (a prescribed acceleration needs a step)
        keep_f_ext();
        contact.commit();
        forces_current_ = true;
        bc_v_prev_.resize(conditions.size());
        for (std::size_t k = 0; k < conditions.size(); ++k)
        {
            const index_t j = conditions[k].dof;
            bc_v_prev_[k] = nodes.v[j];
            reaction_prev_[k] =
                nodes.f_int[j] - nodes.f_ext[j] - contact.force(static_cast<std::size_t>(j)) + reaction_inertia_[k];
        }
        return;
    }
    // external work, trapezoid in time, over the loaded dofs (f_ext is zero elsewhere)
    energy.external_work +=
        parallel_reduce_sum("rkfem::external_work", n_loaded,
                            [&](index_t q)
                            {
                                const index_t j = loaded_dofs_[q];
                                return 0.5 * (f_ext_prev_[q] + nodes.f_ext[j]) * (nodes.u[j] - u_prev[j]);
                            });
    // work of reactions at prescribed dofs: R = f_int - f_ext + m a_prescribed; still dofs
    // (plan_conditions) do none, and their reactions are read from the forces when asked for
    forces_current_ = true;
    for (const index_t k : moving_conditions_)
    {
        const index_t j = conditions[k].dof;
        const real_t du = nodes.u[j] - u_prev[j];
        // prescribed acceleration over the step, from the imposed velocities
        const real_t ap = (nodes.v[j] - bc_v_prev_[k]) / dt;
        bc_v_prev_[k] = nodes.v[j];
        reaction_inertia_[k] = nodes.mass[j / 3] * ap;
        const real_t r =
            nodes.f_int[j] - nodes.f_ext[j] - contact.force(static_cast<std::size_t>(j)) + reaction_inertia_[k];
        energy.external_work += 0.5 * (reaction_prev_[k] + r) * du;
        reaction_prev_[k] = r;
    }
    // contact: the sliding energy is minus the work of the contact forces
    if (!contact.empty())
        energy.contact -= contact.step_work(nodes.u.data(), u_prev);
    contact.commit();
    // mass damping dissipation
    const real_t c = deck_.time.mass_damping;
    if (c > 0)
        energy.damping += dt * c * 2.0 * energy.kinetic;
    keep_f_ext();
}

void Model::check(real_t t, std::int64_t step) const
{
    // the passes that wrote x and a (update_coordinates or set_state, accelerations) flagged any
    // value that is not finite; only then a scan finds the first such node
    if (!nonfinite_u_ && !nonfinite_a_)
        return;
    const index_t n3 = 3 * nodes.size();
    const real_t* u = nodes.u.data();
    const real_t* a = nodes.a.data();
    index_t bad = 0;
    while (bad < n3 && std::isfinite(u[bad]) && std::isfinite(a[bad]))
        ++bad;
    if (bad == n3)
        return; // the state changed since (finite now)
    bad /= 3;
    std::ostringstream os;
    os << "non-finite acceleration or displacement at node " << bad << " (part '" << parts[nodes.part[bad]].name
       << "') at t = " << t << " s, step " << step;
    throw InstabilityError(os.str(), t);
}

std::vector<index_t> Model::velocity_driven_dofs() const
{
    std::vector<index_t> dofs;
    for (const DofCondition& c : conditions)
        if (c.kind != BoundarySpec::Kind::Fixed || carries_coefficients(c.dof / 3))
            dofs.push_back(c.dof);
    return dofs;
}
Vec3 Model::section_force(index_t section) const
{
    Vec3 f = Vec3::Zero();
    for (index_t i : section_nodes[section])
        f -= Vec3(nodes.f_int[3 * i], nodes.f_int[3 * i + 1], nodes.f_int[3 * i + 2]);
    return f;
}

Vec3 Model::reaction(index_t condition) const
{
    std::vector<Vec3> all;
    reactions(all);
    return all.at(static_cast<std::size_t>(condition));
}

void Model::reactions(std::vector<Vec3>& out) const
{
    const std::size_t n_bc = deck_.boundary_conditions.size();
    out.assign(n_bc, Vec3::Zero());
    if (n_bc == 0 || reaction_prev_.size() != conditions.size() || reaction_terms_.size() != conditions.size())
        return;
    // in the conditions' order, the sums as they were when every reaction was stored
    const bool lazy = forces_current_;
    real_t* sum = out.front().data(); // Vec3 is 3 packed doubles
    static_assert(sizeof(Vec3) == 3 * sizeof(real_t));
    for (std::size_t k = 0; k < reaction_terms_.size(); ++k)
    {
        const ReactionTerm& c = reaction_terms_[k];
        const real_t r = lazy && c.still ? still_reaction(c) : reaction_prev_[k];
        if (static_cast<std::size_t>(c.slot) < 3 * n_bc)
            sum[c.slot] += r;
    }
}
} // namespace rkfem
