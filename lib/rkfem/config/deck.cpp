#include "rkfem/config/deck.hpp"
#include "rkfem/config/erk_table_names.hpp"

#include <filesystem>
#include <algorithm>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <yaml-cpp/yaml.h>

#include "rkfem/core/error.hpp"
#include "rkfem/core/units.hpp"

namespace rkfem
{
namespace
{
std::string format_error(const SourceLocation& loc, const std::string& problem,
                         const std::string& expected)
{
    std::string msg = loc.where + ": " + (loc.path.empty() ? std::string("deck") : loc.path) +
                      ": " + problem;
    if (!expected.empty())
        msg += "; " + expected;
    return msg;
}
} // namespace

DeckError::DeckError(const SourceLocation& loc, const std::string& problem,
                     const std::string& expected)
    : std::runtime_error(format_error(loc, problem, expected)), location(loc)
{
}

namespace
{
std::size_t edit_distance(std::string_view a, std::string_view b)
{
    std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
    for (std::size_t j = 0; j <= b.size(); ++j)
        prev[j] = j;
    for (std::size_t i = 1; i <= a.size(); ++i)
    {
        cur[0] = i;
        for (std::size_t j = 1; j <= b.size(); ++j)
            cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1,
                               prev[j - 1] + (a[i - 1] == b[j - 1] ? 0u : 1u)});
        std::swap(prev, cur);
    }
    return prev[b.size()];
}

std::string join(const std::vector<std::string>& items, const char* sep = ", ")
{
    std::string out;
    for (const auto& s : items)
        out += (out.empty() ? "" : sep) + s;
    return out;
}

/// Parsing context: deck name and which key paths came from --set.
struct Context
{
    std::string name;
    std::map<std::string, std::string> overridden; // path -> "path=value"
};

std::string child_path(const std::string& parent, const std::string& key)
{
    return parent.empty() ? key : parent + "." + key;
}

SourceLocation locate(const Context& ctx, const YAML::Node& node, const std::string& path)
{
    for (const auto& [p, text] : ctx.overridden)
        if (path == p || path.rfind(p + ".", 0) == 0)
            return {"--set " + text, path};
    const YAML::Mark m = node.Mark();
    if (m.is_null() || m.line < 0)
        return {ctx.name, path};
    return {ctx.name + ":" + std::to_string(m.line + 1), path};
}

/// A YAML mapping with a fixed set of allowed keys. Unknown keys are rejected at construction
/// (with the closest allowed key suggested).
class Section
{
  public:
    Section(const Context& ctx, const YAML::Node& node, std::string path,
            std::vector<std::string> allowed)
        : ctx_(ctx), node_(node), path_(std::move(path)), allowed_(std::move(allowed))
    {
        if (!node_.IsMap())
            throw DeckError(locate(ctx_, node_, path_),
                            node_.IsNull() ? "is empty" : "is not a mapping",
                            "expected keys: " + join(allowed_));
        std::map<std::string, YAML::Node> seen; // yaml-cpp keeps both of a repeated key; [] reads the first
        for (const auto& kv : node_)
        {
            const std::string key = kv.first.as<std::string>();
            if (const auto [it, fresh] = seen.emplace(key, kv.first); !fresh)
            {
                const YAML::Mark first = it->second.Mark();
                throw DeckError(locate(ctx_, kv.first, child_path(path_, key)), "key '" + key + "' given twice",
                                "each key once" + (first.is_null() ? std::string()
                                                                   : " (first given on line " +
                                                                         std::to_string(first.line + 1) + ")"));
            }
            if (std::find(allowed_.begin(), allowed_.end(), key) != allowed_.end())
                continue;
            std::string best;
            std::size_t best_d = 1000;
            for (const auto& a : allowed_)
            {
                const std::size_t d = edit_distance(key, a);
                if (d < best_d)
                {
                    best_d = d;
                    best = a;
                }
            }
            const std::string cp = child_path(path_, key);
            const bool close = best_d <= std::max<std::size_t>(2, key.size() / 3);
            throw DeckError(locate(ctx_, kv.first, cp), "unknown key '" + key + "'",
                            close ? "did you mean '" + best + "'? (valid keys: " + join(allowed_) +
                                        ")"
                                  : "valid keys: " + join(allowed_));
        }
    }

    bool has(const std::string& key) const { return node_[key].IsDefined() && !node_[key].IsNull(); }
    YAML::Node node(const std::string& key) const { return node_[key]; }
    const YAML::Node& self() const { return node_; }
    std::string path(const std::string& key) const { return child_path(path_, key); }
    const std::string& path() const { return path_; }
    SourceLocation loc() const { return locate(ctx_, node_, path_); }
    SourceLocation loc(const std::string& key) const
    {
        return has(key) ? locate(ctx_, node_[key], path(key)) : SourceLocation{loc().where, path(key)};
    }
    const Context& ctx() const { return ctx_; }

    [[noreturn]] void fail(const std::string& key, const std::string& problem,
                           const std::string& expected) const
    {
        throw DeckError(loc(key), problem, expected);
    }

    void require(const std::string& key, const std::string& expected) const
    {
        if (!has(key))
            throw DeckError(SourceLocation{loc().where, path(key)}, "missing required key",
                            "expected " + expected);
    }

    std::string scalar_text(const std::string& key, const std::string& expected) const
    {
        const YAML::Node n = node_[key];
        if (!n.IsScalar())
            fail(key, n.IsSequence() ? "is a list" : "is a mapping", "expected " + expected);
        return n.Scalar();
    }

