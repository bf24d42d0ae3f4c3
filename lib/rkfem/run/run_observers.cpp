#include "rkfem/run/run_observers.hpp"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <map>
#include <unistd.h>

#include "rkfem/core/error.hpp"
#include "rkfem/io/checkpoint.hpp"
#include "rkfem/run/summary.hpp"

namespace rkfem
{
namespace
{
/// How far below a history row's scheduled time a step's time may fall and still be at it,
/// relative to the time (the frames' and checkpoints' slack is kScheduleSlack, core/types.hpp).
constexpr real_t kHistorySlack = 1e-15;

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

/// impact: the analysis, with the actual depth as last computed (at field outputs); spall: its
/// analysis (a column of nodes: every row)
void append_row(const Model& m, real_t t, real_t dt, std::vector<real_t>& rows, const ImpactAnalysis* impact,
                real_t actual_depth, const SpallAnalysis* spall)
{
    const Energies& e = m.energy;
    rows.insert(rows.end(),
                {t, dt, e.kinetic, e.internal, e.hourglass, e.bulk_viscosity, e.damping, e.external_work, e.contact,
                 e.eroded, e.total(), e.balance_error(), e.hourglass_ratio(), e.hourglass_to_total()});
    if (impact)
        rows.insert(rows.end(), {impact->apparent_depth(m), actual_depth, impact->residual_velocity(m)});
    if (spall)
    {
        const SpallMeasures s = spall->measure(m);
        rows.insert(rows.end(), {s.thickness, s.fly_off_velocity, s.back_face_velocity});
    }
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
        rows.insert(rows.end(),
                    {s.mass, s.kinetic, s.internal, s.hourglass, s.momentum[0], s.momentum[1], s.momentum[2]});
    }
    for (index_t p = 0; p < static_cast<index_t>(m.parts.size()); ++p)
        if (m.deck().parts[static_cast<std::size_t>(p)].converts())
        {
            rows.push_back(static_cast<real_t>(m.rk_element_count(p)));
        }
    if (std::any_of(m.deck().parts.begin(), m.deck().parts.end(), [](const PartSpec& p) { return p.converts(); }))
        rows.insert(rows.end(),
                    {static_cast<real_t>(m.converted_elements()), static_cast<real_t>(m.reverted_elements())});
    if (std::any_of(m.deck().parts.begin(), m.deck().parts.end(),
                    [](const PartSpec& p) { return p.refinement.active(); }))
        rows.insert(rows.end(),
                    {static_cast<real_t>(m.refined_particles()), static_cast<real_t>(m.coarsened_particles())});
    for (index_t n : m.probe_nodes)
    {
        const Vec3 u = m.physical(m.nodes.u, n), v = m.physical(m.nodes.v, n);
        rows.insert(rows.end(), {u[0], u[1], u[2], v[0], v[1], v[2]});
        const Sym6 s = m.nodal_stress(n);
        for (int k = 0; k < 6; ++k)
            rows.push_back(s[k]);
    }
}

} // namespace

std::vector<std::string> history_columns(const Model& m)
{
    std::vector<std::string> c{
        "time",          "dt",      "kinetic", "internal", "hourglass",     "bulk_viscosity",  "damping",
        "external_work", "contact", "eroded",  "total",    "balance_error", "hourglass_ratio", "hourglass_to_total"};
    if (m.deck().impact.active)
        c.insert(c.end(), {"apparent_depth", "actual_depth", "residual_velocity"});
    if (m.deck().spall.active)
        c.insert(c.end(), {"spall_thickness", "spall_velocity", "back_face_velocity"});
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
        for (const char* q :
             {"_mass", "_kinetic", "_internal", "_hourglass", "_momentum_x", "_momentum_y", "_momentum_z"})
            c.push_back("part_" + p.name + q);
    for (const auto& p : m.deck().parts)
        if (p.converts())
            c.push_back("part_" + p.name + "_rk_elements"); // evolutionary coupling: the RK region's size
    // and the events' running totals (summary.json's converted_elements and reverted_elements)
    if (std::any_of(m.deck().parts.begin(), m.deck().parts.end(), [](const PartSpec& p) { return p.converts(); }))
        c.insert(c.end(), {"converted_elements", "reverted_elements"});
    // refinement's running totals (summary.json's refined_particles and coarsened_particles)
    if (std::any_of(m.deck().parts.begin(), m.deck().parts.end(),
                    [](const PartSpec& p) { return p.refinement.active(); }))
        c.insert(c.end(), {"refined_particles", "coarsened_particles"});
    for (const auto& p : m.deck().probes)
    {
        for (const char* q : {"ux", "uy", "uz", "vx", "vy", "vz"})
            c.push_back(p.name + "_" + q);
        for (const char* q : {"sxx", "syy", "szz", "sxy", "syz", "szx"})
            c.push_back(p.name + "_" + q);
    }
    return c;
}

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

