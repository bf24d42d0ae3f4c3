#pragma once
/// @file erk_tables.hpp
/// The explicit Runge-Kutta tables of stepper arkode-erk (config/erk_table_names.hpp) and their
/// stability on the imaginary axis: SUNDIALS' Butcher tables only, so that the deck reader (and
/// its fuzzer) can check a table without the stepper.
#include <string>

#include "rkfem/core/types.hpp"

namespace rkfem
{
/// Builds the Butcher table for a name of config/erk_table_names.hpp; returns its stages and
/// order through the pointers (for tests). The table is owned by the caller (ARKodeButcherTable).
void* make_erk_table(const std::string& name, int* stages = nullptr, int* order = nullptr);
void free_erk_table(void* table);

/// The table's stability interval on the imaginary axis: the largest Y with |R(i y)| <= 1 for
/// every y in [0, Y], R(z) = 1 + z b^T (I - z A)^-1 1 its stability polynomial (to 1e-6; 0 where
/// |R(i y)| > 1 right from 0, as for forward Euler and Heun-Euler). An undamped mode of frequency
/// omega stays bounded where omega dt <= Y; the central difference's interval is 2.
real_t erk_imaginary_stability_limit(const std::string& name);
/// Below this interval a table is refused for time.erk_table: |R(i y)| > 1 from y = 0 on (Heun-Euler;
/// and Cash-Karp, Fehlberg 6-4-5, Sayfy-Aburub, ARK548L2SAb, whose |R(i y)| - 1 grows as a high
/// power of y and passes 1e-14 by y = 0.02), so undamped waves grow at every step.
inline constexpr real_t kMinErkImaginaryInterval = 0.1;
} // namespace rkfem