    real_t quantity(const std::string& key, Dimension d) const
    {
        require(key, describe(d));
        return quantity_of(node_[key], path(key), d);
    }
    real_t quantity(const std::string& key, Dimension d, real_t fallback) const
    {
        return has(key) ? quantity(key, d) : fallback;
    }

    real_t quantity_of(const YAML::Node& n, const std::string& p, Dimension d) const
    {
        if (!n.IsScalar())
            throw DeckError(locate(ctx_, n, p), n.IsSequence() ? "is a list" : "is a mapping",
                            "expected " + describe(d));
        try
        {
            return parse_quantity(n.Scalar(), d).value_si;
        }
        catch (const Error& e)
        {
            throw DeckError(locate(ctx_, n, p), e.what(), "");
        }
    }

    real_t positive(const std::string& key, Dimension d) const
    {
        const real_t v = quantity(key, d);
        if (!(v > 0.0))
            fail(key, "must be positive (got " + scalar_text(key, "") + ")",
                 "expected " + describe(d) + " > 0");
        return v;
    }

    long long integer(const std::string& key, long long fallback) const
    {
        if (!has(key))
            return fallback;
        const std::string t = scalar_text(key, "an integer");
        try
        {
            std::size_t pos = 0;
            const long long v = std::stoll(t, &pos);
            if (pos != t.size())
                throw std::invalid_argument(t);
            return v;
        }
        catch (const std::exception&)
        {
            fail(key, "'" + t + "' is not an integer", "expected an integer");
        }
    }

    std::string text(const std::string& key) const
    {
        require(key, "a name");
        return scalar_text(key, "a name");
    }
    std::string text(const std::string& key, const std::string& fallback) const
    {
        return has(key) ? scalar_text(key, "a name") : fallback;
    }

    std::string choice(const std::string& key, const std::vector<std::string>& options,
                       const std::string& fallback) const
    {
        if (!has(key) && !fallback.empty())
            return fallback;
        require(key, "one of " + join(options, " | "));
        const std::string v = scalar_text(key, "one of " + join(options, " | "));
        if (std::find(options.begin(), options.end(), v) == options.end())
            fail(key, "'" + v + "' is not a valid choice", "expected one of " + join(options, " | "));
        return v;
    }

    Vec3 vec3(const std::string& key, Dimension d) const
    {
        require(key, "a list of 3 values, " + describe(d));
        const YAML::Node n = node_[key];
        if (!n.IsSequence() || n.size() != 3)
            fail(key, "is not a list of 3 values", "expected [x, y, z], each " + describe(d));
        Vec3 v;
        for (int i = 0; i < 3; ++i)
            v[i] = quantity_of(n[i], path(key) + "." + std::to_string(i), d);
        return v;
    }
    Vec3 vec3(const std::string& key, Dimension d, const Vec3& fallback) const
    {
        return has(key) ? vec3(key, d) : fallback;
    }

  private:
    const Context& ctx_;
    YAML::Node node_;
    std::string path_;
    std::vector<std::string> allowed_;
};

// --------------------------------------------------------------------------------------------
// pieces

TimeFunction read_time_function(const Section& parent, const YAML::Node& n, const std::string& p,
                                Dimension d)
{
    if (n.IsScalar())
        return TimeFunction::constant(parent.quantity_of(n, p, d));
    Section s(parent.ctx(), n, p, {"value", "curve", "triangular", "scale"});
    TimeFunction f;
    int kinds = 0;
    if (s.has("value"))
    {
        f = TimeFunction::constant(s.quantity("value", d));
        ++kinds;
    }
    if (s.has("curve"))
    {
        ++kinds;
        f.kind = TimeFunction::Kind::Table;
        const YAML::Node c = s.node("curve");
        if (!c.IsSequence() || c.size() < 2)
            s.fail("curve", "needs at least two points",
                   "expected [[t0, value0], [t1, value1], ...] with times in increasing order");
        for (std::size_t i = 0; i < c.size(); ++i)
        {
            const std::string pi = s.path("curve") + "." + std::to_string(i);
            if (!c[i].IsSequence() || c[i].size() != 2)
                throw DeckError(locate(s.ctx(), c[i], pi), "is not a [time, value] pair",
                                "expected [time, " + describe(d) + "]");
            f.times.push_back(s.quantity_of(c[i][0], pi + ".0", dim::time));
            f.values.push_back(s.quantity_of(c[i][1], pi + ".1", d));
            if (i > 0 && !(f.times[i] > f.times[i - 1]))
                throw DeckError(locate(s.ctx(), c[i], pi), "times are not increasing",
                                "expected strictly increasing times");
        }
    }
    if (s.has("triangular"))
    {
        ++kinds;
        Section t(s.ctx(), s.node("triangular"), s.path("triangular"), {"peak", "duration", "start"});
        f.kind = TimeFunction::Kind::Triangular;
        f.peak = t.quantity("peak", d);
        f.duration = t.positive("duration", dim::time);
        f.start = t.quantity("start", dim::time, 0.0);
    }
    if (kinds != 1)
        throw DeckError(s.loc(), kinds == 0 ? "has no value" : "has more than one definition",
                        "expected exactly one of value | curve | triangular");
    f.scale = s.has("scale") ? s.quantity("scale", dim::none) : 1.0;
    return f;
}

