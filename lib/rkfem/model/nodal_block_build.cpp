#include "rkfem/model/nodal_block_build.hpp"
#include "rkfem/model/nodal_block_build_detail.hpp"

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
#include "rkfem/model/material_from_deck.hpp"

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
namespace nodal_build_detail
{
NodalBlock block_frame(const PartSpec& ps, index_t n_nodes, index_t offset, std::shared_ptr<KccScaleCache> scales)
{
    NodalBlock nb;
    nb.material = ElasticParams::from_E_nu(ps.material.rho, ps.material.E, ps.material.nu);
    configure_points(nb.plastic, ps.material);
    if (scales)
        nb.plastic.kcc_scales = std::move(scales);
    nb.node_begin = offset;
    nb.node_end = offset + n_nodes;
    nb.dt_factor = ps.nodal.dt_factor > 0 ? ps.nodal.dt_factor : default_dt_factor(ps);
    nb.bulk_viscosity = ps.bulk_viscosity;
    nb.stab_plastic_scaling = ps.nodal.plastic_scaling;
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
} // namespace nodal_build_detail

using namespace nodal_build_detail;

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
                                  nb.options().share_stencils && !mscni ? &nb.point_stencils : nullptr);
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
    // a part of one formulation: its operators never change in place
    NodalBlockOptions o = nb.options();
    o.compact_operators = true;
    nb.set_options(o);
    finish_block(nb, offset, l0, l0);
    return nb;
}

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

} // namespace rkfem
