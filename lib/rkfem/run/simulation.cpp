#include "rkfem/run/simulation.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <random>
#include <sstream>
#include <sys/resource.h>
#include <unistd.h>

#include "rkfem/analysis/impact.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/core/interrupt.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/state_archive.hpp"
#include "rkfem/io/checkpoint.hpp"
#include "rkfem/io/results_writer.hpp"
#include "rkfem/run/run_observers.hpp"
#include "rkfem/time/central_difference.hpp"
#include "rkfem/time/stepper.hpp"

namespace rkfem
{
namespace
{
/// The process's involuntary context switches so far (all threads): how often it lost a core.
long involuntary_switches()
{
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return u.ru_nivcsw;
}
} // namespace

namespace
{
/// Refuses a step that is not a number, or a stable step that fell below time.dt_min_fraction of
/// the first: a collapsing stable step (crushed elements, a run gone unstable past the energy
/// check) would take ever more steps and never end (the stable step, not the step taken: the last
/// step is cut short to land on the end time).
void check_step(const TimeSpec& ts, const LoopState& loop, real_t dt, real_t dt_first)
{
    if (!(dt > 0) || !std::isfinite(dt))
        throw InstabilityError("time step collapsed to " + std::to_string(dt) + " s at t = " + std::to_string(loop.t) +
                               " s, step " + std::to_string(loop.step));
    if (loop.step > 0 && ts.dt_min_fraction > 0 && loop.dt_stable * ts.dt_scale < ts.dt_min_fraction * dt_first)
    {
        std::ostringstream os;
        os << "time step fell to " << loop.dt_stable * ts.dt_scale << " s, below time.dt_min_fraction "
           << ts.dt_min_fraction << " of the first step (" << dt_first << " s), at t = " << loop.t << " s, step "
           << loop.step;
        throw InstabilityError(os.str());
    }
}

/// The energy check: the first steps after a step load or an impulsive start carry an O(1)
/// relative balance error that decays like 1/n; an unstable run grows instead, so the check
/// starts at step 50.
void check_energy_balance(const Model& model, const TimeSpec& ts, const LoopState& loop, real_t err)
{
    if (loop.step >= 50 && err > ts.energy_error_limit && model.energy.total() > 0)
    {
        std::ostringstream os;
        os << "energy balance error " << err << " exceeds time.energy_error_limit " << ts.energy_error_limit
           << " at t = " << loop.t << " s, step " << loop.step;
        throw InstabilityError(os.str());
    }
}

/// One step on the team size the governor chooses, its wall time and lost cores recorded.
StepReport governed_step(ThreadGovernor& governor, TimeStepper& stepper, Model& model, real_t t, real_t dt,
                         std::int64_t step)
{
    if (!governor.active())
        return stepper.step(model, t, dt, step);
    set_threads(governor.threads());
    const auto step_start = std::chrono::steady_clock::now();
    const long preempted_before = involuntary_switches();
    const StepReport rep = stepper.step(model, t, dt, step);
    governor.record(std::chrono::duration<double>(std::chrono::steady_clock::now() - step_start).count(),
                    static_cast<double>(involuntary_switches() - preempted_before));
    return rep;
}

/// Says how many nodes of each contact start inside the other surface, and what is done with them.
void warn_initial_penetrations(const Model& model, bool enabled)
{
    for (std::size_t k = 0; k < model.contacts.size(); ++k)
        if (const index_t n = model.contacts[k]->initial_penetrations(); n > 0 && enabled)
            std::fprintf(stderr,
                         "rkfem: warning: contacts.%zu: %lld node(s) start inside the other surface; they are "
                         "%s (summary.json: contacts)\n",
                         k, static_cast<long long>(n),
                         model.contacts[k]->holds_initial_penetrations()
                             ? "held at that depth, not pushed out"
                             : "pushed out by the penalty (mortar contact holds no offsets)");
}

/// After an event changed the discretization: the stepper starts again from this state, and what
/// the new accelerations change in the kinetic energy is booked (event_a: scratch for the
/// accelerations before). Returns the new stable step.
real_t restart_after_event(TimeStepper& stepper, Model& model, real_t t, real_t dt, std::vector<real_t>& event_a)
{
    event_a = model.nodes.a;
    const real_t kinetic = model.energy.kinetic;
    const StepReport rep = stepper.initialize(model, t);
    // prescribed velocities imposed again through a new kinematic map (a conversion made
    // constrained nodes particles): the supports did that work
    model.energy.external_work += model.energy.kinetic - kinetic;
    book_event_energy(model, event_a, dt);
    return rep.dt_stable;
}

/// An unstable run: the summary says where and when. The fields written so far stay; then the last
/// good state (the last accepted step's, when it was not written yet) and the state the run failed
/// in, each at its own time (a step's end, or an ERK stage): the failed frame can be inspected and
/// is never labelled with the last good time. The failed frame's stresses and histories are the
/// committed (last good) ones: only its motion is the failed step's. The summary measures the last
/// good state; its kinetic energy is that of the last balance check or output before the failure
/// (a failed step's accelerations are not those of the last good state).
void record_instability(const InstabilityError& e, Model& model, TimeStepper& stepper, RunRecord& record,
                        LoopState& loop, bool in_step, RunSummary& sum)
{
    sum.status = "unstable";
    sum.message = e.what();
    sum.failed_time = std::isfinite(e.time) ? e.time : loop.t;
    NodeSet& n = model.nodes;
    std::vector<real_t> u_other = n.u, v_other = n.v; // the failed state
    const bool restored = in_step && stepper.restore_last_good(model);
    record.write_failure(model, loop.t, sum.failed_time, restored,
                         [&]
                         {
                             n.u.swap(u_other);
                             n.v.swap(v_other);
                             model.update_coordinates();
                         });
    if (in_step)
        --loop.step; // the failed step is not counted: steps and end_time are the last good step's
}

/// The summary's counts, times and end state.
void finish_summary(RunSummary& sum, const Model& model, const ThreadGovernor& governor, const LoopState& loop,
                    real_t wall_seconds, real_t setup_seconds, real_t start_seconds)
{
    sum.thread_switches = governor.switches();
    sum.steps_on_one_thread = governor.steps_on_one_thread();
    sum.steps = loop.step;
    sum.end_time = loop.t;
    sum.wall_seconds = wall_seconds;
    sum.setup_seconds = setup_seconds;
    sum.stepping_seconds = std::max(0.0, sum.wall_seconds - sum.output_seconds - start_seconds);
    sum.ns_per_element_cycle = loop.element_steps > 0 ? 1e9 * sum.stepping_seconds / loop.element_steps : 0.0;
    sum.energy = model.energy;
    for (index_t b = 0; b < static_cast<index_t>(model.blocks.size()); ++b)
        for (index_t e = 0; e < model.blocks[b].n_elements(); ++e)
            sum.max_plastic_strain = std::max(sum.max_plastic_strain, model.element_plastic_strain(b, e));
}

/// The progress line's energy ratio: the ledger's total over its origin plus the external work.
real_t energy_ratio(const Energies& e)
{
    const real_t ref = e.kinetic0 + e.internal0 + e.external_work;
    return ref > 0 ? e.total() / ref : 1.0;
}

} // namespace

std::string checkpoint_path(const std::string& dir, int k)
{
    return dir + (k == 0 ? "/checkpoint.h5" : "/checkpoint." + std::to_string(k) + ".h5");
}

std::string new_run_id()
{
    std::random_device rd;
    const std::uint64_t v = (static_cast<std::uint64_t>(rd()) << 32) ^ rd() ^
                            static_cast<std::uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count());
    char b[17];
    std::snprintf(b, sizeof b, "%016llx", static_cast<unsigned long long>(v));
    return b;
}

