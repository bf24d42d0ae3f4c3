// Model::build: the discretization, sets, conditions, loads and probes of a deck.
#include "rkfem/model/model.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <sstream>

#include "rkfem/approximation/rk/rk_shape.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/core/memory_limit.hpp"
#include "rkfem/core/setup_progress.hpp"
#include "rkfem/core/stream_stores.hpp"
#include "rkfem/discretization/generators.hpp"
#include "rkfem/model/material_from_deck.hpp"
#include "rkfem/model/nodal_block_build.hpp"
#include "rkfem/operators/nodal_step_estimate.hpp"
#include "rkfem/operators/semi_lagrangian_block.hpp"

namespace rkfem
{
index_t Model::n_elements() const
{
    index_t n = 0;
    for (const auto& b : meshes)
        n += b.n_elements();
    return n;
}

std::pair<index_t, index_t> Model::locate_element(index_t global) const
{
    for (index_t b = 0; b < static_cast<index_t>(meshes.size()); ++b)
    {
        if (global < meshes[b].n_elements())
            return {b, global};
        global -= meshes[b].n_elements();
    }
    return {-1, -1};
}

namespace
{
/// About how many cells (elements, or particles of a cloud) a generator makes, in floating point
/// (no integer overflow for absurd sizes): box by divisions or size / element_size, cylinder and
/// projectile by volume / element_size^3, clouds by volume / spacing^3 (0 for a points file).
real_t estimated_cells(const GeneratorSpec& g)
{
    const real_t h = g.element_size;
    switch (g.type)
    {
    case GeneratorSpec::Type::Box:
    {
        real_t n = 1.0;
        for (int k = 0; k < 3; ++k)
            n *= g.divisions[k] > 0 ? g.divisions[k] : std::max(1.0, std::round(g.size[k] / h));
        return n;
    }
    case GeneratorSpec::Type::Cloud:
        if (!g.points_file.empty())
            return 0.0;
        return (g.body == GeneratorSpec::Body::Box ? g.size[0] * g.size[1] * g.size[2]
                                                   : M_PI * g.radius * g.radius * g.height) /
               (h * h * h);
    default:
        return std::max(1.0, M_PI * g.radius * g.radius * g.height / (h * h * h));
    }
}

/// Refuses, before anything is allocated, a deck whose meshes cannot fit: more cells than the
/// 32-bit indices hold, or an estimated footprint (1.5 kB per 1-point hex, 4 kB per 2x2x2 hex,
/// 45 kB per nodal point: measured) past the machine's memory.
void check_size(const Deck& d)
{
    const MemoryLimit limit = usable_memory();
    const real_t memory = limit.bytes;
    real_t total = 0.0, cells_total = 0.0;
    for (const PartSpec& p : d.parts)
    {
        const real_t cells = estimated_cells(p.generator);
        const real_t per = is_nodal(p.formulation) || p.coupled()   ? 45e3
                           : p.formulation == Formulation::Fem2x2x2 ? 4e3
                                                                    : 1.5e3;
        cells_total += cells;
        total += cells * per;
        std::ostringstream what;
        what.precision(3);
        if (!(cells < 2.5e8))
        {
            what << "makes about " << cells << " cells";
            throw DeckError({p.generator.loc.where, "parts." + p.name + ".generator"}, what.str(),
                            "expected fewer than 2.5e8 cells per part (a larger element_size or fewer divisions)");
        }
        if (!(total < 0.9 * memory))
        {
            what << "needs about " << total / 1e9 << " GB (" << cells_total << " cells so far)";
            std::ostringstream mem;
            mem.precision(3);
            mem << "expected meshes that fit in the " << memory / 1e9 << " GB this process may use (" << limit.what
                << ")";
            throw DeckError({p.generator.loc.where, "parts." + p.name + ".generator"}, what.str(), mem.str());
        }
    }
}

/// A nodal part outside the configurations whose default step factor the test suite holds
/// below the critical one (nodal_step_estimate.hpp): its critical factor measured, and the
/// default lowered to kMeasuredStepShare of it where it is larger; a deck's own dt_factor above
/// the critical one is kept, with a warning.
void measure_step_factor(const PartSpec& ps, NodalBlock& nb, Model& m)
{
    HighestFrequency hf;
    {
        const setup_progress::Phase progress("part '" + ps.name + "': highest frequency", 0);
        hf = nodal_highest_frequency(nb, m.nodes.mass);
    }
    if (!(hf.alpha_crit > 0.0))
        return;
    char text[400];
    const real_t measured = kMeasuredStepShare * hf.alpha_crit;
    if (ps.nodal.dt_factor == 0.0 && measured < nb.dt_factor)
    {
        std::snprintf(text, sizeof text,
                      "%s.nodal_integration.dt_factor: %.3g, not the default %.3g: the part's highest frequency "
                      "(%d force passes of Lanczos) puts the critical factor at %.3g for its RK functions and "
                      "stabilization, which the default is not calibrated for",
                      ps.loc.path.c_str(), measured, nb.dt_factor, hf.passes, hf.alpha_crit);
        nb.dt_factor = measured;
        m.setup_notes.emplace_back(text);
    }
    else if (ps.nodal.dt_factor > hf.alpha_crit)
    {
        std::snprintf(text, sizeof text,
                      "%s.nodal_integration.dt_factor: %.3g is above the part's critical factor %.3g (its highest "
                      "frequency, %d force passes of Lanczos): the run may go unstable; kept as the deck says",
                      ps.loc.path.c_str(), ps.nodal.dt_factor, hf.alpha_crit, hf.passes);
        m.setup_notes.emplace_back(text);
    }
}
/// A generated mesh whose corners are not all convex (a generator's parameters out of reach)
/// is refused; nodes of a part that share a position (an unmerged keyword mesh: its pieces are
/// not connected there) are noted. Keyword meshes check their corners as they are read. A nodal
/// or RK part's tetrahedra are rewritten so that their nodal cells close (canonical_tetrahedra),
/// and a triangle whose two solids still divide it differently is refused.
void check_mesh(const PartSpec& ps, HexMesh& mesh, std::vector<std::string>& notes)
{
    const bool read_from_file = !mesh.element_ids.empty(); // its corners were checked with the file's lines
    if (const HexCorner c = read_from_file ? HexCorner{} : worst_corner(mesh);
        c.element >= 0 && !(c.scaled_jacobian > kDegenerateScaledJacobian))
    {
        std::ostringstream what;
        what.precision(3);
        what << "element " << mesh.element_label(c.element) << " is "
             << (c.scaled_jacobian < 0.0 ? "inverted" : "degenerate") << " at its local node " << c.corner
             << " (scaled Jacobian " << c.scaled_jacobian << ")";
        throw DeckError({ps.generator.loc.where, ps.loc.path + ".generator"}, what.str(),
                        "expected a generator that makes valid (convex, positive-volume) hexahedra");
    }
    // degenerate solids (a node repeated) run as 1-point or 2x2x2 hexes; the nodal and RK
    // formulations build their cells from the images of the solids' natural octants, which close
    // on a triangle when both its solids repeat the same node of it: tetrahedra are written so
    // (canonical_tetrahedra), and a triangle that still is not (a prism's or a pyramid's against
    // another solid's) is refused
    if (ps.coupled() || ps.converts_to_semi_lagrangian())
        for (index_t e = 0; e < mesh.n_elements(); ++e)
            if (const int n = distinct_nodes(mesh.conn.data() + 8 * static_cast<std::size_t>(e)); n < 8)
                throw DeckError({ps.loc.where, ps.loc.path + ".formulation"},
                                "element " + std::to_string(mesh.element_label(e)) + " of the mesh has " +
                                    std::to_string(n) + " distinct nodes (a wedge, pyramid or tetrahedron)",
                                "expected a part without regions or conversion for a mesh with degenerate solids "
                                "(FE-RK coupling and conversion are verified on hexahedra only)");
    if (is_nodal(ps.formulation))
    {
        if (const index_t n = canonical_tetrahedra(mesh); n > 0)
            notes.push_back(ps.name + ": " + std::to_string(n) +
                            " tetrahedra rewritten as a b c c d d d d in node order for the nodal cells");
        if (const std::array<index_t, 4> t = unmatched_triangle(mesh); t[0] >= 0)
            throw DeckError({ps.loc.where, ps.loc.path + ".formulation"},
                            "elements " + std::to_string(mesh.element_label(t[0])) + " and " +
                                std::to_string(mesh.element_label(t[2])) +
                                " write the triangle they share with different nodes repeated, so the nodal cells "
                                "on it do not close",
                            "expected fem-1pt or fem-2x2x2 for this mesh, or one whose prisms and pyramids repeat "
                            "the same node on each shared triangle (tetrahedra are rewritten so)");
    }
    // exact repeats of a position (pre-processors write the same digits for an unmerged node)
    const index_t n = mesh.n_nodes();
    std::vector<index_t> order(static_cast<std::size_t>(n));
    for (index_t i = 0; i < n; ++i)
        order[static_cast<std::size_t>(i)] = i;
    auto position = [&](index_t i) {
        return std::array<real_t, 3>{mesh.x[3 * i], mesh.x[3 * i + 1], mesh.x[3 * i + 2]};
    };
    std::sort(order.begin(), order.end(), [&](index_t a, index_t b) { return position(a) < position(b); });
    index_t shared = 0, first_a = -1, first_b = -1;
    for (std::size_t k = 1; k < order.size(); ++k)
        if (position(order[k]) == position(order[k - 1]))
        {
            if (shared++ == 0)
                first_a = std::min(order[k - 1], order[k]), first_b = std::max(order[k - 1], order[k]);
        }
    if (shared > 0)
    {
        std::ostringstream note;
        note << ps.loc.path << ": " << shared << " node(s) share their position with another node of the part (first: "
             << (mesh.node_ids.empty() ? "nodes " : "NIDs ") << mesh.node_label(first_a) << " and "
             << mesh.node_label(first_b) << "); the " << (mesh.n_elements() > 0 ? "elements" : "particles")
             << " on either side are not connected there";
        notes.push_back(note.str());
    }
}
} // namespace

std::string PartInfo::element_name(index_t e) const
{
    const index_t cell = element_offset + e;
    if (!element_ids.empty())
        return "element " + std::to_string(element_ids[static_cast<std::size_t>(e)]) + " (the mesh file's EID; part '" +
               name + "', cell " + std::to_string(cell) + " in results.h5)";
    return "element " + std::to_string(e) + " of part '" + name + "' (0-based; cell " + std::to_string(cell) +
           " in results.h5)";
}

std::string PartInfo::node_name(index_t i) const
{
    if (!node_ids.empty())
        return "node " + std::to_string(node_ids[static_cast<std::size_t>(i)]) + " (the mesh file's NID; part '" +
               name + "', node " + std::to_string(node_begin + i) + " in results.h5)";
    return "node " + std::to_string(i) + " of part '" + name + "' (0-based; node " + std::to_string(node_begin + i) +
           " in results.h5)";
}

namespace
{
/// The dormant particles a refining part reserves after its own (RefinementSpec::max_new_particles).
index_t refinement_pool(const PartSpec& ps, index_t n_nodes)
{
    if (!ps.refinement.active())
        return 0;
    return ps.refinement.max_new_particles > 0 ? static_cast<index_t>(ps.refinement.max_new_particles) : 7 * n_nodes;
}
} // namespace

/// The nodes, output mesh and blocks of part ip (its nodes from `offset` on, its elements from
/// `elem_offset` on); advances both past the part.
void Model::build_part(std::size_t ip, const HexMesh& mesh, index_t& offset, index_t& elem_offset)
{
    const PartSpec& ps = deck_.parts[ip];
    PartInfo info;
    info.name = ps.name;
    info.node_begin = offset;
    info.mesh_node_end = offset + mesh.n_nodes();
    info.node_end = info.mesh_node_end + refinement_pool(ps, mesh.n_nodes());
    info.element_offset = elem_offset;
    for (index_t i = 0; i < mesh.n_nodes(); ++i)
        for (int k = 0; k < 3; ++k)
        {
            const std::size_t g = 3 * static_cast<std::size_t>(offset + i) + k;
            nodes.x0[g] = nodes.x[g] = mesh.x[3 * i + k];
            nodes.v[g] = ps.initial_velocity[k];
        }
    // a refining part's pool: dormant particles with no mass, parked on its first node
    for (index_t i = info.mesh_node_end; i < info.node_end; ++i)
        for (int k = 0; k < 3; ++k)
            nodes.x0[3 * static_cast<std::size_t>(i) + k] = nodes.x[3 * static_cast<std::size_t>(i) + k] = mesh.x[k];
    for (index_t i = info.node_begin; i < info.node_end; ++i)
        nodes.part[i] = static_cast<index_t>(ip);
    for (const auto& f : mesh.faces)
        info.faces.push_back({f[0] + offset, f[1] + offset, f[2] + offset, f[3] + offset});
    info.named_faces = mesh.named_faces;
    info.element_ids = mesh.element_ids;
    info.node_ids = mesh.node_ids;
    for (const auto& [name, ids] : mesh.named_nodes)
        for (index_t i : ids)
            info.named_nodes[name].push_back(i + offset);

    HexBlock blk;
    blk.part = static_cast<index_t>(ip);
    blk.formulation = ps.formulation;
    blk.hourglass = ps.hourglass;
    blk.bulk_viscosity = ps.bulk_viscosity;
    blk.material = ElasticParams::from_E_nu(ps.material.rho, ps.material.E, ps.material.nu);
    blk.mesh_only = is_nodal(ps.formulation) || ps.coupled();
    if (!blk.mesh_only)
        configure_points(blk.plastic, ps.material);
    blk.conn = mesh.conn;
    for (auto& c : blk.conn)
        c += offset;
    blk.node_begin = info.node_begin;
    blk.node_end = info.mesh_node_end;
    blk.initialize(nodes);
    if (!blk.mesh_only)
    {
        // crack-band length per point: the element's V^(1/3)
        std::vector<real_t> h(static_cast<std::size_t>(blk.n_points()));
        for (index_t q = 0; q < blk.n_points(); ++q)
            h[q] = std::cbrt(blk.volume0[q / blk.points_per_element()]);
        blk.plastic.set_lengths(h);
    }
    part_nodal_.push_back(-1);
    part_fe_side_.push_back(-1);
    rk_elements_.push_back(ps.coupled() ? rk_region_elements(ps, mesh) : std::vector<char>{});
    region_elements_.push_back(ps.regions.empty() ? std::vector<char>{} : rk_elements_.back());
    if (is_nodal(ps.formulation) || ps.coupled())
        build_nodal_part(ps, ip, mesh, offset, blk);
    for (index_t e = 0; e < blk.n_elements(); ++e)
        if (!(blk.volume0[e] > 0.0))
            throw DeckError({ps.generator.loc.where, ps.loc.path + ".generator"},
                            "element " + std::to_string(e) + " has non-positive volume " +
                                std::to_string(blk.volume0[e]) + " m^3",
                            "expected a generator that makes valid (positive-volume) hexahedra");
    if (!is_nodal(ps.formulation) && !ps.coupled())
        add_lumped_mass(blk, nodes);
    elem_offset += blk.n_elements();
    offset = info.node_end;
    const bool integrates = !blk.mesh_only;
    RKFEM_REQUIRE(meshes.size() < meshes.capacity(),
                  "Model::build_part: meshes not reserved (the blocks refer into it)");
    meshes.push_back(std::move(blk));
    if (integrates) // the Gauss-point part's mesh block is its integration block
        blocks_.push_back({std::make_unique<HexForceBlock>(meshes.back()), static_cast<index_t>(ip), false});
    // semi-Lagrangian conversion: the particles its elements' octants will go to, dormant now
    if (ps.converts_to_semi_lagrangian())
        build_semi_lagrangian_part(ps, ip, mesh, info.node_begin, true);
    parts.push_back(std::move(info));
}

/// The nodal block of a nodal or coupled part (its FE side too, fem-1pt), mass and step factor.
void Model::build_nodal_part(const PartSpec& ps, std::size_t ip, const HexMesh& mesh, index_t offset,
                             const HexBlock& blk)
{
    if (ps.semi_lagrangian || ps.nodal.scheme == "snni" || ps.nodal.scheme == "sd-snni")
    {
        build_semi_lagrangian_part(ps, ip, mesh, offset);
        return;
    }
    NodalBlock nb = ps.generator.type == GeneratorSpec::Type::Cloud ? build_cloud_block(ps, mesh, offset)
                    : ps.coupled()                                  ? build_coupled_block(ps, mesh, offset)
                                                                    : build_nodal_block(ps, mesh, offset);
    nb.part = static_cast<index_t>(ip);
    add_nodal_mass(nb, nodes);
    // the default factors are calibrated on hexahedra and clouds: a mesh with degenerate solids
    // has its critical factor measured (fem-nodal MSCNI on tetrahedra went unstable at the
    // hexahedra's default)
    if (!ps.coupled() && (has_degenerate_solids(mesh) || !nodal_step_calibrated(ps.formulation, ps.nodal, ps.rk,
                                                                                jittered_lattice_cloud(ps.generator))))
        measure_step_factor(ps, nb, *this);
    // RK regions of coupled parts and those a conversion makes are not measured
    if ((ps.coupled() || ps.conversion.active()) && !nodal_step_calibrated(Formulation::Rkpm, ps.nodal, ps.rk) &&
        ps.nodal.dt_factor == 0.0)
        setup_notes.push_back(ps.loc.path +
                              ".nodal_integration.dt_factor: the default, which is calibrated for the default RK "
                              "functions and stabilization only; the step of a coupled part's or a conversion's "
                              "RK region is not measured (set dt_factor below the default if the run goes "
                              "unstable)");
    std::optional<FeSide> side;
    if (ps.coupled() && ps.formulation == Formulation::Fem1pt)
    {
        side = build_fe_side(ps, mesh, blk, nb);
        add_lumped_mass(side->block, nodes);
    }
    part_nodal_.back() = static_cast<index_t>(blocks_.size());
    blocks_.push_back({std::make_unique<NodalForceBlock>(std::move(nb)), static_cast<index_t>(ip), false});
    if (side)
    {
        part_fe_side_.back() = static_cast<index_t>(blocks_.size());
        blocks_.push_back({std::make_unique<FeSideForceBlock>(std::move(*side)), static_cast<index_t>(ip), true});
    }
}

namespace
{
/// A refining part's pool: k points after the built ones, each owned by its own node (the pool's
/// nodes follow the part's), no volume and no state yet (SemiLagrangianOptions::spares keeps
/// them dormant; a split gives each its cell, volume, lengths and state), no support.
void append_dormant_points(NodalBlock& nb, index_t k, std::vector<real_t>& radius)
{
    const std::size_t n0 = static_cast<std::size_t>(nb.n_points()), n = n0 + static_cast<std::size_t>(k);
    IntegrationOperator& pts = nb.points;
    for (std::size_t p = n0; p < n; ++p)
    {
        pts.weight.push_back(0.0);
        pts.position.insert(pts.position.end(), 3, 0.0);
        pts.owner.push_back(nb.node_begin + static_cast<index_t>(p));
        pts.offsets.push_back(pts.offsets.back());
        nb.owner_points.push_back(static_cast<index_t>(p));
        nb.owner_offsets.push_back(static_cast<index_t>(nb.owner_points.size()));
    }
    nb.length0.resize(n, 0.0);
    nb.jacobian.resize(n, 0.0);
    radius.resize(n, 0.0);
    const std::size_t stride = batch8_stride(n);
    for (LineVector<real_t>* v : {&nb.stress, &nb.stress_trial})
    {
        LineVector<real_t> w(6 * stride, 0.0);
        for (int c = 0; c < 6; ++c)
            std::copy_n(v->begin() + static_cast<std::ptrdiff_t>(c * nb.stress_stride), n0,
                        w.begin() + static_cast<std::ptrdiff_t>(c * stride));
        *v = std::move(w);
    }
    nb.stress_stride = stride;
    if (nb.plastic.active())
        nb.plastic.grow(n);
    nb.node_end += k;
}
} // namespace

/// A semi-Lagrangian rkpm part: the Lagrangian build (SCNI, no stabilization) gives the particles'
/// volumes, masses, step lengths and supports; the block takes them and rebuilds its own tables
/// in the current configuration every step.
void Model::build_semi_lagrangian_part(const PartSpec& ps, std::size_t ip, const HexMesh& mesh, index_t offset,
                                       bool dormant)
{
    PartSpec lagrangian = ps;
    lagrangian.semi_lagrangian = false;
    lagrangian.formulation = Formulation::Rkpm;
    lagrangian.conversion = ElementCriteria{};
    lagrangian.nodal.scheme = "scni";
    lagrangian.nodal.stabilization = "none";
    NodalBlock nb = ps.generator.type == GeneratorSpec::Type::Cloud ? build_cloud_block(lagrangian, mesh, offset)
                                                                    : build_nodal_block(lagrangian, mesh, offset);
    nb.part = static_cast<index_t>(ip);
    if (!dormant)
        add_nodal_mass(nb, nodes);
    RKFEM_REQUIRE(nb.rk, "semi-Lagrangian part '" << ps.name << "': the build kept no RK functions");
    std::vector<real_t> radius(static_cast<std::size_t>(nb.rk->size()));
    real_t a_max = 0.0;
    for (index_t i = 0; i < nb.rk->size(); ++i)
        a_max = std::max(a_max, radius[i] = nb.rk->radius(i));
    const index_t pool = refinement_pool(ps, mesh.n_nodes());
    if (pool > 0)
        append_dormant_points(nb, pool, radius);
    // mesh parts: each node's cell is the box of its dual cell (the node and the centroids of its
    // elements), scaled to the node's volume; the boxes of a box mesh tile it. Clouds: the cube of
    // the particle's volume, moved inside the body where it stuck out of one of the body's planes
    // (a particle on a face: its cube ends at the face, as a mesh node's box does; kernel contact
    // then meets the body where its surface is)
    std::vector<real_t> cells;
    if (ps.generator.type == GeneratorSpec::Type::Cloud)
    {
        const std::vector<HalfSpace> body = cloud_body(ps.generator, mesh.n_nodes());
        const std::size_t n = static_cast<std::size_t>(mesh.n_nodes());
        cells.assign(12 * n, 0.0);
        for (std::size_t i = 0; i < n; ++i)
        {
            const real_t half = 0.5 * std::cbrt(nb.points.weight[i]);
            Vec3 c = Vec3::Zero();
            for (const HalfSpace& h : body)
            {
                const real_t out =
                    h.normal.dot(mesh.node(static_cast<index_t>(i)) + c) + half * h.normal.cwiseAbs().sum() - h.offset;
                if (out > 0.0)
                    c -= out * h.normal;
            }
            for (int d = 0; d < 3; ++d)
            {
                cells[12 * i + d] = c[d];
                cells[12 * i + 3 + 4 * d] = half;
            }
        }
    }
    else
    {
        const std::size_t n = static_cast<std::size_t>(mesh.n_nodes());
        std::vector<real_t> lo(mesh.x), hi(mesh.x);
        for (index_t e = 0; e < mesh.n_elements(); ++e)
        {
            Vec3 c = Vec3::Zero();
            for (int k = 0; k < 8; ++k)
                c += mesh.node(mesh.conn[8 * static_cast<std::size_t>(e) + k]) / 8.0;
            for (int k = 0; k < 8; ++k)
            {
                const std::size_t i = static_cast<std::size_t>(mesh.conn[8 * static_cast<std::size_t>(e) + k]);
                for (int d = 0; d < 3; ++d)
                {
                    lo[3 * i + d] = std::min(lo[3 * i + d], c[d]);
                    hi[3 * i + d] = std::max(hi[3 * i + d], c[d]);
                }
            }
        }
        cells.assign(12 * n, 0.0);
        for (std::size_t i = 0; i < n; ++i)
        {
            real_t box = 1.0;
            for (int d = 0; d < 3; ++d)
                box *= hi[3 * i + d] - lo[3 * i + d];
            const real_t scale = box > 0.0 ? std::cbrt(nb.points.weight[i] / box) : 0.0;
            for (int d = 0; d < 3; ++d)
            {
                cells[12 * i + d] = 0.5 * (lo[3 * i + d] + hi[3 * i + d]) - mesh.x[3 * i + d];
                cells[12 * i + 3 + 4 * d] = 0.5 * scale * (hi[3 * i + d] - lo[3 * i + d]);
            }
        }
    }
    cells.resize(12 * static_cast<std::size_t>(nb.n_points()), 0.0); // the pool's: empty
    SemiLagrangianOptions opt;
    opt.rk = nb.rk->params();
    opt.skin = ps.neighbour_skin * a_max;
    // Lagrangian SNNI: the tables of the start, never reset
    opt.reset_interval = ps.semi_lagrangian ? ps.reset_interval : std::numeric_limits<index_t>::max();
    opt.separation_damage = ps.separation_damage;
    opt.plastic_scaling = ps.sl_plastic_scaling && opt.reset_interval == 1;
    opt.stabilization_coefficient = ps.nodal.stabilization == "none" ? 0.0 : ps.nodal.stabilization_coefficient;
    opt.sub_cells = ps.nodal.scheme == "sd-snni";
    opt.dormant = dormant;
    opt.spares = pool;
    if (!dormant) // a converting part's particles are no nodal block of the part: its FE block integrates it
        part_nodal_.back() = static_cast<index_t>(blocks_.size());
    blocks_.push_back(
        {std::make_unique<SemiLagrangianForceBlock>(std::move(nb), std::move(radius), std::move(cells), opt),
         static_cast<index_t>(ip), false});
}

/// The FE elements of a coupled part with a fem-1pt FE side: a 1-point block of their own (the
/// part's block only holds the mesh for output), fresh state, no mass added.
FeSide Model::build_fe_side(const PartSpec& ps, const HexMesh& mesh, const HexBlock& blk, const NodalBlock& nb)
{
    FeSide side;
    side.local.assign(static_cast<std::size_t>(mesh.n_elements()), -1);
    HexBlock& fb = side.block;
    fb.part = blk.part;
    fb.formulation = Formulation::Fem1pt;
    fb.hourglass = ps.hourglass;
    fb.bulk_viscosity = ps.bulk_viscosity;
    fb.material = blk.material;
    configure_points(fb.plastic, ps.material);
    if (fb.plastic.kind == PlasticPoints::Kind::Kcc && nb.plastic.kind == PlasticPoints::Kind::Kcc)
        fb.plastic.kcc_scales = nb.plastic.kcc_scales;
    fb.node_begin = blk.node_begin;
    fb.node_end = blk.node_end;
    for (index_t e = 0; e < mesh.n_elements(); ++e)
        if (nb.fe_element[e])
        {
            side.local[e] = fb.n_elements();
            fb.conn.insert(fb.conn.end(), blk.conn.begin() + 8 * static_cast<std::ptrdiff_t>(e),
                           blk.conn.begin() + 8 * static_cast<std::ptrdiff_t>(e + 1));
        }
    fb.initialize(nodes);
    std::vector<real_t> h(static_cast<std::size_t>(fb.n_points()));
    for (index_t q = 0; q < fb.n_points(); ++q)
        h[q] = std::cbrt(fb.volume0[q]);
    fb.plastic.set_lengths(h);
    return side;
}

/// Boundary conditions per dof (later entries override earlier ones) and the loads' sets.
void Model::build_conditions_and_loads()
{
    std::map<index_t, std::size_t> dof_slot;
    for (index_t bi = 0; bi < static_cast<index_t>(deck_.boundary_conditions.size()); ++bi)
    {
        const auto& b = deck_.boundary_conditions[bi];
        for (index_t n : node_sets.at(b.node_set))
            for (int k = 0; k < 3; ++k)
                if (b.active[k])
                {
                    const DofCondition c{3 * n + k, b.kind, &b.value[k], bi};
                    auto it = dof_slot.find(c.dof);
                    if (it == dof_slot.end())
                    {
                        dof_slot[c.dof] = conditions.size();
                        conditions.push_back(c);
                    }
                    else
                        conditions[it->second] = c;
                }
    }
    for (const auto& l : deck_.loads)
    {
        if (l.kind == LoadSpec::Kind::NodalForce)
            nodal_loads_.push_back({&l, node_sets.at(l.set)});
        else
            pressure_loads_.push_back({&l, &face_sets.at(l.set)});
    }
}

/// The kinematic map from the RK rows of every nodal block, moved out of the blocks (they served
/// the build only).
void Model::build_kinematic_map()
{
    kinematics.reset(nodes.size());
    for (index_t ip = 0; ip < static_cast<index_t>(parts.size()); ++ip)
    {
        if (!nodal_block(ip) || nodal_block(ip)->interp_offsets.empty())
            continue;
        NodalBlock& nb = *nodal_block(ip);
        const std::vector<char> all(static_cast<std::size_t>(nb.node_end - nb.node_begin), 1);
        kinematics.set_rows(nb.node_begin, nb.node_end, nb.interp_offsets, nb.interp_nodes, nb.interp_values,
                            nb.particle.empty() ? &all : &nb.particle);
        std::vector<index_t>().swap(nb.interp_offsets);
        std::vector<index_t>().swap(nb.interp_nodes);
        std::vector<real_t>().swap(nb.interp_values);
    }
}

/// Consistent pressure distribution on rkpm faces (Psi_I at 2x2 Gauss points of each face) and
/// on cloud parts' facet points.
void Model::build_rk_face_loads()
{
    for (const auto& [load, faces] : pressure_loads_)
    {
        RkFaceLoads rl;
        rl.point_offsets.assign(1, 0);
        RkSample smp;
        for (const Quad& q : *faces)
        {
            const index_t ip = nodes.part[q[0]];
            // faces of coupled parts: lumped at the corners like FE faces, each corner's force
            // at its physical point, spread to the coefficients through the kinematic map
            const bool is_rk = deck_.parts[ip].formulation == Formulation::Rkpm;
            rl.is_rk.push_back(is_rk);
            if (!is_rk)
            {
                for (int gp = 0; gp < 4; ++gp)
                    rl.point_offsets.push_back(rl.point_offsets.back());
                continue;
            }
            const RkShapeFunctions& rk = *nodal_block(ip)->rk; // local numbering
            const real_t g = 1.0 / std::sqrt(3.0);
            Vec3 xc[4];
            for (int c = 0; c < 4; ++c)
                xc[c] = Vec3(nodes.x0[3 * q[c]], nodes.x0[3 * q[c] + 1], nodes.x0[3 * q[c] + 2]);
            for (int gp = 0; gp < 4; ++gp)
            {
                const real_t r = gp % 2 ? g : -g, s = gp / 2 ? g : -g;
                const Vec3 X = 0.25 * ((1 - r) * (1 - s) * xc[0] + (1 + r) * (1 - s) * xc[1] +
                                       (1 + r) * (1 + s) * xc[2] + (1 - r) * (1 + s) * xc[3]);
                rk.evaluate(X, false, smp);
                for (index_t k = 0; k < smp.size(); ++k)
                {
                    rl.nodes.push_back(smp.nodes[k] + parts[ip].node_begin);
                    rl.psi.push_back(smp.psi[k]);
                }
                rl.point_offsets.push_back(static_cast<index_t>(rl.nodes.size()));
            }
        }
        rk_face_loads_.push_back(std::move(rl));
        CloudFaceLoads cl;
        for (const CloudFacet& cf : cloud_face_sets.at(load->set))
        {
            nodal_block(cf.part)->rk->evaluate(cf.x, true, smp);
            for (index_t k = 0; k < smp.size(); ++k)
            {
                cl.nodes.push_back(smp.nodes[k] + parts[cf.part].node_begin);
                cl.psi.push_back(smp.psi[k]);
                cl.grad.push_back(smp.grad[k]);
            }
            cl.offsets.push_back(static_cast<index_t>(cl.nodes.size()));
            cl.nda.push_back(cf.nda);
        }
        cloud_face_loads_.push_back(std::move(cl));
    }
}

Model Model::build(const Deck& deck)
{
    check_size(deck);
    Model m;
    m.deck_ = deck;
    const Deck& d = m.deck_;
    // the parts' meshes
    std::vector<HexMesh> generated;
    index_t n_nodes = 0;
    for (const auto& p : d.parts)
    {
        generated.push_back(generate(p.generator));
        check_mesh(p, generated.back(), m.setup_notes);
        n_nodes += generated.back().n_nodes() + refinement_pool(p, generated.back().n_nodes());
    }
    m.nodes.resize(n_nodes);
    index_t offset = 0, elem_offset = 0;
    m.meshes.reserve(d.parts.size()); // the block list refers into it
    for (std::size_t ip = 0; ip < d.parts.size(); ++ip)
        m.build_part(ip, generated[ip], offset, elem_offset);
    m.build_node_sets();
    m.build_face_sets();
    m.build_conditions_and_loads();
    m.build_probes_and_sections();
    m.build_kinematic_map();
    m.contact.set_map(&m.kinematics);
    m.build_rk_constraints();
    m.build_rk_face_loads();
    m.collect_loaded_dofs();
    m.plan_conditions();
    m.reaction_prev_.assign(m.conditions.size(), 0.0);
    m.part_energy_.assign(m.parts.size(), {});
    m.part_pending_.assign(m.parts.size(), {});
    m.reaction_inertia_.assign(m.conditions.size(), 0.0);
    m.contact.resize(m.nodes.size());
    m.eroded_.resize(m.meshes.size());
    m.converted_.resize(m.meshes.size());
    m.families_.resize(m.parts.size());
    m.next_refinement_check_.assign(m.parts.size(), 0.0);
    m.build_contacts();
    m.check_initial_overlaps();
    m.plan_assembly();
    m.base_conditions_ = m.conditions;
    m.collect_constrained_dofs();
    // the RK parts' shape functions served the set-up (the face loads above sample them); the
    // run reads only what was built from them (64 bytes a P1 particle)
    for (index_t ip = 0; ip < static_cast<index_t>(m.parts.size()); ++ip)
        if (NodalBlock* nb = m.nodal_block(ip))
            nb->rk.reset();
        else if (SemiLagrangianForceBlock* sl = m.semi_lagrangian_block(ip))
            sl->nodal_points()->rk.reset();
    return m;
}
} // namespace rkfem
