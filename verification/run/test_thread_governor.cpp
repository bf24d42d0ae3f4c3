// The thread governor (run/thread_governor.hpp) chooses the team size between steps from the
// steps' wall times and preemptions. Its logic is a pure function of the times it is given, so
// these tests feed it the times of a machine and check what it chooses: an idle machine where 2
// threads win is probed rarely, a small part that 2 threads slow and a busy machine fall back to
// one thread, a machine that frees up gets its threads back, one that turns busy is probed soon.
// A run whose team size the governor changes every few steps gives the bits of a run on one
// thread (results do not depend on the team size).
#include <gtest/gtest.h>

#include <omp.h>

#include "../support.hpp"
#include "rkfem/config/deck.hpp"
#include "rkfem/run/simulation.hpp"
#include "rkfem/run/thread_governor.hpp"

using namespace rkfem;

namespace
{
/// A machine: step time and preemptions per step on 1 and on 2 threads.
struct Machine
{
    double t1, t2, p1, p2;
};

/// Runs the governor over n steps of the machine; returns the steps on one thread.
std::int64_t drive(ThreadGovernor& g, const Machine& m, int n)
{
    std::int64_t on_one = 0;
    for (int k = 0; k < n; ++k)
    {
        const bool one = g.threads() == 1;
        on_one += one;
        g.record(one ? m.t1 : m.t2, one ? m.p1 : m.p2);
    }
    return on_one;
}
} // namespace

TEST(ThreadGovernor, AnIdleMachineWhereTwoThreadsWinIsProbedRarely)
{
    ThreadGovernor g(2);
    // 2 threads take 0.6 of a step on 1; half a preemption per step (the column on an idle machine)
    // a probe of 8 steps on one thread after 16 steps, which loses by more than a quarter, and
    // the next 4096 steps later: 2 probes by step 5000, none switches
    EXPECT_EQ(drive(g, {1.0, 0.6, 0.2, 0.5}, 5000), 2 * 8);
    EXPECT_EQ(g.switches(), 0);
    EXPECT_EQ(g.threads(), 2);
    // 2 threads win by a little (a part of a few thousand points): probes after 16, 32, ...,
    // 2048 steps (the interval doubles while 2 stay faster), 8 by step 5000
    ThreadGovernor c(2);
    EXPECT_EQ(drive(c, {1.0, 0.9, 0.2, 0.5}, 5000), 8 * 8);
    EXPECT_EQ(c.switches(), 0);
    // later probes come every 4096 steps: 8 steps of 4104 on one thread
    ThreadGovernor h(2);
    drive(h, {1.0, 0.6, 0.2, 0.5}, 20000);
    const std::int64_t before = h.steps_on_one_thread();
    drive(h, {1.0, 0.6, 0.2, 0.5}, 4104);
    EXPECT_EQ(h.steps_on_one_thread() - before, 8);
}

TEST(ThreadGovernor, ASmallPartThatTwoThreadsSlowRunsOnOneThread)
{
    ThreadGovernor g(2);
    // an idle machine, but a step on 2 threads takes 1.5 of one on 1 (fork-joins of tiny loops:
    // the P3 cantilever as fem-1pt)
    const std::int64_t on_one = drive(g, {1.0, 1.5, 0.2, 0.5}, 5000);
    ASSERT_EQ(g.switches(), 1);
    EXPECT_EQ(g.switches(), 1);
    EXPECT_EQ(g.threads(), 1);
    // 16 steps on 2 threads, the first probe wins, then probes of 8 on 2 after 16, ..., 2048
    EXPECT_EQ(on_one, 5000 - 16 - 8 * 8);
}

TEST(ThreadGovernor, ABusyMachineFallsBackToOneThreadAndProbesRarely)
{
    ThreadGovernor g(2);
    // another process holds a core: 2 threads take 1.9 steps of 1 thread and are preempted often
    const std::int64_t on_one = drive(g, {1.0, 1.9, 1.0, 9.0}, 5000);
    std::printf("busy machine: %lld of 5000 steps on one thread, %d switch(es)\n", static_cast<long long>(on_one),
                g.switches());
    EXPECT_EQ(g.switches(), 1);
    EXPECT_EQ(g.threads(), 1);
    // 16 steps on 2 threads before the first probe (which wins), then from one thread a probe
    // of 8 steps on 2 after 16, 32, ..., 2048 steps (the interval doubles while 1 stays faster):
    // 8 probes by step 5000
    EXPECT_EQ(on_one, 5000 - 16 - 8 * 8);
}

