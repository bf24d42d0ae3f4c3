#pragma once
/// @file erk_table_names.hpp
/// Explicit Runge-Kutta tables a deck may name for stepper arkode-erk: SUNDIALS 6.4.1's built-in
/// ERK tables (ARKODE_*), plus RK4 (classical) and SSPRK3 (Shu-Osher) built by rkfem. Tables with
/// c_last = 1 are run with the FSAL workaround (see time/arkode_stepper.hpp).
#include <string>
#include <vector>

namespace rkfem
{
inline std::vector<std::string> erk_table_names()
{
    return {"ARKODE_HEUN_EULER_2_1_2",
            "ARKODE_BOGACKI_SHAMPINE_4_2_3",
            "ARKODE_ARK324L2SA_ERK_4_2_3",
            "ARKODE_ZONNEVELD_5_3_4",
            "ARKODE_ARK436L2SA_ERK_6_3_4",
            "ARKODE_SAYFY_ABURUB_6_3_4",
            "ARKODE_CASH_KARP_6_4_5",
            "ARKODE_FEHLBERG_6_4_5",
            "ARKODE_DORMAND_PRINCE_7_4_5",
            "ARKODE_ARK548L2SA_ERK_8_4_5",
            "ARKODE_VERNER_8_5_6",
            "ARKODE_FEHLBERG_13_7_8",
            "ARKODE_KNOTH_WOLKE_3_3",
            "ARKODE_ARK437L2SA_ERK_7_3_4",
            "ARKODE_ARK548L2SAb_ERK_8_4_5",
            "RK4",
            "SSPRK3"};
}
} // namespace rkfem