void LoopState::save(StateArchive& a, const RunSummary& sum) const
{
    a.put_value("run.t", t);
    a.put_value("run.step", step);
    a.put_value("run.dt_last", dt_last);
    a.put_value("run.dt_stable", dt_stable);
    a.put_value("run.element_steps", element_steps);
    a.put_value("run.dt_first", sum.dt_first);
    a.put_value("run.dt_min", sum.dt_min);
    a.put_value("run.max_balance_error", sum.max_balance_error);
    a.put_value("run.events", sum.events);
}

void LoopState::load(const StateArchive& a, RunSummary& sum)
{
    t = a.value<real_t>("run.t");
    step = a.value<std::int64_t>("run.step");
    dt_last = a.value<real_t>("run.dt_last");
    dt_stable = a.value<real_t>("run.dt_stable");
    element_steps = a.value<std::size_t>("run.element_steps");
    sum.dt_first = a.value<real_t>("run.dt_first");
    sum.dt_min = a.value<real_t>("run.dt_min");
    sum.max_balance_error = a.value<real_t>("run.max_balance_error");
    // checkpoints written before 2026-12-07 have no event count
    sum.events = a.has("run.events") ? a.value<std::int64_t>("run.events") : 0;
}

template <class Work> void RunRecord::clock(Work&& work)
{
    const auto t0 = std::chrono::steady_clock::now();
    work();
    sum_.output_seconds += std::chrono::duration<real_t>(std::chrono::steady_clock::now() - t0).count();
}

RunRecord::RunRecord(const Model& model, const RunOptions& opt, RunSummary& sum)
    : sum_(sum), output_interval_(model.deck().time.output_interval),
      history_interval_(model.deck().time.history_interval), end_(model.deck().time.end)
{
    sum_.history_columns = history_columns(model);
    const StateArchive* resume = opt.resume;
    if (resume)
        resume->get("run.history", sum_.history);
    if (!opt.out_dir.empty())
        clock(
            [&]
            {
                if (resume)
                    writer_ = std::make_unique<ResultsWriter>(opt.out_dir, model.deck().output, *resume);
                else
                {
                    writer_ = std::make_unique<ResultsWriter>(opt.out_dir, model.deck().output);
                    writer_->write_run_id(sum_.run_id);
                    writer_->write_mesh(model);
                }
                csv_.open(opt.out_dir + "/history.csv");
                if (!csv_)
                    throw Error("cannot write " + opt.out_dir + "/history.csv (" + std::strerror(errno) + ")");
                for (std::size_t i = 0; i < sum_.history_columns.size(); ++i)
                    csv_ << (i ? "," : "") << sum_.history_columns[i];
                csv_ << "\n" << std::setprecision(12);
            });
    if (resume)
        flush_rows(0); // the rows before the checkpoint, as the run wrote them
    if (model.deck().impact.active)
        impact_ = std::make_unique<ImpactAnalysis>(model, model.deck().impact);
    if (model.deck().spall.active)
        spall_ = std::make_unique<SpallAnalysis>(model, model.deck().spall);
}

void RunRecord::flush_rows(std::size_t first)
{
    if (!csv_.is_open())
        return;
    const std::size_t nc = sum_.history_columns.size();
    for (std::size_t r = first; r < sum_.history.size() / nc; ++r)
    {
        for (std::size_t c = 0; c < nc; ++c)
            csv_ << (c ? "," : "") << sum_.history[r * nc + c];
        csv_ << "\n";
    }
}

bool RunRecord::row_due(real_t t) const
{
    return t >= next_history_ - kHistorySlack * t;
}

bool RunRecord::frame_due(real_t t) const
{
    return writer_ && t >= next_output_ - kScheduleSlack * t;
}

bool RunRecord::due(real_t t) const
{
    return row_due(t) || frame_due(t);
}

void RunRecord::observe(const Model& model, const LoopState& loop, bool final)
{
    const real_t t = loop.t;
    const bool output_now = frame_due(t) || final || loop.step == 0;
    if (impact_ && output_now)
        actual_depth_ = impact_->actual_depth(model); // a pass over the target: at outputs only
    if (row_due(t) || final)
        clock(
            [&]
            {
                const std::size_t first = sum_.history.size() / sum_.history_columns.size();
                append_row(model, t, loop.dt_last, sum_.history, impact_.get(), actual_depth_, spall_.get());
                flush_rows(first);
                if (history_interval_ > 0)
                    advance_past(next_history_, t, history_interval_);
            });
    if (writer_ && (frame_due(t) || final))
        clock(
            [&]
            {
                writer_->write_step(model, t);
                if (output_interval_ > 0)
                    advance_past(next_output_, t + kScheduleSlack * t, output_interval_);
                else
                    next_output_ = 2 * end_ + 1; // start and end only
                if (csv_.is_open())
                    csv_.flush();
            });
}

