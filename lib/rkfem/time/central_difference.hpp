#pragma once
/// @file central_difference.hpp
/// Explicit central difference with variable dt, in kick-drift-kick form:
///   v(n+1/2) = v(n) + dt/2 a(n);  u(n+1) = u(n) + dt v(n+1/2);  a(n+1);  v(n+1) = v(n+1/2) + dt/2 a(n+1)
/// which is algebraically the classical scheme v(n+1/2) = v(n-1/2) + (dt(n-1) + dt(n))/2 a(n), and
/// keeps full-step velocities for energies and output.
#include <cstdint>
#include <vector>

#include "rkfem/time/stepper.hpp"

namespace rkfem
{
struct NodeSet;
class ExplicitOperator;

/// The common start of every stepper: prescribed velocities at t, forces and accelerations with
/// no material increment, committed state, initial energies; reports the stable step.
StepReport start_model(ExplicitOperator& model, real_t t);

/// v += h a over all nodes (one half kick); v before it into v_before when given (3 n values).
void central_difference_kick(NodeSet& nodes, real_t h, real_t* v_before = nullptr);
/// u += dt v over all nodes; u before it into u_before when given (3 n values).
void central_difference_drift(NodeSet& nodes, real_t dt, real_t* u_before = nullptr);

class CentralDifference final : public TimeStepper
{
  public:
    StepReport initialize(ExplicitOperator& model, real_t t) override;
    StepReport step(ExplicitOperator& model, real_t t, real_t dt, std::int64_t step_index) override;
    const char* name() const override { return "central-difference"; }
    bool restore_last_good(ExplicitOperator& model) override;
    /// Between steps the central difference holds nothing the model does not (u, v, a): a
    /// checkpoint adds nothing, and continuing needs no start.
    void save_state(StateArchive&) const override {}
    void load_state(ExplicitOperator&, real_t, const StateArchive&) override { in_step_ = false; }

  private:
    std::vector<real_t> u_prev_; ///< displacement at the start of the step (work bookkeeping)
    std::vector<real_t> v_prev_; ///< velocity at the start of the step (the last good state)
    bool in_step_ = false;       ///< a step began and did not finish: u_prev_, v_prev_ hold its start
};
} // namespace rkfem
