// Material point updates, ns per update, 1 thread: elastic, J2 (elastic steps, plastic
// hardening steps, failed points), K&C concrete and the CSCM cap model (elastic, softening, cap
// compaction). Each iteration updates a batch of 4096 independent points.
//   build/release/bin/bench_materials --benchmark_counters_tabular=true
#include <benchmark/benchmark.h>
#include <vector>

#include "rkfem/materials/cscm_concrete.hpp"
#include "rkfem/materials/j2_plasticity.hpp"
#include "rkfem/materials/kcc_concrete.hpp"

using namespace rkfem;

namespace
{
constexpr int n = 4096;

void BM_Elastic(benchmark::State& state)
{
    const ElasticParams el = ElasticParams::from_E_nu(7850, 200e9, 0.3);
    std::vector<real_t> s(6 * n, 1e6);
    const real_t d[6] = {1e-3, -3e-4, -3e-4, 1e-4, 0, 2e-4}, w[3] = {1e-4, 0, -1e-4};
    for (auto _ : state)
    {
        for (int p = 0; p < n; ++p)
            elastic_update(el, d, w, 1e-6, &s[6 * p]);
        benchmark::ClobberMemory();
    }
    state.counters["ns_per_update"] =
        benchmark::Counter(n * 1e-9, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

/// mode 0: elastic steps below yield, 1: plastic (every update returns to the surface), 2: failed
void BM_J2(benchmark::State& state)
{
    const ElasticParams el = ElasticParams::from_E_nu(7850, 200e9, 0.3);
    J2Params p;
    p.elastic = el;
    p.curve = {{0.0, 792e6},   {0.01, 946e6},  {0.05, 1026e6}, {0.10, 1072e6},
               {0.20, 1128e6}, {0.50, 1218e6}, {1.0, 1302e6}};
    const int mode = static_cast<int>(state.range(0));
    std::vector<real_t> s(6 * n, 0.0), ep(n, 0.0), failed(n, mode == 2 ? 1.0 : 0.0);
    const real_t d[6] = {1.0, -0.5, -0.5, 0.2, 0, 0.1}, w[3] = {0.1, 0, -0.1};
    const real_t dt = mode == 0 ? 1e-9 : 1e-5;
    for (auto _ : state)
    {
        for (int q = 0; q < n; ++q)
        {
            if (mode == 0)
                for (int k = 0; k < 6; ++k)
                    s[6 * q + k] = 0.0; // stays elastic
            j2_update(p, d, w, dt, &s[6 * q], ep[q], failed[q]);
        }
        benchmark::ClobberMemory();
    }
    state.counters["ns_per_update"] =
        benchmark::Counter(n * 1e-9, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
    state.SetLabel(mode == 0 ? "elastic" : mode == 1 ? "plastic" : "failed");
}
/// mode 0: elastic steps (below the yield surface), 1: softening (past the peak, every update
/// returns to the current surface)
void BM_KCC(benchmark::State& state)
{
    const KccModel m = KccModel::from_fc(45.6e6, 2400);
    const int mode = static_cast<int>(state.range(0));
    std::vector<real_t> s(6 * n, 0.0);
    std::vector<KccState> st(n);
    const real_t d[6] = {-1.0, 0.2, 0.2, 0.1, 0, 0}, w[3] = {0.1, 0, -0.1};
    // prepare: drive every point past the peak for the softening case
    if (mode == 1)
        for (int q = 0; q < n; ++q)
            for (int k = 0; k < 300; ++k)
                kcc_update(m, d, w, 1e-5, &s[6 * q], st[q]);
    const std::vector<real_t> s0 = s;
    const std::vector<KccState> st0 = st;
    const real_t dt = mode == 0 ? 1e-8 : 1e-6;
    for (auto _ : state)
    {
        for (int q = 0; q < n; ++q)
        {
            if (mode == 0)
            {
                for (int k = 0; k < 6; ++k)
                    s[6 * q + k] = 0.0;
                st[q] = KccState{};
            }
            kcc_update(m, d, w, dt, &s[6 * q], st[q]);
        }
        benchmark::ClobberMemory();
    }
    state.counters["ns_per_update"] =
        benchmark::Counter(n * 1e-9, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
    state.SetLabel(mode == 0 ? "elastic" : "softening");
}

/// mode 0: elastic steps, 1: softening (uniaxial compression past the peak: return + damage),
/// 2: cap compaction (hydrostatic compression on the hardening cap)
void BM_CSCM(benchmark::State& state)
{
    const CscmModel m = CscmModel::from_fc(30e6, 2400);
    const int mode = static_cast<int>(state.range(0));
    std::vector<real_t> s(6 * n, 0.0);
    std::vector<CscmState> st(n);
    const real_t w[3] = {0.1, 0, -0.1};
    const real_t duc[6] = {-1.0, 0.25, 0.25, 0.0, 0, 0}, dhyd[6] = {-1.0, -1.0, -1.0, 0, 0, 0};
    const real_t* d = mode == 2 ? dhyd : duc;
    if (mode >= 1)
        for (int q = 0; q < n; ++q)
            for (int k = 0; k < 300; ++k)
                cscm_update(m, d, w, mode == 1 ? 1e-5 : 4e-5, &s[6 * q], st[q]);
    const real_t dt = mode == 0 ? 1e-8 : 1e-6;
    for (auto _ : state)
    {
        for (int q = 0; q < n; ++q)
        {
            if (mode == 0)
                st[q] = CscmState{};
            cscm_update(m, d, w, dt, &s[6 * q], st[q]);
        }
        benchmark::ClobberMemory();
    }
    state.counters["ns_per_update"] =
        benchmark::Counter(n * 1e-9, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
    state.counters["damage"] = st[0].d;
    state.SetLabel(mode == 0 ? "elastic" : mode == 1 ? "softening" : "cap");
}
} // namespace

BENCHMARK(BM_Elastic);
BENCHMARK(BM_KCC)->Arg(0)->Arg(1);
BENCHMARK(BM_J2)->Arg(0)->Arg(1)->Arg(2);
BENCHMARK(BM_CSCM)->Arg(0)->Arg(1)->Arg(2);
BENCHMARK_MAIN();
