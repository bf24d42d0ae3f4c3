/// @file deck_generators.cpp
/// The deck's part generators (box, cylinder, tube, projectile, clouds, keyword meshes).
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

/// divisions of a box: three integers >= 1, into g.divisions.
void read_divisions(const Section& s, GeneratorSpec& g)
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

/// A box generator: origin, size, and divisions or element_size.
void read_box_generator(const Section& part, const YAML::Node& gn, const std::string& gp, GeneratorSpec& g)
{
    Section s(part.ctx(), gn, gp, "generator.box");
    g.type = GeneratorSpec::Type::Box;
    read_box(s, g);
    if (s.has("divisions"))
        read_divisions(s, g);
    else
        g.element_size = s.positive("element_size", dim::length);
    g.loc = s.loc();
}

/// A cylinder (solid, or a tube) or projectile generator: origin, radius, height or length, element_size, and the
/// cylinder's core or inner_radius or the projectile's direction.
void read_cylinder_generator(const Section& part, const YAML::Node& gn, const std::string& gp, const std::string& type,
                             GeneratorSpec& g)
{
    const bool cyl = type == "cylinder";
    Section s(part.ctx(), gn, gp, cyl ? "generator.cylinder" : "generator.projectile");
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

/// A cloud generator: its box or cylinder body, and a jittered lattice (spacing, jitter, seed) or a points file.
void read_cloud_generator(const Section& part, const YAML::Node& gn, const std::string& gp, GeneratorSpec& g)
{
    Section s(part.ctx(), gn, gp, "generator.cloud");
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
            s.fail("jitter", "is outside [0, 0.45]", "expected a fraction of the spacing that keeps the lattice order");
        g.seed = static_cast<int>(s.integer("seed", 1));
    }
    g.loc = s.loc();
}

/// A key that takes one value or a list of them: the values.
std::vector<YAML::Node> one_or_list(const Section& s, const char* key)
{
    const YAML::Node n = s.node(key);
    std::vector<YAML::Node> items;
    if (n.IsSequence())
        for (std::size_t i = 0; i < n.size(); ++i)
            items.push_back(n[i]);
    else
        items.push_back(n);
    return items;
}

/// pid of a keyword mesh: an integer or a list of integers, into g.mesh_pids.
void read_pids(const Section& s, GeneratorSpec& g)
{
    for (const YAML::Node& it : one_or_list(s, "pid"))
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

/// A keyword generator: an LS-DYNA keyword file, its length unit and the PIDs to take.
void read_keyword_generator(const Section& part, const YAML::Node& gn, const std::string& gp, GeneratorSpec& g)
{
    Section s(part.ctx(), gn, gp, "generator.keyword");
    g.type = GeneratorSpec::Type::Keyword;
    s.require("file", "the path of an LS-DYNA keyword file (*NODE, *ELEMENT_SOLID)");
    g.mesh_file = data_file(s, "file");
    read_length_unit(s, "unit", g.mesh_unit, g.mesh_unit_name);
    if (s.has("pid"))
        read_pids(s, g);
    g.loc = s.loc();
}
/// A Gmsh generator: an MSH file, its length unit and the volume physical groups to take.
void read_gmsh_generator(const Section& part, const YAML::Node& gn, const std::string& gp, GeneratorSpec& g)
{
    Section s(part.ctx(), gn, gp, "generator.gmsh");
    g.type = GeneratorSpec::Type::Gmsh;
    s.require("file", "the path of a Gmsh mesh (.msh, ASCII 4.1 or 2.2)");
    g.mesh_file = data_file(s, "file");
    read_length_unit(s, "unit", g.mesh_unit, g.mesh_unit_name);
    if (s.has("physical"))
    {
        for (const YAML::Node& it : one_or_list(s, "physical"))
        {
            if (!it.IsScalar() || it.Scalar().empty())
                s.fail("physical", "is not a name or a list of names",
                       "expected the volume physical groups to take, by name or tag");
            g.mesh_groups.push_back(it.Scalar());
        }
        if (g.mesh_groups.empty())
            s.fail("physical", "is an empty list", "expected the volume physical groups to take, by name or tag");
    }
    g.loc = s.loc();
}
} // namespace

GeneratorSpec read_generator(const Section& part)
{
    part.require("generator", "a mapping with type: box | cylinder | projectile | cloud | keyword | gmsh");
    const YAML::Node gn = part.node("generator");
    const std::string gp = part.path("generator");
    std::string type;
    if (gn.IsMap() && gn["type"].IsDefined())
        type = gn["type"].Scalar();
    GeneratorSpec g;
    if (type == "box")
        read_box_generator(part, gn, gp, g);
    else if (type == "cylinder" || type == "projectile")
        read_cylinder_generator(part, gn, gp, type, g);
    else if (type == "cloud")
        read_cloud_generator(part, gn, gp, g);
    else if (type == "keyword")
        read_keyword_generator(part, gn, gp, g);
    else if (type == "gmsh")
        read_gmsh_generator(part, gn, gp, g);
    else
    {
        const SourceLocation loc = gn.IsMap() && gn["type"].IsDefined() ? locate(part.ctx(), gn["type"], gp + ".type")
                                                                        : locate(part.ctx(), gn, gp + ".type");
        throw DeckError(loc, type.empty() ? "missing generator type" : "unknown generator '" + type + "'",
                        "expected type: box | cylinder | projectile | cloud | keyword | gmsh");
    }
    return g;
}

/// rate_effects of a kcc or cscm material: true | false, and for kcc a mapping: {law: ceb-fip,
/// compression_cap, tension_cap} (caps: a DIF >= 1 or none) or {curve: [[rate, DIF], ...]} (the
/// LS-DYNA LCRATE form: negative rates are tension; caps allowed too).
} // namespace rkfem::deck_detail
