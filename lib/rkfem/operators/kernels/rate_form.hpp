#pragma once
/// @file rate_form.hpp
/// The velocity gradient's parts in the Voigt order the materials take, and the stress power
/// over a step, for the plain point-by-point passes (nodal_reference.cpp, the semi-Lagrangian
/// block's passes).
#include "rkfem/core/types.hpp"

namespace rkfem
{
/// sym and skew parts of L (d: xx yy zz xy yz zx; w: xy yz zx).
inline void split_rate(const Mat3& L, real_t d[6], real_t w[3])
{
    d[0] = L(0, 0), d[1] = L(1, 1), d[2] = L(2, 2);
    d[3] = 0.5 * (L(0, 1) + L(1, 0)), d[4] = 0.5 * (L(1, 2) + L(2, 1)), d[5] = 0.5 * (L(2, 0) + L(0, 2));
    w[0] = 0.5 * (L(0, 1) - L(1, 0)), w[1] = 0.5 * (L(1, 2) - L(2, 1)), w[2] = 0.5 * (L(2, 0) - L(0, 2));
}

/// (sigma_old + sigma_new) / 2 : d, with d's shear entries the tensor's (Voigt's halves).
inline real_t stress_power(const real_t s_old[6], const real_t s_new[6], const real_t d[6])
{
    real_t power = 0.0;
    for (int k = 0; k < 6; ++k)
        power += (k < 3 ? 0.5 : 1.0) * (s_old[k] + s_new[k]) * d[k];
    return power;
}
} // namespace rkfem
