#pragma once
/// @file thread_governor.hpp
/// Chooses the OpenMP team size of a run between steps from the steps' own wall times, so that a
/// run on a busy machine is not slower than on one thread. On an idle machine a big part's step on
/// more threads takes less time than on one; while another process holds a core, the static loops
/// wait at every barrier for the thread that lost its core, and the team can take longer than one
/// thread (measurements: docs/performance.md).
///
/// The run steps in windows of `window` steps on one team size. Every `probe_interval` steps a
/// window on the other size follows (one thread while on the largest, the largest while on one),
/// and the size whose median step time is lower is kept (the other must win by `margin` to take
/// over). A probe that confirms the current size doubles the interval (up to `max_interval`), a
/// switch resets it; on the largest size, a probe on one thread whose median step the current
/// size's beats by `decisive` (a quarter) or more sets it to `max_interval` at once. On an idle
/// machine and a big part that costs 8 steps on one thread after 16 steps and then every 4,096
/// (0.2 % of the steps, each slower than on the team); a small part, whose steps are fork-joins of
/// tiny loops, may find one thread faster (the cache lines the loops share take long to move from
/// one core to another). When the machine turns busy (a window of steps preempted `contention`
/// times per step or more on average, involuntary context switches of the process: on an idle
/// machine well below it, while another process holds a core well above it;
/// measurements: docs/performance.md) the interval is reset once, so that a probe follows as soon
/// as a window of busy steps has been timed; the spell ends when the average falls below half
/// that. Results do not depend on the team size (every reduction sums fixed chunks in order, see
/// core/parallel.hpp), so a switch changes no bits. The time source is the caller's: the logic is
/// a pure function of the step times it is given.
#include <algorithm>
#include <cstdint>
#include <vector>

namespace rkfem
{
class ThreadGovernor
{
  public:
    struct Options
    {
        int window = 8;                   ///< steps per measurement window
        std::int64_t probe_interval = 16; ///< steps between probes at first
        std::int64_t max_interval = 4096; ///< the longest interval between probes
        double margin = 0.05;             ///< the other size must be this much faster to take over
        double decisive = 0.25;           ///< one thread this much slower: probe it again after max_interval
        double contention = 2.0;          ///< preemptions per step that make the largest size probe soon
    };

    /// max_threads: the largest team size (OMP_NUM_THREADS or the cores); 1: the governor idles.
    explicit ThreadGovernor(int max_threads) : ThreadGovernor(max_threads, Options{}) {}
    ThreadGovernor(int max_threads, Options opt) : max_(std::max(1, max_threads)), current_(max_), opt_(opt)
    {
        interval_ = opt_.probe_interval;
    }

    bool active() const { return max_ > 1; }
    /// The team size for the next step.
    int threads() const { return probing_ ? other() : current_; }
    /// The wall time of the step just run on threads(), and how often the process was preempted
    /// during it (involuntary context switches).
    void record(double seconds, double preemptions)
    {
        if (!active())
            return;
        ++steps_;
        if (threads() == 1)
            ++steps_on_one_;
        std::vector<double>& w = probing_ ? probe_times_ : current_times_;
        w.push_back(seconds);
        if (!probing_)
        {
            preempted_.push_back(preemptions);
            if (static_cast<int>(w.size()) > opt_.window)
            {
                w.erase(w.begin()); // the latest window on the current size
                preempted_.erase(preempted_.begin());
            }
            double per_step = 0.0;
            for (double p : preempted_)
                per_step += p / static_cast<double>(preempted_.size());
            // the machine turned busy on the largest size: probe one thread soon (once per busy
            // spell: it ends below half the threshold), against a window of busy steps only
            if (current_ == max_ && !busy_ && per_step >= opt_.contention)
            {
                busy_ = true;
                interval_ = opt_.probe_interval;
                current_times_.clear();
            }
            else if (current_ != max_ || per_step < 0.5 * opt_.contention)
                busy_ = false;
            if (++since_probe_ >= interval_ && static_cast<int>(w.size()) == opt_.window)
            {
                probing_ = true;
                probe_times_.clear();
            }
            return;
        }
        if (static_cast<int>(w.size()) < opt_.window)
            return;
        // the probe's window is complete: keep the faster size
        probing_ = false;
        since_probe_ = 0;
        if (median(probe_times_) < (1.0 - opt_.margin) * median(current_times_))
        {
            current_ = other();
            current_times_ = probe_times_;
            preempted_.clear();
            interval_ = opt_.probe_interval;
            ++switches_;
        }
        else if (current_ == max_ && median(current_times_) < (1.0 - opt_.decisive) * median(probe_times_))
            interval_ = opt_.max_interval; // one thread lost by far: a big part, an idle machine
        else
            interval_ = std::min(2 * interval_, opt_.max_interval);
    }
    int switches() const { return switches_; }
    std::int64_t steps_on_one_thread() const { return steps_on_one_; }
    std::int64_t steps() const { return steps_; }

  private:
    int other() const { return current_ == max_ ? 1 : max_; }
    static double median(std::vector<double> v)
    {
        std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
        return v[v.size() / 2];
    }

    int max_, current_;
    Options opt_;
    std::int64_t interval_ = 0, since_probe_ = 0, steps_ = 0, steps_on_one_ = 0;
    bool probing_ = false, busy_ = false;
    int switches_ = 0;
    std::vector<double> current_times_, probe_times_, preempted_;
};
} // namespace rkfem
