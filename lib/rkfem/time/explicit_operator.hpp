#pragma once
/// @file explicit_operator.hpp
/// What a time stepper sees of a model: the nodal state and the named phases of one explicit
/// step (docs/architecture.md, "One explicit step"). Steppers depend on this
/// interface alone; `Model` builds the discretization and implements it, and the run loop with
/// its observers sits above both.
///
/// One evaluation at a state (u, v) is: set state (or update coordinates after the stepper moved
/// nodes.u itself), refresh, internal forces, external and contact forces, accelerations,
/// checks. After an accepted step: commit, then energies. A discretization change is an event
/// between steps; the stepper is then started again (its initialize()) and the energy ledger
/// continues (Energies::start records the origin once).
#include <algorithm>
#include <cstdint>
#include <vector>

#include "rkfem/core/types.hpp"
#include "rkfem/discretization/node_set.hpp"
#include "rkfem/operators/energy_ledger.hpp"

namespace rkfem
{
class ExplicitOperator
{
  public:
    virtual ~ExplicitOperator() = default;

    virtual NodeSet& state() = 0;
    virtual const NodeSet& state() const = 0;
    virtual Energies& ledger() = 0;

    // ---- set state ----
    /// Prescribed velocities for the interval (t, t + dt) (half_step) or at t, written into v
    /// (3 n values; the unconstrained ones are read, as constraints on RK coefficients need them).
    virtual void impose_velocity(real_t t, real_t dt, bool half_step, real_t* v) = 0;
    /// x = x0 + u from nodes.u (after the stepper moved it in place).
    virtual void update_coordinates() = 0;
    /// u, v (3 n each) from a stepper's vector, then x = x0 + u, in one pass.
    virtual void set_state(const real_t* u, const real_t* v) = 0;
    /// Degrees of freedom with a prescribed condition (fixed, velocity, displacement), ascending.
    virtual const std::vector<index_t>& constrained_dofs() const = 0;
    /// Degrees of freedom whose velocity is not the integral of their acceleration (prescribed
    /// non-zero motion, or RK coefficients solved from a constraint): a stepper that integrates
    /// v' must set v' there from the imposed velocities.
    virtual std::vector<index_t> velocity_driven_dofs() const = 0;

    // ---- evaluation ----
    /// Tables and neighbours that follow the motion (semi-Lagrangian blocks, contact search).
    virtual void refresh(real_t /*t*/) {}
    /// f_int from every block (zeroed once, each block adds), trial material state over a step
    /// dt (0: no increment); the smallest stable step. Throws InstabilityError on a bad point.
    virtual ForceReport internal_forces(real_t t, real_t dt, std::int64_t step) = 0;
    /// f_ext (loads at t, fixed dofs) and the contact channel (changing dofs).
    virtual void external_forces(real_t t) = 0;
    /// The step the contact found stable in the last external_forces [s] (kernel contact's
    /// closing pairs, penalty springs).
    virtual real_t contact_step() const { return kNoLimit; }
    /// a = (f_ext + f_contact - f_int) / m - c v; zero on constrained dofs.
    virtual void accelerations() = 0;
    /// Throws InstabilityError naming where and when the state is not finite.
    virtual void check(real_t t, std::int64_t step) const = 0;

    // ---- after an accepted step ----
    /// Commits material trial state and books the step's energy increments.
    virtual void commit() = 0;
    /// Kinetic energy, and the work of loads, reactions and contact over a step whose
    /// displacement increment is u - u_prev (dt = 0: no step, the forces are kept as the start).
    virtual void update_energies(const real_t* u_prev, real_t dt) = 0;

    /// refresh + internal forces + external and contact forces: one force evaluation.
    ForceReport compute_forces(real_t t, real_t dt, std::int64_t step)
    {
        refresh(t);
        ForceReport r = internal_forces(t, dt, step);
        external_forces(t);
        // the contact's bound from this evaluation, not the last one: pairs that formed in it
        // (fragments that separated at the last commit) bound the next step already
        r.dt_stable = std::min(r.dt_stable, contact_step());
        return r;
    }
};
} // namespace rkfem
