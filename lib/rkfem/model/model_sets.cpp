// Model::build's sets: the parts a name selects, node and face sets, probes and sections.
#include "rkfem/model/model.hpp"

#include <algorithm>
#include <cmath>
#include <map>

namespace rkfem
{
namespace
{
bool matches(const SelectorSpec& s, const Vec3& p, real_t tol)
{
    switch (s.type)
    {
    case SelectorSpec::Type::Plane:
        return std::abs((p - s.point).dot(s.normal)) <= tol;
    case SelectorSpec::Type::Box:
        return (p.array() >= s.min.array() - tol).all() && (p.array() <= s.max.array() + tol).all();
    case SelectorSpec::Type::Cylinder:
    {
        const Vec3 r = p - s.point;
        const Vec3 radial = r - r.dot(s.normal) * s.normal;
        return std::abs(radial.norm() - s.radius) <= tol;
    }
    case SelectorSpec::Type::Sphere:
        return (p - s.point).norm() <= s.radius;
    case SelectorSpec::Type::Named:
    case SelectorSpec::Type::Ids:
    case SelectorSpec::Type::Segments:
        return false;
    }
    return false;
}

bool by_file_ids(const SelectorSpec& s)
{
    return s.type == SelectorSpec::Type::Ids || s.type == SelectorSpec::Type::Segments;
}

/// The NIDs an ids or segments selector names, sorted (segments: their nodes).
std::vector<long long> selected_ids(const SelectorSpec& s)
{
    if (s.type == SelectorSpec::Type::Ids)
        return s.ids;
    std::vector<long long> ids;
    for (const auto& seg : s.segments)
        ids.insert(ids.end(), seg.begin(), seg.end());
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    return ids;
}

/// A part an ids or segments selector may look at: one from a keyword file (its nodes carry NIDs). Parts
/// without are skipped when the set names no part, refused when it names this one.
bool has_file_ids(const PartInfo& pi, const SetSpec& s)
{
    if (!pi.node_ids.empty())
        return true;
    if (!s.part.empty())
        throw DeckError({s.loc.where, s.loc.path + ".select.type"},
                        "part '" + pi.name + "' has no node numbers of a keyword file",
                        "expected ids and segments on parts whose generator is type keyword");
    return false;
}

real_t default_tolerance(const NodeSet& nodes, index_t begin, index_t end)
{
    Vec3 lo = Vec3::Constant(kNoLimit), hi = Vec3::Constant(-kNoLimit);
    for (index_t i = begin; i < end; ++i)
        for (int d = 0; d < 3; ++d)
        {
            lo[d] = std::min(lo[d], nodes.x0[3 * i + d]);
            hi[d] = std::max(hi[d], nodes.x0[3 * i + d]);
        }
    return 1e-6 * (hi - lo).norm();
}
} // namespace

/// The parts named `name` (every part for "").
std::vector<index_t> Model::parts_named(const std::string& name) const
{
    std::vector<index_t> ids;
    for (index_t ip = 0; ip < static_cast<index_t>(parts.size()); ++ip)
        if (name.empty() || parts[ip].name == name)
            ids.push_back(ip);
    return ids;
}

/// The deck's node sets: named groups of the generators or the nodes a selector matches.
void Model::build_node_sets()
{
    for (const auto& s : deck_.node_sets)
    {
        std::vector<index_t> ids;
        for (index_t ip : parts_named(s.part))
        {
            const PartInfo& pi = parts[ip];
            if (s.select.type == SelectorSpec::Type::Named)
            {
                if (s.select.name == "all")
                {
                    for (index_t i = pi.node_begin; i < pi.mesh_node_end; ++i)
                        ids.push_back(i);
                    continue;
                }
                if (auto nit = pi.named_nodes.find(s.select.name); nit != pi.named_nodes.end())
                {
                    ids.insert(ids.end(), nit->second.begin(), nit->second.end());
                    continue;
                }
                auto it = pi.named_faces.find(s.select.name);
                if (it == pi.named_faces.end())
                {
                    std::string names = "all";
                    for (const auto& [n, _] : pi.named_faces)
                        names += ", " + n;
                    for (const auto& [n, _] : pi.named_nodes)
                        names += ", " + n;
                    throw DeckError({s.loc.where, s.loc.path + ".select.name"},
                                    "part '" + pi.name + "' has no set named '" + s.select.name + "'",
                                    "expected one of " + names);
                }
                for (index_t f : it->second)
                    for (index_t n : pi.faces[f])
                        ids.push_back(n);
            }
            else if (by_file_ids(s.select))
            {
                if (!has_file_ids(pi, s))
                    continue;
                const std::vector<long long> wanted = selected_ids(s.select);
                for (index_t i = pi.node_begin; i < pi.mesh_node_end; ++i)
                    if (std::binary_search(wanted.begin(), wanted.end(),
                                           pi.node_ids[static_cast<std::size_t>(i - pi.node_begin)]))
                        ids.push_back(i);
            }
            else
            {
                const real_t tol = s.select.tolerance >= 0 ? s.select.tolerance
                                                           : default_tolerance(nodes, pi.node_begin, pi.mesh_node_end);
                for (index_t i = pi.node_begin; i < pi.mesh_node_end; ++i)
                    if (matches(s.select, Vec3(nodes.x0[3 * i], nodes.x0[3 * i + 1], nodes.x0[3 * i + 2]), tol))
                        ids.push_back(i);
            }
        }
        std::sort(ids.begin(), ids.end());
        ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
        if (ids.empty())
            throw DeckError({s.loc.where, s.loc.path + ".select"}, "selects no node",
                            "expected a selector that matches at least one node of " +
                                (s.part.empty() ? std::string("any part") : "part '" + s.part + "'"));
        node_sets[s.name] = std::move(ids);
    }
}

/// The deck's face sets: boundary faces (mesh parts) or boundary facet points (cloud parts).
void Model::build_face_sets()
{
    for (const auto& s : deck_.face_sets)
    {
        std::vector<Quad> faces;
        std::vector<CloudFacet> facets;
        for (index_t ip : parts_named(s.part))
        {
            const PartInfo& pi = parts[ip];
            if (is_cloud(ip))
            {
                if (by_file_ids(s.select))
                    throw DeckError({s.loc.where, s.loc.path + ".select.type"},
                                    "cloud part '" + pi.name + "' has no node numbers of a keyword file",
                                    "expected ids and segments on parts whose generator is type keyword");
                // the boundary facet points of the Voronoi cells: by the box face they lie on
                // (named) or by the selector applied to the point
                static const std::map<std::string, Vec3> normals = {{"xmin", -Vec3::UnitX()},   {"xmax", Vec3::UnitX()},
                                                                    {"ymin", -Vec3::UnitY()},   {"ymax", Vec3::UnitY()},
                                                                    {"zmin", -Vec3::UnitZ()},   {"zmax", Vec3::UnitZ()},
                                                                    {"bottom", -Vec3::UnitZ()}, {"top", Vec3::UnitZ()}};
                const bool named = s.select.type == SelectorSpec::Type::Named;
                const bool cylinder = deck_.parts[ip].generator.body == GeneratorSpec::Body::Cylinder;
                if (named && s.select.name != "side" &&
                    (!normals.count(s.select.name) ||
                     (cylinder && s.select.name != "top" && s.select.name != "bottom")))
                    throw DeckError({s.loc.where, s.loc.path + ".select.name"},
                                    "cloud part '" + pi.name + "' has no face set named '" + s.select.name + "'",
                                    cylinder ? "expected one of top, bottom, side (a cylinder body)"
                                             : "expected one of xmin, xmax, ymin, ymax, zmin, zmax, top, bottom, side");
                const real_t tol = s.select.tolerance >= 0 ? s.select.tolerance
                                                           : default_tolerance(nodes, pi.node_begin, pi.mesh_node_end);
                for (const CellFacetPoint& fp : nodal_block(ip)->boundary_facets)
                {
                    const Vec3 n = fp.nda.normalized();
                    const bool take = !named                    ? matches(s.select, fp.x, tol)
                                      : s.select.name == "side" ? std::abs(n[2]) < 1e-9
                                                                : n.dot(normals.at(s.select.name)) > 1.0 - 1e-9;
                    if (take)
                        facets.push_back({ip, fp.x, fp.nda});
                }
                continue;
            }
            if (s.select.type == SelectorSpec::Type::Named)
            {
                auto it = pi.named_faces.find(s.select.name);
                if (it == pi.named_faces.end())
                {
                    std::string names;
                    for (const auto& [n, _] : pi.named_faces)
                        names += (names.empty() ? "" : ", ") + n;
                    throw DeckError({s.loc.where, s.loc.path + ".select.name"},
                                    "part '" + pi.name + "' has no face set named '" + s.select.name + "'",
                                    "expected one of " + names);
                }
                for (index_t f : it->second)
                    faces.push_back(pi.faces[f]);
            }
            else if (by_file_ids(s.select))
            {
                if (!has_file_ids(pi, s))
                    continue;
                auto nid = [&](index_t n) { return pi.node_ids[static_cast<std::size_t>(n - pi.node_begin)]; };
                for (const auto& f : pi.faces)
                {
                    std::array<long long, 4> key{nid(f[0]), nid(f[1]), nid(f[2]), nid(f[3])};
                    bool take = true;
                    if (s.select.type == SelectorSpec::Type::Ids)
                        for (long long k : key)
                            take = take && std::binary_search(s.select.ids.begin(), s.select.ids.end(), k);
                    else
                    {
                        std::sort(key.begin(), key.end());
                        take = std::binary_search(s.select.segments.begin(), s.select.segments.end(), key);
                    }
                    if (take)
                        faces.push_back(f);
                }
            }
            else
            {
                const real_t tol = s.select.tolerance >= 0 ? s.select.tolerance
                                                           : default_tolerance(nodes, pi.node_begin, pi.mesh_node_end);
                for (const auto& f : pi.faces)
                {
                    bool all = true;
                    for (index_t n : f)
                        all = all &&
                              matches(s.select, Vec3(nodes.x0[3 * n], nodes.x0[3 * n + 1], nodes.x0[3 * n + 2]), tol);
                    if (all)
                        faces.push_back(f);
                }
            }
        }
        if (faces.empty() && facets.empty())
            throw DeckError({s.loc.where, s.loc.path + ".select"}, "selects no boundary face",
                            "expected a selector that matches all four nodes of at least one boundary face "
                            "(on cloud parts: a point of the cells' boundary facets)");
        face_sets[s.name] = std::move(faces);
        cloud_face_sets[s.name] = std::move(facets);
    }
}

/// Probes (the nearest node) and sections (the nodes on the positive side of each plane).
void Model::build_probes_and_sections()
{
    for (const auto& p : deck_.probes)
    {
        index_t best = -1;
        real_t best_d = kNoLimit;
        for (index_t ip : parts_named(p.part))
            for (index_t i = parts[ip].node_begin; i < parts[ip].mesh_node_end; ++i)
            {
                const real_t dd =
                    (Vec3(nodes.x0[3 * i], nodes.x0[3 * i + 1], nodes.x0[3 * i + 2]) - p.point).squaredNorm();
                if (dd < best_d)
                {
                    best_d = dd;
                    best = i;
                }
            }
        if (best < 0)
            throw DeckError({p.loc.where, p.loc.path + ".part"}, "unknown part '" + p.part + "'",
                            "expected the name of a part");
        probe_nodes.push_back(best);
    }
    // sections: the nodes on the positive side of each plane
    for (const auto& sc : deck_.sections)
    {
        std::vector<index_t> side;
        bool known = sc.part.empty();
        for (index_t ip : parts_named(sc.part))
        {
            known = true;
            const real_t tol = sc.tolerance >= 0
                                   ? sc.tolerance
                                   : default_tolerance(nodes, parts[ip].node_begin, parts[ip].mesh_node_end);
            for (index_t i = parts[ip].node_begin; i < parts[ip].mesh_node_end; ++i)
                if ((Vec3(nodes.x0[3 * i], nodes.x0[3 * i + 1], nodes.x0[3 * i + 2]) - sc.point).dot(sc.normal) >= -tol)
                    side.push_back(i);
        }
        if (!known)
            throw DeckError({sc.loc.where, sc.loc.path + ".part"}, "unknown part '" + sc.part + "'",
                            "expected the name of a part");
        section_nodes.push_back(std::move(side));
    }
}

} // namespace rkfem
