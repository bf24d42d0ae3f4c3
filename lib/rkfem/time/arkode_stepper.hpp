#pragma once
/// @file arkode_stepper.hpp
/// Explicit time integration through SUNDIALS ARKODE ERKStep (Debian 12: SUNDIALS 6.4.1), behind
/// the same TimeStepper interface as the hand-written central difference. State y = (u, v).
///
/// Mode CentralDifference (`arkode-cd`): a 1-stage forward-Euler table with the right-hand side
///   u' = v + h s a,  v' = s a,  s = (h_prev + h) / (2 h),
/// so one ERK step is v(n+1/2) = v(n-1/2) + (h_prev + h)/2 a(n), u(n+1) = u(n) + h v(n+1/2): the
/// variable-step central difference with one force evaluation per step. Prescribed velocities are
/// imposed on the kicked velocity inside the right-hand side. h is the next step, computed by
/// next_time_step() from the stable step of the same force pass, exactly as the run loop does.
///
/// Mode RungeKutta (`arkode-erk`): u' = v, v' = a(u, v) with a built-in or rkfem-built ERK table.
/// Every stage starts the material update from the committed state at t_n with the stage's
/// displacement increment (kernels see v = (u_stage - u_n) / (t_stage - t_n)), and the state is
/// committed only after the step, from a fresh right-hand side at y(n+1).
///
/// Around the three defects of Debian's 6.4.1 (SUNDIALS 6.7.0 CHANGELOG: the ERKStep FSAL fix;
/// LLNL/sundials PR #422: no optimisation in the default build; 6.4.1 src/arkode/arkode.c, arkEvolve):
/// a registered post-process step function forces a fresh f(y(n+1)) (the FSAL bug), the state is
/// rkfem's own N_Vector (state_vector.hpp: -O3 OpenMP loops, where Debian builds SUNDIALS at -O0;
/// ARKODE's four per-step copies of the state share storage instead of copying it; the
/// right-hand side works on the state in place), and error weights of zero, set once, avoid the
/// denormal WRMS norm of fixed-step mode (with rkfem's vectors the norm then reads nothing).
/// With rkfem's vectors, nodes.u between steps is ARKODE's state itself (lent, not copied):
/// whoever changes the state between steps calls initialize() again, as after any change of
/// the discretization.
#include <memory>
#include <string>
#include <vector>

#include "rkfem/time/erk_tables.hpp"

#include "rkfem/time/stepper.hpp"

namespace rkfem
{
class StatePool;

class ArkodeStepper final : public TimeStepper
{
  public:
    enum class Mode
    {
        CentralDifference,
        RungeKutta,
    };
    /// `project_vector_ops` = false uses Debian's own serial vector and its (unoptimised)
    /// operations, copying the state in and out of the model, for the benchmark that shows what
    /// rkfem's vectors buy.
    /// `fsal_workaround` = false leaves out the post-process step function (only for the test that
    /// shows Debian's 6.4.1 FSAL bug: classical RK4 then converges at order 3).
    ArkodeStepper(Mode mode, const TimeSpec& ts, bool project_vector_ops = true, bool fsal_workaround = true);
    ~ArkodeStepper() override;
    StepReport initialize(ExplicitOperator& model, real_t t) override;
    StepReport step(ExplicitOperator& model, real_t t, real_t dt, std::int64_t step_index) override;
    const char* name() const override { return mode_ == Mode::CentralDifference ? "arkode-cd" : "arkode-erk"; }
    bool restore_last_good(ExplicitOperator& model) override;
    /// y(n) (its v half is v(n - 1/2) for the central difference), the step sizes and the last
    /// force report. load_state makes a fresh ARKODE from them whose first evaluation, at y(n),
    /// reuses the model's restored accelerations instead of a force pass: the evaluation the
    /// checkpoint was written after, which the uninterrupted run did once.
    void save_state(StateArchive& archive) const override;
    void load_state(ExplicitOperator& model, real_t t, const StateArchive& archive) override;

    long rhs_evaluations() const { return n_rhs_; }
    /// rkfem's state vectors of the current run (null before initialize() and with Debian's).
    const StatePool* state_pool() const;

    struct Impl;

  private:
    /// ARKODE (context, state vector y = (y_u, y_v), ERKStep and its settings) at t.
    void create(ExplicitOperator& model, real_t t, const real_t* y_u, const real_t* y_v);
    Mode mode_;
    TimeSpec ts_;
    bool project_ops_;
    bool fsal_workaround_;
    /// an ERK table's step as a share of the central difference's: its imaginary stability
    /// interval over the central difference's 2, at most 1 (1 for the central difference)
    real_t step_share_ = 1.0;
    std::unique_ptr<Impl> impl_;
    long n_rhs_ = 0;
    friend struct Impl;
};

/// The arkode-cd kick over n values, one pass: v(n) = v(n-1/2) + h_prev/2 a(n) into v_full,
/// v(n+1/2) = v(n) + h/2 a(n) into du (u' of the right-hand side), and, unless dv is null (rkfem's
/// vectors record it instead), v' = (v(n+1/2) - v(n-1/2)) / h into dv. Exposed for its test.
void arkode_cd_kick(index_t n, const real_t* v, const real_t* a, real_t h_prev, real_t h, real_t* v_full, real_t* du,
                    real_t* dv);
} // namespace rkfem
