#include "rkfem/model/material_from_deck.hpp"

#include <initializer_list>
#include <string_view>

namespace rkfem
{
namespace
{
/// Sets the named fields a deck material overrides (names the deck reader accepted).
void apply_overrides(const std::vector<std::pair<std::string, real_t>>& overrides,
                     std::initializer_list<std::pair<std::string_view, real_t*>> fields)
{
    for (const auto& [name, v] : overrides)
        for (const auto& [key, field] : fields)
            if (name == key)
                *field = v;
}
} // namespace

J2Params j2_params(const MaterialSpec& m)
{
    J2Params p;
    if (m.model != "j2")
        return p;
    const ElasticParams el = ElasticParams::from_E_nu(m.rho, m.E, m.nu);
    if (!m.curve.empty())
    {
        p.elastic = el;
        p.curve = m.curve;
        if (p.curve.size() == 1)
            p.curve.emplace_back(1.0, p.curve[0].second);
    }
    else
        p = J2Params::bilinear(el, m.E, m.sigy, m.etan);
    p.cs_c = m.cs_c;
    p.cs_p = m.cs_p;
    p.fail = m.fail;
    if (m.eos_type == "linear")
    {
        p.eos.kind = Eos::Kind::Linear;
        p.eos.bulk = el.bulk_modulus();
    }
    else if (m.eos_type == "gruneisen")
    {
        p.eos.kind = Eos::Kind::Gruneisen;
        p.eos.rho0 = m.rho;
        p.eos.c0 = m.eos_c0;
        p.eos.s = m.eos_s;
        p.eos.gamma0 = m.eos_gamma0;
        p.eos.a = m.eos_a;
    }
    return p;
}

KccModel kcc_model(const MaterialSpec& m)
{
    KccModel kcc = KccModel::from_fc(m.fc, m.rho, m.nu, m.E);
    kcc.rate = m.rate_law;
    kcc.rate.fc = m.fc;
    KccParameters& k = kcc.surfaces;
    apply_overrides(m.overrides, {{"a0", &k.a0},
                                  {"a1", &k.a1},
                                  {"a2", &k.a2},
                                  {"a0y", &k.a0y},
                                  {"a1y", &k.a1y},
                                  {"a2y", &k.a2y},
                                  {"a1f", &k.a1f},
                                  {"a2f", &k.a2f},
                                  {"b1", &k.b1},
                                  {"b2", &k.b2},
                                  {"b3", &k.b3},
                                  {"omega", &k.omega},
                                  {"edrop", &k.edrop},
                                  {"ft", &k.ft}});
    if (!m.kcc_eta.empty())
    {
        k.eta_table = m.kcc_eta;
        if (k.eta_table.back().first < 1e10) // the return walks the table to large lambda
            k.eta_table.emplace_back(1e10, k.eta_table.back().second);
    }
    if (!m.kcc_eos_strain.empty())
        for (int i = 0; i < 10; ++i)
        {
            kcc.eos_strain[i] = m.kcc_eos_strain[i];
            kcc.eos_pressure[i] = m.kcc_eos_pressure[i];
            kcc.eos_unload[i] = m.kcc_eos_unload[i];
        }
    k.update_derived();
    kcc.fracture_energy = m.fracture_energy < 0 ? ceb_fracture_energy(m.fc) : m.fracture_energy;
    return kcc;
}

CscmModel cscm_model(const MaterialSpec& m)
{
    CscmModel c = CscmModel::from_fc(m.fc, m.rho, m.nu, m.E, m.fracture_energy > 0 ? m.fracture_energy : 0.0);
    c.rate_effects = m.rate_effects;
    apply_overrides(m.overrides, {{"alpha", &c.alpha},
                                  {"theta", &c.theta},
                                  {"lambda", &c.lambda},
                                  {"beta", &c.beta},
                                  {"R", &c.R},
                                  {"X0", &c.X0},
                                  {"W", &c.W},
                                  {"D1", &c.D1},
                                  {"D2", &c.D2},
                                  {"B", &c.B},
                                  {"D", &c.D},
                                  {"Gfc", &c.Gfc},
                                  {"length", &c.default_length}});
    c.finish();
    return c;
}

void configure_points(PlasticPoints& points, const MaterialSpec& m)
{
    if (m.model == "j2")
        points.set_j2(j2_params(m));
    else if (m.model == "kcc")
        points.set_kcc(kcc_model(m));
    else if (m.model == "cscm")
        points.set_cscm(cscm_model(m));
}
} // namespace rkfem
