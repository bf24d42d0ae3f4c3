// Full manufactured-solution sweeps (label long), h = 1/8, 1/16, 1/32, every nodal scheme, rates
// between the two finest resolutions:
// - studies/sweeps/mms_dirichlet.yaml, u = 0 on the boundary: SCNI with and without stabilization,
//   SD-SCNI, RK and FE functions, L2 >= 1.8 and H1 >= 0.85 (linear basis: 2 and 1 in theory);
// - studies/sweeps/mms_full.yaml, exact tractions on the whole boundary: the stabilized schemes
//   are asserted the same way, and H1 for plain SCNI too. Plain SCNI's L2 rate is recorded, not
//   asserted: on this all-free-surface problem it converges at L2 1.75-1.79 (a/h 1.25, 1.51, FE
//   functions) although it passes the patch test to round-off and converges at 1.97 with u = 0 on
//   the boundary (its low-energy surface modes; Puso, Chen, Zywicz & Elmer 2008). The Dirichlet
//   sweep holds the same plain SCNI cases and asserts them.
// DNI is the negative control in both (recorded).
// The semi-Lagrangian block's SNNI tables (issue #48; on the dual cells' boxes, which tile the
// cube): SNNI with the face-gradient term asserted in both sweeps; SD-SNNI asserted with u = 0 on
// the boundary, its L2 rate recorded with tractions (1.80 at a/h 1.51, 1.87 at 1.25, still
// rising: the surface modes plain SCNI shows there); plain SNNI recorded in both (it has the
// sawtooth zero-energy mode in dynamics; statically it converges at L2 2.1-2.9).
#include <gtest/gtest.h>

#include <cstdio>

#include "rkfem/analysis/convergence_study.hpp"

using namespace rkfem;

namespace
{
struct Rates
{
    real_t l2 = 0.0, h1 = 0.0;
};

Rates finest_rates(const std::vector<MmsResult>& r)
{
    const std::size_t k = r.size() - 1;
    return {observed_rate(r[k - 1].l2, r[k].l2, r[k - 1].h, r[k].h),
            observed_rate(r[k - 1].h1, r[k].h1, r[k - 1].h, r[k].h)};
}

bool plain_scni(const MmsCase& c)
{
    return c.scheme == "scni" && c.stabilization == 0;
}

bool plain_snni(const MmsCase& c)
{
    return c.scheme == "snni" && c.stabilization == 0;
}

std::vector<std::vector<MmsResult>> run(const char* file, const char* out, ConvergenceSweep& s)
{
    s = read_sweep(std::string(RKFEM_SOURCE_DIR) + "/studies/sweeps/" + file);
    EXPECT_EQ(s.resolutions.back(), 32) << file << ": the issue's sweep ends at h = 1/32";
    return run_sweep(s, out, false);
}
} // namespace

TEST(ManufacturedSolution, DirichletSweepRates)
{
    ConvergenceSweep s;
    const auto results = run("mms_dirichlet.yaml", "convergence_dirichlet", s);
    for (std::size_t c = 0; c < s.cases.size(); ++c)
    {
        const Rates r = finest_rates(results[c]);
        std::printf("%-28s a/h %.2f finest rates: L2 %.3f  H1 %.3f\n", s.cases[c].label().c_str(),
                    s.cases[c].rk.normalized_support, r.l2, r.h1);
        ASSERT_EQ(s.cases[c].boundary, MmsBoundary::Dirichlet) << s.cases[c].label();
        if (s.cases[c].scheme == "dni" || plain_snni(s.cases[c]))
            continue;
        EXPECT_GE(r.l2, 1.8) << s.cases[c].label() << " a/h " << s.cases[c].rk.normalized_support;
        EXPECT_GE(r.h1, 0.85) << s.cases[c].label() << " a/h " << s.cases[c].rk.normalized_support;
    }
}

TEST(ManufacturedSolution, TractionSweepRates)
{
    ConvergenceSweep s;
    const auto results = run("mms_full.yaml", "convergence_full", s);
    for (std::size_t c = 0; c < s.cases.size(); ++c)
    {
        const Rates r = finest_rates(results[c]);
        const bool recorded = s.cases[c].scheme == "dni" || plain_snni(s.cases[c]);
        const bool l2_recorded = recorded || plain_scni(s.cases[c]) || s.cases[c].scheme == "sd-snni";
        std::printf("%-28s a/h %.2f finest rates: L2 %.3f%s  H1 %.3f\n", s.cases[c].label().c_str(),
                    s.cases[c].rk.normalized_support, r.l2, l2_recorded ? " (recorded)" : "", r.h1);
        ASSERT_EQ(s.cases[c].boundary, MmsBoundary::Traction) << s.cases[c].label();
        if (recorded)
            continue;
        if (!l2_recorded)
        {
            EXPECT_GE(r.l2, 1.8) << s.cases[c].label() << " a/h " << s.cases[c].rk.normalized_support;
        }
        EXPECT_GE(r.h1, 0.85) << s.cases[c].label() << " a/h " << s.cases[c].rk.normalized_support;
    }
}
