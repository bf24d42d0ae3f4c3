// Whole explicit steps through each stepper on the same model, in ns per element-step:
// the hand-written central difference, arkode-cd with rkfem's state vector (shared copies, the
// state lent to the model), and arkode-cd with Debian's own serial vector and its (unoptimised)
// operations. Steady state: three steps run before the timed ones.
//   build/release/bin/bench_steppers --benchmark_counters_tabular=true
// Arguments: {elements (approximate cube), stepper 0 hand / 1 arkode-cd / 2 arkode-cd Debian ops,
// OpenMP threads}.
#include <benchmark/benchmark.h>
#include <cmath>
#include <omp.h>
#include <string>

#include "rkfem/config/deck.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/time/arkode_stepper.hpp"
#include "rkfem/time/central_difference.hpp"

using namespace rkfem;

namespace
{
void BM_Step(benchmark::State& state)
{
    const int saved = omp_get_max_threads();
    omp_set_num_threads(static_cast<int>(state.range(2)));
    const int n = std::max(1, static_cast<int>(std::lround(std::cbrt(static_cast<double>(state.range(0))))));
    const std::string deck = "title: bench\ntime: {end: 1 s}\nparts:\n  b:\n"
                             "    generator: {type: box, size: [" +
                             std::to_string(n) + " mm, " + std::to_string(n) + " mm, " + std::to_string(n) +
                             " mm], divisions: [" + std::to_string(n) + ", " + std::to_string(n) + ", " +
                             std::to_string(n) +
                             "]}\n"
                             "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n"
                             "    initial_velocity: [0, 0, 1 m/s]\n"
                             "node_sets:\n  base: {select: {type: named, name: bottom}}\n"
                             "boundary_conditions:\n  - {node_set: base, fixed: [x, y, z]}\n";
    Model m = Model::build(parse_deck(deck, "bench.yaml"));
    TimeSpec ts = m.deck().time;
    std::unique_ptr<TimeStepper> st;
    if (state.range(1) == 0)
        st = std::make_unique<CentralDifference>();
    else
        st = std::make_unique<ArkodeStepper>(ArkodeStepper::Mode::CentralDifference, ts, state.range(1) == 1);
    StepReport r = st->initialize(m, 0.0);
    real_t t = 0.0;
    std::int64_t k = 0;
    // steady state: the first steps allocate (ARKODE's vectors get their storage on first write)
    for (int w = 0; w < 3; ++w)
    {
        r = st->step(m, t, next_time_step(ts, t, r.dt_stable), ++k);
        t = r.t;
    }
    for (auto _ : state)
    {
        const real_t dt = next_time_step(ts, t, r.dt_stable);
        r = st->step(m, t, dt, ++k);
        t = r.t;
    }
    state.counters["ns_per_element_step"] =
        benchmark::Counter(static_cast<double>(m.n_elements()) * 1e-9,
                           benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
    state.SetLabel(st->name());
    omp_set_num_threads(saved);
}
} // namespace

BENCHMARK(BM_Step)
    ->ArgNames({"elements", "stepper", "threads"})
    ->ArgsProduct({{1000, 3000, 10000, 100000, 1000000}, {0, 1, 2}, {1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_MAIN();
