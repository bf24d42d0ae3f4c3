/// @file rk_region_gradients.cpp
/// The region evaluator's gradients and second derivatives (RkRegionValues::evaluate_gradients,
/// hessians), from the kernel slopes and the moment matrix's derivatives.
// GCC 12 reports a false "may be used uninitialized" inside Eigen's fixed-size LDL^T (as in
// rk_shape.cpp); every value is initialised.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

#include "rkfem/approximation/rk/rk_region_values.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "rkfem/approximation/rk/rk_basis.hpp"
#include "rkfem/core/simd.hpp"

#include "rkfem/approximation/rk/rk_region_detail.hpp"
#include "rkfem/core/parallel.hpp"

namespace rkfem
{
using namespace rk_region_detail;

void RkRegionValues::evaluate_gradients(const Vec3& x)
{
    (this->*slopes_)(x);
    if (checked_basis_size(x) == 4)
        gradients_linear(x);
    else
        gradients_quadratic(x);
}

/// Order 1: M and dM_i = sum phi (dH_i H^T + H dH_i^T) + dphi_i H H^T (dH_i = e_{1+i} / s, so
/// the first part is e_{1+i} m0^T + m0 e_{1+i}^T over s with m0 = M e_0) from the sums;
/// b = M^-1 e_0, db_i = -M^-1 dM_i b; grad_i Psi_k = phi_k (db_i . H_k + b_{1+i} / s) + dphi_ki b . H_k.
void RkRegionValues::gradients_linear(const Vec3& x)
{
    const real_t inv_s = 1.0 / a_min_;
    const Eigen::Matrix4d M = scaled_moments(sum_, inv_s);
    const Ldlt4 ldlt = factor_moments(rk_, x, n_cover_, M);
    const Eigen::Vector4d b = ldlt.solve(Eigen::Vector4d(1.0, 0.0, 0.0, 0.0));
    const real_t c[4] = {b[0], b[1] * inv_s, b[2] * inv_s, b[3] * inv_s};
    real_t e[3][4];
    linear_gradient_coefficients(M, ldlt, b, slope_sum_, inv_s, e);
    const std::size_t n = ids_.size();
    const real_t *dx = dx_.data(), *dy = dy_.data(), *dz = dz_.data(), *phi = phi_.data();
    const real_t *q0 = dphi_[0].data(), *q1 = dphi_[1].data(), *q2 = dphi_[2].data();
    real_t *psi = psi_.data(), *g0 = grad_[0].data(), *g1 = grad_[1].data(), *g2 = grad_[2].data();
    RKFEM_SIMD()
    for (std::size_t k = 0; k < n; ++k)
        linear_value_gradient(c, e, phi[k], q0[k], q1[k], q2[k], dx[k], dy[k], dz[k], psi[k], g0[k], g1[k], g2[k]);
}

/// Order 2: solve_and_fill's sums, one candidate at a time.
void RkRegionValues::gradients_quadratic(const Vec3& x)
{
    using Mat10 = Eigen::Matrix<real_t, 10, 10>;
    using Vec10 = Eigen::Matrix<real_t, 10, 1>;
    const real_t inv_s = 1.0 / a_min_;
    const std::size_t n = ids_.size();
    Mat10 M = Mat10::Zero(), dM[3] = {Mat10::Zero(), Mat10::Zero(), Mat10::Zero()};
    Vec10 H, dH[3];
    for (std::size_t k = 0; k < n; ++k)
        if (phi_[k] > 0.0)
        {
            rk_detail::basis<10>(Vec3(dx_[k], dy_[k], dz_[k]) * inv_s, H, dH);
            M.noalias() += phi_[k] * H * H.transpose();
            for (int i = 0; i < 3; ++i)
            {
                const Vec10 Hi = dH[i] * inv_s;
                dM[i].noalias() +=
                    phi_[k] * (Hi * H.transpose() + H * Hi.transpose()) + dphi_[i][k] * H * H.transpose();
            }
        }
    const Eigen::LDLT<Mat10> ldlt(M);
    if (!pivots_ok<10>(ldlt))
        rk_.throw_singular(x, static_cast<index_t>(n_cover_), "pivot ratio below 1e-12");
    Vec10 e0 = Vec10::Zero();
    e0[0] = 1.0;
    const Vec10 b = ldlt.solve(e0);
    Vec10 db[3];
    for (int i = 0; i < 3; ++i)
        db[i] = -ldlt.solve(dM[i] * b);
    for (std::size_t k = 0; k < n; ++k)
    {
        psi_[k] = 0.0;
        for (int i = 0; i < 3; ++i)
            grad_[i][k] = 0.0;
        if (phi_[k] > 0.0)
        {
            rk_detail::basis<10>(Vec3(dx_[k], dy_[k], dz_[k]) * inv_s, H, dH);
            const real_t bH = b.dot(H);
            psi_[k] = bH * phi_[k];
            for (int i = 0; i < 3; ++i)
                grad_[i][k] = phi_[k] * (db[i].dot(H) + inv_s * b.dot(dH[i])) + dphi_[i][k] * bH;
        }
    }
}

void RkRegionValues::hessians(const Vec3& x, std::vector<index_t>& nodes, std::vector<Mat3>& H)
{
    // every particle covering a point within 1e-3 of the largest radius of x
    const Vec3 reach = hessian_reach(rk_);
    gather(x - reach, x + reach);
    hessians_in_region(x, nodes, H);
}

void RkRegionValues::hessians(const Vec3& x, const index_t* region, std::size_t n, std::vector<index_t>& nodes,
                              std::vector<Mat3>& H)
{
    gather(region, n);
    hessians_in_region(x, nodes, H);
}

void RkRegionValues::hessians_in_region(const Vec3& x, std::vector<index_t>& nodes, std::vector<Mat3>& H)
{
    // the functions at x itself: the same checks as the twin's evaluate there, and the radius
    values_at(x);
    const real_t delta = 1e-3 * a_min_;
    const std::size_t n = ids_.size();
    hess_.assign(9 * n, 0.0); // [candidate][row i][column j]
    hit_.assign(n, 0.0);
    for (int j = 0; j < 3; ++j)
        for (int side = 0; side < 2; ++side)
        {
            Vec3 xs = x;
            xs[j] += side == 0 ? delta : -delta;
            evaluate_gradients(xs);
            // column j is (grad Psi(x + delta e_j) - grad Psi(x - delta e_j)) / (2 delta)
            const real_t f = (side == 0 ? 1.0 : -1.0) / (2.0 * delta);
            for (std::size_t k = 0; k < n; ++k)
            {
                for (int i = 0; i < 3; ++i)
                    hess_[9 * k + 3 * i + j] += f * grad_[i][k];
                hit_[k] = larger(hit_[k], kept_[k]);
            }
        }
    nodes.clear();
    H.clear();
    for (std::size_t k = 0; k < n; ++k)
        if (hit_[k] != 0.0)
        {
            Mat3 h;
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    h(i, j) = hess_[9 * k + 3 * i + j];
            nodes.push_back(ids_[k]);
            H.push_back(0.5 * (h + h.transpose())); // the exact Hessian is symmetric
        }
}
} // namespace rkfem
