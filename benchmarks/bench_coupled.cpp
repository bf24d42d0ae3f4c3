// Whole central-difference steps of a uniaxial-strain column (steel, lateral rollers, one end
// driven) that is all fem-nodal, all rkpm, or half and half in one coupled part (mixed
// transition), on the same mesh: ns per node-step of each, so the share the transition layer
// adds shows against the mean of the two halves. kind: 0 all FE (fem-nodal), 1 all RK,
// 2 coupled (mixed), 3 all FE fem-1pt (for scale). BM_ConversionEvent: in the coupled column, a
// slab of FE elements at the interface turned RK and back (two events, the stepper restarted
// after each), ns per event beside the step of the same model, and their ratio (issue #49's goal:
// an event at most the time of 20 steps of the converted region).
#include <benchmark/benchmark.h>

#include <chrono>
#include <omp.h>
#include <string>

#include "rkfem/config/deck.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/time/central_difference.hpp"

using namespace rkfem;

namespace
{
std::string column_deck(int n_side, int n_len, int kind)
{
    const std::string form = kind == 1 ? "rkpm" : kind == 3 ? "fem-1pt" : "fem-nodal";
    std::string d = "time: {end: 1 s}\nparts:\n  c:\n    generator: {type: box, size: [" + std::to_string(n_side) +
                    " mm, " + std::to_string(n_side) + " mm, " + std::to_string(n_len) +
                    " mm], element_size: 1 mm}\n"
                    "    material: {model: elastic, rho: 7850, E: 200e9, nu: 0.3}\n    formulation: " +
                    form + "\n";
    if (kind == 2)
        d += "    regions:\n      - {select: {type: box, min: [-1 mm, -1 mm, " + std::to_string(n_len / 2) +
             " mm], max: [1 m, 1 m, 1 m]}}\n";
    d += "node_sets:\n  all: {select: {type: named, name: all}}\n  end: {select: {type: named, name: bottom}}\n"
         "boundary_conditions:\n  - {node_set: all, fixed: [x, y]}\n  - {node_set: end, velocity: {z: 10 m/s}}\n";
    return d;
}

void BM_CoupledColumnStep(benchmark::State& state)
{
    const int saved = omp_get_max_threads();
    omp_set_num_threads(static_cast<int>(state.range(1)));
    const int kind = static_cast<int>(state.range(2));
    Model m = Model::build(parse_deck(column_deck(8, static_cast<int>(state.range(0)), kind), "bench.yaml"));
    CentralDifference cd;
    StepReport r = cd.initialize(m, 0.0);
    const real_t dt = 0.5 * r.dt_stable;
    real_t t = 0.0;
    std::int64_t k = 0;
    for (auto _ : state)
    {
        r = cd.step(m, t, dt, ++k);
        t = r.t;
        benchmark::DoNotOptimize(m.nodes.u.data());
    }
    const double nn = m.nodes.size();
    state.counters["nodes"] = nn;
    state.counters["ns_per_node_step"] =
        benchmark::Counter(nn * state.iterations() * 1e-9, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
    omp_set_num_threads(saved);
}
void BM_ConversionEvent(benchmark::State& state)
{
    const int saved = omp_get_max_threads();
    omp_set_num_threads(static_cast<int>(state.range(1)));
    const int length = static_cast<int>(state.range(0)), slab = static_cast<int>(state.range(2));
    Model m = Model::build(parse_deck(column_deck(8, length, 2), "bench.yaml"));
    CentralDifference cd;
    StepReport r = cd.initialize(m, 0.0);
    const real_t dt = 0.5 * r.dt_stable;
    real_t t = 0.0;
    std::int64_t k = 0;
    // the step's own cost, for the ratio
    const auto s0 = std::chrono::steady_clock::now();
    const int steps = 20;
    for (int i = 0; i < steps; ++i)
        t = cd.step(m, t, dt, ++k).t;
    const double step_ns =
        std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - s0).count() / steps;
    // the FE slab just below the RK half (element centroids, 1 mm elements)
    const HexBlock& blk = m.meshes[0];
    std::vector<char> flags(static_cast<std::size_t>(blk.n_elements()), 0);
    index_t flagged = 0;
    for (index_t e = 0; e < blk.n_elements(); ++e)
    {
        real_t z = 0.0;
        for (int a = 0; a < 8; ++a)
            z += m.nodes.x0[3 * static_cast<std::size_t>(blk.conn[8 * static_cast<std::size_t>(e) + a]) + 2] / 8.0;
        const real_t cut = 0.5 * length * 1e-3;
        flags[e] = z < cut && z > cut - slab * 1e-3;
        flagged += flags[e];
    }
    for (auto _ : state)
    {
        m.convert_elements(0, flags);
        m.restart_after_event(cd, t, dt);
        m.revert_elements(0, flags);
        m.restart_after_event(cd, t, dt);
        benchmark::DoNotOptimize(m.nodes.a.data());
    }
    state.counters["elements_per_event"] = static_cast<double>(flagged);
    state.counters["ns_per_event"] =
        benchmark::Counter(2.0 * state.iterations() * 1e-9, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
    state.counters["step_ns"] = step_ns;
    omp_set_num_threads(saved);
}
} // namespace

BENCHMARK(BM_ConversionEvent)
    ->ArgNames({"length_mm", "threads", "slab"})
    ->ArgsProduct({{200}, {1}, {1, 4}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

BENCHMARK(BM_CoupledColumnStep)
    ->ArgNames({"length_mm", "threads", "kind"})
    ->ArgsProduct({{200, 800}, {1}, {0, 1, 2, 3}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

BENCHMARK_MAIN();
