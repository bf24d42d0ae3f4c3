#pragma once
/// @file elastic.hpp
/// Linear (hypo)elastic material with the Jaumann objective stress rate: a pointwise value type.
/// The update is rate form: sigma_new = R sigma R^T + dt (lambda tr(D) I + 2 mu D) with the
/// Hughes-Winget rotation R, so the same material serves Gauss points and nodal integration points.
#include <cmath>

#include "rkfem/core/types.hpp"
#include "rkfem/materials/objective_rate.hpp"

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

/// s += dt (lambda tr(d) 1 + 2 mu d), the elastic increment after the rotation.
template <class T>
inline void add_elastic_increment(const ElasticParams& p, T d0, T d1, T d2, T d3, T d4, T d5, real_t dt, T& s0, T& s1,
                                  T& s2, T& s3, T& s4, T& s5)
{
    const T l = p.lambda * (d0 + d1 + d2);
    const real_t m2 = 2.0 * p.mu;
    // s += dt (l + m2 d), s += (dt m2) d: fused on lane vectors (simd::mul_add)
    s0 = simd::mul_add(dt, simd::mul_add(m2, d0, l), s0);
    s1 = simd::mul_add(dt, simd::mul_add(m2, d1, l), s1);
    s2 = simd::mul_add(dt, simd::mul_add(m2, d2, l), s2);
    s3 = simd::mul_add(dt * m2, d3, s3);
    s4 = simd::mul_add(dt * m2, d4, s4);
    s5 = simd::mul_add(dt * m2, d5, s5);
}

/// Elastic update of one point. `s` is Voigt stress (xx yy zz xy yz zx) updated in place;
/// d is the rate of deformation (Voigt, tensor shear components); w = (W_xy, W_yz, W_zx) are the
/// independent spin components, W = (L - L^T)/2. The Jaumann rotation is integrated by the
/// Hughes-Winget rule (objective_rate.hpp), then the elastic increment is added.
/// The update on scalars (the element kernels' lane loops vectorize over this form).
/// T is real_t or a lane vector (simd::dvec).
template <class T>
inline void elastic_update(const ElasticParams& p, T d0, T d1, T d2, T d3, T d4, T d5, T w0, T w1, T w2, real_t dt,
                           T& s0, T& s1, T& s2, T& s3, T& s4, T& s5)
{
    rotate_stress(w0, w1, w2, dt, s0, s1, s2, s3, s4, s5);
    add_elastic_increment(p, d0, d1, d2, d3, d4, d5, dt, s0, s1, s2, s3, s4, s5);
}

/// The same with the step's rotation formed already (hughes_winget: points that share a spin).
template <class T>
inline void elastic_update(const ElasticParams& p, T d0, T d1, T d2, T d3, T d4, T d5, const Rotation<T>& R, real_t dt,
                           T& s0, T& s1, T& s2, T& s3, T& s4, T& s5)
{
    rotate_stress(R, s0, s1, s2, s3, s4, s5);
    add_elastic_increment(p, d0, d1, d2, d3, d4, d5, dt, s0, s1, s2, s3, s4, s5);
}

inline void elastic_update(const ElasticParams& p, const real_t d[6], const real_t w[3], real_t dt, real_t s[6])
{
    elastic_update(p, d[0], d[1], d[2], d[3], d[4], d[5], w[0], w[1], w[2], dt, s[0], s[1], s[2], s[3], s[4], s[5]);
}
} // namespace rkfem
