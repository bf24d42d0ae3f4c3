#include "rkfem/analysis/material_point.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>

#include "rkfem/core/error.hpp"
#include "rkfem/materials/j2_plasticity.hpp"
#include "rkfem/materials/kcc_concrete.hpp"

namespace rkfem
{
namespace
{
struct PointMaterial
{
    ElasticParams elastic;
    J2Params j2;
    bool plastic = false;
    bool kcc = false;
    KccModel kcc_model;
    // committed state
    real_t s[6] = {};
    real_t ep = 0.0, failed = 0.0;
    KccState kcc_state;
    mutable KccState kcc_trial;
    real_t ev = 0.0, energy = 0.0; ///< J2 with an EOS
    mutable real_t ev_trial = 0.0, energy_trial = 0.0;
    mutable real_t work_trial = 0.0;

    /// Trial update from the committed state; commit = true keeps it.
    void update(const real_t d[6], const real_t w[3], real_t dt, real_t out[6], real_t& ep_out, real_t& f_out) const
    {
        std::copy(s, s + 6, out);
        ep_out = ep;
        f_out = failed;
        if (kcc)
        {
            kcc_trial = kcc_state;
            work_trial = kcc_update(kcc_model, d, w, dt, out, kcc_trial);
            ep_out = kcc_trial.eps_p;
            f_out = kcc_trial.lambda; // the damage function in the `failed` column for kcc
        }
        else if (plastic)
        {
            ev_trial = ev;
            energy_trial = energy;
            j2_update(j2, d, w, dt, out, ep_out, f_out, &ev_trial, &energy_trial);
        }
        else
            elastic_update(elastic, d, w, dt, out);
    }
};
} // namespace

std::vector<MaterialPointRecord> run_material_point(const MaterialPointDeck& deck)
{
    const MaterialSpec& ms = deck.material;
    PointMaterial pm;
    pm.elastic = ElasticParams::from_E_nu(ms.rho, ms.E, ms.nu);
    pm.j2 = j2_params(ms);
    pm.plastic = pm.j2.curve.size() > 0;
    if (ms.model == "kcc")
    {
        pm.kcc = true;
        pm.kcc_model = KccModel::from_fc(ms.fc, ms.rho, ms.nu, ms.E);
        pm.kcc_model.rate_effects = ms.rate_effects;
        // the lateral Newton uses the elastic constants of the model
        pm.elastic.mu = pm.kcc_model.shear;
        pm.elastic.lambda = pm.kcc_model.bulk - 2.0 * pm.kcc_model.shear / 3.0;
    }
    const MaterialPathSpec& lp = deck.load_path;
    const real_t T = std::abs(lp.strain) / lp.rate;
    const int n = lp.steps;
    const real_t sign = lp.strain < 0 ? -1.0 : 1.0;
    real_t k_lat = 2.0 * (pm.elastic.lambda + pm.elastic.mu); // d(sigma_yy + sigma_zz)/2 / d(lateral rate dt)
    real_t k_iso = 3.0 * pm.elastic.bulk_modulus();
    std::vector<MaterialPointRecord> h;
    MaterialPointRecord rec;
    h.push_back(rec);
    const bool triaxial = lp.type == "triaxial";
    const int n_pre = triaxial ? std::max(1, n / 4) : 0;
    const int n_total = n + n_pre + (lp.type == "rotation" ? n : 0);
    real_t lat = lp.type == "uniaxial-stress" ? -ms.nu * sign * lp.rate : 0.0; // lateral strain rate guess
    real_t t = 0.0;
    for (int k = 0; k < n_total; ++k)
    {
        real_t d[6] = {}, w[3] = {};
        real_t dt = T / n;
        const bool pre = k < n_pre;
        const bool spin = lp.type == "rotation" && k >= n;
        real_t trial[6], ep, f;
        if (pre)
        {
            // isotropic compression to -confinement: solve the rate for the target mean stress
            const real_t target = -lp.confinement * (k + 1) / n_pre;
            real_t e = 0.0;
            for (int it = 0; it < 100; ++it)
            {
                const real_t dd[6] = {e, e, e, 0, 0, 0};
                pm.update(dd, w, dt, trial, ep, f);
                const real_t r = (trial[0] + trial[1] + trial[2]) / 3.0 - target;
                if (std::abs(r) <= 1e-10 * (std::abs(target) + pm.elastic.mu * 1e-6))
                    break;
                e -= r / (k_iso * dt / 3.0 * 3.0); // d(mean stress)/d(e dt) = 3 K
            }
            d[0] = d[1] = d[2] = e;
        }
        else if (spin)
        {
            w[0] = -lp.angle / T; // W_xy = -omega_z
        }
        else if (lp.type == "uniaxial-stress" || triaxial)
        {
            const real_t target = triaxial ? -lp.confinement : 0.0;
            for (int it = 0; it < 100; ++it)
            {
                const real_t dd[6] = {sign * lp.rate, lat, lat, 0, 0, 0};
                pm.update(dd, w, dt, trial, ep, f);
                const real_t r = 0.5 * (trial[1] + trial[2]) - target;
                if (std::abs(r) <= 1e-10 * (std::abs(trial[0]) + std::abs(target) + 1.0))
                    break;
                lat -= r / (k_lat * dt);
            }
            d[0] = sign * lp.rate;
            d[1] = d[2] = lat;
        }
        else if (lp.type == "uniaxial-strain" || lp.type == "rotation")
            d[0] = sign * lp.rate;
        else if (lp.type == "hydrostatic")
            d[0] = d[1] = d[2] = sign * lp.rate / 3.0;
        else if (lp.type == "pure-shear")
            d[3] = 0.5 * sign * lp.rate;
        else
            throw Error("material point: unknown path type '" + lp.type + "'");
        pm.update(d, w, dt, trial, ep, f);
        std::copy(trial, trial + 6, pm.s);
        pm.ep = ep;
        pm.failed = f;
        if (pm.kcc)
        {
            pm.kcc_state = pm.kcc_trial;
            rec.work += pm.work_trial;
        }
        else if (pm.plastic)
        {
            pm.ev = pm.ev_trial;
            pm.energy = pm.energy_trial;
        }
        t += dt;
        rec.time = t;
        for (int c = 0; c < 6; ++c)
        {
            rec.strain[c] += d[c] * dt;
            rec.stress[c] = pm.s[c];
        }
        rec.plastic_strain = pm.ep;
        rec.failed = pm.failed;
        h.push_back(rec);
    }
    return h;
}

void write_material_point(const std::vector<MaterialPointRecord>& h, const std::string& out_dir)
{
    std::filesystem::create_directories(out_dir);
    std::ofstream o(out_dir + "/stress_strain.csv");
    RKFEM_REQUIRE(o, "cannot write " << out_dir << "/stress_strain.csv");
    o.precision(12);
    o << "time,eps_xx,eps_yy,eps_zz,eps_xy,eps_yz,eps_zx,sig_xx,sig_yy,sig_zz,sig_xy,sig_yz,sig_zx,plastic_strain,failed\n";
    for (const auto& r : h)
    {
        o << r.time;
        for (real_t v : r.strain)
            o << ',' << v;
        for (real_t v : r.stress)
            o << ',' << v;
        o << ',' << r.plastic_strain << ',' << r.failed << '\n';
    }
}
} // namespace rkfem
