// Contact definitions of the deck (key contacts) as contact algorithms on the model's
// surfaces; after erosion a part's surface is its remaining elements' boundary (eroding contact).
#include "rkfem/model/model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "rkfem/contact/kernel_contact.hpp"
#include "rkfem/contact/mortar.hpp"
#include "rkfem/contact/node_to_segment.hpp"
#include "rkfem/contact/rigid_wall.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/discretization/cell_list.hpp"
#include "rkfem/operators/semi_lagrangian_block.hpp"

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
        const HexBlock& blk = meshes[static_cast<std::size_t>(ip)];
        std::vector<index_t> owner;
        const std::vector<Quad> faces = extract_boundary_faces(blk.conn, &owner);
        s.add(faces, owner, blk.conn, nodes.x0, blk.material.bulk_modulus());
        // a semi-Lagrangian RK part's other particles: spheres of half their cube's side (the
        // volume at the start; a box mesh's interior particles then touch where their dual cells do)
        if (const SemiLagrangianForceBlock* sl = semi_lagrangian_block(ip))
        {
            std::vector<char> on_face(static_cast<std::size_t>(sl->n_particles()), 0);
            const index_t begin = sl->nodal_points()->node_begin;
            for (const Quad& q : faces)
                for (index_t n : q)
                    if (n >= begin && n < begin + sl->n_particles())
                        on_face[static_cast<std::size_t>(n - begin)] = 1;
            for (index_t p = 0; p < sl->n_particles(); ++p)
                if (!on_face[static_cast<std::size_t>(p)] && sl->nodal_points()->points.weight[p] > 0.0)
                {
                    // (not a refinement's pool particle, which has no volume while it sleeps; a
                    // refinement event refreshes the surfaces with the children's volumes)
                    s.particles.push_back(begin + p);
                    s.particle_radius.push_back(0.5 * std::cbrt(sl->nodal_points()->points.weight[p]));
                }
        }
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
            s.add({q}, {}, {}, nodes.x0, meshes[static_cast<std::size_t>(ip)].material.bulk_modulus());
        }
    }
    if (s.n_segments() == 0)
        throw DeckError({loc.where, loc.path + ".surfaces"}, "has no surface: every part it names is a particle cloud",
                        "expected meshed parts (box, cylinder, projectile, keyword); clouds take no contact yet");
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

namespace
{
/// A hex's face as a plane: centroid and unit outward normal, and its area
struct FacePlane
{
    Vec3 c, n;
    real_t area;
};

FacePlane face_plane(const std::vector<real_t>& x, const Quad& q)
{
    const Vec3 n = quad_normal(x, q);
    Vec3 c = Vec3::Zero();
    for (index_t i : q)
        c += Vec3(x[3 * i], x[3 * i + 1], x[3 * i + 2]) / 4.0;
    const real_t a = n.norm();
    return {c, a > 0.0 ? Vec3(n / a) : n, a};
}
} // namespace

