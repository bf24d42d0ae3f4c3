#include "rkfem/config/deck_section.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "rkfem/core/error.hpp"

namespace rkfem::deck_detail
{
namespace
{
/// origin (default 0) and size (three positive lengths) of a box or a cloud's box body.
void read_box(const Section& s, GeneratorSpec& g)
{
    g.origin = s.vec3("origin", dim::length, Vec3::Zero());
    g.size = s.vec3("size", dim::length);
    for (int i = 0; i < 3; ++i)
        if (!(g.size[i] > 0))
            s.fail("size", "has a non-positive edge", "expected three positive lengths");
}
} // namespace

namespace
{
/// A data file's path from `key`, relative paths from the deck's folder.
std::string data_file(const Section& s, const char* key)
{
    const std::filesystem::path file = s.text(key);
    return file.is_absolute() ? file.string() : (std::filesystem::path(s.ctx().name).parent_path() / file).string();
}

/// A data file's length unit from `key` (default m): metres per file unit, and the name as
/// written (the resolved deck echoes it).
void read_length_unit(const Section& s, const char* key, real_t& scale, std::string& name)
{
    name = s.text(key, "m");
    std::string err;
    const std::optional<Unit> u = parse_unit(name, &err);
    if (!u || !(u->dimension == dim::length))
        s.fail(key, "'" + name + "' is not a length unit" + (err.empty() ? "" : " (" + err + ")"),
               "expected the file's length unit, one of " + known_units_for(dim::length));
    scale = u->scale;
}
} // namespace

GeneratorSpec read_generator(const Section& part)
{
    part.require("generator", "a mapping with type: box | cylinder | projectile | cloud | keyword");
    const YAML::Node gn = part.node("generator");
    const std::string gp = part.path("generator");
    std::string type;
    if (gn.IsMap() && gn["type"].IsDefined())
        type = gn["type"].Scalar();
    GeneratorSpec g;
    if (type == "box")
    {
        Section s(part.ctx(), gn, gp, {"type", "origin", "size", "element_size", "divisions"});
        g.type = GeneratorSpec::Type::Box;
        read_box(s, g);
        if (s.has("divisions"))
        {
            const YAML::Node d = s.node("divisions");
            if (!d.IsSequence() || d.size() != 3)
                s.fail("divisions", "is not a list of 3 integers", "expected [nx, ny, nz] >= 1");
            for (int i = 0; i < 3; ++i)
            {
                int v = 0;
                try
                {
                    v = d[i].as<int>();
                }
                catch (const std::exception&)
                {
                    s.fail("divisions", "has a non-integer entry", "expected [nx, ny, nz] >= 1");
                }
                if (v < 1)
                    s.fail("divisions", "has an entry below 1", "expected [nx, ny, nz] >= 1");
                g.divisions[i] = v;
            }
        }
        else
            g.element_size = s.positive("element_size", dim::length);
        g.loc = s.loc();
    }
    else if (type == "cylinder" || type == "projectile")
    {
        const bool cyl = type == "cylinder";
        Section s(
            part.ctx(), gn, gp,
            cyl ? std::vector<std::string>{"type", "origin", "radius", "height", "element_size", "core", "inner_radius"}
                : std::vector<std::string>{"type", "origin", "radius", "length", "element_size", "direction"});
        g.type = cyl ? GeneratorSpec::Type::Cylinder : GeneratorSpec::Type::Projectile;
        g.origin = s.vec3("origin", dim::length, Vec3::Zero());
        g.radius = s.positive("radius", dim::length);
        g.height = s.positive(cyl ? "height" : "length", dim::length);
        g.element_size = s.positive("element_size", dim::length);
        if (cyl)
        {
            g.core = s.choice("core", {"butterfly", "ogrid"}, "butterfly");
            if (s.has("inner_radius"))
            {
                g.inner_radius = s.positive("inner_radius", dim::length);
                if (!(g.inner_radius < g.radius))
                    s.fail("inner_radius", "is not below the radius", "expected 0 < inner_radius < radius (a tube)");
                if (s.has("core"))
                    s.fail("core", "a tube has no core", "remove core, or inner_radius");
            }
        }
        else
            g.direction = s.choice("direction", {"-z", "+z"}, "-z") == "-z" ? -1 : +1;
        g.loc = s.loc();
    }
    else if (type == "cloud")
    {
        Section s(part.ctx(), gn, gp,
                  {"type", "body", "origin", "size", "radius", "height", "spacing", "jitter", "seed", "points",
                   "points_unit"});
        g.type = GeneratorSpec::Type::Cloud;
        g.body = s.choice("body", {"box", "cylinder"}, "box") == "box" ? GeneratorSpec::Body::Box
                                                                       : GeneratorSpec::Body::Cylinder;
        if (g.body == GeneratorSpec::Body::Box)
        {
            for (const char* k : {"radius", "height"})
                if (s.has(k))
                    s.fail(k, "is not used by a box body", "expected origin and size, or body: cylinder");
            read_box(s, g);
        }
        else
        {
            if (s.has("size"))
                s.fail("size", "is not used by a cylinder body", "expected origin (bottom centre), radius and height");
            g.origin = s.vec3("origin", dim::length, Vec3::Zero());
            g.radius = s.positive("radius", dim::length);
            g.height = s.positive("height", dim::length);
        }
        if (s.has("points") == s.has("spacing"))
            s.fail(s.has("points") ? "points" : "spacing", s.has("points") ? "is given with spacing" : "is missing",
                   "expected either spacing (a jittered lattice) or points (a CSV file of x,y,z)");
        if (s.has("points"))
        {
            g.points_file = data_file(s, "points");
            read_length_unit(s, "points_unit", g.points_unit, g.points_unit_name);
        }
        else
        {
            g.element_size = s.positive("spacing", dim::length);
            g.jitter = s.quantity("jitter", dim::none, 0.25);
            if (!(g.jitter >= 0.0 && g.jitter <= 0.45))
                s.fail("jitter", "is outside [0, 0.45]",
                       "expected a fraction of the spacing that keeps the lattice order");
            g.seed = static_cast<int>(s.integer("seed", 1));
        }
        g.loc = s.loc();
    }
    else if (type == "keyword")
    {
        Section s(part.ctx(), gn, gp, {"type", "file", "unit", "pid"});
        g.type = GeneratorSpec::Type::Keyword;
        s.require("file", "the path of an LS-DYNA keyword file (*NODE, *ELEMENT_SOLID)");
        g.mesh_file = data_file(s, "file");
        read_length_unit(s, "unit", g.mesh_unit, g.mesh_unit_name);
        if (s.has("pid"))
        {
            const YAML::Node pn = s.node("pid");
            std::vector<YAML::Node> items;
            if (pn.IsSequence())
                for (std::size_t i = 0; i < pn.size(); ++i)
                    items.push_back(pn[i]);
            else
                items.push_back(pn);
            for (const YAML::Node& it : items)
            {
                long long v = 0;
                try
                {
                    v = it.as<long long>();
                }
                catch (const std::exception&)
                {
                    s.fail("pid", "is not an integer or a list of integers", "expected the PIDs of the solids to take");
                }
                g.mesh_pids.push_back(v);
            }
            if (g.mesh_pids.empty())
                s.fail("pid", "is an empty list", "expected the PIDs of the solids to take");
        }
        g.loc = s.loc();
    }
    else
    {
        const SourceLocation loc = gn.IsMap() && gn["type"].IsDefined() ? locate(part.ctx(), gn["type"], gp + ".type")
                                                                        : locate(part.ctx(), gn, gp + ".type");
        throw DeckError(loc, type.empty() ? "missing generator type" : "unknown generator '" + type + "'",
                        "expected type: box | cylinder | projectile | cloud | keyword");
    }
    return g;
}

/// rate_effects of a kcc or cscm material: true | false, and for kcc a mapping: {law: ceb-fip,
/// compression_cap, tension_cap} (caps: a DIF >= 1 or none) or {curve: [[rate, DIF], ...]} (the
/// LS-DYNA LCRATE form: negative rates are tension; caps allowed too).
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
    Section r(s.ctx(), rn, s.path("rate_effects"), {"law", "curve", "compression_cap", "tension_cap"});
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

MaterialSpec read_material(const Section& part)
{
    part.require("material", "a mapping with model: elastic, rho, E, nu");
    const YAML::Node mn = part.node("material");
    std::string model = mn.IsMap() && mn["model"].IsDefined() ? mn["model"].Scalar() : "";
    MaterialSpec m;
    if (model == "kcc" || model == "cscm")
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
            {"ft", dim::pressure}};
        const auto& override_keys = model == "cscm" ? cscm_keys : kcc_keys;
        std::vector<std::string> keys = {"model", "rho", "fc", "E", "nu", "rate_effects", "fracture_energy"};
        for (const auto& k : override_keys)
            keys.push_back(k.first);
        if (model == "kcc")
        {
            keys.push_back("eta");
            keys.push_back("eos");
        }
        Section s(part.ctx(), mn, part.path("material"), keys);
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
        m.E = s.quantity("E", dim::pressure,
                         cscm ? 21.5e9 * std::cbrt(m.fc / 10e6) : 4700.0 * std::sqrt(m.fc / 1e6) * 1e6);
        if (cscm && (m.fc < 20e6 || m.fc > 58e6))
            s.fail("fc", "is outside the range of Murray's fits",
                   "expected 20 MPa <= fc <= 58 MPa for the generated CSCM parameters");
        if (s.has("eta"))
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
        if (s.has("eos"))
        {
            Section e(s.ctx(), s.node("eos"), s.path("eos"), {"strain", "pressure", "unload_bulk"});
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
                if ((i == 0 && m.kcc_eos_strain[0] != 0.0) ||
                    (i > 0 && !(m.kcc_eos_strain[i] < m.kcc_eos_strain[i - 1])) ||
                    (i > 0 && !(m.kcc_eos_pressure[i] > m.kcc_eos_pressure[i - 1])) || !(m.kcc_eos_unload[i] > 0.0))
                    e.fail("strain", "is not an EOS_8 table",
                           "expected volumetric strains from 0 decreasing, pressures increasing, unloading moduli > 0");
        }
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
                else if (!(v > 0) && !any_sign)
                    s.fail(k, "must be positive", "expected a positive " + k);
                m.overrides.emplace_back(k, v);
            }
        read_rate_effects(s, m);
        if (s.has("fracture_energy"))
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
        m.loc = s.loc();
        return m;
    }
    if (model == "elastic" || model == "j2")
    {
        Section s(part.ctx(), mn, part.path("material"),
                  model == "elastic" ? std::vector<std::string>{"model", "rho", "E", "nu"}
                                     : std::vector<std::string>{"model", "rho", "E", "nu", "sigy", "etan", "curve",
                                                                "cowper_symonds", "fail", "eos"});
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
        {
            if (s.has("curve"))
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
                Section cs(s.ctx(), s.node("cowper_symonds"), s.path("cowper_symonds"), {"C", "P"});
                m.cs_c = cs.quantity("C", Dimension{0, 0, -1});
                m.cs_p = cs.quantity("P", dim::none);
                if (!(m.cs_c > 0 && m.cs_p > 0))
                    cs.fail(m.cs_c > 0 ? "P" : "C", "must be positive", "expected C > 0 [1/s] and P > 0");
            }
            m.fail = s.quantity("fail", dim::none, 0.0);
            if (m.fail < 0)
                s.fail("fail", "is negative", "expected a failure plastic strain > 0, or 0 for none");
            if (s.has("eos"))
            {
                const YAML::Node en = s.node("eos");
                const std::string t = en.IsMap() && en["type"].IsDefined() ? en["type"].Scalar() : "";
                if (t == "linear")
                {
                    Section e(s.ctx(), en, s.path("eos"), {"type"});
                    m.eos_type = t;
                }
                else if (t == "gruneisen")
                {
                    Section e(s.ctx(), en, s.path("eos"), {"type", "c0", "s", "gamma0", "a"});
                    m.eos_type = t;
                    m.eos_c0 = e.positive("c0", dim::velocity);
                    m.eos_s = e.quantity("s", dim::none);
                    m.eos_gamma0 = e.quantity("gamma0", dim::none);
                    m.eos_a = e.quantity("a", dim::none, 0.0);
                    // the ranges of published Us-up fits (metals and polymers: s 0.5-3.5,
                    // gamma0 0.5-4, a 0-1): a negative slope or Gruneisen gamma has no meaning
                    if (!(m.eos_s >= 0.0 && m.eos_s <= 10.0))
                        e.fail("s", "is out of range",
                               "expected 0 <= s <= 10 (the slope of Us against up; 1-2 for metals)");
                    if (!(m.eos_gamma0 >= 0.0 && m.eos_gamma0 <= 10.0))
                        e.fail("gamma0", "is out of range",
                               "expected 0 <= gamma0 <= 10 (Gruneisen gamma; 1.5-2.2 for metals)");
                    if (!(m.eos_a >= 0.0 && m.eos_a <= 10.0))
                        e.fail("a", "is out of range", "expected 0 <= a <= 10 (the first-order volume correction)");
                }
                else
                    throw DeckError(locate(s.ctx(), en.IsMap() && en["type"].IsDefined() ? en["type"] : en,
                                           s.path("eos") + ".type"),
                                    t.empty() ? "missing EOS type" : "unknown EOS type '" + t + "'",
                                    "expected type: linear | gruneisen");
            }
        }
        m.loc = s.loc();
        return m;
    }
    const std::string p = part.path("material") + ".model";
    throw DeckError(mn.IsMap() && mn["model"].IsDefined() ? locate(part.ctx(), mn["model"], p)
                                                          : locate(part.ctx(), mn, p),
                    model.empty() ? "missing material model" : "unknown material model '" + model + "'",
                    "expected model: elastic | j2 | kcc | cscm");
}

