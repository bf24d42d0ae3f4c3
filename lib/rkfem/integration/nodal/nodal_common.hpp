#pragma once
/// @file nodal_common.hpp
/// What the nodal integration builders share (internal to integration/nodal/): per-point entry
/// lists (node, gradient coefficients), their merging, the facet sums of a sub-hex, and the
/// packing of per-point lists into an IntegrationOperator in point order.
#include <utility>
#include <vector>

#include <omp.h>

#include "rkfem/approximation/rk/rk_region_values.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/setup_progress.hpp"
#include "rkfem/integration/nodal/nodal_integration.hpp"

namespace rkfem::nodal_detail
{
/// One point's row: (node, gradient coefficients) per entry.
using Entries = std::vector<std::pair<index_t, Vec3>>;

/// Merges duplicate nodes (each node's contributions summed in the order they come), sorts by
/// node and scales by `scale`.
void merge(Entries& e, real_t scale);
void element_coordinates(const HexMesh& mesh, index_t e, real_t xe[8][3]);
/// A row summed as its contributions come (node -> its entry through a slot table), so the raw
/// contributions (every facet point times every function there) are never stored: each node's
/// terms are added in the order they come, as merge adds them. One per thread; the slot table
/// grows to the largest node id seen and is clear again after take() or clear().
class RowSum
{
  public:
    void add(index_t node, const Vec3& g)
    {
        if (static_cast<std::size_t>(node) >= slot_.size())
            slot_.resize(static_cast<std::size_t>(node) + 1, -1);
        index_t& k = slot_[static_cast<std::size_t>(node)];
        if (k < 0)
        {
            k = static_cast<index_t>(e_.size());
            e_.emplace_back(node, g);
        }
        else
            e_[static_cast<std::size_t>(k)].second += g;
    }
    void add(const RowSum& other)
    {
        for (const auto& [n, g] : other.e_)
            add(n, g);
    }
    void clear()
    {
        for (const auto& [n, g] : e_)
            slot_[static_cast<std::size_t>(n)] = -1;
        e_.clear();
    }
    /// The row, sorted by node and scaled, into `out` (replacing it); the sum is clear again.
    void take(Entries& out, real_t scale);

  private:
    std::vector<index_t> slot_;
    Entries e_;
};
/// Adds sum_q Psi(x_q) n dA_q over facet f of sub-hex `sh` in element e to `row` (the facet's
/// box handed to shapes.focus first).
void add_facet_sum(const ShapeEvaluator& shapes, index_t e, const SubHex& sh, int f, RowSum& row,
                   std::vector<index_t>& nodes, std::vector<real_t>& psi);
/// Appends a point's row to op: its nodes, their gradients (3 each), the point's end offset.
void append_row(IntegrationOperator& op, const Entries& row);
/// The centroid of sub-hex a of an element: the natural centre of its octant.
Vec3 sub_hex_centroid(const real_t xe[8][3], int a);
/// Evaluates the functions at x and adds psi n dA over the current candidates k into the flat
/// sums (g[k], g[n + k], g[2 n + k]) and kept into hit[k] (n = values.size()).
void add_point_values(RkRegionValues& values, const Vec3& x, const Vec3& nda, real_t* g, real_t* hit);
/// The operator of per-point merged entry lists (freed as they are copied).
IntegrationOperator pack(std::vector<Entries>& entries, std::vector<real_t> weight, std::vector<real_t> position,
                         std::vector<index_t> owner);

/// Builds an operator from per-point entry lists (parallel over points, concatenated in order),
/// each point a set-up progress item where `progress`.
template <class PointFn> IntegrationOperator assemble(index_t n_points, PointFn&& fn, bool progress = true)
{
    std::vector<Entries> entries(static_cast<std::size_t>(n_points));
    std::vector<real_t> weight(static_cast<std::size_t>(n_points)), position(3 * static_cast<std::size_t>(n_points));
    std::vector<index_t> owner(static_cast<std::size_t>(n_points));
    ParallelErrors errors;
#pragma omp parallel
    {
        std::vector<index_t> nodes;
        std::vector<real_t> psi;
        // the raw facet contributions (every facet point times every node of its support,
        // tens of times the merged count) go to one scratch list per thread; each point keeps
        // an exactly sized copy of its merged entries
        Entries scratch;
#pragma omp for schedule(dynamic, 64)
        for (index_t p = 0; p < n_points; ++p)
        {
            try
            {
                Vec3 pos;
                scratch.clear();
                fn(p, scratch, weight[p], pos, owner[p], nodes, psi);
                entries[p].assign(scratch.begin(), scratch.end());
                for (int d = 0; d < 3; ++d)
                    position[3 * p + d] = pos[d];
                if (progress)
                    setup_progress::advance();
            }
            catch (...)
            {
                errors.capture();
            }
        }
    }
    errors.rethrow(); // the first failure, with its type (SingularMomentError)
    return pack(entries, std::move(weight), std::move(position), std::move(owner));
}

} // namespace rkfem::nodal_detail
