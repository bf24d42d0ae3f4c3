#pragma once
/// @file point_history.hpp
/// The inelastic model of a block and its per-point history beyond the stress, committed/trial
/// like the stress: J2 (effective plastic strain, failed flag), K&C concrete (damage function,
/// volumetric strains, plastic strain) or the continuous surface cap model (undamaged stress,
/// strain, cap, damage). Elastic blocks have none (active() is false). The kernels call update()
/// per point; the branch on the kind is uniform over a block.
#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <vector>

#include "rkfem/core/parallel.hpp"
#include "rkfem/materials/cscm_concrete.hpp"
#include "rkfem/materials/j2_plasticity.hpp"
#include "rkfem/materials/kcc_concrete.hpp"

namespace rkfem
{
struct PlasticPoints
{
    enum class Kind
    {
        None,
        J2,
        Kcc,
        Cscm,
    };
    Kind kind = Kind::None;
    J2Params params;
    KccModel kcc;
    /// kcc's tensile damage scales per crack-band length solved (set_lengths, set_length). Shared
    /// by the blocks a converting part builds again at each event (its FE side and nodal block:
    /// Model hands the old blocks' cache to the new ones), so each length is solved once per part.
    std::shared_ptr<KccScaleCache> kcc_scales = std::make_shared<KccScaleCache>();
    std::vector<real_t> eps_p, eps_p_trial, failed, failed_trial; ///< J2; eps_p also for output (Kcc)
    std::vector<KccState> kcc_state, kcc_trial;
    CscmModel cscm;
    std::vector<CscmState> cscm_state, cscm_trial;
    std::vector<real_t> ev, ev_trial, energy, energy_trial; ///< J2 with an EOS: ln(V/V0), E [J/m^3]

