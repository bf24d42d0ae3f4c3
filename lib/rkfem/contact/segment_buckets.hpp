#pragma once
/// @file segment_buckets.hpp
/// Bucket sort of contact segments on a uniform grid of cells (current positions): each segment
/// goes into every cell its bounding box, inflated by a margin, overlaps; a point's candidate
/// segments are those of its cell whose inflated box holds it. Cells are CSR (counts, offsets,
/// items); the arrays keep their capacity between builds, so a search allocates only while the
/// surface grows.
#include <vector>

#include "rkfem/core/types.hpp"

namespace rkfem
{
class SegmentBuckets
{
  public:
    /// Sorts n segments with boxes [lo, hi] (3 values each per segment), inflated by `margin`.
    /// The cell size follows the mean inflated box, enlarged so that there are at most about
    /// 4 cells per segment.
    void build(const std::vector<real_t>& lo, const std::vector<real_t>& hi, real_t margin);

    /// Calls f(segment) for every segment whose inflated box holds p (each once).
    template <class F> void for_candidates(const Vec3& p, F&& f) const
    {
        index_t c[3];
        for (int d = 0; d < 3; ++d)
        {
            const real_t s = (p[d] - origin_[d]) / cell_;
            if (!(s >= 0.0) || s >= static_cast<real_t>(dims_[d]))
                return;
            c[d] = static_cast<index_t>(s);
        }
        const index_t cell = (c[2] * dims_[1] + c[1]) * dims_[0] + c[0];
        for (index_t k = offsets_[cell]; k < offsets_[cell + 1]; ++k)
        {
            const index_t s = items_[k];
            bool in = true;
            for (int d = 0; d < 3 && in; ++d)
                in = p[d] >= lo_[3 * s + d] && p[d] <= hi_[3 * s + d];
            if (in)
                f(s);
        }
    }
    index_t n_cells() const { return dims_[0] * dims_[1] * dims_[2]; }

  private:
    Vec3 origin_ = Vec3::Zero();
    real_t cell_ = 1.0;
    index_t dims_[3] = {0, 0, 0};
    std::vector<real_t> lo_, hi_; ///< inflated boxes
    std::vector<index_t> offsets_, items_;
    std::vector<index_t> scratch_; ///< fill cursors of build()
    void cell_range(index_t s, index_t (&a)[3], index_t (&b)[3]) const;
};
} // namespace rkfem
