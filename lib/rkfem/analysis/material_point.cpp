#include "rkfem/analysis/material_point.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "rkfem/config/deck.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/io/hdf5_dataset.hpp"
#include "rkfem/materials/point_history.hpp"
#include "rkfem/model/material_from_deck.hpp"

namespace rkfem
{
namespace
{
/// One point of the deck's material: elastic, or the block models' PlasticPoints with one point
/// (so the driver exercises exactly the update the force loops call).
struct PointMaterial
{
    ElasticParams elastic;
    PlasticPoints plastic;
    real_t s[6] = {}; ///< committed stress
    real_t work_trial = 0.0;

    /// Trial update from the committed state into out (and the plastic trial arrays).
    void update(const real_t d[6], const real_t w[3], real_t dt, real_t out[6], real_t& ep_out, real_t& f_out)
    {
        std::copy(s, s + 6, out);
        ep_out = f_out = 0.0;
        if (!plastic.active())
        {
            elastic_update(elastic, d, w, dt, out);
            return;
        }
        work_trial = plastic.update(0, d, w, dt, out);
        ep_out = plastic.eps_p_trial[0];
        f_out = plastic.failed_trial[0];
    }
};
} // namespace

std::vector<MaterialPointRecord> run_material_point(const MaterialPointDeck& deck)
{
    const MaterialSpec& ms = deck.material;
    PointMaterial pm;
    pm.elastic = ElasticParams::from_E_nu(ms.rho, ms.E, ms.nu);
    configure_points(pm.plastic, ms);
    pm.plastic.resize(1);
    if (deck.load_path.length > 0)
        pm.plastic.set_lengths({deck.load_path.length});
    if (pm.plastic.kind == PlasticPoints::Kind::Kcc)
    {
        // the lateral Newton uses the elastic constants of the model
        pm.elastic.mu = pm.plastic.kcc.shear;
        pm.elastic.lambda = pm.plastic.kcc.bulk - 2.0 * pm.plastic.kcc.shear / 3.0;
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
        if (pm.plastic.active())
        {
            pm.plastic.commit();
            rec.work += pm.work_trial;
        }
        t += dt;
        rec.time = t;
        for (int c = 0; c < 6; ++c)
        {
            rec.strain[c] += d[c] * dt;
            rec.stress[c] = pm.s[c];
        }
        rec.plastic_strain = ep;
        rec.failed = f;
        bool finite = std::isfinite(rec.time) && std::isfinite(ep) && std::isfinite(f) && std::isfinite(rec.work);
        for (int c = 0; c < 6; ++c)
            finite = finite && std::isfinite(rec.strain[c]) && std::isfinite(rec.stress[c]);
        if (!finite)
        {
            // nothing is written: a table with NaN or inf rows is not a result
            std::ostringstream os;
            os << "the point's state is not finite at step " << k + 1 << " of " << n_total << " (t = " << rec.time
               << " s, strain xx " << rec.strain[0] << ", stress xx " << rec.stress[0] << " Pa)";
            throw DeckError(lp.loc, os.str(),
                            "expected a path the material can follow: check path.strain, path.rate, path.angle and "
                            "the material's parameters");
        }
        h.push_back(rec);
    }
    return h;
}

void write_material_point(const std::vector<MaterialPointRecord>& h, const std::string& out_dir)
{
    std::filesystem::create_directories(out_dir);
    {
        // the same history in HDF5: time, strain (n x 6), stress (n x 6), plastic_strain, failed, work
        const std::size_t n = h.size();
        std::vector<real_t> time(n), strain(6 * n), stress(6 * n), ep(n), failed(n), work(n);
        for (std::size_t k = 0; k < n; ++k)
        {
            time[k] = h[k].time;
            ep[k] = h[k].plastic_strain;
            failed[k] = h[k].failed;
            work[k] = h[k].work;
            for (int c = 0; c < 6; ++c)
            {
                strain[6 * k + c] = h[k].strain[c];
                stress[6 * k + c] = h[k].stress[c];
            }
        }
        const hid_t f = H5Fcreate((out_dir + "/stress_strain.h5").c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
        RKFEM_REQUIRE(f >= 0, "cannot write " << out_dir << "/stress_strain.h5");
        write_dataset(f, "time", time.data(), n);
        write_dataset(f, "strain", strain.data(), n, 6);
        write_dataset(f, "stress", stress.data(), n, 6);
        write_dataset(f, "plastic_strain", ep.data(), n);
        write_dataset(f, "failed", failed.data(), n);
        write_dataset(f, "work", work.data(), n);
        H5Fclose(f);
    }
    std::filesystem::create_directories(out_dir);
    std::ofstream o(out_dir + "/stress_strain.csv");
    RKFEM_REQUIRE(o, "cannot write " << out_dir << "/stress_strain.csv");
    o.precision(12);
    o << "time,eps_xx,eps_yy,eps_zz,eps_xy,eps_yz,eps_zx,sig_xx,sig_yy,sig_zz,sig_xy,sig_yz,sig_zx,plastic_strain,"
         "failed,work\n";
    for (const auto& r : h)
    {
        o << r.time;
        for (real_t v : r.strain)
            o << ',' << v;
        for (real_t v : r.stress)
            o << ',' << v;
        o << ',' << r.plastic_strain << ',' << r.failed << ',' << r.work << '\n';
    }
}
} // namespace rkfem
