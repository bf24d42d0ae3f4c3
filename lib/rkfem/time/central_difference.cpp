#include "rkfem/time/central_difference.hpp"

#include <cmath>
#include <sstream>

#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/time/arkode_stepper.hpp"
#include "rkfem/time/explicit_operator.hpp"

namespace rkfem
{
void central_difference_kick(NodeSet& n, real_t h, real_t* v_before)
{
    const index_t n3 = 3 * n.size();
    if (v_before == nullptr)
        parallel_for("rkfem::cd::kick", n3, [&](index_t j) { n.v[j] += h * n.a[j]; });
    else
        parallel_for("rkfem::cd::kick", n3,
                     [&](index_t j)
                     {
                         v_before[j] = n.v[j];
                         n.v[j] += h * n.a[j];
                     });
}

void central_difference_drift(NodeSet& n, real_t dt, real_t* u_before)
{
    const index_t n3 = 3 * n.size();
    if (u_before == nullptr)
        parallel_for("rkfem::cd::drift", n3, [&](index_t j) { n.u[j] += dt * n.v[j]; });
    else
        parallel_for("rkfem::cd::drift", n3,
                     [&](index_t j)
                     {
                         u_before[j] = n.u[j];
                         n.u[j] += dt * n.v[j];
                     });
}

StepReport start_model(ExplicitOperator& model, real_t t)
{
    NodeSet& n = model.state();
    model.impose_velocity(t, 0.0, false, n.v.data());
    model.update_coordinates();
    const ForceReport fr = model.compute_forces(t, 0.0, 0);
    model.accelerations();
    model.check(t, 0);
    model.commit();
    model.update_energies(n.u.data(), 0.0);
    model.ledger().start(); // the first start only: a restart continues the ledger
    StepReport r;
    r.t = t;
    r.dt_stable = fr.dt_stable;
    r.dt_element = fr.dt_element;
    return r;
}

StepReport CentralDifference::initialize(ExplicitOperator& model, real_t t)
{
    return start_model(model, t);
}

StepReport CentralDifference::step(ExplicitOperator& model, real_t t, real_t dt, std::int64_t step_index)
{
    NodeSet& n = model.state();
    // the start of the step, copied in the passes that move it (capacity is reused after the
    // first step): u(n) for the work of the step, u(n) and v(n) for a failure in it
    u_prev_.resize(n.u.size());
    v_prev_.resize(n.v.size());
    in_step_ = true;
    central_difference_kick(n, 0.5 * dt, v_prev_.data());
    model.impose_velocity(t, dt, true, n.v.data());
    central_difference_drift(n, dt, u_prev_.data());
    model.update_coordinates();
    const ForceReport fr = model.compute_forces(t + dt, dt, step_index);
    model.accelerations();
    model.check(t + dt, step_index);
    central_difference_kick(n, 0.5 * dt);
    model.impose_velocity(t + dt, dt, false, n.v.data());
    model.commit();
    model.update_energies(u_prev_.data(), dt);
    in_step_ = false;
    StepReport r;
    r.t = t + dt;
    r.dt = dt;
    r.dt_stable = fr.dt_stable;
    r.dt_element = fr.dt_element;
    return r;
}

bool CentralDifference::restore_last_good(ExplicitOperator& model)
{
    if (!in_step_)
        return false;
    NodeSet& n = model.state();
    n.u = u_prev_;
    n.v = v_prev_;
    model.update_coordinates();
    in_step_ = false;
    return true;
}

std::unique_ptr<TimeStepper> make_stepper(const TimeSpec& ts)
{
    switch (ts.stepper)
    {
    case StepperKind::CentralDifference:
        return std::make_unique<CentralDifference>();
    case StepperKind::ArkodeCd:
        return std::make_unique<ArkodeStepper>(ArkodeStepper::Mode::CentralDifference, ts);
    case StepperKind::ArkodeErk:
        return std::make_unique<ArkodeStepper>(ArkodeStepper::Mode::RungeKutta, ts);
    }
    throw Error("unknown stepper");
}
} // namespace rkfem
