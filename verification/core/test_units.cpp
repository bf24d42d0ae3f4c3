// Units at the boundary: the conversions a deck relies on, checked against exact definitions.
#include <gtest/gtest.h>

#include "rkfem/core/error.hpp"
#include "rkfem/core/units.hpp"

using namespace rkfem;

TEST(Units, ConvertsTheSeedPaperQuantitiesToSI)
{
    // exact definitions: 1 in = 0.0254 m, 1 lbf = 4.4482216152605 N
    const double psi = 4.4482216152605 / (0.0254 * 0.0254);
    EXPECT_NEAR(parse_quantity("5000 psi", dim::pressure).value_si, 5000 * psi, 1e-9 * 5000 * psi);
    EXPECT_NEAR(parse_quantity("20 ksi", dim::pressure).value_si, 20e3 * psi, 1e-9 * 20e3 * psi);
    EXPECT_DOUBLE_EQ(parse_quantity("0.5 in", dim::length).value_si, 0.0127);
    EXPECT_DOUBLE_EQ(parse_quantity("30.78 g", dim::mass).value_si, 0.03078);
    EXPECT_DOUBLE_EQ(parse_quantity("820 m/s", dim::velocity).value_si, 820.0);
    EXPECT_DOUBLE_EQ(parse_quantity("3 ms", dim::time).value_si, 3e-3);
    EXPECT_DOUBLE_EQ(parse_quantity("26 us", dim::time).value_si, 26e-6);
    EXPECT_DOUBLE_EQ(parse_quantity("7850 kg/m^3", dim::density).value_si, 7850.0);
    EXPECT_DOUBLE_EQ(parse_quantity("200 GPa", dim::pressure).value_si, 200e9);
    EXPECT_DOUBLE_EQ(parse_quantity("10 kN", dim::force).value_si, 1e4);
    EXPECT_NEAR(parse_quantity("1 g/cm^3", dim::density).value_si, 1000.0, 1e-9);
    EXPECT_NEAR(parse_quantity("1 N/mm^2", dim::pressure).value_si, 1e6, 1e-6);
    EXPECT_DOUBLE_EQ(parse_quantity("9.81 m/s^2", dim::acceleration).value_si, 9.81);
    EXPECT_DOUBLE_EQ(parse_quantity("1.5", dim::none).value_si, 1.5); // bare number: SI
}

TEST(Units, RejectsUnknownAndMismatchedUnits)
{
    EXPECT_THROW(parse_quantity("5 furlongs", dim::length), Error);
    EXPECT_THROW(parse_quantity("5 psi", dim::length), Error);  // pressure where length expected
    EXPECT_THROW(parse_quantity("abc", dim::length), Error);    // not a number
    EXPECT_THROW(parse_quantity("5 m/", dim::velocity), Error); // incomplete
    try
    {
        parse_quantity("5 psi", dim::length);
    }
    catch (const Error& e)
    {
        EXPECT_NE(std::string(e.what()).find("length"), std::string::npos);
    }
}

TEST(Units, ReciprocalUnitsForRates)
{
    const Dimension per_second{0, 0, -1};
    EXPECT_DOUBLE_EQ(parse_quantity("1000 1/s", per_second).value_si, 1000.0);
    EXPECT_DOUBLE_EQ(parse_quantity("1000 /s", per_second).value_si, 1000.0);
    EXPECT_DOUBLE_EQ(parse_quantity("2 1/ms", per_second).value_si, 2000.0);
    EXPECT_DOUBLE_EQ(parse_quantity("3 s^-1", per_second).value_si, 3.0);
    EXPECT_THROW(parse_quantity("3 1/m", per_second), Error);
}
