#pragma once
/// @file units.hpp
/// Quantities with units at the boundary ("5000 psi", "0.5 in", "820 m/s", "7850 kg/m^3");
/// everything inside the library is SI (kg, m, s, N, Pa, J).
#include <optional>
#include <string>
#include <string_view>

#include "rkfem/core/types.hpp"

namespace rkfem
{
/// Physical dimension as exponents of mass, length and time.
struct Dimension
{
    int mass = 0;
    int length = 0;
    int time = 0;
    constexpr bool operator==(const Dimension&) const = default;
};

namespace dim
{
inline constexpr Dimension none{0, 0, 0};
inline constexpr Dimension mass{1, 0, 0};
inline constexpr Dimension length{0, 1, 0};
inline constexpr Dimension time{0, 0, 1};
inline constexpr Dimension velocity{0, 1, -1};
inline constexpr Dimension acceleration{0, 1, -2};
inline constexpr Dimension force{1, 1, -2};
inline constexpr Dimension pressure{1, -1, -2};
inline constexpr Dimension density{1, -3, 0};
inline constexpr Dimension energy{1, 2, -2};
} // namespace dim

/// "length", "pressure (stress)", ... and an example unit, for error messages.
std::string describe(Dimension d);

/// A unit expression resolved to SI: value_SI = number * scale.
struct Unit
{
    real_t scale = 1.0;
    Dimension dimension{};
};

/// Parses a unit expression such as "m/s", "kg/m^3", "N*m", "ksi", "lbf/in^2".
/// Returns nullopt and fills `error` when a symbol is unknown or the syntax is bad.
std::optional<Unit> parse_unit(std::string_view text, std::string* error);

/// Result of parsing "number [unit]".
struct Quantity
{
    real_t value_si = 0.0;
    bool has_unit = false;
};

/// Parses "820 m/s" (or a bare number, taken as SI) and checks the dimension.
/// Throws rkfem::Error with a message (without location) on failure.
Quantity parse_quantity(std::string_view text, Dimension expected);

/// Known unit symbols, for error messages.
std::string known_units_for(Dimension d);
} // namespace rkfem