namespace
{
/// A key that another formulation uses (hourglass on an rkpm part): read and checked, then
/// ignored with a note in the resolved deck, so a formulation sweep needs one override per case.
void ignore(PartSpec& p, const Section& s, const std::string& key, const std::string& formulation)
{
    p.ignored.push_back(s.path(key) + " (" + s.loc(key).where + "): formulation " + formulation +
                        " does not use it; ignored");
}

/// The element criteria under `key` (erosion, conversion): at least one set, none negative.
ElementCriteria read_criteria(const Context& ctx, const Section& s, const std::string& key, const PartSpec& p)
{
    std::vector<std::string> keys = {"effective_plastic_strain", "damage", "principal_strain", "volumetric_strain",
                                     "time_step"};
    if (key == "conversion")
        keys.push_back("interval");
    Section e(ctx, s.node(key), s.path(key), keys);
    ElementCriteria c;
    if (key == "conversion")
    {
        c.interval = e.quantity("interval", dim::time, 0.0);
        if (!(c.interval >= 0.0 && std::isfinite(c.interval)))
            e.fail("interval", "is negative or not finite", "expected a time >= 0 (0: check after every step)");
    }
    c.plastic_strain = e.quantity("effective_plastic_strain", dim::none, 0.0);
    c.damage = e.quantity("damage", dim::none, 0.0);
    c.principal_strain = e.quantity("principal_strain", dim::none, 0.0);
    c.volumetric_strain = e.quantity("volumetric_strain", dim::none, 0.0);
    c.time_step = e.quantity("time_step", dim::time, 0.0);
    for (const char* k : {"principal_strain", "volumetric_strain", "time_step"})
        if (e.has(k) && !(e.quantity(k, k == std::string("time_step") ? dim::time : dim::none) >= 0.0))
            e.fail(k, "is negative", "expected a value > 0 (0: off)");
    if (p.material.model == "elastic" && (c.plastic_strain > 0 || c.damage > 0))
        s.fail(key, "effective_plastic_strain and damage need a material with history",
               "expected material model j2, kcc or cscm, or the criteria principal_strain, volumetric_strain, "
               "time_step");
    if (!(c.plastic_strain >= 0.0 && std::isfinite(c.plastic_strain)))
        e.fail("effective_plastic_strain", "is negative or not finite", "expected a strain > 0 (0: off)");
    if (!(c.damage >= 0.0 && c.damage <= 1.0))
        e.fail("damage", "is outside [0, 1]", "expected a damage index in (0, 1] (0: off)");
    if (!c.active())
        s.fail(key, "has no criterion",
               "expected effective_plastic_strain, damage, principal_strain, volumetric_strain or time_step > 0");
    return c;
}
} // namespace

