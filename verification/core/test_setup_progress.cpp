// Set-up progress (core/setup_progress.hpp): a builder's phases reach the sink with their names
// and counts, the last line of a phase counts every item, nothing goes out before the delay, and
// without a sink nothing goes out at all.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "../support.hpp"
#include "rkfem/core/setup_progress.hpp"
#include "rkfem/model/nodal_block_build.hpp"

using namespace rkfem;

namespace
{
struct Line
{
    std::string text;
    bool last;
};

std::vector<Line> build_with_progress(double delay, const std::string& stab)
{
    std::vector<Line> lines;
    setup_progress::install([&](const std::string& s, bool last) { lines.push_back({s, last}); }, delay, 0.0);
    const HexMesh mesh = test::distorted_box(6, 0.01, 0.2);
    PartSpec ps = test::steel_nodal_part(Formulation::Rkpm, "scni", stab);
    ps.name = "block";
    build_nodal_block(ps, mesh, 0);
    setup_progress::install({});
    return lines;
}
} // namespace

TEST(SetupProgress, PhasesReportTheirNamesAndEveryItem)
{
    const std::vector<Line> lines = build_with_progress(0.0, "nsni");
    for (const Line& l : lines)
        std::printf("%s%s\n", l.text.c_str(), l.last ? "  (last)" : "");
    const std::string n = std::to_string(7 * 7 * 7);  // nodes of a 6 x 6 x 6 box: one NSNI triplet each
    const std::string ne = std::to_string(6 * 6 * 6); // its elements: RK SCNI is built by elements
    int last_gradients = 0, last_stab = 0;
    for (const Line& l : lines)
        if (l.last)
        {
            if (l.text.find("part 'block': scni gradients 100.0% (" + ne + " of " + ne + ")") != std::string::npos)
                ++last_gradients;
            if (l.text.find("part 'block': nsni stabilization 100.0% (" + n + " of " + n + ")") != std::string::npos)
                ++last_stab;
        }
    EXPECT_EQ(last_gradients, 1);
    EXPECT_EQ(last_stab, 1);
}

TEST(SetupProgress, NothingBeforeTheDelayNorWithoutASink)
{
    EXPECT_TRUE(build_with_progress(3600.0, "nsni").empty());
    setup_progress::install({});
    const HexMesh mesh = test::distorted_box(3, 0.01, 0.2);
    build_nodal_block(test::steel_nodal_part(Formulation::Rkpm, "scni", "nsni"), mesh, 0); // must not crash
}

TEST(SetupProgress, CountsOutsideAPhaseSayNothing)
{
    // a builder that counts items with no phase open (the clock's start unset) printed
    // "set-up: , 1366.3 s", the time since the clock's epoch; now it is silent
    std::vector<Line> lines;
    setup_progress::install([&](const std::string& s, bool last) { lines.push_back({s, last}); }, 0.0, 0.0);
    for (int i = 0; i < 64; ++i)
        setup_progress::advance();
    {
        const setup_progress::Phase p("counted", 32);
        for (int i = 0; i < 32; ++i)
            setup_progress::advance();
    }
    for (int i = 0; i < 64; ++i)
        setup_progress::advance(); // after the phase closed
    setup_progress::install({});
    ASSERT_FALSE(lines.empty());
    for (const Line& l : lines)
        EXPECT_NE(l.text.find("set-up: counted"), std::string::npos) << l.text;
}
