#include "rkfem/operators/nodal_block_build.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <map>
#include <memory>
#include <optional>

#include <omp.h>

#include "rkfem/approximation/coupling/coupled_shapes.hpp"
#include "rkfem/approximation/rk/rk_region_values.hpp"
#include "rkfem/approximation/shape_evaluator.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/setup_progress.hpp"
#include "rkfem/discretization/cell_list.hpp"
#include "rkfem/discretization/voronoi_cells.hpp"
#include "rkfem/integration/nodal/nodal_integration.hpp"

namespace rkfem
{
namespace
{
/// Default dt factor alpha (dt = alpha J^(1/3) l0 / c) per nodal formulation, calibrated from
/// the largest eigenvalue of M^-1 K on free regular and jittered blocks (verification/
/// operators/test_nodal_dynamics.cpp, NodalTimeStep prints alpha_crit): the smallest critical
/// value found (regular block: rkpm 1.054, fem-nodal 0.957), rounded down. Like l/c for hexes
/// it is the critical estimate; time.dt_scale (0.9) applies on top.
real_t default_dt_factor(const PartSpec& ps)
{
    return ps.formulation == Formulation::Rkpm ? 1.0 : 0.95;
}

} // namespace

RkParams rk_params(const RkSpec& spec)
{
    RkParams rp;
    rp.order = spec.order;
    rp.kernel = spec.kernel == "quintic-bspline" ? KernelType::QuinticBSpline
                : spec.kernel == "gaussian"      ? KernelType::Gaussian
                                                 : KernelType::CubicBSpline;
    rp.support = spec.support == "sphere" ? SupportShape::Sphere : SupportShape::Box;
    rp.normalized_support = spec.normalized_support;
    return rp;
}

namespace
{
NodalBlock block_frame(const PartSpec& ps, index_t n_nodes, index_t offset)
{
    NodalBlock nb;
    nb.material = ElasticParams::from_E_nu(ps.material.rho, ps.material.E, ps.material.nu);
    nb.plastic.configure(ps.material);
    nb.node_begin = offset;
    nb.node_end = offset + n_nodes;
    nb.dt_factor = ps.nodal.dt_factor > 0 ? ps.nodal.dt_factor : default_dt_factor(ps);
    nb.bulk_viscosity = ps.bulk_viscosity;
    return nb;
}

/// RK interpolation Psi_J(X_I) at the particles, for physical nodal values. A particle whose
/// neighbourhood is a translate of an earlier particle's (particles: particle_translates) takes
/// that particle's row, its particles matched to the source's.
void add_interpolation(NodalBlock& nb, const RkShapeFunctions& rk, const RkTranslates& particles, index_t offset)
{
    // Psi_J(x_i) of every source i by the region evaluator (particles ascending in each row),
    // threads over contiguous ranges of the sources, their rows joined in source order
    const index_t n = rk.size();
    std::vector<index_t> sources, source_index(static_cast<std::size_t>(n), -1);
    for (index_t i = 0; i < n; ++i)
        if (particles.computed(i))
        {
            source_index[i] = static_cast<index_t>(sources.size());
            sources.push_back(i);
        }
    const index_t ns = static_cast<index_t>(sources.size());
    std::vector<std::vector<index_t>> block_nodes;
    std::vector<std::vector<real_t>> block_values;
    std::vector<index_t> count(static_cast<std::size_t>(ns));
    ParallelErrors errors;
#pragma omp parallel
    {
#pragma omp single
        {
            const std::size_t teams = static_cast<std::size_t>(omp_get_num_threads());
            block_nodes.resize(teams);
            block_values.resize(teams);
        }
        const std::size_t t = static_cast<std::size_t>(omp_get_thread_num());
        RkRegionValues region(rk, 0.0);
#pragma omp for schedule(static)
        for (index_t k = 0; k < ns; ++k)
        {
            try
            {
                const Vec3 p = rk.position(sources[k]);
                region.gather(p, p);
                region.evaluate(p);
                index_t c = 0;
                for (std::size_t j = 0; j < region.size(); ++j)
                    if (region.kept()[j] != 0.0)
                    {
                        block_nodes[t].push_back(region.candidates()[j]);
                        block_values[t].push_back(region.psi()[j]);
                        ++c;
                    }
                count[k] = c;
            }
            catch (...)
            {
                errors.capture();
            }
        }
    }
    errors.rethrow();
    std::vector<index_t> source_nodes, source_offsets(static_cast<std::size_t>(ns) + 1, 0);
    std::vector<real_t> source_values;
    for (std::size_t t = 0; t < block_nodes.size(); ++t)
    {
        source_nodes.insert(source_nodes.end(), block_nodes[t].begin(), block_nodes[t].end());
        source_values.insert(source_values.end(), block_values[t].begin(), block_values[t].end());
    }
    for (index_t k = 0; k < ns; ++k)
        source_offsets[k + 1] = source_offsets[k] + count[k];
    // every particle's row: its source's, read through its own particles
    nb.interp_offsets.assign(static_cast<std::size_t>(n) + 1, 0);
    for (index_t i = 0; i < n; ++i)
    {
        const index_t k = source_index[particles.source[i]];
        nb.interp_offsets[i + 1] = nb.interp_offsets[i] + source_offsets[k + 1] - source_offsets[k];
    }
    nb.interp_nodes.resize(static_cast<std::size_t>(nb.interp_offsets[n]));
    nb.interp_values.resize(nb.interp_nodes.size());
    parallel_for("rkfem::add_interpolation::rows", n,
                 [&](index_t i)
                 {
                     const index_t k = source_index[particles.source[i]];
                     const bool own = particles.computed(i);
                     index_t q = nb.interp_offsets[i];
                     for (index_t j = source_offsets[k]; j < source_offsets[k + 1]; ++j, ++q)
                     {
                         nb.interp_nodes[q] =
                             (own ? source_nodes[j] : particles.counterpart(i, source_nodes[j])) + offset;
                         nb.interp_values[q] = source_values[j];
                     }
                 });
}

/// NSNI held as its triplets alone from the start (a compact block's form, NodalBlock::
/// stab_in_triplets): build_tables keeps them and forms no sub-point entries.
void hold_nsni(NodalBlock& nb, NsniTriplets nsni)
{
    nb.stabilization = std::move(nsni.frame);
    nb.stab_triplets = std::move(nsni.table);
    nb.stabilization_triplets = true;
    nb.stab_in_triplets = true;
}

DeckError singular_support(const PartSpec& ps, const SingularMomentError& e)
{
    return DeckError({ps.rk.loc.where.empty() ? ps.loc.where : ps.rk.loc.where, ps.loc.path + ".rk.normalized_support"},
                     e.what(),
                     "expected a support large enough that every point is covered by 4 particles not in one plane "
                     "(near one spacing, rk.drop_tolerance: 0 keeps the small functions)");
}

/// Operators to global node ids, l0 per point from the owner node, state arrays, crack bands.
void finish_block(NodalBlock& nb, index_t offset, const std::vector<real_t>& l0, const std::vector<real_t>& band)
{
    for (auto* op : {&nb.points, &nb.stabilization})
    {
        for (auto& n : op->nodes)
            n += offset;
        for (auto& o : op->owner)
            o += offset;
    }
    // NSNI held as its triplets (hold_nsni): each point's stencil counts its nodes from its
    // base, a node id too (a part after others in the model starts past their nodes)
    for (auto& b : nb.stab_triplets.point_base)
        b += offset;
    // the same for SCNI held in shared stencils from the start (build_scni_rk)
    for (auto& b : nb.point_stencils.point_base)
        b += offset;
    nb.length0.resize(static_cast<std::size_t>(nb.points.n_points()));
    std::vector<real_t> lengths(nb.length0.size());
    for (index_t p = 0; p < nb.points.n_points(); ++p)
    {
        nb.length0[p] = l0[nb.points.owner[p] - offset];
        lengths[p] = band[nb.points.owner[p] - offset];
    }
    nb.initialize();
    nb.plastic.set_lengths(lengths);
}
} // namespace

NodalBlock build_nodal_block(const PartSpec& ps, const HexMesh& mesh, index_t offset)
{
    NodalBlock nb = block_frame(ps, mesh.n_nodes(), offset);
    const NodalScheme scheme = ps.nodal.scheme == "dni"       ? NodalScheme::Dni
                               : ps.nodal.scheme == "sd-scni" ? NodalScheme::SdScni
                                                              : NodalScheme::Scni;
    std::shared_ptr<const RkShapeFunctions> rk;
    std::unique_ptr<ShapeEvaluator> shapes;
    if (ps.formulation == Formulation::Rkpm)
    {
        rk = std::make_shared<const RkShapeFunctions>(rk_on_mesh(mesh, rk_params(ps.rk)));
        shapes = std::make_unique<RkShapes>(*rk, ps.rk.drop_tolerance);
        nb.rk = rk;
    }
    else
        shapes = std::make_unique<FemShapes>(mesh);
    // the particles' neighbourhoods as translates, for NSNI and the interpolation (found once)
    std::optional<RkTranslates> translates;
    auto particles = [&]() -> const RkTranslates&
    {
        if (!translates)
            translates = particle_translates(*rk, ps.rk.share_translates);
        return *translates;
    };
    try
    {
        const bool stabilized =
            scheme == NodalScheme::Scni && ps.nodal.stabilization != "none" && ps.nodal.stabilization_coefficient > 0;
        const bool mscni = stabilized && !(ps.nodal.stabilization == "nsni" && rk);
        IntegrationOperator sd; // MSCNI's sub-cells, in the same pass as the SCNI points
        {
            // RK SCNI (and MSCNI's sub-cells) by elements (each facet point evaluated once),
            // counted per element
            const bool by_elements = rk && scheme == NodalScheme::Scni;
            const setup_progress::Phase progress("part '" + ps.name + "': " + ps.nodal.scheme + " gradients",
                                                 by_elements ? mesh.n_elements() : mesh.n_nodes());
            if (by_elements)
            {
                // the rows straight into shared stencils where they pay (a part of one
                // formulation keeps only the table: compact_operators below; MSCNI's
                // stabilization is formed from the rows)
                nb.points =
                    build_scni_rk(mesh, *rk, ps.rk.drop_tolerance, mscni ? &sd : nullptr, ps.rk.share_translates,
                                  nb.share_stencils && !mscni ? &nb.point_stencils : nullptr);
                nb.points_in_table = !nb.point_stencils.empty();
            }
            else if (mscni)
                build_scni_sd(mesh, *shapes, nb.points, &sd);
            else
                nb.points = build_nodal(scheme, mesh, *shapes);
        }
        if (stabilized)
        {
            const setup_progress::Phase progress("part '" + ps.name + "': " + ps.nodal.stabilization + " stabilization",
                                                 mscni ? 0 : nb.points.n_points());
            if (mscni)
                nb.stabilization = build_mscni_stabilization(nb.points, sd);
            else
                hold_nsni(nb, build_nsni_triplets(nb.points, *rk, nodal_second_moments(mesh), ps.rk.drop_tolerance,
                                                  particles()));
            nb.stabilization_coefficient = ps.nodal.stabilization_coefficient;
        }
        if (rk)
            add_interpolation(nb, *rk, particles(), offset);
    }
    catch (const SingularMomentError& e)
    {
        throw singular_support(ps, e);
    }
    // stable-step length and crack band: the shortest mesh edge at the node
    const std::vector<real_t> l0 = nodal_spacing(mesh, false);
    nb.compact_operators = true; // a part of one formulation: its operators never change in place
    finish_block(nb, offset, l0, l0);
    return nb;
}

namespace
{
/// Is point c inside region r (box, within radius of a cylinder's axis, sphere)?
bool inside_region(const SelectorSpec& r, const Vec3& c)
{
    switch (r.type)
    {
    case SelectorSpec::Type::Box:
        return (c.array() >= r.min.array()).all() && (c.array() <= r.max.array()).all();
    case SelectorSpec::Type::Cylinder:
    {
        const Vec3 d = c - r.point;
        return (d - d.dot(r.normal) * r.normal).norm() <= r.radius;
    }
    case SelectorSpec::Type::Sphere:
        return (c - r.point).norm() <= r.radius;
    default:
        return false;
    }
}
} // namespace

std::vector<char> rk_region_elements(const PartSpec& ps, const HexMesh& mesh)
{
    std::vector<char> rk(static_cast<std::size_t>(mesh.n_elements()), 0);
    for (index_t e = 0; e < mesh.n_elements(); ++e)
    {
        Vec3 c = Vec3::Zero();
        for (int a = 0; a < 8; ++a)
            c += mesh.node(mesh.conn[8 * e + a]) / 8.0;
        for (const SelectorSpec& r : ps.regions)
            rk[e] = rk[e] || inside_region(r, c);
    }
    return rk;
}

namespace
{
/// The coupled shapes seen through a sub-mesh of some of the part's elements: element e of the
/// sub-mesh is element elements[e] of the part (node ids stay the part's).
class SubMeshShapes final : public ShapeEvaluator
{
  public:
    SubMeshShapes(const CoupledShapes& shapes, const std::vector<index_t>& elements) : s_(shapes), e_(elements) {}
    void values(index_t e, const Vec3& xi, const Vec3& x, std::vector<index_t>& nodes,
                std::vector<real_t>& psi) const override
    {
        s_.values(e_[static_cast<std::size_t>(e)], xi, x, nodes, psi);
    }
    void gradients_at_node(index_t i, std::vector<index_t>& nodes, std::vector<Vec3>& grad) const override
    {
        s_.gradients_at_node(i, nodes, grad);
    }

