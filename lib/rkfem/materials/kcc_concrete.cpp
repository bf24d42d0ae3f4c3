#include "rkfem/materials/kcc_concrete.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"

namespace rkfem
{
KccModel KccModel::from_fc(real_t fc_pa, real_t rho, real_t nu, real_t E)
{
    KccModel m;
    m.surfaces = KccParameters::from_fc(fc_pa);
    m.rho = rho;
    if (!(E > 0))
        E = 4700.0 * std::sqrt(fc_pa / 1e6) * 1e6;
    m.bulk = E / (3.0 * (1.0 - 2.0 * nu));
    m.shear = 3.0 * m.bulk * (1.0 - 2.0 * nu) / (2.0 * (1.0 + nu));
    m.eos_strain = {0, -0.0015, -0.0043, -0.0101, -0.0305, -0.0513, -0.0726, -0.0943, -0.174, -0.208};
    const real_t p_shape[10] = {0,        0.0015,   0.003270, 0.005250, 0.009975,
                                0.015045, 0.021345, 0.032655, 0.19065,  0.29160};
    const real_t k_shape[10] = {1, 1, 1.014, 1.065, 1.267, 1.470, 1.672, 1.825, 4.106, 5.000};
    for (int i = 0; i < 10; ++i)
    {
        m.eos_pressure[i] = p_shape[i] * m.bulk;
        m.eos_unload[i] = k_shape[i] * m.bulk;
    }
    return m;
}

namespace
{
/// Piecewise-linear interpolation over the (decreasing) EOS strains, extrapolated with the last
/// segment beyond the table.
real_t interp(const std::array<real_t, 10>& x, const std::array<real_t, 10>& y, real_t v)
{
    if (v >= x[0])
        return y[0] + (v - x[0]) * (y[1] - y[0]) / (x[1] - x[0]);
    for (int i = 1; i < 10; ++i)
        if (v >= x[i])
            return y[i - 1] + (v - x[i - 1]) * (y[i] - y[i - 1]) / (x[i] - x[i - 1]);
    return y[9] + (v - x[9]) * (y[9] - y[8]) / (x[9] - x[8]);
}
} // namespace

real_t KccModel::eos(real_t ev, real_t& ev_min) const
{
    if (ev <= ev_min)
    {
        ev_min = ev;
        return ev >= 0.0 ? bulk * (-ev) : interp(eos_strain, eos_pressure, ev);
    }
    // unloading / reloading from the most compressive state on the K(ev_min) line
    const real_t pmin = ev_min >= 0.0 ? 0.0 : interp(eos_strain, eos_pressure, ev_min);
    const real_t k = ev_min >= 0.0 ? bulk : interp(eos_strain, eos_unload, ev_min);
    return pmin + k * (ev_min - ev);
}

namespace
{
/// Trial state of a KCC point.
struct KccTrial
{
    real_t p;       ///< pressure (compression positive), after the tensile cutoff
    real_t dev_cut; ///< volumetric strain past the cutoff this step
    real_t dev[6];  ///< trial deviator (scaled onto the surface by the return)
    real_t J2, q;   ///< its J2 and sqrt(3 J2)
};

/// Volumetric strain, EOS pressure and tensile cutoff (the excess opening taken as plastic).
static inline void kcc_pressure(const KccModel& m, real_t tr, real_t dt, KccState& st, KccTrial& t)
{
    const KccParameters& k = m.surfaces;
    st.ev += tr * dt;
    // pressure (compression positive) from the EOS on the elastic part of the volumetric strain
    const real_t ev_eos = st.ev - st.ev_plastic;
    const real_t ev_min0 = st.ev_min;
    real_t p = m.eos(ev_eos, st.ev_min);
    const real_t eta_now = st.lambda <= k.lambda_m ? 1.0 : k.eta(st.lambda);
    const real_t cutoff = -k.ft * eta_now; // tensile cutoff moves with eta after the peak [U]
    real_t dev_cut = 0.0;                  // volumetric strain past the cutoff this step
    if (p < cutoff)
    {
        // the excess opening is plastic: the pressure unloads from the cutoff, not from the EOS
        // line far past it (tangent of the current tensile branch, linear there)
        real_t hist = ev_min0;
        const real_t dv = 1e-9;
        const real_t kt = (m.eos(ev_eos - dv, hist) - p) / dv;
        if (kt > 0.0)
        {
            dev_cut = (cutoff - p) / kt;
            st.ev_plastic += dev_cut;
        }
        p = cutoff;
    }
    t.p = p;
    t.dev_cut = dev_cut;
}

/// Trial deviator (elastic shear increment on the rotated stress), its J2 and q = sqrt(3 J2).
static inline void kcc_trial_deviator(const KccModel& m, const real_t d[6], real_t dt, const real_t s[6], real_t tr,
                                      KccTrial& t)
{
    const real_t G = m.shear;
    auto& dev = t.dev;
    // trial deviator
    const real_t mean = (s[0] + s[1] + s[2]) / 3.0;
    for (int c = 0; c < 3; ++c)
        dev[c] = s[c] - mean + 2.0 * G * (d[c] - tr / 3.0) * dt;
    for (int c = 3; c < 6; ++c)
        dev[c] = s[c] + 2.0 * G * d[c] * dt;
    const real_t J2 = 0.5 * (dev[0] * dev[0] + dev[1] * dev[1] + dev[2] * dev[2]) + dev[3] * dev[3] + dev[4] * dev[4] +
                      dev[5] * dev[5];
    const real_t q = std::sqrt(3.0 * J2);
    t.J2 = J2;
    t.q = q;
}

/// Willam-Warnke factor at the trial deviator's Lode angle (from the tensile meridian).
static inline real_t kcc_lode_factor(const KccParameters& k, const KccTrial& t)
{
    const auto& dev = t.dev;
    const real_t J2 = t.J2;
    // Lode angle from the tensile meridian: cos 3 theta = (3 sqrt 3 / 2) J3 / J2^(3/2)
    const real_t J3 = dev[0] * (dev[1] * dev[2] - dev[4] * dev[4]) - dev[3] * (dev[3] * dev[2] - dev[4] * dev[5]) +
                      dev[5] * (dev[3] * dev[4] - dev[1] * dev[5]);
    const real_t c3 = std::clamp(1.5 * std::sqrt(3.0) * J3 / (J2 * std::sqrt(J2)), -1.0, 1.0);
    const real_t wlode = willam_warnke_cos(cos_third_acos(c3), k.psi(t.p));
    return wlode;
}

/// Rate enhancement factor r_f (radial scaling Delta sigma_e(p) = r_f Delta sigma(p / r_f)); 1 without rate effects.
static inline real_t kcc_rate_factor(const KccModel& m, const real_t d[6], real_t p)
{
    // rate enhancement: radial scaling Delta sigma_e(p) = r_f Delta sigma(p / r_f)
    real_t rf = 1.0;
    if (m.rate.active())
    {
        const real_t rate = RateLaw::loading_rate(d, p < 0.0);
        rf = m.rate.dif(rate, p < 0.0);
    }
    return rf;
}

/// Plastic strain increment dep of the return: root of q - 3 G dep - H(lambda), walking the eta-table segments.
static inline real_t kcc_eta_walk(const KccParameters& k, real_t G, real_t q, real_t p, real_t rf, real_t wlode,
                                  real_t lambda_n, real_t dlam_per_ep)
{
    // g(x) = q - 3 G x - H(lambda_n + x c) = 0 with c = d lambda / d eps_p. H is linear in
    // eta and eta is piecewise linear in lambda, so g is piecewise linear in x: walk the
    // eta-table segments from lambda_n and solve exactly in the one where g changes sign.
    const real_t ps = p / rf;
    const real_t A = wlode * rf;
    const real_t dm = k.max_surface(ps), dy = k.yield_surface(ps), dr = k.residual_surface(ps);
    auto H = [&](real_t lam, real_t eta)
    { return A * std::max(eta * (dm - (lam <= k.lambda_m ? dy : dr)) + (lam <= k.lambda_m ? dy : dr), 0.0); };
    const auto& tab = k.eta_table;
    real_t x = 0.0, lam = lambda_n;
    real_t dep = q / (3.0 * G); // fallback: full return (surface collapsed)
    std::size_t i = 0;
    while (i + 1 < tab.size() && tab[i + 1].first <= lam)
        ++i;
    for (; i + 1 < tab.size(); ++i)
    {
        // segment [tab[i], tab[i+1]] (split at lambda_m where the branch changes)
        real_t l1 = tab[i + 1].first;
        const real_t slope_eta = (tab[i + 1].second - tab[i].second) / (tab[i + 1].first - tab[i].first);
        const real_t eta0 = tab[i].second + slope_eta * (lam - tab[i].first);
        if (lam < k.lambda_m && l1 > k.lambda_m)
            l1 = k.lambda_m;
        const real_t g0 = q - 3.0 * G * x - H(lam, eta0);
        const real_t eta1 = tab[i].second + slope_eta * (l1 - tab[i].first);
        const real_t x1 = x + (l1 - lam) / dlam_per_ep;
        const real_t g1 = q - 3.0 * G * x1 - H(l1, eta1);
        if (g1 <= 0.0)
        {
            // g linear on the segment (unless the surface clamps at 0; then still monotone)
            dep = x + (x1 - x) * g0 / (g0 - g1);
            break;
        }
        x = x1;
        lam = l1;
        if (l1 < tab[i + 1].first)
            --i; // continue on the same table segment past lambda_m
    }
    return dep;
}

/// Slope d(w Delta sigma)/dp of the damaged surface at damage lambda, by a central difference (for the dilatancy).
static inline real_t kcc_dilatancy_slope(const KccParameters& k, real_t p, real_t rf, real_t wlode, real_t lambda)
{
    const real_t h = 1e-6 * std::max(std::abs(p), k.fc);
    auto surf_at = [&](real_t pp)
    {
        const real_t dm = k.max_surface(pp / rf);
        const real_t e = k.eta(lambda);
        const real_t other = lambda <= k.lambda_m ? k.yield_surface(pp / rf) : k.residual_surface(pp / rf);
        return wlode * rf * std::max(e * (dm - other) + other, 0.0);
    };
    const real_t dsdp = (surf_at(p + h) - surf_at(p - h)) / (2.0 * h);
    return dsdp;
}

/// Deviatoric return to the damaged surface, damage and plastic strain update, dilatancy; returns the plastic work.
static inline real_t kcc_shear_return(const KccModel& m, real_t wlode, real_t rf, KccTrial& t, KccState& st)
{
    const KccParameters& k = m.surfaces;
    const real_t G = m.shear;
    const real_t p = t.p, q = t.q;
    auto& dev = t.dev;
    real_t work = 0.0;
    auto surface = [&](real_t lambda)
    {
        const real_t ps = p / rf;
        const real_t dm = k.max_surface(ps);
        real_t ds;
        if (lambda <= k.lambda_m)
        {
            const real_t dy = k.yield_surface(ps);
            ds = k.eta(lambda) * (dm - dy) + dy;
        }
        else
        {
            const real_t dr = k.residual_surface(ps);
            ds = k.eta(lambda) * (dm - dr) + dr;
        }
        return wlode * rf * std::max(ds, 0.0);
    };
    const real_t pd = std::max(p / rf, -0.999 * k.ft); // keep 1 + p/(r_f f_t) > 0
    const real_t bexp = p >= 0.0 ? k.b1 : k.b2;
    const real_t dlam_per_ep = (p >= 0.0 ? 1.0 : st.tension_scale) / (rf * std::pow(1.0 + pd / k.ft, bexp));
    if (q > surface(st.lambda))
    {
        const real_t dep = kcc_eta_walk(k, G, q, p, rf, wlode, st.lambda, dlam_per_ep);
        const real_t scale = std::max(0.0, 1.0 - 3.0 * G * dep / q);
        // plastic work density of the return: s : d eps_p = q_new dep
        work = scale * q * dep;
        for (auto& x : dev)
            x *= scale;
        st.lambda += dep * dlam_per_ep;
        st.eps_p += dep;
        // partially associated dilatancy: d ev_p = omega dep d(w Delta sigma)/dp, past the peak
        // omega eta(lambda)^edrop (0 on the residual surface)
        const real_t dsdp = kcc_dilatancy_slope(k, p, rf, wlode, st.lambda);
        const real_t decay =
            k.edrop > 0.0 && st.lambda > k.lambda_m ? std::pow(std::max(k.eta(st.lambda), 0.0), k.edrop) : 1.0;
        // acts on the pressure from the next update on (explicit, one step lag)
        st.ev_plastic += k.omega * decay * dep * dsdp;
    }
    return work;
}

/// b3 volumetric damage in near-hydrostatic tension past the cutoff (materials.md 1.5).
static inline void kcc_volumetric_damage(const KccParameters& k, const KccTrial& t, real_t tr, real_t dt, KccState& st)
{
    const auto& dev = t.dev;
    const real_t p = t.p;
    // b3 volumetric damage in near-hydrostatic tension past the cutoff (materials.md 1.5):
    // d lambda += b3 f_d k_d d eps_v, f_d = 1 - (sqrt(3 J2) / |p|) / 0.1, k_d = 1 [U]
    if (t.dev_cut > 0.0 && tr > 0.0)
    {
        const real_t J2n = 0.5 * (dev[0] * dev[0] + dev[1] * dev[1] + dev[2] * dev[2]) + dev[3] * dev[3] +
                           dev[4] * dev[4] + dev[5] * dev[5];
        const real_t ratio = std::abs(p) > 0.0 ? std::sqrt(3.0 * J2n) / std::abs(p) : 1.0;
        const real_t fd = ratio < 0.1 ? 1.0 - ratio / 0.1 : 0.0;
        st.lambda += k.b3 * fd * st.tension_scale * tr * dt;
    }
}
} // namespace

real_t kcc_update(const KccModel& m, const real_t d[6], const real_t w[3], real_t dt, real_t s[6], KccState& st)
{
    const KccParameters& k = m.surfaces;
    rotate_stress(w, dt, s);
    const real_t tr = d[0] + d[1] + d[2];
    KccTrial t;
    kcc_pressure(m, tr, dt, st, t);
    kcc_trial_deviator(m, d, dt, s, tr, t);
    real_t work = 0.0;
    if (t.q > 0.0)
    {
        const real_t wlode = kcc_lode_factor(k, t);
        const real_t rf = kcc_rate_factor(m, d, t.p);
        work = kcc_shear_return(m, wlode, rf, t, st);
    }
    kcc_volumetric_damage(k, t, tr, dt, st);
    for (int c = 0; c < 3; ++c)
        s[c] = t.dev[c] - t.p;
    for (int c = 3; c < 6; ++c)
        s[c] = t.dev[c];
    return work;
}
real_t ceb_fracture_energy(real_t fc_pa)
{
    const real_t fcm = fc_pa / 1e6 + 8.0;
    return 0.030e3 * std::pow(fcm / 10.0, 0.7); // N/mm -> J/m^2 (x 1e3)
}

real_t kcc_tension_work(const KccModel& m, real_t scale)
{
    return kcc_tension_test(m, scale).work;
}

KccTensionTest kcc_tension_test(const KccModel& m, real_t scale)
{
    // uniaxial stress tension, lateral stress held at zero by a safeguarded secant iteration on
    // the lateral strain rate
    KccTensionTest out;
    KccState st;
    st.tension_scale = scale;
    real_t s[6] = {};
    const real_t ft = m.surfaces.ft;
    const real_t E = 9.0 * m.bulk * m.shear / (3.0 * m.bulk + m.shear);
    const real_t nu = (3.0 * m.bulk - 2.0 * m.shear) / (2.0 * (3.0 * m.bulk + m.shear));
    const real_t de = 0.02 * ft / E;                            // 50 steps to the peak
    const real_t elastic = 2.0 * (m.bulk + m.shear / 3.0) * de; // d(lateral stress) / d(lateral rate)
    real_t lat = -nu, work = 0.0, peak = 0.0;
    const real_t w[3] = {0, 0, 0};
    for (int step = 0; step < 200000; ++step)
    {
        real_t trial[6];
        KccState ts;
        // the lateral stress r rises with the lateral rate: lo has r < 0, hi has r > 0 (NaN: none yet)
        real_t lo = std::numeric_limits<real_t>::quiet_NaN(), hi = lo, lat_prev = 0.0, r_prev = 0.0, r = 0.0;
        int it = 0;
        for (; it < 60; ++it)
        {
            std::copy(s, s + 6, trial);
            ts = st;
            const real_t d[6] = {1.0, lat, lat, 0, 0, 0};
            kcc_update(m, d, w, de, trial, ts);
            ++out.updates;
            r = 0.5 * (trial[1] + trial[2]);
            if (std::abs(r) <= 1e-9 * ft)
                break;
            (r < 0.0 ? lo : hi) = lat;
            real_t slope = elastic;
            if (it > 0 && lat != lat_prev)
            {
                const real_t secant = (r - r_prev) / (lat - lat_prev);
                if (secant > 1e-2 * elastic && secant < 1e2 * elastic)
                    slope = secant;
            }
            lat_prev = lat;
            r_prev = r;
            lat -= r / slope;
            if (!std::isnan(lo) && !std::isnan(hi) && !(lat > std::min(lo, hi) && lat < std::max(lo, hi)))
                lat = 0.5 * (lo + hi);
        }
        if (it == 60 && std::abs(hi - lo) <= 1e-12 * (1.0 + std::abs(lo)))
            ++out.jumps;
        else if (it == 60)
        {
            ++out.unheld;
            out.worst_lateral = std::max(out.worst_lateral, std::abs(r) / ft);
        }
        ++out.steps;
        work += 0.5 * (s[0] + trial[0]) * de;
        std::copy(trial, trial + 6, s);
        st = ts;
        peak = std::max(peak, s[0]);
        if (peak > 0.5 * ft && s[0] < 1e-3 * ft)
            break;
    }
    out.work = work;
    return out;
}

namespace
{
constexpr real_t kScaleLo = 1e-4, kScaleHi = 1e4;   // the widest bracket
constexpr real_t kNarrowLo = 1e-2, kNarrowHi = 1e2; // holds crack bands of about 1 mm to 1 m

/// The scale for length h in the bracket [scale_lo, scale_hi], given the works at its ends (they
/// do not depend on h, and the slow low end costs the most: many lengths share them).
real_t scale_for_length(const KccModel& m, real_t h, real_t scale_lo, real_t scale_hi, real_t work_lo, real_t work_hi)
{
    // root of f(x) = log W(e^x) - log(G_f / h), W decreasing in the scale e^x, bracketed:
    // regula falsi with the Illinois modification (superlinear, about 8 evaluations of the
    // tension test instead of bisection's 40), to |dx| < 1e-10
    const real_t target = std::log(m.fracture_energy / h);
    real_t a = std::log(scale_lo), b = std::log(scale_hi);
    real_t fa = std::log(work_lo) - target;
    if (fa <= 0.0)
        return std::exp(a);
    real_t fb = std::log(work_hi) - target;
    if (fb >= 0.0)
        return std::exp(b);
    int side = 0;
    real_t x = 0.5 * (a + b);
    for (int it = 0; it < 100; ++it)
    {
        x = (a * fb - b * fa) / (fb - fa);
        const real_t fx = std::log(kcc_tension_work(m, std::exp(x))) - target;
        if (fx == 0.0 || b - a < 1e-10)
            break;
        if ((fx > 0.0) == (fa > 0.0))
        {
            a = x;
            fa = fx;
            if (side == -1)
                fb *= 0.5;
            side = -1;
        }
        else
        {
            b = x;
            fb = fx;
            if (side == +1)
                fa *= 0.5;
            side = +1;
        }
        if (std::abs(fx) < 1e-12)
            break;
    }
    return std::exp(x);
}
} // namespace

real_t kcc_tension_scale_for_length(const KccModel& m, real_t h)
{
    const real_t target = m.fracture_energy / h;
    const real_t lo = kcc_tension_work(m, kNarrowLo), hi = kcc_tension_work(m, kNarrowHi);
    if (lo > target && hi < target)
        return scale_for_length(m, h, kNarrowLo, kNarrowHi, lo, hi);
    return scale_for_length(m, h, kScaleLo, kScaleHi, kcc_tension_work(m, kScaleLo), kcc_tension_work(m, kScaleHi));
}
} // namespace rkfem

