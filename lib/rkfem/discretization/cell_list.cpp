#include "rkfem/discretization/cell_list.hpp"

#include <algorithm>
#include <cmath>

#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"

namespace rkfem
{
CellList::CellList(const std::vector<real_t>& x, real_t cell_size) : h_(cell_size)
{
    RKFEM_REQUIRE(cell_size > 0.0, "cell list: cell size must be positive, got " << cell_size);
    const index_t n = static_cast<index_t>(x.size() / 3);
    Vec3 hi = Vec3::Constant(-kNoLimit);
    lo_ = Vec3::Constant(kNoLimit);
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
        RKFEM_REQUIRE(span < 1e6, "cell list: " << span << " bins along axis " << d << "; the cell size " << h_
                                                << " m is too small for the cloud");
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

NeighbourList::NeighbourList(real_t radius, real_t skin) : radius_(radius), skin_(skin)
{
    RKFEM_REQUIRE(radius > 0.0 && skin >= 0.0,
                  "neighbour list: radius must be positive and skin non-negative, got " << radius << ", " << skin);
}

real_t NeighbourList::max_displacement(const std::vector<real_t>& x) const
{
    const index_t n = static_cast<index_t>(x.size() / 3);
    const real_t d2 = -parallel_reduce_min("rkfem::neighbours::displacement", n,
                                           [&](index_t i)
                                           {
                                               real_t s = 0.0;
                                               for (int d = 0; d < 3; ++d)
                                               {
                                                   const real_t u = x[3 * i + d] - x_built_[3 * i + d];
                                                   s += u * u;
                                               }
                                               return -s;
                                           });
    return n > 0 ? std::sqrt(d2) : 0.0;
}

bool NeighbourList::update(const std::vector<real_t>& x)
{
    if (rebuilds_ > 0 && x.size() == x_built_.size() && max_displacement(x) <= 0.5 * skin_)
        return false;
    build(x);
    return true;
}

void NeighbourList::build(const std::vector<real_t>& x)
{
    const index_t n = static_cast<index_t>(x.size() / 3);
    const real_t r = radius_ + skin_, r2 = r * r;
    const CellList cells(x, r);
    auto within = [&](index_t i, index_t j)
    {
        real_t s = 0.0;
        for (int d = 0; d < 3; ++d)
        {
            const real_t u = x[3 * j + d] - x[3 * i + d];
            s += u * u;
        }
        return s < r2;
    };
    build_neighbour_rows(cells, x, n, within, offsets_, ids_);
    x_built_ = x;
    ++rebuilds_;
}
} // namespace rkfem
