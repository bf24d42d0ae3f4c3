// Long (label `long`): static tip deflection of fully integrated hexes at 80 x 8 x 8, where
// shear locking has dropped below the 3% band (at 40 x 4 x 4 the 2x2x2 hex is 4.3% too stiff).
#include <gtest/gtest.h>

#include "cantilever_common.hpp"

using namespace rkfem;

TEST(CantileverLong, StaticTipDeflectionFullyIntegrated)
{
    const real_t exact = test::timoshenko_tip_deflection(1e4, 200e9, 0.3, 1.0, 0.1, 0.1);
    const real_t d = test::relaxed_tip_deflection("    formulation: fem-2x2x2\n", 80, 8, 8);
    std::printf("2x2x2, 80x8x8: tip %.4f mm vs %.4f mm (%+.2f%%)\n", d * 1e3, exact * 1e3, 100 * (d / exact - 1));
    EXPECT_NEAR(d, exact, 0.03 * exact);
}

TEST(CantileverLong, StaticTipDeflectionOnePointStiffnessFineMesh)
{
    const real_t exact = test::timoshenko_tip_deflection(1e4, 200e9, 0.3, 1.0, 0.1, 0.1);
    const real_t d = test::relaxed_tip_deflection(
        "    formulation: fem-1pt\n    hourglass: {type: stiffness, coefficient: 0.05}\n", 80, 8, 8);
    std::printf("1-pt stiffness QM 0.05, 80x8x8: tip %.4f mm vs %.4f mm (%+.2f%%)\n", d * 1e3, exact * 1e3,
                100 * (d / exact - 1));
    EXPECT_NEAR(d, exact, 0.03 * exact);
}

TEST(CantileverLong, FreeVibrationFullyIntegrated)
{
    // 80 x 4 x 4 fully integrated: measured -1.8% against Euler-Bernoulli (locking shortens it)
    const real_t T = test::euler_bernoulli_period(200e9, 7850, 1.0, 0.05);
    const test::Vibration v = test::free_vibration("    formulation: fem-2x2x2\n", 80, 4);
    EXPECT_NEAR(v.period, T, 0.02 * T);
    EXPECT_LT(v.drift, 0.005);
}