void Model::check_initial_overlaps() const
{
    for (std::size_t k = 0; k < deck_.contacts.size(); ++k)
    {
        const ContactSpec& c = deck_.contacts[k];
        if (c.kind == ContactSpec::Kind::RigidWall || c.kind == ContactSpec::Kind::Kernel)
            continue;
        // the parts on each side (a face set stands for the parts its faces lie on)
        auto parts_of = [&](const std::vector<std::string>& names)
        {
            std::vector<index_t> out;
            if (names.empty())
                for (index_t ip = 0; ip < static_cast<index_t>(parts.size()); ++ip)
                    out.push_back(ip);
            for (const std::string& name : names)
            {
                const auto part =
                    std::find_if(parts.begin(), parts.end(), [&](const PartInfo& p) { return p.name == name; });
                if (part != parts.end())
                    out.push_back(static_cast<index_t>(part - parts.begin()));
                else if (const auto fs = face_sets.find(name); fs != face_sets.end())
                    for (const Quad& q : fs->second)
                        out.push_back(nodes.part[q[0]]);
            }
            std::sort(out.begin(), out.end());
            out.erase(std::unique(out.begin(), out.end()), out.end());
            out.erase(std::remove_if(out.begin(), out.end(), [&](index_t ip) { return is_cloud(ip); }), out.end());
            return out;
        };
        std::vector<std::pair<index_t, index_t>> pairs; // (solid, surface) of distinct parts
        if (c.kind == ContactSpec::Kind::SurfaceToSurface && c.surfaces.size() == 2)
        {
            const std::vector<index_t> a = parts_of({c.surfaces[0]}), b = parts_of({c.surfaces[1]});
            for (index_t i : a)
                for (index_t j : b)
                    if (i != j)
                        pairs.insert(pairs.end(), {{i, j}, {j, i}});
        }
        else
        {
            const std::vector<index_t> all = parts_of(c.surfaces);
            for (index_t i : all)
                for (index_t j : all)
                    if (i != j)
                        pairs.emplace_back(i, j);
        }
        for (const auto& [solid, surface] : pairs)
        {
            // the surface part's boundary nodes, binned
            const HexBlock& sb = meshes[static_cast<std::size_t>(surface)];
            std::vector<index_t> probe;
            for (const Quad& q : extract_boundary_faces(sb.conn))
                probe.insert(probe.end(), q.begin(), q.end());
            std::sort(probe.begin(), probe.end());
            probe.erase(std::unique(probe.begin(), probe.end()), probe.end());
            std::vector<real_t> px;
            px.reserve(3 * probe.size());
            for (index_t i : probe)
                px.insert(px.end(), {nodes.x0[3 * i], nodes.x0[3 * i + 1], nodes.x0[3 * i + 2]});
            const HexBlock& ab = meshes[static_cast<std::size_t>(solid)];
            const index_t ne = ab.n_elements();
            if (probe.empty() || ne == 0)
                continue;
            real_t volume = 0.0;
            std::vector<index_t> owner;
            const std::vector<Quad> boundary = extract_boundary_faces(ab.conn, &owner);
            std::vector<index_t> first_face(static_cast<std::size_t>(ne) + 1, 0); // CSR: element -> boundary faces
            for (index_t o : owner)
                ++first_face[static_cast<std::size_t>(o) + 1];
            for (std::size_t e = 0; e < static_cast<std::size_t>(ne); ++e)
                first_face[e + 1] += first_face[e];
            std::vector<FacePlane> planes; // of the boundary faces, once
            planes.reserve(boundary.size());
            for (const Quad& q : boundary)
            {
                planes.push_back(face_plane(nodes.x0, q));
                volume += planes.back().c.dot(planes.back().n) * planes.back().area / 3.0;
            }
            const CellList bins(px, std::cbrt(std::max(volume, 1e-300) / static_cast<real_t>(ne)));
            // per probe node: the least depth past the contact's reach over the elements that
            // hold it (NaN: in none); an element with no boundary face is a whole element deep
            constexpr real_t kNone = std::numeric_limits<real_t>::quiet_NaN();
            std::vector<real_t> excess(probe.size(), kNone), depth_of(probe.size(), kNone);
            for (index_t e = 0; e < ne; ++e)
            {
                FacePlane f[6];
                real_t ev = 0.0;
                Vec3 lo = Vec3::Constant(kNoLimit), hi = Vec3::Constant(-kNoLimit);
                for (int a = 0; a < 8; ++a)
                {
                    const index_t i = ab.conn[8 * static_cast<std::size_t>(e) + static_cast<std::size_t>(a)];
                    const Vec3 xi(nodes.x0[3 * i], nodes.x0[3 * i + 1], nodes.x0[3 * i + 2]);
                    lo = lo.cwiseMin(xi), hi = hi.cwiseMax(xi);
                }
                for (int j = 0; j < 6; ++j)
                {
                    Quad q;
                    for (int a = 0; a < 4; ++a)
                        q[a] = ab.conn[8 * static_cast<std::size_t>(e) + static_cast<std::size_t>(hex_faces[j][a])];
                    f[j] = face_plane(nodes.x0, q);
                    ev += f[j].c.dot(f[j].n) * f[j].area / 3.0;
                }
                const real_t tol = 1e-9 * std::cbrt(std::abs(ev));
                bins.for_each_near_box(lo, hi,
                                       [&](index_t p)
                                       {
                                           const Vec3 x(px[3 * p], px[3 * p + 1], px[3 * p + 2]);
                                           for (const FacePlane& fp : f)
                                               if (!((x - fp.c).dot(fp.n) <= tol))
                                                   return; // outside the element (on its faces counts as inside)
                                           real_t depth = std::numeric_limits<real_t>::infinity(), over = depth;
                                           for (index_t b = first_face[e]; b < first_face[e + 1]; ++b)
                                           {
                                               const FacePlane& fp = planes[static_cast<std::size_t>(b)];
                                               const real_t d = -(x - fp.c).dot(fp.n);
                                               depth = std::min(depth, d);
                                               over =
                                                   std::min(over, d - (c.max_penetration * ev / fp.area + c.thickness));
                                           }
                                           real_t& was = excess[static_cast<std::size_t>(p)];
                                           if (std::isnan(was) || over < was)
                                               was = over, depth_of[static_cast<std::size_t>(p)] = depth;
                                       });
            }
            index_t deep = 0, first = -1;
            real_t first_depth = 0.0;
            for (std::size_t p = 0; p < probe.size(); ++p)
                if (excess[p] > 0.0 && deep++ == 0)
                    first = probe[p], first_depth = depth_of[p];
            if (deep > 0)
            {
                std::ostringstream what;
                what.precision(3);
                what << deep << " node(s) of part '" << parts[surface].name << "' start inside part '"
                     << parts[solid].name << "' deeper than the contact reaches (first: "
                     << parts[surface].node_name(first - parts[surface].node_begin);
                if (std::isfinite(first_depth))
                    what << ", " << first_depth << " m behind its surface";
                else
                    what << ", more than an element behind its surface";
                what << ")";
                throw DeckError({c.loc.where, c.loc.path}, what.str(),
                                "expected parts that do not overlap at the start (a node that starts within "
                                "max_penetration of an element's depth behind the surface is held there, none deeper)");
            }
        }
    }
}

