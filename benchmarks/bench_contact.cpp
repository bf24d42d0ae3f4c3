// Contact search and force: two elastic plates pressed face to face (surface-to-surface, both
// passes; node-to-segment or mortar), every node of both touching faces in contact each step. Per iteration the contact
// pass of one force evaluation (motion check, search when due, projections, forces into the
// channel); reported as ns per contact node-step, the surface nodes of both parts. Sizes: about
// 10^4 and 10^5 surface nodes. A small drift every step makes the search run every few steps,
// as it does in a penetration.
#include <benchmark/benchmark.h>

#include <omp.h>
#include <string>

#include "rkfem/config/deck.hpp"
#include "rkfem/model/model.hpp"

using namespace rkfem;

namespace
{
std::string plates_deck(int n, bool mortar)
{
    const std::string s = std::to_string(n), size = std::to_string(n) + " mm";
    std::string d = "time: {end: 1 s}\nparts:\n";
    for (int k = 0; k < 2; ++k)
        d += std::string("  p") + std::to_string(k) + ":\n    generator: {type: box, origin: [0, 0, " +
             (k ? "-0.001 mm" : "-1 mm") + "], size: [" + size + ", " + size + ", 1 mm], divisions: [" + s + ", " + s +
             ", 1]}\n    material: {model: elastic, rho: 7850, E: 200e9, nu: 0.3}\n    formulation: fem-1pt\n";
    d += std::string("contacts:\n  - {type: surface-to-surface, surfaces: [p0, p1], formulation: ") +
         (mortar ? "mortar" : "node-to-segment") + "}\n";
    return d;
}

void BM_ContactPass(benchmark::State& state)
{
    const int saved = omp_get_max_threads();
    omp_set_num_threads(static_cast<int>(state.range(1)));
    Model m =
        Model::build(parse_deck(plates_deck(static_cast<int>(state.range(0)), state.range(2) != 0), "bench.yaml"));
    m.compute_forces(0.0, 0.0, 0); // the elements' critical step, the first search
    index_t surface_nodes = 0;
    for (const char* p : {"p0", "p1"})
        surface_nodes += static_cast<index_t>(m.contact_surface({p}, {}).nodes.size());
    const PhysicalNodes physical(m.nodes, m.kinematics);
    const ContactClock clock{0.0, 1e-7};
    real_t drift = 0.0;
    for (auto _ : state)
    {
        // the upper plate slides 1 um per step: a search about every 60 steps
        drift += 1e-6;
        const index_t b = m.parts[1].node_begin, e = m.parts[1].node_end;
        for (index_t i = b; i < e; ++i)
            m.nodes.x[3 * i] = m.nodes.x0[3 * i] + drift;
        m.contact.clear();
        m.contacts[0]->add_forces(physical, clock, m.contact);
        benchmark::DoNotOptimize(m.contact.f.data());
    }
    state.counters["surface_nodes"] = surface_nodes;
    state.counters["in_contact"] = m.contacts[0]->active_nodes();
    state.counters["ns_per_contact_node_step"] = benchmark::Counter(
        surface_nodes * state.iterations() * 1e-9, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
    omp_set_num_threads(saved);
}
} // namespace

// 48 x 48 plates: 1.0e4 surface nodes; 158 x 158: 1.0e5; mortar 0: node-to-segment, 1: mortar
BENCHMARK(BM_ContactPass)
    ->ArgNames({"n", "threads", "mortar"})
    ->ArgsProduct({{48, 158}, {1, 2}, {0, 1}})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_MAIN();
