#pragma once
/// @file eos.hpp
/// Equations of state for the pressure of a material point as a function of the compression
/// mu = rho / rho0 - 1 and the internal energy per reference volume E [J/m^3]:
///   linear     p = K mu_v, with mu_v = -ln(V/V0) (the small-strain bulk response);
///   gruneisen  (LS-DYNA EOS_GRUNEISEN with S2 = S3 = 0) in compression
///              p = rho0 C^2 mu [1 + (1 - g0/2) mu - a/2 mu^2] / [1 - (S - 1) mu]^2 + (g0 + a mu) E,
///              in tension p = rho0 C^2 mu + (g0 + a mu) E.
/// The tabulated-compaction EOS of concrete lives with the K&C model (kcc_concrete.hpp).
#include <cmath>

#include "rkfem/core/types.hpp"

namespace rkfem
{
struct Eos
{
    enum class Kind
    {
        None, ///< the material's own incremental bulk response
        Linear,
        Gruneisen,
    };
    Kind kind = Kind::None;
    real_t rho0 = 0.0;
    real_t bulk = 0.0;                               ///< linear: K [Pa]
    real_t c0 = 0.0, s = 0.0, gamma0 = 0.0, a = 0.0; ///< gruneisen

    /// Pressure (compression positive) at volumetric strain ev = ln(V/V0) and energy e [J/m^3].
    real_t pressure(real_t ev, real_t e) const
    {
        if (kind == Kind::Linear)
            return -bulk * ev;
        const real_t mu = std::exp(-ev) - 1.0;
        const real_t k0 = rho0 * c0 * c0;
        if (mu <= 0.0)
            return k0 * mu + (gamma0 + a * mu) * e;
        const real_t den = 1.0 - (s - 1.0) * mu;
        return k0 * mu * (1.0 + (1.0 - 0.5 * gamma0) * mu - 0.5 * a * mu * mu) / (den * den) + (gamma0 + a * mu) * e;
    }
};
} // namespace rkfem
