#include "rkfem/run/simulation.hpp"

#include <chrono>
#include <algorithm>
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

#include "rkfem/core/error.hpp"
#include "rkfem/core/interrupt.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/state_archive.hpp"
#include "rkfem/io/checkpoint.hpp"
#include "rkfem/io/results_writer.hpp"
#include "rkfem/analysis/impact.hpp"
#include "rkfem/run/summary.hpp"
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
/// PREFIX + SET per entry ("PREFIX SET_2" for the second entry on one set).
std::vector<std::string> names_by_set(const std::vector<std::string>& sets, const char* prefix)
{
    std::vector<std::string> names;
    std::map<std::string, int> seen;
    for (const auto& set : sets)
    {
        const int n = ++seen[set];
        std::string name = prefix;
        name += set;
        if (n > 1)
        {
            name += '_';
            name += std::to_string(n);
        }
        names.push_back(name);
    }
    return names;
}

/// A load's value at t: the pressure [Pa], or the length of the nodal force vector [N] (per
/// node, or the total with `total: true`), as the deck gives it.
real_t load_value(const LoadSpec& l, real_t t)
{
    if (l.kind == LoadSpec::Kind::Pressure)
        return l.pressure(t);
    real_t f2 = 0;
    for (int k = 0; k < 3; ++k)
        if (l.active[k])
            f2 += l.force[k](t) * l.force[k](t);
    return std::sqrt(f2);
}

std::vector<std::string> history_columns(const Model& m)
{
    std::vector<std::string> c{"time",          "dt",       "kinetic", "internal", "hourglass",
                               "bulk_viscosity", "damping", "external_work", "contact", "eroded",
                               "total",         "balance_error", "hourglass_ratio", "hourglass_to_total"};
    if (m.deck().impact.active)
        c.insert(c.end(), {"apparent_depth", "actual_depth", "residual_velocity"});
    std::vector<std::string> sets;
    for (const auto& b : m.deck().boundary_conditions)
        sets.push_back(b.node_set);
    for (const std::string& name : names_by_set(sets, "reaction_"))
        for (const char* q : {"_x", "_y", "_z"})
            c.push_back(name + q);
    sets.clear();
    for (const auto& l : m.deck().loads)
        sets.push_back(l.set);
    for (const std::string& name : names_by_set(sets, "load_"))
        c.push_back(name);
    for (const auto& sc : m.deck().sections)
        for (const char* q : {"_x", "_y", "_z"})
            c.push_back("section_" + sc.name + q);
    for (const auto& p : m.parts)
        for (const char* q : {"_mass", "_kinetic", "_internal", "_hourglass", "_momentum_x", "_momentum_y", "_momentum_z"})
            c.push_back("part_" + p.name + q);
    for (const auto& p : m.deck().parts)
        if (p.converts())
            c.push_back("part_" + p.name + "_rk_elements"); // evolutionary coupling: the RK region's size
    for (const auto& p : m.deck().probes)
    {
        for (const char* q : {"ux", "uy", "uz", "vx", "vy", "vz"})
            c.push_back(p.name + "_" + q);
        for (const char* q : {"sxx", "syy", "szz", "sxy", "syz", "szx"})
            c.push_back(p.name + "_" + q);
    }
    return c;
}

