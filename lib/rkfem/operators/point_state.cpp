#include "rkfem/operators/point_state.hpp"

#include "rkfem/core/error.hpp"

namespace rkfem
{
void copy_point_state(const PointState& src, std::size_t from, const PointState& dst, std::size_t to)
{
    RKFEM_REQUIRE(from < src.n_points && to < dst.n_points, "copy_point_state: point " << from << " of " << src.n_points
                                                                                       << " to " << to << " of "
                                                                                       << dst.n_points);
    const bool src_h = src.history != nullptr && src.history->active();
    const bool dst_h = dst.history != nullptr && dst.history->active();
    RKFEM_REQUIRE(src_h == dst_h && (!src_h || src.history->kind == dst.history->kind),
                  "copy_point_state: the blocks' material models differ");
    for (int k = 0; k < 6; ++k)
        dst.stress[k * dst.stride + to] = dst.stress_trial[k * dst.stride + to] = src.stress[k * src.stride + from];
    if (dst_h)
        dst.history->copy_point(*src.history, from, to);
}
} // namespace rkfem
