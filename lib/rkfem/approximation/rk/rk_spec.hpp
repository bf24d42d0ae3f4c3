#pragma once
/// @file rk_spec.hpp
/// The settings of an RK part's approximation (deck key `rk`).
#include <string>

#include "rkfem/core/input_error.hpp"
#include "rkfem/core/types.hpp"

namespace rkfem
{
/// RK approximation of `rkpm` parts.
struct RkSpec
{
    int order = 1;
    std::string kernel = "cubic-bspline"; ///< cubic-bspline | quintic-bspline | gaussian
    std::string support = "box";          ///< box | sphere
    real_t normalized_support = 1.51;     ///< a / h, h = longest incident mesh edge
    /// Smoothed-gradient stencils drop the functions below this fraction of the largest at each
    /// facet point (RkShapes, prune_rk_values; order 1 only): 0 keeps them all
    real_t drop_tolerance = 1e-5;
    /// The set-up evaluates the RK functions once for elements and particles whose
    /// neighbourhoods are translates of each other (approximation/rk/rk_translates.hpp) and
    /// copies the results to the rest; false evaluates every one (the same numbers to round-off)
    bool share_translates = true;
    SourceLocation loc;
};
} // namespace rkfem
