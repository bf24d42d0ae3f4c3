#include "rkfem/config/deck_section.hpp"

#include <cmath>
#include <sstream>

#include "rkfem/config/erk_table_names.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/time/erk_tables.hpp"

namespace rkfem::deck_detail
{
TimeFunction read_time_function(const Section& parent, const YAML::Node& n, const std::string& p, Dimension d)
{
    if (n.IsScalar())
        return TimeFunction::constant(parent.quantity_of(n, p, d));
    Section s(parent.ctx(), n, p, "time-function");
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
        Section t(s.ctx(), s.node("triangular"), s.path("triangular"), "triangular");
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

void read_components(const Section& s, const std::string& key, Dimension d, std::array<bool, 3>& active,
                     std::array<TimeFunction, 3>& value)
{
    Section c(s.ctx(), s.node(key), s.path(key), "components");
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

SelectorSpec read_selector(const Section& parent)
{
    parent.require("select", "a mapping with type: named | plane | box | cylinder | sphere | ids | segments");
    const YAML::Node n = parent.node("select");
    const std::string p = parent.path("select");
    const std::string type = n.IsMap() && n["type"].IsDefined() ? n["type"].Scalar() : "";
    SelectorSpec sel;
    const Context& ctx = parent.ctx();
    if (type == "named")
    {
        Section s(ctx, n, p, "selector.named");
        sel.type = SelectorSpec::Type::Named;
        sel.name = s.text("name");
    }
    else if (type == "plane")
    {
        Section s(ctx, n, p, "selector.plane");
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
        Section s(ctx, n, p, "selector.box");
        sel.type = SelectorSpec::Type::Box;
        sel.min = s.vec3("min", dim::length);
        sel.max = s.vec3("max", dim::length);
        sel.tolerance = s.quantity("tolerance", dim::length, -1.0);
    }
    else if (type == "cylinder")
    {
        Section s(ctx, n, p, "selector.cylinder");
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
        Section s(ctx, n, p, "selector.sphere");
        sel.type = SelectorSpec::Type::Sphere;
        sel.point = s.vec3("point", dim::length);
        sel.radius = s.positive("radius", dim::length);
    }
    else if (type == "ids" || type == "segments")
    {
        Section s(ctx, n, p, "selector." + type);
        sel.type = type == "ids" ? SelectorSpec::Type::Ids : SelectorSpec::Type::Segments;
        const YAML::Node list = s.node(type);
        const std::string expected = type == "ids" ? "expected ids: [NID, ...], the keyword file's node numbers"
                                                   : "expected segments: [[N1, N2, N3, N4], ...], the keyword file's "
                                                     "node numbers of boundary faces";
        if (!list.IsSequence() || list.size() == 0)
            s.fail(type, "is not a non-empty list", expected);
        auto nid = [&](const YAML::Node& v, const std::string& vp)
        {
            long long id = 0;
            std::size_t used = 0;
            try
            {
                id = v.IsScalar() ? std::stoll(v.Scalar(), &used) : 0;
            }
            catch (const std::exception&)
            {
                used = 0;
            }
            if (!v.IsScalar() || used != v.Scalar().size())
                throw DeckError(locate(ctx, v, vp), "is not a node number", expected);
            return id;
        };
        for (std::size_t i = 0; i < list.size(); ++i)
        {
            const std::string ip = s.path(type) + "." + std::to_string(i);
            if (sel.type == SelectorSpec::Type::Ids)
            {
                sel.ids.push_back(nid(list[i], ip));
                continue;
            }
            if (!list[i].IsSequence() || list[i].size() != 4)
                throw DeckError(locate(ctx, list[i], ip), "is not a list of 4 node numbers", expected);
            std::array<long long, 4> seg{};
            for (std::size_t k = 0; k < 4; ++k)
                seg[k] = nid(list[i][k], ip + "." + std::to_string(k));
            std::sort(seg.begin(), seg.end());
            sel.segments.push_back(seg);
        }
        std::sort(sel.ids.begin(), sel.ids.end());
        sel.ids.erase(std::unique(sel.ids.begin(), sel.ids.end()), sel.ids.end());
        std::sort(sel.segments.begin(), sel.segments.end());
        sel.segments.erase(std::unique(sel.segments.begin(), sel.segments.end()), sel.segments.end());
    }
    else
        throw DeckError(locate(ctx, n.IsMap() && n["type"].IsDefined() ? n["type"] : n, p + ".type"),
                        type.empty() ? "missing selector type" : "unknown selector '" + type + "'",
                        "expected type: named | plane | box | cylinder | sphere | ids | segments");
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
    reject_repeated_keys(ctx, n, key);
    for (const auto& kv : n)
    {
        const std::string name = kv.first.as<std::string>();
        Section s(ctx, kv.second, key + "." + name, "set");
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
    Section s(ctx, n, p, "boundary");
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
                s.fail("fixed", "'" + c + "' is not a component", "expected all or a list of x, y, z");
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
        Section s(ctx, n, p, "load.nodal_force");
        l.kind = LoadSpec::Kind::NodalForce;
        l.set = s.text("node_set");
        s.require("force", "a mapping of components x, y, z to forces");
        read_components(s, "force", dim::force, l.active, l.force);
        l.total = s.has("total") ? s.choice("total", {"true", "false"}, "false") == "true" : false;
        l.loc = s.loc();
    }
    else if (type == "pressure")
    {
        Section s(ctx, n, p, "load.pressure");
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
    Section s(ctx, root["time"], "time", "time");
    TimeSpec t;
    t.end = s.positive("end", dim::time);
    t.output_interval = s.quantity("output_interval", dim::time, 0.0);
    t.history_interval = s.quantity("history_interval", dim::time, 0.0);
    if (t.output_interval < 0 || t.history_interval < 0)
        s.fail(t.output_interval < 0 ? "output_interval" : "history_interval", "is negative", "expected a time >= 0");
    t.dt_scale = s.quantity("dt_scale", dim::none, 0.9);
    if (!(t.dt_scale > 0 && t.dt_scale <= 1.0))
        s.fail("dt_scale", "is out of range", "expected 0 < dt_scale <= 1");
    t.dt_max = s.quantity("dt_max", dim::time, 0.0);
    if (!(t.dt_max >= 0.0))
        s.fail("dt_max", "is negative", "expected a step cap >= 0 (0: no cap)");
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
    if (t.stepper == StepperKind::ArkodeErk && erk_imaginary_stability_limit(t.erk_table) < kMinErkImaginaryInterval)
    {
        std::string stable;
        for (const std::string& name : erk_table_names())
            if (erk_imaginary_stability_limit(name) >= kMinErkImaginaryInterval)
                stable += (stable.empty() ? "" : ", ") + name;
        s.fail(s.has("erk_table") ? "erk_table" : "stepper",
               t.erk_table + " has no stability interval on the imaginary axis (|R(i y)| > 1 from y = 0 on): a "
                             "solid's undamped waves grow at any step",
               "expected a table with one: " + stable);
    }
    t.energy_error_limit = s.quantity("energy_error_limit", dim::none, 0.05);
    if (!(t.energy_error_limit > 0))
        s.fail("energy_error_limit", "must be positive", "expected a fraction > 0 (e.g. 0.05)");
    t.dt_min_fraction = s.quantity("dt_min_fraction", dim::none, 1e-5);
    if (!(t.dt_min_fraction >= 0 && t.dt_min_fraction < 1))
        s.fail("dt_min_fraction", "is out of range", "expected 0 <= dt_min_fraction < 1 (0: no floor; default 1e-5)");
    t.mass_damping = s.quantity("mass_damping", Dimension{0, 0, -1}, 0.0);
    if (t.mass_damping < 0)
        s.fail("mass_damping", "is negative", "expected a rate >= 0 (1/s)");
    return t;
}
} // namespace rkfem::deck_detail
