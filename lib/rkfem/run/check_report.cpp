#include "rkfem/run/check_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <vector>

#include "rkfem/core/parallel.hpp"
#include "rkfem/model/model.hpp"

namespace rkfem
{
namespace
{
/// "name = value unit" entries, wrapped at about 100 characters with a "#     " indent.
class Lines
{
  public:
    explicit Lines(std::ostringstream& os) : os_(os) {}
    /// With `generated` (a value the deck overrode), the generated one follows in brackets.
    void add(const char* name, real_t value, const char* unit, real_t generated = std::nan(""))
    {
        char b[128];
        if (!std::isnan(generated) && std::abs(value - generated) > 1e-9 * std::abs(generated))
            std::snprintf(b, sizeof b, "%s = %.6g%s%s (deck; generated %.6g)", name, value, *unit ? " " : "", unit,
                          generated);
        else
            std::snprintf(b, sizeof b, "%s = %.6g%s%s", name, value, *unit ? " " : "", unit);
        if (width_ + std::string(b).size() > 96)
            flush();
        line_ += (line_.empty() ? "" : ", ") + std::string(b);
        width_ = line_.size();
    }
    void flush()
    {
        if (!line_.empty())
            os_ << "#     " << line_ << "\n";
        line_.clear();
        width_ = 0;
    }

