#include "rkfem/time/arkode_stepper.hpp"

#include <algorithm>
#include <arkode/arkode_erkstep.h>
#include <cmath>
#include <exception>
#include <nvector/nvector_serial.h>
#include <string>
#include <vector>

#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/state_archive.hpp"
#include "rkfem/core/stream_stores.hpp"
#include "rkfem/time/central_difference.hpp"
#include "rkfem/time/explicit_operator.hpp"
#include "rkfem/time/state_vector.hpp"

namespace rkfem
{
namespace
{
inline real_t* data(N_Vector v)
{
    return NV_DATA_S(v);
}

void cd_kick_range(index_t j0, index_t j1, const real_t* __restrict v, const real_t* __restrict a, real_t h_prev,
                   real_t h, real_t* __restrict v_full, real_t* __restrict du, real_t* __restrict dv,
                   [[maybe_unused]] bool stream)
{
    const real_t inv_h = 1.0 / h;
#if defined(__AVX512F__)
    if (stream) // (set only without dv)
    {
        const simd::dvec c0 = simd::broadcast(0.5 * h_prev), c1 = simd::broadcast(0.5 * h);
        auto vf = [&](index_t j) { return v[j] + 0.5 * h_prev * a[j]; };
        auto vf8 = [&](index_t j) { return simd::mul_add(c0, simd::load(a + j), simd::load(v + j)); };
        stream_range(j0, j1, v_full, vf, vf8);
        stream_range(
            j0, j1, du, [&](index_t j) { return vf(j) + 0.5 * h * a[j]; },
            [&](index_t j) { return simd::mul_add(c1, simd::load(a + j), vf8(j)); });
        simd::stream_fence();
        return;
    }
#endif
    for (index_t j = j0; j < j1; ++j)
    {
        const real_t vf = v[j] + 0.5 * h_prev * a[j];
        const real_t vk = vf + 0.5 * h * a[j];
        v_full[j] = vf;
        du[j] = vk;
        if (dv != nullptr)
            dv[j] = (vk - v[j]) * inv_h;
    }
}
} // namespace

/// Blocks of contiguous values with unaliased pointers, so the loop vectorizes (the dv test is
/// the same for the whole loop); arrays far larger than the caches are written with streaming
/// stores (stream_stores.hpp).
void arkode_cd_kick(index_t n, const real_t* v, const real_t* a, real_t h_prev, real_t h, real_t* v_full, real_t* du,
                    real_t* dv)
{
    constexpr index_t block = 2048;
    const bool stream = dv == nullptr && stream_pays(n);
    parallel_for("rkfem::arkode_cd::kick", (n + block - 1) / block,
                 [&](index_t b)
                 { cd_kick_range(b * block, std::min(n, (b + 1) * block), v, a, h_prev, h, v_full, du, dv, stream); });
}

struct ArkodeStepper::Impl
{
    ArkodeStepper* self = nullptr;
    SUNContext ctx = nullptr;
    N_Vector y = nullptr;
    void* mem = nullptr;
    ARKodeButcherTable table = nullptr;
    /// rkfem's state vectors (shared copies, lending to the NodeSet); null with Debian's own
    /// serial vector over `state`
    std::shared_ptr<StatePool> pool;
    std::vector<real_t> state; ///< (u, v), 6 n: the serial vector's values
    ExplicitOperator* model = nullptr;
    index_t n3 = 0;
    /// ARKODE's own last error line: kept for rkfem's message instead of printed to stderr
    std::string arkode_message;
    static void error_handler(int code, const char* module, const char* function, char* msg, void* data)
    {
        auto* im = static_cast<Impl*>(data);
        im->arkode_message = std::string(module ? module : "ARKODE") + " " + (function ? function : "") + " (" +
                             std::to_string(code) + "): " + (msg ? msg : "");
    }
    // central difference
    real_t h_prev = 0.0, h_pending = 0.0;
    real_t h_next = 0.0;          ///< the step the last evaluation's kick was formed with
    bool state_committed = false; ///< re-evaluation after a reset: no material increment
    /// Full-step velocity at the last evaluation (Debian's serial vector; with rkfem's vectors
    /// the kick writes it into nodes.v, whose own array is back before the kick)
    std::vector<real_t> v_full;
    /// Debian's serial vector: prescribed dofs whose v' the kick does not get right by itself
    /// (rkfem's vectors record v' = (u' - v) / h, which holds at every dof). A fixed dof of an FE part
    /// has v = 0 (start_model imposes it, and v' stays 0) and a = 0 (accelerations) at
    /// every evaluation, so the kick already gives u' = v' = 0 there; prescribed motion and RK
    /// coefficients (the mixed transformation) need v' = (u' - v) / h after the conditions.
    std::vector<index_t> fixup_dofs;
    StatePool::Ref y_start;     ///< y(n) held across a step: its u is the step's u_prev
    std::vector<real_t> u_prev; ///< the same, copied (serial vector)
    std::vector<real_t> v_prev; ///< nodes.v at the start of a step: v(n), for a failure in it
    bool in_step = false;       ///< a step began and did not finish
    // Runge-Kutta
    real_t t_n = 0.0;
    std::vector<real_t> u_n;
    // last evaluation
    ForceReport force;
    real_t forced_h = 0.0; ///< > 0: the caller's step differs from the prediction (re-evaluation)
    std::int64_t step_index = 0;
    std::exception_ptr error;
    bool ewt_set = false;
    /// The next evaluation is the one a checkpoint was written after (ARKODE evaluates f(y(n))
    /// again when it starts): its forces and accelerations are the model's, restored with it.
    bool replay = false;
    /// An evaluation happened since ARKODE was made: its f(y(n)) is then ARKODE's, to be replayed
    /// after a restart; a checkpoint written right after a start (an event) has none, and the
    /// first evaluation after the restart is a real one, as it was in the run
    bool evaluated = false;