int component_index(const std::string& c)
{
    if (c == "x")
        return 0;
    if (c == "y")
        return 1;
    if (c == "z")
        return 2;
    return -1;
}

void read_components(const Section& s, const std::string& key, Dimension d,
                     std::array<bool, 3>& active, std::array<TimeFunction, 3>& value)
{
    Section c(s.ctx(), s.node(key), s.path(key), {"x", "y", "z"});
    bool any = false;
    for (const char* comp : {"x", "y", "z"})
        if (c.has(comp))
        {
            const int i = component_index(comp);
            active[i] = true;
            value[i] = read_time_function(c, c.node(comp), c.path(comp), d);
            any = true;
        }
    if (!any)
        s.fail(key, "names no component", "expected a mapping with x, y and/or z");
}

/// origin (default 0) and size (three positive lengths) of a box or a cloud's box body.
void read_box(const Section& s, GeneratorSpec& g)
{
    g.origin = s.vec3("origin", dim::length, Vec3::Zero());
    g.size = s.vec3("size", dim::length);
    for (int i = 0; i < 3; ++i)
        if (!(g.size[i] > 0))
            s.fail("size", "has a non-positive edge", "expected three positive lengths");
}

GeneratorSpec read_generator(const Section& part)
{
    part.require("generator", "a mapping with type: box | cylinder | projectile | cloud");
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
        Section s(part.ctx(), gn, gp,
                  cyl ? std::vector<std::string>{"type", "origin", "radius", "height",
                                                 "element_size", "core"}
                      : std::vector<std::string>{"type", "origin", "radius", "length",
                                                 "element_size", "direction"});
        g.type = cyl ? GeneratorSpec::Type::Cylinder : GeneratorSpec::Type::Projectile;
        g.origin = s.vec3("origin", dim::length, Vec3::Zero());
        g.radius = s.positive("radius", dim::length);
        g.height = s.positive(cyl ? "height" : "length", dim::length);
        g.element_size = s.positive("element_size", dim::length);
        if (cyl)
            g.core = s.choice("core", {"butterfly", "ogrid"}, "butterfly");
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
            const std::filesystem::path file = s.text("points");
            g.points_file = file.is_absolute() ? file.string()
                                               : (std::filesystem::path(part.ctx().name).parent_path() / file).string();
            const std::string unit = s.text("points_unit", "m");
            std::string err;
            const std::optional<Unit> u = parse_unit(unit, &err);
            if (!u || !(u->dimension == dim::length))
                s.fail("points_unit", "'" + unit + "' is not a length unit" + (err.empty() ? "" : " (" + err + ")"),
                       "expected one of " + known_units_for(dim::length));
            g.points_unit = u->scale;
        }
        else
        {
            g.element_size = s.positive("spacing", dim::length);
            g.jitter = s.quantity("jitter", dim::none, 0.25);
            if (!(g.jitter >= 0.0 && g.jitter <= 0.45))
                s.fail("jitter", "is outside [0, 0.45]", "expected a fraction of the spacing that keeps the lattice order");
            g.seed = static_cast<int>(s.integer("seed", 1));
        }
        g.loc = s.loc();
    }
    else
    {
        const SourceLocation loc = gn.IsMap() && gn["type"].IsDefined()
                                       ? locate(part.ctx(), gn["type"], gp + ".type")
                                       : locate(part.ctx(), gn, gp + ".type");
        throw DeckError(loc, type.empty() ? "missing generator type" : "unknown generator '" + type + "'",
                        "expected type: box | cylinder | projectile | cloud");
    }
    return g;
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
        static const std::vector<std::pair<std::string, Dimension>> cscm_keys = {
            {"alpha", dim::pressure}, {"theta", dim::none},  {"lambda", dim::pressure},
            {"beta", Dimension{-1, 1, 2}}, {"R", dim::none}, {"X0", dim::pressure},
            {"W", dim::none},          {"D1", Dimension{-1, 1, 2}}, {"D2", Dimension{-2, 2, 4}},
            {"B", dim::none},          {"D", dim::none},     {"Gfc", Dimension{1, 0, -2}},
            {"length", dim::length}};
        // kcc: the generated Release III coefficients (materials.md 1.9), likewise
        static const std::vector<std::pair<std::string, Dimension>> kcc_keys = {
            {"a0", dim::pressure}, {"a1", dim::none}, {"a2", Dimension{-1, 1, 2}},
            {"a0y", dim::pressure}, {"a1y", dim::none}, {"a2y", Dimension{-1, 1, 2}},
            {"a1f", dim::none}, {"a2f", Dimension{-1, 1, 2}}, {"b1", dim::none}, {"b2", dim::none},
            {"b3", dim::none}, {"omega", dim::none}, {"ft", dim::pressure}};
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
        const bool cscm = model == "cscm";
        m.nu = s.quantity("nu", dim::none, cscm ? 0.2 : 0.19);
        if (!(m.nu > -1.0 && m.nu < 0.5))
            s.fail("nu", "is out of range", cscm ? "expected -1 < nu < 0.5 (default 0.2)" : "expected -1 < nu < 0.5 (default 0.19)");
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
                if ((i == 0 && m.kcc_eos_strain[0] != 0.0) || (i > 0 && !(m.kcc_eos_strain[i] < m.kcc_eos_strain[i - 1])) ||
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
                if (!(v > 0) && !any_sign)
                    s.fail(k, "must be positive", "expected a positive " + k);
                m.overrides.emplace_back(k, v);
            }
        m.rate_effects = s.has("rate_effects") && s.choice("rate_effects", {"true", "false"}, "false") == "true";
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
            s.fail("nu", "Poisson's ratio " + s.scalar_text("nu", "") + " is out of range",
                   "expected -1 < nu < 0.5");
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
                }
                else
                    throw DeckError(locate(s.ctx(), en.IsMap() && en["type"].IsDefined() ? en["type"] : en, s.path("eos") + ".type"),
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

SelectorSpec read_selector(const Section& parent);

PartSpec read_part(const Context& ctx, const std::string& name, const YAML::Node& n,
                   const std::string& path)
{
    Section s(ctx, n, path,
              {"generator", "material", "formulation", "hourglass", "bulk_viscosity",
               "nodal_integration", "rk", "initial_velocity", "regions", "transition", "erosion"});
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
    if (s.has("nodal_integration"))
    {
        if (!is_nodal(p.formulation))
            s.fail("nodal_integration", "is only used by formulations fem-nodal and rkpm",
                   "remove it or set formulation: rkpm (or fem-nodal)");
        Section ni(ctx, s.node("nodal_integration"), s.path("nodal_integration"),
                   {"scheme", "stabilization", "stabilization_coefficient", "dt_factor"});
        p.nodal.scheme = ni.choice("scheme", {"scni", "sd-scni", "dni"}, "scni");
        const bool cloud = p.generator.type == GeneratorSpec::Type::Cloud;
        p.nodal.stabilization =
            ni.choice("stabilization", {"mscni", "none"}, p.nodal.scheme == "scni" && !cloud ? "mscni" : "none");
        if (p.nodal.stabilization == "mscni" && p.nodal.scheme != "scni")
            ni.fail("stabilization", "mscni stabilizes scheme scni only",
                    "expected stabilization: none with scheme " + p.nodal.scheme);
        p.nodal.stabilization_coefficient = ni.quantity("stabilization_coefficient", dim::none, 1.0);
        if (!(p.nodal.stabilization_coefficient >= 0.0))
            ni.fail("stabilization_coefficient", "is negative", "expected c_s >= 0 (1 is the RKPM2D default)");
        p.nodal.dt_factor = ni.quantity("dt_factor", dim::none, 0.0);
        if (!(p.nodal.dt_factor >= 0.0 && p.nodal.dt_factor <= 2.0))
            ni.fail("dt_factor", "is outside [0, 2]", "expected alpha in (0, 2], or 0 for the calibrated default");
    }
    if (p.generator.type == GeneratorSpec::Type::Cloud)
    {
        // a cloud has no elements: RK particles integrated on their Voronoi cells
        if (p.formulation != Formulation::Rkpm)
            s.fail("formulation", "'" + f + "' needs elements, and a cloud part has none", "expected formulation: rkpm");
        if (!s.has("nodal_integration"))
            p.nodal.stabilization = "none";
    }
    if (s.has("regions"))
    {
        // FE-RK coupling: the RK regions of an FE part
        if (p.formulation != Formulation::FemNodal)
            s.fail("regions", "RK regions are coupled to formulation fem-nodal only (fem-1pt is not built yet)",
                   "expected formulation: fem-nodal on a part with regions");
        if (p.generator.type == GeneratorSpec::Type::Cloud)
            s.fail("regions", "a cloud part has no elements to divide", "remove regions");
        p.regions_loc = s.loc("regions");
        const YAML::Node rn = s.node("regions");
        if (!rn.IsSequence() || rn.size() == 0)
            s.fail("regions", "is not a non-empty list", "expected regions: [{select: {type: box | cylinder | sphere, ...}}]");
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
        p.transition = s.choice("transition", {"mixed", "ramp"}, "mixed");
        p.nodal.scheme = s.has("nodal_integration") ? p.nodal.scheme : "scni";
        if (p.nodal.scheme != "scni")
            s.fail("nodal_integration", "a coupled part is integrated by scheme scni (with or without mscni)",
                   "expected nodal_integration.scheme: scni");
    }
    else if (s.has("transition"))
        s.fail("transition", "is only used by parts with regions", "remove it or add regions");
    if (s.has("rk"))
    {
        if (p.formulation != Formulation::Rkpm && !p.coupled())
            s.fail("rk", "is only used by formulation rkpm and by parts with regions",
                   "remove it or set formulation: rkpm");
        Section r(ctx, s.node("rk"), s.path("rk"), {"order", "kernel", "support", "normalized_support"});
        p.rk.loc = r.loc();
        const std::string order = r.choice("order", {"1", "2"}, "1");
        p.rk.order = order == "1" ? 1 : 2;
        p.rk.kernel = r.choice("kernel", {"cubic-bspline", "quintic-bspline", "gaussian"}, "cubic-bspline");
        p.rk.support = r.choice("support", {"box", "sphere"}, "box");
        p.rk.normalized_support = r.quantity("normalized_support", dim::none, 1.51);
        const real_t c = p.rk.normalized_support;
        if (!(c >= 1.0 && c <= 4.0))
            r.fail("normalized_support", "is outside [1, 4]", "expected a / h between 1 and 4 (box 1.5-1.8, sphere 1.6-2.0)");
        if (std::abs(c - std::round(c)) < 1e-6)
            r.fail("normalized_support",
                   "is an integer, which puts neighbours exactly on the support boundary of uniform grids",
                   "expected a non-integer value such as " + std::to_string(std::round(c)).substr(0, 1) + ".01");
    }
    if (s.has("hourglass"))
    {
        if (p.formulation != Formulation::Fem1pt)
            s.fail("hourglass", "is only used by formulation fem-1pt",
                   "remove it or set formulation: fem-1pt");
        Section h(ctx, s.node("hourglass"), s.path("hourglass"), {"type", "coefficient"});
        const std::string t =
            h.choice("type", {"viscous", "stiffness", "none", "viscous-plain"}, "viscous");
        p.hourglass.type = t == "viscous"     ? HourglassType::Viscous
                           : t == "stiffness" ? HourglassType::Stiffness
                           : t == "none"      ? HourglassType::None
                                              : HourglassType::ViscousPlain;
        p.hourglass.coefficient = h.quantity("coefficient", dim::none, 0.1);
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
            b.fail(p.bulk_viscosity.linear < 0 ? "linear" : "quadratic", "is negative",
                   "expected a coefficient >= 0");
    }
    p.initial_velocity = s.vec3("initial_velocity", dim::velocity, Vec3::Zero());
    if (s.has("erosion"))
    {
        if (p.formulation != Formulation::Fem1pt && p.formulation != Formulation::Fem2x2x2)
            s.fail("erosion", "erodes elements of Gauss-point formulations only",
                   "expected formulation fem-1pt or fem-2x2x2 on a part with erosion");
        if (p.material.model == "elastic")
            s.fail("erosion", "needs a material with history (plastic strain, damage)",
                   "expected material model j2, kcc or cscm");
        Section e(ctx, s.node("erosion"), s.path("erosion"), {"effective_plastic_strain", "damage"});
        p.erosion.plastic_strain = e.quantity("effective_plastic_strain", dim::none, 0.0);
        p.erosion.damage = e.quantity("damage", dim::none, 0.0);
        if (!(p.erosion.plastic_strain >= 0.0 && std::isfinite(p.erosion.plastic_strain)))
            e.fail("effective_plastic_strain", "is negative or not finite", "expected a strain > 0 (0: off)");
        if (!(p.erosion.damage >= 0.0 && p.erosion.damage <= 1.0))
            e.fail("damage", "is outside [0, 1]", "expected a damage index in (0, 1] (0: off)");
        if (!p.erosion.active())
            s.fail("erosion", "has no criterion", "expected effective_plastic_strain and/or damage > 0");
    }
    return p;
}

SelectorSpec read_selector(const Section& parent)
{
    parent.require("select", "a mapping with type: named | plane | box | cylinder | sphere");
    const YAML::Node n = parent.node("select");
    const std::string p = parent.path("select");
    const std::string type = n.IsMap() && n["type"].IsDefined() ? n["type"].Scalar() : "";
    SelectorSpec sel;
    const Context& ctx = parent.ctx();
    if (type == "named")
    {
        Section s(ctx, n, p, {"type", "name"});
        sel.type = SelectorSpec::Type::Named;
        sel.name = s.text("name");
    }
    else if (type == "plane")
    {
        Section s(ctx, n, p, {"type", "point", "normal", "tolerance"});
        sel.type = SelectorSpec::Type::Plane;
        sel.point = s.vec3("point", dim::length);
        sel.normal = s.vec3("normal", dim::none);
        if (sel.normal.norm() == 0)
            s.fail("normal", "is the zero vector", "expected a nonzero direction");
        sel.normal.normalize();
        sel.tolerance = s.quantity("tolerance", dim::length, -1.0);
    }
    else if (type == "box")
    {
        Section s(ctx, n, p, {"type", "min", "max", "tolerance"});
        sel.type = SelectorSpec::Type::Box;
        sel.min = s.vec3("min", dim::length);
        sel.max = s.vec3("max", dim::length);
        sel.tolerance = s.quantity("tolerance", dim::length, -1.0);
    }
    else if (type == "cylinder")
    {
        Section s(ctx, n, p, {"type", "point", "axis", "radius", "tolerance"});
        sel.type = SelectorSpec::Type::Cylinder;
        sel.point = s.vec3("point", dim::length);
        sel.normal = s.vec3("axis", dim::none);
        if (sel.normal.norm() == 0)
            s.fail("axis", "is the zero vector", "expected a nonzero direction");
        sel.normal.normalize();
        sel.radius = s.positive("radius", dim::length);
        sel.tolerance = s.quantity("tolerance", dim::length, -1.0);
    }
    else if (type == "sphere")
    {
        Section s(ctx, n, p, {"type", "point", "radius"});
        sel.type = SelectorSpec::Type::Sphere;
        sel.point = s.vec3("point", dim::length);
        sel.radius = s.positive("radius", dim::length);
    }
    else
        throw DeckError(locate(ctx, n.IsMap() && n["type"].IsDefined() ? n["type"] : n, p + ".type"),
                        type.empty() ? "missing selector type" : "unknown selector '" + type + "'",
                        "expected type: named | plane | box | cylinder | sphere");
    return sel;
}

std::vector<SetSpec> read_sets(const Context& ctx, const YAML::Node& root, const std::string& key)
{
    std::vector<SetSpec> out;
    const YAML::Node n = root[key];
    if (!n.IsDefined() || n.IsNull())
        return out;
    if (!n.IsMap())
        throw DeckError(locate(ctx, n, key), "is not a mapping", "expected name: {part, select}");
    for (const auto& kv : n)
    {
        const std::string name = kv.first.as<std::string>();
        Section s(ctx, kv.second, key + "." + name, {"part", "select"});
        SetSpec set;
        set.name = name;
        set.part = s.text("part", "");
        set.select = read_selector(s);
        set.loc = s.loc();
        out.push_back(std::move(set));
    }
    return out;
}

BoundarySpec read_boundary(const Context& ctx, const YAML::Node& n, const std::string& p)
{
    Section s(ctx, n, p, {"node_set", "fixed", "velocity", "displacement"});
    BoundarySpec b;
    b.loc = s.loc();
    b.node_set = s.text("node_set");
    const int kinds = int(s.has("fixed")) + int(s.has("velocity")) + int(s.has("displacement"));
    if (kinds != 1)
        throw DeckError(s.loc(), kinds == 0 ? "has no condition" : "has more than one condition",
                        "expected exactly one of fixed | velocity | displacement");
    if (s.has("fixed"))
    {
        b.kind = BoundarySpec::Kind::Fixed;
        const YAML::Node f = s.node("fixed");
        std::vector<std::string> comps;
        if (f.IsScalar() && f.Scalar() == "all")
            comps = {"x", "y", "z"};
        else if (f.IsSequence())
            for (const auto& c : f)
                comps.push_back(c.IsScalar() ? c.Scalar() : "?");
        else if (f.IsScalar())
            comps = {f.Scalar()};
        for (const auto& c : comps)
        {
            const int i = component_index(c);
            if (i < 0)
                s.fail("fixed", "'" + c + "' is not a component",
                       "expected all or a list of x, y, z");
            b.active[i] = true;
            b.value[i] = TimeFunction::constant(0.0);
        }
        if (comps.empty())
            s.fail("fixed", "names no component", "expected all or a list of x, y, z");
    }
    else if (s.has("velocity"))
    {
        b.kind = BoundarySpec::Kind::Velocity;
        read_components(s, "velocity", dim::velocity, b.active, b.value);
    }
    else
    {
        b.kind = BoundarySpec::Kind::Displacement;
        read_components(s, "displacement", dim::length, b.active, b.value);
    }
    return b;
}

LoadSpec read_load(const Context& ctx, const YAML::Node& n, const std::string& p)
{
    const std::string type = n.IsMap() && n["type"].IsDefined() ? n["type"].Scalar() : "";
    LoadSpec l;
    if (type == "nodal_force")
    {
        Section s(ctx, n, p, {"type", "node_set", "force", "total"});
        l.kind = LoadSpec::Kind::NodalForce;
        l.set = s.text("node_set");
        s.require("force", "a mapping of components x, y, z to forces");
        read_components(s, "force", dim::force, l.active, l.force);
        l.total = s.has("total") ? s.choice("total", {"true", "false"}, "false") == "true" : false;
        l.loc = s.loc();
    }
    else if (type == "pressure")
    {
        Section s(ctx, n, p, {"type", "face_set", "pressure"});
        l.kind = LoadSpec::Kind::Pressure;
        l.set = s.text("face_set");
        s.require("pressure", "a pressure, curve or triangular pulse");
        l.pressure = read_time_function(s, s.node("pressure"), s.path("pressure"), dim::pressure);
        l.loc = s.loc();
    }
    else
        throw DeckError(locate(ctx, n.IsMap() && n["type"].IsDefined() ? n["type"] : n, p + ".type"),
                        type.empty() ? "missing load type" : "unknown load type '" + type + "'",
                        "expected type: nodal_force | pressure");
    return l;
}

TimeSpec read_time(const Context& ctx, const YAML::Node& root)
{
    if (!root["time"].IsDefined())
        throw DeckError({ctx.name, "time"}, "missing required key",
                        "expected a mapping with at least end: (e.g. end: 26 us)");
    Section s(ctx, root["time"], "time",
              {"end", "output_interval", "history_interval", "dt_scale", "dt_max", "max_steps",
               "stepper", "erk_table", "energy_error_limit", "mass_damping"});
    TimeSpec t;
    t.end = s.positive("end", dim::time);
    t.output_interval = s.quantity("output_interval", dim::time, 0.0);
    t.history_interval = s.quantity("history_interval", dim::time, 0.0);
    if (t.output_interval < 0 || t.history_interval < 0)
        s.fail(t.output_interval < 0 ? "output_interval" : "history_interval", "is negative",
               "expected a time >= 0");
    t.dt_scale = s.quantity("dt_scale", dim::none, 0.9);
    if (!(t.dt_scale > 0 && t.dt_scale <= 1.0))
        s.fail("dt_scale", "is out of range", "expected 0 < dt_scale <= 1");
    t.dt_max = s.quantity("dt_max", dim::time, 0.0);
    t.max_steps = s.integer("max_steps", 0);
    if (t.max_steps < 0)
        s.fail("max_steps", "is negative", "expected an integer >= 0 (0: no limit)");
    const std::string st = s.choice("stepper", {"central-difference", "arkode-cd", "arkode-erk"}, "arkode-cd");
    t.stepper = st == "arkode-cd"    ? StepperKind::ArkodeCd
                : st == "arkode-erk" ? StepperKind::ArkodeErk
                                     : StepperKind::CentralDifference;
    if (s.has("erk_table"))
    {
        if (t.stepper != StepperKind::ArkodeErk)
            s.fail("erk_table", "is only used by stepper arkode-erk", "remove it or set stepper: arkode-erk");
        t.erk_table = s.choice("erk_table", erk_table_names(), "ARKODE_BOGACKI_SHAMPINE_4_2_3");
    }
    t.energy_error_limit = s.quantity("energy_error_limit", dim::none, 0.05);
    if (!(t.energy_error_limit > 0))
        s.fail("energy_error_limit", "must be positive", "expected a fraction > 0 (e.g. 0.05)");
    t.mass_damping = s.quantity("mass_damping", Dimension{0, 0, -1}, 0.0);
    if (t.mass_damping < 0)
        s.fail("mass_damping", "is negative", "expected a rate >= 0 (1/s)");
    return t;
}

/// Applies "a.b.0.c=value" to the YAML tree.
void apply_override(YAML::Node root, const std::string& text, Context& ctx)
{
    const auto eq = text.find('=');
    if (eq == std::string::npos || eq == 0)
        throw DeckError({"--set " + text, ""}, "is not of the form key.path=value",
                        "expected e.g. --set parts.column.material.E=\"210 GPa\"");
    const std::string path = text.substr(0, eq);
    const std::string value = text.substr(eq + 1);
    std::vector<std::string> keys;
    std::stringstream ss(path);
    for (std::string k; std::getline(ss, k, '.');)
        keys.push_back(k);
    YAML::Node value_node;
    try
    {
        value_node = YAML::Load(value);
    }
    catch (const YAML::Exception& e)
    {
        throw DeckError({"--set " + text, path}, "value is not valid YAML (" + e.msg + ")", "");
    }
    // Walk with fresh handles (yaml-cpp nodes are references into the tree).
    std::vector<YAML::Node> chain{root};
    for (std::size_t i = 0; i + 1 < keys.size(); ++i)
    {
        YAML::Node cur = chain.back();
        const std::string& k = keys[i];
        if (cur.IsSequence())
        {
            std::size_t idx = 0;
            try
            {
                idx = std::stoul(k);
            }
            catch (const std::exception&)
            {
                throw DeckError({"--set " + text, path},
                                "'" + k + "' indexes a list", "expected a number 0.." +
                                    std::to_string(cur.size() - 1));
            }
            if (idx >= cur.size())
                throw DeckError({"--set " + text, path}, "index " + k + " is past the end",
                                "expected 0.." + std::to_string(cur.size() - 1));
            chain.push_back(cur[idx]);
        }
        else if (cur.IsMap() || cur.IsNull() || !cur.IsDefined())
        {
            if (!cur[k].IsDefined() || cur[k].IsNull())
                cur[k] = YAML::Node(YAML::NodeType::Map);
            chain.push_back(cur[k]);
        }
        else
            throw DeckError({"--set " + text, path}, "'" + keys[i - 1] + "' is a value, not a section",
                            "expected a path through mappings and lists");
    }
    YAML::Node last = chain.back();
    if (last.IsSequence())
    {
        const std::size_t idx = std::stoul(keys.back());
        if (idx >= last.size())
            throw DeckError({"--set " + text, path}, "index past the end", "");
        last[idx] = value_node;
    }
    else
        last[keys.back()] = value_node;
    ctx.overridden[path] = text;
}

Deck build(const YAML::Node& root, Context& ctx)
{
    if (!root.IsMap())
        throw DeckError({ctx.name, ""}, "is not a YAML mapping",
                        "expected top-level keys title, time, parts, ...");
    Section top(ctx, root, "",
                {"title", "time", "parts", "node_sets", "face_sets", "boundary_conditions",
                 "loads", "probes"});
    Deck deck;
    deck.path = ctx.name;
    deck.title = top.text("title", "");
    deck.time = read_time(ctx, root);
    deck.time_loc = locate(ctx, root["time"], "time");
    top.require("parts", "a mapping of part names to parts");
    const YAML::Node parts = root["parts"];
    if (!parts.IsMap() || parts.size() == 0)
        top.fail("parts", "is empty or not a mapping", "expected name: {generator, material, ...}");
    for (const auto& kv : parts)
    {
        const std::string name = kv.first.as<std::string>();
        deck.parts.push_back(read_part(ctx, name, kv.second, "parts." + name));
    }
    deck.node_sets = read_sets(ctx, root, "node_sets");
    deck.face_sets = read_sets(ctx, root, "face_sets");
    auto check_part = [&](const SetSpec& s, const char* key)
    {
        if (s.part.empty())
            return;
        for (const auto& p : deck.parts)
            if (p.name == s.part)
                return;
        std::vector<std::string> names;
        for (const auto& p : deck.parts)
            names.push_back(p.name);
        throw DeckError({s.loc.where, std::string(key) + "." + s.name + ".part"},
                        "unknown part '" + s.part + "'", "expected one of " + join(names));
    };
    for (const auto& s : deck.node_sets)
        check_part(s, "node_sets");
    for (const auto& s : deck.face_sets)
        check_part(s, "face_sets");

    auto list = [&](const char* key, auto&& reader, auto& out)
    {
        const YAML::Node n = root[key];
        if (!n.IsDefined() || n.IsNull())
            return;
        if (!n.IsSequence())
            top.fail(key, "is not a list", "expected a list of entries (- ...)");
        for (std::size_t i = 0; i < n.size(); ++i)
            out.push_back(reader(ctx, n[i], std::string(key) + "." + std::to_string(i)));
    };
    list("boundary_conditions", read_boundary, deck.boundary_conditions);
    list("loads", read_load, deck.loads);

    auto set_exists = [&](const std::vector<SetSpec>& sets, const std::string& name)
    {
        return std::any_of(sets.begin(), sets.end(), [&](const SetSpec& s) { return s.name == name; });
    };
    auto names_of = [&](const std::vector<SetSpec>& sets)
    {
        std::vector<std::string> v;
        for (const auto& s : sets)
            v.push_back(s.name);
        return v.empty() ? std::string("(none defined)") : join(v);
    };
    for (std::size_t i = 0; i < deck.boundary_conditions.size(); ++i)
    {
        const auto& b = deck.boundary_conditions[i];
        if (!set_exists(deck.node_sets, b.node_set))
            throw DeckError({b.loc.where, b.loc.path + ".node_set"},
                            "unknown node set '" + b.node_set + "'",
                            "expected one of " + names_of(deck.node_sets));
    }
    for (const auto& l : deck.loads)
    {
        const bool face = l.kind == LoadSpec::Kind::Pressure;
        const auto& sets = face ? deck.face_sets : deck.node_sets;
        if (!set_exists(sets, l.set))
            throw DeckError({l.loc.where, l.loc.path + (face ? ".face_set" : ".node_set")},
                            "unknown " + std::string(face ? "face" : "node") + " set '" + l.set + "'",
                            "expected one of " + names_of(sets));
    }

    const YAML::Node probes = root["probes"];
    if (probes.IsDefined() && !probes.IsNull())
    {
        if (!probes.IsMap())
            top.fail("probes", "is not a mapping", "expected name: {point: [x, y, z]}");
        for (const auto& kv : probes)
        {
            const std::string name = kv.first.as<std::string>();
            Section s(ctx, kv.second, "probes." + name, {"point", "part"});
            ProbeSpec pr;
            pr.name = name;
            pr.point = s.vec3("point", dim::length);
            pr.part = s.text("part", "");
            pr.loc = s.loc();
            deck.probes.push_back(pr);
        }
    }
    return deck;
}
} // namespace

