#pragma once
/// @file cell_list.hpp
/// Uniform-bin neighbour search over a point cloud: points are binned into cubes of side
/// `cell_size` (>= the largest search radius), and a query visits the 27 bins around a point.
/// Bins are a CSR (bin -> point ids, ascending), so a query returns candidates in a fixed order.
#include <algorithm>
#include <vector>

#include "rkfem/core/parallel.hpp"
#include "rkfem/core/types.hpp"

namespace rkfem
{
class CellList
{
  public:
    CellList() = default;
    /// `x` is n x 3 node-major; cell_size > 0.
    CellList(const std::vector<real_t>& x, real_t cell_size);

    /// Calls f(j) for every point j in the 27 bins around p (a superset of the points within
    /// cell_size of p), bins in a fixed order.
    template <class F> void for_each_candidate(const Vec3& p, F&& f) const
    {
        int c[3];
        for (int d = 0; d < 3; ++d)
            c[d] = bin_coord(p[d], d);
        for (int k = c[2] - 1; k <= c[2] + 1; ++k)
        {
            if (k < 0 || k >= dims_[2])
                continue;
            for (int j = c[1] - 1; j <= c[1] + 1; ++j)
            {
                if (j < 0 || j >= dims_[1])
                    continue;
                for (int i = c[0] - 1; i <= c[0] + 1; ++i)
                {
                    if (i < 0 || i >= dims_[0])
                        continue;
                    const std::size_t b = (static_cast<std::size_t>(k) * dims_[1] + j) * dims_[0] + i;
                    for (index_t q = offsets_[b]; q < offsets_[b + 1]; ++q)
                        f(ids_[q]);
                }
            }
        }
    }

    /// Calls f(j) for every point j in the bins that meet the box [lo - cell_size, hi +
    /// cell_size] (a superset of the points within cell_size of the box along every axis), bins
    /// in a fixed order, each point once.
    template <class F> void for_each_near_box(const Vec3& lo, const Vec3& hi, F&& f) const
    {
        for_each_run_near_box(lo, hi,
                              [&](index_t q0, index_t q1)
                              {
                                  for (index_t q = q0; q < q1; ++q)
                                      f(ids_[q]);
                              });
    }
    /// The same bins as for_each_near_box, as runs of the bins' order: f(q0, q1) for each row of
    /// bins along the first axis, whose points are ids()[q0 .. q1) (bins in a fixed order).
    template <class F> void for_each_run_near_box(const Vec3& lo, const Vec3& hi, F&& f) const
    {
        int c0[3], c1[3];
        for (int d = 0; d < 3; ++d)
        {
            c0[d] = clamped_bin(lo[d] - h_, d);
            c1[d] = clamped_bin(hi[d] + h_, d);
        }
        for (int k = c0[2]; k <= c1[2]; ++k)
            for (int j = c0[1]; j <= c1[1]; ++j)
            {
                const std::size_t b = (static_cast<std::size_t>(k) * dims_[1] + j) * dims_[0];
                f(offsets_[b + c0[0]], offsets_[b + c1[0] + 1]);
            }
    }
    /// The points in bin order (each bin's ascending).
    const std::vector<index_t>& ids() const { return ids_; }
    real_t cell_size() const { return h_; }

  private:
    int bin_coord(real_t v, int d) const
    {
        const real_t t = (v - lo_[d]) / h_;
        if (t < 0)
            return -1 - static_cast<int>(std::min<real_t>(-t, 1.0)); // -1 or -2: outside
        const real_t m = static_cast<real_t>(dims_[d]);
        return t >= m ? dims_[d] + static_cast<int>(std::min<real_t>(t - m, 1.0)) : static_cast<int>(t);
    }
    /// The bin a point at v would be binned in (clamped into the grid, as the points are).
    int clamped_bin(real_t v, int d) const
    {
        const real_t t = std::clamp<real_t>((v - lo_[d]) / h_, 0.0, static_cast<real_t>(dims_[d] - 1));
        return static_cast<int>(t);
    }
    Vec3 lo_ = Vec3::Zero();
    real_t h_ = 1.0;
    int dims_[3] = {0, 0, 0};
    std::vector<index_t> offsets_, ids_;
};

/// Neighbour rows over the n points of `x` (n x 3) that a cell list of them holds: row i is every
/// j among the 27 bins about x_i with within(i, j), ascending (ids[offsets[i] .. offsets[i + 1]));
/// counted, then filled, in parallel. The bins must be at least the largest reach `within` takes.
template <class Within>
void build_neighbour_rows(const CellList& cells, const std::vector<real_t>& x, index_t n, Within&& within,
                          std::vector<index_t>& offsets, std::vector<index_t>& ids)
{
    offsets.assign(static_cast<std::size_t>(n) + 1, 0);
    parallel_for("rkfem::neighbours::count", n,
                 [&](index_t i)
                 {
                     const Vec3 p(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
                     index_t c = 0;
                     cells.for_each_candidate(p, [&](index_t j) { c += within(i, j); });
                     offsets[static_cast<std::size_t>(i) + 1] = c;
                 });
    for (index_t i = 0; i < n; ++i)
        offsets[i + 1] += offsets[i];
    ids.resize(static_cast<std::size_t>(offsets[n]));
    // each point's candidates come in the cell list's fixed order, sorted after
    parallel_for("rkfem::neighbours::fill", n,
                 [&](index_t i)
                 {
                     const Vec3 p(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
                     index_t k = offsets[i];
                     cells.for_each_candidate(p,
                                              [&](index_t j)
                                              {
                                                  if (within(i, j))
                                                      ids[k++] = j;
                                              });
                     std::sort(ids.begin() + offsets[i], ids.begin() + offsets[i + 1]);
                 });
}

/// Neighbour lists with a skin (Verlet lists) for clouds that move: the pairs within
/// radius + skin of the positions at the last build stay a superset of the pairs within `radius`
/// until some point has moved more than skin / 2 since that build (two points then approach by
/// at most skin). update() rebuilds only then, so a Lagrangian or slowly moving cloud searches
/// once and a semi-Lagrangian one every few steps.
class NeighbourList
{
  public:
    NeighbourList(real_t radius, real_t skin);

    /// Brings the lists up to date for positions x (n x 3): rebuilds on the first call, when
    /// the number of points changes, or when a point has moved more than skin / 2 since the
    /// last build. Returns whether it rebuilt.
    bool update(const std::vector<real_t>& x);

    /// Largest displacement of a point since the last build.
    real_t max_displacement(const std::vector<real_t>& x) const;

    /// Neighbours of point i (itself included), ascending: ids()[offsets()[i] .. offsets()[i+1]).
    const std::vector<index_t>& offsets() const { return offsets_; }
    const std::vector<index_t>& ids() const { return ids_; }
    index_t rebuilds() const { return rebuilds_; }
    real_t radius() const { return radius_; }
    real_t skin() const { return skin_; }

  private:
    void build(const std::vector<real_t>& x);
    real_t radius_, skin_;
    std::vector<real_t> x_built_;
    std::vector<index_t> offsets_{0}, ids_;
    index_t rebuilds_ = 0;
};
} // namespace rkfem
