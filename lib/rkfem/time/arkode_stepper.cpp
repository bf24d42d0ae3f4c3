#include "rkfem/time/arkode_stepper.hpp"

#include <arkode/arkode_erkstep.h>
#include <array>
#include <atomic>
#include <cmath>
#include <exception>
#include <nvector/nvector_serial.h>
#include <sstream>
#include <vector>

#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/time/central_difference.hpp"

namespace rkfem
{
namespace
{
// ---- rkfem's vector operations for ARKODE's serial vectors (-O3, OpenMP, deterministic sums) ----
inline real_t* data(N_Vector v) { return NV_DATA_S(v); }
inline index_t len(N_Vector v) { return static_cast<index_t>(NV_LENGTH_S(v)); }

void op_linear_sum(realtype a, N_Vector x, realtype b, N_Vector y, N_Vector z)
{
    const real_t *px = data(x), *py = data(y);
    real_t* pz = data(z);
    parallel_for("rkfem::nv::linear_sum", len(z), [&](index_t i) { pz[i] = a * px[i] + b * py[i]; });
}
void op_const(realtype c, N_Vector z)
{
    real_t* pz = data(z);
    parallel_for("rkfem::nv::const", len(z), [&](index_t i) { pz[i] = c; });
}
void op_scale(realtype c, N_Vector x, N_Vector z)
{
    const real_t* px = data(x);
    real_t* pz = data(z);
    parallel_for("rkfem::nv::scale", len(z), [&](index_t i) { pz[i] = c * px[i]; });
}
// Weight vectors known to hold only ones (the unit error weights of the fixed-step steppers, set
// once by unit_ewt): the weighted sum of squares then reads x alone. A few slots suffice (one
// per live stepper); a vector not found here takes the general loop.
std::array<std::atomic<N_Vector>, 16> g_unit_weights{};

void register_unit_weights(N_Vector w, bool on)
{
    for (auto& slot : g_unit_weights)
    {
        N_Vector expected = on ? nullptr : w;
        if (slot.compare_exchange_strong(expected, on ? w : nullptr))
            return;
    }
}

bool is_unit_weights(N_Vector w)
{
    for (const auto& slot : g_unit_weights)
        if (slot.load(std::memory_order_relaxed) == w)
            return true;
    return false;
}

realtype op_wsqrsum_local(N_Vector x, N_Vector w)
{
    const real_t *px = data(x), *pw = data(w);
    if (is_unit_weights(w))
        return parallel_reduce_sum("rkfem::nv::sqrsum", len(x), [&](index_t i) { return px[i] * px[i]; });
    return parallel_reduce_sum("rkfem::nv::wsqrsum", len(x),
                               [&](index_t i)
                               {
                                   const real_t p = px[i] * pw[i];
                                   return p * p;
                               });
}
realtype op_wrms_norm(N_Vector x, N_Vector w) { return std::sqrt(op_wsqrsum_local(x, w) / len(x)); }
int op_linear_combination(int nv, realtype* c, N_Vector* X, N_Vector z)
{
    real_t* pz = data(z);
    const index_t n = len(z);
    // z may alias X[0] (ARKODE's accumulate form); the one- and two-term forms (forward Euler's
    // y + h f every step) get their own vectorized loops with the data pointers hoisted
    if (nv == 1)
    {
        const real_t* x0 = data(X[0]);
        const real_t c0 = c[0];
        parallel_for("rkfem::nv::linear_combination1", n, [&](index_t i) { pz[i] = c0 * x0[i]; });
        return 0;
    }
    if (nv == 2)
    {
        const real_t *x0 = data(X[0]), *x1 = data(X[1]);
        const real_t c0 = c[0], c1 = c[1];
        parallel_for("rkfem::nv::linear_combination2", n, [&](index_t i) { pz[i] = c0 * x0[i] + c1 * x1[i]; });
        return 0;
    }
    std::vector<const real_t*> px(static_cast<std::size_t>(nv));
    for (int k = 0; k < nv; ++k)
        px[k] = data(X[k]);
    parallel_for("rkfem::nv::linear_combination", n,
                 [&](index_t i)
                 {
                     real_t s = c[0] * px[0][i];
                     for (int k = 1; k < nv; ++k)
                         s += c[k] * px[k][i];
                     pz[i] = s;
                 });
    return 0;
}
int op_scale_add_multi(int nv, realtype* a, N_Vector x, N_Vector* Y, N_Vector* Z)
{
    const real_t* px = data(x);
    const index_t n = len(x);
    for (int k = 0; k < nv; ++k)
    {
        const real_t *py = data(Y[k]);
        real_t* pz = data(Z[k]);
        const real_t ak = a[k];
        parallel_for("rkfem::nv::scale_add_multi", n, [&](index_t i) { pz[i] = ak * px[i] + py[i]; });
    }
    return 0;
}

void install_project_ops(N_Vector v)
{
    v->ops->nvlinearsum = op_linear_sum;
    v->ops->nvconst = op_const;
    v->ops->nvscale = op_scale;
    v->ops->nvwrmsnorm = op_wrms_norm;
    v->ops->nvwsqrsumlocal = op_wsqrsum_local;
    v->ops->nvlinearcombination = op_linear_combination;
    v->ops->nvscaleaddmulti = op_scale_add_multi;
}


} // namespace

void* make_erk_table(const std::string& name, int* stages, int* order)
{
    ARKodeButcherTable B = nullptr;
    if (name == "FORWARD_EULER")
    {
        realtype c[1] = {0}, A[1] = {0}, b[1] = {1};
        B = ARKodeButcherTable_Create(1, 1, 0, c, A, b, nullptr);
    }
    else if (name == "RK4")
    {
        realtype c[4] = {0, 0.5, 0.5, 1};
        realtype A[16] = {0, 0, 0, 0, 0.5, 0, 0, 0, 0, 0.5, 0, 0, 0, 0, 1, 0};
        realtype b[4] = {1.0 / 6, 1.0 / 3, 1.0 / 3, 1.0 / 6};
        B = ARKodeButcherTable_Create(4, 4, 0, c, A, b, nullptr);
    }
    else if (name == "SSPRK3")
    {
        realtype c[3] = {0, 1, 0.5};
        realtype A[9] = {0, 0, 0, 1, 0, 0, 0.25, 0.25, 0};
        realtype b[3] = {1.0 / 6, 1.0 / 6, 2.0 / 3};
        B = ARKodeButcherTable_Create(3, 3, 0, c, A, b, nullptr);
    }
    else
        B = ARKodeButcherTable_LoadERKByName(name.c_str());
    RKFEM_REQUIRE(B != nullptr, "unknown ERK table '" << name << "'");
    if (stages)
        *stages = B->stages;
    if (order)
        *order = B->q;
    return B;
}

void free_erk_table(void* table) { ARKodeButcherTable_Free(static_cast<ARKodeButcherTable>(table)); }

struct ArkodeStepper::Impl
{
    ArkodeStepper* self = nullptr;
    SUNContext ctx = nullptr;
    N_Vector y = nullptr;
    void* mem = nullptr;
    ARKodeButcherTable table = nullptr;
    std::vector<real_t> state; ///< (u, v), 6 n
    Model* model = nullptr;
    index_t n3 = 0;
    // central difference
    real_t h_prev = 0.0, h_pending = 0.0;
    real_t h_next = 0.0;          ///< the step the last evaluation's kick was formed with
    bool state_committed = false; ///< re-evaluation after a reset: no material increment
    std::vector<real_t> v_full; ///< full-step velocity at the last evaluation
    // Runge-Kutta
    real_t t_n = 0.0;
    std::vector<real_t> u_n, u_prev;
    std::vector<real_t> target; ///< prescribed velocity targets (scratch)
    // last evaluation
    ForceReport force;
    real_t forced_h = 0.0; ///< > 0: the caller's step differs from the prediction (re-evaluation)
    std::int64_t step_index = 0;
    std::exception_ptr error;

