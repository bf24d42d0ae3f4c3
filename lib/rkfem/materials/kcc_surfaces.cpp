#include "rkfem/materials/kcc_surfaces.hpp"

#include <algorithm>
#include <cmath>

#include "rkfem/core/error.hpp"

namespace rkfem
{
namespace
{
constexpr real_t MPa = 1e6;
constexpr real_t psi_pa = 6894.757293168361; // Pa per psi

/// Linear interpolation through (x, y) points with increasing x, constant beyond the ends.
real_t piecewise_linear(const std::pair<real_t, real_t>* pts, std::size_t n, real_t x)
{
    if (x <= pts[0].first)
        return pts[0].second;
    for (std::size_t i = 1; i < n; ++i)
        if (x <= pts[i].first)
            return pts[i - 1].second +
                   (x - pts[i - 1].first) / (pts[i].first - pts[i - 1].first) * (pts[i].second - pts[i - 1].second);
    return pts[n - 1].second;
}
} // namespace

KccParameters KccParameters::from_fc(real_t fc_pa)
{
    RKFEM_REQUIRE(fc_pa > 0, "K&C concrete: f'c must be positive, got " << fc_pa << " Pa");
    KccParameters k;
    k.fc = fc_pa;
    const real_t fc_psi = fc_pa / psi_pa;
    k.ft = 1.58 * std::cbrt(fc_psi * fc_psi) * psi_pa;
    k.a0 = 0.29559 * fc_pa;
    k.a1 = 0.4463;
    k.a2 = 0.08081 / fc_pa;
    k.a0y = 0.22313 * fc_pa;
    k.a1y = 0.625;
    k.a2y = 0.25769 / fc_pa;
    k.a1f = 0.4417;
    k.a2f = 0.1184 / fc_pa;
    k.eta_table = {{0, 0},         {8.0e-6, 0.85}, {2.4e-5, 0.97}, {4.0e-5, 0.99}, {5.6e-5, 1.00},
                   {7.2e-5, 0.99}, {8.8e-5, 0.97}, {3.2e-4, 0.50}, {5.2e-4, 0.10}, {5.7e-4, 0},
                   {1.0, 0},       {10.0, 0},      {1.0e10, 0}};
    k.update_derived();
    return k;
}

void KccParameters::update_derived()
{
    // lambda_m: first lambda where eta = 1; lambda_z: first lambda after it where eta = 0
    for (std::size_t i = 0; i < eta_table.size(); ++i)
        if (eta_table[i].second == 1.0)
        {
            lambda_m = eta_table[i].first;
            lambda_z = eta_table.back().first;
            for (std::size_t j = i + 1; j < eta_table.size(); ++j)
                if (eta_table[j].second == 0.0)
                {
                    lambda_z = eta_table[j].first;
                    break;
                }
            break;
        }
    // f_yc solves s = a0y + (s/3) / (a1y + a2y s/3) (a contraction: fixed-point iteration)
    fyc = a0y;
    for (int it = 0; it < 200; ++it)
        fyc = a0y + (fyc / 3.0) / (a1y + a2y * fyc / 3.0);
    const real_t pb = 2.0 * alpha_biaxial * fc / 3.0;
    psi_biaxial = alpha_biaxial * fc / max_surface(pb);
}

real_t KccParameters::max_surface(real_t p) const
{
    if (p >= fc / 3.0)
        return a0 + p / (a1 + a2 * p);
    if (p < 0.0)
        return std::max(0.0, 3.0 * (p + ft));
    // 0 <= p < f'c/3: reading (a) of section 1.2, psi linear from 1/2 at p = 0 to
    // 1/2 + 1.5 f_t/f'c at p = f'c/3 (the public MATLAB script's choice) [U]
    const real_t psi_lin = 0.5 + 1.5 * ft / fc * (p / (fc / 3.0));
    return 3.0 * (p + ft) / (2.0 * psi_lin);
}

real_t KccParameters::yield_surface(real_t p) const
{
    if (p >= fyc / 3.0)
        return a0y + p / (a1y + a2y * p);
    if (p < 0.0)
        return std::max(0.0, 1.35 * (p + ft));
    return 1.35 * ft + 3.0 * p * (1.0 - 1.35 * ft / fyc); // [C script; U as LS-DYNA-exact]
}

real_t KccParameters::residual_surface(real_t p) const
{
    return p <= 0.0 ? 0.0 : p / (a1f + a2f * p);
}

real_t KccParameters::psi(real_t p) const
{
    const real_t pb = 2.0 * alpha_biaxial * fc / 3.0;
    const std::array<std::pair<real_t, real_t>, 5> pts = {
        {{0.0, 0.5}, {fc / 3.0, 0.5 + 1.5 * ft / fc}, {pb, psi_biaxial}, {3.0 * fc, 0.753}, {8.45 * fc, 1.0}}};
    return piecewise_linear(pts.data(), pts.size(), p);
}

real_t KccParameters::eta(real_t lambda) const
{
    return piecewise_linear(eta_table.data(), eta_table.size(), lambda);
}

real_t cos_third_acos(real_t c3)
{
    // f(s) = cos(2/3 acos s) on s in [0, 1] as a polynomial of degree 18 in x = 2 s - 1: the
    // Chebyshev interpolant at the 19 Chebyshev points (to 60 digits) in monomial form, within
    // 2.3e-16 of f (verification/materials/test_kcc_surfaces.cpp holds it to cos(acos(c3) / 3)
    // over [-1, 1]); evaluated by Estrin's scheme, whose chain is 9 operations deep where Horner's
    // or Clenshaw's is 18 (the point update waits on it)
    static constexpr real_t m[19] = {
        0.766044443118978,       0.2474090663228534,     -0.015509188436485936,   0.0024663528150656285,
        -0.0005041246911381233,  0.00011642545331824931, -2.891993630551945e-05,  7.541075563453027e-06,
        -2.0358696650818406e-06, 5.641643328528482e-07,  -1.5954336266674776e-07, 4.5826322066904776e-08,
        -1.334861626366851e-08,  3.982036064644077e-09,  -1.1846250703174136e-09, 3.093616173100703e-10,
        -9.309326514430476e-11,  5.11466452650849e-11,   -1.5686102744613355e-11};
    const real_t s = std::sqrt(0.5 * (1.0 + std::clamp(c3, -1.0, 1.0)));
    const real_t x = 2.0 * s - 1.0, x2 = x * x, x4 = x2 * x2, x8 = x4 * x4, x16 = x8 * x8;
    real_t p[10];
    for (int k = 0; k < 9; ++k)
        p[k] = std::fma(m[2 * k + 1], x, m[2 * k]);
    p[9] = m[18];
    const real_t q0 = std::fma(p[1], x2, p[0]), q1 = std::fma(p[3], x2, p[2]), q2 = std::fma(p[5], x2, p[4]);
    const real_t q3 = std::fma(p[7], x2, p[6]), q4 = std::fma(p[9], x2, p[8]);
    const real_t r0 = std::fma(q1, x4, q0), r1 = std::fma(q3, x4, q2);
    return std::fma(q4, x16, std::fma(r1, x8, r0));
}

real_t willam_warnke(real_t theta, real_t psi)
{
    return willam_warnke_cos(std::cos(theta), psi);
}

real_t willam_warnke_cos(real_t c, real_t psi)
{
    psi = std::clamp(psi, 0.5, 1.0);
    const real_t q = 1.0 - psi * psi;
    const real_t num = 2.0 * q * c + (2.0 * psi - 1.0) * std::sqrt(4.0 * q * c * c + 5.0 * psi * psi - 4.0 * psi);
    const real_t den = 4.0 * q * c * c + (1.0 - 2.0 * psi) * (1.0 - 2.0 * psi);
    return num / den;
}

} // namespace rkfem
