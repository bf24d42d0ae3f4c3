#pragma once
/// @file offsets_hash.hpp
/// The key by which shared stencils (integration/stencil_table.hpp) and the kinematic map's
/// shared rows (approximation/rk/kinematic_map.hpp) find their translates: FNV-1a over a list's
/// length and its entries' offsets from the first.
#include <cstdint>

#include "rkfem/core/types.hpp"

namespace rkfem
{
inline std::uint64_t offsets_hash(const index_t* ids, index_t size)
{
    std::uint64_t h = 1469598103934665603ull;
    auto mix = [&](std::uint32_t x)
    {
        h ^= x;
        h *= 1099511628211ull;
    };
    mix(static_cast<std::uint32_t>(size));
    for (index_t k = 1; k < size; ++k)
        mix(static_cast<std::uint32_t>(ids[k] - ids[0]));
    return h;
}
} // namespace rkfem
