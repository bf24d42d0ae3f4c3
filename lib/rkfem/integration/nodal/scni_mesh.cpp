/// @file scni_mesh.cpp
/// Mesh-based nodal integration with a FE or RK shape evaluator: nodal volumes, DNI, SCNI on
/// hex-dual cells, SD-SCNI sub-cells, the element colouring the builders share.
#include "rkfem/integration/nodal/nodal_common.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <utility>

#include <omp.h>

#include "rkfem/approximation/rk/rk_region_values.hpp"
#include "rkfem/approximation/rk/rk_translates.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/core/mark_set.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/setup_progress.hpp"
#include "rkfem/integration/stencil_table.hpp"

namespace rkfem
{
using namespace nodal_detail;

std::vector<real_t> nodal_volumes(const HexMesh& mesh)
{
    std::vector<real_t> v(static_cast<std::size_t>(mesh.n_nodes()), 0.0);
    SubHex sh;
    real_t xe[8][3];
    for (index_t e = 0; e < mesh.n_elements(); ++e)
    {
        element_coordinates(mesh, e, xe);
        for (int a = 0; a < 8; ++a)
        {
            build_sub_hex(xe, a, sh);
            v[mesh.conn[8 * e + a]] += sh.volume;
        }
    }
    return v;
}

IntegrationOperator build_dni(const HexMesh& mesh, const ShapeEvaluator& shapes)
{
    return build_dni_cells(nodal_volumes(mesh), mesh.x, shapes);
}

IntegrationOperator build_scni(const HexMesh& mesh, const ShapeEvaluator& shapes)
{
    IntegrationOperator scni;
    build_scni_sd(mesh, shapes, scni, nullptr);
    return scni;
}

void build_scni_sd(const HexMesh& mesh, const ShapeEvaluator& shapes, IntegrationOperator& scni,
                   IntegrationOperator* sd)
{
    std::vector<index_t> offsets, slots;
    node_element_incidence(mesh, offsets, slots);
    const std::vector<index_t> nb = face_neighbours(mesh);
    const std::size_t n_sub = sd ? 8 * static_cast<std::size_t>(mesh.n_elements()) : 0;
    std::vector<Entries> sub_entries(n_sub);
    std::vector<real_t> sub_weight(n_sub), sub_position(3 * n_sub);
    std::vector<index_t> sub_owner(n_sub);
    scni = assemble(
        mesh.n_nodes(),
        [&](index_t i, Entries& out, real_t& w, Vec3& pos, index_t& owner, std::vector<index_t>& nodes,
            std::vector<real_t>& psi)
        {
            // each facet's terms summed as they come (the node's row, and with sd the sub-cell's
            // and the facet's own), never stored raw
            thread_local RowSum row, sub, facet;
            row.clear();
            real_t vol = 0.0;
            SubHex sh;
            real_t xe[8][3];
            for (index_t k = offsets[i]; k < offsets[i + 1]; ++k)
            {
                const index_t e = slots[k] / 8;
                const int a = slots[k] % 8;
                element_coordinates(mesh, e, xe);
                build_sub_hex(xe, a, sh);
                vol += sh.volume;
                // facets on element faces shared with another element of the cell
                // are interior to the nodal cell: skip them
                bool use[6];
                for (int f = 0; f < 6; ++f)
                    use[f] = sh.element_face[f] < 0 || nb[6 * e + sh.element_face[f]] < 0;
                if (!sd)
                {
                    // facet by facet, as with the sub-cells (the same sums, bit for bit)
                    for (int f = 0; f < 6; ++f)
                        if (use[f])
                        {
                            facet.clear();
                            add_facet_sum(shapes, e, sh, f, facet, nodes, psi);
                            row.add(facet);
                        }
                    continue;
                }
                // with the sub-cells: every facet evaluated once, the sub-cell's row
                // from all six (as build_sd_scni), the node's from those it uses
                const std::size_t s = static_cast<std::size_t>(slots[k]);
                sub.clear();
                for (int f = 0; f < 6; ++f)
                {
                    facet.clear();
                    add_facet_sum(shapes, e, sh, f, facet, nodes, psi);
                    sub.add(facet);
                    if (use[f])
                        row.add(facet);
                }
                RKFEM_REQUIRE(sh.volume > 0.0, "SD-SCNI: sub-cell " << a << " of element " << e
                                                                    << " has non-positive volume " << sh.volume);
                sub.take(sub_entries[s], 1.0 / sh.volume);
                sub_weight[s] = sh.volume;
                const Vec3 c = sub_hex_centroid(xe, a);
                for (int d = 0; d < 3; ++d)
                    sub_position[3 * s + d] = c[d];
                sub_owner[s] = i;
            }
            RKFEM_REQUIRE(vol > 0.0, "SCNI: nodal cell of node " << i << " has non-positive volume " << vol);
            row.take(out, 1.0 / vol);
            w = vol;
            pos = mesh.node(i);
            owner = i;
        });
    if (sd)
        *sd = pack(sub_entries, std::move(sub_weight), std::move(sub_position), std::move(sub_owner));
}

void colour_elements(const HexMesh& mesh, std::vector<index_t>& offsets, std::vector<index_t>& elements)
{
    std::vector<index_t> inc_offsets, slots;
    node_element_incidence(mesh, inc_offsets, slots);
    const index_t ne = mesh.n_elements();
    std::vector<index_t> colour(static_cast<std::size_t>(ne), -1);
    std::vector<char> taken;
    index_t n_colours = 0;
    for (index_t e = 0; e < ne; ++e)
    {
        taken.assign(static_cast<std::size_t>(n_colours) + 1, 0);
        for (int a = 0; a < 8; ++a)
        {
            const index_t L = mesh.conn[8 * e + a];
            for (index_t k = inc_offsets[L]; k < inc_offsets[L + 1]; ++k)
            {
                const index_t c = colour[slots[k] / 8];
                if (c >= 0)
                    taken[static_cast<std::size_t>(c)] = 1;
            }
        }
        index_t c = 0;
        while (taken[static_cast<std::size_t>(c)])
            ++c;
        colour[e] = c;
        n_colours = std::max(n_colours, c + 1);
    }
    offsets.assign(static_cast<std::size_t>(n_colours) + 1, 0);
    for (index_t e = 0; e < ne; ++e)
        ++offsets[colour[e] + 1];
    for (index_t c = 0; c < n_colours; ++c)
        offsets[c + 1] += offsets[c];
    elements.resize(static_cast<std::size_t>(ne));
    std::vector<index_t> fill(offsets.begin(), offsets.end() - 1);
    for (index_t e = 0; e < ne; ++e)
        elements[fill[colour[e]]++] = e;
}

IntegrationOperator build_sd_scni(const HexMesh& mesh, const ShapeEvaluator& shapes)
{
    return assemble(8 * mesh.n_elements(),
                    [&](index_t p, Entries& out, real_t& w, Vec3& pos, index_t& owner, std::vector<index_t>& nodes,
                        std::vector<real_t>& psi)
                    {
                        const index_t e = p / 8;
                        const int a = p % 8;
                        SubHex sh;
                        real_t xe[8][3];
                        element_coordinates(mesh, e, xe);
                        build_sub_hex(xe, a, sh);
                        // facet by facet, as build_scni_sd sums its sub-cells (the same bits)
                        thread_local RowSum sub, facet;
                        sub.clear();
                        for (int f = 0; f < 6; ++f)
                        {
                            facet.clear();
                            add_facet_sum(shapes, e, sh, f, facet, nodes, psi);
                            sub.add(facet);
                        }
                        RKFEM_REQUIRE(sh.volume > 0.0, "SD-SCNI: sub-cell " << a << " of element " << e
                                                                            << " has non-positive volume "
                                                                            << sh.volume);
                        sub.take(out, 1.0 / sh.volume);
                        w = sh.volume;
                        pos = sub_hex_centroid(xe, a);
                        owner = mesh.conn[8 * e + a];
                    });
}

IntegrationOperator build_nodal(NodalScheme scheme, const HexMesh& mesh, const ShapeEvaluator& shapes)
{
    switch (scheme)
    {
    case NodalScheme::Dni:
        return build_dni(mesh, shapes);
    case NodalScheme::Scni:
        return build_scni(mesh, shapes);
    case NodalScheme::SdScni:
        return build_sd_scni(mesh, shapes);
    }
    return {};
}

} // namespace rkfem
