// Deck section `contacts`: surface-to-surface, single-surface and rigid-wall definitions.
#include "rkfem/config/deck_section.hpp"

namespace rkfem::deck_detail
{
ContactSpec read_contact(const Context& ctx, const YAML::Node& n, const std::string& p)
{
    // the type decides the keys; read it first from a plain mapping
    if (!n.IsMap())
        throw DeckError(locate(ctx, n, p), n.IsNull() ? "is empty" : "is not a mapping",
                        "expected {type: surface-to-surface | single-surface | rigid-wall | kernel, ...}");
    const YAML::Node type_node = n["type"];
    const std::string type = type_node.IsScalar() ? type_node.Scalar() : "";
    if (type != "surface-to-surface" && type != "single-surface" && type != "rigid-wall" && type != "kernel")
    {
        const std::string expected = "expected one of surface-to-surface | single-surface | rigid-wall | kernel";
        if (!type_node.IsDefined() || type_node.IsNull())
            throw DeckError({locate(ctx, n, p).where, p + ".type"}, "missing required key", expected);
        throw DeckError(locate(ctx, type_node, p + ".type"),
                        type_node.IsScalar() ? "'" + type + "' is not a valid choice" : "is not a name", expected);
    }
    Section s(ctx, n, p, "contact." + type);
    ContactSpec c;
    const std::string t = s.choice("type", {"surface-to-surface", "single-surface", "rigid-wall", "kernel"}, "");
    c.kind = t == "surface-to-surface" ? ContactSpec::Kind::SurfaceToSurface
             : t == "single-surface"   ? ContactSpec::Kind::SingleSurface
             : t == "kernel"           ? ContactSpec::Kind::Kernel
                                       : ContactSpec::Kind::RigidWall;
    if (s.has("surfaces"))
    {
        const YAML::Node list = s.node("surfaces");
        if (!list.IsSequence() || list.size() == 0)
            s.fail("surfaces", "is not a non-empty list", "expected [name, ...], part or face-set names");
        for (std::size_t i = 0; i < list.size(); ++i)
        {
            if (!list[i].IsScalar())
                throw DeckError(locate(ctx, list[i], s.path("surfaces") + "." + std::to_string(i)), "is not a name",
                                "expected a part or face-set name");
            c.surfaces.push_back(list[i].Scalar());
        }
    }
    if (c.kind == ContactSpec::Kind::Kernel && (c.surfaces.empty() || c.surfaces.size() > 2))
        s.fail("surfaces", c.surfaces.empty() ? "missing required key" : "names more than two parts",
               "expected surfaces: [A, B], two semi-Lagrangian RK parts, or [A], one part's separated particles "
               "against the part and each other (self-contact)");
    if (c.kind == ContactSpec::Kind::SurfaceToSurface && c.surfaces.size() != 2)
        s.fail("surfaces", c.surfaces.empty() ? "missing required key" : "does not name two surfaces",
               "expected surfaces: [A, B], two part or face-set names");
    if (s.has("friction"))
    {
        Section f(ctx, s.node("friction"), s.path("friction"), "friction");
        c.mu_static = f.quantity("static", dim::none, 0.0);
        c.mu_dynamic = f.quantity("dynamic", dim::none, c.mu_static);
        c.decay = f.quantity("decay", Dimension{0, -1, 1}, 0.0);
        if (!(c.mu_static >= 0.0))
            f.fail("static", "is negative", "expected a friction coefficient >= 0");
        if (!(c.mu_dynamic >= 0.0))
            f.fail("dynamic", "is negative", "expected a friction coefficient >= 0");
        if (!(c.decay >= 0.0))
            f.fail("decay", "is negative", "expected an exponential decay coefficient >= 0 s/m");
    }
    auto scale = [&](const char* key, real_t fallback, real_t hi)
    {
        const real_t v = s.quantity(key, dim::none, fallback);
        if (!(v > 0.0 && v <= hi))
            s.fail(key, "is outside (0, " + std::to_string(hi).substr(0, 4) + "]",
                   "expected a penalty scale factor above 0 and at most " + std::to_string(hi).substr(0, 4));
        return v;
    };
    if (c.kind == ContactSpec::Kind::Kernel)
    {
        c.thickness = s.quantity("thickness", dim::length, 0.0);
        if (!(c.thickness >= 0.0))
            s.fail("thickness", "is negative", "expected a contact thickness >= 0");
        c.loc = s.loc();
        return c;
    }
    // LS-DYNA's VDC is in percent of critical: `damping: 20 %` reads as 0.2
    c.damping = s.quantity("damping", dim::none, 0.0);
    if (!(c.damping >= 0.0 && c.damping <= 1.0))
        s.fail("damping", "is outside [0, 1]", "expected a fraction of critical damping, e.g. 0.2 or 20 %");
    if (c.kind == ContactSpec::Kind::RigidWall)
    {
        c.point = s.vec3("point", dim::length);
        c.normal = s.vec3("normal", dim::none);
        if (!(c.normal.norm() > 0.0))
            s.fail("normal", "is the zero vector", "expected the wall's normal, pointing to the side the nodes are on");
        c.normal.normalize();
        c.velocity = s.vec3("velocity", dim::velocity, Vec3::Zero());
        // k = scale m / dt0^2 with dt = 0.9 dt0: above 0.8 the wall's spring and the element's
        // frequency together pass the central-difference limit
        c.penalty_scale = scale("penalty_scale", 0.1, 0.8);
        c.loc = s.loc();
        return c;
    }
    c.mortar = s.choice("formulation", {"node-to-segment", "mortar"}, "node-to-segment") == "mortar";
    if (c.mortar && c.kind != ContactSpec::Kind::SurfaceToSurface)
        s.fail("formulation", "'mortar' is for surface-to-surface contact only",
               "expected node-to-segment for single-surface contact");
    c.soft = s.choice("stiffness", {"soft", "segment"}, "soft") == "soft";
    c.penalty_scale = scale("penalty_scale", 0.1, 100.0);
    c.soft_scale = scale("soft_scale", 0.1, 0.8);
    c.thickness = s.quantity("thickness", dim::length, 0.0);
    if (!(c.thickness >= 0.0))
        s.fail("thickness", "is negative", "expected a contact thickness >= 0");
    c.max_penetration = s.quantity("max_penetration", dim::none, 0.5);
    if (!(c.max_penetration > 0.0 && c.max_penetration <= 1.0))
        s.fail("max_penetration", "is outside (0, 1]", "expected a fraction of the element depth behind a segment");
    c.loc = s.loc();
    return c;
}
} // namespace rkfem::deck_detail
