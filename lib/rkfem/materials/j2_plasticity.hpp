#pragma once
/// @file j2_plasticity.hpp
/// Piecewise-linear J2 plasticity with failure (LS-DYNA *MAT_PIECEWISE_LINEAR_PLASTICITY analog,
/// LS-DYNA Keyword Manual Vol II, MAT_024; return: Simo & Hughes 1998, Computational Inelasticity):
/// hypoelastic, Jaumann rate (Hughes-Winget rotation),
/// radial return, yield stress piecewise linear in the effective plastic strain (extrapolated
/// with the last slope) or bilinear from SIGY and ETAN, Cowper-Symonds scaling by the total
/// strain rate sqrt(d:d) (VP = 0 form), and failure at a plastic strain: a failed point carries
/// no deviatoric stress and no tension. A pointwise value type: parameters are const, state
/// (stress, plastic strain, failed flag) is passed in and out.
#include <cmath>
#include <utility>
#include <vector>

#include "rkfem/materials/elastic.hpp"
#include "rkfem/materials/eos.hpp"
#include "rkfem/materials/objective_rate.hpp"

namespace rkfem
{
struct J2Params
{
    ElasticParams elastic;
    /// yield curve: (effective plastic strain, yield stress) points with eps_0 = 0, increasing
    std::vector<std::pair<real_t, real_t>> curve;
    real_t cs_c = 0.0, cs_p = 0.0; ///< Cowper-Symonds C [1/s] and P; C = 0: no rate effect
    real_t fail = 0.0;             ///< failure plastic strain; 0: none
    Eos eos;                       ///< pressure from an EOS (kind None: incremental K tr(D) dt)

    /// Bilinear: yield stress sigy, tangent modulus etan of the total-strain curve.
    static J2Params bilinear(ElasticParams el, real_t E, real_t sigy, real_t etan)
    {
        J2Params p;
        p.elastic = el;
        const real_t ep = E * etan / (E - etan); // plastic hardening modulus
        p.curve = {{0.0, sigy}, {1.0, sigy + ep}};
        return p;
    }
    /// sigma_y(eps) and its slope, piecewise linear, last slope beyond the last point.
    void yield(real_t eps, real_t& sy, real_t& slope) const
    {
        std::size_t k = 0;
        while (k + 2 < curve.size() && eps >= curve[k + 1].first)
            ++k;
        slope = (curve[k + 1].second - curve[k].second) / (curve[k + 1].first - curve[k].first);
        sy = curve[k].second + slope * (eps - curve[k].first);
    }
    real_t rate_factor(real_t rate) const
    {
        return cs_c > 0.0 && rate > 0.0 ? 1.0 + std::pow(rate / cs_c, 1.0 / cs_p) : 1.0;
    }
};

/// One update over dt with rate of deformation d (tensor shear) and spin w; s is the Voigt
/// stress, eps_p the effective plastic strain, failed 0/1. Returns the plastic strain increment.
/// With an EOS, ev (ln V/V0, accumulated tr(D) dt) and e (internal energy per reference volume,
/// accumulated from the stress power) are the point's volumetric history; the mean stress is
/// -p(ev, e) instead of the incremental bulk response.
inline real_t j2_update(const J2Params& p, const real_t d[6], const real_t w[3], real_t dt, real_t s[6], real_t& eps_p,
                        real_t& failed, real_t* ev = nullptr, real_t* e = nullptr)
{
    const bool with_eos = p.eos.kind != Eos::Kind::None && ev && e;
    real_t s_start[6];
    for (int k = 0; k < 6; ++k)
        s_start[k] = s[k];
    rotate_stress(w, dt, s);
    const real_t G = p.elastic.mu, K = p.elastic.bulk_modulus();
    const real_t tr = d[0] + d[1] + d[2];
    real_t pm = (s[0] + s[1] + s[2]) / 3.0 + K * tr * dt; // mean stress
    if (with_eos)
    {
        // volumetric strain, then the EOS at an energy predicted with the old stress power
        *ev += tr * dt;
        real_t power_old = 0.0;
        for (int k = 0; k < 3; ++k)
            power_old += s_start[k] * d[k] + 2.0 * s_start[k + 3] * d[k + 3];
        pm = -p.eos.pressure(*ev, *e + power_old * dt * std::exp(*ev));
    }
    real_t dev[6];
    for (int k = 0; k < 3; ++k)
        dev[k] = s[k] - (s[0] + s[1] + s[2]) / 3.0 + 2.0 * G * (d[k] - tr / 3.0) * dt;
    for (int k = 3; k < 6; ++k)
        dev[k] = s[k] + 2.0 * G * d[k] * dt;
    real_t dep = 0.0;
    if (failed != 0.0)
    {
        for (auto& x : dev)
            x = 0.0;
        pm = std::min(pm, 0.0);
    }
    else
    {
        const real_t J2 = 0.5 * (dev[0] * dev[0] + dev[1] * dev[1] + dev[2] * dev[2]) + dev[3] * dev[3] +
                          dev[4] * dev[4] + dev[5] * dev[5];
        const real_t q = std::sqrt(3.0 * J2);
        real_t dd = 0.0;
        for (int k = 0; k < 3; ++k)
            dd += d[k] * d[k] + 2.0 * d[k + 3] * d[k + 3];
        const real_t beta = p.rate_factor(std::sqrt(dd));
        real_t sy, h;
        p.yield(eps_p, sy, h);
        if (q > beta * sy)
        {
            // q - 3 G dep - beta sigma_y(eps_p + dep) = 0, exact segment by segment
            real_t e = eps_p;
            for (int it = 0; it < 64; ++it)
            {
                p.yield(e, sy, h);
                const real_t r = q - 3.0 * G * (e - eps_p) - beta * sy; // residual at e
                const real_t step = r / (3.0 * G + beta * h);
                // next breakpoint of the curve above e
                real_t next = kNoLimit;
                for (const auto& c : p.curve)
                    if (c.first > e * (1 + 1e-14) + 1e-300)
                    {
                        next = c.first;
                        break;
                    }
                if (e + step <= next || next == p.curve.back().first)
                {
                    e += step;
                    break;
                }
                e = next;
            }
            dep = e - eps_p;
            const real_t scale = 1.0 - 3.0 * G * dep / q;
            for (auto& x : dev)
                x *= scale;
            eps_p = e;
            if (p.fail > 0.0 && eps_p >= p.fail)
            {
                failed = 1.0;
                for (auto& x : dev)
                    x = 0.0;
                pm = std::min(pm, 0.0);
            }
        }
    }
    for (int k = 0; k < 3; ++k)
        s[k] = dev[k] + pm;
    for (int k = 3; k < 6; ++k)
        s[k] = dev[k];
    if (with_eos) // internal energy per reference volume: trapezoid of the stress power, times J
    {
        real_t power = 0.0;
        for (int k = 0; k < 3; ++k)
            power += 0.5 * (s_start[k] + s[k]) * d[k] + (s_start[k + 3] + s[k + 3]) * d[k + 3];
        *e += power * dt * std::exp(*ev);
    }
    return dep;
}

} // namespace rkfem
