#pragma once
/// @file simulation.hpp
/// The run loop: step, check, observe. Output (fields, histories, progress) is an observer that
/// runs at step boundaries and never changes the solution.
#include <functional>
#include <string>
#include <vector>

#include "rkfem/analysis/impact.hpp"
#include "rkfem/analysis/spall.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/run/thread_governor.hpp"

namespace rkfem
{
struct RunOptions
{
    std::string out_dir;  ///< "" = no files (tests)
    bool progress = true; ///< progress line on stderr
    std::string deck_path;
    std::vector<std::string> overrides;
    /// Events between steps: called after each accepted step; returns true when it changed the
    /// discretization (the stepper is then started again; the energy ledger continues).
    std::function<bool(Model&, real_t t, std::int64_t step)> events;
    /// Seconds spent before run_simulation on this run (reading the deck, building the model),
    /// reported in summary.json's set-up time.
    real_t setup_seconds = 0.0;
    /// > 0 (with out_dir): a checkpoint every this much simulated time and at the end of the
    /// run, out_dir/checkpoint.h5 (io/checkpoint.hpp), from which `rkfem restart` continues with
    /// the same bits. deck_text is stored in it (the deck as read, with deck_path and overrides).
    real_t checkpoint_interval = 0.0;
    /// Checkpoints kept: checkpoint.h5 the newest, checkpoint.1.h5 the one before, ...
    int checkpoint_keep = 1;
    std::string deck_text;
    /// The deck's folder, absolute: a restart from another working folder resolves the data
    /// files the deck names from it. And the data files' hashes (data_file_hashes).
    std::string deck_dir;
    std::string data_files;
    /// Continue from this checkpoint (restart): the model was built from its deck and has loaded
    /// its state (Model::load_state); the loop, the output cursors, results.h5 and the history
    /// go on from where it was written.
    const StateArchive* resume = nullptr;
    /// Choose the team size between steps from the steps' wall times (run/thread_governor.hpp):
    /// on a busy machine, or with a part too small for its threads, a run falls back to one
    /// thread; off (or environment RKFEM_ADAPTIVE_THREADS=0): every step on the OpenMP default.
    /// Results are the same bits.
    bool adaptive_threads = true;
    ThreadGovernor::Options thread_governor;
};

/// A new run id: 16 hexadecimal digits from the system's random source.
std::string new_run_id();

/// The file of checkpoint k in a run's directory (0: the newest, checkpoint.h5).
std::string checkpoint_path(const std::string& dir, int k = 0);

/// The newest whole checkpoint in a run's directory, for `restart DIR`: checkpoint.new.h5 where
/// a run was stopped while rotating (it is renamed there only once whole, and is newer than
/// checkpoint.h5), else checkpoint.h5, else checkpoint.1.h5; checkpoint.h5 when none exists.
std::string newest_checkpoint(const std::string& dir);

struct RunSummary
{
    std::string status = "completed"; ///< completed | unstable | interrupted (SIGINT / SIGTERM: the state at the step
                                      ///< it arrived in written)
    std::string message;
    std::string run_id;
    std::int64_t steps = 0;
    real_t end_time = 0.0;
    real_t failed_time = -1.0;     ///< unstable runs: the time of the state written as the last frame (-1: none)
    real_t wall_seconds = 0.0;     ///< run_simulation from start to end: stepper start, steps, output
    real_t setup_seconds = 0.0;    ///< RunOptions::setup_seconds plus the stepper's first start
    real_t output_seconds = 0.0;   ///< history rows, field outputs, summary not included
    real_t stepping_seconds = 0.0; ///< wall - output - the stepper's first start
    /// steps after which the discretization changed (conversion, reversion, erosion events that
    /// rebuild tables; carried across a restart from a checkpoint) and the seconds those events
    /// took, the stepper's restart included (part of stepping_seconds; this process's)
    std::int64_t events = 0;
    real_t event_seconds = 0.0;
    /// stepping_seconds per (work item x step): FE elements of element-integrated blocks and
    /// stress points (particles, nodes) of nodal blocks, as they were at each step
    real_t ns_per_element_cycle = 0.0;
    real_t dt_first = 0.0;           ///< the first step [s]
    real_t dt_min = 0.0;             ///< the smallest step taken [s]
    real_t max_plastic_strain = 0.0; ///< largest element-average effective plastic strain at the end
    Energies energy;
    real_t max_balance_error = 0.0;
    int n_outputs = 0;
    int thread_switches = 0;              ///< team-size changes the thread governor made
    std::int64_t steps_on_one_thread = 0; ///< steps run on one thread while more were allowed
    bool has_impact = false;              ///< the deck has an impact key
    ImpactMeasures impact;                ///< at the end
    bool has_spall = false;               ///< the deck has a spall key
    SpallMeasures spall;                  ///< at the end
    std::vector<std::string> history_columns;
    std::vector<real_t> history; ///< rows x columns, row-major
};

/// Observer called after each accepted step (and once after initialization with dt = 0).
using StepObserver = std::function<void(const Model&, real_t t, real_t dt, std::int64_t step)>;

/// Runs the model to deck.time.end. Never throws on instability: the summary says where and when.
RunSummary run_simulation(Model& model, const RunOptions& options, const StepObserver& observer = {});
} // namespace rkfem
