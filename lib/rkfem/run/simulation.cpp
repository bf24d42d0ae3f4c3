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
    for (index_t b = 0; b < static_cast<index_t>(model.meshes.size()); ++b)
        for (index_t e = 0; e < model.meshes[b].n_elements(); ++e)
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

namespace
{
/// One run: the stepper, the loop's state and the observers the steps feed (history and
/// fields, checkpoints, progress, the caller's observer). start(), then step() until it returns
/// false, then end(); fail() on an instability; finish() writes the summary either way.
class RunLoop
{
  public:
    RunLoop(Model& model, const RunOptions& opt, const StepObserver& observer, RunSummary& sum)
        : model_(model), opt_(opt), observer_(observer), ts_(model.deck().time), sum_(sum),
          wall0_(std::chrono::steady_clock::now()), resume_(opt.resume), record_(model, opt, name_run(sum, opt)),
          checkpoints_(opt), stepper_(make_stepper(ts_)), progress_(opt.progress), team_(max_threads()),
          governor_(adaptive(opt) ? team_ : 1, opt.thread_governor),
          defer_motion_(!observer && !opt.events), motion_restore_{model}, team_restore_{team_}
    {
        if (resume_)
        {
            RKFEM_REQUIRE(resume_->text("run.stepper") == stepper_->name(),
                          "the checkpoint was written with time.stepper " << resume_->text("run.stepper")
                                                                          << "; the deck now has " << stepper_->name());
            loop_.load(*resume_, sum_);
            record_.load(*resume_);
            checkpoints_.load(*resume_, loop_.t);
        }
        model_.defer_motion(defer_motion_);
    }

    /// The stepper's start (or a checkpoint's state), and the first observation.
    void start()
    {
        StepReport rep;
        if (resume_)
        {
            stepper_->load_state(model_, loop_.t, *resume_);
            rep.t = loop_.t;
            rep.dt_stable = loop_.dt_stable;
        }
        else
            rep = stepper_->initialize(model_, loop_.t);
        start_seconds_ = elapsed() - sum_.output_seconds;
        if (!resume_) // a restart's state at t is already in the output
        {
            observe(false);
            warn_initial_penetrations(model_, opt_.progress);
        }
        loop_.dt_stable = rep.dt_stable;
        work_items_ = model_.n_work_items();
    }

    /// One step and what follows it (events, the balance check, observers, checkpoint, progress);
    /// false when the run has ended (end time, max_steps, an interrupt).
    bool step()
    {
        real_t& t = loop_.t;
        std::int64_t& step = loop_.step;
        if (!(t < ts_.end * (1 - kScheduleSlack)) || (ts_.max_steps > 0 && step >= ts_.max_steps))
            return false;
        const real_t dt = next_time_step(ts_, t, loop_.dt_stable);
        check_step(ts_, loop_, dt, sum_.dt_first);
        ++step;
        in_step_ = true;
        const StepReport rep = governed_step(governor_, *stepper_, model_, t, dt, step);
        in_step_ = false;
        t = rep.t;
        loop_.dt_last = dt;
        if (step == 1)
            sum_.dt_first = sum_.dt_min = dt;
        sum_.dt_min = std::min(sum_.dt_min, dt);
        loop_.dt_stable = rep.dt_stable;
        loop_.element_steps += static_cast<std::size_t>(work_items_);
        // SIGINT / SIGTERM: this step is the last; its state is written as the end's is
        const int stop_signal = interrupt_signal();
        const bool last =
            t >= ts_.end * (1 - kScheduleSlack) || (ts_.max_steps > 0 && step >= ts_.max_steps) || stop_signal != 0;
        // the nodes' motion (kinetic energy, the parts' momentum) for what reads it this step:
        // the balance check (every kBalanceEvery steps), history rows, fields, checkpoints
        const bool check_due =
            !defer_motion_ || step % kBalanceEvery == 0 || last || record_.due(t) || checkpoints_.due(t);
        if (check_due)
            model_.refresh_motion();
        const auto event_start = std::chrono::steady_clock::now();
        const bool own = model_.apply_events(t, step);
        if ((opt_.events && opt_.events(model_, t, step)) || own)
        {
            loop_.dt_stable = model_.restart_after_event(*stepper_, t, dt);
            work_items_ = model_.n_work_items();
            ++sum_.events;
            sum_.event_seconds += std::chrono::duration<real_t>(std::chrono::steady_clock::now() - event_start).count();
        }
        const real_t err = check_due ? model_.energy.balance_error() : 0.0;
        sum_.max_balance_error = std::max(sum_.max_balance_error, err);
        observe(last);
        if (check_due)
            check_energy_balance(model_, ts_, loop_, err);
        if (checkpoints_.due(t) || (checkpoints_.active() && last))
        {
            const auto t0 = std::chrono::steady_clock::now();
            checkpoints_.write(model_, *stepper_, record_, loop_, sum_);
            sum_.output_seconds += std::chrono::duration<real_t>(std::chrono::steady_clock::now() - t0).count();
        }
        progress_.update(t, ts_.end, step, dt, energy_ratio(model_.energy), elapsed());
        if (stop_signal != 0)
        {
            std::ostringstream os;
            os << "interrupted by " << interrupt_signal_name(stop_signal) << " at t = " << t << " s, step " << step
               << "; the state there written"
               << (checkpoints_.active() ? " (frame, history row and checkpoint)" : " (frame and history row)");
            sum_.status = "interrupted";
            sum_.message = os.str();
            return false;
        }
        return true;
    }