Deck parse_deck(const std::string& text, const std::string& name,
                const std::vector<std::string>& overrides)
{
    Context ctx{name, {}};
    YAML::Node root;
    try
    {
        root = YAML::Load(text);
    }
    catch (const YAML::Exception& e)
    {
        throw DeckError({name + ":" + std::to_string(e.mark.line + 1), ""},
                        "YAML syntax error: " + e.msg, "expected a valid YAML document");
    }
    for (const auto& o : overrides)
        apply_override(root, o, ctx);
    return build(root, ctx);
}

MaterialPointDeck read_material_point_deck(const std::string& path)
{
    std::ifstream in(path);
    if (!in)
        throw DeckError({path, ""}, "cannot be opened", "expected a readable YAML material-point deck");
    std::stringstream ss;
    ss << in.rdbuf();
    Context ctx{path, {}};
    YAML::Node root;
    try
    {
        root = YAML::Load(ss.str());
    }
    catch (const YAML::Exception& e)
    {
        throw DeckError({path + ":" + std::to_string(e.mark.line + 1), ""}, "YAML syntax error: " + e.msg,
                        "expected a valid YAML document");
    }
    if (!root.IsMap())
        throw DeckError({path, ""}, "is not a YAML mapping", "expected top-level keys title, material, path");
    Section top(ctx, root, "", {"title", "material", "path"});
    MaterialPointDeck d;
    d.path = path;
    d.title = top.text("title", "");
    d.material = read_material(top);
    top.require("path", "a mapping with type, strain, rate, steps");
    Section p(ctx, top.node("path"), "path", {"type", "strain", "rate", "confinement", "angle", "length", "steps"});
    MaterialPathSpec& lp = d.load_path;
    lp.type = p.choice("type", {"uniaxial-stress", "uniaxial-strain", "hydrostatic", "pure-shear", "triaxial", "rotation"},
                       "");
    lp.strain = p.quantity("strain", dim::none);
    if (lp.strain == 0.0)
        p.fail("strain", "is zero", "expected a nonzero final strain (negative for compression)");
    lp.rate = p.positive("rate", Dimension{0, 0, -1});
    lp.confinement = p.quantity("confinement", dim::pressure, 0.0);
    if (lp.confinement < 0)
        p.fail("confinement", "is negative", "expected a lateral pressure >= 0");
    lp.angle = p.quantity("angle", dim::none, 0.0);
    lp.length = p.quantity("length", dim::length, 0.0);
    if (lp.length < 0)
        p.fail("length", "is negative", "expected a crack-band length > 0 (or omit it for the model default)");
    lp.steps = static_cast<int>(p.integer("steps", 1000));
    if (lp.steps < 1)
        p.fail("steps", "is below 1", "expected a positive number of steps");
    lp.loc = p.loc();
    return d;
}

Deck read_deck(const std::string& path, const std::vector<std::string>& overrides)
{
    std::ifstream in(path);
    if (!in)
        throw DeckError({path, ""}, "cannot be opened", "expected a readable YAML deck file");
    std::stringstream ss;
    ss << in.rdbuf();
    return parse_deck(ss.str(), path, overrides);
}
} // namespace rkfem
