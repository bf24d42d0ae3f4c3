#pragma once
/// @file stepper.hpp
/// Steppers see an explicit operator (explicit_operator.hpp: the phases of a step) and advance it.
/// The hand-written central difference and the SUNDIALS ARKODE steppers implement this one
/// interface.
#include <cstdint>
#include <memory>
#include <string>

#include "rkfem/core/error.hpp"
#include "rkfem/core/types.hpp"
#include "rkfem/time/time_spec.hpp"

namespace rkfem
{
class ExplicitOperator;
class StateArchive;

struct StepReport
{
    real_t t = 0.0;          ///< time reached [s]
    real_t dt = 0.0;         ///< step just taken [s]
    real_t dt_stable = 0.0;  ///< stable step found in this step's force pass (unscaled) [s]
    index_t dt_element = -1; ///< element that controls it
};

class TimeStepper
{
  public:
    virtual ~TimeStepper() = default;
    /// Prepares the operator at time t (initial forces, accelerations, energies). Call again after
    /// the discretization changes: the trajectory and the energy ledger continue.
    virtual StepReport initialize(ExplicitOperator& model, real_t t) = 0;
    /// Advances from t by dt; commits material state when the step is accepted.
    /// Throws InstabilityError when the step cannot be completed.
    virtual StepReport step(ExplicitOperator& model, real_t t, real_t dt, std::int64_t step_index) = 0;
    virtual const char* name() const = 0;
    /// After step() threw: puts the state the failed step started from (u, v and x of the last
    /// accepted step) back into the operator's nodes; the material's committed state is already
    /// that step's. False when there is no failed step to undo. The stepper is not used again.
    virtual bool restore_last_good(ExplicitOperator& /*model*/) { return false; }
    /// A checkpoint's share of the stepper's state between steps (save_state), and continuing
    /// from it in place of initialize() (load_state, after the model loaded its own state): the
    /// next step() then takes the same bits as the run that wrote it. Steppers whose state is
    /// not covered throw Error.
    virtual void save_state(StateArchive& /*archive*/) const
    {
        throw Error(std::string("checkpoints do not cover time.stepper ") + name() +
                    " yet; expected central-difference");
    }
    virtual void load_state(ExplicitOperator& /*model*/, real_t /*t*/, const StateArchive& /*archive*/)
    {
        throw Error(std::string("checkpoints do not cover time.stepper ") + name() +
                    " yet; expected central-difference");
    }
};

/// The step the run loop takes next: dt_scale * dt_stable, capped by dt_max and by the end time.
/// The ARKODE central difference evaluates the same rule inside its right-hand side (it needs the
/// next step when it forms the kick), so both steppers follow one dt sequence.
inline real_t next_time_step(const TimeSpec& ts, real_t t, real_t dt_stable)
{
    real_t dt = ts.dt_scale * dt_stable;
    if (ts.dt_max > 0 && dt > ts.dt_max)
        dt = ts.dt_max;
    if (t + dt > ts.end)
        dt = ts.end - t;
    return dt;
}

/// A stepper for the deck's time section (central difference, arkode-cd, arkode-erk + table).
std::unique_ptr<TimeStepper> make_stepper(const TimeSpec& ts);
} // namespace rkfem
