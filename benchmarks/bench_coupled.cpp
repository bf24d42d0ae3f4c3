// Whole central-difference steps of a uniaxial-strain column (steel, lateral rollers, one end
// driven) that is all fem-nodal, all rkpm, or half and half in one coupled part (mixed
// transition), on the same mesh: ns per node-step of each, so the share the transition layer
// adds shows against the mean of the two halves. kind: 0 all FE (fem-nodal), 1 all RK,
// 2 coupled (mixed), 3 all FE fem-1pt (for scale).
#include <benchmark/benchmark.h>

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
} // namespace

BENCHMARK(BM_CoupledColumnStep)
    ->ArgNames({"length_mm", "threads", "kind"})
    ->ArgsProduct({{200, 800}, {1}, {0, 1, 2, 3}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

BENCHMARK_MAIN();