TEST(ThreadGovernor, AMachineThatFreesUpGetsItsThreadsBack)
{
    ThreadGovernor g(2);
    drive(g, {1.0, 1.9, 1.0, 9.0}, 200);
    ASSERT_EQ(g.threads(), 1);
    drive(g, {1.0, 0.6, 0.2, 0.5}, 200); // the other process ended
    EXPECT_EQ(g.threads(), 2);
    EXPECT_EQ(g.switches(), 2);
    // a small difference (within the margin) does not make it switch back and forth
    ThreadGovernor h(2);
    drive(h, {1.0, 0.98, 0.0, 3.0}, 2000);
    EXPECT_EQ(h.switches(), 0);
}

TEST(ThreadGovernor, AMachineThatTurnsBusyIsProbedSoon)
{
    ThreadGovernor g(2);
    drive(g, {1.0, 0.6, 0.2, 0.5}, 20000); // idle: the interval has grown to 4096
    ASSERT_EQ(g.threads(), 2);
    ASSERT_EQ(g.switches(), 0);
    // another process takes a core: the window's preemptions cross 2 per step after 2 steps, the
    // interval is reset to 16, and once 8 busy steps have filled the window a probe of 8 steps
    // on one thread follows: one switch within 2 + 8 + 8 steps
    drive(g, {1.0, 1.9, 1.0, 9.0}, 17);
    EXPECT_EQ(g.switches(), 0);
    drive(g, {1.0, 1.9, 1.0, 9.0}, 1);
    EXPECT_EQ(g.switches(), 1);
    EXPECT_EQ(g.threads(), 1);
    // preemptions that hover at the threshold (2 threads still faster) reset the interval once
    ThreadGovernor h(2);
    drive(h, {1.0, 0.6, 0.2, 2.1}, 20000);
    EXPECT_EQ(h.switches(), 0);
    const std::int64_t before = h.steps_on_one_thread();
    drive(h, {1.0, 0.6, 0.2, 2.1}, 4104);
    EXPECT_EQ(h.steps_on_one_thread() - before, 8);
}

TEST(ThreadGovernor, SwitchingTheTeamEveryFewStepsKeepsTheBits)
{
    // 2 threads whatever OMP_NUM_THREADS says (ctest sets 1): the team changes between 2 and 1
    // the FSP into the concrete panel at smoke size: contact, erosion, K&C, ARKODE
    const std::vector<std::string> set = {"parts.panel.generator.element_size=10 mm",
                                          "parts.fsp.generator.element_size=5 mm", "time.end=15 us"};
    auto run = [&](bool adapt, int threads, ThreadGovernor::Options o)
    {
        const int saved = omp_get_max_threads();
        omp_set_num_threads(threads);
        Model m = Model::build(read_deck(std::string(RKFEM_SOURCE_DIR) + "/studies/decks/fsp_impact.yaml", set));
        RunOptions opt;
        opt.progress = false;
        opt.adaptive_threads = adapt;
        opt.thread_governor = o;
        const RunSummary s = run_simulation(m, opt);
        EXPECT_EQ(s.status, "completed") << s.message;
        EXPECT_EQ(omp_get_max_threads(), threads); // the team size is the caller's again
        omp_set_num_threads(saved);
        return std::make_pair(m.nodes.u, s);
    };
    // every probe wins (margin -1e9: a probe loses only if a billion times slower; at -100 a probe
    // step descheduled for a time slice on a machine with more busy threads than cores lost, and
    // the run made 9 changes, 2026-12-06) and probes come at once (no busy spell resets a
    // window): the team changes every 3 steps
    ThreadGovernor::Options flip;
    flip.window = 2;
    flip.probe_interval = 1;
    flip.margin = -1e9;
    flip.contention = 1e9;
    const auto [u_flip, s_flip] = run(true, 2, flip);
    const auto [u_one, s_one] = run(false, 1, {});
    std::printf("switching run: %d team changes, %lld of %lld steps on one thread\n", s_flip.thread_switches,
                static_cast<long long>(s_flip.steps_on_one_thread), static_cast<long long>(s_flip.steps));
    EXPECT_GT(s_flip.thread_switches, 10);
    EXPECT_GT(s_flip.steps_on_one_thread, 0);
    EXPECT_LT(s_flip.steps_on_one_thread, s_flip.steps);
    EXPECT_TRUE(u_flip == u_one);
}
