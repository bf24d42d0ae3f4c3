#pragma once
/// @file objective_rate.hpp
/// The rotation part of the Jaumann rate integrated by the Hughes-Winget rule:
///   sigma <- R sigma R^T,  R = (1 - dt/2 W)^-1 (1 + dt/2 W),
/// which is exactly orthogonal, so a rigid rotation leaves the stress invariants unchanged to
/// round-off (the additive update sigma + dt (W sigma - sigma W) drifts by O(dt^2) per step).
/// Voigt order xx yy zz xy yz zx; w = (W_xy, W_yz, W_zx), W = (L - L^T)/2.
#include "rkfem/core/types.hpp"

namespace rkfem
{
/// The rotation on six scalars (the element kernels' lane loops vectorize over this form; the
/// array form below calls it).
inline void rotate_stress(real_t w0, real_t w1, real_t w2, real_t dt, real_t& s0, real_t& s1, real_t& s2, real_t& s3,
                          real_t& s4, real_t& s5)
{
    const real_t h = 0.5 * dt;
    const real_t a = h * w0, b = h * w1, c = h * w2; // half-step spin: xy, yz, zx
    // A = h W = [[0, a, -c], [-a, 0, b], [c, -b, 0]]; Cayley transform of a skew matrix:
    // R = (1 - A)^-1 (1 + A) = 1 + k (A + A^2), k = 2 / (1 + a^2 + b^2 + c^2).
    const real_t k = 2.0 / (1.0 + a * a + b * b + c * c);
    // A^2 (symmetric): [[-a2-c2, bc, ab], [bc, -a2-b2, ac], [ab, ac, -b2-c2]]
    const real_t r00 = 1.0 + k * (-a * a - c * c), r11 = 1.0 + k * (-a * a - b * b), r22 = 1.0 + k * (-b * b - c * c);
    const real_t r01 = k * (a + b * c), r10 = k * (-a + b * c);
    const real_t r02 = k * (-c + a * b), r20 = k * (c + a * b);
    const real_t r12 = k * (b + a * c), r21 = k * (-b + a * c);
    const real_t s00 = s0, s11 = s1, s22 = s2, s01 = s3, s12 = s4, s20 = s5;
    // T = R S
    const real_t t00 = r00 * s00 + r01 * s01 + r02 * s20, t01 = r00 * s01 + r01 * s11 + r02 * s12,
                 t02 = r00 * s20 + r01 * s12 + r02 * s22;
    const real_t t10 = r10 * s00 + r11 * s01 + r12 * s20, t11 = r10 * s01 + r11 * s11 + r12 * s12,
                 t12 = r10 * s20 + r11 * s12 + r12 * s22;
    const real_t t20 = r20 * s00 + r21 * s01 + r22 * s20, t21 = r20 * s01 + r21 * s11 + r22 * s12,
                 t22 = r20 * s20 + r21 * s12 + r22 * s22;
    // S' = T R^T
    s0 = t00 * r00 + t01 * r01 + t02 * r02;
    s1 = t10 * r10 + t11 * r11 + t12 * r12;
    s2 = t20 * r20 + t21 * r21 + t22 * r22;
    s3 = t00 * r10 + t01 * r11 + t02 * r12;
    s4 = t10 * r20 + t11 * r21 + t12 * r22;
    s5 = t20 * r00 + t21 * r01 + t22 * r02;
}

inline void rotate_stress(const real_t w[3], real_t dt, real_t s[6])
{
    rotate_stress(w[0], w[1], w[2], dt, s[0], s[1], s[2], s[3], s[4], s[5]);
}
} // namespace rkfem
