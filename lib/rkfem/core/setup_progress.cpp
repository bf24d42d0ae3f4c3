#include "rkfem/core/setup_progress.hpp"

#include <atomic>
#include <chrono>
#include <cstdio>
#include <mutex>
#include <omp.h>

namespace rkfem::setup_progress
{
namespace
{
using Clock = std::chrono::steady_clock;

struct State
{
    std::function<void(const std::string&, bool)> sink;
    double delay = 2.0, interval = 0.5;
    bool started = false;
    Clock::time_point start, last;
    std::string name;
    std::int64_t total = 0;
    std::atomic<std::int64_t> count{0};
    bool shown = false;  ///< a line of this phase went out
    bool active = false; ///< a phase is open: counts outside one (a builder called without it) say nothing
    std::mutex print;
};

State& state()
{
    static State s;
    return s;
}

double seconds(Clock::time_point a, Clock::time_point b)
{
    return std::chrono::duration<double>(b - a).count();
}

void report(State& s, Clock::time_point now, bool last)
{
    char line[256];
    const std::int64_t c = s.count.load(std::memory_order_relaxed);
    if (s.total > 0)
        std::snprintf(line, sizeof line, "set-up: %s %5.1f%% (%lld of %lld), %.1f s", s.name.c_str(),
                      100.0 * static_cast<double>(c) / static_cast<double>(s.total), static_cast<long long>(c),
                      static_cast<long long>(s.total), seconds(s.start, now));
    else
        std::snprintf(line, sizeof line, "set-up: %s, %.1f s", s.name.c_str(), seconds(s.start, now));
    s.sink(line, last);
    s.last = now;
    s.shown = true;
}
} // namespace

void install(std::function<void(const std::string&, bool)> sink, double delay, double interval)
{
    State& s = state();
    s.sink = std::move(sink);
    s.delay = delay;
    s.interval = interval;
    s.started = false;
}

void phase(const std::string& name, std::int64_t total)
{
    State& s = state();
    s.name = name;
    s.total = total;
    s.count.store(0, std::memory_order_relaxed);
    s.shown = false;
    s.active = true;
    if (!s.sink)
        return;
    const Clock::time_point now = Clock::now();
    if (!s.started)
    {
        s.started = true;
        s.start = now;
        s.last = now - std::chrono::hours(1);
    }
    if (seconds(s.start, now) >= s.delay)
        report(s, now, false);
}

void advance(std::int64_t n)
{
    State& s = state();
    const std::int64_t c = s.count.fetch_add(n, std::memory_order_relaxed) + n;
    // the clock is read by the master thread only, every 16th count
    if (!s.sink || !s.active || omp_get_thread_num() != 0 || (c & 15) != 0)
        return;
    const Clock::time_point now = Clock::now();
    if (seconds(s.start, now) < s.delay || seconds(s.last, now) < s.interval)
        return;
    const std::lock_guard<std::mutex> lock(s.print);
    report(s, now, false);
}

void done()
{
    State& s = state();
    if (s.sink && s.shown)
        report(s, Clock::now(), true);
    s.shown = false;
    s.active = false;
}
} // namespace rkfem::setup_progress