    ~Impl()
    {
        if (pool)
            pool->detach(); // the NodeSet keeps the state it holds
        y_start.reset();
        if (mem)
            ERKStepFree(&mem);
        if (table)
            ARKodeButcherTable_Free(table);
        if (y)
            N_VDestroy(y);
        if (ctx)
            SUNContext_Free(&ctx);
    }

    /// The values of a state vector (u half, v half), for reading or for overwriting.
    StatePool::Halves values(N_Vector v) const
    {
        if (pool)
            return StatePool::values(v);
        return {data(v), data(v) + n3};
    }
    StatePool::Halves overwrite(N_Vector v) const
    {
        if (pool)
            return StatePool::overwrite(v);
        return {data(v), data(v) + n3};
    }

    static int rhs(realtype t, N_Vector yv, N_Vector ydot, void* user)
    {
        auto* im = static_cast<Impl*>(user);
        try
        {
            im->evaluate(t, yv, ydot);
            ++im->self->n_rhs_;
            return 0;
        }
        catch (...)
        {
            im->error = std::current_exception();
            return -1; // unrecoverable
        }
    }

    /// Error weights for fixed-step mode: ARKODE only uses them in its per-step "too much
    /// accuracy" check (unit roundoff x WRMS norm of y(n)), moot at a fixed step. Zero weights ask
    /// no accuracy of the step: the norm is 0, and rkfem's vectors take it without reading y.
    /// (Debian's default, N_VConst(DBL_MIN), makes that norm run on denormals.) Set once; the
    /// weight vector persists.
    static int zero_ewt(N_Vector, N_Vector ewt, void* user)
    {
        auto* im = static_cast<Impl*>(user);
        if (!im->ewt_set)
        {
            N_VConst(0.0, ewt);
            im->ewt_set = true;
        }
        return 0;
    }

    static int postprocess(realtype, N_Vector, void* user)
    {
        auto* im = static_cast<Impl*>(user);
        im->h_prev = im->h_pending; // the step just completed; the end-of-step RHS follows
        im->forced_h = 0.0;         // ... and predicts the next step itself
        return 0;
    }

