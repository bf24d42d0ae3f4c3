// Set-up (BM_SeedDeckSetup) and whole steps of the seed's own decks (studies/decks): the P3 cantilever (1 in hexes /
// 1,400 particles, J2 steel) and the P1 cylinder (K&C concrete, 0.5 in), each as fem-1pt and rkpm (its defaults: SCNI +
// NSNI, rk.drop_tolerance 1e-5), one arkode-cd step per iteration with every per-step pass the driver runs (no output).
// Counters: ns per node-step (the comparison: both formulations have the same nodes), over the first 600 steps,
// ns per work item (elements or particles) and the resident bytes the model added per work item (the process's RSS
// before and after Model::build, so set-up scratch that was freed does not count).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <malloc.h>
#include <omp.h>
#include <string>
#include <unistd.h>

#include "rkfem/config/deck.hpp"
#include "rkfem/core/allocator_tuning.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/operators/force_block.hpp"
#include "rkfem/operators/nodal_force.hpp"
#include "rkfem/operators/semi_lagrangian_block.hpp"
#include "rkfem/time/stepper.hpp"

using namespace rkfem;

namespace
{
double resident_bytes()
{
    std::ifstream statm("/proc/self/statm");
    long pages = 0, resident = 0;
    statm >> pages >> resident;
    return static_cast<double>(resident) * static_cast<double>(sysconf(_SC_PAGESIZE));
}

const char* deck_path(int deck)
{
    return deck == 0 ? "p3_cantilever.yaml" : "p1_uuc_cylinder.yaml";
}

void BM_SeedDeckStep(benchmark::State& state)
{
    const int saved = omp_get_max_threads();
    omp_set_num_threads(static_cast<int>(state.range(2)));
    const int deck = static_cast<int>(state.range(0));
    const bool rk = state.range(1) == 1;
    const std::string part = deck == 0 ? "beam" : "cylinder";
    const double rss0 = resident_bytes();
    const double heap0 = static_cast<double>(mallinfo2().uordblks) + static_cast<double>(mallinfo2().hblkhd);
    Model m = Model::build(read_deck(std::string(RKFEM_SOURCE_DIR) + "/studies/decks/" + deck_path(deck),
                                     {"parts." + part + ".formulation=" + (rk ? "rkpm" : "fem-1pt")}));
    const double bytes = resident_bytes() - rss0;
    const double heap = static_cast<double>(mallinfo2().uordblks) + static_cast<double>(mallinfo2().hblkhd) - heap0;
    auto stepper = make_stepper(m.deck().time);
    StepReport r = stepper->initialize(m, 0.0);
    real_t t = 0.0;
    std::int64_t k = 0;
    for (auto _ : state)
    {
        r = stepper->step(m, t, m.deck().time.dt_scale * r.dt_stable, ++k); // the driver's step
        t = r.t;
        benchmark::DoNotOptimize(m.nodes.u.data());
    }
    const double nn = m.nodes.size(), items = m.n_work_items();
    state.counters["nodes"] = nn;
    state.counters["work_items"] = items;
    state.counters["ns_per_node_step"] =
        benchmark::Counter(nn * state.iterations() * 1e-9, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
    state.counters["ns_per_item_step"] = benchmark::Counter(items * state.iterations() * 1e-9,
                                                            benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
    if (rk && m.nodal_block(0))
    {
        // per particle: SCNI entries, NSNI entries per direction, and the batches of 8 whose
        // points share one stencil at consecutive bases (the whole-vector path)
        const NodalBlock& blk = *m.nodal_block(0);
        const index_t np = blk.n_points();
        double entries = 0.0, stab = 0.0;
        for (index_t p = 0; p < np; ++p)
        {
            entries += blk.point_view(p).size;
            if (!blk.stab_triplets.empty())
                stab += blk.stab_triplets.view(p).size;
        }
        // the flags the force pass reads (NodalBlock::build_tables)
        const index_t nb = np / 8;
        const auto& su = blk.point_stencils.uniform;
        const auto& tu = blk.stab_triplets.uniform;
        const double uniform = static_cast<double>(std::count(su.begin(), su.end(), 1));
        const double uniform_stab = static_cast<double>(std::count(tu.begin(), tu.end(), 1));
        state.counters["scni_entries"] = entries / np;
        state.counters["nsni_entries"] = stab / np;
        state.counters["uniform_batches"] = uniform / std::max<index_t>(nb, 1);
        state.counters["uniform_nsni_batches"] = uniform_stab / std::max<index_t>(nb, 1);
    }
    state.counters["bytes_per_item"] = bytes / items;
    state.counters["heap_bytes_per_item"] = heap / items;
    omp_set_num_threads(saved);
}

/// The force pass alone (nodal_internal_force and the assembly) on an irregular cloud: the
/// particles of studies/decks/column_wave_cloud.yaml (a jittered lattice with Voronoi cells, SCNI
/// + NSNI, a/h 1.51), whose stencils are not translates of each other, so none are shared.
/// length 200 (mm): the deck, 5,025 particles, whose tables (about 23 MB) stream from memory
/// each pass; 20: a tenth of the column (525 particles, 2.3 MB), whose tables stay in cache.
/// support: 100 a/h of the box support, the deck's 151 or 135 (fewer entries per point; the
/// plateau each gives: studies/tables/cloud_quadrature.yaml, cases box135_*).
void BM_CloudForcePass(benchmark::State& state)
{
    const int saved = omp_get_max_threads();
    omp_set_num_threads(static_cast<int>(state.range(0)));
    Model m =
        Model::build(read_deck(std::string(RKFEM_SOURCE_DIR) + "/studies/decks/column_wave_cloud.yaml",
                               {"parts.column.generator.size=[4 mm, 4 mm, " + std::to_string(state.range(1)) + " mm]",
                                "parts.column.rk.normalized_support=" + std::to_string(state.range(2) / 100.0)}));
    NodalBlock& blk = *m.nodal_block(0);
    NodeSet& nodes = m.nodes;
    for (std::size_t i = 0; i < nodes.x0.size(); ++i)
    {
        nodes.v[i] = 1e-3 * std::sin(1e3 * nodes.x0[i] + static_cast<double>(i % 3));
        nodes.u[i] = 1e-9 * std::cos(1e3 * nodes.x0[i] + static_cast<double>(i % 3));
    }
    for (auto _ : state)
    {
        benchmark::DoNotOptimize(nodal_internal_force(blk, nodes, 1e-8));
        assemble_nodal_forces(blk, nodes);
        benchmark::ClobberMemory();
    }
    state.counters["ns_per_particle_step"] =
        benchmark::Counter(static_cast<double>(blk.n_points()) * 1e-9,
                           benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
    state.counters["entries"] = static_cast<double>(blk.points.offsets.back()) / blk.n_points();
    state.counters["stab_entries"] = static_cast<double>(blk.stabilization.offsets.back()) / blk.n_points();
    state.counters["shared"] = blk.point_stencils.empty() ? 0 : 1;
    omp_set_num_threads(saved);
}
/// The semi-Lagrangian force pass (operators/semi_lagrangian_block.hpp) on the column wave's
/// lattice (studies/decks/column_wave_rkpm.yaml: 5,025 particles at 200 mm, 10,025 at 400 mm,
/// 300,025 at 12,000 mm),
/// with a deforming velocity field: mode 0 rebuilds the tables every pass (the default), mode 1
/// resets the reference every 10 passes (semi_lagrangian.reset_interval: 10), mode 2 is the
/// deck's Lagrangian block (SCNI + MSCNI) of the same part for comparison, mode 3 is mode 0
/// assembled by the per-pair gather instead of the chunked scatter, mode 4 is SD-SNNI (every step). The neighbour lists
/// are built once before the loop (their skin holds them across the passes of a run).
void BM_SemiLagrangianPass(benchmark::State& state)
{
    const int saved = omp_get_max_threads();
    omp_set_num_threads(static_cast<int>(state.range(0)));
    const int mode = static_cast<int>(state.range(2));
    std::vector<std::string> sets = {"parts.column.generator.size=[4 mm, 4 mm, " + std::to_string(state.range(1)) +
                                     " mm]"};
    if (mode != 2)
    {
        sets.push_back("parts.column.kinematics=semi-lagrangian");
        sets.push_back(mode == 4 ? "parts.column.nodal_integration={scheme: sd-snni}"
                                 : "parts.column.nodal_integration={scheme: snni}");
        sets.push_back(std::string("parts.column.semi_lagrangian={reset_interval: ") + (mode == 1 ? "10" : "1") + "}");
    }
    Model m = Model::build(read_deck(std::string(RKFEM_SOURCE_DIR) + "/studies/decks/column_wave_rkpm.yaml", sets));
    NodeSet& nodes = m.nodes;
    for (std::size_t i = 0; i < nodes.x0.size(); ++i)
        nodes.v[i] = 1e-3 * std::sin(1e3 * nodes.x0[i] + static_cast<double>(i % 3));
    ForceBlock& blk = m.block(0);
    if (mode == 3)
        dynamic_cast<SemiLagrangianForceBlock&>(blk).set_assembly(Assembly::Gather);
    index_t passes = 0;
    for (auto _ : state)
    {
        benchmark::DoNotOptimize(blk.add_forces(nodes, 1e-8, false));
        if (mode == 1 && ++passes % 10 == 0)
            for (int k = 0; k < 10; ++k)
                blk.commit(); // the steps since the reset: the next pass resets
        benchmark::ClobberMemory();
    }
    state.counters["ns_per_particle_step"] =
        benchmark::Counter(static_cast<double>(nodes.size()) * 1e-9,
                           benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
    if (const auto* sl = dynamic_cast<const SemiLagrangianForceBlock*>(&blk))
    {
        state.counters["bytes_per_particle"] = static_cast<double>(sl->memory_bytes()) / sl->n_particles();
        state.counters["scatter"] = sl->scatters() ? 1 : 0;
        state.counters["entries"] = static_cast<double>(sl->neighbour_entries()) / sl->n_particles();
    }
    omp_set_num_threads(saved);
}
/// Set-up: Model::build of a seed deck as rkpm (deck read, mesh, RK functions, SCNI + NSNI,
/// kinematic map, tables), the deck to the first step less the stepper's start. deck 0: the P1
/// cylinder at 0.5 in (4,300 particles), 1: at 0.25 in (38,220), 2: column_wave_cloud.yaml
/// (5,025 particles, Voronoi cells). Counter: seconds per 10^5 particles (the unit).
void BM_SeedDeckSetup(benchmark::State& state)
{
    const int saved = omp_get_max_threads();
    omp_set_num_threads(static_cast<int>(state.range(1)));
    const int deck = static_cast<int>(state.range(0));
    const std::string dir = std::string(RKFEM_SOURCE_DIR) + "/studies/decks/";
    const Deck d =
        deck == 2
            ? read_deck(dir + "column_wave_cloud.yaml")
            : read_deck(dir + "p1_uuc_cylinder.yaml",
                        {"parts.cylinder.formulation=rkpm",
                         std::string("parts.cylinder.generator.element_size=") + (deck == 0 ? "0.5in" : "0.25in")});
    double particles = 0.0;
    for (auto _ : state)
    {
        Model m = Model::build(d);
        particles = m.nodes.size();
        benchmark::DoNotOptimize(m.nodes.x0.data());
    }
    state.counters["particles"] = particles;
    state.counters["s_per_1e5_particles"] = benchmark::Counter(
        particles * 1e-5, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
    omp_set_num_threads(saved);
}
} // namespace

BENCHMARK(BM_SeedDeckSetup)
    ->ArgNames({"deck", "threads"})
    ->ArgsProduct({{0, 1, 2}, {1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

BENCHMARK(BM_CloudForcePass)
    ->ArgNames({"threads", "length", "support"})
    ->ArgsProduct({{1, 2}, {200, 20}, {151, 135}})
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

BENCHMARK(BM_SemiLagrangianPass)
    ->ArgNames({"threads", "length", "mode"})
    ->ArgsProduct({{1, 2}, {200, 400}, {0, 1, 2, 3, 4}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
// the larger size: 300,025 particles (a 12 m column), every step against the Lagrangian block
BENCHMARK(BM_SemiLagrangianPass)
    ->ArgNames({"threads", "length", "mode"})
    ->ArgsProduct({{1, 2}, {12000}, {0, 2}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// deck 0: P3 cantilever, 1: P1 cylinder (0.5 in); form 0: fem-1pt, 1: rkpm
BENCHMARK(BM_SeedDeckStep)
    ->ArgNames({"deck", "rkpm", "threads"})
    ->ArgsProduct({{0, 1}, {0, 1}, {1}})
    ->Unit(benchmark::kMicrosecond)
    ->Iterations(600); // the first 600 steps: within each deck's end time

// the driver's allocator (core/allocator_tuning.hpp), so that set-up is timed as `rkfem` runs it
int main(int argc, char** argv)
{
    rkfem::tune_allocator(argv);
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv))
        return 1;
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    return 0;
}
