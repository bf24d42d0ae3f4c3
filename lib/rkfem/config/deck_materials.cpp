/// @file deck_materials.cpp
/// The deck's materials (elastic, J2, K&C with its rate laws and user parameters, CSCM, EOS).
#include "rkfem/config/deck_section.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "rkfem/core/error.hpp"

namespace rkfem::deck_detail
{
void read_rate_effects(const Section& s, MaterialSpec& m)
{
    const bool kcc = m.model == "kcc";
    if (!s.has("rate_effects"))
        return;
    const YAML::Node rn = s.node("rate_effects");
    if (!rn.IsMap())
    {
        m.rate_effects = s.choice("rate_effects", {"true", "false"}, "false") == "true";
        if (kcc && m.rate_effects)
            m.rate_law = RateLaw::standard(m.fc);
        return;
    }
    if (!kcc)
        s.fail("rate_effects", "is a mapping", "expected true or false (cscm's rate law is its own)");
    Section r(s.ctx(), rn, s.path("rate_effects"), "rate_effects");
    RateLaw law;
    law.fc = m.fc;
    if (r.has("curve") == r.has("law"))
        r.fail("law", r.has("curve") ? "is given beside curve" : "is missing",
               "expected law: ceb-fip (CEB-FIP compression, Malvar-Ross tension) or curve: [[rate, DIF], ...]");
    if (r.has("law"))
    {
        r.choice("law", {"ceb-fip"}, "");
        law = RateLaw::standard(m.fc);
    }
    else
    {
        law.kind = RateLaw::Kind::Curve;
        const YAML::Node c = r.node("curve");
        const std::string expected =
            "expected [[rate, DIF], ...]: at least two points, rates strictly increasing (negative = tension, as "
            "LS-DYNA's LCRATE), DIF > 0";
        if (!c.IsSequence() || c.size() < 2)
            r.fail("curve", "needs at least two points", expected);
        for (std::size_t i = 0; i < c.size(); ++i)
        {
            const std::string pi = r.path("curve") + "." + std::to_string(i);
            if (!c[i].IsSequence() || c[i].size() != 2)
                throw DeckError(locate(r.ctx(), c[i], pi), "is not a [rate, DIF] pair", expected);
            const real_t rate = r.quantity_of(c[i][0], pi + ".0", Dimension{0, 0, -1});
            const real_t dif = r.quantity_of(c[i][1], pi + ".1", dim::none);
            if ((i > 0 && !(rate > law.curve.back().first)) || !(dif > 0.0))
                throw DeckError(locate(r.ctx(), c[i], pi), "is out of order or range", expected);
            law.curve.emplace_back(rate, dif);
        }
        law.compression_cap = law.tension_cap = 0.0;
    }
    auto cap = [&](const char* key, real_t& out)
    {
        if (!r.has(key))
            return;
        if (r.scalar_text(key, "a DIF >= 1 or none") == "none")
        {
            out = 0.0;
            return;
        }
        out = r.quantity(key, dim::none);
        if (!(out >= 1.0))
            r.fail(key, "is below 1", "expected a largest DIF >= 1, or none");
    };
    cap("compression_cap", law.compression_cap);
    cap("tension_cap", law.tension_cap);
    m.rate_law = law;
    m.rate_effects = true;
}

namespace
{
/// The parameters a kcc or cscm material may override by name, with their dimensions.
const std::vector<std::pair<std::string, Dimension>>& concrete_override_keys(const std::string& model)
{
    // cscm: every generated parameter can be overridden by name (SI after units)
    static const std::vector<std::pair<std::string, Dimension>> cscm_keys = {{"alpha", dim::pressure},
                                                                             {"theta", dim::none},
                                                                             {"lambda", dim::pressure},
                                                                             {"beta", Dimension{-1, 1, 2}},
                                                                             {"R", dim::none},
                                                                             {"X0", dim::pressure},
                                                                             {"W", dim::none},
                                                                             {"D1", Dimension{-1, 1, 2}},
                                                                             {"D2", Dimension{-2, 2, 4}},
                                                                             {"B", dim::none},
                                                                             {"D", dim::none},
                                                                             {"Gfc", Dimension{1, 0, -2}},
                                                                             {"length", dim::length}};
    // kcc: the generated Release III coefficients (materials.md 1.9), likewise
    static const std::vector<std::pair<std::string, Dimension>> kcc_keys = {
        {"a0", dim::pressure},       {"a1", dim::none},
        {"a2", Dimension{-1, 1, 2}}, {"a0y", dim::pressure},
        {"a1y", dim::none},          {"a2y", Dimension{-1, 1, 2}},
        {"a1f", dim::none},          {"a2f", Dimension{-1, 1, 2}},
        {"b1", dim::none},           {"b2", dim::none},
        {"b3", dim::none},           {"omega", dim::none},
        {"edrop", dim::none},        {"ft", dim::pressure}};
    return model == "cscm" ? cscm_keys : kcc_keys;
}

/// eta of a kcc material: the damage function's [[lambda, eta], ...] table, into m.kcc_eta.
void read_kcc_eta(const Section& s, MaterialSpec& m)
{
    const YAML::Node c = s.node("eta");
    if (!c.IsSequence() || c.size() < 3)
        s.fail("eta", "needs at least three points",
               "expected [[lambda0, eta0], [lambda1, eta1], ...], lambda increasing from 0, eta in [0, 1] "
               "reaching 1 once");
    for (std::size_t i = 0; i < c.size(); ++i)
    {
        const std::string pi = s.path("eta") + "." + std::to_string(i);
        if (!c[i].IsSequence() || c[i].size() != 2)
            throw DeckError(locate(s.ctx(), c[i], pi), "is not a [lambda, eta] pair", "expected [lambda, eta]");
        const real_t lam = s.quantity_of(c[i][0], pi + ".0", dim::none);
        const real_t eta = s.quantity_of(c[i][1], pi + ".1", dim::none);
        if ((i == 0 && lam != 0.0) || (i > 0 && !(lam > m.kcc_eta.back().first)) || eta < 0.0 || eta > 1.0)
            throw DeckError(locate(s.ctx(), c[i], pi), "is out of order or range",
                            "expected lambda from 0, strictly increasing, and 0 <= eta <= 1");
        m.kcc_eta.emplace_back(lam, eta);
    }
    bool peak = false;
    for (const auto& e : m.kcc_eta)
        peak = peak || e.second == 1.0;
    if (!peak)
        s.fail("eta", "never reaches 1", "expected eta = 1 at the peak (lambda_m)");
}

/// eos of a kcc material: the EOS_8 table (strain, pressure, unload_bulk), into m.kcc_eos_*.
void read_kcc_eos(const Section& s, MaterialSpec& m)
{
    Section e(s.ctx(), s.node("eos"), s.path("eos"), "kcc-eos");
    auto list = [&](const char* key, Dimension dm, std::vector<real_t>& out)
    {
        e.require(key, "a list of 10 values");
        const YAML::Node c = e.node(key);
        if (!c.IsSequence() || c.size() != 10)
            e.fail(key, "does not have 10 entries", "expected the 10 points of an EOS_8 table");
        for (std::size_t i = 0; i < 10; ++i)
            out.push_back(e.quantity_of(c[i], e.path(key) + "." + std::to_string(i), dm));
    };
    list("strain", dim::none, m.kcc_eos_strain);
    list("pressure", dim::pressure, m.kcc_eos_pressure);
    list("unload_bulk", dim::pressure, m.kcc_eos_unload);
    for (std::size_t i = 0; i < 10; ++i)
        if ((i == 0 && m.kcc_eos_strain[0] != 0.0) || (i > 0 && !(m.kcc_eos_strain[i] < m.kcc_eos_strain[i - 1])) ||
            (i > 0 && !(m.kcc_eos_pressure[i] > m.kcc_eos_pressure[i - 1])) || !(m.kcc_eos_unload[i] > 0.0))
            e.fail("strain", "is not an EOS_8 table",
                   "expected volumetric strains from 0 decreasing, pressures increasing, unloading moduli > 0");
}

/// The parameter overrides of a kcc or cscm material given by name, into m.overrides.
void read_overrides(const Section& s, const std::string& model,
                    const std::vector<std::pair<std::string, Dimension>>& override_keys, MaterialSpec& m)
{
    for (const auto& [k, dimension] : override_keys)
        if (s.has(k))
        {
            const real_t v = s.quantity(k, dimension);
            // exponents and shape factors may be any sign; strengths and scales must be positive
            const bool any_sign = k == "theta" || k == "b1" || k == "b2" || k == "b3";
            if (k == "omega" && model == "kcc")
            {
                // the fraction of associated dilatancy: 0 (volume-preserving flow) to 1
                if (!(v >= 0.0 && v <= 1.0))
                    s.fail(k, "is out of range", "expected 0 <= omega <= 1 (0: no dilatancy, 1: associated flow)");
            }
            else if (k == "edrop")
            {
                if (!(v >= 0.0))
                    s.fail(k, "is out of range", "expected edrop >= 0 (0: no post-peak decay of the dilatancy)");
            }
            else if (!(v > 0) && !any_sign)
                s.fail(k, "must be positive", "expected a positive " + k);
            m.overrides.emplace_back(k, v);
        }
}

/// fracture_energy of a kcc or cscm material: a G_f >= 0 or auto (-1).
void read_fracture_energy(const Section& s, MaterialSpec& m)
{
    if (s.scalar_text("fracture_energy", "") == "auto")
        m.fracture_energy = -1.0;
    else
    {
        m.fracture_energy = s.quantity("fracture_energy", Dimension{1, 0, -2});
        if (m.fracture_energy < 0)
            s.fail("fracture_energy", "is negative", "expected G_f >= 0 [J/m^2], auto (CEB-FIP) or 0 (none)");
    }
}

/// A kcc or cscm material: rho, fc, nu, E (defaults from fc), eta, eos, overrides, rate effects, fracture energy.
MaterialSpec read_concrete(const Section& part, const YAML::Node& mn, const std::string& model)
{
    MaterialSpec m;
    const auto& override_keys = concrete_override_keys(model);
    Section s(part.ctx(), mn, part.path("material"), "material." + model);
    m.model = model;
    m.rho = s.quantity("rho", dim::density);
    if (!(m.rho > 0))
        s.fail("rho", "density must be positive", "expected rho > 0 (e.g. 2400 kg/m^3)");
    m.fc = s.positive("fc", dim::pressure);
    if (model == "kcc" && !(m.fc >= 1e6 && m.fc <= 500e6))
        s.fail("fc", "is outside the range of concrete",
               "expected 1 MPa <= fc <= 500 MPa (normal concrete to UHPC; the generated K&C parameters are fitted "
               "on 20-60 MPa concrete)");
    const bool cscm = model == "cscm";
    m.nu = s.quantity("nu", dim::none, cscm ? 0.2 : 0.19);
    if (!(m.nu > -1.0 && m.nu < 0.5))
        s.fail("nu", "is out of range",
               cscm ? "expected -1 < nu < 0.5 (default 0.2)" : "expected -1 < nu < 0.5 (default 0.19)");
    // defaults: K&C E = 4700 sqrt(f'c [MPa]) MPa (ACI); CSCM E = 21.5 GPa (f'c / 10 MPa)^(1/3) (CEB-FIP)
    m.E = s.quantity("E", dim::pressure, cscm ? 21.5e9 * std::cbrt(m.fc / 10e6) : 4700.0 * std::sqrt(m.fc / 1e6) * 1e6);
    if (cscm && (m.fc < 20e6 || m.fc > 58e6))
        s.fail("fc", "is outside the range of Murray's fits",
               "expected 20 MPa <= fc <= 58 MPa for the generated CSCM parameters");
    if (!cscm && s.has("eta"))
        read_kcc_eta(s, m);
    if (!cscm && s.has("eos"))
        read_kcc_eos(s, m);
    read_overrides(s, model, override_keys, m);
    read_rate_effects(s, m);
    if (s.has("fracture_energy"))
        read_fracture_energy(s, m);
    m.loc = s.loc();
    return m;
}

/// curve of a j2 material: [[eps_p, yield stress], ...] from eps_p 0, into m.curve and m.sigy.
void read_j2_curve(const Section& s, MaterialSpec& m)
{
    const YAML::Node c = s.node("curve");
    if (!c.IsSequence() || c.size() < 2)
        s.fail("curve", "needs at least two points", "expected [[0, sigy], [eps_p1, sigma_1], ...]");
    for (std::size_t i = 0; i < c.size(); ++i)
    {
        const std::string pi = s.path("curve") + "." + std::to_string(i);
        if (!c[i].IsSequence() || c[i].size() != 2)
            throw DeckError(locate(s.ctx(), c[i], pi), "is not an [eps_p, yield stress] pair",
                            "expected [plastic strain, stress]");
        const real_t e = s.quantity_of(c[i][0], pi + ".0", dim::none);
        const real_t y = s.quantity_of(c[i][1], pi + ".1", dim::pressure);
        if ((i == 0 && e != 0.0) || (i > 0 && !(e > m.curve.back().first)) || !(y > 0))
            throw DeckError(locate(s.ctx(), c[i], pi), "is not a valid curve point",
                            "expected eps_p starting at 0 and increasing, yield stress > 0");
        m.curve.emplace_back(e, y);
    }
    m.sigy = m.curve.front().second;
}

/// eos of a j2 material: {type: linear} or {type: gruneisen, c0, s, gamma0, a}.
void read_eos(const Section& s, MaterialSpec& m)
{
    const YAML::Node en = s.node("eos");
    const std::string t = en.IsMap() && en["type"].IsDefined() ? en["type"].Scalar() : "";
    if (t == "linear")
    {
        Section e(s.ctx(), en, s.path("eos"), "eos.linear");
        m.eos_type = t;
    }
    else if (t == "gruneisen")
    {
        Section e(s.ctx(), en, s.path("eos"), "eos.gruneisen");
        m.eos_type = t;
        m.eos_c0 = e.positive("c0", dim::velocity);
        m.eos_s = e.quantity("s", dim::none);
        m.eos_gamma0 = e.quantity("gamma0", dim::none);
        m.eos_a = e.quantity("a", dim::none, 0.0);
        // the ranges of published Us-up fits (metals and polymers: s 0.5-3.5,
        // gamma0 0.5-4, a 0-1): a negative slope or Gruneisen gamma has no meaning
        if (!(m.eos_s >= 0.0 && m.eos_s <= 10.0))
            e.fail("s", "is out of range", "expected 0 <= s <= 10 (the slope of Us against up; 1-2 for metals)");
        if (!(m.eos_gamma0 >= 0.0 && m.eos_gamma0 <= 10.0))
            e.fail("gamma0", "is out of range", "expected 0 <= gamma0 <= 10 (Gruneisen gamma; 1.5-2.2 for metals)");
        if (!(m.eos_a >= 0.0 && m.eos_a <= 10.0))
            e.fail("a", "is out of range", "expected 0 <= a <= 10 (the first-order volume correction)");
    }
    else
        throw DeckError(
            locate(s.ctx(), en.IsMap() && en["type"].IsDefined() ? en["type"] : en, s.path("eos") + ".type"),
            t.empty() ? "missing EOS type" : "unknown EOS type '" + t + "'", "expected type: linear | gruneisen");
}

/// The keys of a j2 material beyond the elastic ones: curve or sigy and etan, cowper_symonds, fail, eos.
void read_j2(const Section& s, MaterialSpec& m)
{
    if (s.has("curve"))
        read_j2_curve(s, m);
    else
    {
        m.sigy = s.quantity("sigy", dim::pressure);
        if (!(m.sigy > 0))
            s.fail("sigy", "must be positive", "expected a yield stress > 0 (e.g. 792 MPa)");
        m.etan = s.quantity("etan", dim::pressure, 0.0);
        if (!(m.etan >= 0 && m.etan < m.E))
            s.fail("etan", "is out of range", "expected 0 <= etan < E");
    }
    if (s.has("cowper_symonds"))
    {
        Section cs(s.ctx(), s.node("cowper_symonds"), s.path("cowper_symonds"), "cowper_symonds");
        m.cs_c = cs.quantity("C", Dimension{0, 0, -1});
        m.cs_p = cs.quantity("P", dim::none);
        if (!(m.cs_c > 0 && m.cs_p > 0))
            cs.fail(m.cs_c > 0 ? "P" : "C", "must be positive", "expected C > 0 [1/s] and P > 0");
    }
    m.fail = s.quantity("fail", dim::none, 0.0);
    if (m.fail < 0)
        s.fail("fail", "is negative", "expected a failure plastic strain > 0, or 0 for none");
    if (s.has("eos"))
        read_eos(s, m);
}

/// An elastic or j2 material: rho, E, nu, and for j2 its plasticity, failure and EOS.
MaterialSpec read_elastic_or_j2(const Section& part, const YAML::Node& mn, const std::string& model)
{
    MaterialSpec m;
    Section s(part.ctx(), mn, part.path("material"), "material." + model);
    m.model = model;
    m.rho = s.quantity("rho", dim::density);
    if (!(m.rho > 0))
        s.fail("rho", "density must be positive", "expected rho > 0 (e.g. 7850 kg/m^3)");
    m.E = s.quantity("E", dim::pressure);
    if (!(m.E > 0))
        s.fail("E", "Young's modulus must be positive", "expected E > 0 (e.g. 200 GPa)");
    m.nu = s.quantity("nu", dim::none);
    if (!(m.nu > -1.0 && m.nu < 0.5))
        s.fail("nu", "Poisson's ratio " + s.scalar_text("nu", "") + " is out of range", "expected -1 < nu < 0.5");
    if (model == "j2")
        read_j2(s, m);
    m.loc = s.loc();
    return m;
}
} // namespace

MaterialSpec read_material(const Section& part)
{
    part.require("material", "a mapping with model: elastic, rho, E, nu");
    const YAML::Node mn = part.node("material");
    std::string model = mn.IsMap() && mn["model"].IsDefined() ? mn["model"].Scalar() : "";
    if (model == "kcc" || model == "cscm")
        return read_concrete(part, mn, model);
    if (model == "elastic" || model == "j2")
        return read_elastic_or_j2(part, mn, model);
    const std::string p = part.path("material") + ".model";
    throw DeckError(mn.IsMap() && mn["model"].IsDefined() ? locate(part.ctx(), mn["model"], p)
                                                          : locate(part.ctx(), mn, p),
                    model.empty() ? "missing material model" : "unknown material model '" + model + "'",
                    "expected model: elastic | j2 | kcc | cscm");
}

} // namespace rkfem::deck_detail
