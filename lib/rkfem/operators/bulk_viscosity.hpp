#pragma once
/// @file bulk_viscosity.hpp
/// Bulk viscosity and the stable time step of an element or stress point, shared by the hex and
/// nodal kernels. T is real_t or a lane vector (simd::dvec) of simd::kLanes points. Both are
/// written without branches (min and a select instead of "trD < 0 ? ... : 0") so that the
/// kernels' lane loops vectorize: GCC keeps a conditional floating-point expression as control
/// flow.
#include <cmath>

#include "rkfem/core/simd.hpp"
#include "rkfem/core/types.hpp"

namespace rkfem
{
/// The bulk viscosity coefficients of a part (deck key `bulk_viscosity`).
struct BulkViscositySpec
{
    real_t linear = 0.06;   ///< Q2 (LS-DYNA), multiplies rho c l |tr D|
    real_t quadratic = 1.5; ///< Q1 (LS-DYNA), multiplies rho l^2 (tr D)^2
};

/// Bulk viscosity pressure (LS-DYNA form): q = rho l (Q1 l trD^2 - Q2 c trD) when trD < 0.
template <class T> inline T bulk_q(T rho, real_t c, T l, T trd, real_t q1, real_t q2)
{
    const T neg = simd::min(trd, T{});
    return rho * l * (q1 * l * neg * neg - q2 * c * neg);
}

namespace detail
{
/// Q + sqrt(Q^2 + c^2), Q = Q1 l |trD| + Q2 c when trD < 0 (else 0)
template <class T> inline T dt_denominator(real_t c, T l, T trd, real_t q1, real_t q2)
{
    const T neg = simd::min(trd, T{});
    const T Q = -q1 * l * neg + simd::where_negative(trd, simd::lanes_like<T>(q2 * c));
    return Q + simd::sqrt(Q * Q + c * c);
}
} // namespace detail

/// Stable time step: l / (Q + sqrt(Q^2 + c^2)), Q = Q1 l |trD| + Q2 c when trD < 0.
template <class T> inline T element_dt(real_t c, T l, T trd, real_t q1, real_t q2)
{
    return l / detail::dt_denominator(c, l, trd, q1, q2);
}

/// 1 / element_dt from l and 1/l: no division (the element kernels keep the largest inverse and
/// divide once per batch).
template <class T> inline T element_dt_inverse(real_t c, T l, T inv_l, T trd, real_t q1, real_t q2)
{
    return detail::dt_denominator(c, l, trd, q1, q2) * inv_l;
}
} // namespace rkfem
