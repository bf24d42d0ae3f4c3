#include "rkfem/contact/segment_buckets.hpp"

#include <algorithm>
#include <cmath>

namespace rkfem
{
void SegmentBuckets::cell_range(index_t s, index_t (&a)[3], index_t (&b)[3]) const
{
    for (int d = 0; d < 3; ++d)
    {
        a[d] = std::clamp(static_cast<index_t>((lo_[3 * s + d] - origin_[d]) / cell_), index_t{0}, dims_[d] - 1);
        b[d] = std::clamp(static_cast<index_t>((hi_[3 * s + d] - origin_[d]) / cell_), index_t{0}, dims_[d] - 1);
    }
}

void SegmentBuckets::build(const std::vector<real_t>& lo, const std::vector<real_t>& hi, real_t margin)
{
    const index_t n = static_cast<index_t>(lo.size() / 3);
    lo_.resize(lo.size());
    hi_.resize(hi.size());
    Vec3 blo = Vec3::Constant(kNoLimit), bhi = Vec3::Constant(-kNoLimit);
    real_t mean_size = 0.0;
    for (index_t s = 0; s < n; ++s)
    {
        real_t size = 0.0;
        for (int d = 0; d < 3; ++d)
        {
            lo_[3 * s + d] = lo[3 * s + d] - margin;
            hi_[3 * s + d] = hi[3 * s + d] + margin;
            blo[d] = std::min(blo[d], lo_[3 * s + d]);
            bhi[d] = std::max(bhi[d], hi_[3 * s + d]);
            size = std::max(size, hi_[3 * s + d] - lo_[3 * s + d]);
        }
        mean_size += size;
    }
    if (n == 0)
    {
        dims_[0] = dims_[1] = dims_[2] = 0;
        offsets_.assign(1, 0);
        items_.clear();
        return;
    }
    mean_size /= static_cast<real_t>(n);
    origin_ = blo;
    const Vec3 extent = bhi - blo;
    cell_ = std::max(mean_size, 1e-12 * std::max(1.0, extent.maxCoeff()));
    // at most about 4 cells per segment (a long thin surface keeps its resolution along its length)
    for (;;)
    {
        real_t cells = 1.0;
        for (int d = 0; d < 3; ++d)
            cells *= std::floor(extent[d] / cell_) + 1.0;
        if (cells <= 4.0 * static_cast<real_t>(n) + 64.0)
            break;
        cell_ *= 1.25;
    }
    for (int d = 0; d < 3; ++d)
        dims_[d] = static_cast<index_t>(std::floor(extent[d] / cell_)) + 1;
    const index_t n_cells = dims_[0] * dims_[1] * dims_[2];
    offsets_.assign(static_cast<std::size_t>(n_cells) + 1, 0);
    index_t a[3], b[3];
    for (index_t s = 0; s < n; ++s)
    {
        cell_range(s, a, b);
        for (index_t k = a[2]; k <= b[2]; ++k)
            for (index_t j = a[1]; j <= b[1]; ++j)
                for (index_t i = a[0]; i <= b[0]; ++i)
                    ++offsets_[(k * dims_[1] + j) * dims_[0] + i + 1];
    }
    for (index_t c = 0; c < n_cells; ++c)
        offsets_[c + 1] += offsets_[c];
    items_.resize(static_cast<std::size_t>(offsets_[n_cells]));
    // fill in segment order: a cell's list is ascending, so candidates come in a fixed order
    std::vector<index_t>& fill = scratch_;
    fill.assign(offsets_.begin(), offsets_.end() - 1);
    for (index_t s = 0; s < n; ++s)
    {
        cell_range(s, a, b);
        for (index_t k = a[2]; k <= b[2]; ++k)
            for (index_t j = a[1]; j <= b[1]; ++j)
                for (index_t i = a[0]; i <= b[0]; ++i)
                    items_[fill[(k * dims_[1] + j) * dims_[0] + i]++] = s;
    }
}
} // namespace rkfem
