// Cantilever checks that fit the default run: free vibration (period against Euler-Bernoulli,
// energy drift), and the static tip deflection of 1-point hexes with stiffness hourglass control.
#include <gtest/gtest.h>

#include "cantilever_common.hpp"

using namespace rkfem;

TEST(Cantilever, FreeVibrationOnePointStiffnessHourglass)
{
    const real_t T = test::euler_bernoulli_period(200e9, 7850, 1.0, 0.05);
    const test::Vibration v =
        test::free_vibration("    formulation: fem-1pt\n    hourglass: {type: stiffness, coefficient: 0.15}\n", 80, 4);
    EXPECT_NEAR(v.period, T, 0.02 * T);
    EXPECT_LT(v.drift, 0.005);
}

TEST(Cantilever, StaticTipDeflectionOnePointStiffnessHourglass)
{
    // 1000 x 100 x 100 mm, P = 10 kN: Timoshenko tip deflection 2.0153 mm.
    const real_t exact = test::timoshenko_tip_deflection(1e4, 200e9, 0.3, 1.0, 0.1, 0.1);
    const real_t d = test::relaxed_tip_deflection(
        "    formulation: fem-1pt\n    hourglass: {type: stiffness, coefficient: 0.15}\n", 40, 4, 4);
    std::printf("1-pt stiffness QM 0.15, 40x4x4: tip %.4f mm vs %.4f mm (%+.2f%%)\n", d * 1e3, exact * 1e3,
                100 * (d / exact - 1));
    EXPECT_NEAR(d, exact, 0.03 * exact);
}
