#pragma once
/// @file time_spec.hpp
/// The run's time control (deck section `time`): end, output intervals, step scale and limits,
/// the stepper.
#include <cstdint>
#include <string>

#include "rkfem/core/types.hpp"

namespace rkfem
{
enum class StepperKind
{
    CentralDifference, ///< hand-written kick-drift-kick
    ArkodeCd,          ///< the same central difference through SUNDIALS ARKODE ERKStep (1-stage table)
    ArkodeErk,         ///< ARKODE ERKStep with an explicit Runge-Kutta table (verification)
};

struct TimeSpec
{
    real_t end = 0.0;              ///< termination time [s]
    real_t output_interval = 0.0;  ///< field output interval [s]; 0: start and end only
    real_t history_interval = 0.0; ///< history interval [s]; 0: every step
    real_t dt_scale = 0.9;
    real_t dt_max = 0.0;                                     ///< 0: unlimited
    std::int64_t max_steps = 0;                              ///< 0: unlimited
    StepperKind stepper = StepperKind::ArkodeCd;             ///< the default: within a few % of the hand loop
    std::string erk_table = "ARKODE_BOGACKI_SHAMPINE_4_2_3"; ///< arkode-erk: built-in name, RK4 or SSPRK3
    real_t energy_error_limit = 0.05;                        ///< stop when the balance error exceeds this (fraction)
    /// stop (as unstable) when the step falls below this fraction of the first step (0: no floor;
    /// LS-DYNA's DTMIN of *CONTROL_TERMINATION)
    real_t dt_min_fraction = 1e-5;
    real_t mass_damping = 0.0; ///< dynamic-relaxation damping coefficient [1/s] (a -= c v)
};
} // namespace rkfem
