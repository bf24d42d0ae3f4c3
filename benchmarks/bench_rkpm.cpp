// RKPM kernels.
//   build/release/bin/bench_rkpm --benchmark_counters_tabular=true
// BM_RkShapeFunctions: Psi and direct gradients at every particle of a lattice, us per particle.
// BM_NodalInternalForce: one internal-force pass of a total-Lagrangian nodal block (gather F and
// Fdot, elastic update, V0 P, plus MSCNI stabilization when on) and the transpose assembly, in
// ns per particle-step. Arguments: {particles (approximate cube), 100 a/h, stabilization 0/1,
// threads, shared stencils 0/1}. `entries` is the gradient stencil per stress point; on the
// lattice the points share 27 (a/h 1.25) or 125 (a/h 1.51) stencils (integration/
// stencil_table.hpp), and with the last argument 0 each reads its own, as on a jittered cloud.
// BM_NeighbourListBuild: cell-list neighbour lists with a skin (radius 1.51 h + skin 0.3 h) for a
// lattice, ns per particle per build; BM_NeighbourListCheck: the per-step "moved more than
// skin / 2?" test that decides whether to rebuild, ns per particle.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdlib>
#include <omp.h>

#include "rkfem/approximation/rk/rk_shape.hpp"
#include "rkfem/discretization/cell_list.hpp"
#include "rkfem/discretization/generators.hpp"
#include "rkfem/model/nodal_block_build.hpp"
#include "rkfem/operators/nodal_block.hpp"
#include "rkfem/operators/nodal_force.hpp"

using namespace rkfem;

namespace
{
HexMesh lattice(index_t n_particles)
{
    const int n = std::max(2, static_cast<int>(std::lround(std::cbrt(static_cast<double>(n_particles)))) - 1);
    return generate_box(Vec3::Zero(), Vec3::Constant(n * 1e-3), {n, n, n});
}

void BM_RkShapeFunctions(benchmark::State& state)
{
    const HexMesh mesh = lattice(state.range(0));
    const real_t c = state.range(1) / 100.0;
    const RkShapeFunctions rk = rk_on_mesh(mesh, {1, KernelType::CubicBSpline, SupportShape::Box, c});
    RkSample s;
    std::size_t nbrs = 0;
    for (auto _ : state)
    {
        nbrs = 0;
        for (index_t i = 0; i < mesh.n_nodes(); ++i)
        {
            rk.evaluate(mesh.node(i), true, s);
            nbrs += s.nodes.size();
            benchmark::DoNotOptimize(s.grad.data());
        }
    }
    state.counters["us_per_particle"] =
        benchmark::Counter(static_cast<double>(mesh.n_nodes()) * 1e-6,
                           benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
    state.counters["neighbours"] = static_cast<double>(nbrs) / mesh.n_nodes();
}

void BM_NodalInternalForce(benchmark::State& state)
{
    const HexMesh mesh = lattice(state.range(0));
    PartSpec ps;
    ps.formulation = Formulation::Rkpm;
    ps.material.model = "elastic";
    ps.material.rho = 2400.0;
    ps.material.E = 30e9;
    ps.material.nu = 0.2;
    ps.rk.normalized_support = state.range(1) / 100.0;
    ps.nodal.stabilization = state.range(2) ? "mscni" : "none";
    NodalBlock blk = build_nodal_block(ps, mesh, 0);
    // argument 5 = 0: each point streams its own stencil from the operator, as on a jittered
    // cloud (the lattice's shared stencils off)
    if (state.range(4) == 0)
    {
        {
            NodalBlockOptions o = blk.options();
            o.share_stencils = false;
            blk.set_options(o);
        }
        blk.initialize();
    }
    // RKFEM_BENCH_PLAIN_STORES=1: the stress stored plainly, for an A/B of the streamed stores
    {
        NodalBlockOptions o = blk.options();
        o.stream_stress = std::getenv("RKFEM_BENCH_PLAIN_STORES") == nullptr;
        blk.set_options(o);
    }
    NodeSet nodes;
    nodes.resize(mesh.n_nodes());
    for (std::size_t i = 0; i < mesh.x.size(); ++i)
    {
        nodes.x0[i] = nodes.x[i] = mesh.x[i];
        nodes.v[i] = 1e-3 * std::sin(1e3 * mesh.x[i] + i % 3);
        nodes.u[i] = 1e-9 * std::cos(1e3 * mesh.x[i] + i % 3);
    }
    const int saved = omp_get_max_threads();
    omp_set_num_threads(static_cast<int>(state.range(3)));
    for (auto _ : state)
    {
        benchmark::DoNotOptimize(nodal_internal_force(blk, nodes, 1e-8));
        assemble_nodal_forces(blk, nodes);
        benchmark::ClobberMemory();
    }
    omp_set_num_threads(saved);
    state.counters["ns_per_particle_step"] =
        benchmark::Counter(static_cast<double>(blk.n_points()) * 1e-9,
                           benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
    state.counters["entries"] =
        static_cast<double>(blk.points.offsets.back()) / blk.n_points(); // held in the table or the operator
    state.counters["particles"] = static_cast<double>(blk.n_points());
}
} // namespace

BENCHMARK(BM_RkShapeFunctions)->Args({10000, 151})->Args({10000, 125})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_NodalInternalForce)
    ->ArgsProduct({{10000, 30000, 100000, 300000}, {125, 151}, {0, 1}, {1, 2}, {1}})
    ->ArgsProduct({{10000, 300000}, {125, 151}, {0}, {1, 2}, {0}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

namespace
{
void BM_NeighbourListBuild(benchmark::State& state)
{
    const HexMesh mesh = lattice(state.range(0));
    for (auto _ : state)
    {
        NeighbourList nl(1.51e-3, 0.3e-3);
        nl.update(mesh.x);
        benchmark::DoNotOptimize(nl.ids().data());
        state.counters["per_particle"] = static_cast<double>(nl.offsets().back()) / mesh.n_nodes();
    }
    state.counters["ns_per_particle"] =
        benchmark::Counter(static_cast<double>(mesh.n_nodes()) * 1e-9,
                           benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

void BM_NeighbourListCheck(benchmark::State& state)
{
    const HexMesh mesh = lattice(state.range(0));
    NeighbourList nl(1.51e-3, 0.3e-3);
    nl.update(mesh.x);
    std::vector<real_t> x = mesh.x;
    for (auto& c : x)
        c += 1e-6; // moved, but well within the skin: no rebuild
    for (auto _ : state)
        benchmark::DoNotOptimize(nl.update(x));
    state.counters["ns_per_particle"] =
        benchmark::Counter(static_cast<double>(mesh.n_nodes()) * 1e-9,
                           benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
} // namespace

BENCHMARK(BM_NeighbourListBuild)->Arg(100000)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_NeighbourListCheck)->Arg(100000)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_MAIN();