/// impact: the analysis, with the actual depth as last computed (at field outputs)
void append_row(const Model& m, real_t t, real_t dt, std::vector<real_t>& rows, const ImpactAnalysis* impact,
                real_t actual_depth)
{
    const Energies& e = m.energy;
    rows.insert(rows.end(), {t, dt, e.kinetic, e.internal, e.hourglass, e.bulk_viscosity, e.damping,
                             e.external_work, e.contact, e.eroded, e.total(), e.balance_error(), e.hourglass_ratio(),
                             e.hourglass_to_total()});
    if (impact)
        rows.insert(rows.end(), {impact->apparent_depth(m), actual_depth, impact->residual_velocity(m)});
    thread_local std::vector<Vec3> reactions; // kept between rows: no allocation per row
    m.reactions(reactions);
    for (const Vec3& r : reactions)
        rows.insert(rows.end(), {r[0], r[1], r[2]});
    for (const LoadSpec& l : m.deck().loads)
        rows.push_back(load_value(l, t));
    for (index_t k = 0; k < static_cast<index_t>(m.section_nodes.size()); ++k)
    {
        const Vec3 f = m.section_force(k);
        rows.insert(rows.end(), {f[0], f[1], f[2]});
    }
    for (index_t p = 0; p < static_cast<index_t>(m.parts.size()); ++p)
    {
        const Model::PartSummary s = m.part_summary(p);
        rows.insert(rows.end(), {s.mass, s.kinetic, s.internal, s.hourglass, s.momentum[0], s.momentum[1], s.momentum[2]});
    }
    for (index_t p = 0; p < static_cast<index_t>(m.parts.size()); ++p)
        if (m.deck().parts[static_cast<std::size_t>(p)].converts())
        {
            const std::vector<char>& rk = m.rk_elements(p);
            rows.push_back(static_cast<real_t>(std::count(rk.begin(), rk.end(), 1)));
        }
    for (index_t n : m.probe_nodes)
    {
        const Vec3 u = m.physical(m.nodes.u, n), v = m.physical(m.nodes.v, n);
        rows.insert(rows.end(), {u[0], u[1], u[2], v[0], v[1], v[2]});
        const Sym6 s = m.nodal_stress(n);
        for (int k = 0; k < 6; ++k)
            rows.push_back(s[k]);
    }
}

/// next += interval until next > limit: the next output time after one at `limit`. An interval
/// far below the step skips the missed times in one jump, and one below the resolution of `limit`
/// (next + interval == next) ends just past limit: an output every step, never an endless loop.
void advance_past(real_t& next, real_t limit, real_t interval)
{
    if (next > limit)
        return;
    const real_t missed = std::floor((limit - next) / interval);
    if (missed > 16)
        next += (missed - 1) * interval;
    while (next <= limit)
    {
        const real_t after = next + interval;
        if (!(after > next))
        {
            next = std::nextafter(limit, std::numeric_limits<real_t>::infinity());
            return;
        }
        next = after;
    }
}

/// The progress line's energy ratio: the ledger's total over its origin plus the external work.
real_t energy_ratio(const Energies& e)
{
    const real_t ref = e.kinetic0 + e.internal0 + e.external_work;
    return ref > 0 ? e.total() / ref : 1.0;
}

class Progress
{
  public:
    explicit Progress(bool enabled) : enabled_(enabled), tty_(isatty(STDERR_FILENO) != 0) {}
    void update(real_t t, real_t t_end, std::int64_t step, real_t dt, real_t energy_ratio,
                real_t elapsed, bool force = false)
    {
        if (!enabled_)
            return;
        const real_t interval = tty_ ? 0.25 : 5.0;
        if (!force && elapsed - last_ < interval)
            return;
        last_ = elapsed;
        const real_t frac = t / t_end;
        const real_t eta = frac > 0 ? elapsed * (1 - frac) / frac : 0.0;
        char line[200];
        std::snprintf(line, sizeof line,
                      "t = %.4e s (%5.1f%%)  step %lld  dt = %.3e s  energy ratio %.4f  ETA %.1f s",
                      t, 100 * frac, static_cast<long long>(step), dt, energy_ratio, eta);
        if (tty_)
            std::fprintf(stderr, "\r%s\033[K", line);
        else
            std::fprintf(stderr, "%s\n", line);
        std::fflush(stderr);
    }
    void finish()
    {
        if (enabled_ && tty_)
            std::fprintf(stderr, "\n");
    }

  private:
    bool enabled_;
    bool tty_;
    real_t last_ = -1e9;
};
} // namespace

std::string checkpoint_path(const std::string& dir, int k)
{
    return dir + (k == 0 ? "/checkpoint.h5" : "/checkpoint." + std::to_string(k) + ".h5");
}

