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

namespace rkfem::nodal_detail
{

/// Merges duplicate nodes (each node's contributions summed in the order they come) and sorts
/// by node; scales by `scale`. A per-thread node -> slot table does the merging in one pass, so
/// only the distinct nodes are sorted (a node's raw list holds tens of contributions per node:
/// every facet point's whole support); the sums are those of a stable sort and a sweep, bit for bit.
void merge(Entries& e, real_t scale)
{
    thread_local RowSum row;
    row.clear();
    for (const auto& [n, g] : e)
        row.add(n, g);
    row.take(e, scale);
}

void element_coordinates(const HexMesh& mesh, index_t e, real_t xe[8][3])
{
    for (int I = 0; I < 8; ++I)
        for (int d = 0; d < 3; ++d)
            xe[I][d] = mesh.x[3 * static_cast<std::size_t>(mesh.conn[8 * e + I]) + d];
}

void RowSum::take(Entries& out, real_t scale)
{
    for (const auto& [n, g] : e_)
        slot_[static_cast<std::size_t>(n)] = -1;
    std::sort(e_.begin(), e_.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    out.assign(e_.begin(), e_.end());
    for (auto& [n, g] : out)
        g *= scale;
    e_.clear();
}

void add_facet_sum(const ShapeEvaluator& shapes, index_t e, const SubHex& sh, int f, RowSum& row,
                   std::vector<index_t>& nodes, std::vector<real_t>& psi)
{
    const auto& points = sh.facets[f];
    Vec3 lo = points.front().x, hi = lo;
    for (const FacetPoint& fp : points)
    {
        lo = lo.cwiseMin(fp.x);
        hi = hi.cwiseMax(fp.x);
    }
    shapes.focus(e, lo, hi);
    for (const FacetPoint& fp : points)
    {
        shapes.values(e, fp.xi, fp.x, nodes, psi);
        for (std::size_t k = 0; k < nodes.size(); ++k)
            row.add(nodes[k], psi[k] * fp.nda);
    }
}

/// Appends a point's row to op: its nodes, their gradients (3 each), the point's end offset.
void append_row(IntegrationOperator& op, const Entries& row)
{
    for (const auto& [n, g] : row)
    {
        op.nodes.push_back(n);
        op.grad.insert(op.grad.end(), {g[0], g[1], g[2]});
    }
    op.offsets.push_back(op.n_entries());
}

/// The centroid of sub-hex a of an element: the natural centre of its octant.
Vec3 sub_hex_centroid(const real_t xe[8][3], int a)
{
    real_t N[8];
    const real_t xi[3] = {0.5 * hex8_nodes[a][0], 0.5 * hex8_nodes[a][1], 0.5 * hex8_nodes[a][2]};
    hex8_shape(xi, N);
    Vec3 pos = Vec3::Zero();
    for (int I = 0; I < 8; ++I)
        pos += N[I] * Vec3(xe[I][0], xe[I][1], xe[I][2]);
    return pos;
}

/// The operator of per-point merged entry lists (freed as they are copied).
IntegrationOperator pack(std::vector<Entries>& entries, std::vector<real_t> weight, std::vector<real_t> position,
                         std::vector<index_t> owner)
{
    IntegrationOperator op;
    op.weight = std::move(weight);
    op.position = std::move(position);
    op.owner = std::move(owner);
    op.offsets.assign(1, 0);
    std::size_t total = 0;
    for (const auto& e : entries)
        total += e.size();
    op.nodes.reserve(total);
    op.grad.reserve(3 * total);
    op.offsets.reserve(entries.size() + 1);
    for (auto& e : entries)
    {
        append_row(op, e);
        Entries().swap(e); // free as we go
    }
    return op;
}
/// Evaluates the functions at x and adds psi n dA over the current candidates k into the flat
/// sums (g[k], g[n + k], g[2 n + k]) and kept into hit[k] (n = values.size()).
void add_point_values(RkRegionValues& values, const Vec3& x, const Vec3& nda, real_t* g, real_t* hit)
{
    values.evaluate(x);
    const std::size_t n = values.size();
    const real_t n0 = nda[0], n1 = nda[1], n2 = nda[2];
    const real_t *psi = values.psi(), *kept = values.kept();
    real_t *g0 = g, *g1 = g + n, *g2 = g + 2 * n;
    RKFEM_SIMD()
    for (std::size_t k = 0; k < n; ++k)
    {
        g0[k] += psi[k] * n0;
        g1[k] += psi[k] * n1;
        g2[k] += psi[k] * n2;
        hit[k] = hit[k] < kept[k] ? kept[k] : hit[k];
    }
}

} // namespace rkfem::nodal_detail
