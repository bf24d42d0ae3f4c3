#pragma once
/// @file kernel.hpp
/// Reproducing-kernel window functions phi(z), z = r / a, with phi(z) = 0 for z >= 1, and the
/// kernel of a particle with box (tensor-product) or spherical support.
/// Formulas: Liu, Jun & Zhang 1995, IJNMF 20; RKPM2D, Huang, Wei, Chen & Hillman 2020, Comp Part
/// Mech 7 (cubic B-spline phi(0) = 2/3, quintic B-spline phi(0) = 1, truncated Gaussian with beta = 0.4).
#include <cmath>

#include "rkfem/core/types.hpp"

namespace rkfem
{
enum class KernelType
{
    CubicBSpline,   ///< C2, default
    QuinticBSpline, ///< C4
    Gaussian,       ///< truncated Gaussian, C0 at the support edge, beta = 0.4
};

enum class SupportShape
{
    Box,    ///< phi(|dx|/a) phi(|dy|/a) phi(|dz|/a)
    Sphere, ///< phi(|dx|/a)
};

/// phi(z) and phi'(z) for z >= 0.
inline void kernel_1d(KernelType type, real_t z, real_t& phi, real_t& dphi)
{
    if (z >= 1.0)
    {
        phi = dphi = 0.0;
        return;
    }
    switch (type)
    {
    case KernelType::CubicBSpline:
        if (z <= 0.5)
        {
            phi = 2.0 / 3.0 - 4.0 * z * z + 4.0 * z * z * z;
            dphi = -8.0 * z + 12.0 * z * z;
        }
        else
        {
            const real_t t = 1.0 - z;
            phi = 4.0 / 3.0 * t * t * t;
            dphi = -4.0 * t * t;
        }
        return;
    case KernelType::QuinticBSpline:
    {
        if (z <= 1.0 / 3.0)
        {
            const real_t z2 = z * z, z3 = z2 * z, z4 = z3 * z, z5 = z4 * z;
            phi = 1.0 - 90.0 / 11.0 * z2 + 405.0 / 11.0 * z4 - 405.0 / 11.0 * z5;
            dphi = -180.0 / 11.0 * z + 1620.0 / 11.0 * z3 - 2025.0 / 11.0 * z4;
        }
        else if (z <= 2.0 / 3.0)
        {
            const real_t z2 = z * z, z3 = z2 * z, z4 = z3 * z, z5 = z4 * z;
            phi = 17.0 / 22.0 + 75.0 / 22.0 * z - 315.0 / 11.0 * z2 + 675.0 / 11.0 * z3 - 1215.0 / 22.0 * z4 +
                  405.0 / 22.0 * z5;
            dphi = 75.0 / 22.0 - 630.0 / 11.0 * z + 2025.0 / 11.0 * z2 - 2430.0 / 11.0 * z3 + 2025.0 / 22.0 * z4;
        }
        else
        {
            const real_t t = 1.0 - z, t2 = t * t;
            phi = 81.0 / 22.0 * t2 * t2 * t;
            dphi = -405.0 / 22.0 * t2 * t2;
        }
        return;
    }
    case KernelType::Gaussian:
    {
        constexpr real_t beta = 0.4;
        const real_t e1 = std::exp(-1.0 / (beta * beta));
        const real_t ez = std::exp(-(z * z) / (beta * beta));
        phi = (ez - e1) / (1.0 - e1);
        dphi = -2.0 * z / (beta * beta) * ez / (1.0 - e1);
        return;
    }
    }
}

/// Kernel value and gradient with respect to x of a particle at xi with support radius a,
/// evaluated at x (dx = x - xi). Returns false (phi = 0, grad = 0) outside the support.
inline bool kernel_3d(KernelType type, SupportShape shape, const Vec3& dx, real_t a, real_t& phi, Vec3& grad)
{
    const real_t inv_a = 1.0 / a;
    if (shape == SupportShape::Box)
    {
        real_t p[3] = {}, dp[3] = {};
        for (int k = 0; k < 3; ++k)
        {
            const real_t z = std::abs(dx[k]) * inv_a;
            if (z >= 1.0)
            {
                phi = 0.0;
                grad.setZero();
                return false;
            }
            kernel_1d(type, z, p[k], dp[k]);
            dp[k] *= (dx[k] < 0 ? -inv_a : inv_a);
        }
        phi = p[0] * p[1] * p[2];
        grad = Vec3(dp[0] * p[1] * p[2], p[0] * dp[1] * p[2], p[0] * p[1] * dp[2]);
        return true;
    }
    const real_t r = dx.norm();
    const real_t z = r * inv_a;
    if (z >= 1.0)
    {
        phi = 0.0;
        grad.setZero();
        return false;
    }
    real_t dphi = 0.0;
    kernel_1d(type, z, phi, dphi);
    // d phi / dx = phi'(z) dx / (a r); phi'(0) = 0 for every kernel here
    grad = r > 0.0 ? Vec3(dphi * inv_a / r * dx) : Vec3::Zero();
    return true;
}
} // namespace rkfem
