#include "rkfem/core/units.hpp"

#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <sstream>

#include "rkfem/core/error.hpp"

namespace rkfem
{
namespace
{
struct UnitEntry
{
    std::string_view symbol;
    real_t scale;
    Dimension dimension;
};

constexpr real_t inch = 0.0254;
constexpr real_t foot = 0.3048;
constexpr real_t pound_mass = 0.45359237;
constexpr real_t pound_force = 4.4482216152605;
constexpr real_t psi = pound_force / (inch * inch);

// One table; symbols are case-sensitive (mm vs Mm matter, as in SI).
constexpr std::array<UnitEntry, 45> unit_table{{
    // length
    {"m", 1.0, dim::length},
    {"km", 1e3, dim::length},
    {"cm", 1e-2, dim::length},
    {"mm", 1e-3, dim::length},
    {"um", 1e-6, dim::length},
    {"in", inch, dim::length},
    {"ft", foot, dim::length},
    {"yd", 3 * foot, dim::length},
    {"mil", 1e-3 * inch, dim::length},
    // mass
    {"kg", 1.0, dim::mass},
    {"g", 1e-3, dim::mass},
    {"mg", 1e-6, dim::mass},
    {"t", 1e3, dim::mass},
    {"lb", pound_mass, dim::mass},
    {"lbm", pound_mass, dim::mass},
    {"slug", 14.593902937, dim::mass},
    // time
    {"s", 1.0, dim::time},
    {"ms", 1e-3, dim::time},
    {"us", 1e-6, dim::time},
    {"ns", 1e-9, dim::time},
    {"min", 60.0, dim::time},
    {"h", 3600.0, dim::time},
    // force
    {"N", 1.0, dim::force},
    {"kN", 1e3, dim::force},
    {"MN", 1e6, dim::force},
    {"lbf", pound_force, dim::force},
    {"kip", 1e3 * pound_force, dim::force},
    // pressure / stress
    {"Pa", 1.0, dim::pressure},
    {"kPa", 1e3, dim::pressure},
    {"MPa", 1e6, dim::pressure},
    {"GPa", 1e9, dim::pressure},
    {"bar", 1e5, dim::pressure},
    {"atm", 101325.0, dim::pressure},
    {"psi", psi, dim::pressure},
    {"ksi", 1e3 * psi, dim::pressure},
    {"Msi", 1e6 * psi, dim::pressure},
    {"psf", pound_force / (foot * foot), dim::pressure},
    // energy
    {"J", 1.0, dim::energy},
    {"kJ", 1e3, dim::energy},
    {"MJ", 1e6, dim::energy},
    // velocity shorthands
    {"mph", 0.44704, dim::velocity},
    {"fps", foot, dim::velocity},
    // dimensionless
    {"rad", 1.0, dim::none},
    {"deg", M_PI / 180.0, dim::none},
    {"%", 0.01, dim::none},
}};

const UnitEntry* find_symbol(std::string_view s)
{
    if (s == "µs")
        return find_symbol("us");
    if (s == "µm")
        return find_symbol("um");
    for (const auto& e : unit_table)
        if (e.symbol == s)
            return &e;
    return nullptr;
}

Dimension scaled(Dimension d, int p)
{
    return {d.mass * p, d.length * p, d.time * p};
}
Dimension added(Dimension a, Dimension b)
{
    return {a.mass + b.mass, a.length + b.length, a.time + b.time};
}

std::string_view trim(std::string_view s)
{
    while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front())))
        s.remove_prefix(1);
    while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back())))
        s.remove_suffix(1);
    return s;
}
} // namespace

std::string describe(Dimension d)
{
    if (d == dim::none)
        return "a plain number";
    if (d == dim::length)
        return "a length (e.g. 0.5 in, 12 mm)";
    if (d == dim::mass)
        return "a mass (e.g. 30.78 g)";
    if (d == dim::time)
        return "a time (e.g. 3 ms, 26 us)";
    if (d == dim::velocity)
        return "a velocity (e.g. 820 m/s)";
    if (d == dim::acceleration)
        return "an acceleration (e.g. 9.81 m/s^2)";
    if (d == dim::force)
        return "a force (e.g. 10 kN, 500 lbf)";
    if (d == dim::pressure)
        return "a pressure or stress (e.g. 5000 psi, 200 GPa)";
    if (d == dim::density)
        return "a density (e.g. 7850 kg/m^3)";
    if (d == dim::energy)
        return "an energy (e.g. 1 kJ)";
    if (d == Dimension{-1, 1, 2})
        return "a reciprocal pressure (e.g. 2.5e-4 1/MPa)";
    if (d == Dimension{-2, 2, 4})
        return "a reciprocal pressure squared (e.g. 3.5e-7 1/MPa^2)";
    if (d == Dimension{1, 0, -2})
        return "an energy per area (e.g. 100 J/m^2, 0.1 N/mm)";
    if (d == Dimension{0, 0, -1})
        return "a rate (e.g. 100 1/s)";
    std::ostringstream os;
    os << "a quantity of dimension kg^" << d.mass << " m^" << d.length << " s^" << d.time;
    return os.str();
}