namespace
{
// kScheduleSlack (core/types.hpp) is relative to the scheduled time itself, not to time.end: a run
// whose end was 1e30 s, bounded by max_steps, wrote every step's row and no frame between the
// first and the last.
constexpr real_t kHistorySlack = 1e-15;
} // namespace

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
    sum.history_columns = history_columns(model);
    const auto wall0 = std::chrono::steady_clock::now();
    auto elapsed = [&]
    { return std::chrono::duration<real_t>(std::chrono::steady_clock::now() - wall0).count(); };
    // output time: history rows and field frames (their clocks are read only when they run)
    auto output_clock = [&sum](auto&& work)
    {
        const auto t0 = std::chrono::steady_clock::now();
        work();
        sum.output_seconds += std::chrono::duration<real_t>(std::chrono::steady_clock::now() - t0).count();
    };
    real_t start_seconds = 0.0; // the stepper's first start

    const StateArchive* resume = opt.resume;
    if (resume)
    {
        RKFEM_REQUIRE(!opt.out_dir.empty(), "a restart continues a run's directory: out_dir is empty");
        resume->get("run.history", sum.history);
    }
    // the run's id (results.h5, checkpoints, summary.json): a new one, or a restart continues its
    // checkpoint's run (one from before ids: none)
    sum.run_id = !resume                    ? new_run_id()
                 : resume->has("run.run_id") ? resume->text("run.run_id")
                                             : std::string();
    std::unique_ptr<ResultsWriter> writer;
    std::ofstream csv;
    if (!opt.out_dir.empty())
        output_clock(
            [&]
            {
                if (resume)
                    writer = std::make_unique<ResultsWriter>(opt.out_dir, model.deck().output, *resume);
                else
                {
                    writer = std::make_unique<ResultsWriter>(opt.out_dir, model.deck().output);
                    writer->write_run_id(sum.run_id);
                    writer->write_mesh(model);
                }
                csv.open(opt.out_dir + "/history.csv");
                if (!csv)
                    throw Error("cannot write " + opt.out_dir + "/history.csv (" + std::strerror(errno) + ")");
                for (std::size_t i = 0; i < sum.history_columns.size(); ++i)
                    csv << (i ? "," : "") << sum.history_columns[i];
                csv << "\n" << std::setprecision(12);
            });

    auto flush_history_row = [&](std::size_t first)
    {
        if (!csv.is_open())
            return;
        const std::size_t nc = sum.history_columns.size();
        for (std::size_t r = first; r < sum.history.size() / nc; ++r)
        {
            for (std::size_t c = 0; c < nc; ++c)
                csv << (c ? "," : "") << sum.history[r * nc + c];
            csv << "\n";
        }
    };
    if (resume)
        flush_history_row(0); // the rows before the checkpoint, as the run wrote them

    std::unique_ptr<ImpactAnalysis> impact;
    if (model.deck().impact.active)
        impact = std::make_unique<ImpactAnalysis>(model, model.deck().impact);
    real_t actual_depth = 0.0; // the crater's, at the last field output

    auto stepper = make_stepper(ts);
    Progress progress(opt.progress);
    real_t t = 0.0;
    std::int64_t step = 0;
    real_t next_output = 0.0;
    real_t next_history = 0.0;
    real_t dt_last = 0.0;
    std::size_t element_steps = 0;
    const bool checkpointing = opt.checkpoint_interval > 0 && !opt.out_dir.empty();
    real_t next_checkpoint = opt.checkpoint_interval;
    real_t dt_stable = 0.0;
    if (resume)
    {
        RKFEM_REQUIRE(resume->text("run.stepper") == stepper->name(),
                      "the checkpoint was written with time.stepper " << resume->text("run.stepper")
                                                                      << "; the deck now has " << stepper->name());
        t = resume->value<real_t>("run.t");
        step = resume->value<std::int64_t>("run.step");
        next_output = resume->value<real_t>("run.next_output");
        next_history = resume->value<real_t>("run.next_history");
        dt_last = resume->value<real_t>("run.dt_last");
        dt_stable = resume->value<real_t>("run.dt_stable");
        element_steps = resume->value<std::size_t>("run.element_steps");
        sum.dt_first = resume->value<real_t>("run.dt_first");
        sum.dt_min = resume->value<real_t>("run.dt_min");
        sum.max_balance_error = resume->value<real_t>("run.max_balance_error");
        actual_depth = resume->value<real_t>("run.actual_depth");
        if (checkpointing)
        {
            next_checkpoint = resume->value<real_t>("run.next_checkpoint");
            if (resume->value<real_t>("run.checkpoint_interval") != opt.checkpoint_interval)
                next_checkpoint = t; // a new interval: the clock starts again from here
            advance_past(next_checkpoint, t, opt.checkpoint_interval);
        }
    }
    // a checkpoint of the state between steps: the model's, the stepper's, the loop's and the
    // output's, with the deck that built the model; the oldest kept ones rotate out
    auto write_checkpoint_now = [&]
    {
        StateArchive a;
        a.put_text("run.run_id", sum.run_id);
        a.put_text("run.deck_text", opt.deck_text);
        a.put_text("run.deck_path", opt.deck_path);
        a.put_text("run.deck_dir", opt.deck_dir);
        a.put_text("run.data_files", opt.data_files);
        std::string overrides;
        for (const auto& o : opt.overrides)
            overrides += o + "\n";
        a.put_text("run.overrides", overrides);
        a.put_text("run.stepper", stepper->name());
        a.put_value("run.t", t);
        a.put_value("run.step", step);
        a.put_value("run.next_output", next_output);
        a.put_value("run.next_history", next_history);
        a.put_value("run.dt_last", dt_last);
        a.put_value("run.dt_stable", dt_stable);
        a.put_value("run.element_steps", element_steps);
        a.put_value("run.dt_first", sum.dt_first);
        a.put_value("run.dt_min", sum.dt_min);
        a.put_value("run.max_balance_error", sum.max_balance_error);
        a.put_value("run.actual_depth", actual_depth);
        a.put_value("run.next_checkpoint", next_checkpoint);
        a.put_value("run.checkpoint_interval", opt.checkpoint_interval);
        a.put("run.history", sum.history);
        model.save_state(a);
        stepper->save_state(a);
        writer->save(a);
        // the new one whole first (a failed write leaves the others as they were), then the
        // older ones move down, then the new one takes the newest name
        const std::string fresh = opt.out_dir + "/checkpoint.new.h5";
        write_checkpoint(fresh, a);
        std::error_code ec;
        for (int k = opt.checkpoint_keep - 1; k > 0; --k)
            if (std::filesystem::exists(checkpoint_path(opt.out_dir, k - 1), ec))
                std::filesystem::rename(checkpoint_path(opt.out_dir, k - 1), checkpoint_path(opt.out_dir, k), ec);
        std::filesystem::rename(fresh, checkpoint_path(opt.out_dir), ec);
        if (ec)
            throw Error("cannot rename " + fresh + " to " + checkpoint_path(opt.out_dir) + ": " + ec.message());
        sync_directory(opt.out_dir); // the renames reach the disk
    };
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
    try
    {
        StepReport rep;
        if (resume)
        {
            stepper->load_state(model, t, *resume);
            rep.t = t;
            rep.dt_stable = dt_stable;
        }
        else
            rep = stepper->initialize(model, t);
        start_seconds = elapsed() - sum.output_seconds;
        auto observe = [&](bool final_step)
        {
            const bool output_now = (writer && t >= next_output - kScheduleSlack * t) || final_step || step == 0;
            if (impact && output_now)
                actual_depth = impact->actual_depth(model); // a pass over the target: at outputs only
            if (t >= next_history - kHistorySlack * t || final_step)
                output_clock(
                    [&]
                    {
                        const std::size_t first = sum.history.size() / sum.history_columns.size();
                        append_row(model, t, dt_last, sum.history, impact.get(), actual_depth);
                        flush_history_row(first);
                        if (ts.history_interval > 0)
                            advance_past(next_history, t, ts.history_interval);
                    });
            if (writer && (t >= next_output - kScheduleSlack * t || final_step))
                output_clock(
                    [&]
                    {
                        writer->write_step(model, t);
                        if (ts.output_interval > 0)
                            advance_past(next_output, t + kScheduleSlack * t, ts.output_interval);
                        else
                            next_output = 2 * ts.end + 1; // start and end only
                        if (csv.is_open())
                            csv.flush();
                    });
            if (observer)
                observer(model, t, dt_last, step);
        };
        if (!resume) // a restart's state at t is already in the output
        {
            observe(false);
            for (std::size_t k = 0; k < model.contacts.size(); ++k)
                if (const index_t n = model.contacts[k]->initial_penetrations(); n > 0 && opt.progress)
                    std::fprintf(stderr,
                                 "rkfem: warning: contacts.%zu: %lld node(s) start inside the other surface; they are "
                                 "%s (summary.json: contacts)\n",
                                 k, static_cast<long long>(n),
                                 model.contacts[k]->holds_initial_penetrations()
                                     ? "held at that depth, not pushed out"
                                     : "pushed out by the penalty (mortar contact holds no offsets)");
        }
        dt_stable = rep.dt_stable;
        index_t ne = model.n_work_items(); // elements, and the stress points of nodal parts
        std::vector<real_t> event_a;  // accelerations before an event
        while (t < ts.end * (1 - kScheduleSlack))
        {
            if (ts.max_steps > 0 && step >= ts.max_steps)
                break;
            const real_t dt = next_time_step(ts, t, dt_stable);
            if (!(dt > 0) || !std::isfinite(dt))
                throw InstabilityError("time step collapsed to " + std::to_string(dt) + " s at t = " +
                                       std::to_string(t) + " s, step " + std::to_string(step));
            if (step > 0 && ts.dt_min_fraction > 0 && dt_stable * ts.dt_scale < ts.dt_min_fraction * sum.dt_first)
            {
                // a collapsing stable step (crushed elements, a run gone unstable past the energy
                // check) would take ever more steps and never end (the stable step, not the step
                // taken: the last step is cut short to land on the end time)
                std::ostringstream os;
                os << "time step fell to " << dt_stable * ts.dt_scale << " s, below time.dt_min_fraction " << ts.dt_min_fraction
                   << " of the first step (" << sum.dt_first << " s), at t = " << t << " s, step " << step;
                throw InstabilityError(os.str());
            }
            ++step;
            in_step = true;
            if (governor.active())
                set_threads(governor.threads());
            const auto step_start = std::chrono::steady_clock::now();
            const long preempted_before = governor.active() ? involuntary_switches() : 0;
            rep = stepper->step(model, t, dt, step);
            if (governor.active())
                governor.record(std::chrono::duration<double>(std::chrono::steady_clock::now() - step_start).count(),
                                static_cast<double>(involuntary_switches() - preempted_before));
            in_step = false;
            t = rep.t;
            dt_last = dt;
            if (step == 1)
                sum.dt_first = sum.dt_min = dt;
            sum.dt_min = std::min(sum.dt_min, dt);
            dt_stable = rep.dt_stable;
            element_steps += static_cast<std::size_t>(ne);
            // the nodes' motion (kinetic energy, the parts' momentum) for what reads it this step:
            // the balance check (every kBalanceEvery steps), history rows, fields, checkpoints
            // SIGINT / SIGTERM: this step is the last; its state is written as the end's is
            const int stop_signal = interrupt_signal();
            const bool last =
                t >= ts.end * (1 - kScheduleSlack) || (ts.max_steps > 0 && step >= ts.max_steps) || stop_signal != 0;
            const bool check_due =
                !defer_motion || step % kBalanceEvery == 0 || last || t >= next_history - kHistorySlack * t ||
                (writer && t >= next_output - kScheduleSlack * t) ||
                (checkpointing && t >= next_checkpoint - kScheduleSlack * t);
            if (check_due)
                model.refresh_motion();
            const bool own = model.apply_events(t, step);
            if ((opt.events && opt.events(model, t, step)) || own)
            {
                // the discretization changed: start the stepper again from this state, and book
                // what the new accelerations change in the kinetic energy
                event_a = model.nodes.a;
                const real_t kinetic = model.energy.kinetic;
                rep = stepper->initialize(model, t);
                // prescribed velocities imposed again through a new kinematic map (a conversion
                // made constrained nodes particles): the supports did that work
                model.energy.external_work += model.energy.kinetic - kinetic;
                book_event_energy(model, event_a, dt);
                dt_stable = rep.dt_stable;
                ne = model.n_work_items();
            }
            const real_t err = check_due ? model.energy.balance_error() : 0.0;
            sum.max_balance_error = std::max(sum.max_balance_error, err);
            observe(last);
            // The first steps after a step load or an impulsive start carry an O(1) relative balance error
            // that decays like 1/n; an unstable run grows instead, so the check starts at step 50.
            if (check_due && step >= 50 && err > ts.energy_error_limit && model.energy.total() > 0)
            {
                std::ostringstream os;
                os << "energy balance error " << err << " exceeds time.energy_error_limit "
                   << ts.energy_error_limit << " at t = " << t << " s, step " << step;
                throw InstabilityError(os.str());
            }
            if (checkpointing && (t >= next_checkpoint - kScheduleSlack * t || last))
                output_clock(
                    [&]
                    {
                        advance_past(next_checkpoint, t + kScheduleSlack * t, opt.checkpoint_interval);
                        write_checkpoint_now();
                    });
            progress.update(t, ts.end, step, dt, energy_ratio(model.energy), elapsed());
            if (stop_signal != 0)
            {
                std::ostringstream os;
                os << "interrupted by " << interrupt_signal_name(stop_signal) << " at t = " << t << " s, step " << step
                   << "; the state there written" << (checkpointing ? " (frame, history row and checkpoint)" : " (frame and history row)");
                sum.status = "interrupted";
                sum.message = os.str();
                break;
            }
        }
        model.refresh_motion();
        progress.update(t, ts.end, step, dt_last, energy_ratio(model.energy), elapsed(), true);
    }
    catch (const InstabilityError& e)
    {
        // the summary's kinetic energy is that of the last balance check or output before the
        // failure (a failed step's accelerations are not those of the last good state)
        sum.status = "unstable";
        sum.message = e.what();
        // the fields written so far stay; then the last good state (the last accepted step's,
        // when it was not written yet) and the state the run failed in, each at its own time (a
        // step's end, or an ERK stage): the failed frame can be inspected and is never labelled
        // with the last good time. The failed frame's stresses and histories are the committed
        // (last good) ones: only its motion is the failed step's. The summary measures the last good
        // state.
        sum.failed_time = std::isfinite(e.time) ? e.time : t;
        NodeSet& n = model.nodes;
        std::vector<real_t> u_other = n.u, v_other = n.v; // the failed state
        const bool restored = in_step && stepper->restore_last_good(model);
        auto swap_state = [&]
        {
            n.u.swap(u_other);
            n.v.swap(v_other);
            model.update_coordinates();
        };
        if (writer)
            output_clock(
                [&]
                {
                    if (restored && writer->last_time() < t)
                        writer->write_step(model, t);
                    if (restored)
                        swap_state(); // the failed state, for its frame
                    if (writer->last_time() < sum.failed_time)
                        writer->write_step(model, sum.failed_time);
                    if (restored)
                        swap_state(); // the last good state again, for the summary
                });
        if (in_step)
            --step; // the failed step is not counted: steps and end_time are the last good step's
    }
    progress.finish();
    set_threads(team);
    sum.thread_switches = governor.switches();
    sum.steps_on_one_thread = governor.steps_on_one_thread();
    sum.steps = step;
    sum.end_time = t;
    sum.wall_seconds = elapsed();
    sum.setup_seconds = opt.setup_seconds + start_seconds;
    sum.stepping_seconds = std::max(0.0, sum.wall_seconds - sum.output_seconds - start_seconds);
    sum.ns_per_element_cycle = element_steps > 0 ? 1e9 * sum.stepping_seconds / element_steps : 0.0;
    sum.energy = model.energy;
    for (index_t b = 0; b < static_cast<index_t>(model.blocks.size()); ++b)
        for (index_t e = 0; e < model.blocks[b].n_elements(); ++e)
            sum.max_plastic_strain = std::max(sum.max_plastic_strain, model.element_plastic_strain(b, e));
    sum.n_outputs = writer ? writer->n_steps() : 0;
    if (impact)
    {
        sum.has_impact = true;
        sum.impact = impact->measure(model);
    }
    if (csv.is_open())
    {
        csv.flush();
        if (!csv)
            throw Error("cannot write " + opt.out_dir + "/history.csv (disk full?); results.h5 holds the history too");
    }
    if (writer)
    {
        writer->write_history(sum.history_columns, sum.history);
        write_summary_json(opt.out_dir + "/summary.json", model, opt, sum);
    }
    return sum;
}
} // namespace rkfem