    void evaluate(real_t t, N_Vector yv, N_Vector ydot)
    {
        evaluated = true;
        ExplicitOperator& m = *model;
        NodeSet& nodes = m.state();
        if (self->mode_ == Mode::CentralDifference)
        {
            // the model works on y in place: rkfem's vectors lend their halves to nodes.u and
            // nodes.v (u stays lent after the evaluation: nodes.u is then y's u); Debian's
            // serial vector is copied
            if (pool)
            {
                pool->lend(yv, nodes.u, nodes.v);
                m.update_coordinates();
            }
            else
            {
                const StatePool::Halves y = values(yv);
                m.set_state(y.u, y.v);
            }
            if (replay)
                replay = false;
            else
            {
                force = m.compute_forces(t, state_committed ? 0.0 : h_prev, step_index);
                state_committed = false;
                m.accelerations();
            }
            real_t h = forced_h > 0 ? forced_h : next_time_step(self->ts_, t, force.dt_stable);
            if (!(h > 0))
                h = h_prev > 0 ? h_prev : force.dt_stable; // at the end time: any positive step
            h_next = h;
            const real_t* a = nodes.a.data();
            const real_t* v = nodes.v.data(); // y's v
            const real_t inv_h = 1.0 / h;
            // v(n) = v(n-1/2) + h_prev/2 a(n);  v(n+1/2) = v(n) + h/2 a(n);  u' = v(n+1/2),
            // v' = (v(n+1/2) - v(n-1/2)) / h: one pass; then the prescribed motion on u' (the
            // kicked velocity), which changes only the conditions' dofs, and their v'. rkfem's
            // vectors record v' = (u' - v) / h over y instead of storing it: after the prescribed
            // motion it holds at every dof, and ERKStep's update forms it on the fly
            if (pool)
            {
                pool->return_v(); // y keeps its v (v still points to it); nodes.v gets v(n)
                real_t* du = StatePool::overwrite_with_difference(ydot, yv, inv_h);
                arkode_cd_kick(n3, v, a, h_prev, h, nodes.v.data(), du, nullptr);
                m.impose_velocity(t, h, true, du);
                return;
            }
            const StatePool::Halves yd = overwrite(ydot);
            arkode_cd_kick(n3, v, a, h_prev, h, v_full.data(), yd.u, yd.v);
            m.impose_velocity(t, h, true, yd.u);
            for (const index_t j : fixup_dofs)
                yd.v[j] = (yd.u[j] - v[j]) * inv_h;
            return;
        }
        // Runge-Kutta: kernels see the displacement increment from the committed state
        const StatePool::Halves y = values(yv);
        const real_t* u = y.u;
        const real_t* v = y.v;
        const real_t dtm = t - t_n;
        std::copy(u, u + n3, nodes.u.begin());
        if (dtm > 0)
            parallel_for("rkfem::arkode_erk::increment", n3, [&](index_t j) { nodes.v[j] = (u[j] - u_n[j]) / dtm; });
        else
            std::copy(v, v + n3, nodes.v.begin());
        m.update_coordinates();
        if (replay)
            replay = false;
        else
        {
            force = m.compute_forces(t, dtm, step_index);
            m.accelerations();
        }
        const real_t* a = nodes.a.data();
        const StatePool::Halves yd = overwrite(ydot);
        parallel_for("rkfem::arkode_erk::rhs", n3,
                     [&](index_t j)
                     {
                         yd.u[j] = v[j];
                         yd.v[j] = a[j];
                     });
        // prescribed dofs: u' = target velocity, v' = 0
        std::copy(v, v + n3, nodes.v.begin());
        m.impose_velocity(t, 0.0, false, nodes.v.data());
        for (const index_t j : m.constrained_dofs())
        {
            yd.u[j] = nodes.v[j];
            yd.v[j] = 0.0;
        }
    }