void RunRecord::save(StateArchive& a) const
{
    a.put_value("run.next_output", next_output_);
    a.put_value("run.next_history", next_history_);
    a.put_value("run.actual_depth", actual_depth_);
    a.put("run.history", sum_.history);
    if (writer_)
        writer_->save(a);
}

void RunRecord::load(const StateArchive& a)
{
    next_output_ = a.value<real_t>("run.next_output");
    next_history_ = a.value<real_t>("run.next_history");
    actual_depth_ = a.value<real_t>("run.actual_depth");
}

void RunRecord::write_failure(const Model& model, real_t t, real_t failed_time, bool restored,
                              const std::function<void()>& swap)
{
    if (!writer_)
        return;
    clock(
        [&]
        {
            if (restored && writer_->last_time() < t)
                writer_->write_step(model, t);
            if (restored)
                swap(); // the failed state, for its frame
            if (writer_->last_time() < failed_time)
                writer_->write_step(model, failed_time);
            if (restored)
                swap(); // the last good state again, for the summary
        });
}

void RunRecord::finish(const Model& model, const RunOptions& opt)
{
    sum_.n_outputs = writer_ ? writer_->n_steps() : 0;
    if (impact_)
    {
        sum_.has_impact = true;
        sum_.impact = impact_->measure(model);
    }
    if (spall_)
    {
        sum_.has_spall = true;
        sum_.spall = spall_->measure(model);
    }
    if (csv_.is_open())
    {
        csv_.flush();
        if (!csv_)
            throw Error("cannot write " + opt.out_dir + "/history.csv (disk full?); results.h5 holds the history too");
    }
    if (writer_)
    {
        writer_->write_history(sum_.history_columns, sum_.history);
        write_summary_json(opt.out_dir + "/summary.json", model, opt, sum_);
    }
}

bool Checkpointer::due(real_t t) const
{
    return active() && t >= next_ - kScheduleSlack * t;
}

void Checkpointer::load(const StateArchive& a, real_t t)
{
    if (!active())
        return;
    next_ = a.value<real_t>("run.next_checkpoint");
    if (a.value<real_t>("run.checkpoint_interval") != opt_.checkpoint_interval)
        next_ = t; // a new interval: the clock starts again from here
    advance_past(next_, t, opt_.checkpoint_interval);
}

void Checkpointer::write(const Model& model, const TimeStepper& stepper, const RunRecord& record, const LoopState& loop,
                         const RunSummary& sum)
{
    advance_past(next_, loop.t + kScheduleSlack * loop.t, opt_.checkpoint_interval);
    StateArchive a;
    a.put_text("run.run_id", sum.run_id);
    a.put_text("run.deck_text", opt_.deck_text);
    a.put_text("run.deck_path", opt_.deck_path);
    a.put_text("run.deck_dir", opt_.deck_dir);
    a.put_text("run.data_files", opt_.data_files);
    std::string overrides;
    for (const auto& o : opt_.overrides)
        overrides += o + "\n";
    a.put_text("run.overrides", overrides);
    a.put_text("run.stepper", stepper.name());
    loop.save(a, sum);
    record.save(a);
    a.put_value("run.next_checkpoint", next_);
    a.put_value("run.checkpoint_interval", opt_.checkpoint_interval);
    model.save_state(a);
    stepper.save_state(a);
    // the new one whole first (a failed write leaves the others as they were), then the older
    // ones move down, then the new one takes the newest name
    const std::string fresh = opt_.out_dir + "/checkpoint.new.h5";
    write_checkpoint(fresh, a);
    std::error_code ec;
    for (int k = opt_.checkpoint_keep - 1; k > 0; --k)
        if (std::filesystem::exists(checkpoint_path(opt_.out_dir, k - 1), ec))
            std::filesystem::rename(checkpoint_path(opt_.out_dir, k - 1), checkpoint_path(opt_.out_dir, k), ec);
    std::filesystem::rename(fresh, checkpoint_path(opt_.out_dir), ec);
    if (ec)
        throw Error("cannot rename " + fresh + " to " + checkpoint_path(opt_.out_dir) + ": " + ec.message());
    sync_directory(opt_.out_dir); // the renames reach the disk
}

Progress::Progress(bool enabled) : enabled_(enabled), tty_(isatty(STDERR_FILENO) != 0) {}

void Progress::update(real_t t, real_t t_end, std::int64_t step, real_t dt, real_t energy_ratio, real_t elapsed,
                      bool force)
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
    std::snprintf(line, sizeof line, "t = %.4e s (%5.1f%%)  step %lld  dt = %.3e s  energy ratio %.4f  ETA %.1f s", t,
                  100 * frac, static_cast<long long>(step), dt, energy_ratio, eta);
    if (tty_)
        std::fprintf(stderr, "\r%s\033[K", line);
    else
        std::fprintf(stderr, "%s\n", line);
    std::fflush(stderr);
}

void Progress::finish()
{
    if (enabled_ && tty_)
        std::fprintf(stderr, "\n");
}
} // namespace rkfem
