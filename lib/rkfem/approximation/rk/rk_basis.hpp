#pragma once
/// @file rk_basis.hpp
/// The RK basis in shifted and scaled coordinates y = (x - x_I) / s: H(y) and dH/dy_i, order 1
/// (m = 4: 1, y) or 2 (m = 10: 1, y, y_i^2, y0 y1, y1 y2, y2 y0). Shared by the pointwise
/// evaluation (rk_shape.cpp) and the region evaluation (rk_region_values.cpp).
#include <Eigen/Core>

#include "rkfem/core/types.hpp"

namespace rkfem::rk_detail
{
template <int m> inline void basis(const Vec3& y, Eigen::Matrix<real_t, m, 1>& H, Eigen::Matrix<real_t, m, 1> dH[3])
{
    for (int i = 0; i < 3; ++i)
        dH[i].setZero();
    H[0] = 1.0;
    for (int i = 0; i < 3; ++i)
    {
        H[1 + i] = y[i];
        dH[i][1 + i] = 1.0;
    }
    if constexpr (m == 10)
    {
        for (int i = 0; i < 3; ++i)
        {
            H[4 + i] = y[i] * y[i];
            dH[i][4 + i] = 2.0 * y[i];
        }
        // cross terms y0 y1, y1 y2, y2 y0
        for (int i = 0; i < 3; ++i)
        {
            const int j = (i + 1) % 3;
            H[7 + i] = y[i] * y[j];
            dH[i][7 + i] = y[j];
            dH[j][7 + i] = y[i];
        }
    }
}
} // namespace rkfem::rk_detail