std::string known_units_for(Dimension d)
{
    std::string out;
    for (const auto& e : unit_table)
        if (e.dimension == d)
        {
            if (!out.empty())
                out += ", ";
            out += e.symbol;
        }
    return out;
}

std::optional<Unit> parse_unit(std::string_view text, std::string* error)
{
    text = trim(text);
    Unit unit;
    if (text.empty())
        return unit;
    int sign = +1; // +1 multiplying, -1 dividing
    std::size_t i = 0;
    bool expect_term = true;
    bool any_term = false;
    while (i < text.size())
    {
        const char c = text[i];
        if (std::isspace(static_cast<unsigned char>(c)))
        {
            ++i;
            continue;
        }
        // a leading reciprocal: "1/s", "/s"
        if (!any_term && sign > 0 && (c == '/' || (c == '1' && i + 1 < text.size() && text[i + 1] == '/')))
        {
            sign = -1;
            i += c == '/' ? 1 : 2;
            continue;
        }
        if (c == '*' || c == '.')
        {
            if (expect_term)
                break;
            sign = +1;
            expect_term = true;
            ++i;
            continue;
        }
        if (c == '/')
        {
            if (expect_term)
                break;
            sign = -1;
            expect_term = true;
            ++i;
            continue;
        }
        // a symbol: letters, µ, %
        std::size_t j = i;
        while (j < text.size() && (std::isalpha(static_cast<unsigned char>(text[j])) ||
                                   static_cast<unsigned char>(text[j]) >= 0x80 || text[j] == '%'))
            ++j;
        if (j == i)
        {
            if (error)
                *error = "unexpected character '" + std::string(1, c) + "' in unit '" + std::string(text) + "'";
            return std::nullopt;
        }
        const std::string_view symbol = text.substr(i, j - i);
        const UnitEntry* entry = find_symbol(symbol);
        if (!entry)
        {
            if (error)
                *error = "unknown unit '" + std::string(symbol) + "'";
            return std::nullopt;
        }
        int power = 1;
        i = j;
        if (i < text.size() && text[i] == '^')
        {
            ++i;
            const char* begin = text.data() + i;
            const char* end = text.data() + text.size();
            auto [ptr, ec] = std::from_chars(begin, end, power);
            if (ec != std::errc())
            {
                if (error)
                    *error = "bad exponent in unit '" + std::string(text) + "'";
                return std::nullopt;
            }
            i += static_cast<std::size_t>(ptr - begin);
        }
        else if (i < text.size() && (text[i] == '2' || text[i] == '3'))
        {
            power = text[i] - '0'; // "m2", "m3"
            ++i;
        }
        power *= sign;
        any_term = true;
        unit.scale *= std::pow(entry->scale, power);
        unit.dimension = added(unit.dimension, scaled(entry->dimension, power));
        expect_term = false;
        // juxtaposition ("N m") multiplies; a following '/' divides only the next term
        sign = +1;
    }
    if (expect_term)
    {
        if (error)
            *error = "incomplete unit '" + std::string(text) + "'";
        return std::nullopt;
    }
    return unit;
}

Quantity parse_quantity(std::string_view text, Dimension expected)
{
    text = trim(text);
    // leading number
    const char* begin = text.data();
    const char* end = text.data() + text.size();
    real_t number = 0.0;
    auto [ptr, ec] = std::from_chars(begin, end, number);
    if (ec != std::errc() || ptr == begin)
        throw Error("'" + std::string(text) + "' is not a number; expected " + describe(expected));
    if (!std::isfinite(number))
        throw Error("'" + std::string(text) + "' is not finite; expected " + describe(expected));
    const std::string_view rest = trim(std::string_view(ptr, static_cast<std::size_t>(end - ptr)));
    Quantity q;
    if (rest.empty())
    {
        q.value_si = number;
        return q;
    }
    std::string err;
    auto unit = parse_unit(rest, &err);
    if (!unit)
    {
        const std::string known = known_units_for(expected);
        throw Error(err + "; expected " + describe(expected) +
                    (known.empty() ? std::string() : " with a unit such as " + known));
    }
    if (!(unit->dimension == expected))
        throw Error("unit '" + std::string(rest) + "' is " + describe(unit->dimension) + ", not " + describe(expected));
    q.value_si = number * unit->scale;
    q.has_unit = true;
    return q;
}
} // namespace rkfem
