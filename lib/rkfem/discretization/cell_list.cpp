#include "rkfem/discretization/cell_list.hpp"

#include <algorithm>
#include <cmath>

#include "rkfem/core/error.hpp"

namespace rkfem
{
CellList::CellList(const std::vector<real_t>& x, real_t cell_size) : h_(cell_size)
{
    RKFEM_REQUIRE(cell_size > 0.0, "cell list: cell size must be positive, got " << cell_size);
    const index_t n = static_cast<index_t>(x.size() / 3);
    Vec3 hi = Vec3::Constant(-1e300);
    lo_ = Vec3::Constant(1e300);
    for (index_t i = 0; i < n; ++i)
        for (int d = 0; d < 3; ++d)
        {
            lo_[d] = std::min(lo_[d], x[3 * i + d]);
            hi[d] = std::max(hi[d], x[3 * i + d]);
        }
    if (n == 0)
        lo_ = hi = Vec3::Zero();
    std::size_t n_bins = 1;
    for (int d = 0; d < 3; ++d)
    {
        const real_t span = (hi[d] - lo_[d]) / h_;
        RKFEM_REQUIRE(span < 1e6, "cell list: " << span << " bins along axis " << d
                                                 << "; the cell size " << h_ << " m is too small for the cloud");
        dims_[d] = std::max(1, static_cast<int>(std::floor(span)) + 1);
        n_bins *= static_cast<std::size_t>(dims_[d]);
    }
    std::vector<index_t> bin(static_cast<std::size_t>(n));
    offsets_.assign(n_bins + 1, 0);
    for (index_t i = 0; i < n; ++i)
    {
        int c[3];
        for (int d = 0; d < 3; ++d)
            c[d] = std::clamp(static_cast<int>((x[3 * i + d] - lo_[d]) / h_), 0, dims_[d] - 1);
        bin[i] = static_cast<index_t>((static_cast<std::size_t>(c[2]) * dims_[1] + c[1]) * dims_[0] + c[0]);
        ++offsets_[bin[i] + 1];
    }
    for (std::size_t b = 0; b < n_bins; ++b)
        offsets_[b + 1] += offsets_[b];
    ids_.resize(static_cast<std::size_t>(n));
    std::vector<index_t> fill(offsets_.begin(), offsets_.end() - 1);
    for (index_t i = 0; i < n; ++i)
        ids_[fill[bin[i]]++] = i;
}
} // namespace rkfem