    /// The end state's motion and the last progress line.
    void end()
    {
        model_.refresh_motion();
        progress_.update(loop_.t, ts_.end, loop_.step, loop_.dt_last, energy_ratio(model_.energy), elapsed(), true);
    }

    void fail(const InstabilityError& e) { record_instability(e, model_, *stepper_, record_, loop_, in_step_, sum_); }

    /// The summary and the run's last output.
    void finish()
    {
        progress_.finish();
        set_threads(team_);
        finish_summary(sum_, model_, governor_, loop_, elapsed(), opt_.setup_seconds + start_seconds_, start_seconds_);
        record_.finish(model_, opt_);
    }

  private:
    /// The nodes' motion (kinetic energy, the parts' mass and momentum: a pass over every node) is
    /// computed on the steps that read it (Model::defer_motion): balance checks every
    /// kBalanceEvery steps, history rows, fields, checkpoints, the last step. Observers and event
    /// hooks may read the model on any step: with them, every step.
    static constexpr std::int64_t kBalanceEvery = 8;

    /// The run's id (results.h5, checkpoints, summary.json): a new one, or a restart continues its
    /// checkpoint's run (one from before ids: none).
    static RunSummary& name_run(RunSummary& sum, const RunOptions& opt)
    {
        const StateArchive* resume = opt.resume;
        RKFEM_REQUIRE(!resume || !opt.out_dir.empty(), "a restart continues a run's directory: out_dir is empty");
        sum.run_id = !resume ? new_run_id() : resume->has("run.run_id") ? resume->text("run.run_id") : std::string();
        return sum;
    }
    /// The team size per step (run/thread_governor.hpp); the OpenMP default again after the loop.
    static bool adaptive(const RunOptions& opt)
    {
        const char* env = std::getenv("RKFEM_ADAPTIVE_THREADS");
        return opt.adaptive_threads && !(env && std::string(env) == "0");
    }
    real_t elapsed() const { return std::chrono::duration<real_t>(std::chrono::steady_clock::now() - wall0_).count(); }
    void observe(bool final_step)
    {
        record_.observe(model_, loop_, final_step);
        if (observer_)
            observer_(model_, loop_.t, loop_.dt_last, loop_.step);
    }

    Model& model_;
    const RunOptions& opt_;
    const StepObserver& observer_;
    const TimeSpec& ts_;
    RunSummary& sum_;
    const std::chrono::steady_clock::time_point wall0_;
    const StateArchive* resume_;
    RunRecord record_;
    Checkpointer checkpoints_;
    std::unique_ptr<TimeStepper> stepper_;
    Progress progress_;
    LoopState loop_;
    real_t start_seconds_ = 0.0; ///< the stepper's first start
    bool in_step_ = false;       ///< a step is under way: a failure in it leaves t and step at the last good one
    index_t work_items_ = 0;     ///< elements, and the stress points of nodal parts
    const int team_;
    ThreadGovernor governor_;
    const bool defer_motion_;
    struct MotionRestore
    {
        Model& m;
        ~MotionRestore() { m.defer_motion(false); }
    } motion_restore_;
    struct TeamRestore
    {
        int n;
        ~TeamRestore() { set_threads(n); }
    } team_restore_;
};
} // namespace

RunSummary run_simulation(Model& model, const RunOptions& opt, const StepObserver& observer)
{
    RunSummary sum;
    RunLoop run(model, opt, observer, sum);
    try
    {
        run.start();
        while (run.step())
        {
        }
        run.end();
    }
    catch (const InstabilityError& e)
    {
        run.fail(e);
    }
    run.finish();
    return sum;
}
} // namespace rkfem
