#pragma once
/// @file kcc_surfaces.hpp
/// K&C concrete model, Release III (LS-DYNA MAT_072R3 analog): the parameter set generated from
/// f'c alone, the three fixed surfaces with their low-pressure branches, the Willam-Warnke Lode
/// dependence psi(p), the damage table eta(lambda) and the scaled damage delta (the strain-rate
/// dynamic increase factors: rate_law.hpp). Formulas and default tables: Malvar, Crawford, Wesevich &
/// Simons 1997 (IJIE 19); Malvar, Crawford & Morrill 2000 (K&C TR-99-24-B1, generation from f'c);
/// Schwer & Malvar 2005 (LS-DYNA User Week); LS-DYNA Keyword Manual Vol II, MAT_072R3. [K] marks a
/// known published result, [U] a choice where these sources are uncertain. Pressures and strengths
/// in Pa (compression positive for p and for the surfaces' stress difference Delta sigma).
/// The stress update that uses these pieces is not part of this file.
#include <array>
#include <cmath>
#include <utility>
#include <vector>

#include "rkfem/core/types.hpp"

namespace rkfem
{
struct KccParameters
{
    real_t fc = 0.0;                  ///< unconfined compressive strength f'c [Pa]
    real_t ft = 0.0;                  ///< tensile strength f_t [Pa]
    real_t a0 = 0, a1 = 0, a2 = 0;    ///< maximum surface: a0 + p / (a1 + a2 p)
    real_t a0y = 0, a1y = 0, a2y = 0; ///< yield surface
    real_t a1f = 0, a2f = 0;          ///< residual surface: p / (a1f + a2f p)
    real_t b1 = 1.6, b2 = 1.35, b3 = 1.15, omega = 0.5;
    /// Post-peak dilatancy decay (MAT_072R3's EDROP, whose formula LS-DYNA does not publish):
    /// past the peak the dilatancy is omega eta(lambda)^edrop, so it vanishes on the residual
    /// surface (eta = 0: crushed concrete flows at constant volume); 0 (the default): omega
    /// throughout. Published MAT_072R3 calibrations set 1 (Yin et al. 2023, Cem. Concr. Compos.
    /// 137, 104911, their deck's EDROP), as the P6 and P4 decks do; docs/theory/materials.md says
    /// what it changes.
    real_t edrop = 0.0;
    std::vector<std::pair<real_t, real_t>> eta_table; ///< (lambda, eta), 13 points
    real_t lambda_m = 5.6e-5;                         ///< first lambda where eta = 1
    real_t lambda_z = 5.7e-4;                         ///< first lambda after the peak where eta returns to 0
    real_t alpha_biaxial = 1.15;                      ///< f_bc / f'c
    real_t fyc = 0.0;         ///< uniaxial compressive yield strength (from the yield hyperbola)
    real_t psi_biaxial = 0.0; ///< psi at p = 2 alpha f'c / 3

    /// The generic parameter set scaled from the 45.4 MPa reference concrete (Schwer & Malvar 2005):
    /// a0, a0y proportional to f'c; a2, a2y, a2f inversely proportional; a1, a1y, a1f fixed;
    /// f_t = 1.58 (f'c^2)^(1/3) in psi. [K/U: that LS-DYNA scales exactly linearly]
    static KccParameters from_fc(real_t fc_pa);

    /// lambda_m, lambda_z from the eta table, f_yc and psi at the biaxial point from the
    /// coefficients (after overrides).
    void update_derived();

    /// Compressive-meridian stress differences of the three surfaces at pressure p.
    real_t max_surface(real_t p) const;
    real_t yield_surface(real_t p) const;
    real_t residual_surface(real_t p) const;

    /// psi(p) = r_t / r_c, piecewise linear through the breakpoints of Malvar et al. 1997.
    real_t psi(real_t p) const;

    /// eta(lambda), linear in the table; delta = 2 lambda / (lambda + lambda_m).
    real_t eta(real_t lambda) const;
    real_t scaled_damage(real_t lambda) const { return 2.0 * lambda / (lambda + lambda_m); }

    /// Peak axial stress difference in triaxial compression at confinement p_c on a surface:
    /// solves ds = surface(p_c + ds / 3).
    template <class Surface> real_t triaxial_difference(real_t pc, Surface&& surface) const
    {
        real_t ds = surface(pc + fc / 3.0);
        for (int it = 0; it < 200; ++it)
        {
            const real_t next = surface(pc + ds / 3.0);
            if (std::abs(next - ds) <= 1e-14 * std::abs(next))
                return next;
            ds = next;
        }
        return ds;
    }
};

/// Willam-Warnke ratio r'/r_c at Lode angle theta (0 tensile meridian, pi/3 compressive) for
/// psi in [1/2, 1] (clamped).
real_t willam_warnke(real_t theta, real_t psi);
/// The same from cos theta.
real_t willam_warnke_cos(real_t c, real_t psi);
/// cos(acos(c3) / 3) for c3 in [-1, 1]: the cosine of the Lode angle theta in [0, pi / 3] from
/// cos 3 theta, without acos and cos (which took a fifth of a fem-1pt K&C run): with
/// s = sqrt((1 + c3) / 2), f(s) = cos(2/3 acos s) is analytic on [0, 1] (at s = 1 it is even in
/// acos s, so analytic in 1 - s), and a Chebyshev series of degree 18 holds it to 2.3e-16.
real_t cos_third_acos(real_t c3);

} // namespace rkfem
