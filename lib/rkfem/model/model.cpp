// GCC 12 reports a false "may be used uninitialized" inside Eigen's AVX-512 kernels (dense LU and
// SparseLU here); every value is initialised.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

#include "rkfem/model/model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>

#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/approximation/rk/rk_shape.hpp"
#include "rkfem/approximation/shape_evaluator.hpp"
#include "rkfem/discretization/generators.hpp"
#include "rkfem/operators/linear_static.hpp"
#include <Eigen/SparseLU>
#include "rkfem/integration/nodal/nodal_integration.hpp"

namespace rkfem
{
struct RkVelocityConstraint
{
    index_t block = 0;                  ///< nodal block
    int component = 0;
    std::vector<index_t> condition;     ///< index into Model::conditions, per constrained node
    std::vector<index_t> node;          ///< global node per constrained node
    std::vector<index_t> slot;          ///< global node -> position in `node`, -1 if free (block range)
    Eigen::SparseLU<SparseMatrix> lu;   ///< Lambda_bb
    Eigen::VectorXd rhs, x;
};

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
        return false;
    }
    return false;
}

real_t default_tolerance(const NodeSet& nodes, index_t begin, index_t end)
{
    Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
    for (index_t i = begin; i < end; ++i)
        for (int d = 0; d < 3; ++d)
        {
            lo[d] = std::min(lo[d], nodes.x0[3 * i + d]);
            hi[d] = std::max(hi[d], nodes.x0[3 * i + d]);
        }
    return 1e-6 * (hi - lo).norm();
}
} // namespace

index_t Model::n_elements() const
{
    index_t n = 0;
    for (const auto& b : blocks)
        n += b.n_elements();
    return n;
}

std::pair<index_t, index_t> Model::locate_element(index_t global) const
{
    for (index_t b = 0; b < static_cast<index_t>(blocks.size()); ++b)
    {
        if (global < blocks[b].n_elements())
            return {b, global};
        global -= blocks[b].n_elements();
    }
    return {-1, -1};
}

