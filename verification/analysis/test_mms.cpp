// Manufactured solution u_i = sin(pi x) sin(pi y) sin(pi z) on the unit cube (static, exact
// tractions, rigid modes pinned): convergence rates of the nodal schemes, driven by the sweep
// definitions in studies/sweeps. The smoke sweep (h = 1/4, 1/8, 1/16) runs in CI and leaves its
// table for the notebook test; the full sweep is test_mms_long (label long).
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "rkfem/analysis/convergence_study.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/core/input_error.hpp"

using namespace rkfem;

namespace
{
std::string out_dir(const char* fallback)
{
    const char* d = std::getenv("RKFEM_CONVERGENCE_OUT");
    return d ? d : fallback;
}

/// Asserts the rates between the two finest resolutions of every SCNI-family case.
void check(const std::string& sweep_file, const std::string& dir)
{
    const ConvergenceSweep s = read_sweep(std::string(RKFEM_SOURCE_DIR) + "/studies/sweeps/" + sweep_file);
    const auto results = run_sweep(s, dir, false);
    for (std::size_t c = 0; c < s.cases.size(); ++c)
    {
        const auto& r = results[c];
        const std::size_t k = r.size() - 1;
        const real_t l2 = observed_rate(r[k - 1].l2, r[k].l2, r[k - 1].h, r[k].h);
        const real_t h1 = observed_rate(r[k - 1].h1, r[k].h1, r[k - 1].h, r[k].h);
        const std::string name = s.cases[c].label() + " a/h " + std::to_string(s.cases[c].rk.normalized_support);
        std::printf("%-40s finest rates: L2 %.3f  H1 %.3f\n", name.c_str(), l2, h1);
        if (s.cases[c].scheme == "dni")
            continue; // recorded only: DNI is the negative control
        EXPECT_GE(l2, 1.8) << name;
        EXPECT_GE(h1, 0.85) << name;
    }
}
} // namespace

TEST(ManufacturedSolution, SmokeSweepRates)
{
    check("mms_smoke.yaml", out_dir("convergence_smoke"));
}

// SNNI on the semi-Lagrangian block's cells with its face-gradient term, and SD-SNNI (issue #48)
TEST(ManufacturedSolution, SnniSmokeSweepRates)
{
    check("mms_snni_smoke.yaml", "convergence_snni_smoke");
}

namespace
{
/// read_sweep's error for a sweep file with `body` ("" when it reads).
std::string sweep_error(const std::string& body)
{
    const std::string path = ::testing::TempDir() + "/sweep_under_test.yaml";
    std::ofstream(path) << body;
    try
    {
        read_sweep(path);
    }
    catch (const DeckError& e)
    {
        return e.what();
    }
    return "";
}
} // namespace

TEST(ConvergenceSweepInput, BadCasesNameTheKeyAndLine)
{
    const std::string head = "title: t\nresolutions: [4, 8]\ncases:\n";
    // the solver does not change the problem, so two cases may differ in it alone
    EXPECT_EQ(sweep_error(head + "  - {scheme: scni, solver: direct}\n  - {scheme: scni, solver: pcg}\n"), "");
    const std::string twice = sweep_error(head + "  - {scheme: scni}\n  - {scheme: sd-scni}\n  - {scheme: scni}\n");
    EXPECT_NE(twice.find(":6: cases.2: the same case as cases.0 (line 4)"), std::string::npos) << twice;
    const std::string bc = sweep_error(head + "  - {scheme: scni, boundary: free}\n");
    EXPECT_NE(bc.find(":4: cases.0.boundary: 'free' is not a valid choice; expected one of traction | dirichlet"),
              std::string::npos)
        << bc;
    const std::string solver = sweep_error(head + "  - {scheme: scni, solver: gmres}\n");
    EXPECT_NE(solver.find("cases.0.solver: 'gmres' is not a valid choice; expected one of auto | direct | pcg"),
              std::string::npos)
        << solver;
    const std::string fe = sweep_error(head + "  - {formulation: fem-nodal, scheme: snni}\n");
    EXPECT_NE(fe.find(":4: cases.0.scheme: snni integrates RK particles on their own (semi-Lagrangian) cells; "
                      "expected formulation rkpm with scheme snni"),
              std::string::npos)
        << fe;
    const std::string sd = sweep_error(head + "  - {scheme: sd-snni, stabilization: 1}\n");
    EXPECT_NE(sd.find(":4: cases.0.stabilization: stabilizes scheme scni (MSCNI) or snni (the face-gradient term) "
                      "only; expected no stabilization with scheme sd-snni"),
              std::string::npos)
        << sd;
}

TEST(ConvergenceSweepInput, EverySweepInStudiesReads)
{
    // the long sweeps do not run in CI: their definitions are at least read here
    int n = 0;
    for (const auto& e : std::filesystem::directory_iterator(std::string(RKFEM_SOURCE_DIR) + "/studies/sweeps"))
        if (e.path().extension() == ".yaml")
        {
            const ConvergenceSweep s = read_sweep(e.path().string());
            EXPECT_FALSE(s.cases.empty()) << e.path();
            ++n;
        }
    EXPECT_GE(n, 4);
}
