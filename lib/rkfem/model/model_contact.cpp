// Contact definitions of the deck (key contacts) as contact algorithms on the model's
// surfaces; after erosion a part's surface is its remaining elements' boundary (eroding contact).
#include "rkfem/model/model.hpp"

#include <algorithm>

#include "rkfem/contact/mortar.hpp"
#include "rkfem/contact/node_to_segment.hpp"
#include "rkfem/contact/rigid_wall.hpp"
#include "rkfem/core/error.hpp"

namespace rkfem
{
ContactSurface Model::contact_surface(const std::vector<std::string>& names, const SourceLocation& loc) const
{
    ContactSurface s;
    auto add_part = [&](index_t ip)
    {
        if (is_cloud(ip))
            throw DeckError({loc.where, loc.path + ".surfaces"},
                            "part '" + parts[ip].name + "' is a particle cloud, which has no surface segments yet",
                            "expected parts generated as meshes (box, cylinder, projectile)");
        const HexBlock& blk = blocks[static_cast<std::size_t>(ip)];
        std::vector<index_t> owner;
        const std::vector<Quad> faces = extract_boundary_faces(blk.conn, &owner);
        s.add(faces, owner, blk.conn, nodes.x0, blk.material.bulk_modulus());
    };
    if (names.empty())
        for (index_t ip = 0; ip < static_cast<index_t>(parts.size()); ++ip)
        {
            if (!is_cloud(ip))
                add_part(ip);
        }
    for (const std::string& name : names)
    {
        const auto part = std::find_if(parts.begin(), parts.end(), [&](const PartInfo& p) { return p.name == name; });
        if (part != parts.end())
        {
            add_part(static_cast<index_t>(part - parts.begin()));
            continue;
        }
        const std::vector<Quad>& faces = face_sets.at(name);
        if (faces.empty())
            throw DeckError({loc.where, loc.path + ".surfaces"},
                            "face set '" + name + "' has no mesh faces (cloud facets cannot take contact yet)",
                            "expected a face set on meshed parts");
        // per face: the bulk modulus of its part; the depth behind it from its area
        for (const Quad& q : faces)
        {
            const index_t ip = nodes.part[q[0]];
            s.add({q}, {}, {}, nodes.x0, blocks[static_cast<std::size_t>(ip)].material.bulk_modulus());
        }
    }
    s.finish();
    return s;
}

std::vector<ContactSurface> Model::contact_surfaces(const ContactSpec& c) const
{
    std::vector<ContactSurface> out;
    if (c.kind == ContactSpec::Kind::SurfaceToSurface)
        for (const std::string& name : c.surfaces)
            out.push_back(contact_surface({name}, c.loc));
    else
        out.push_back(contact_surface(c.surfaces, c.loc));
    return out;
}

void Model::build_contacts()
{
    contacts.clear();
    for (const ContactSpec& c : deck_.contacts)
    {
        Friction friction;
        friction.mu_static = c.mu_static;
        friction.mu_dynamic = c.mu_dynamic;
        friction.decay = c.decay;
        if (c.kind == ContactSpec::Kind::RigidWall)
        {
            RigidWallParameters p;
            p.point = c.point;
            p.normal = c.normal;
            p.velocity = c.velocity;
            p.scale = c.penalty_scale;
            p.friction = friction;
            contacts.push_back(std::make_unique<RigidWall>(contact_surfaces(c), p));
            continue;
        }
        ContactParameters p;
        p.soft = c.soft;
        p.penalty_scale = c.penalty_scale;
        p.soft_scale = c.soft_scale;
        p.thickness = c.thickness;
        p.max_penetration = c.max_penetration;
        p.friction = friction;
        if (c.mortar)
            contacts.push_back(std::make_unique<MortarContact>(contact_surfaces(c), p));
        else
            contacts.push_back(std::make_unique<NodeToSegmentContact>(contact_surfaces(c), p));
    }
}

void Model::refresh_contact_surfaces()
{
    for (std::size_t k = 0; k < contacts.size() && k < deck_.contacts.size(); ++k)
        contacts[k]->set_surfaces(contact_surfaces(deck_.contacts[k]));
}
} // namespace rkfem
