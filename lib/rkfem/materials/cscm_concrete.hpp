#pragma once
/// @file cscm_concrete.hpp
/// Continuous surface cap model for concrete (LS-DYNA MAT_159 / CSCM analog, Murray 2007), with
/// the parameter set generated from f'c by Murray's fits. Formulas: Murray 2007 (FHWA-HRT-05-062
/// user manual; FHWA-HRT-05-063 evaluation). Murray's sign convention: the first invariant
/// I1 = -tr(sigma) is positive in compression (here `P`); deviators are tension-positive.
///
///   yield   f = J2 - Rubin(beta_hat)^2 Ff(P)^2 Fc(P, kappa)
///   shear   Ff(P) = alpha - lambda exp(-beta P) + theta P          (compressive meridian, TXC)
///   Rubin   TOR/TXC = Q1(P), TXE/TXC = Q2(P) (1/sqrt3 and 1/2 for P < 0)
///   cap     Fc = 1 - (P - L)^2 / (X - L)^2 for P > L, else 1;  L = max(kappa, kappa0),
///           X = L + R Ff(L);  plastic compaction eps_v^p = W (1 - exp(-D1 (X - X0) - D2 (X - X0)^2))
///   damage  sigma = (1 - d) sigma^vp; ductile d(tau_c), tau_c = sqrt(sigma^vp : eps / 2), for
///           P >= 0; brittle d(tau_t), tau_t = sqrt(E) max principal strain, for P < 0
///   rate    Duvaut-Lions: sigma^vp = sigma^P + (1 - gamma)(sigma^T - sigma^P),
///           gamma = dt / (eta + dt), eta = eta0 / rate^N (tension, compression, shear blend)
///
/// Choices where Murray's reports are silent or uncertain are marked [U]:
///  - plastic return: cutting-plane iterations (Ortiz-Simo) with the Lode angle of the trial
///    state held fixed and associated flow in the meridian plane; apex return in tension;
///  - the cap does not contract below X0 (X = X0 while the compaction eps_v^p <= 0);
///  - Q1 and Q2 are clamped to Q2 <= Q1 <= 1 (the fits exceed 1 above I1 ~ 220 MPa);
///  - damage thresholds are the energy norms where the point first yields with dilatant flow
///    (the shear part of the surface; not while it compacts the cap) with P >= 0 (ductile) and
///    P < 0 (brittle) (Murray: "coincident with the shear plasticity surface"); confined states
///    harden on the cap undamaged until they dilate; in uniaxial
///    paths they equal r0c = fcu / sqrt(2E) and r0t = ftu / sqrt(E), which the softening uses;
///  - maximum ductile damage d_max = min(1, (sqrt(3 J2) / I1)^1.5); brittle d_max = 1;
///    brittle damage is not applied while P >= 0 (full modulus recovery, RECOV = 0);
///  - softening A (ductile) and C (brittle) follow in closed form from G_fc, G_ft and the
///    crack-band length h for a perfectly plastic uniaxial post-peak (see softening());
///    the pressure blending of G_f (PWRC, PWRT) is not applied to G_f, only to eta;
///  - E from CEB-FIP 1990, E = 21.5 GPa (f'c / 10 MPa)^(1/3), nu = 0.2, when not given;
///    G_ft = CEB-FIP G_f, G_fs = G_ft, G_fc = 100 G_ft;
///  - eta0c, eta0t are Murray's fits in psi read as SI (s^(1-N)); the effective strain rate is
///    sqrt(2/3 D:D).
#include <cmath>
#include <limits>

#include "rkfem/materials/objective_rate.hpp"

namespace rkfem
{
struct CscmModel
{
    struct Softening
    {
        real_t A = 0, C = 0; ///< ductile [1/sqrt(Pa)], brittle [1/sqrt(Pa)]
    };
    real_t fc = 0.0, rho = 2400.0;
    real_t bulk = 0.0, shear = 0.0, E = 0.0; ///< K, G, Young's modulus [Pa]
    // shear surface, compressive meridian (P in Pa)
    real_t alpha = 0, theta = 0, lambda = 0, beta = 0;
    real_t alpha1 = 0, theta1 = 0, lambda1 = 0, beta1 = 0; ///< Q1 = TOR/TXC
    real_t alpha2 = 0, theta2 = 0, lambda2 = 0, beta2 = 0; ///< Q2 = TXE/TXC
    // cap
    real_t R = 5.0, X0 = 0, W = 0.05, D1 = 0, D2 = 0;
    // damage
    real_t B = 100.0, D = 0.1;
    real_t Gfc = 0, Gft = 0, Gfs = 0; ///< fracture energies [J/m^2]
    real_t default_length = 0.1;      ///< crack-band length where none is set [m] [U]
    // rate effects
    bool rate_effects = false;
    real_t eta0c = 0, nc = 0.78, eta0t = 0, nt = 0.48, overc = 0, overt = 0, srate = 1.0;
    real_t pwrc = 5.0, pwrt = 1.0;
    // derived by finish()
    real_t kappa0 = 0;       ///< X(kappa0) = X0
    real_t p_apex = 0;       ///< Ff(p_apex) = 0 (tension, < 0)
    real_t fcu = 0, ftu = 0; ///< uniaxial compressive / tensile strengths on the initial surface
    real_t r0c = 0, r0t = 0; ///< uniaxial damage thresholds [sqrt(Pa)]
    Softening soft0;         ///< softening at default_length

