// Full manufactured-solution sweeps (label long): every nodal scheme of studies/sweeps/mms_full.yaml
// to h = 1/16, and the default stabilized RK scheme to h = 1/32 (studies/sweeps/mms_h32.yaml).
#include <gtest/gtest.h>

#include <cstdio>

#include "rkfem/analysis/convergence_study.hpp"

using namespace rkfem;

TEST(ManufacturedSolution, FullSweepRates)
{
    const ConvergenceSweep s = read_sweep(std::string(RKFEM_SOURCE_DIR) + "/studies/sweeps/mms_full.yaml");
    const auto results = run_sweep(s, "convergence_full", false);
    for (std::size_t c = 0; c < s.cases.size(); ++c)
    {
        const auto& r = results[c];
        const std::size_t k = r.size() - 1;
        const real_t l2 = observed_rate(r[k - 1].l2, r[k].l2, r[k - 1].h, r[k].h);
        const real_t h1 = observed_rate(r[k - 1].h1, r[k].h1, r[k - 1].h, r[k].h);
        std::printf("%-24s a/h %.2f finest rates: L2 %.3f  H1 %.3f\n", s.cases[c].label().c_str(),
                    s.cases[c].rk.normalized_support, l2, h1);
        if (s.cases[c].scheme == "dni")
            continue;
        EXPECT_GE(l2, 1.8) << s.cases[c].label() << " a/h " << s.cases[c].rk.normalized_support;
        EXPECT_GE(h1, 0.85) << s.cases[c].label();
    }
}

TEST(ManufacturedSolution, RatesToH32)
{
    // studies/sweeps/mms_h32.yaml: the default stabilized RK scheme to h = 1/32 (about 12 minutes
    // and 6 GB for the CHOLMOD solve at 1/32 on the 2-core machine)
    const ConvergenceSweep s = read_sweep(std::string(RKFEM_SOURCE_DIR) + "/studies/sweeps/mms_h32.yaml");
    const auto results = run_sweep(s, "convergence_h32", false);
    const auto& r = results.front();
    const std::size_t k = r.size() - 1;
    const real_t l2 = observed_rate(r[k - 1].l2, r[k].l2, r[k - 1].h, r[k].h);
    const real_t h1 = observed_rate(r[k - 1].h1, r[k].h1, r[k - 1].h, r[k].h);
    std::printf("%s, h 1/16 -> 1/32: L2 %.3f  H1 %.3f\n", s.cases.front().label().c_str(), l2, h1);
    EXPECT_GE(l2, 1.8);
    EXPECT_GE(h1, 0.85);
}