const SemiLagrangianForceBlock* Model::semi_lagrangian_block(index_t part) const
{
    const SemiLagrangianForceBlock* found = nullptr;
    for (const PlannedBlock& pb : blocks_)
        if (pb.part == part)
            if (const auto* sl = dynamic_cast<const SemiLagrangianForceBlock*>(pb.block.get()))
                found = sl;
    return found;
}

std::vector<const SemiLagrangianForceBlock*> Model::kernel_contact_bodies(const ContactSpec& c) const
{
    std::vector<const SemiLagrangianForceBlock*> out;
    for (const std::string& name : c.surfaces)
    {
        const auto part = std::find_if(parts.begin(), parts.end(), [&](const PartInfo& p) { return p.name == name; });
        if (part == parts.end())
            throw DeckError({c.loc.where, c.loc.path + ".surfaces"}, "'" + name + "' is not a part",
                            "expected the names of semi-Lagrangian RK parts (kernel contact acts between particles)");
        const index_t ip = static_cast<index_t>(part - parts.begin());
        const SemiLagrangianForceBlock* found = semi_lagrangian_block(ip);
        if (found == nullptr)
            throw DeckError({c.loc.where, c.loc.path + ".surfaces"},
                            "part '" + name + "' is not a semi-Lagrangian RK part",
                            "expected parts with formulation: rkpm and kinematics: semi-lagrangian (or "
                            "nodal_integration.scheme: snni); other parts meet through surface contact");
        out.push_back(found);
    }
    if (out.size() == 2 && out[0] == out[1])
        throw DeckError({c.loc.where, c.loc.path + ".surfaces"}, "names the same part twice",
                        "expected two different semi-Lagrangian RK parts");
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
        if (c.kind == ContactSpec::Kind::Kernel)
        {
            if (deck_.time.stepper != StepperKind::CentralDifference)
                throw DeckError({c.loc.where, c.loc.path + ".type"},
                                "kernel contact shares velocities over a central-difference step",
                                "expected time.stepper: central-difference with kernel contact");
            KernelContactParameters p;
            p.thickness = c.thickness;
            p.friction = friction;
            contacts.push_back(std::make_unique<KernelContact>(kernel_contact_bodies(c), p));
            continue;
        }
        if (c.kind == ContactSpec::Kind::RigidWall)
        {
            RigidWallParameters p;
            p.point = c.point;
            p.normal = c.normal;
            p.velocity = c.velocity;
            p.scale = c.penalty_scale;
            p.friction = friction;
            p.damping.zeta = c.damping;
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
        p.damping.zeta = c.damping;
        if (c.mortar)
            contacts.push_back(std::make_unique<MortarContact>(contact_surfaces(c), p));
        else
            contacts.push_back(std::make_unique<NodeToSegmentContact>(contact_surfaces(c), p));
    }
}

void Model::refresh_contact_surfaces()
{
    for (std::size_t k = 0; k < contacts.size() && k < deck_.contacts.size(); ++k)
    {
        if (deck_.contacts[k].kind == ContactSpec::Kind::Kernel)
            static_cast<KernelContact&>(*contacts[k]).set_bodies(kernel_contact_bodies(deck_.contacts[k]));
        else
            contacts[k]->set_surfaces(contact_surfaces(deck_.contacts[k]));
    }
}
} // namespace rkfem