  private:
    const CoupledShapes& s_;
    const std::vector<index_t>& e_;
};
} // namespace

namespace
{
/// The part's elements with keep[e] != 0 as a mesh of their own: element k is elements[k] of the
/// part (element_to_sub the inverse, -1 for the others), node j is sub_to_part[j] (part_to_sub the
/// inverse), boundary faces extracted.
struct SubMesh
{
    HexMesh mesh;
    std::vector<index_t> elements, element_to_sub, sub_to_part, part_to_sub;
};
SubMesh sub_mesh(const HexMesh& mesh, const std::vector<char>& keep)
{
    SubMesh s;
    s.element_to_sub.assign(static_cast<std::size_t>(mesh.n_elements()), -1);
    s.part_to_sub.assign(static_cast<std::size_t>(mesh.n_nodes()), -1);
    for (index_t e = 0; e < mesh.n_elements(); ++e)
    {
        if (!keep[e])
            continue;
        s.element_to_sub[e] = static_cast<index_t>(s.elements.size());
        s.elements.push_back(e);
        for (int a = 0; a < 8; ++a)
        {
            const index_t i = mesh.conn[8 * e + a];
            if (s.part_to_sub[i] < 0)
            {
                s.part_to_sub[i] = static_cast<index_t>(s.sub_to_part.size());
                s.sub_to_part.push_back(i);
                for (int d = 0; d < 3; ++d)
                    s.mesh.x.push_back(mesh.x[3 * i + d]);
            }
            s.mesh.conn.push_back(s.part_to_sub[i]);
        }
    }
    s.mesh.faces = extract_boundary_faces(s.mesh.conn);
    return s;
}
} // namespace

NodalBlock build_coupled_block(const PartSpec& ps, const HexMesh& mesh, index_t offset, const std::vector<char>* rk_set)
{
    const std::vector<char> rk_elements = rk_set ? *rk_set : rk_region_elements(ps, mesh);
    index_t n_rk = 0;
    for (char c : rk_elements)
        n_rk += c;
    if (n_rk == 0 && ps.converts() && ps.formulation == Formulation::FemNodal)
    {
        // no RK element yet: nodal-integrated FE on the same cells as a coupled block's
        NodalBlock nb = block_frame(ps, mesh.n_nodes(), offset);
        const FemShapes shapes(mesh);
        if (ps.nodal.stabilization == "mscni" && ps.nodal.stabilization_coefficient > 0)
        {
            IntegrationOperator sd;
            build_scni_sd(mesh, shapes, nb.points, &sd);
            nb.stabilization = build_mscni_stabilization(nb.points, sd);
            nb.stabilization_coefficient = ps.nodal.stabilization_coefficient;
        }
        else
            nb.points = build_scni(mesh, shapes);
        nb.particle.assign(static_cast<std::size_t>(mesh.n_nodes()), 0);
        nb.fe_element.assign(static_cast<std::size_t>(mesh.n_elements()), 1);
        // physical values: identity rows
        nb.interp_offsets.resize(static_cast<std::size_t>(mesh.n_nodes()) + 1);
        for (index_t i = 0; i <= mesh.n_nodes(); ++i)
            nb.interp_offsets[i] = i;
        for (index_t i = 0; i < mesh.n_nodes(); ++i)
            nb.interp_nodes.push_back(i + offset);
        nb.interp_values.assign(static_cast<std::size_t>(mesh.n_nodes()), 1.0);
        const std::vector<real_t> l0 = nodal_spacing(mesh, false);
        finish_block(nb, offset, l0, l0);
        return nb;
    }
    if (!rk_set && (n_rk == 0 || n_rk == mesh.n_elements()))
        throw DeckError(ps.regions_loc,
                        n_rk == 0 ? "contain no element centroid of the part"
                                  : "contain every element of the part, leaving no FE region",
                        n_rk == 0 ? "expected regions that hold some of the part's elements"
                                  : "expected formulation: rkpm for an all-RK part, or smaller regions");
    NodalBlock nb = block_frame(ps, mesh.n_nodes(), offset);
    const Transition t = ps.transition == "ramp" ? Transition::Ramp : Transition::Mixed;
    try
    {
        const CoupledShapes shapes(mesh, rk_elements, rk_params(ps.rk), t);
        const bool stabilized = ps.nodal.stabilization == "mscni" && ps.nodal.stabilization_coefficient > 0;
        if (ps.formulation == Formulation::FemNodal)
        {
            // every node's dual cell
            IntegrationOperator sd;
            build_scni_sd(mesh, shapes, nb.points, stabilized ? &sd : nullptr);
            if (stabilized)
                nb.stabilization = build_mscni_stabilization(nb.points, sd);
        }
        else
        {
            // fem-1pt FE side: the FE elements are the part's 1-point block; the nodes of the
            // transition and RK elements get the dual cells of those elements only (their faces
            // with FE elements are the cells' boundary), on a sub-mesh with its own numbering
            std::vector<char> keep(static_cast<std::size_t>(mesh.n_elements()));
            for (index_t e = 0; e < mesh.n_elements(); ++e)
                keep[e] = shapes.kind(e) != CoupledShapes::Kind::Fe;
            const SubMesh sm = sub_mesh(mesh, keep);
            const SubMeshShapes sub_shapes(shapes, sm.elements);
            IntegrationOperator sd;
            build_scni_sd(sm.mesh, sub_shapes, nb.points, stabilized ? &sd : nullptr);
            if (stabilized)
                nb.stabilization = build_mscni_stabilization(nb.points, sd);
            // owners to the part's numbering (the gradients' nodes already are)
            for (auto* op : {&nb.points, &nb.stabilization})
                for (auto& o : op->owner)
                    o = sm.sub_to_part[static_cast<std::size_t>(o)];
        }
        if (stabilized)
            nb.stabilization_coefficient = ps.nodal.stabilization_coefficient;
        // physical values: identity at FE nodes, the RK interpolant at particles
        nb.interp_offsets.assign(1, 0);
        std::vector<index_t> row_nodes;
        std::vector<real_t> row_values;
        for (index_t i = 0; i < mesh.n_nodes(); ++i)
        {
            row_nodes.clear();
            row_values.clear();
            shapes.node_row(i, row_nodes, row_values);
            for (std::size_t k = 0; k < row_nodes.size(); ++k)
            {
                nb.interp_nodes.push_back(row_nodes[k] + offset);
                nb.interp_values.push_back(row_values[k]);
            }
            nb.interp_offsets.push_back(static_cast<index_t>(nb.interp_nodes.size()));
        }
        nb.particle.resize(static_cast<std::size_t>(mesh.n_nodes()));
        nb.fe_element.resize(static_cast<std::size_t>(mesh.n_elements()));
        for (index_t i = 0; i < mesh.n_nodes(); ++i)
            nb.particle[i] = shapes.is_particle(i);
        for (index_t e = 0; e < mesh.n_elements(); ++e)
            nb.fe_element[e] = shapes.kind(e) == CoupledShapes::Kind::Fe;
    }
    catch (const SingularMomentError& e)
    {
        throw singular_support(ps, e);
    }
    const std::vector<real_t> l0 = nodal_spacing(mesh, false);
    finish_block(nb, offset, l0, l0);
    return nb;
}

namespace
{
/// Replaces the rows of op's points with replace[p] by rows of `from` (point from_point[p]).
void splice_rows(IntegrationOperator& op, const std::vector<char>& replace, const IntegrationOperator& from,
                 const std::vector<index_t>& from_point)
{
    IntegrationOperator out;
    out.weight = op.weight;
    out.position = op.position;
    out.owner = op.owner;
    out.parent = op.parent;
    out.offsets.reserve(op.offsets.size());
    out.nodes.reserve(op.nodes.size());
    out.grad.reserve(op.grad.size());
    for (index_t p = 0; p < op.n_points(); ++p)
    {
        const IntegrationOperator& src = replace[p] ? from : op;
        const index_t q = replace[p] ? from_point[p] : p;
        for (index_t k = src.offsets[q]; k < src.offsets[q + 1]; ++k)
        {
            out.nodes.push_back(src.nodes[k]);
            out.grad.insert(out.grad.end(), {src.grad[3 * k], src.grad[3 * k + 1], src.grad[3 * k + 2]});
        }
        out.offsets.push_back(out.n_entries());
        if (replace[p])
        {
            out.weight[p] = from.weight[q];
            for (int d = 0; d < 3; ++d)
                out.position[3 * p + d] = from.position[3 * q + d];
        }
    }
    op = std::move(out);
}
} // namespace

ChangedRows update_coupled_block(const PartSpec& ps, const HexMesh& mesh, index_t offset,
                                 const std::vector<char>& rk_old, const std::vector<char>& rk_new, NodalBlock& nb)
{
    const index_t ne = mesh.n_elements(), nn = mesh.n_nodes();
    const RkParams params = rk_params(ps.rk);
    auto layout = [&](const std::vector<char>& rk)
    {
        for (char c : rk)
            if (c)
                return coupled_layout(mesh, rk, params);
        CoupledLayout all_fe;
        all_fe.kind.assign(static_cast<std::size_t>(ne), CoupledShapes::Kind::Fe);
        all_fe.radius.assign(static_cast<std::size_t>(nn), 0.0);
        return all_fe;
    };
    const CoupledLayout before = layout(rk_old), after = layout(rk_new);
    // particles that appear, disappear or change their support, with the larger radius
    std::vector<index_t> changed;
    std::vector<real_t> changed_x, reach;
    real_t reach_max = 0.0;
    for (index_t i = 0; i < nn; ++i)
        if (before.radius[i] != after.radius[i])
        {
            changed.push_back(i);
            for (int d = 0; d < 3; ++d)
                changed_x.push_back(mesh.x[3 * i + d]);
            reach.push_back(std::max(before.radius[i], after.radius[i]));
            reach_max = std::max(reach_max, reach.back());
        }
    // elements whose approximation changes: another kind, or a transition or RK element whose
    // box meets a changed particle's support box (a box contains the sphere of a sphere support)
    std::vector<char> affected(static_cast<std::size_t>(ne), 0);
    std::vector<Vec3> lo(static_cast<std::size_t>(ne)), hi(static_cast<std::size_t>(ne));
    real_t half_max = 0.0;
    for (index_t e = 0; e < ne; ++e)
    {
        lo[e] = hi[e] = mesh.node(mesh.conn[8 * e]);
        for (int a = 1; a < 8; ++a)
        {
            lo[e] = lo[e].cwiseMin(mesh.node(mesh.conn[8 * e + a]));
            hi[e] = hi[e].cwiseMax(mesh.node(mesh.conn[8 * e + a]));
        }
        half_max = std::max(half_max, 0.5 * (hi[e] - lo[e]).maxCoeff());
        affected[e] = before.kind[e] != after.kind[e];
    }
    if (!changed.empty())
    {
        const CellList bins(changed_x, reach_max + half_max);
        for (index_t e = 0; e < ne; ++e)
        {
            if (affected[e] || after.kind[e] == CoupledShapes::Kind::Fe)
                continue;
            bins.for_each_candidate(0.5 * (lo[e] + hi[e]),
                                    [&](index_t j)
                                    {
                                        const Vec3 x(changed_x[3 * j], changed_x[3 * j + 1], changed_x[3 * j + 2]);
                                        if (((lo[e].array() - reach[j]) <= x.array()).all() &&
                                            (x.array() <= (hi[e].array() + reach[j])).all())
                                            affected[e] = 1;
                                    });
        }
    }
    // the nodes whose points change, and every element around them
    std::vector<char> node_changes(static_cast<std::size_t>(nn), 0);
    for (index_t e = 0; e < ne; ++e)
        if (affected[e])
            for (int a = 0; a < 8; ++a)
                node_changes[mesh.conn[8 * e + a]] = 1;
    std::vector<char> around(static_cast<std::size_t>(ne), 0);
    for (index_t e = 0; e < ne; ++e)
        for (int a = 0; a < 8; ++a)
            around[e] = around[e] || node_changes[mesh.conn[8 * e + a]];
    const SubMesh sm = sub_mesh(mesh, around);
    ChangedRows rows;
    if (sm.elements.empty())
        return rows;
    const Transition t = ps.transition == "ramp" ? Transition::Ramp : Transition::Mixed;
    try
    {
        const CoupledShapes shapes(mesh, rk_new, params, t);
        const SubMeshShapes sub_shapes(shapes, sm.elements);
        IntegrationOperator scni, sd;
        build_scni_sd(sm.mesh, sub_shapes, scni, nb.n_stab() > 0 ? &sd : nullptr);
        for (auto& n : scni.nodes)
            n += offset;
        // SCNI: point p is node p
        std::vector<index_t> from(static_cast<std::size_t>(nn), -1);
        for (index_t i = 0; i < nn; ++i)
            if (node_changes[i])
                from[i] = sm.part_to_sub[i];
        splice_rows(nb.points, node_changes, scni, from);
        if (nb.n_stab() > 0)
        {
            // MSCNI: sub-cell 8 e + a of the node conn[8 e + a]; the sub-mesh's 8 k + a
            for (auto& n : sd.nodes)
                n += offset;
            const IntegrationOperator stab = build_mscni_stabilization(scni, sd);
            std::vector<char> replace(static_cast<std::size_t>(nb.n_stab()), 0);
            std::vector<index_t> from_stab(replace.size(), -1);
            for (index_t e = 0; e < ne; ++e)
                for (int a = 0; a < 8; ++a)
                    if (node_changes[mesh.conn[8 * e + a]])
                    {
                        replace[8 * e + a] = 1;
                        from_stab[8 * e + a] = 8 * sm.element_to_sub[e] + a;
                    }
            splice_rows(nb.stabilization, replace, stab, from_stab);
        }
        // physical values at the nodes whose rows changed
        std::vector<index_t> row_nodes;
        std::vector<real_t> row_values;
        for (index_t i = 0; i < nn; ++i)
        {
            if (!node_changes[i])
                continue;
            row_nodes.clear();
            row_values.clear();
            shapes.node_row(i, row_nodes, row_values);
            rows.node.push_back(i);
            for (std::size_t k = 0; k < row_nodes.size(); ++k)
            {
                rows.columns.push_back(row_nodes[k] + offset);
                rows.values.push_back(row_values[k]);
            }
            rows.offsets.push_back(static_cast<index_t>(rows.columns.size()));
        }
        for (index_t i = 0; i < nn; ++i)
            nb.particle[i] = shapes.is_particle(i);
        for (index_t e = 0; e < ne; ++e)
            nb.fe_element[e] = shapes.kind(e) == CoupledShapes::Kind::Fe;
    }
    catch (const SingularMomentError& e)
    {
        throw singular_support(ps, e);
    }
    nb.build_tables();
    return rows;
}

std::vector<HalfSpace> cloud_body(const GeneratorSpec& g, index_t n_particles)
{
    if (g.body == GeneratorSpec::Body::Box)
        return box_halfspaces(g.origin, g.origin + g.size);
    // the tangent prism, its facets about a quarter of the mean spacing wide: the body's volume
    // is then the cylinder's to (pi / sides)^2 / 3 (2e-4 at the minimum of 128 sides), and a
    // boundary cell meets a few of them
    const real_t spacing = std::cbrt(M_PI * g.radius * g.radius * g.height / std::max<index_t>(1, n_particles));
    const int sides = std::clamp(static_cast<int>(std::ceil(8.0 * M_PI * g.radius / spacing)), 128, 4096);
    return cylinder_halfspaces(g.origin, g.radius, g.height, sides);
}

NodalBlock build_cloud_block(const PartSpec& ps, const HexMesh& cloud, index_t offset)
{
    const GeneratorSpec& g = ps.generator;
    const index_t n = cloud.n_nodes();
    const bool stabilized =
        ps.nodal.scheme == "scni" && ps.nodal.stabilization != "none" && ps.nodal.stabilization_coefficient > 0;
    const bool nsni = ps.nodal.stabilization == "nsni";
    VoronoiCells cells;
    try
    {
        const setup_progress::Phase progress("part '" + ps.name + "': Voronoi cells", n);
        // the sub-cells only for the schemes that integrate on them (SD-SCNI, MSCNI)
        cells = voronoi_cells(cloud.x, cloud_body(g, n), VoronoiHull::Clip,
                              ps.nodal.scheme == "sd-scni" || (stabilized && !nsni));
    }
    catch (const Error& e)
    {
        throw DeckError({g.loc.where, ps.loc.path + ".generator"}, e.what(),
                        "expected distinct particles inside the body");
    }
    // per particle: the facet area shared with each neighbour, and the longest distance to a
    // neighbour across a facet of at least 10% of the cell's largest (jitter adds small facets to
    // diagonal neighbours, which this leaves out). It sets the support size and the stable-step
    // length: with it the critical alpha of free clouds is 1.15-1.41 for jitter 0-0.45 and for
    // random points (NodalTimeStep.DefaultFactorIsBelowTheCriticalValueOnClouds), against 1.175
    // for the regular lattice; the nearest neighbour's distance gave 2-6 on jittered clouds
    // (needlessly small steps).
    std::vector<real_t> reach(static_cast<std::size_t>(n), 0.0);
    for (index_t i = 0; i < n; ++i)
    {
        std::map<index_t, real_t> area;
        for (index_t q = cells.offsets[i]; q < cells.offsets[i + 1]; ++q)
            if (cells.points[q].neighbour >= 0)
                area[cells.points[q].neighbour] += cells.points[q].nda.norm();
        real_t amax = 0.0;
        for (const auto& [j, a] : area)
            amax = std::max(amax, a);
        for (const auto& [j, a] : area)
        {
            if (a >= 0.1 * amax)
                reach[i] = std::max(reach[i], (cloud.node(i) - cloud.node(j)).norm());
        }
        if (area.empty())
            throw DeckError({g.loc.where, ps.loc.path + ".generator"},
                            "particle " + std::to_string(i) + " has no neighbour", "expected at least 2 particles");
    }
    // one SCNI point per Voronoi face where the deck asks (after the reach, which reads the
    // triangles' areas per neighbour): the SCNI rows and the body's facets for loads alike
    if (ps.nodal.facet_points == "faces")
        merge_face_points(cells);
    NodalBlock nb = block_frame(ps, n, offset);
    std::vector<real_t> a = reach;
    for (auto& v : a)
        v *= ps.rk.normalized_support;
    auto rk = std::make_shared<const RkShapeFunctions>(cloud.x, std::move(a), rk_params(ps.rk));
    nb.rk = rk;
    // the particles' neighbourhoods as translates, for NSNI and the interpolation (a jittered
    // cloud has none, and its NSNI reads the regions found here)
    const RkTranslates particles = particle_translates(*rk, ps.rk.share_translates);
    try
    {
        const RkShapes shapes(*rk, ps.rk.drop_tolerance);
        // SD-SCNI on a cloud: each Voronoi cell's pyramids (VoronoiCells::sub_cells, the sub-cells
        // MSCNI uses) are stress points of their own, owned by the cell's particle
        {
            const setup_progress::Phase progress("part '" + ps.name + "': " + ps.nodal.scheme + " gradients",
                                                 ps.nodal.scheme == "scni" ? n : 0);
            nb.points = ps.nodal.scheme == "dni"       ? build_dni_cells(cells.volume, cloud.x, shapes)
                        : ps.nodal.scheme == "sd-scni" ? build_sd_cells(cells, shapes)
                                                       : build_scni_cells_rk(cells, cloud.x, *rk, ps.rk.drop_tolerance);
        }
        // the facet points on the body's surface are kept (face loads act there); the rest go
        // now, not at the end of the part's set-up: on the 24k-particle column cloud they are
        // 100 MB that NSNI's sources and the force tables would otherwise be built beside
        // (MSCNI and SD-SCNI read the sub-cells' points, which stay)
        for (const CellFacetPoint& fp : cells.points)
            if (fp.neighbour < 0)
                nb.boundary_facets.push_back(fp);
        std::vector<CellFacetPoint>().swap(cells.points);
        std::vector<index_t>().swap(cells.offsets);
        if (stabilized)
        {
            const setup_progress::Phase progress("part '" + ps.name + "': " + ps.nodal.stabilization + " stabilization",
                                                 nsni ? nb.points.n_points() : 0);
            if (nsni)
                hold_nsni(nb, build_nsni_triplets(nb.points, *rk, cube_second_moments(cells.volume),
                                                  ps.rk.drop_tolerance, particles));
            else
                nb.stabilization = build_mscni_stabilization(nb.points, build_sd_cells(cells, shapes));
            nb.stabilization_coefficient = ps.nodal.stabilization_coefficient;
        }
        add_interpolation(nb, *rk, particles, offset);
    }
    catch (const SingularMomentError& e)
    {
        throw singular_support(ps, e);
    }
    std::vector<real_t> band(cells.volume.size());
    for (std::size_t i = 0; i < band.size(); ++i)
        band[i] = std::cbrt(cells.volume[i]); // crack band: the cell's size
    nb.compact_operators = true;
    finish_block(nb, offset, reach, band);
    return nb;
}

void add_nodal_mass(const NodalBlock& blk, NodeSet& nodes)
{
    for (index_t p = 0; p < blk.n_points(); ++p)
        nodes.mass[blk.points.owner[p]] += blk.material.rho * blk.points.weight[p];
}
} // namespace rkfem