    /// Murray's generic fits from f'c [Pa] (Murray 2007's defaults, valid ~20-58 MPa), then
    /// finish(). E <= 0 and Gft <= 0 pick the defaults above.
    static CscmModel from_fc(real_t fc_pa, real_t rho, real_t nu = 0.2, real_t E = 0.0, real_t Gft = 0.0);

    /// Derived quantities (kappa0, apex, uniaxial strengths, thresholds) after any override.
    void finish();

    real_t Ff(real_t P) const { return alpha - lambda * std::exp(-beta * P) + theta * P; }
    real_t dFf(real_t P) const { return lambda * beta * std::exp(-beta * P) + theta; }
    real_t Q1(real_t P) const;
    real_t Q2(real_t P) const;
    /// Rubin scale at pressure P and Lode angle beta_hat in [-pi/6, pi/6] (pi/6: TXC -> 1);
    /// the second form takes cos and sin of beta_hat.
    real_t rubin(real_t P, real_t beta_hat) const { return rubin_cs(P, std::cos(beta_hat), std::sin(beta_hat)); }
    real_t rubin_cs(real_t P, real_t cb, real_t sb) const;
    real_t cap_X(real_t kappa) const { return kappa + R * Ff(kappa); }
    real_t kappa_of_X(real_t X, real_t guess = std::numeric_limits<real_t>::quiet_NaN()) const;
    real_t X_of_compaction(real_t evp) const;
    real_t compaction_of_X(real_t X) const;
    real_t Fc(real_t P, real_t kappa) const;
    /// Yield function f = J2 - Rubin^2 Ff^2 Fc (Ff clipped at 0 past the apex); the second form
    /// takes cos and sin of the Lode angle.
    real_t yield(real_t P, real_t J2, real_t beta_hat, real_t kappa) const
    {
        return yield_cs(P, J2, std::cos(beta_hat), std::sin(beta_hat), kappa);
    }
    real_t yield_cs(real_t P, real_t J2, real_t cb, real_t sb, real_t kappa) const;

    /// Damage softening for a crack band of length h: C from G_ft (brittle, uniaxial tension),
    /// A from G_fc (ductile, uniaxial compression), each for a perfectly plastic post-peak:
    ///   G_ft / h = ftu / sqrt(E) (1 + D) ln(1 + D) / (C D)
    ///   G_fc / h = 4 (1 + B) / B [ -Li2(-B) / A^2 + r0c ln(1 + B) / A ]
    Softening softening(real_t h) const;
};

/// Dilogarithm Li2(x) for x <= 1 (real branch).
real_t dilog(real_t x);

/// History of one CSCM point.
struct CscmState
{
    real_t svp[6] = {};                                      ///< undamaged (viscoplastic) stress
    real_t eps[6] = {};                                      ///< total strain (tensor shear), rotated with the stress
    real_t evp = 0.0;                                        ///< plastic volumetric compaction (compression positive)
    real_t kappa = std::numeric_limits<real_t>::quiet_NaN(); ///< cap parameter (NaN: kappa0)
    real_t rc = 0.0, rt = 0.0;                               ///< largest ductile / brittle energy norms so far
    real_t r0c = std::numeric_limits<real_t>::quiet_NaN();   ///< ductile threshold (set at first yield)
    real_t r0t = std::numeric_limits<real_t>::quiet_NaN();   ///< brittle threshold (set at first yield)
    real_t dc = 0.0, db = 0.0;                               ///< ductile / brittle damage
    real_t d = 0.0;                                          ///< damage applied to the stress
    real_t eps_p = 0.0;                                      ///< effective plastic strain
    real_t A = std::numeric_limits<real_t>::quiet_NaN();     ///< softening (NaN: default length)
    real_t C = std::numeric_limits<real_t>::quiet_NaN();
};

/// Updates the stress s (Voigt, tension positive; the damaged stress) and the state over dt;
/// returns the plastic work density increment (>= 0).
real_t cscm_update(const CscmModel& m, const real_t d[6], const real_t w[3], real_t dt, real_t s[6], CscmState& st);
} // namespace rkfem
