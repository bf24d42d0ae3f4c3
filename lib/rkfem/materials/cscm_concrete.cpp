#include "rkfem/materials/cscm_concrete.hpp"

#include <algorithm>
#include <numbers>

#include "rkfem/core/error.hpp"
#include "rkfem/materials/kcc_concrete.hpp"

namespace rkfem
{
namespace
{
constexpr real_t MPa = 1e6;

/// Root of an increasing function g on [lo, hi] with g(lo) <= 0 <= g(hi), by bisection.
template <class F> real_t bisect(F&& g, real_t lo, real_t hi)
{
    for (int it = 0; it < 200 && hi - lo > 1e-15 * std::max(std::abs(lo), std::abs(hi)); ++it)
    {
        const real_t mid = 0.5 * (lo + hi);
        (g(mid) <= 0.0 ? lo : hi) = mid;
    }
    return 0.5 * (lo + hi);
}

/// Largest eigenvalue of a symmetric tensor (Voigt, tensor shear), trigonometric closed form.
real_t max_principal(const real_t e[6])
{
    const real_t m = (e[0] + e[1] + e[2]) / 3.0;
    const real_t a = e[0] - m, b = e[1] - m, c = e[2] - m;
    const real_t p2 = 0.5 * (a * a + b * b + c * c) + e[3] * e[3] + e[4] * e[4] + e[5] * e[5]; // J2
    if (p2 <= 1e-300)
        return m;
    const real_t J3 = a * (b * c - e[4] * e[4]) - e[3] * (e[3] * c - e[4] * e[5]) + e[5] * (e[3] * e[4] - b * e[5]);
    const real_t r = std::clamp(1.5 * std::sqrt(3.0) * J3 / std::pow(p2, 1.5), -1.0, 1.0);
    return m + 2.0 * std::sqrt(p2 / 3.0) * std::cos(std::acos(r) / 3.0);
}
} // namespace

real_t dilog(real_t x)
{
    constexpr real_t pi2_6 = std::numbers::pi * std::numbers::pi / 6.0;
    RKFEM_REQUIRE(x <= 1.0, "dilog: argument " << x << " above 1");
    if (x < -1.0)
        return -pi2_6 - 0.5 * std::log(-x) * std::log(-x) - dilog(1.0 / x);
    if (x > 0.5)
        return x == 1.0 ? pi2_6 : pi2_6 - std::log(x) * std::log(1.0 - x) - dilog(1.0 - x);
    if (x < -0.5) // Landen: x / (x - 1) lies in [1/3, 1/2]
        return -dilog(x / (x - 1.0)) - 0.5 * std::log(1.0 - x) * std::log(1.0 - x);
    real_t sum = 0.0, xk = x;
    for (int k = 1; k < 200; ++k, xk *= x)
    {
        const real_t term = xk / (static_cast<real_t>(k) * k);
        sum += term;
        if (std::abs(term) < 1e-18)
            break;
    }
    return sum;
}

CscmModel CscmModel::from_fc(real_t fc_pa, real_t rho, real_t nu, real_t E, real_t Gft)
{
    CscmModel m;
    const real_t f = fc_pa / MPa;
    m.fc = fc_pa;
    m.rho = rho;
    if (!(E > 0))
        E = 21.5e9 * std::cbrt(f / 10.0); // CEB-FIP 1990 E_ci [U]
    m.bulk = E / (3.0 * (1.0 - 2.0 * nu));
    m.shear = E / (2.0 * (1.0 + nu));
    m.alpha = (-0.003 * f * f + 0.3169747 * f + 7.7047) * MPa;
    m.theta = 1.3216e-5 * f * f + 2.3548e-3 * f + 0.2140058;
    m.lambda = 10.5 * MPa;
    m.beta = 1.929e-2 / MPa;
    m.alpha1 = 0.74735;
    m.lambda1 = 0.17;
    m.theta1 = (-4.0856e-7 * f * f - 1.2132e-6 * f + 1.5593e-3) / MPa;
    m.beta1 = (-1.9972e-5 * f * f + 2.2655e-4 * f + 8.1748e-2) / MPa;
    m.alpha2 = 0.66;
    m.lambda2 = 0.16;
    m.theta2 = (-4.8697e-7 * f * f - 1.8883e-6 * f + 1.8822e-3) / MPa;
    m.beta2 = (-1.9972e-5 * f * f + 2.2655e-4 * f + 8.2748e-2) / MPa;
    m.R = 5.0;
    m.X0 = (8.769178e-3 * f * f - 7.3302306e-2 * f + 84.85) * MPa;
    m.W = 0.05;
    m.D1 = 2.5e-4 / MPa;
    m.D2 = 3.49e-7 / (MPa * MPa);
    m.B = 100.0;
    m.D = 0.1;
    m.Gft = Gft > 0 ? Gft : ceb_fracture_energy(fc_pa);
    m.Gfs = m.Gft;
    m.Gfc = 100.0 * m.Gft;
    const real_t fpsi = f * 145.0377;
    m.eta0c = 1.2772337e-11 * fpsi * fpsi - 1.0613722e-7 * fpsi + 3.203497e-4; // [U] read as SI
    m.eta0t = 8.0614774e-13 * fpsi * fpsi - 9.77736719e-10 * fpsi + 5.0752351e-5;
    m.overc = m.overt = (1.309663e-2 * f * f - 0.3927659 * f + 21.45) * MPa;
    m.finish();
    return m;
}

real_t CscmModel::Q1(real_t P) const
{
    if (P < 0.0)
        return 1.0 / std::sqrt(3.0);
    return std::min(1.0, alpha1 - lambda1 * std::exp(-beta1 * P) + theta1 * P);
}

real_t CscmModel::Q2(real_t P) const
{
    if (P < 0.0)
        return 0.5;
    return std::min(Q1(P), alpha2 - lambda2 * std::exp(-beta2 * P) + theta2 * P);
}

real_t CscmModel::rubin_cs(real_t P, real_t c, real_t s) const
{
    const real_t q1 = Q1(P), q2 = Q2(P);
    const real_t a0 = 2.0 * q1 * q1 * (q2 - 1.0);
    const real_t a1 = std::sqrt(3.0) * q2 + 2.0 * q1 * (q2 - 1.0);
    const real_t a2 = q2;
    const real_t a = (-a1 + std::sqrt(a1 * a1 - 4.0 * a2 * a0)) / (2.0 * a2);
    const real_t b = (2.0 * q1 + a) * (2.0 * q1 + a) - 3.0;
    const real_t b0 = -(3.0 + b - a * a) / 4.0;
    const real_t b1 = a * (c - a * s);
    const real_t b2 = (c - a * s) * (c - a * s) + b * s * s;
    return (-b1 + std::sqrt(b1 * b1 - 4.0 * b2 * b0)) / (2.0 * b2);
}

real_t CscmModel::kappa_of_X(real_t X, real_t guess) const
{
    // kappa + R Ff(kappa) = X: increasing and concave, so Newton converges monotonically from
    // the left, and from the right after one step that lands left; default start: the apex
    // where Ff = 0
    if (X == X0 && kappa0 > p_apex)
        return kappa0;
    real_t k = std::isnan(guess) ? std::min(p_apex, X) : guess;
    for (int it = 0; it < 100; ++it)
    {
        const real_t g = cap_X(k) - X;
        const real_t dk = -g / (1.0 + R * dFf(k));
        k += dk;
        if (std::abs(dk) <= 1e-14 * std::max(std::abs(k), fc))
            break;
    }
    return std::max(k, kappa0);
}

real_t CscmModel::X_of_compaction(real_t evp) const
{
    if (evp <= 0.0)
        return X0; // the cap does not contract below X0 [U]
    const real_t r = std::log(1.0 - std::min(evp / W, 1.0 - 1e-15));
    const real_t z = D2 > 0.0 ? (-D1 + std::sqrt(D1 * D1 - 4.0 * D2 * r)) / (2.0 * D2) : -r / D1;
    return X0 + z;
}

real_t CscmModel::compaction_of_X(real_t X) const
{
    const real_t z = X - X0;
    return W * (1.0 - std::exp(-D1 * z - D2 * z * z));
}

real_t CscmModel::Fc(real_t P, real_t kappa) const
{
    const real_t L = std::max(kappa, kappa0);
    if (P <= L)
        return 1.0;
    const real_t t = (P - L) / (R * Ff(L)); // X - L = R Ff(L)
    return 1.0 - t * t;
}

real_t CscmModel::yield_cs(real_t P, real_t J2, real_t cb, real_t sb, real_t kappa) const
{
    const real_t F = std::max(Ff(P), 0.0);
    const real_t r = rubin_cs(P, cb, sb);
    return J2 - r * r * F * F * Fc(P, kappa);
}

void CscmModel::finish()
{
    E = 9.0 * bulk * shear / (3.0 * bulk + shear);
    RKFEM_REQUIRE(alpha - lambda > 0.0,
                  "cscm: alpha - lambda = " << alpha - lambda << " Pa; the shear surface must be open at I1 = 0");
    real_t lo = -fc;
    while (Ff(lo) > 0.0)
        lo *= 2.0;
    p_apex = bisect([&](real_t P) { return Ff(P); }, lo, 0.0);
    kappa0 = p_apex; // so that kappa_of_X does not clamp while it solves for kappa0
    kappa0 = kappa_of_X(X0);
    const real_t txc = std::numbers::pi / 6.0;
    fcu = bisect([&](real_t s)
                 { return s / std::sqrt(3.0) - rubin(s, txc) * Ff(s) * std::sqrt(std::max(Fc(s, kappa0), 0.0)); },
                 0.0, X0);
    ftu = bisect([&](real_t s) { return s / std::sqrt(3.0) - rubin(-s, -txc) * std::max(Ff(-s), 0.0); }, 0.0, -p_apex);
    r0c = fcu / std::sqrt(2.0 * E);
    r0t = ftu / std::sqrt(E);
    soft0 = softening(default_length);
}

CscmModel::Softening CscmModel::softening(real_t h) const
{
    Softening out;
    out.C = ftu * h * (1.0 + D) * std::log1p(D) / (std::sqrt(E) * D * Gft);
    const real_t a2 = 4.0 * (1.0 + B) / B * (-dilog(-B));
    const real_t a1 = 4.0 * (1.0 + B) / B * r0c * std::log1p(B);
    const real_t g = Gfc / h;
    const real_t y = (-a1 + std::sqrt(a1 * a1 + 4.0 * a2 * g)) / (2.0 * a2); // 1 / A
    out.A = 1.0 / y;
    return out;
}

namespace
{
/// Elastic trial state of a CSCM point.
struct CscmTrial
{
    real_t sT[6];  ///< trial stress
    real_t dev[6]; ///< its deviator
    real_t PT;     ///< its pressure (compression positive)
    real_t J2T;    ///< its J2
    real_t bh;     ///< its Lode angle (Rubin's beta hat)
};

/// Result of the inviscid return.
struct CscmReturn
{
    real_t P, sc, evp, kap, eps_p; ///< pressure, deviator scale, compaction, cap parameter, effective plastic strain
    bool plastic;                  ///< the trial stress lay outside the surface
};

/// Objective rotation of the stress and strain histories, the elastic trial stress and the total strain update.
static inline void cscm_trial_stress(const CscmModel& m, const real_t d[6], const real_t w[3], real_t dt, CscmState& st,
                                     CscmTrial& t)
{
    rotate_stress(w, dt, st.svp);
    rotate_stress(w, dt, st.eps);
    const real_t K = m.bulk, G = m.shear;
    const real_t tr = d[0] + d[1] + d[2];
    auto& sT = t.sT;
    for (int c = 0; c < 3; ++c)
        sT[c] = st.svp[c] + dt * ((K - 2.0 * G / 3.0) * tr + 2.0 * G * d[c]);
    for (int c = 3; c < 6; ++c)
        sT[c] = st.svp[c] + dt * 2.0 * G * d[c];
    for (int c = 0; c < 6; ++c)
        st.eps[c] += d[c] * dt;
}

/// Pressure, deviator, J2 and Lode angle (beta hat) of the trial stress.
static inline void cscm_trial_invariants(const CscmModel& m, CscmTrial& t)
{
    const auto& sT = t.sT;
    auto& dev = t.dev;
    const real_t PT = -(sT[0] + sT[1] + sT[2]);
    for (int c = 0; c < 3; ++c)
        dev[c] = sT[c] + PT / 3.0;
    for (int c = 3; c < 6; ++c)
        dev[c] = sT[c];
    const real_t J2T = 0.5 * (dev[0] * dev[0] + dev[1] * dev[1] + dev[2] * dev[2]) + dev[3] * dev[3] + dev[4] * dev[4] +
                       dev[5] * dev[5];
    real_t bh = std::numbers::pi / 6.0;
    if (J2T > 1e-24 * m.fc * m.fc)
    {
        const real_t J3 = dev[0] * (dev[1] * dev[2] - dev[4] * dev[4]) - dev[3] * (dev[3] * dev[2] - dev[4] * dev[5]) +
                          dev[5] * (dev[3] * dev[4] - dev[1] * dev[5]);
        real_t s3 = std::clamp(-1.5 * std::sqrt(3.0) * J3 / (J2T * std::sqrt(J2T)), -1.0, 1.0);
        // states within rounding of a meridian are put on it: Rubin's section has a corner there
        // and asin amplifies a 1e-15 error in s3 to 1e-8 rad
        if (std::abs(s3) > 1.0 - 1e-12)
            s3 = std::copysign(1.0, s3);
        bh = std::asin(s3) / 3.0;
    }
    t.PT = PT;
    t.J2T = J2T;
    t.bh = bh;
}

/// Inviscid return to the shear surface and cap: cutting plane in P, deviator scale sc, compaction evp.
static inline void cscm_return(const CscmModel& m, const CscmTrial& trial, real_t cb, real_t sb, real_t kappa_n,
                               real_t evp_n, real_t eps_p_n, CscmReturn& r)
{
    const real_t K = m.bulk, G = m.shear;
    const real_t PT = trial.PT, J2T = trial.J2T;
    auto yield = [&](real_t P, real_t J2, real_t kappa) { return m.yield_cs(P, J2, cb, sb, kappa); };

    real_t P = PT, sc = 1.0, evp = evp_n, kap = kappa_n, eps_p = eps_p_n;
    bool plastic = false;
    // yield tolerance relative to J2: Rubin's scaling has a corner at the compressive meridian
    // (d Rubin / d beta_hat = 0.35 at I1 = 76 MPa), so the Lode angle's rounding shows in f
    const real_t tol = 1e-8 * std::max(J2T, 1e-6 * m.fc * m.fc);
    if (PT <= m.p_apex)
    {
        P = m.p_apex;
        sc = 0.0;
        plastic = true;
    }
    else if (yield(PT, J2T, kap) > tol)
    {
        plastic = true;
        for (int it = 0; it < 100; ++it)
        {
            // f = J2 - Rb^2 F^2 Fc with Rb the Rubin scale, F = Ff(P), Fc the cap function
            const real_t J2 = sc * sc * J2T;
            const real_t F = std::max(m.Ff(P), 0.0), dF = F > 0.0 ? m.dFf(P) : 0.0;
            const real_t Rb = m.rubin_cs(P, cb, sb);
            const real_t L = std::max(kap, m.kappa0);
            const real_t FfL = m.Ff(L), XL = m.R * FfL; // X - L
            const real_t t = P > L ? (P - L) / XL : 0.0;
            const real_t Fcap = 1.0 - t * t;
            const real_t f = J2 - Rb * Rb * F * F * Fcap;
            if (f <= 1e-8 * std::max(J2, 1e-6 * m.fc * m.fc))
                break;
            // d f / d P: the Rubin scale's dependence on P (through Q1, Q2) by a forward difference,
            // the rest analytic
            const real_t hP = 1e-6 * std::max(std::abs(P), m.fc);
            const real_t dRb = (m.rubin_cs(P + hP, cb, sb) - Rb) / hP;
            const real_t dFcap = P > L ? -2.0 * t / XL : 0.0;
            const real_t fP =
                -(2.0 * Rb * dRb * F * F * Fcap + 2.0 * Rb * Rb * F * dF * Fcap + Rb * Rb * F * F * dFcap);
            real_t fk_kp = 0.0; // (d f / d kappa) (d kappa / d evp)
            if (P > L && (evp > 0.0 || fP > 0.0))
            {
                // t = (P - kappa) / (R Ff(kappa)): dt/dkappa = -(1 + t R Ff'(kappa)) / (R Ff(kappa))
                const real_t dt = -(1.0 + t * m.R * m.dFf(L)) / XL;
                const real_t fk = Rb * Rb * F * F * 2.0 * t * dt; // -Rb^2 F^2 dFcap/dkappa, dFcap = -2 t dt
                const real_t z = m.X_of_compaction(std::max(evp, 0.0)) - m.X0;
                const real_t devp_dX = m.W * (m.D1 + 2.0 * m.D2 * z) * std::exp(-m.D1 * z - m.D2 * z * z);
                fk_kp = fk / (devp_dX * (1.0 + m.R * m.dFf(L)));
            }
            const real_t denom = 9.0 * K * fP * fP + 4.0 * G * J2 - 3.0 * fk_kp * fP;
            if (!(denom > 0.0))
                break;
            const real_t dl = f / denom;
            eps_p += 2.0 / std::sqrt(3.0) * std::sqrt(J2) * dl;
            P -= 9.0 * K * dl * fP;
            sc /= 1.0 + 2.0 * G * dl;
            evp += 3.0 * dl * fP;
            kap = evp > 0.0 ? m.kappa_of_X(m.X_of_compaction(evp), kap) : m.kappa0;
            if (P <= m.p_apex)
            {
                P = m.p_apex;
                sc = 0.0;
                break;
            }
        }
    }
    r.P = P;
    r.sc = sc;
    r.evp = evp;
    r.kap = kap;
    r.eps_p = eps_p;
    r.plastic = plastic;
}

/// Rate effects: the viscoplastic fraction gamma = dt / (eta + dt) of the return applied this step (1: inviscid).
static inline real_t cscm_rate_gamma(const CscmModel& m, const real_t d[6], real_t dt, real_t PT, real_t J2T)
{
    real_t gamma = 1.0;
    if (m.rate_effects)
    {
        real_t dd = 0.0;
        for (int c = 0; c < 3; ++c)
            dd += d[c] * d[c] + 2.0 * d[c + 3] * d[c + 3];
        const real_t rate = std::sqrt(2.0 / 3.0 * dd);
        if (rate > 0.0)
        {
            const real_t eta_t = m.eta0t / std::pow(rate, m.nt), eta_s = m.srate * eta_t;
            const real_t ratio = J2T > 0.0 ? std::abs(PT) / std::sqrt(3.0 * J2T) : kNoLimit;
            real_t eta, over;
            if (PT < 0.0)
            {
                eta = eta_s + std::min(1.0, std::pow(ratio, m.pwrt)) * (eta_t - eta_s);
                over = m.overt;
            }
            else
            {
                const real_t eta_c = m.eta0c / std::pow(rate, m.nc);
                eta = eta_s + std::min(1.0, std::pow(ratio, m.pwrc)) * (eta_c - eta_s);
                over = m.overc;
            }
            eta = std::min(eta, over / (m.E * rate));
            gamma = dt / (eta + dt);
        }
    }
    return gamma;
}

/// Viscoplastic stress and history: the return relaxed toward the trial state by gamma; returns the plastic work.
static inline real_t cscm_viscoplastic(const CscmModel& m, const real_t d[6], real_t dt, const CscmTrial& t,
                                       const CscmReturn& r, CscmState& st)
{
    const real_t K = m.bulk, G = m.shear;
    const auto& sT = t.sT;
    const auto& dev = t.dev;
    const real_t PT = t.PT, J2T = t.J2T, P = r.P, sc = r.sc;
    // plastic work of the return: sigma^P : C^-1 (sigma^T - sigma^P) >= 0 for a convex surface
    real_t work = std::max(0.0, P * (PT - P) / (9.0 * K) + sc * (1.0 - sc) * J2T / G);
    const real_t gamma = cscm_rate_gamma(m, d, dt, PT, J2T);
    for (int c = 0; c < 3; ++c)
    {
        const real_t sp = sc * dev[c] - P / 3.0;
        st.svp[c] = sp + (1.0 - gamma) * (sT[c] - sp);
    }
    for (int c = 3; c < 6; ++c)
    {
        const real_t sp = sc * dev[c];
        st.svp[c] = sp + (1.0 - gamma) * (sT[c] - sp);
    }
    st.evp += gamma * (r.evp - st.evp);
    st.kappa = gamma == 1.0 ? r.kap : m.kappa_of_X(m.X_of_compaction(st.evp));
    st.eps_p += gamma * (r.eps_p - st.eps_p);
    work *= gamma;
    return work;
}

/// Brittle and ductile damage from the energy norms of the undamaged stress and total strain; the damage applied.
static inline void cscm_damage(const CscmModel& m, const CscmReturn& r, real_t evp_n, CscmState& st)
{
    // damage from the energy norms of the undamaged stress and the total strain
    const real_t Pv = -(st.svp[0] + st.svp[1] + st.svp[2]);
    const real_t C = std::isnan(st.C) ? m.soft0.C : st.C;
    const real_t A = std::isnan(st.A) ? m.soft0.A : st.A;
    // a threshold is set where the point first yields with dilatant flow (on the shear part of
    // the surface, not compacting on the cap) in its pressure regime: the damage threshold
    // surface coincides with the shear surface [U]
    const bool on_shear = r.plastic && r.evp < evp_n;
    if (Pv < 0.0)
    {
        const real_t tau = std::sqrt(m.E) * std::max(max_principal(st.eps), 0.0);
        if (on_shear && std::isnan(st.r0t))
            st.r0t = tau;
        st.rt = std::max(st.rt, tau);
        if (st.rt > st.r0t)
            st.db = std::max(st.db, ((1.0 + m.D) / (1.0 + m.D * std::exp(-C * (st.rt - st.r0t))) - 1.0) / m.D);
    }
    else
    {
        const real_t se = st.svp[0] * st.eps[0] + st.svp[1] * st.eps[1] + st.svp[2] * st.eps[2] +
                          2.0 * (st.svp[3] * st.eps[3] + st.svp[4] * st.eps[4] + st.svp[5] * st.eps[5]);
        const real_t tau = std::sqrt(std::max(0.5 * se, 0.0));
        if (on_shear && std::isnan(st.r0c))
            st.r0c = tau;
        st.rc = std::max(st.rc, tau);
        if (st.rc > st.r0c)
        {
            real_t dv[6];
            for (int c = 0; c < 6; ++c)
                dv[c] = st.svp[c] + (c < 3 ? Pv / 3.0 : 0.0);
            const real_t J2v =
                0.5 * (dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]) + dv[3] * dv[3] + dv[4] * dv[4] + dv[5] * dv[5];
            const real_t dmax = Pv > 0.0 ? std::min(1.0, std::pow(std::sqrt(3.0 * J2v) / Pv, 1.5)) : 1.0;
            st.dc = std::max(st.dc, dmax / m.B * ((1.0 + m.B) / (1.0 + m.B * std::exp(-A * (st.rc - st.r0c))) - 1.0));
        }
    }
    st.d = Pv >= 0.0 ? st.dc : std::max(st.db, st.dc);
}
} // namespace

real_t cscm_update(const CscmModel& m, const real_t d[6], const real_t w[3], real_t dt, real_t s[6], CscmState& st)
{
    CscmTrial t;
    cscm_trial_stress(m, d, w, dt, st, t);
    cscm_trial_invariants(m, t);
    const real_t kappa_n = std::isnan(st.kappa) ? m.kappa0 : st.kappa;
    const real_t cb = std::cos(t.bh), sb = std::sin(t.bh);

    // inviscid return (cutting plane in P, deviator scale sc, compaction evp)
    const real_t evp_n = st.evp;
    CscmReturn r;
    cscm_return(m, t, cb, sb, kappa_n, evp_n, st.eps_p, r);
    real_t work = 0.0;
    if (r.plastic)
        work = cscm_viscoplastic(m, d, dt, t, r, st);
    else
        std::copy(t.sT, t.sT + 6, st.svp);

    cscm_damage(m, r, evp_n, st);
    for (int c = 0; c < 6; ++c)
        s[c] = (1.0 - st.d) * st.svp[c];
    return work;
}
} // namespace rkfem