    /// J2 points with the parameters p.
    void set_j2(const J2Params& p)
    {
        kind = Kind::J2;
        params = p;
    }
    /// K&C points of model m.
    void set_kcc(const KccModel& m)
    {
        kind = Kind::Kcc;
        kcc = m;
        kcc_scales = std::make_shared<KccScaleCache>();
    }
    /// CSCM points of model m.
    void set_cscm(const CscmModel& m)
    {
        kind = Kind::Cscm;
        cscm = m;
    }
    bool active() const { return kind != Kind::None; }
    /// Committed 0..1 damage index of point p: J2 the failed flag; K&C D = clamp(delta - 1, 0, 1)
    /// (0 at the peak, 1 on the residual surface; materials.md 1.6); CSCM its damage d.
    real_t damage(std::size_t p) const
    {
        if (kind == Kind::Kcc)
            return std::clamp(kcc_delta(p) - 1.0, 0.0, 1.0);
        return kind == Kind::None ? 0.0 : failed[p];
    }
    /// K&C scaled damage delta = 2 lambda / (lambda + lambda_m) (0..2), 0 for other models.
    real_t kcc_delta(std::size_t p) const { return kind == Kind::Kcc ? kcc.surfaces.scaled_damage(failed[p]) : 0.0; }
    void resize(std::size_t n)
    {
        eps_p.assign(n, 0.0);
        eps_p_trial.assign(n, 0.0);
        failed.assign(n, 0.0);
        failed_trial.assign(n, 0.0);
        if (kind == Kind::Kcc)
        {
            kcc_state.assign(n, KccState{});
            kcc_trial.assign(n, KccState{});
        }
        if (kind == Kind::Cscm)
        {
            cscm_state.assign(n, CscmState{});
            cscm_trial.assign(n, CscmState{});
        }
        if (kind == Kind::J2 && params.eos.kind != Eos::Kind::None)
        {
            ev.assign(n, 0.0);
            ev_trial.assign(n, 0.0);
            energy.assign(n, 0.0);
            energy_trial.assign(n, 0.0);
        }
    }
    /// Calls f(committed, trial) for each history array pair, and with `other` (a block of the
    /// same model) f(committed, trial, other's committed): the one list of the state's arrays.
    template <class F> void each_array(F&& f) { each_array_of(*this, f); }
    template <class F> void each_array(F&& f) const { each_array_of(*this, f); }
    /// Every committed and trial array of `self` (const or not), in one order.
    template <class Self, class F> static void each_array_of(Self& self, F& f)
    {
        f(self.eps_p, self.eps_p_trial);
        f(self.failed, self.failed_trial);
        f(self.kcc_state, self.kcc_trial);
        f(self.cscm_state, self.cscm_trial);
        f(self.ev, self.ev_trial);
        f(self.energy, self.energy_trial);
    }
    template <class F> void each_array(const PlasticPoints& other, F&& f)
    {
        f(eps_p, eps_p_trial, other.eps_p);
        f(failed, failed_trial, other.failed);
        f(kcc_state, kcc_trial, other.kcc_state);
        f(cscm_state, cscm_trial, other.cscm_state);
        f(ev, ev_trial, other.ev);
        f(energy, energy_trial, other.energy);
    }
    /// Copies the committed history of point `from` of `src` (the same model) into point `to`,
    /// trial = committed: state that moves between blocks (an element's points to the particles
    /// that replace it).
    void copy_point(const PlasticPoints& src, std::size_t from, std::size_t to)
    {
        each_array(src,
                   [&](auto& committed, auto& trial, const auto& other)
                   {
                       if (committed.empty())
                           return;
                       committed[to] = other[from];
                       trial[to] = other[from];
                   });
    }
    /// One share of the material a point takes over in blend_point: the committed history of point
    /// `point` of `from` (a block of the same model), over `weight` (its volume).
    struct Share
    {
        const PlasticPoints* from;
        std::size_t point;
        real_t weight;
    };
    /// Point `to` takes the history of the material its shares held (an event that hands a volume
    /// from points of one kind to those of another: a fem-1pt element's octants to the particles
    /// that take them, or back): each measure the volume-weighted mean of the shares', except the
    /// damage measures (J2's failed flag, K&C's damage function lambda), which take the largest.
    /// K&C's crack-band scale stays `to`'s own (it follows the point's length). Shares that are
    /// all one point give its values as they are. Trial = committed. CSCM history (thresholds set
    /// at first yield) has no such mean: refused (the deck refuses it first).
    void blend_point(const Share* s, std::size_t n, std::size_t to)
    {
        if (kind == Kind::None || n == 0)
            return;
        if (kind == Kind::Cscm)
            throw std::logic_error("PlasticPoints::blend_point: CSCM history is not blended");
        bool one = true;
        real_t total = 0.0;
        for (std::size_t k = 0; k < n; ++k)
        {
            one = one && s[k].from == s[0].from && s[k].point == s[0].point;
            total += s[k].weight;
        }
        auto mean = [&](auto get)
        {
            if (one)
                return get(*s[0].from, s[0].point);
            real_t m = 0.0;
            for (std::size_t k = 0; k < n; ++k)
                m += s[k].weight * get(*s[k].from, s[k].point);
            return m / total;
        };
        auto largest = [&](auto get)
        {
            real_t m = get(*s[0].from, s[0].point);
            for (std::size_t k = 1; k < n; ++k)
                m = std::max(m, get(*s[k].from, s[k].point));
            return m;
        };
        eps_p[to] = eps_p_trial[to] = mean([](const PlasticPoints& b, std::size_t p) { return b.eps_p[p]; });
        failed[to] = failed_trial[to] = largest([](const PlasticPoints& b, std::size_t p) { return b.failed[p]; });
        if (kind == Kind::Kcc)
        {
            KccState st = kcc_state[to];
            st.lambda = largest([](const PlasticPoints& b, std::size_t p) { return b.kcc_state[p].lambda; });
            st.ev = mean([](const PlasticPoints& b, std::size_t p) { return b.kcc_state[p].ev; });
            st.ev_min = mean([](const PlasticPoints& b, std::size_t p) { return b.kcc_state[p].ev_min; });
            st.ev_plastic = mean([](const PlasticPoints& b, std::size_t p) { return b.kcc_state[p].ev_plastic; });
            st.eps_p = mean([](const PlasticPoints& b, std::size_t p) { return b.kcc_state[p].eps_p; });
            kcc_state[to] = kcc_trial[to] = st;
        }
        if (!ev.empty())
        {
            ev[to] = ev_trial[to] = mean([](const PlasticPoints& b, std::size_t p) { return b.ev[p]; });
            energy[to] = energy_trial[to] = mean([](const PlasticPoints& b, std::size_t p) { return b.energy[p]; });
        }
    }
    /// Keeps the committed state of points from[0], from[1], ... as points 0, 1, ... (an event
    /// that removes or reorders points); trial state = committed.
    void gather(const std::vector<index_t>& from)
    {
        each_array(
            [&](auto& committed, auto& trial)
            {
                if (committed.empty())
                    return;
                auto out = committed;
                out.resize(from.size());
                for (std::size_t q = 0; q < from.size(); ++q)
                    out[q] = committed[static_cast<std::size_t>(from[q])];
                committed = out;
                trial = std::move(out);
            });
    }
    /// Crack-band lengths per point (element size, nodal spacing): with a fracture energy, each
    /// K&C point gets the tensile damage scale that dissipates G_f over its length
    /// (kcc_tension_scales: one solve per distinct length, or a table over the range);
    /// each CSCM point gets the softening A, C of its length.
    void set_lengths(const std::vector<real_t>& h)
    {
        if (kind == Kind::Cscm)
        {
            for (std::size_t p = 0; p < h.size() && p < cscm_state.size(); ++p)
            {
                const CscmModel::Softening sf = cscm.softening(h[p]);
                cscm_state[p].A = cscm_trial[p].A = sf.A;
                cscm_state[p].C = cscm_trial[p].C = sf.C;
            }
            return;
        }
        if (kind != Kind::Kcc || !(kcc.fracture_energy > 0))
            return;
        const std::vector<real_t> scale = kcc_tension_scales(kcc, h, kcc_scales.get());
        for (std::size_t p = 0; p < h.size() && p < kcc_state.size(); ++p)
            kcc_state[p].tension_scale = kcc_trial[p].tension_scale = scale[p];
    }
    /// Point p's crack-band length alone (set_lengths for one point: a particle made by splitting).
    void set_length(std::size_t p, real_t h)
    {
        if (kind == Kind::Cscm && p < cscm_state.size())
        {
            const CscmModel::Softening sf = cscm.softening(h);
            cscm_state[p].A = cscm_trial[p].A = sf.A;
            cscm_state[p].C = cscm_trial[p].C = sf.C;
        }
        if (kind == Kind::Kcc && kcc.fracture_energy > 0 && p < kcc_state.size())
            kcc_state[p].tension_scale = kcc_trial[p].tension_scale = kcc_tension_scales(kcc, {h}, kcc_scales.get())[0];
    }
    /// n points, the first ones kept as they are and the new ones at the arrays' initial values
    /// (a pool of particles reserved for refinement; each takes a state when it is used).
    void grow(std::size_t n)
    {
        each_array(
            [&](auto& committed, auto& trial)
            {
                if (committed.empty())
                    return;
                committed.resize(n);
                trial.resize(n);
            });
    }
    void commit()
    {
        each_array([](auto& committed, auto& trial) { committed.swap(trial); });
    }
    /// Trial history of point p = its committed history.
    void keep(std::size_t p)
    {
        eps_p_trial[p] = eps_p[p];
        failed_trial[p] = failed[p];
        if (kind == Kind::Kcc)
            kcc_trial[p] = kcc_state[p];
        else if (kind == Kind::Cscm)
            cscm_trial[p] = cscm_state[p];
        else if (!ev.empty())
        {
            ev_trial[p] = ev[p];
            energy_trial[p] = energy[p];
        }
    }
    /// update() for W lanes of J2 points at once where their trial stress stays inside the yield
    /// surface (most points on most steps): j2_update's elastic path (rotation, trial, yield
    /// check, s = dev + p) in one lane loop that the compiler vectorizes, with the same
    /// operations per lane; GCC fuses some of them differently there than in j2_update, so the
    /// stress agrees with update()'s to a few units in the last place of the largest component
    /// (test_j2: ElasticLanesAgreeWithTheUpdate), not bit for bit. Lanes l < nl are points pt[l]; s holds
    /// their committed stress in and, for the lanes it updates (elastic[l]), the new stress out,
    /// with trial history = committed. The other lanes keep s and need update(). No lane is
    /// taken with an EOS, a rate effect, dt = 0 or a failed point. The plain twin is update().
    template <int W>
    void j2_elastic_lanes(const std::size_t (&pt)[W], int nl, const real_t (&d)[6][W], const real_t (&w)[3][W],
                          real_t dt, real_t (&s)[6][W], bool (&elastic)[W])
    {
        for (int l = 0; l < W; ++l)
            elastic[l] = false;
        if (kind != Kind::J2 || !ev.empty() || params.cs_c > 0.0 || dt == 0.0)
            return;
        alignas(64) real_t sy[W], ok[W];
        for (int l = 0; l < W; ++l)
        {
            const std::size_t p = pt[l < nl ? l : 0];
            real_t h;
            params.yield(eps_p[p], sy[l], h);
            ok[l] = 0.0;
            if (failed[p] != 0.0)
                sy[l] = -1.0; // never elastic here: update() zeroes its deviator
        }
        const real_t G = params.elastic.mu, K = params.elastic.bulk_modulus();
        RKFEM_SIMD()
        for (int l = 0; l < W; ++l)
        {
            real_t s0 = s[0][l], s1 = s[1][l], s2 = s[2][l], s3 = s[3][l], s4 = s[4][l], s5 = s[5][l];
            rotate_stress(w[0][l], w[1][l], w[2][l], dt, s0, s1, s2, s3, s4, s5);
            const real_t d0 = d[0][l], d1 = d[1][l], d2 = d[2][l];
            const real_t tr = d0 + d1 + d2;
            const real_t pm = (s0 + s1 + s2) / 3.0 + K * tr * dt;
            const real_t e0 = s0 - (s0 + s1 + s2) / 3.0 + 2.0 * G * (d0 - tr / 3.0) * dt;
            const real_t e1 = s1 - (s0 + s1 + s2) / 3.0 + 2.0 * G * (d1 - tr / 3.0) * dt;
            const real_t e2 = s2 - (s0 + s1 + s2) / 3.0 + 2.0 * G * (d2 - tr / 3.0) * dt;
            const real_t e3 = s3 + 2.0 * G * d[3][l] * dt, e4 = s4 + 2.0 * G * d[4][l] * dt,
                         e5 = s5 + 2.0 * G * d[5][l] * dt;
            const real_t J2 = 0.5 * (e0 * e0 + e1 * e1 + e2 * e2) + e3 * e3 + e4 * e4 + e5 * e5;
            const real_t q = std::sqrt(3.0 * J2);
            const bool in = !(q > sy[l]) && sy[l] >= 0.0;
            ok[l] = in ? 1.0 : 0.0;
            s[0][l] = in ? e0 + pm : s[0][l];
            s[1][l] = in ? e1 + pm : s[1][l];
            s[2][l] = in ? e2 + pm : s[2][l];
            s[3][l] = in ? e3 : s[3][l];
            s[4][l] = in ? e4 : s[4][l];
            s[5][l] = in ? e5 : s[5][l];
        }
        for (int l = 0; l < nl; ++l)
            if (ok[l] != 0.0)
            {
                elastic[l] = true;
                eps_p_trial[pt[l]] = eps_p[pt[l]];
                failed_trial[pt[l]] = failed[pt[l]];
            }
    }
    /// Updates point p from its committed history into the trial arrays; returns the plastic
    /// work density increment (K&C and CSCM; 0 for J2). With dt = 0 (a stepper starting again
    /// after an event or a restart evaluates forces without a step) the trial history is the
    /// committed one and s is left as it is: a rate-dependent surface seen at the new state's
    /// strain rate would otherwise return the stress with no strain increment, adding damage at
    /// every restart.
    /// The kernels call it with the block's kind as a compile-time constant (dispatch_kind), so
    /// the model is chosen once per block, not per point.
    template <Kind K> real_t update_as(std::size_t p, const real_t d[6], const real_t w[3], real_t dt, real_t s[6])
    {
        if (dt == 0.0)
        {
            keep(p);
            return 0.0;
        }
        if constexpr (K == Kind::Kcc)
        {
            KccState st = kcc_state[p];
            const real_t work = kcc_update(kcc, d, w, dt, s, st);
            kcc_trial[p] = st;
            eps_p_trial[p] = st.eps_p;
            failed_trial[p] = st.lambda; // damage function (0 intact) [output]
            return work;
        }
        else if constexpr (K == Kind::Cscm)
        {
            CscmState st = cscm_state[p];
            const real_t work = cscm_update(cscm, d, w, dt, s, st);
            cscm_trial[p] = st;
            eps_p_trial[p] = st.eps_p;
            failed_trial[p] = st.d; // damage 0..1 [output]
            return work;
        }
        else
        {
            real_t e = eps_p[p], f = failed[p];
            if (!ev.empty())
            {
                real_t v = ev[p], en = energy[p];
                j2_update(params, d, w, dt, s, e, f, &v, &en);
                ev_trial[p] = v;
                energy_trial[p] = en;
            }
            else
                j2_update(params, d, w, dt, s, e, f);
            eps_p_trial[p] = e;
            failed_trial[p] = f;
            return 0.0;
        }
    }
    /// update_as with the block's kind chosen at run time (for callers outside the kernels).
    real_t update(std::size_t p, const real_t d[6], const real_t w[3], real_t dt, real_t s[6])
    {
        switch (kind)
        {
        case Kind::Kcc:
            return update_as<Kind::Kcc>(p, d, w, dt, s);
        case Kind::Cscm:
            return update_as<Kind::Cscm>(p, d, w, dt, s);
        default:
            return update_as<Kind::J2>(p, d, w, dt, s);
        }
    }
};

/// Calls f.template operator()<K>() with kind k as a compile-time constant: the one dispatch of a
/// block's force pass on its material (Kind::None: elastic).
template <class F> void dispatch_kind(PlasticPoints::Kind k, F&& f)
{
    switch (k)
    {
    case PlasticPoints::Kind::None:
        return f.template operator()<PlasticPoints::Kind::None>();
    case PlasticPoints::Kind::J2:
        return f.template operator()<PlasticPoints::Kind::J2>();
    case PlasticPoints::Kind::Kcc:
        return f.template operator()<PlasticPoints::Kind::Kcc>();
    case PlasticPoints::Kind::Cscm:
        return f.template operator()<PlasticPoints::Kind::Cscm>();
    }
}
} // namespace rkfem