  private:
    std::ostringstream& os_;
    std::string line_;
    std::size_t width_ = 0;
};

void kcc(std::ostringstream& os, const KccModel& m)
{
    const KccParameters& k = m.surfaces;
    const real_t E = 9 * m.bulk * m.shear / (3 * m.bulk + m.shear);
    const real_t nu = (3 * m.bulk - 2 * m.shear) / (2 * (3 * m.bulk + m.shear));
    const KccModel gen = KccModel::from_fc(k.fc, m.rho, nu, E); // what f'c alone generates
    const KccParameters& g = gen.surfaces;
    os << "#   K&C concrete Release III (MAT_072R3), generated from f'c:\n";
    Lines l(os);
    l.add("fc", k.fc, "Pa");
    l.add("ft", k.ft, "Pa", g.ft);
    l.add("E", E, "Pa");
    l.add("nu", nu, "");
    l.add("K1", m.bulk, "Pa");
    l.add("G", m.shear, "Pa");
    l.add("a0", k.a0, "Pa", g.a0);
    l.add("a1", k.a1, "", g.a1);
    l.add("a2", k.a2, "1/Pa", g.a2);
    l.add("a0y", k.a0y, "Pa", g.a0y);
    l.add("a1y", k.a1y, "", g.a1y);
    l.add("a2y", k.a2y, "1/Pa", g.a2y);
    l.add("a1f", k.a1f, "", g.a1f);
    l.add("a2f", k.a2f, "1/Pa", g.a2f);
    l.add("b1", k.b1, "", g.b1);
    l.add("b2", k.b2, "", g.b2);
    l.add("b3", k.b3, "", g.b3);
    l.add("omega", k.omega, "", g.omega);
    l.add("edrop", k.edrop, "", g.edrop);
    l.add("lambda_m", k.lambda_m, "", g.lambda_m);
    l.add("lambda_z", k.lambda_z, "", g.lambda_z);
    l.add("fbc/fc", k.alpha_biaxial, "");
    l.add("fyc", k.fyc, "Pa", g.fyc);
    l.add("psi_biaxial", k.psi_biaxial, "", g.psi_biaxial);
    l.add("fracture_energy", m.fracture_energy, "J/m^2");
    l.flush();
    os << "#     rate effects: " << m.rate.describe() << "\n";
    if (m.rate.kind == RateLaw::Kind::Curve)
    {
        os << "#     DIF(rate [1/s]):";
        for (const auto& [r, d] : m.rate.curve)
            os << " (" << r << ", " << d << ")";
        os << "\n";
    }
    else if (m.rate.active())
    {
        os << "#     DIF at 1, 10^2, 10^4 1/s: compression";
        for (real_t r : {1.0, 1e2, 1e4})
            os << " " << m.rate.dif(r, false);
        os << "; tension";
        for (real_t r : {1.0, 1e2, 1e4})
            os << " " << m.rate.dif(r, true);
        os << "\n";
    }
    os << "#     eta(lambda)" << (k.eta_table == g.eta_table ? "" : " (deck's)") << ":";
    for (const auto& [lam, eta] : k.eta_table)
        os << " (" << lam << ", " << eta << ")";
    // (to 1e-9: E and nu printed and read back move the generated table at round-off)
    auto differs = [](const std::array<real_t, 10>& a, const std::array<real_t, 10>& b)
    {
        for (std::size_t i = 0; i < a.size(); ++i)
            if (std::abs(a[i] - b[i]) > 1e-9 * std::max(std::abs(a[i]), std::abs(b[i])))
                return true;
        return false;
    };
    const bool eos_own = differs(m.eos_strain, gen.eos_strain) || differs(m.eos_pressure, gen.eos_pressure) ||
                         differs(m.eos_unload, gen.eos_unload);
    os << "\n#     EOS_8" << (eos_own ? " (deck's)" : "") << " ln(V/V0):";
    for (real_t v : m.eos_strain)
        os << " " << v;
    os << "\n#     EOS_8 pressure [Pa]:";
    for (real_t v : m.eos_pressure)
        os << " " << v;
    os << "\n#     EOS_8 unloading bulk modulus [Pa]:";
    for (real_t v : m.eos_unload)
        os << " " << v;
    os << "\n";
}

void cscm(std::ostringstream& os, const CscmModel& c)
{
    os << "#   continuous surface cap model (MAT_159), generated from f'c:\n";
    Lines l(os);
    l.add("fc", c.fc, "Pa");
    l.add("E", c.E, "Pa");
    l.add("K", c.bulk, "Pa");
    l.add("G", c.shear, "Pa");
    l.add("alpha", c.alpha, "Pa");
    l.add("theta", c.theta, "");
    l.add("lambda", c.lambda, "Pa");
    l.add("beta", c.beta, "1/Pa");
    l.add("alpha1", c.alpha1, "");
    l.add("theta1", c.theta1, "1/Pa");
    l.add("lambda1", c.lambda1, "");
    l.add("beta1", c.beta1, "1/Pa");
    l.add("alpha2", c.alpha2, "");
    l.add("theta2", c.theta2, "1/Pa");
    l.add("lambda2", c.lambda2, "");
    l.add("beta2", c.beta2, "1/Pa");
    l.add("R", c.R, "");
    l.add("X0", c.X0, "Pa");
    l.add("W", c.W, "");
    l.add("D1", c.D1, "1/Pa");
    l.add("D2", c.D2, "1/Pa^2");
    l.add("B", c.B, "");
    l.add("D", c.D, "");
    l.add("Gfc", c.Gfc, "J/m^2");
    l.add("Gft", c.Gft, "J/m^2");
    l.add("Gfs", c.Gfs, "J/m^2");
    l.add("fcu", c.fcu, "Pa");
    l.add("ftu", c.ftu, "Pa");
    l.flush();
}

void material(std::ostringstream& os, const PlasticPoints& p)
{
    switch (p.kind)
    {
    case PlasticPoints::Kind::Kcc:
        kcc(os, p.kcc);
        break;
    case PlasticPoints::Kind::Cscm:
        cscm(os, p.cscm);
        break;
    default:
        break; // elastic and J2 parameters are the deck's own (above)
    }
}
} // namespace

namespace
{
/// The Gauss-point element with the smallest step (V / A_max) / c, the first of equals, from the
/// mesh alone (dt kNoLimit and block -1 when there is none).
struct SmallestStep
{
    real_t dt = kNoLimit;
    index_t block = -1, element = -1;
};
SmallestStep smallest_element_step(const Model& model)
{
    SmallestStep s;
    std::vector<real_t> dt;
    for (index_t b = 0; b < static_cast<index_t>(model.meshes.size()); ++b)
        if (!model.nodal_block(b))
        {
            // the elements' steps on the threads, then the first smallest in element order
            const index_t ne = model.meshes[b].n_elements();
            dt.resize(static_cast<std::size_t>(ne));
            parallel_for("rkfem::check::element_steps", ne,
                         [&](index_t e) { dt[static_cast<std::size_t>(e)] = model.element_time_step(b, e); });
            for (index_t e = 0; e < ne; ++e)
                if (dt[static_cast<std::size_t>(e)] < s.dt * (1 - 1e-12))
                    s = {dt[static_cast<std::size_t>(e)], b, e};
        }
    return s;
}
} // namespace

void check_step_budget(const Model& model)
{
    const TimeSpec& ts = model.deck().time;
    if (ts.max_steps > 0)
        return;
    const SmallestStep smallest = smallest_element_step(model);
    if (smallest.block < 0 || !(smallest.dt > 0))
        return; // no Gauss-point elements to estimate from
    real_t dt = smallest.dt * ts.dt_scale;
    if (ts.dt_max > 0)
        dt = std::min(dt, ts.dt_max);
    const real_t steps = ts.end / dt;
    if (steps > 1e10)
    {
        char what[200];
        std::snprintf(what, sizeof what, "%.6g s would take about %.3g steps of %.3g s", ts.end, steps, dt);
        throw DeckError({model.deck().time_loc.where, "time.end"}, what,
                        "expected an end time within 10^10 steps, or time.max_steps to bound the run");
    }
}

std::string check_report(Model& model)
{
    std::ostringstream os;
    os << "# generated material parameters (SI):\n";
    bool any = false;
    for (std::size_t p = 0; p < model.parts.size(); ++p)
    {
        const PlasticPoints* pts = nullptr;
        if (model.nodal_block(p))
            pts = &model.nodal_block(p)->plastic;
        else if (p < model.meshes.size())
            pts = &model.meshes[p].plastic;
        if (!pts || (pts->kind != PlasticPoints::Kind::Kcc && pts->kind != PlasticPoints::Kind::Cscm))
            continue;
        any = true;
        os << "#  part " << model.parts[p].name << ":\n";
        material(os, *pts);
    }
    if (!any)
        os << "#   none (every material's parameters are the deck's own)\n";
    for (const std::string& note : model.setup_notes)
        os << "# note: " << note << "\n";
    // the stable step at t = 0 and what sets it
    ForceReport rep = model.internal_forces(0.0, 0.0, 0);
    rep.dt_stable = std::min(rep.dt_stable, model.contact_step());
    const real_t scale = model.deck().time.dt_scale;
    char line[256];
    std::snprintf(line, sizeof line, "# time step: %.6g s stable, x time.dt_scale %.3g = %.6g s", rep.dt_stable, scale,
                  rep.dt_stable * scale);
    os << line;
    auto [b, e] = rep.dt_element >= 0 ? model.locate_element(rep.dt_element) : std::pair<index_t, index_t>{-1, -1};
    if (b >= 0 && !model.nodal_block(b))
    {
        // the kernels' reduction breaks ties by thread; name the first element of the smallest step
        const SmallestStep s = smallest_element_step(model);
        b = s.block;
        e = s.element;
    }
    if (b >= 0 && model.nodal_block(b) && !model.fe_side(b))
        os << ", set by part '" << model.parts[b].name << "' (its nodal integration points)";
    else if (b >= 0)
    {
        Vec3 c = Vec3::Zero();
        for (int i = 0; i < 8; ++i)
        {
            const index_t n = model.meshes[b].conn[8 * e + i];
            c += Vec3(model.nodes.x0[3 * n], model.nodes.x0[3 * n + 1], model.nodes.x0[3 * n + 2]) / 8;
        }
        for (int d = 0; d < 3; ++d)
            if (std::abs(c[d]) < 1e-9)
                c[d] = 0.0; // round-off of a coordinate on an axis, which a round trip changes
        std::snprintf(line, sizeof line, ", set by part '%s' element %d (centroid %.6g, %.6g, %.6g m)",
                      model.parts[b].name.c_str(), static_cast<int>(e), c[0], c[1], c[2]);
        os << line;
    }
    os << "\n";
    return os.str();
}
} // namespace rkfem
