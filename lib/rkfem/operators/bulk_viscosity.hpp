#pragma once
/// @file bulk_viscosity.hpp
/// Bulk viscosity and the stable time step of an element or stress point, shared by the hex and
/// nodal kernels. Both are written without branches (min and a 0/1 factor instead of
/// "trD < 0 ? ... : 0") so that the kernels' lane loops vectorize: GCC keeps a conditional
/// floating-point expression as control flow.
#include <algorithm>
#include <cmath>

#include "rkfem/core/types.hpp"

namespace rkfem
{
/// Bulk viscosity pressure (LS-DYNA form): q = rho l (Q1 l trD^2 - Q2 c trD) when trD < 0.
inline real_t bulk_q(real_t rho, real_t c, real_t l, real_t trd, real_t q1, real_t q2)
{
    const real_t neg = std::min(trd, 0.0);
    return rho * l * (q1 * l * neg * neg - q2 * c * neg);
}

/// Stable time step: l / (Q + sqrt(Q^2 + c^2)), Q = Q1 l |trD| + Q2 c when trD < 0.
inline real_t element_dt(real_t c, real_t l, real_t trd, real_t q1, real_t q2)
{
    const real_t neg = std::min(trd, 0.0);
    const real_t Q = -q1 * l * neg + q2 * c * static_cast<real_t>(trd < 0.0);
    return l / (Q + std::sqrt(Q * Q + c * c));
}
} // namespace rkfem