PartSpec read_part(const Context& ctx, const std::string& name, const YAML::Node& n, const std::string& path)
{
    Section s(ctx, n, path,
              {"generator", "material", "formulation", "hourglass", "bulk_viscosity", "nodal_integration", "rk",
               "initial_velocity", "regions", "transition", "erosion", "conversion"});
    PartSpec p;
    p.name = name;
    p.loc = s.loc();
    p.generator = read_generator(s);
    p.material = read_material(s);
    const std::string f = s.choice("formulation", {"fem-1pt", "fem-2x2x2", "fem-nodal", "rkpm"}, "fem-1pt");
    p.formulation = f == "fem-1pt"     ? Formulation::Fem1pt
                    : f == "fem-2x2x2" ? Formulation::Fem2x2x2
                    : f == "fem-nodal" ? Formulation::FemNodal
                                       : Formulation::Rkpm;
    if (s.has("conversion"))
    {
        // evolutionary coupling: state lives at the nodes on both sides, so conversion moves none
        if (p.formulation != Formulation::FemNodal)
            s.fail("conversion",
                   "turns elements of nodal-integrated FE into RK particles (the state stays at the nodes)",
                   "expected formulation: fem-nodal on a part with conversion");
        p.conversion = read_criteria(ctx, s, "conversion", p);
    }
    // the default stabilization of scheme scni: NSNI for RK parts (cheaper per step than MSCNI,
    // the same stable step and the same answers on the seed's P1 and P3; README,
    // nodal_integration; measurements: docs/performance.md), on meshes and clouds; MSCNI where
    // there are no RK second derivatives (fem-nodal, coupled parts)
    const std::string default_stab = p.formulation == Formulation::Rkpm && !s.has("regions") ? "nsni" : "mscni";
    p.nodal.stabilization = default_stab;
    p.nodal.stabilization_coefficient = default_stab == "nsni" ? kNsniCoefficient : 1.0;
    if (s.has("nodal_integration"))
    {
        if (!is_nodal(p.formulation) && !s.has("regions"))
            ignore(p, s, "nodal_integration", f); // read (and checked) below, then not used
        Section ni(ctx, s.node("nodal_integration"), s.path("nodal_integration"),
                   {"scheme", "stabilization", "stabilization_coefficient", "dt_factor", "facet_points"});
        p.nodal.scheme = ni.choice("scheme", {"scni", "sd-scni", "dni"}, "scni");
        p.nodal.stabilization =
            ni.choice("stabilization", {"mscni", "nsni", "none"}, p.nodal.scheme == "scni" ? default_stab : "none");
        if (p.nodal.stabilization != "none" && p.nodal.scheme != "scni")
            ni.fail("stabilization", p.nodal.stabilization + " stabilizes scheme scni only",
                    "expected stabilization: none with scheme " + p.nodal.scheme);
        if (p.nodal.stabilization == "nsni" && (p.formulation != Formulation::Rkpm || s.has("regions")))
            ni.fail("stabilization", "nsni needs the second derivatives of RK shape functions",
                    "expected stabilization: mscni or none on a " + f +
                        (s.has("regions") ? " part with regions" : " part"));
        p.nodal.stabilization_coefficient = ni.quantity("stabilization_coefficient", dim::none,
                                                        p.nodal.stabilization == "nsni" ? kNsniCoefficient : 1.0);
        if (!(p.nodal.stabilization_coefficient >= 0.0))
            ni.fail("stabilization_coefficient", "is negative", "expected c_s >= 0 (1 is the RKPM2D default)");
        p.nodal.dt_factor = ni.quantity("dt_factor", dim::none, 0.0);
        if (!(p.nodal.dt_factor >= 0.0 && p.nodal.dt_factor <= 2.0))
            ni.fail("dt_factor", "is outside [0, 2]", "expected alpha in (0, 2], or 0 for the calibrated default");
        p.nodal.facet_points = ni.choice("facet_points", {"triangles", "faces"}, "triangles");
        if (p.nodal.facet_points == "faces" && p.generator.type != GeneratorSpec::Type::Cloud)
            ni.fail("facet_points", "faces chooses the points on a cloud's Voronoi faces, and this part is a mesh",
                    "expected facet_points: triangles (or none) on a mesh part; its nodal cells' facets take 2 x 2 "
                    "Gauss points");
    }
    if (p.generator.type == GeneratorSpec::Type::Cloud)
    {
        // a cloud has no elements: RK particles integrated on their Voronoi cells
        if (p.formulation != Formulation::Rkpm)
            s.fail("formulation", "'" + f + "' needs elements, and a cloud part has none",
                   "expected formulation: rkpm");
    }
    if (s.has("regions"))
    {
        // FE-RK coupling: the RK regions of an FE part
        if (p.formulation != Formulation::FemNodal && p.formulation != Formulation::Fem1pt)
            s.fail("regions", "RK regions are coupled to an FE side of formulation fem-nodal or fem-1pt",
                   "expected formulation: fem-nodal or fem-1pt on a part with regions");
        if (p.generator.type == GeneratorSpec::Type::Cloud)
            s.fail("regions", "a cloud part has no elements to divide", "remove regions");
        p.regions_loc = s.loc("regions");
        const YAML::Node rn = s.node("regions");
        if (!rn.IsSequence() || rn.size() == 0)
            s.fail("regions", "is not a non-empty list",
                   "expected regions: [{select: {type: box | cylinder | sphere, ...}}]");
        for (std::size_t i = 0; i < rn.size(); ++i)
        {
            Section r(ctx, rn[i], s.path("regions") + "." + std::to_string(i), {"formulation", "select"});
            r.choice("formulation", {"rkpm"}, "rkpm");
            SelectorSpec sel = read_selector(r);
            if (sel.type != SelectorSpec::Type::Box && sel.type != SelectorSpec::Type::Cylinder &&
                sel.type != SelectorSpec::Type::Sphere)
                r.fail("select", "a region is a volume", "expected select type box, cylinder or sphere");
            p.regions.push_back(sel);
        }
    }
    if (p.coupled())
    {
        p.transition = s.choice("transition", {"mixed", "ramp"}, "mixed");
        p.nodal.scheme = s.has("nodal_integration") ? p.nodal.scheme : "scni";
        if (p.nodal.scheme != "scni")
            s.fail("nodal_integration", "a coupled part is integrated by scheme scni (with or without mscni)",
                   "expected nodal_integration.scheme: scni");
    }
    else if (s.has("transition"))
        s.fail("transition", "is only used by parts with regions or conversion", "remove it or add regions");
    if (s.has("rk"))
    {
        if (p.formulation != Formulation::Rkpm && !p.coupled())
            ignore(p, s, "rk", f);
        Section r(ctx, s.node("rk"), s.path("rk"),
                  {"order", "kernel", "support", "normalized_support", "drop_tolerance", "share_translates"});
        p.rk.loc = r.loc();
        const std::string order = r.choice("order", {"1", "2"}, "1");
        p.rk.order = order == "1" ? 1 : 2;
        p.rk.kernel = r.choice("kernel", {"cubic-bspline", "quintic-bspline", "gaussian"}, "cubic-bspline");
        p.rk.support = r.choice("support", {"box", "sphere"}, "box");
        p.rk.normalized_support = r.quantity("normalized_support", dim::none, 1.51);
        p.rk.drop_tolerance = r.quantity("drop_tolerance", dim::none, p.rk.order == 1 ? 1e-5 : 0.0);
        if (!(p.rk.drop_tolerance >= 0.0 && p.rk.drop_tolerance <= 1e-2))
            r.fail("drop_tolerance", "is outside [0, 0.01]",
                   "expected a small fraction such as 1e-5 (0: keep every function)");
        p.rk.share_translates = r.choice("share_translates", {"true", "false"}, "true") == "true";
        if (p.rk.drop_tolerance > 0.0 && p.rk.order != 1)
            r.fail("drop_tolerance", "restores linear reproduction only", "expected drop_tolerance: 0 with order 2");
        const real_t c = p.rk.normalized_support;
        if (!(c >= 1.0 && c <= 4.0))
            r.fail("normalized_support", "is outside [1, 4]",
                   "expected a / h between 1 and 4 (box 1.5-1.8, sphere 1.6-2.0)");
        if (std::abs(c - std::round(c)) < 1e-6)
            r.fail("normalized_support",
                   "is an integer, which puts neighbours exactly on the support boundary of uniform grids",
                   "expected a non-integer value such as " + std::to_string(std::round(c)).substr(0, 1) + ".01");
    }
    if (s.has("hourglass"))
    {
        if (p.formulation != Formulation::Fem1pt)
            ignore(p, s, "hourglass", f);
        Section h(ctx, s.node("hourglass"), s.path("hourglass"), {"type", "coefficient", "plastic_scaling"});
        const std::string t =
            h.choice("type", {"viscous", "stiffness", "assumed-strain", "none", "viscous-plain"}, "viscous");
        p.hourglass.type = t == "viscous"          ? HourglassType::Viscous
                           : t == "stiffness"      ? HourglassType::Stiffness
                           : t == "assumed-strain" ? HourglassType::AssumedStrain
                           : t == "none"           ? HourglassType::None
                                                   : HourglassType::ViscousPlain;
        p.hourglass.coefficient = h.quantity("coefficient", dim::none, 0.1);
        p.hourglass.plastic_scaling =
            h.choice("plastic_scaling", {"true", "false"},
                     p.hourglass.type == HourglassType::AssumedStrain ? "true" : "false") == "true";
        if (h.has("plastic_scaling") && p.hourglass.type != HourglassType::Stiffness &&
            p.hourglass.type != HourglassType::AssumedStrain)
            h.fail("plastic_scaling", "applies to the stiffness forms only",
                   "expected type: stiffness or assumed-strain with plastic_scaling");
        if (!(p.hourglass.coefficient >= 0.0))
            h.fail("coefficient", "is negative", "expected QM >= 0 (LS-DYNA default 0.1)");
    }
    if (p.formulation != Formulation::Fem1pt)
        p.hourglass.type = HourglassType::None;
    if (s.has("bulk_viscosity"))
    {
        Section b(ctx, s.node("bulk_viscosity"), s.path("bulk_viscosity"), {"linear", "quadratic"});
        p.bulk_viscosity.linear = b.quantity("linear", dim::none, 0.06);
        p.bulk_viscosity.quadratic = b.quantity("quadratic", dim::none, 1.5);
        if (p.bulk_viscosity.linear < 0 || p.bulk_viscosity.quadratic < 0)
            b.fail(p.bulk_viscosity.linear < 0 ? "linear" : "quadratic", "is negative", "expected a coefficient >= 0");
    }
    p.initial_velocity = s.vec3("initial_velocity", dim::velocity, Vec3::Zero());
    if (s.has("erosion"))
    {
        if (p.formulation != Formulation::Fem1pt && p.formulation != Formulation::Fem2x2x2)
            s.fail("erosion", "erodes elements of Gauss-point formulations only",
                   "expected formulation fem-1pt or fem-2x2x2 on a part with erosion");
        p.erosion = read_criteria(ctx, s, "erosion", p);
    }
    return p;
}
} // namespace rkfem::deck_detail