namespace rkfem
{
std::vector<real_t> kcc_tension_scales(const KccModel& m, const std::vector<real_t>& h, KccScaleCache* solved)
{
    // distinct lengths to 1 nm
    std::vector<long long> keys(h.size());
    for (std::size_t p = 0; p < h.size(); ++p)
        keys[p] = std::llround(h[p] * 1e9);
    std::vector<long long> distinct = keys;
    std::sort(distinct.begin(), distinct.end());
    distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
    std::vector<real_t> out(h.size(), 1.0);
    if (distinct.empty())
        return out;
    const bool exact = distinct.size() <= static_cast<std::size_t>(kExactLengths);
    // the lengths solved exactly: every distinct one, or kExactLengths spaced in log h
    std::vector<real_t> lengths;
    if (exact)
        for (long long k : distinct)
            lengths.push_back(1e-9 * static_cast<real_t>(k));
    else
    {
        const real_t lo = std::log(1e-9 * static_cast<real_t>(distinct.front()));
        const real_t hi = std::log(1e-9 * static_cast<real_t>(distinct.back()));
        for (int i = 0; i < kExactLengths; ++i)
            lengths.push_back(std::exp(lo + (hi - lo) * i / (kExactLengths - 1)));
    }
    std::vector<real_t> scales(lengths.size());
    // the lengths no earlier call solved (all of them without a cache): the same length always
    // gets the same scale, so a cached one is the bits a solve would give
    std::vector<index_t> todo;
    for (std::size_t i = 0; i < lengths.size(); ++i)
    {
        const auto it = solved ? solved->find(lengths[i]) : KccScaleCache::iterator{};
        if (solved && it != solved->end())
            scales[i] = it->second;
        else
            todo.push_back(static_cast<index_t>(i));
    }
    if (!todo.empty())
    {
        // the narrow bracket's end works once; lengths outside it take the widest (rare)
        real_t narrow[2];
        parallel_for_tasks("rkfem::kcc::narrow_bracket", 2,
                           [&](index_t e) { narrow[e] = kcc_tension_work(m, e == 0 ? kNarrowLo : kNarrowHi); });
        parallel_for_tasks("rkfem::kcc::tension_scales", static_cast<index_t>(todo.size()),
                           [&](index_t t)
                           {
                               const std::size_t i = static_cast<std::size_t>(todo[static_cast<std::size_t>(t)]);
                               const real_t len = lengths[i];
                               const real_t target = m.fracture_energy / len;
                               scales[i] = narrow[0] > target && narrow[1] < target
                                               ? scale_for_length(m, len, kNarrowLo, kNarrowHi, narrow[0], narrow[1])
                                               : kcc_tension_scale_for_length(m, len);
                           });
        if (solved)
            for (const index_t i : todo)
                (*solved)[lengths[static_cast<std::size_t>(i)]] = scales[static_cast<std::size_t>(i)];
    }
    for (std::size_t p = 0; p < h.size(); ++p)
    {
        if (exact)
        {
            const std::size_t i = static_cast<std::size_t>(std::lower_bound(distinct.begin(), distinct.end(), keys[p]) -
                                                           distinct.begin());
            out[p] = scales[i];
            continue;
        }
        const real_t x = std::log(1e-9 * static_cast<real_t>(keys[p]));
        const real_t lo = std::log(lengths.front()), hi = std::log(lengths.back());
        const real_t u = hi > lo ? std::clamp((x - lo) / (hi - lo) * (kExactLengths - 1), 0.0,
                                              static_cast<real_t>(kExactLengths - 1))
                                 : 0.0;
        const int i = std::min(static_cast<int>(u), kExactLengths - 2);
        const real_t f = u - i;
        out[p] = std::exp((1 - f) * std::log(scales[static_cast<std::size_t>(i)]) +
                          f * std::log(scales[static_cast<std::size_t>(i) + 1]));
    }
    return out;
}
} // namespace rkfem