    ~Impl()
    {
        if (unit_w)
            register_unit_weights(unit_w, false);
        if (mem)
            ERKStepFree(&mem);
        if (table)
            ARKodeButcherTable_Free(table);
        if (y)
            N_VDestroy(y);
        if (ctx)
            SUNContext_Free(&ctx);
    }

    static int rhs(realtype t, N_Vector yv, N_Vector ydot, void* user)
    {
        auto* im = static_cast<Impl*>(user);
        try
        {
            im->evaluate(t, data(yv), data(ydot));
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
    /// accuracy" check (unit roundoff x WRMS norm of y). Debian's default, N_VConst(DBL_MIN),
    /// makes that norm run on denormals; here the weights are set to 1 once (the vector persists).
    static int unit_ewt(N_Vector, N_Vector ewt, void* user)
    {
        auto* im = static_cast<Impl*>(user);
        if (!im->ewt_set)
        {
            N_VConst(1.0, ewt);
            im->ewt_set = true;
            if (im->unit_w != ewt)
            {
                if (im->unit_w)
                    register_unit_weights(im->unit_w, false);
                register_unit_weights(ewt, true);
                im->unit_w = ewt;
            }
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

    void evaluate(real_t t, const real_t* y, real_t* ydot)
    {
        Model& m = *model;
        NodeSet& nodes = m.nodes;
        const real_t* u = y;
        const real_t* v = y + n3;
        if (self->mode_ == Mode::CentralDifference)
        {
            m.set_state(u, v);
            force = m.compute_forces(t, state_committed ? 0.0 : h_prev, step_index);
            state_committed = false;
            m.compute_accelerations();
            real_t h = forced_h > 0 ? forced_h : next_time_step(self->ts_, t, force.dt_stable);
            if (!(h > 0))
                h = h_prev > 0 ? h_prev : force.dt_stable; // at the end time: any positive step
            h_next = h;
            const real_t* a = nodes.a.data();
            // v(n) = v(n-1/2) + h_prev/2 a(n);  v(n+1/2) = v(n) + h/2 a(n);  u' = v(n+1/2),
            // v' = (v(n+1/2) - v(n-1/2)) / h: one pass; then the prescribed motion, which changes
            // only the conditions' dofs, and their entries of ydot
            const real_t inv_h = 1.0 / h;
            parallel_for("rkfem::arkode_cd::kick", n3,
                         [&](index_t j)
                         {
                             const real_t vf = v[j] + 0.5 * h_prev * a[j];
                             const real_t vk = vf + 0.5 * h * a[j];
                             v_full[j] = vf;
                             nodes.v[j] = vk;
                             ydot[j] = vk;
                             ydot[n3 + j] = (vk - v[j]) * inv_h;
                         });
            m.impose_velocity(t, h, true);
            for (const DofCondition& c : m.conditions)
            {
                ydot[c.dof] = nodes.v[c.dof];
                ydot[n3 + c.dof] = (nodes.v[c.dof] - v[c.dof]) * inv_h;
            }
            return;
        }
        // Runge-Kutta: kernels see the displacement increment from the committed state
        const real_t dtm = t - t_n;
        std::copy(u, u + n3, nodes.u.begin());
        if (dtm > 0)
            parallel_for("rkfem::arkode_erk::increment", n3,
                         [&](index_t j) { nodes.v[j] = (u[j] - u_n[j]) / dtm; });
        else
            std::copy(v, v + n3, nodes.v.begin());
        m.update_coordinates();
        force = m.compute_forces(t, dtm, step_index);
        m.compute_accelerations();
        const real_t* a = nodes.a.data();
        parallel_for("rkfem::arkode_erk::rhs", n3,
                     [&](index_t j)
                     {
                         ydot[j] = v[j];
                         ydot[n3 + j] = a[j];
                     });
        // prescribed dofs: u' = target velocity, v' = 0
        std::copy(v, v + n3, nodes.v.begin());
        m.impose_velocity(t, 0.0, false);
        for (const DofCondition& c : m.conditions)
        {
            ydot[c.dof] = nodes.v[c.dof];
            ydot[n3 + c.dof] = 0.0;
        }
    }

    bool ewt_set = false;
    N_Vector unit_w = nullptr; ///< the error-weight vector registered as all ones

    void check(int flag, const char* what)
    {
        if (error)
        {
            auto e = error;
            error = nullptr;
            std::rethrow_exception(e);
        }
        RKFEM_REQUIRE(flag >= 0, "ARKODE " << what << " failed with flag " << flag);
    }
};

ArkodeStepper::ArkodeStepper(Mode mode, const TimeSpec& ts, bool project_vector_ops, bool fsal_workaround)
    : mode_(mode), ts_(ts), project_ops_(project_vector_ops), fsal_workaround_(fsal_workaround)
{
}

ArkodeStepper::~ArkodeStepper() = default;

StepReport ArkodeStepper::initialize(Model& model, real_t t)
{
    impl_ = std::make_unique<Impl>();
    Impl& im = *impl_;
    im.self = this;
    im.model = &model;
    NodeSet& n = model.nodes;
    im.n3 = 3 * n.size();
    // the same start as the hand-written central difference
    const StepReport start = start_model(model, t);

    im.state.resize(2 * static_cast<std::size_t>(im.n3));
    std::copy(n.u.begin(), n.u.end(), im.state.begin());
    std::copy(n.v.begin(), n.v.end(), im.state.begin() + im.n3);
    im.v_full.assign(static_cast<std::size_t>(im.n3), 0.0);
    im.target.assign(static_cast<std::size_t>(im.n3), 0.0);
    im.h_prev = im.h_pending = 0.0;
    im.t_n = t;
    im.u_n = n.u;

    im.check(SUNContext_Create(nullptr, &im.ctx), "SUNContext_Create");
    im.y = N_VMake_Serial(2 * im.n3, im.state.data(), im.ctx);
    RKFEM_REQUIRE(im.y != nullptr, "ARKODE: N_VMake_Serial failed");
    if (project_ops_)
        install_project_ops(im.y);
    im.mem = ERKStepCreate(Impl::rhs, t, im.y, im.ctx);
    RKFEM_REQUIRE(im.mem != nullptr, "ARKODE: ERKStepCreate failed");
    im.check(ERKStepSetUserData(im.mem, &im), "ERKStepSetUserData");
    im.table = static_cast<ARKodeButcherTable>(
        make_erk_table(mode_ == Mode::CentralDifference ? "FORWARD_EULER" : ts_.erk_table));
    im.check(ERKStepSetTable(im.mem, im.table), "ERKStepSetTable");
    im.check(ERKStepWFtolerances(im.mem, Impl::unit_ewt), "ERKStepWFtolerances");
    if (fsal_workaround_ || mode_ == Mode::CentralDifference)
        im.check(ERKStepSetPostprocessStepFn(im.mem, Impl::postprocess), "ERKStepSetPostprocessStepFn");
    im.check(ERKStepSetMaxNumSteps(im.mem, 1), "ERKStepSetMaxNumSteps");
    // ARK_ONE_STEP never interpolates, but 6.4.1 updates the interpolant every step: the
    // Hermite module copies y and f (two full-state copies); Lagrange of degree 0 copies y once
    // (the module cannot be switched off before SUNDIALS 7.1)
    im.check(ERKStepSetInterpolantType(im.mem, ARK_INTERP_LAGRANGE), "ERKStepSetInterpolantType");
    im.check(ERKStepSetInterpolantDegree(im.mem, 0), "ERKStepSetInterpolantDegree");
    return start;
}

StepReport ArkodeStepper::step(Model& model, real_t t, real_t dt, std::int64_t step_index)
{
    Impl& im = *impl_;
    NodeSet& n = model.nodes;
    im.step_index = step_index;
    im.h_pending = dt;
    im.u_prev = n.u;
    if (mode_ == Mode::RungeKutta)
    {
        im.t_n = t;
        im.u_n.assign(im.state.begin(), im.state.begin() + im.n3);
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
    // the last evaluation was f(y(n+1)): nodes already hold u(n+1), x(n+1), a(n+1) and the trial
    // state of the step; only the velocity is the kicked one, replaced by the full-step value
    if (mode_ == Mode::CentralDifference)
        std::swap(n.v, im.v_full);
    else
    {
        // without the FSAL workaround the last evaluation may sit at a stage point: take y(n+1)
        std::copy(im.state.begin(), im.state.begin() + im.n3, n.u.begin());
        std::copy(im.state.begin() + im.n3, im.state.end(), n.v.begin());
        model.update_coordinates();
    }
    model.impose_velocity(tret, dt, false);
    const real_t bad = parallel_reduce_min("rkfem::arkode::check", im.n3,
                                           [&](index_t j)
                                           {
                                               return std::isfinite(n.u[j]) && std::isfinite(n.a[j])
                                                          ? 1e300
                                                          : static_cast<real_t>(j);
                                           });
    if (bad < 1e299)
    {
        const index_t j = static_cast<index_t>(bad);
        std::ostringstream os;
        os << "non-finite acceleration or displacement at node " << j / 3 << " (part '"
           << model.parts[n.part[j / 3]].name << "') at t = " << tret << " s, step " << step_index;
        throw InstabilityError(os.str());
    }
    model.commit();
    model.update_energies(im.u_prev, dt);
    StepReport r;
    r.t = tret;
    r.dt = dt;
    r.dt_stable = im.force.dt_stable;
    r.dt_element = im.force.dt_element;
    return r;
}
} // namespace rkfem
