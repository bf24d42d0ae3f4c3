// Internal force + hourglass + elastic update + assembly for hex blocks, in ns per element-cycle,
// and the nodal update (kick-drift-kick) in ns per node.
//   build/release/bin/bench_internal_force --benchmark_counters_tabular=true
// Arguments: {elements (approximate cube), threads, kind} with kind 0 none, 1 viscous,
// 2 stiffness, 3 fully integrated.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdlib>
#include <omp.h>

#include "rkfem/config/deck.hpp"
#include "rkfem/discretization/generators.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/operators/hex_block.hpp"
#include "rkfem/time/central_difference.hpp"

using namespace rkfem;

namespace
{
struct Setup
{
    NodeSet nodes;
    HexBlock blk;
};

Setup make_setup(index_t n_elements, int kind)
{
    const int n = std::max(1, static_cast<int>(std::lround(std::cbrt(static_cast<double>(n_elements)))));
    const HexMesh mesh = generate_box(Vec3::Zero(), Vec3::Constant(n * 1e-3), {n, n, n});
    Setup s;
    s.nodes.resize(mesh.n_nodes());
    for (std::size_t i = 0; i < mesh.x.size(); ++i)
    {
        s.nodes.x0[i] = s.nodes.x[i] = mesh.x[i];
        s.nodes.v[i] = 1e-3 * std::sin(1e3 * mesh.x[i] + i % 3); // smooth, non-trivial velocity
    }
    s.blk.formulation = kind == 3 ? Formulation::Fem2x2x2 : Formulation::Fem1pt;
    s.blk.hourglass = {kind == 1   ? HourglassType::Viscous
                       : kind == 2 ? HourglassType::Stiffness
                                   : HourglassType::None,
                       0.1};
    s.blk.material = ElasticParams::from_E_nu(7850, 200e9, 0.3);
    s.blk.conn = mesh.conn;
    s.blk.node_begin = 0;
    s.blk.node_end = mesh.n_nodes();
    s.blk.initialize(s.nodes);
    // RKFEM_BENCH_PLAIN_STORES=1: the stress stored plainly, for an A/B of the streamed stores
    s.blk.stream_stress = std::getenv("RKFEM_BENCH_PLAIN_STORES") == nullptr;
    add_lumped_mass(s.blk, s.nodes);
    return s;
}

void BM_HexInternalForce(benchmark::State& state)
{
    const int saved = omp_get_max_threads();
    omp_set_num_threads(static_cast<int>(state.range(1)));
    Setup s = make_setup(static_cast<index_t>(state.range(0)), static_cast<int>(state.range(2)));
    for (auto _ : state)
    {
        hex_internal_force(s.blk, s.nodes, 1e-8);
        assemble_block_forces(s.blk, s.nodes);
        s.blk.commit();
        benchmark::DoNotOptimize(s.nodes.f_int.data());
    }
    const double ne = s.blk.n_elements();
    state.counters["elements"] = ne;
    state.counters["ns_per_element_cycle"] =
        benchmark::Counter(ne * state.iterations() * 1e-9, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
    omp_set_num_threads(saved);
}

void BM_NodalUpdate(benchmark::State& state)
{
    // The per-node phases of a central-difference step, as the stepper runs them: kick, velocity
    // conditions, drift, coordinates, accelerations, kick. Forces are left as they are.
    const int saved = omp_get_max_threads();
    omp_set_num_threads(static_cast<int>(state.range(1)));
    const int n = std::max(1, static_cast<int>(std::lround(std::cbrt(static_cast<double>(state.range(0))))));
    const std::string deck =
        "time: {end: 1 s}\nparts:\n  b:\n    generator: {type: box, size: [1 m, 1 m, 1 m], divisions: [" +
        std::to_string(n) + ", " + std::to_string(n) + ", " + std::to_string(n) +
        "]}\n    material: {model: elastic, rho: 7850, E: 200e9, nu: 0.3}\n"
        "node_sets:\n  bottom: {select: {type: named, name: bottom}}\n"
        "boundary_conditions:\n  - {node_set: bottom, fixed: all}\n";
    Model m = Model::build(parse_deck(deck, "bench.yaml"));
    const real_t dt = 1e-8;
    for (auto _ : state)
    {
        central_difference_kick(m.nodes, 0.5 * dt);
        m.impose_velocity(0.0, dt, true);
        central_difference_drift(m.nodes, dt);
        m.update_coordinates();
        m.accelerations();
        central_difference_kick(m.nodes, 0.5 * dt);
        benchmark::DoNotOptimize(m.nodes.v.data());
    }
    const double nn = m.nodes.size();
    state.counters["nodes"] = nn;
    state.counters["ns_per_node"] =
        benchmark::Counter(nn * state.iterations() * 1e-9, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
    omp_set_num_threads(saved);
}
} // namespace

BENCHMARK(BM_HexInternalForce)
    ->ArgNames({"elements", "threads", "kind"})
    ->ArgsProduct({{10000, 1000000}, {1, 2}, {0, 1, 2, 3}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_NodalUpdate)
    ->ArgNames({"elements", "threads"})
    ->ArgsProduct({{10000, 1000000}, {1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

BENCHMARK_MAIN();
