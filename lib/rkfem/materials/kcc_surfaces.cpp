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

real_t willam_warnke(real_t theta, real_t psi)
{
    psi = std::clamp(psi, 0.5, 1.0);
    const real_t c = std::cos(theta);
    const real_t q = 1.0 - psi * psi;
    const real_t num = 2.0 * q * c + (2.0 * psi - 1.0) * std::sqrt(4.0 * q * c * c + 5.0 * psi * psi - 4.0 * psi);
    const real_t den = 4.0 * q * c * c + (1.0 - 2.0 * psi) * (1.0 - 2.0 * psi);
    return num / den;
}

} // namespace rkfem
