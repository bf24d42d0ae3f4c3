/// @file nodal_block_cloud.cpp
/// Particle clouds: Voronoi cells, SCNI and stabilization, and the lumped mass of nodal blocks.
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

namespace rkfem
{
using namespace nodal_build_detail;

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
    {
        NodalBlockOptions o = nb.options();
        o.compact_operators = true;
        nb.set_options(o);
    }
    finish_block(nb, offset, reach, band);
    return nb;
}

void add_nodal_mass(const NodalBlock& blk, NodeSet& nodes)
{
    for (index_t p = 0; p < blk.n_points(); ++p)
        nodes.mass[blk.points.owner[p]] += blk.material.rho * blk.points.weight[p];
}
} // namespace rkfem