std::string newest_checkpoint(const std::string& dir)
{
    std::error_code ec;
    for (const std::string& p : {dir + "/checkpoint.new.h5", checkpoint_path(dir), checkpoint_path(dir, 1)})
        if (std::filesystem::is_regular_file(p, ec))
            return p;
    return checkpoint_path(dir);
}

RunSummary run_simulation(Model& model, const RunOptions& opt, const StepObserver& observer)
{
    const TimeSpec& ts = model.deck().time;
    RunSummary sum;
    const auto wall0 = std::chrono::steady_clock::now();
    auto elapsed = [&] { return std::chrono::duration<real_t>(std::chrono::steady_clock::now() - wall0).count(); };
    const StateArchive* resume = opt.resume;
    RKFEM_REQUIRE(!resume || !opt.out_dir.empty(), "a restart continues a run's directory: out_dir is empty");
    // the run's id (results.h5, checkpoints, summary.json): a new one, or a restart continues its
    // checkpoint's run (one from before ids: none)
    sum.run_id = !resume ? new_run_id() : resume->has("run.run_id") ? resume->text("run.run_id") : std::string();
    RunRecord record(model, opt, sum);
    Checkpointer checkpoints(opt);
    auto stepper = make_stepper(ts);
    Progress progress(opt.progress);
    LoopState loop;
    real_t start_seconds = 0.0; // the stepper's first start
    if (resume)
    {
        RKFEM_REQUIRE(resume->text("run.stepper") == stepper->name(), "the checkpoint was written with time.stepper "
                                                                          << resume->text("run.stepper")
                                                                          << "; the deck now has " << stepper->name());
        loop.load(*resume, sum);
        record.load(*resume);
        checkpoints.load(*resume, loop.t);
    }
    bool in_step = false; // a step is under way: a failure in it leaves t and step at the last good one
    // the team size per step (run/thread_governor.hpp); the OpenMP default again after the loop
    const char* adapt_env = std::getenv("RKFEM_ADAPTIVE_THREADS");
    const bool adapt = opt.adaptive_threads && !(adapt_env && std::string(adapt_env) == "0");
    const int team = max_threads();
    ThreadGovernor governor(adapt ? team : 1, opt.thread_governor);
    // The nodes' motion (kinetic energy, the parts' mass and momentum: a pass over every node) is
    // computed on the steps that read it (Model::defer_motion): balance checks every
    // kBalanceEvery steps, history rows, fields, checkpoints, the last step. Observers and event
    // hooks may read the model on any step: with them, every step.
    constexpr std::int64_t kBalanceEvery = 8;
    const bool defer_motion = !observer && !opt.events;
    model.defer_motion(defer_motion);
    struct MotionRestore
    {
        Model& m;
        ~MotionRestore() { m.defer_motion(false); }
    } motion_restore{model};
    struct TeamRestore
    {
        int n;
        ~TeamRestore() { set_threads(n); }
    } team_restore{team};
    real_t& t = loop.t;
    std::int64_t& step = loop.step;
    try
    {
        StepReport rep;
        if (resume)
        {
            stepper->load_state(model, t, *resume);
            rep.t = t;
            rep.dt_stable = loop.dt_stable;
        }
        else
            rep = stepper->initialize(model, t);
        start_seconds = elapsed() - sum.output_seconds;
        auto observe = [&](bool final_step)
        {
            record.observe(model, loop, final_step);
            if (observer)
                observer(model, t, loop.dt_last, step);
        };
        if (!resume) // a restart's state at t is already in the output
        {
            observe(false);
            warn_initial_penetrations(model, opt.progress);
        }
        loop.dt_stable = rep.dt_stable;
        index_t ne = model.n_work_items(); // elements, and the stress points of nodal parts
        std::vector<real_t> event_a;       // accelerations before an event
        while (t < ts.end * (1 - kScheduleSlack))
        {
            if (ts.max_steps > 0 && step >= ts.max_steps)
                break;
            const real_t dt = next_time_step(ts, t, loop.dt_stable);
            check_step(ts, loop, dt, sum.dt_first);
            ++step;
            in_step = true;
            rep = governed_step(governor, *stepper, model, t, dt, step);
            in_step = false;
            t = rep.t;
            loop.dt_last = dt;
            if (step == 1)
                sum.dt_first = sum.dt_min = dt;
            sum.dt_min = std::min(sum.dt_min, dt);
            loop.dt_stable = rep.dt_stable;
            loop.element_steps += static_cast<std::size_t>(ne);
            // SIGINT / SIGTERM: this step is the last; its state is written as the end's is
            const int stop_signal = interrupt_signal();
            const bool last =
                t >= ts.end * (1 - kScheduleSlack) || (ts.max_steps > 0 && step >= ts.max_steps) || stop_signal != 0;
            // the nodes' motion (kinetic energy, the parts' momentum) for what reads it this step:
            // the balance check (every kBalanceEvery steps), history rows, fields, checkpoints
            const bool check_due =
                !defer_motion || step % kBalanceEvery == 0 || last || record.due(t) || checkpoints.due(t);
            if (check_due)
                model.refresh_motion();
            const bool own = model.apply_events(t, step);
            if ((opt.events && opt.events(model, t, step)) || own)
            {
                loop.dt_stable = restart_after_event(*stepper, model, t, dt, event_a);
                ne = model.n_work_items();
            }
            const real_t err = check_due ? model.energy.balance_error() : 0.0;
            sum.max_balance_error = std::max(sum.max_balance_error, err);
            observe(last);
            if (check_due)
                check_energy_balance(model, ts, loop, err);
            if (checkpoints.due(t) || (checkpoints.active() && last))
            {
                const auto t0 = std::chrono::steady_clock::now();
                checkpoints.write(model, *stepper, record, loop, sum);
                sum.output_seconds += std::chrono::duration<real_t>(std::chrono::steady_clock::now() - t0).count();
            }
            progress.update(t, ts.end, step, dt, energy_ratio(model.energy), elapsed());
            if (stop_signal != 0)
            {
                std::ostringstream os;
                os << "interrupted by " << interrupt_signal_name(stop_signal) << " at t = " << t << " s, step " << step
                   << "; the state there written"
                   << (checkpoints.active() ? " (frame, history row and checkpoint)" : " (frame and history row)");
                sum.status = "interrupted";
                sum.message = os.str();
                break;
            }
        }
        model.refresh_motion();
        progress.update(t, ts.end, step, loop.dt_last, energy_ratio(model.energy), elapsed(), true);
    }
    catch (const InstabilityError& e)
    {
        record_instability(e, model, *stepper, record, loop, in_step, sum);
    }
    progress.finish();
    set_threads(team);
    finish_summary(sum, model, governor, loop, elapsed(), opt.setup_seconds + start_seconds, start_seconds);
    record.finish(model, opt);
    return sum;
}
} // namespace rkfem