    void check(int flag, const char* what)
    {
        if (error)
        {
            auto e = error;
            error = nullptr;
            std::rethrow_exception(e);
        }
        RKFEM_REQUIRE(flag >= 0, "ARKODE " << what << " failed with flag " << flag
                                           << (arkode_message.empty() ? "" : ": " + arkode_message));
    }
};

ArkodeStepper::ArkodeStepper(Mode mode, const TimeSpec& ts, bool project_vector_ops, bool fsal_workaround)
    : mode_(mode), ts_(ts), project_ops_(project_vector_ops), fsal_workaround_(fsal_workaround)
{
    // the stable step estimates are the central difference's (2 / omega_max): an ERK table steps
    // at its own interval's share of it (BS23 and SSPRK3 sqrt(3) / 2; RK4's 2.83 is held to 1)
    if (mode_ == Mode::RungeKutta)
        step_share_ = std::min<real_t>(1.0, 0.5 * erk_imaginary_stability_limit(ts_.erk_table));
}

ArkodeStepper::~ArkodeStepper() = default;

StepReport ArkodeStepper::initialize(ExplicitOperator& model, real_t t)
{
    impl_.reset(); // an earlier stepper state leaves the NodeSet holding the state
    impl_ = std::make_unique<Impl>();
    Impl& im = *impl_;
    im.self = this;
    im.model = &model;
    NodeSet& n = model.state();
    im.n3 = 3 * n.size();
    // the same start as the hand-written central difference
    StepReport start = start_model(model, t);
    im.h_prev = im.h_pending = 0.0;
    im.t_n = t;
    create(model, t, n.u.data(), n.v.data());
    start.dt_stable *= step_share_;
    return start;
}

void ArkodeStepper::create(ExplicitOperator& model, real_t t, const real_t* y_u, const real_t* y_v)
{
    Impl& im = *impl_;
    if (!project_ops_)
    {
        im.v_full.assign(static_cast<std::size_t>(im.n3), 0.0);
        im.fixup_dofs = model.velocity_driven_dofs();
    }

    im.check(SUNContext_Create(nullptr, &im.ctx), "SUNContext_Create");
    if (project_ops_)
    {
        im.pool = StatePool::create(im.n3);
        im.y = im.pool->make_vector(im.ctx);
    }
    else
    {
        im.state.resize(2 * static_cast<std::size_t>(im.n3));
        im.y = N_VMake_Serial(2 * im.n3, im.state.data(), im.ctx);
    }
    RKFEM_REQUIRE(im.y != nullptr, "ARKODE: the state vector could not be made");
    const StatePool::Halves y = im.overwrite(im.y);
    std::copy(y_u, y_u + im.n3, y.u);
    std::copy(y_v, y_v + im.n3, y.v);
    im.mem = ERKStepCreate(Impl::rhs, t, im.y, im.ctx);
    RKFEM_REQUIRE(im.mem != nullptr, "ARKODE: ERKStepCreate failed");
    im.check(ERKStepSetUserData(im.mem, &im), "ERKStepSetUserData");
    // ARKODE's error lines go into the failure's message (it printed them to stderr, --quiet too)
    im.check(ERKStepSetErrHandlerFn(im.mem, Impl::error_handler, &im), "ERKStepSetErrHandlerFn");
    im.table = static_cast<ARKodeButcherTable>(
        make_erk_table(mode_ == Mode::CentralDifference ? "FORWARD_EULER" : ts_.erk_table));
    im.check(ERKStepSetTable(im.mem, im.table), "ERKStepSetTable");
    im.check(ERKStepWFtolerances(im.mem, Impl::zero_ewt), "ERKStepWFtolerances");
    if (fsal_workaround_ || mode_ == Mode::CentralDifference)
        im.check(ERKStepSetPostprocessStepFn(im.mem, Impl::postprocess), "ERKStepSetPostprocessStepFn");
    im.check(ERKStepSetMaxNumSteps(im.mem, 1), "ERKStepSetMaxNumSteps");
    // ARK_ONE_STEP never interpolates, but 6.4.1 updates the interpolant every step: the
    // Hermite module copies y and f (two full-state copies); Lagrange of degree 0 copies y once
    // (the module cannot be switched off before SUNDIALS 7.1; rkfem's vectors share the copy)
    im.check(ERKStepSetInterpolantType(im.mem, ARK_INTERP_LAGRANGE), "ERKStepSetInterpolantType");
    im.check(ERKStepSetInterpolantDegree(im.mem, 0), "ERKStepSetInterpolantDegree");
}

void ArkodeStepper::save_state(StateArchive& a) const
{
    if (!impl_ || !impl_->mem) // not started: nothing to save (the probe before a run)
        return;
    Impl& im = *impl_;
    // y(n): for the central difference its v half is v(n - 1/2), which the model does not hold.
    // Reading y takes a lent half back; the model's u is then lent to it again as the next
    // evaluation expects (nothing else changes)
    const StatePool::Halves y = im.values(im.y);
    a.put_bytes("arkode.y_u", y.u, static_cast<std::size_t>(im.n3) * sizeof(real_t));
    a.put_bytes("arkode.y_v", y.v, static_cast<std::size_t>(im.n3) * sizeof(real_t));
    if (im.pool && mode_ == Mode::CentralDifference)
    {
        NodeSet& n = im.model->state();
        im.pool->lend(im.y, n.u, n.v);
        im.pool->return_v();
    }
    a.put_value("arkode.h_prev", im.h_prev);
    a.put_value("arkode.h_pending", im.h_pending);
    a.put_value("arkode.h_next", im.h_next);
    a.put_value("arkode.forced_h", im.forced_h);
    a.put_value("arkode.t_n", im.t_n);
    a.put_value("arkode.force", im.force);
    a.put_value("arkode.state_committed", im.state_committed);
    a.put_value("arkode.evaluated", im.evaluated);
}

void ArkodeStepper::load_state(ExplicitOperator& model, real_t t, const StateArchive& a)
{
    impl_.reset();
    impl_ = std::make_unique<Impl>();
    Impl& im = *impl_;
    im.self = this;
    im.model = &model;
    im.n3 = 3 * model.state().size();
    std::vector<real_t> y_u(static_cast<std::size_t>(im.n3)), y_v(y_u.size());
    a.get_same_size("arkode.y_u", y_u);
    a.get_same_size("arkode.y_v", y_v);
    im.h_prev = a.value<real_t>("arkode.h_prev");
    im.h_pending = a.value<real_t>("arkode.h_pending");
    im.h_next = a.value<real_t>("arkode.h_next");
    im.forced_h = a.value<real_t>("arkode.forced_h");
    im.t_n = a.value<real_t>("arkode.t_n");
    im.force = a.value<ForceReport>("arkode.force");
    im.state_committed = a.value<bool>("arkode.state_committed");
    create(model, t, y_u.data(), y_v.data());
    im.replay = im.evaluated = a.value<bool>("arkode.evaluated");
}

StepReport ArkodeStepper::step(ExplicitOperator& model, real_t t, real_t dt, std::int64_t step_index)
{
    Impl& im = *impl_;
    NodeSet& n = model.state();
    im.step_index = step_index;
    im.h_pending = dt;
    im.v_prev.assign(n.v.begin(), n.v.end()); // v(n): the central difference's is in no ARKODE vector
    im.in_step = true;
    if (im.pool)
        im.y_start = StatePool::Ref(im.y); // y(n): ARKODE's writes go to fresh storages
    else
        im.u_prev = n.u;
    if (mode_ == Mode::RungeKutta)
    {
        im.t_n = t;
        const StatePool::Halves y = im.values(im.y);
        im.u_n.assign(y.u, y.u + im.n3);
    }
    if (mode_ == Mode::CentralDifference && im.h_next == 0.0)
        im.forced_h = dt; // first step after initialize(): the first evaluation kicks with dt
    else if (mode_ == Mode::CentralDifference && dt != im.h_next)
    {
        // The caller takes a step other than the one the last kick was formed with (a dt
        // schedule of its own): re-evaluate f(y(n)) with this step and no material increment
        // (the state is committed). Runs driven by next_time_step() never get here.
        im.forced_h = dt;
        im.state_committed = true;
        im.check(ERKStepReset(im.mem, t, im.y), "ERKStepReset");
        im.ewt_set = false;
    }
    im.check(ERKStepSetFixedStep(im.mem, dt), "ERKStepSetFixedStep");
    realtype tret = t;
    im.check(ERKStepEvolve(im.mem, t + dt, im.y, &tret, ARK_ONE_STEP), "ERKStepEvolve");
    // the last evaluation was f(y(n+1)): nodes already hold u(n+1) (rkfem's vectors: y's u,
    // lent), x(n+1), a(n+1) and the trial state of the step; the velocity is replaced by the
    // full-step value
    if (mode_ == Mode::CentralDifference)
    {
        if (!im.pool) // (rkfem's vectors: the kick wrote it into nodes.v's own array)
            std::swap(n.v, im.v_full);
    }
    else
    {
        // without the FSAL workaround the last evaluation may sit at a stage point: take y(n+1)
        const StatePool::Halves y = im.values(im.y);
        std::copy(y.u, y.u + im.n3, n.u.begin());
        std::copy(y.v, y.v + im.n3, n.v.begin());
        model.update_coordinates();
    }
    model.impose_velocity(tret, dt, false, n.v.data());
    model.check(tret, step_index);
    model.commit();
    model.update_energies(im.pool ? im.y_start.half(0).data() : im.u_prev.data(), dt);
    im.y_start.reset();
    im.in_step = false;
    StepReport r;
    r.t = tret;
    r.dt = dt;
    r.dt_stable = im.force.dt_stable * step_share_;
    r.dt_element = im.force.dt_element;
    return r;
}

bool ArkodeStepper::restore_last_good(ExplicitOperator& model)
{
    if (!impl_ || !impl_->in_step)
        return false;
    Impl& im = *impl_;
    NodeSet& n = model.state();
    if (im.pool)
    {
        const std::vector<real_t>& u0 = im.y_start.half(0); // y(n)'s u, its storage taken back if lent
        im.pool->reclaim();                                 // nodes.u and nodes.v hold their own arrays again
        n.u.assign(u0.begin(), u0.end());
    }
    else
        n.u = im.u_prev;
    n.v = im.v_prev;
    model.update_coordinates();
    im.in_step = false;
    return true;
}

const StatePool* ArkodeStepper::state_pool() const
{
    return impl_ ? impl_->pool.get() : nullptr;
}
} // namespace rkfem