Model Model::build(const Deck& deck)
{
    Model m;
    m.deck_ = deck;
    const Deck& d = m.deck_;
    // meshes
    std::vector<HexMesh> meshes;
    index_t n_nodes = 0;
    for (const auto& p : d.parts)
    {
        meshes.push_back(generate(p.generator));
        n_nodes += meshes.back().n_nodes();
    }
    m.nodes.resize(n_nodes);
    index_t offset = 0, elem_offset = 0;
    for (std::size_t ip = 0; ip < d.parts.size(); ++ip)
    {
        const PartSpec& ps = d.parts[ip];
        const HexMesh& mesh = meshes[ip];
        PartInfo info;
        info.name = ps.name;
        info.node_begin = offset;
        info.node_end = offset + mesh.n_nodes();
        info.element_offset = elem_offset;
        for (index_t i = 0; i < mesh.n_nodes(); ++i)
            for (int k = 0; k < 3; ++k)
            {
                const std::size_t g = 3 * static_cast<std::size_t>(offset + i) + k;
                m.nodes.x0[g] = m.nodes.x[g] = mesh.x[3 * i + k];
                m.nodes.v[g] = ps.initial_velocity[k];
            }
        for (index_t i = info.node_begin; i < info.node_end; ++i)
            m.nodes.part[i] = static_cast<index_t>(ip);
        for (const auto& f : mesh.faces)
            info.faces.push_back({f[0] + offset, f[1] + offset, f[2] + offset, f[3] + offset});
        info.named_faces = mesh.named_faces;
        for (const auto& [name, ids] : mesh.named_nodes)
            for (index_t i : ids)
                info.named_nodes[name].push_back(i + offset);

        HexBlock blk;
        blk.part = static_cast<index_t>(ip);
        blk.formulation = ps.formulation;
        blk.hourglass = ps.hourglass;
        blk.bulk_viscosity = ps.bulk_viscosity;
        blk.material = ElasticParams::from_E_nu(ps.material.rho, ps.material.E, ps.material.nu);
        blk.plastic.configure(ps.material);
        blk.conn = mesh.conn;
        for (auto& c : blk.conn)
            c += offset;
        blk.node_begin = info.node_begin;
        blk.node_end = info.node_end;
        blk.initialize(m.nodes);
        {
            // crack-band length per point: the element's V^(1/3)
            std::vector<real_t> h(static_cast<std::size_t>(blk.n_points()));
            for (index_t q = 0; q < blk.n_points(); ++q)
                h[q] = std::cbrt(blk.volume0[q / blk.points_per_element()]);
            blk.plastic.set_lengths(h);
        }
        m.part_nodal.push_back(-1);
        if (is_nodal(ps.formulation))
        {
            NodalBlock nb = ps.generator.type == GeneratorSpec::Type::Cloud ? build_cloud_block(ps, mesh, offset)
                            : ps.coupled()                                  ? build_coupled_block(ps, mesh, offset)
                                                                            : build_nodal_block(ps, mesh, offset);
            nb.part = static_cast<index_t>(ip);
            add_nodal_mass(nb, m.nodes);
            m.part_nodal.back() = static_cast<index_t>(m.nodal_blocks.size());
            m.nodal_blocks.push_back(std::move(nb));
        }
        for (index_t e = 0; e < blk.n_elements(); ++e)
            if (!(blk.volume0[e] > 0.0))
                throw DeckError({ps.generator.loc.where, ps.loc.path + ".generator"},
                                "element " + std::to_string(e) + " has non-positive volume " +
                                    std::to_string(blk.volume0[e]) + " m^3",
                                "expected a generator that makes valid (positive-volume) hexahedra");
        if (!is_nodal(ps.formulation))
            add_lumped_mass(blk, m.nodes);
        elem_offset += blk.n_elements();
        offset = info.node_end;
        m.blocks.push_back(std::move(blk));
        m.parts.push_back(std::move(info));
    }

    auto part_range = [&](const std::string& name)
    {
        std::vector<index_t> ids;
        for (index_t ip = 0; ip < static_cast<index_t>(m.parts.size()); ++ip)
            if (name.empty() || m.parts[ip].name == name)
                ids.push_back(ip);
        return ids;
    };

    // node sets
    for (const auto& s : d.node_sets)
    {
        std::vector<index_t> ids;
        for (index_t ip : part_range(s.part))
        {
            const PartInfo& pi = m.parts[ip];
            if (s.select.type == SelectorSpec::Type::Named)
            {
                if (s.select.name == "all")
                {
                    for (index_t i = pi.node_begin; i < pi.node_end; ++i)
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
            else
            {
                const real_t tol = s.select.tolerance >= 0
                                       ? s.select.tolerance
                                       : default_tolerance(m.nodes, pi.node_begin, pi.node_end);
                for (index_t i = pi.node_begin; i < pi.node_end; ++i)
                    if (matches(s.select, Vec3(m.nodes.x0[3 * i], m.nodes.x0[3 * i + 1], m.nodes.x0[3 * i + 2]), tol))
                        ids.push_back(i);
            }
        }
        std::sort(ids.begin(), ids.end());
        ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
        if (ids.empty())
            throw DeckError({s.loc.where, s.loc.path + ".select"}, "selects no node",
                            "expected a selector that matches at least one node of " +
                                (s.part.empty() ? std::string("any part") : "part '" + s.part + "'"));
        m.node_sets[s.name] = std::move(ids);
    }
    // face sets
    for (const auto& s : d.face_sets)
    {
        std::vector<Quad> faces;
        std::vector<CloudFacet> facets;
        for (index_t ip : part_range(s.part))
        {
            const PartInfo& pi = m.parts[ip];
            if (m.is_cloud(ip))
            {
                // the boundary facet points of the Voronoi cells: by the box face they lie on
                // (named) or by the selector applied to the point
                static const std::map<std::string, Vec3> normals = {
                    {"xmin", -Vec3::UnitX()}, {"xmax", Vec3::UnitX()}, {"ymin", -Vec3::UnitY()},
                    {"ymax", Vec3::UnitY()},  {"zmin", -Vec3::UnitZ()}, {"zmax", Vec3::UnitZ()},
                    {"bottom", -Vec3::UnitZ()}, {"top", Vec3::UnitZ()}};
                const bool named = s.select.type == SelectorSpec::Type::Named;
                const bool cylinder = d.parts[ip].generator.body == GeneratorSpec::Body::Cylinder;
                if (named && s.select.name != "side" &&
                    (!normals.count(s.select.name) ||
                     (cylinder && s.select.name != "top" && s.select.name != "bottom")))
                    throw DeckError({s.loc.where, s.loc.path + ".select.name"},
                                    "cloud part '" + pi.name + "' has no face set named '" + s.select.name + "'",
                                    cylinder ? "expected one of top, bottom, side (a cylinder body)"
                                             : "expected one of xmin, xmax, ymin, ymax, zmin, zmax, top, bottom, side");
                const real_t tol = s.select.tolerance >= 0 ? s.select.tolerance
                                                           : default_tolerance(m.nodes, pi.node_begin, pi.node_end);
                for (const CellFacetPoint& fp : m.nodal_blocks[m.part_nodal[ip]].boundary_facets)
                {
                    const Vec3 n = fp.nda.normalized();
                    const bool take = !named                     ? matches(s.select, fp.x, tol)
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
            else
            {
                const real_t tol = s.select.tolerance >= 0
                                       ? s.select.tolerance
                                       : default_tolerance(m.nodes, pi.node_begin, pi.node_end);
                for (const auto& f : pi.faces)
                {
                    bool all = true;
                    for (index_t n : f)
                        all = all && matches(s.select, Vec3(m.nodes.x0[3 * n], m.nodes.x0[3 * n + 1], m.nodes.x0[3 * n + 2]), tol);
                    if (all)
                        faces.push_back(f);
                }
            }
        }
        if (faces.empty() && facets.empty())
            throw DeckError({s.loc.where, s.loc.path + ".select"}, "selects no boundary face",
                            "expected a selector that matches all four nodes of at least one boundary face "
                            "(on cloud parts: a point of the cells' boundary facets)");
        m.face_sets[s.name] = std::move(faces);
        m.cloud_face_sets[s.name] = std::move(facets);
    }
    // boundary conditions (later entries override earlier ones on the same dof)
    std::map<index_t, std::size_t> dof_slot;
    for (const auto& b : d.boundary_conditions)
        for (index_t n : m.node_sets.at(b.node_set))
            for (int k = 0; k < 3; ++k)
                if (b.active[k])
                {
                    const DofCondition c{3 * n + k, b.kind, &b.value[k]};
                    auto it = dof_slot.find(c.dof);
                    if (it == dof_slot.end())
                    {
                        dof_slot[c.dof] = m.conditions.size();
                        m.conditions.push_back(c);
                    }
                    else
                        m.conditions[it->second] = c;
                }
    for (const auto& l : d.loads)
    {
        if (l.kind == LoadSpec::Kind::NodalForce)
            m.nodal_loads_.push_back({&l, m.node_sets.at(l.set)});
        else
            m.pressure_loads_.push_back({&l, &m.face_sets.at(l.set)});
    }
    // probes: nearest node
    for (const auto& p : d.probes)
    {
        index_t best = -1;
        real_t best_d = 1e300;
        for (index_t ip : part_range(p.part))
            for (index_t i = m.parts[ip].node_begin; i < m.parts[ip].node_end; ++i)
            {
                const real_t dd = (Vec3(m.nodes.x0[3 * i], m.nodes.x0[3 * i + 1], m.nodes.x0[3 * i + 2]) - p.point).squaredNorm();
                if (dd < best_d)
                {
                    best_d = dd;
                    best = i;
                }
            }
        if (best < 0)
            throw DeckError({p.loc.where, p.loc.path + ".part"}, "unknown part '" + p.part + "'",
                            "expected the name of a part");
        m.probe_nodes.push_back(best);
    }
    // the kinematic map: the RK rows of every nodal block, moved out of the block (it served
    // the build only)
    m.kinematics.reset(m.nodes.size());
    for (NodalBlock& nb : m.nodal_blocks)
    {
        if (nb.interp_offsets.empty())
            continue;
        const std::vector<char> all(static_cast<std::size_t>(nb.node_end - nb.node_begin), 1);
        m.kinematics.set_rows(nb.node_begin, nb.node_end, nb.interp_offsets, nb.interp_nodes, nb.interp_values,
                              nb.particle.empty() ? &all : &nb.particle);
        std::vector<index_t>().swap(nb.interp_offsets);
        std::vector<index_t>().swap(nb.interp_nodes);
        std::vector<real_t>().swap(nb.interp_values);
    }
    m.contact.set_map(&m.kinematics);
    m.build_rk_constraints();
    // consistent pressure distribution on rkpm faces: Psi_I at 2x2 Gauss points of each face
    for (const auto& [load, faces] : m.pressure_loads_)
    {
        RkFaceLoads rl;
        rl.point_offsets.assign(1, 0);
        RkSample smp;
        for (const Quad& q : *faces)
        {
            const index_t ip = m.nodes.part[q[0]];
            const bool is_rk = d.parts[ip].formulation == Formulation::Rkpm;
            if (d.parts[ip].coupled())
                for (index_t node : q)
                    if (m.carries_coefficients(node))
                        throw DeckError({load->loc.where, load->loc.path + ".set"},
                                        "face set '" + load->set + "' reaches the RK region of coupled part '" +
                                            d.parts[ip].name + "', where pressure is not distributed yet",
                                        "expected a pressure on faces of the FE region");
            rl.is_rk.push_back(is_rk);
            if (!is_rk)
            {
                for (int gp = 0; gp < 4; ++gp)
                    rl.point_offsets.push_back(rl.point_offsets.back());
                continue;
            }
            const RkShapeFunctions& rk = *m.nodal_blocks[m.part_nodal[ip]].rk; // local numbering
            const real_t g = 1.0 / std::sqrt(3.0);
            Vec3 xc[4];
            for (int c = 0; c < 4; ++c)
                xc[c] = Vec3(m.nodes.x0[3 * q[c]], m.nodes.x0[3 * q[c] + 1], m.nodes.x0[3 * q[c] + 2]);
            for (int gp = 0; gp < 4; ++gp)
            {
                const real_t r = gp % 2 ? g : -g, s = gp / 2 ? g : -g;
                const Vec3 X = 0.25 * ((1 - r) * (1 - s) * xc[0] + (1 + r) * (1 - s) * xc[1] + (1 + r) * (1 + s) * xc[2] +
                                       (1 - r) * (1 + s) * xc[3]);
                rk.evaluate(X, false, smp);
                for (index_t k = 0; k < smp.size(); ++k)
                {
                    rl.nodes.push_back(smp.nodes[k] + m.parts[ip].node_begin);
                    rl.psi.push_back(smp.psi[k]);
                }
                rl.point_offsets.push_back(static_cast<index_t>(rl.nodes.size()));
            }
        }
        m.rk_face_loads_.push_back(std::move(rl));
        CloudFaceLoads cl;
        for (const CloudFacet& cf : m.cloud_face_sets.at(load->set))
        {
            m.nodal_blocks[m.part_nodal[cf.part]].rk->evaluate(cf.x, true, smp);
            for (index_t k = 0; k < smp.size(); ++k)
            {
                cl.nodes.push_back(smp.nodes[k] + m.parts[cf.part].node_begin);
                cl.psi.push_back(smp.psi[k]);
                cl.grad.push_back(smp.grad[k]);
            }
            cl.offsets.push_back(static_cast<index_t>(cl.nodes.size()));
            cl.nda.push_back(cf.nda);
        }
        m.cloud_face_loads_.push_back(std::move(cl));
    }
    m.collect_loaded_dofs();
    m.reaction_prev_.assign(m.conditions.size(), 0.0);
    m.reaction_inertia_.assign(m.conditions.size(), 0.0);
    m.contact.resize(m.nodes.size());
    m.plan_assembly();
    for (const DofCondition& c : m.conditions)
        m.constrained_dofs_.push_back(c.dof);
    std::sort(m.constrained_dofs_.begin(), m.constrained_dofs_.end());
    return m;
}

void Model::remove_elements(index_t block, const std::vector<char>& keep)
{
    RKFEM_REQUIRE(block >= 0 && block < static_cast<index_t>(blocks.size()), "remove_elements: no block " << block);
    RKFEM_REQUIRE(part_nodal[block] < 0, "remove_elements: part '" << parts[block].name
                                                                   << "' is integrated at its nodes; only Gauss-point "
                                                                      "FE parts lose elements");
    blocks[block].remove_elements(keep, nodes);
    index_t offset = 0;
    for (std::size_t ip = 0; ip < parts.size(); ++ip)
    {
        parts[ip].element_offset = offset;
        offset += blocks[ip].n_elements();
    }
    plan_assembly();
    ++topology_version_;
}

bool Model::apply_events(real_t, std::int64_t)
{
    bool changed = false;
    for (index_t b = 0; b < static_cast<index_t>(blocks.size()); ++b)
    {
        const ErosionSpec& er = deck_.parts[static_cast<std::size_t>(b)].erosion;
        if (!er.active() || part_nodal[b] >= 0)
            continue;
        const index_t ne = blocks[b].n_elements();
        std::vector<char> keep(static_cast<std::size_t>(ne), 1);
        index_t removed = 0;
        for (index_t e = 0; e < ne; ++e)
        {
            const bool erode = (er.plastic_strain > 0 && element_history(b, e, History::PlasticStrain) >= er.plastic_strain) ||
                               (er.damage > 0 && element_history(b, e, History::Damage) >= er.damage);
            keep[e] = !erode;
            removed += erode;
        }
        if (removed == 0)
            continue;
        remove_elements(b, keep);
        eroded_elements_ += removed;
        changed = true;
    }
    return changed;
}

void Model::plan_assembly()
{
    // each block's node range (nodal parts: the nodal block's)
    std::vector<std::pair<index_t, index_t>> range;
    for (std::size_t ib = 0; ib < blocks.size(); ++ib)
        if (part_nodal[ib] >= 0)
            range.emplace_back(nodal_blocks[part_nodal[ib]].node_begin, nodal_blocks[part_nodal[ib]].node_end);
        else
            range.emplace_back(blocks[ib].node_begin, blocks[ib].node_end);
    block_adds_.assign(blocks.size(), 0);
    for (std::size_t a = 0; a < range.size(); ++a)
        for (std::size_t b = 0; b < range.size(); ++b)
            if (a != b && range[a].first < range[b].second && range[b].first < range[a].second)
                block_adds_[a] = 1;
    // the union of the adding blocks' ranges, as disjoint sorted intervals
    std::vector<std::pair<index_t, index_t>> shared;
    for (std::size_t a = 0; a < range.size(); ++a)
        if (block_adds_[a])
            shared.push_back(range[a]);
    std::sort(shared.begin(), shared.end());
    shared_node_ranges_.clear();
    for (const auto& r : shared)
        if (!shared_node_ranges_.empty() && r.first <= shared_node_ranges_.back().second)
            shared_node_ranges_.back().second = std::max(shared_node_ranges_.back().second, r.second);
        else
            shared_node_ranges_.push_back(r);
}

void Model::collect_loaded_dofs()
{
    std::vector<char> loaded(nodes.f_ext.size(), 0);
    auto node_dofs = [&](index_t n)
    {
        for (int k = 0; k < 3; ++k)
            loaded[3 * static_cast<std::size_t>(n) + k] = 1;
    };
    for (const auto& [load, ids] : nodal_loads_)
        for (int k = 0; k < 3; ++k)
            if (load->active[k])
                for (index_t n : ids)
                    kinematics.for_row(n, [&](index_t j, real_t) { loaded[3 * static_cast<std::size_t>(j) + k] = 1; });
    for (std::size_t il = 0; il < pressure_loads_.size(); ++il)
    {
        for (index_t n : cloud_face_loads_[il].nodes)
            node_dofs(n);
        const RkFaceLoads& rl = rk_face_loads_[il];
        const std::vector<Quad>& faces = *pressure_loads_[il].second;
        for (std::size_t fi = 0; fi < faces.size(); ++fi)
            if (!rl.is_rk[fi])
                for (index_t n : faces[fi])
                    node_dofs(n);
        for (index_t n : rl.nodes)
            node_dofs(n);
    }
    loaded_dofs_.clear();
    for (std::size_t j = 0; j < loaded.size(); ++j)
        if (loaded[j])
            loaded_dofs_.push_back(static_cast<index_t>(j));
    f_ext_prev_.assign(loaded_dofs_.size(), 0.0);
}

void Model::impose_velocity(real_t t, real_t dt, bool half_step) { impose_velocity(t, dt, half_step, nodes.v.data()); }

void Model::impose_velocity(real_t t, real_t dt, bool half_step, real_t* vel)
{
    for (const auto& c : conditions)
    {
        real_t v = 0.0;
        switch (c.kind)
        {
        case BoundarySpec::Kind::Fixed:
            v = 0.0;
            break;
        case BoundarySpec::Kind::Velocity:
            v = (*c.value)(half_step ? t + 0.5 * dt : t);
            break;
        case BoundarySpec::Kind::Displacement:
            if (half_step)
                v = dt > 0 ? ((*c.value)(t + dt) - nodes.u[c.dof]) / dt : 0.0;
            else
            {
                const real_t h = dt > 0 ? dt : 1e-9;
                v = ((*c.value)(t + h) - (*c.value)(t)) / h;
            }
            break;
        }
        vel[c.dof] = v;
    }
    // rkpm parts: the values just set are targets for the physical velocity
    for (auto& rc : rk_constraints_)
    {
        const NodalBlock& nb = nodal_blocks[rc->block];
        const int k = rc->component;
        const index_t nb_count = static_cast<index_t>(rc->node.size());
        for (index_t q = 0; q < nb_count; ++q)
        {
            real_t r = vel[3 * rc->node[q] + k];
            if (conditions[rc->condition[q]].kind == BoundarySpec::Kind::Displacement && half_step)
            {
                // target from the physical displacement: (g(t + dt) - u^h(X_b)) / dt
                const DofCondition& c = conditions[rc->condition[q]];
                const real_t uh = physical(nodes.u, rc->node[q])[k];
                r = dt > 0 ? ((*c.value)(t + dt) - uh) / dt : 0.0;
            }
            kinematics.for_row(rc->node[q],
                               [&](index_t J, real_t w)
                               {
                                   if (rc->slot[J - nb.node_begin] < 0)
                                       r -= w * vel[3 * J + k];
                               });
            rc->rhs[q] = r;
        }
        rc->x = rc->lu.solve(rc->rhs);
        for (index_t q = 0; q < nb_count; ++q)
            vel[3 * rc->node[q] + k] = rc->x[q];
    }
}

void Model::build_rk_constraints()
{
    for (index_t b = 0; b < static_cast<index_t>(nodal_blocks.size()); ++b)
    {
        const NodalBlock& nb = nodal_blocks[b];
        bool any = false;
        for (index_t i = nb.node_begin; i < nb.node_end && !any; ++i)
            any = kinematics.carries_coefficients(i);
        if (!any)
            continue;
        for (int k = 0; k < 3; ++k)
        {
            auto rc = std::make_shared<RkVelocityConstraint>();
            rc->block = b;
            rc->component = k;
            rc->slot.assign(static_cast<std::size_t>(nb.node_end - nb.node_begin), -1);
            for (index_t ci = 0; ci < static_cast<index_t>(conditions.size()); ++ci)
            {
                const index_t n = conditions[ci].dof / 3;
                if (conditions[ci].dof % 3 != k || n < nb.node_begin || n >= nb.node_end)
                    continue;
                rc->slot[n - nb.node_begin] = static_cast<index_t>(rc->node.size());
                rc->node.push_back(n);
                rc->condition.push_back(ci);
            }
            if (rc->node.empty())
                continue;
            const index_t m = static_cast<index_t>(rc->node.size());
            std::vector<Eigen::Triplet<real_t, int>> t;
            for (index_t q = 0; q < m; ++q)
            {
                kinematics.for_row(rc->node[q],
                                   [&](index_t J, real_t w)
                                   {
                                       const index_t col = rc->slot[J - nb.node_begin];
                                       if (col >= 0)
                                           t.emplace_back(q, col, w);
                                   });
            }
            SparseMatrix A(m, m);
            A.setFromTriplets(t.begin(), t.end());
            rc->lu.compute(A);
            if (rc->lu.info() != Eigen::Success)
            {
                const auto& bc = deck_.boundary_conditions;
                const std::string where = bc.empty() ? deck_.path : bc.front().loc.where;
                throw DeckError({where, "boundary_conditions"},
                                "the RK interpolation matrix of the " + std::to_string(m) + " particles constrained in component " +
                                    std::to_string(k) + " of part '" + parts[nb.part].name + "' is singular",
                                "expected constrained particle sets whose kernel functions are independent (e.g. whole faces)");
            }
            rc->rhs.resize(m);
            rc->x.resize(m);
            rk_constraints_.push_back(std::move(rc));
        }
    }
}

void Model::update_coordinates()
{
    const index_t n3 = 3 * nodes.size();
    parallel_for("rkfem::coordinates", n3, [&](index_t i) { nodes.x[i] = nodes.x0[i] + nodes.u[i]; });
}

void Model::set_state(const real_t* u, const real_t* v)
{
    const index_t n3 = 3 * nodes.size();
    parallel_for("rkfem::set_state", n3,
                 [&](index_t i)
                 {
                     nodes.u[i] = u[i];
                     nodes.v[i] = v[i];
                     nodes.x[i] = nodes.x0[i] + u[i];
                 });
}

void Model::apply_external_forces(real_t t)
{
    // f_ext is zero at every dof but the loaded ones; a load added here must add the dofs it
    // writes in collect_loaded_dofs()
    for (const index_t j : loaded_dofs_)
        nodes.f_ext[j] = 0.0;
    for (const auto& [load, ids] : nodal_loads_)
        for (int k = 0; k < 3; ++k)
            if (load->active[k])
            {
                real_t f = load->force[k](t);
                if (load->total)
                    f /= static_cast<real_t>(ids.size());
                for (index_t n : ids)
                {
                    // a force at the node's physical point (RK particles: spread to the
                    // coefficients through the kinematic map)
                    Vec3 fk = Vec3::Zero();
                    fk[k] = f;
                    kinematics.spread(n, fk, nodes.f_ext.data());
                }
            }
    for (std::size_t il = 0; il < pressure_loads_.size(); ++il)
    {
        const auto& [load, faces] = pressure_loads_[il];
        const real_t p = load->pressure(t);
        if (p == 0.0)
            continue;
        // cloud facets: -p Psi_I n da on the current facet, n da = J F^-T N dA (Nanson) with
        // F = 1 + sum_I d_I (x) grad Psi_I at the facet point
        const CloudFaceLoads& cl = cloud_face_loads_[il];
        for (std::size_t q = 0; q < cl.nda.size(); ++q)
        {
            Mat3 F = Mat3::Identity();
            for (index_t k = cl.offsets[q]; k < cl.offsets[q + 1]; ++k)
                F += Vec3(nodes.u[3 * cl.nodes[k]], nodes.u[3 * cl.nodes[k] + 1], nodes.u[3 * cl.nodes[k] + 2]) *
                     cl.grad[k].transpose();
            const Vec3 nda = F.determinant() * F.inverse().transpose() * cl.nda[q];
            for (index_t k = cl.offsets[q]; k < cl.offsets[q + 1]; ++k)
                for (int d = 0; d < 3; ++d)
                    nodes.f_ext[3 * cl.nodes[k] + d] -= p * cl.psi[k] * nda[d];
        }
        const RkFaceLoads& rl = rk_face_loads_[il];
        for (std::size_t fi = 0; fi < faces->size(); ++fi)
        {
            const Quad& q = (*faces)[fi];
            if (!rl.is_rk[fi])
            {
                const Vec3 n = quad_normal(nodes.x, q); // area-weighted, outward
                for (index_t node : q)
                    for (int k = 0; k < 3; ++k)
                        nodes.f_ext[3 * node + k] -= 0.25 * p * n[k];
                continue;
            }
            // RK face: bilinear patch through the physical corner positions, 2x2 Gauss points,
            // force -p n dA distributed with Psi_I(X_K)
            Vec3 xc[4];
            for (int c = 0; c < 4; ++c)
                xc[c] = Vec3(nodes.x0[3 * q[c]], nodes.x0[3 * q[c] + 1], nodes.x0[3 * q[c] + 2]) + physical(nodes.u, q[c]);
            const real_t g = 1.0 / std::sqrt(3.0);
            for (int gp = 0; gp < 4; ++gp)
            {
                const real_t r = gp % 2 ? g : -g, s = gp / 2 ? g : -g;
                // corners in order (-1,-1), (1,-1), (1,1), (-1,1)
                const Vec3 xr = 0.25 * ((1 - s) * (xc[1] - xc[0]) + (1 + s) * (xc[2] - xc[3]));
                const Vec3 xs = 0.25 * ((1 - r) * (xc[3] - xc[0]) + (1 + r) * (xc[2] - xc[1]));
                const Vec3 nda = xr.cross(xs); // weight 1 per Gauss point on [-1, 1]^2
                const std::size_t pt = 4 * fi + gp;
                for (index_t k = rl.point_offsets[pt]; k < rl.point_offsets[pt + 1]; ++k)
                    for (int d = 0; d < 3; ++d)
                        nodes.f_ext[3 * rl.nodes[k] + d] -= p * rl.psi[k] * nda[d];
            }
        }
    }
}

ForceReport Model::internal_forces(real_t t, real_t dt, std::int64_t step)
{
    ForceReport rep;
    pending_int_ = pending_hg_ = pending_bv_ = 0.0;
    index_t offset = 0;
    // energy increments and the controlling stable step of one block's pass
    auto book = [&](const ForcePassResult& r, index_t dt_element)
    {
        pending_int_ += r.d_internal;
        pending_hg_ += r.d_hourglass;
        pending_bv_ += r.d_bulk_viscosity;
        if (r.dt_stable < rep.dt_stable)
        {
            rep.dt_stable = r.dt_stable;
            rep.dt_element = dt_element;
        }
    };
    // blocks whose node ranges overlap add into f_int, zeroed once here over those ranges; a
    // block alone on its nodes writes them (no clearing pass)
    for (const auto& [lo, hi] : shared_node_ranges_)
        std::fill(nodes.f_int.begin() + 3 * static_cast<std::ptrdiff_t>(lo),
                  nodes.f_int.begin() + 3 * static_cast<std::ptrdiff_t>(hi), 0.0);
    for (std::size_t ib = 0; ib < blocks.size(); ++ib)
    {
        HexBlock& blk = blocks[ib];
        const bool add = block_adds_[ib] != 0;
        if (part_nodal[ib] >= 0)
        {
            NodalBlock& nb = nodal_blocks[part_nodal[ib]];
            const ForcePassResult r = nodal_internal_force(nb, nodes, dt);
            if (r.bad_element >= 0)
            {
                std::ostringstream os;
                os << "integration point " << r.bad_element << " (owner node " << nb.points.owner[r.bad_element]
                   << ", part '" << parts[ib].name << "') has non-positive or NaN det F = "
                   << nb.jacobian[r.bad_element] << " at t = " << t << " s, step " << step;
                throw InstabilityError(os.str());
            }
            book(r, offset); // first element of the part; nodal points are not elements
            assemble_nodal_forces(nb, nodes, add);
            offset += blk.n_elements();
            continue;
        }
        const ForcePassResult r = hex_internal_force(blk, nodes, dt);
        if (r.bad_element >= 0)
        {
            std::ostringstream os;
            os << "element " << offset + r.bad_element << " (part '" << parts[ib].name
               << "', local " << r.bad_element << ") has non-positive or NaN volume "
               << element_volume(blk, nodes, r.bad_element) << " m^3 at t = " << t << " s, step " << step;
            throw InstabilityError(os.str());
        }
        book(r, offset + r.dt_element);
        assemble_block_forces(blk, nodes, add);
        offset += blk.n_elements();
    }
    return rep;
}

void Model::external_forces(real_t t)
{
    apply_external_forces(t);
    if (contacts.empty())
        return;
    contact.clear();
    const PhysicalNodes physical_nodes(nodes, kinematics);
    for (auto& c : contacts)
        c->add_forces(physical_nodes, t, contact);
}

void Model::accelerations()
{
    const real_t c = deck_.time.mass_damping;
    const index_t n = nodes.size();
    parallel_for("rkfem::accelerations", n,
                 [&](index_t i)
                 {
                     const real_t inv_m = 1.0 / nodes.mass[i];
                     for (int k = 0; k < 3; ++k)
                     {
                         const std::size_t j = 3 * static_cast<std::size_t>(i) + k;
                         nodes.a[j] = (nodes.f_ext[j] - nodes.f_int[j]) * inv_m - c * nodes.v[j];
                     }
                 });
    // contact forces: only on the nodes in contact this pass
    for (index_t i : contact.nodes())
    {
        const real_t inv_m = 1.0 / nodes.mass[i];
        for (int k = 0; k < 3; ++k)
            nodes.a[3 * static_cast<std::size_t>(i) + k] += contact.f[3 * static_cast<std::size_t>(i) + k] * inv_m;
    }
    for (const auto& cnd : conditions)
        nodes.a[cnd.dof] = 0.0;
}

void Model::commit()
{
    for (auto& b : blocks)
        b.commit();
    for (auto& b : nodal_blocks)
        b.commit();
    energy.internal += pending_int_;
    energy.hourglass += pending_hg_;
    energy.bulk_viscosity += pending_bv_;
    pending_int_ = pending_hg_ = pending_bv_ = 0.0;
}

void Model::update_energies(const real_t* u_prev, real_t dt)
{
    const index_t n = nodes.size();
    energy.kinetic = parallel_reduce_sum("rkfem::kinetic", n,
                                         [&](index_t i)
                                         {
                                             const std::size_t j = 3 * static_cast<std::size_t>(i);
                                             return 0.5 * nodes.mass[i] *
                                                    (nodes.v[j] * nodes.v[j] + nodes.v[j + 1] * nodes.v[j + 1] +
                                                     nodes.v[j + 2] * nodes.v[j + 2]);
                                         });
    energy.kinetic_correction =
        -0.125 * dt * dt *
        parallel_reduce_sum("rkfem::kinetic_correction", n,
                            [&](index_t i)
                            {
                                const std::size_t j = 3 * static_cast<std::size_t>(i);
                                return nodes.mass[i] * (nodes.a[j] * nodes.a[j] + nodes.a[j + 1] * nodes.a[j + 1] +
                                                        nodes.a[j + 2] * nodes.a[j + 2]);
                            });
    const index_t n_loaded = static_cast<index_t>(loaded_dofs_.size());
    auto keep_f_ext = [&]
    {
        for (index_t q = 0; q < n_loaded; ++q)
            f_ext_prev_[q] = nodes.f_ext[loaded_dofs_[q]];
    };
    if (dt <= 0)
    {
        // a (re)start: the forces of this state open the next step's trapezoids; after an event
        // the reactions are those of the new discretization, with the last step's inertia term
        // m a_p (a prescribed acceleration needs a step)
        keep_f_ext();
        contact.commit();
        bc_v_prev_.resize(conditions.size());
        for (std::size_t k = 0; k < conditions.size(); ++k)
        {
            const index_t j = conditions[k].dof;
            bc_v_prev_[k] = nodes.v[j];
            reaction_prev_[k] = nodes.f_int[j] - nodes.f_ext[j] - contact.f[j] + reaction_inertia_[k];
        }
        return;
    }
    // external work, trapezoid in time, over the loaded dofs (f_ext is zero elsewhere)
    energy.external_work += parallel_reduce_sum("rkfem::external_work", n_loaded,
                                                [&](index_t q)
                                                {
                                                    const index_t j = loaded_dofs_[q];
                                                    return 0.5 * (f_ext_prev_[q] + nodes.f_ext[j]) *
                                                           (nodes.u[j] - u_prev[j]);
                                                });
    // work of reactions at prescribed dofs: R = f_int - f_ext + m a_prescribed
    for (std::size_t k = 0; k < conditions.size(); ++k)
    {
        const index_t j = conditions[k].dof;
        const real_t du = nodes.u[j] - u_prev[j];
        // prescribed acceleration over the step, from the imposed velocities
        const real_t ap = (nodes.v[j] - bc_v_prev_[k]) / dt;
        bc_v_prev_[k] = nodes.v[j];
        reaction_inertia_[k] = nodes.mass[j / 3] * ap;
        const real_t r = nodes.f_int[j] - nodes.f_ext[j] - contact.f[j] + reaction_inertia_[k];
        energy.external_work += 0.5 * (reaction_prev_[k] + r) * du;
        reaction_prev_[k] = r;
    }
    // contact: the sliding energy is minus the work of the contact forces
    if (!contact.empty())
        energy.contact -= contact.step_work(nodes.u.data(), u_prev);
    contact.commit();
    // mass damping dissipation
    const real_t c = deck_.time.mass_damping;
    if (c > 0)
        energy.damping += dt * c * 2.0 * energy.kinetic;
    keep_f_ext();
}

void Model::check(real_t t, std::int64_t step) const
{
    const index_t n3 = 3 * nodes.size();
    const real_t* u = nodes.u.data();
    const real_t* a = nodes.a.data();
    // x - x is 0 for finite x and NaN otherwise: one vectorized sum finds whether any value is
    // not finite; only then a scan finds the first such node
    const real_t s = parallel_reduce_sum("rkfem::check_finite", n3, [&](index_t j) { return (u[j] - u[j]) + (a[j] - a[j]); });
    if (s == 0.0)
        return;
    index_t bad = 0;
    while (bad < n3 && std::isfinite(u[bad]) && std::isfinite(a[bad]))
        ++bad;
    bad /= 3;
    std::ostringstream os;
    os << "non-finite acceleration or displacement at node " << bad << " (part '" << parts[nodes.part[bad]].name
       << "') at t = " << t << " s, step " << step;
    throw InstabilityError(os.str());
}

std::vector<index_t> Model::velocity_driven_dofs() const
{
    std::vector<index_t> dofs;
    for (const DofCondition& c : conditions)
        if (c.kind != BoundarySpec::Kind::Fixed || carries_coefficients(c.dof / 3))
            dofs.push_back(c.dof);
    return dofs;
}

bool Model::carries_coefficients(index_t node) const { return kinematics.carries_coefficients(node); }

Vec3 Model::physical(const std::vector<real_t>& field, index_t node) const
{
    return kinematics.physical(field.data(), node);
}

void Model::physical_field(const std::vector<real_t>& field, std::vector<real_t>& out) const
{
    kinematics.physical_field(field, out);
}

namespace
{
/// History value h of point p.
real_t history_value(const PlasticPoints& pp, std::size_t p, Model::History h)
{
    switch (h)
    {
    case Model::History::PlasticStrain:
        return pp.eps_p[p];
    case Model::History::Damage:
        return pp.damage(p);
    case Model::History::KccDelta:
        return pp.kcc_delta(p);
    }
    return 0.0;
}
} // namespace

real_t Model::element_history(index_t b, index_t e, History h) const
{
    auto value = [h](const PlasticPoints& pp, std::size_t p) { return history_value(pp, p, h); };
    if (part_nodal[b] >= 0)
    {
        const NodalBlock& nb = nodal_blocks[part_nodal[b]];
        if (!nb.plastic.active())
            return 0.0;
        real_t s = 0.0;
        int count = 0;
        for (int I = 0; I < 8; ++I)
        {
            const index_t i = blocks[b].conn[8 * static_cast<std::size_t>(e) + I] - nb.node_begin;
            for (index_t k = nb.owner_offsets[i]; k < nb.owner_offsets[i + 1]; ++k, ++count)
                s += value(nb.plastic, static_cast<std::size_t>(nb.owner_points[k]));
        }
        return count ? s / count : 0.0;
    }
    const HexBlock& blk = blocks[b];
    if (!blk.plastic.active())
        return 0.0;
    const index_t npe = blk.points_per_element();
    real_t s = 0.0;
    for (index_t g = 0; g < npe; ++g)
        s += value(blk.plastic, static_cast<std::size_t>(e) * npe + g);
    return s / npe;
}

real_t Model::nodal_history(index_t node, History h) const
{
    const index_t ip = nodes.part[node];
    if (part_nodal[ip] < 0)
        return 0.0;
    const NodalBlock& nb = nodal_blocks[part_nodal[ip]];
    if (!nb.plastic.active())
        return 0.0;
    const index_t i = node - nb.node_begin;
    real_t s = 0.0;
    const index_t k0 = nb.owner_offsets[i], k1 = nb.owner_offsets[i + 1];
    for (index_t k = k0; k < k1; ++k)
        s += history_value(nb.plastic, static_cast<std::size_t>(nb.owner_points[k]), h);
    return k1 > k0 ? s / static_cast<real_t>(k1 - k0) : 0.0;
}

bool Model::is_cloud(index_t part) const
{
    return deck_.parts[static_cast<std::size_t>(part)].generator.type == GeneratorSpec::Type::Cloud;
}

index_t Model::n_cells() const
{
    index_t n = n_elements();
    for (index_t ip = 0; ip < static_cast<index_t>(parts.size()); ++ip)
        if (is_cloud(ip))
            n += parts[ip].node_end - parts[ip].node_begin;
    return n;
}

Sym6 Model::element_stress(index_t b, index_t e) const
{
    if (part_nodal[b] >= 0)
    {
        Sym6 s = Sym6::Zero();
        for (int I = 0; I < 8; ++I)
            s += nodal_stress(blocks[b].conn[8 * static_cast<std::size_t>(e) + I]);
        return s / 8.0;
    }
    const HexBlock& blk = blocks[b];
    const index_t npe = blk.points_per_element();
    const std::size_t np = blk.stress_stride;
    Sym6 s = Sym6::Zero();
    for (index_t g = 0; g < npe; ++g)
        for (int k = 0; k < 6; ++k)
            s[k] += blk.stress[k * np + static_cast<std::size_t>(e) * npe + g];
    return s / static_cast<real_t>(npe);
}

Sym6 Model::nodal_stress(index_t node) const
{
    const index_t ip = nodes.part[node];
    if (part_nodal[ip] >= 0)
    {
        const NodalBlock& nb = nodal_blocks[part_nodal[ip]];
        const index_t i = node - nb.node_begin;
        const std::size_t np = nb.stress_stride;
        Sym6 s = Sym6::Zero();
        const index_t k0 = nb.owner_offsets[i], k1 = nb.owner_offsets[i + 1];
        for (index_t k = k0; k < k1; ++k)
            for (int c = 0; c < 6; ++c)
                s[c] += nb.stress[c * np + nb.owner_points[k]];
        return k1 > k0 ? Sym6(s / static_cast<real_t>(k1 - k0)) : s;
    }
    const HexBlock& blk = blocks[ip];
    const index_t i = node - blk.node_begin;
    Sym6 s = Sym6::Zero();
    const index_t k0 = blk.node_elem_offsets[i], k1 = blk.node_elem_offsets[i + 1];
    for (index_t k = k0; k < k1; ++k)
        s += element_stress(ip, blk.node_elem_slots[k] / 8);
    return k1 > k0 ? Sym6(s / static_cast<real_t>(k1 - k0)) : s;
}
} // namespace rkfem
