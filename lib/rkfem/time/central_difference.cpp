#include "rkfem/time/central_difference.hpp"

#include <cmath>
#include <sstream>

#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/time/arkode_stepper.hpp"

namespace rkfem
{
void central_difference_kick(NodeSet& n, real_t h)
{
    const index_t n3 = 3 * n.size();
    parallel_for("rkfem::cd::kick", n3, [&](index_t j) { n.v[j] += h * n.a[j]; });
}

void central_difference_drift(NodeSet& n, real_t dt)
{
    const index_t n3 = 3 * n.size();
    parallel_for("rkfem::cd::drift", n3, [&](index_t j) { n.u[j] += dt * n.v[j]; });
}

void check_finite(const Model& m, real_t t, std::int64_t step)
{
    const NodeSet& n = m.nodes;
    const index_t n3 = 3 * n.size();
    const real_t* u = n.u.data();
    const real_t* a = n.a.data();
    // x - x is 0 for finite x and NaN otherwise: one vectorized sum finds whether any value is
    // not finite; only then a scan finds the first such node
    const real_t s = parallel_reduce_sum("rkfem::check_finite", n3, [&](index_t j) { return (u[j] - u[j]) + (a[j] - a[j]); });
    if (s == 0.0)
        return;
    index_t bad = 0;
    while (bad < n3 && std::isfinite(u[bad]) && std::isfinite(a[bad]))
        ++bad;
    bad /= 3;
    std::ostringstream os;
    os << "non-finite acceleration or displacement at node " << bad << " (part '" << m.parts[n.part[bad]].name
       << "') at t = " << t << " s, step " << step;
    throw InstabilityError(os.str());
}

StepReport start_model(Model& model, real_t t)
{
    model.impose_velocity(t, 0.0, false);
    model.update_coordinates();
    const ForceReport fr = model.compute_forces(t, 0.0, 0);
    model.compute_accelerations();
    check_finite(model, t, 0);
    model.commit();
    model.update_energies(model.nodes.u, 0.0);
    model.energy.kinetic0 = model.energy.kinetic + model.energy.kinetic_correction;
    model.energy.internal0 = model.energy.internal;
    StepReport r;
    r.t = t;
    r.dt_stable = fr.dt_stable;
    r.dt_element = fr.dt_element;
    return r;
}

StepReport CentralDifference::initialize(Model& model, real_t t) { return start_model(model, t); }


StepReport CentralDifference::step(Model& model, real_t t, real_t dt, std::int64_t step_index)
{
    NodeSet& n = model.nodes;
    u_prev_ = n.u; // capacity is reused after the first step
    central_difference_kick(n, 0.5 * dt);
    model.impose_velocity(t, dt, true);
    central_difference_drift(n, dt);
    model.update_coordinates();
    const ForceReport fr = model.compute_forces(t + dt, dt, step_index);
    model.compute_accelerations();
    check_finite(model, t + dt, step_index);
    central_difference_kick(n, 0.5 * dt);
    model.impose_velocity(t + dt, dt, false);
    model.commit();
    model.update_energies(u_prev_, dt);
    StepReport r;
    r.t = t + dt;
    r.dt = dt;
    r.dt_stable = fr.dt_stable;
    r.dt_element = fr.dt_element;
    return r;
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
