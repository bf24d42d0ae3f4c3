#pragma once
/// @file objective_rate.hpp
/// The rotation part of the Jaumann rate integrated by the Hughes-Winget rule:
///   sigma <- R sigma R^T,  R = (1 - dt/2 W)^-1 (1 + dt/2 W),
/// which is exactly orthogonal, so a rigid rotation leaves the stress invariants unchanged to
/// round-off (the additive update sigma + dt (W sigma - sigma W) drifts by O(dt^2) per step).
/// Voigt order xx yy zz xy yz zx; w = (W_xy, W_yz, W_zx), W = (L - L^T)/2.
#include "rkfem/core/simd.hpp"
#include "rkfem/core/types.hpp"

namespace rkfem
{
/// The Hughes-Winget rotation R of a step (row-major entries), for points that share a spin (a
/// particle's NSNI sub-points): formed once, each stress rotated by it. rotate_stress(w, ...)
/// below is these two parts called in turn, so a stress rotated from the spin and one rotated by
/// the shared R are the same bits (ObjectiveRate.HughesWingetRotationIsOrthogonalAndSharedOnce).
/// Until 2026-12-08 rotate_stress(w, ...) had a body of its own with the same expressions, which
/// GCC contracts into FMAs per inlined context and per CPU (-march=native): built on that day's
/// machine, the two forms differed in the last bits (the test failed at HEAD c5b6b52 there).
template <class T> struct Rotation
{
    T r00, r01, r02, r10, r11, r12, r20, r21, r22;
};

/// R = (1 - dt/2 W)^-1 (1 + dt/2 W) for the spin w = (W_xy, W_yz, W_zx).
/// T is real_t or a lane vector (simd::dvec) of simd::kLanes points.
template <class T> inline Rotation<T> hughes_winget(T w0, T w1, T w2, real_t dt)
{
    using simd::mul_add;
    using simd::neg_mul_add;
    const real_t h = 0.5 * dt;
    const T a = h * w0, b = h * w1, c = h * w2; // half-step spin: xy, yz, zx
    // A = h W = [[0, a, -c], [-a, 0, b], [c, -b, 0]]; Cayley transform of a skew matrix:
    // R = (1 - A)^-1 (1 + A) = 1 + k (A + A^2), k = 2 / (1 + a^2 + b^2 + c^2).
    // (mul_add(x, y, z) is x y + z: fused on lane vectors, in this order unfused on scalars)
    const T k = 2.0 / mul_add(c, c, mul_add(b, b, mul_add(a, a, 1.0)));
    // A^2 (symmetric): [[-a2-c2, bc, ab], [bc, -a2-b2, ac], [ab, ac, -b2-c2]]
    Rotation<T> R;
    R.r00 = mul_add(k, neg_mul_add(c, c, -(a * a)), 1.0);
    R.r11 = mul_add(k, neg_mul_add(b, b, -(a * a)), 1.0);
    R.r22 = mul_add(k, neg_mul_add(c, c, -(b * b)), 1.0);
    R.r01 = k * mul_add(b, c, a);
    R.r10 = k * mul_add(b, c, -a);
    R.r02 = k * mul_add(a, b, -c);
    R.r20 = k * mul_add(a, b, c);
    R.r12 = k * mul_add(a, c, b);
    R.r21 = k * mul_add(a, c, -b);
    return R;
}

/// sigma <- R sigma R^T on six scalars (Voigt order).
template <class T> inline void rotate_stress(const Rotation<T>& R, T& s0, T& s1, T& s2, T& s3, T& s4, T& s5)
{
    using simd::mul_add;
    const T s00 = s0, s11 = s1, s22 = s2, s01 = s3, s12 = s4, s20 = s5;
    // T = R S, row . column as x0 y0 + x1 y1 + x2 y2 left to right
    auto dot = [](T x0, T y0, T x1, T y1, T x2, T y2) { return mul_add(x2, y2, mul_add(x1, y1, x0 * y0)); };
    const T t00 = dot(R.r00, s00, R.r01, s01, R.r02, s20), t01 = dot(R.r00, s01, R.r01, s11, R.r02, s12),
            t02 = dot(R.r00, s20, R.r01, s12, R.r02, s22);
    const T t10 = dot(R.r10, s00, R.r11, s01, R.r12, s20), t11 = dot(R.r10, s01, R.r11, s11, R.r12, s12),
            t12 = dot(R.r10, s20, R.r11, s12, R.r12, s22);
    const T t20 = dot(R.r20, s00, R.r21, s01, R.r22, s20), t21 = dot(R.r20, s01, R.r21, s11, R.r22, s12),
            t22 = dot(R.r20, s20, R.r21, s12, R.r22, s22);
    // S' = T R^T
    s0 = dot(t00, R.r00, t01, R.r01, t02, R.r02);
    s1 = dot(t10, R.r10, t11, R.r11, t12, R.r12);
    s2 = dot(t20, R.r20, t21, R.r21, t22, R.r22);
    s3 = dot(t00, R.r10, t01, R.r11, t02, R.r12);
    s4 = dot(t10, R.r20, t11, R.r21, t12, R.r22);
    s5 = dot(t20, R.r00, t21, R.r01, t22, R.r02);
}

/// The rotation on six scalars (the element kernels' lane loops vectorize over this form; the
/// array form below calls it). T is real_t or a lane vector (simd::dvec) of simd::kLanes points.
template <class T> inline void rotate_stress(T w0, T w1, T w2, real_t dt, T& s0, T& s1, T& s2, T& s3, T& s4, T& s5)
{
    rotate_stress(hughes_winget(w0, w1, w2, dt), s0, s1, s2, s3, s4, s5);
}

inline void rotate_stress(const real_t w[3], real_t dt, real_t s[6])
{
    rotate_stress(w[0], w[1], w[2], dt, s[0], s[1], s[2], s[3], s[4], s[5]);
}
} // namespace rkfem
