#pragma once
/// @file elastic.hpp
/// Linear (hypo)elastic material with the Jaumann objective stress rate: a pointwise value type.
/// The update is rate form: sigma_new = sigma + dt (W sigma - sigma W) + dt (lambda tr(D) I + 2 mu D),
/// so the same material serves Gauss points and nodal integration points.
#include <cmath>

#include "rkfem/core/types.hpp"

namespace rkfem
{
struct ElasticParams
{
    real_t rho = 0.0;    ///< reference density [kg/m^3]
    real_t lambda = 0.0; ///< Lame's first parameter [Pa]
    real_t mu = 0.0;     ///< shear modulus [Pa]

    static ElasticParams from_E_nu(real_t rho, real_t E, real_t nu)
    {
        ElasticParams p;
        p.rho = rho;
        p.lambda = E * nu / ((1 + nu) * (1 - 2 * nu));
        p.mu = E / (2 * (1 + nu));
        return p;
    }
    real_t bulk_modulus() const { return lambda + 2.0 * mu / 3.0; }
    real_t plane_wave_modulus() const { return lambda + 2.0 * mu; }
    /// Dilatational wave speed sqrt((lambda + 2 mu) / rho) [m/s].
    real_t wave_speed() const { return std::sqrt(plane_wave_modulus() / rho); }
};

/// Elastic update of one point. `s` is Voigt stress (xx yy zz xy yz zx) updated in place;
/// d is the rate of deformation (Voigt, tensor shear components); w = (W_xy, W_yz, W_zx) are the
/// independent spin components, W = (L - L^T)/2.
inline void elastic_update(const ElasticParams& p, const real_t d[6], const real_t w[3], real_t dt,
                           real_t s[6])
{
    // Jaumann rotation term R = W s - s W for symmetric s and skew W.
    const real_t wxy = w[0], wyz = w[1], wzx = w[2];
    // W = [[0, wxy, -wzx], [-wxy, 0, wyz], [wzx, -wyz, 0]]
    const real_t sxx = s[0], syy = s[1], szz = s[2], sxy = s[3], syz = s[4], szx = s[5];
    const real_t rxx = 2.0 * (wxy * sxy - wzx * szx);
    const real_t ryy = 2.0 * (-wxy * sxy + wyz * syz);
    const real_t rzz = 2.0 * (wzx * szx - wyz * syz);
    const real_t rxy = wxy * (syy - sxx) + wyz * szx - wzx * syz;
    const real_t ryz = wyz * (szz - syy) - wxy * szx + wzx * sxy;
    const real_t rzx = wzx * (sxx - szz) + wxy * syz - wyz * sxy;
    const real_t tr = d[0] + d[1] + d[2];
    const real_t l = p.lambda * tr;
    const real_t m2 = 2.0 * p.mu;
    s[0] = sxx + dt * (rxx + l + m2 * d[0]);
    s[1] = syy + dt * (ryy + l + m2 * d[1]);
    s[2] = szz + dt * (rzz + l + m2 * d[2]);
    s[3] = sxy + dt * (rxy + m2 * d[3]);
    s[4] = syz + dt * (ryz + m2 * d[4]);
    s[5] = szx + dt * (rzx + m2 * d[5]);
}
} // namespace rkfem
