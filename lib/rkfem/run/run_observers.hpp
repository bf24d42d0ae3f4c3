#pragma once
/// @file run_observers.hpp
/// What the run loop (simulation.cpp) calls at step boundaries besides the stepper: the record
/// of the run (history rows and history.csv, field frames in results.h5, the impact measures the
/// rows carry), checkpoints, the progress line and the energy check. Each reads the model and
/// never changes the solution; each says when it is next due, so that the loop brings the nodes'
/// motion up to date only on the steps something reads it (Model::defer_motion).
#include <fstream>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "rkfem/analysis/impact.hpp"
#include "rkfem/core/state_archive.hpp"
#include "rkfem/io/results_writer.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/run/simulation.hpp"
#include "rkfem/time/stepper.hpp"

namespace rkfem
{
/// The loop's own state between steps: what a checkpoint keeps of it and a restart takes back.
struct LoopState
{
    real_t t = 0.0;
    std::int64_t step = 0;
    real_t dt_last = 0.0;   ///< the last step taken [s]
    real_t dt_stable = 0.0; ///< the last stable-step estimate [s]
    std::size_t element_steps = 0;
    void save(StateArchive& a, const RunSummary& sum) const;
    void load(const StateArchive& a, RunSummary& sum);
};

/// The history columns a model's rows carry (energies, impact, reactions, loads, sections, parts,
/// RK regions, probes), in order.
std::vector<std::string> history_columns(const Model& m);

/// History rows (RunSummary::history, history.csv) and field frames (results.h5): the schedule of
/// each, and the impact measures the rows carry (the crater's actual depth at frames only: a pass
/// over the target). Output time is booked into RunSummary::output_seconds.
class RunRecord
{
  public:
    /// Opens out_dir's history.csv and results.h5 (none when out_dir is empty): new, or for a
    /// restart the writer continues results.h5 and the rows before the checkpoint are written again.
    RunRecord(const Model& model, const RunOptions& opt, RunSummary& sum);
    /// A history row or a field frame falls due at t.
    bool due(real_t t) const;
    /// At the start and after each accepted step (events applied): the row and the frame due at
    /// loop.t; `final` writes both.
    void observe(const Model& model, const LoopState& loop, bool final);
    void save(StateArchive& a) const;
    void load(const StateArchive& a);
    /// After an instability, the frames that show it: the last good state's (when the stepper
    /// restored it and it was not written yet) and the failed one at `failed_time`, each at its
    /// own time. `swap` exchanges the model's state between the two.
    void write_failure(const Model& model, real_t t, real_t failed_time, bool restored,
                       const std::function<void()>& swap);
    /// The end: summary's impact measures and frame count; history.csv flushed (checked), the
    /// history into results.h5 and summary.json.
    void finish(const Model& model, const RunOptions& opt);
    bool writes_files() const { return writer_ != nullptr; }

  private:
    template <class Work> void clock(Work&& work);
    bool row_due(real_t t) const;   ///< a history row
    bool frame_due(real_t t) const; ///< a field frame (only with files)
    void flush_rows(std::size_t first);
    RunSummary& sum_;
    std::unique_ptr<ResultsWriter> writer_;
    std::ofstream csv_;
    std::unique_ptr<ImpactAnalysis> impact_;
    std::unique_ptr<SpallAnalysis> spall_;
    real_t actual_depth_ = 0.0; ///< the crater's, at the last frame
    real_t next_output_ = 0.0, next_history_ = 0.0;
    real_t output_interval_ = 0.0, history_interval_ = 0.0, end_ = 0.0;
};

/// Checkpoints every RunOptions::checkpoint_interval of simulated time and at the end
/// (out_dir/checkpoint.h5, the oldest kept ones rotating out): the model's state, the stepper's,
/// the loop's and the record's, with the deck that built the model.
class Checkpointer
{
  public:
    explicit Checkpointer(const RunOptions& opt) : opt_(opt), next_(opt.checkpoint_interval) {}
    bool active() const { return opt_.checkpoint_interval > 0 && !opt_.out_dir.empty(); }
    bool due(real_t t) const;
    /// A restart: the schedule the checkpoint had (a new interval starts again from t).
    void load(const StateArchive& a, real_t t);
    /// Writes one and moves the schedule past t.
    void write(const Model& model, const TimeStepper& stepper, const RunRecord& record, const LoopState& loop,
               const RunSummary& sum);

  private:
    const RunOptions& opt_;
    real_t next_;
};

/// The progress line on stderr: every 0.25 s on a terminal (one line, rewritten), every 5 s
/// otherwise.
class Progress
{
  public:
    explicit Progress(bool enabled);
    void update(real_t t, real_t t_end, std::int64_t step, real_t dt, real_t energy_ratio, real_t elapsed,
                bool force = false);
    void finish();

  private:
    bool enabled_;
    bool tty_;
    real_t last_ = -1e9;
};

/// next += interval until next > limit: the next output time after one at `limit`. An interval
/// far below the step skips the missed times in one jump, and one below the resolution of `limit`
/// (next + interval == next) ends just past limit: an output every step, never an endless loop.
void advance_past(real_t& next, real_t limit, real_t interval);
} // namespace rkfem
