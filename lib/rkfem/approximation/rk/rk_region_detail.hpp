#pragma once
/// @file rk_region_detail.hpp
/// What the region evaluator's two files share (internal to approximation/rk/): the kernel windows
/// and their slopes, the moment sums, the 4x4 LDL^T of the linear basis' moment matrix.
// GCC 12 reports a false "may be used uninitialized" inside Eigen's fixed-size LDL^T (as in
// rk_shape.cpp); every value is initialised.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

#include "rkfem/approximation/rk/rk_region_values.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "rkfem/approximation/rk/rk_basis.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/simd.hpp"

namespace rkfem::rk_region_detail
{
/// phi(z) of kernel_1d, written without branches for the cubic B-spline (the default) so that
/// the candidate loop vectorizes; the same expressions, so the same values.
template <KernelType K> inline real_t window(real_t z)
{
    if constexpr (K == KernelType::CubicBSpline)
    {
        const real_t t = 1.0 - z;
        const real_t inner = 2.0 / 3.0 - 4.0 * z * z + 4.0 * z * z * z;
        const real_t outer = 4.0 / 3.0 * t * t * t;
        return z <= 0.5 ? inner : (z < 1.0 ? outer : 0.0);
    }
    else
    {
        real_t phi = 0.0, dphi = 0.0;
        kernel_1d(K, z, phi, dphi);
        return phi;
    }
}

/// phi(z) and phi'(z) of kernel_1d, branch-free for the cubic B-spline (as window).
template <KernelType K> inline void window_slope(real_t z, real_t& phi, real_t& dphi)
{
    if constexpr (K == KernelType::CubicBSpline)
    {
        const real_t t = 1.0 - z;
        const real_t inner = 2.0 / 3.0 - 4.0 * z * z + 4.0 * z * z * z;
        const real_t outer = 4.0 / 3.0 * t * t * t;
        const real_t d_inner = -8.0 * z + 12.0 * z * z;
        const real_t d_outer = -4.0 * t * t;
        const bool near = z <= 0.5, in = z < 1.0;
        phi = near ? inner : (in ? outer : 0.0);
        dphi = near ? d_inner : (in ? d_outer : 0.0);
    }
    else
        kernel_1d(K, z, phi, dphi);
}

/// The kernel of a particle at offset d = x - x_k with 1 / radius inv_a: its value (kernel_3d's,
/// in the loops' branch-free form; 0 outside the support, and where the truncated Gaussian rounds
/// to <= 0 at the edge the caller tests phi > 0).
template <KernelType K, SupportShape S>
RKFEM_LANE_INLINE real_t window_at(real_t d0, real_t d1, real_t d2, real_t inv_a)
{
    if constexpr (S == SupportShape::Box)
        return window<K>(std::abs(d0) * inv_a) * window<K>(std::abs(d1) * inv_a) * window<K>(std::abs(d2) * inv_a);
    else
        return window<K>(std::sqrt(d0 * d0 + d1 * d1 + d2 * d2) * inv_a);
}

/// window_at and its gradient d phi / dx (kernel_3d's product: phi = p0 p1 p2, grad = (q0 p1 p2,
/// p0 q1 p2, p0 p1 q2) on a box; phi'(r / a) d / (a r) on a sphere).
template <KernelType K, SupportShape S>
RKFEM_LANE_INLINE void window_gradient_at(real_t d0, real_t d1, real_t d2, real_t inv_a, real_t& phi, real_t& g0,
                                          real_t& g1, real_t& g2)
{
    if constexpr (S == SupportShape::Box)
    {
        real_t p0, p1, p2, q0, q1, q2;
        window_slope<K>(std::abs(d0) * inv_a, p0, q0);
        window_slope<K>(std::abs(d1) * inv_a, p1, q1);
        window_slope<K>(std::abs(d2) * inv_a, p2, q2);
        q0 *= d0 < 0 ? -inv_a : inv_a;
        q1 *= d1 < 0 ? -inv_a : inv_a;
        q2 *= d2 < 0 ? -inv_a : inv_a;
        phi = p0 * p1 * p2;
        g0 = q0 * p1 * p2;
        g1 = p0 * q1 * p2;
        g2 = p0 * p1 * q2;
    }
    else
    {
        const real_t r = std::sqrt(d0 * d0 + d1 * d1 + d2 * d2);
        real_t q;
        window_slope<K>(r * inv_a, phi, q);
        const real_t f = r > 0.0 ? q * inv_a / r : 0.0; // phi'(0) = 0 for every kernel
        g0 = f * d0;
        g1 = f * d1;
        g2 = f * d2;
    }
}

/// The order-1 moment sums of one candidate with weight w at offset d: sum w, sum w d_i,
/// sum w d_i d_j (i <= j), in scalars the candidate loops reduce over (inlined, so the loops
/// still vectorize).
RKFEM_LANE_INLINE void add_moments(real_t w, real_t d0, real_t d1, real_t d2, real_t& m0, real_t& m1, real_t& m2,
                                   real_t& m3, real_t& m11, real_t& m12, real_t& m13, real_t& m22, real_t& m23,
                                   real_t& m33)
{
    m0 += w;
    m1 += w * d0;
    m2 += w * d1;
    m3 += w * d2;
    m11 += w * d0 * d0;
    m12 += w * d0 * d1;
    m13 += w * d0 * d2;
    m22 += w * d1 * d1;
    m23 += w * d1 * d2;
    m33 += w * d2 * d2;
}

/// std::max's rule by value (std::max returns a reference, which keeps GCC from vectorizing
/// a loop that takes the maximum of loaded values)
inline real_t larger(real_t a, real_t b)
{
    return a < b ? b : a;
}

/// The symmetric 4 x 4 matrix of order-1 sums (sum w, sum w d_i, sum w d_i d_j) in the scaled
/// basis H = (1, d / s): entries scaled by 1, 1 / s, 1 / s^2.
inline Eigen::Matrix4d scaled_moments(const real_t sums[10], real_t inv_s)
{
    const real_t i2 = inv_s * inv_s;
    Eigen::Matrix4d M;
    M(0, 0) = sums[0];
    for (int i = 0; i < 3; ++i)
        M(0, 1 + i) = M(1 + i, 0) = inv_s * sums[1 + i];
    M(1, 1) = i2 * sums[4];
    M(1, 2) = M(2, 1) = i2 * sums[5];
    M(1, 3) = M(3, 1) = i2 * sums[6];
    M(2, 2) = i2 * sums[7];
    M(2, 3) = M(3, 2) = i2 * sums[8];
    M(3, 3) = i2 * sums[9];
    return M;
}

/// LDL^T of a symmetric 4 x 4 with symmetric pivoting on the largest remaining diagonal, as
/// Eigen::LDLT does it (the same pivots, so evaluate's test on them holds the same), written out:
/// Eigen's general LDL^T was a large share of the set-up at this size. The pivoting permutes an
/// index (perm_: position -> row of M) instead of moving rows and columns: the same operations on
/// the same values as the swaps, without the stores (which GCC vectorized into scatters). Its
/// factorization and solve are scalar code (RKFEM_SCALAR_CODE): vectorized, the solve's permuted
/// stores became stack scatters, and the set-up of the P1 cylinder took longer
/// (measurements: docs/performance.md).
class Ldlt4
{
  public:
    RKFEM_SCALAR_CODE explicit Ldlt4(const Eigen::Matrix4d& M)
    {
        real_t A[4][4]; // M's rows and columns, addressed through perm_
        for (int i = 0; i < 4; ++i)
        {
            perm_[i] = i;
            for (int j = 0; j < 4; ++j)
                A[i][j] = M(i, j);
        }
        for (int k = 0; k < 4; ++k)
        {
            int p = k;
            for (int i = k + 1; i < 4; ++i)
                if (std::abs(A[perm_[i]][perm_[i]]) > std::abs(A[perm_[p]][perm_[p]]))
                    p = i;
            if (p != k)
            {
                std::swap(perm_[k], perm_[p]);
                for (int j = 0; j < k; ++j)
                    std::swap(L_[k][j], L_[p][j]);
            }
            const int rk = perm_[k];
            D_[k] = A[rk][rk];
            for (int i = k + 1; i < 4; ++i)
                L_[i][k] = A[perm_[i]][rk] / D_[k];
            for (int i = k + 1; i < 4; ++i)
            {
                const int ri = perm_[i];
                for (int j = k + 1; j <= i; ++j)
                {
                    const int rj = perm_[j];
                    A[rj][ri] = A[ri][rj] -= L_[i][k] * A[rk][rj];
                }
            }
        }
    }
    /// evaluate's test: every pivot above 1e-12 of the largest in magnitude
    bool pivots_ok() const { return pivots_above(1e-12); }
    /// Every pivot above `ratio` times the largest in magnitude (false on a NaN pivot).
    bool pivots_above(real_t ratio) const
    {
        real_t big = 0.0;
        for (const real_t d : D_)
            big = std::max(big, std::abs(d));
        for (const real_t d : D_)
            if (!(d > ratio * big))
                return false;
        return true;
    }
    RKFEM_SCALAR_CODE Eigen::Vector4d solve(const Eigen::Vector4d& b) const
    {
        real_t y[4];
        for (int k = 0; k < 4; ++k)
            y[k] = b[perm_[k]];
        for (int i = 1; i < 4; ++i)
            for (int j = 0; j < i; ++j)
                y[i] -= L_[i][j] * y[j];
        for (int i = 0; i < 4; ++i)
            y[i] /= D_[i];
        for (int i = 2; i >= 0; --i)
            for (int j = i + 1; j < 4; ++j)
                y[i] -= L_[j][i] * y[j];
        Eigen::Vector4d x;
        for (int k = 0; k < 4; ++k)
            x[perm_[k]] = y[k];
        return x;
    }

  private:
    real_t L_[4][4] = {}, D_[4] = {};
    int perm_[4] = {};
};

/// Order 1's gradient coefficients (RkRegionValues::gradients_linear's algebra): with M's scaled
/// sums, its factors, b = M^-1 e_0 and the window gradients' sums t_i (add_moments' order),
/// dM_i = t_i + (e_{1+i} m0^T + m0 e_{1+i}^T) / s (m0 = M e_0: the basis' own derivative),
/// db_i = -M^-1 dM_i b, and e_i = (db_i0 + b_{1+i} / s, db_i1 / s, db_i2 / s, db_i3 / s), so that
/// grad_i Psi_k = phi_k (e_i0 + e_i1 d0 + e_i2 d1 + e_i3 d2) + dphi_ki b.H_k (linear_value_gradient).
inline void linear_gradient_coefficients(const Eigen::Matrix4d& M, const Ldlt4& ldlt, const Eigen::Vector4d& b,
                                         const real_t (&slope_sums)[3][10], real_t inv_s, real_t (&e)[3][4])
{
    const Eigen::Vector4d m0 = M.col(0) * inv_s;
    for (int i = 0; i < 3; ++i)
    {
        Eigen::Matrix4d dM = scaled_moments(slope_sums[i], inv_s);
        dM.row(1 + i) += m0.transpose();
        dM.col(1 + i) += m0;
        const Eigen::Vector4d db = -ldlt.solve(dM * b);
        e[i][0] = db[0] + b[1 + i] * inv_s; // + b . dH_i / s, constant for order 1
        for (int j = 1; j < 4; ++j)
            e[i][j] = db[j] * inv_s;
    }
}

/// One candidate's order-1 value and gradient at offset d from its window phi and the window's
/// gradient q: c = (b_0, b_1 / s, b_2 / s, b_3 / s), e from linear_gradient_coefficients.
RKFEM_LANE_INLINE void linear_value_gradient(const real_t (&c)[4], const real_t (&e)[3][4], real_t phi, real_t q0,
                                             real_t q1, real_t q2, real_t d0, real_t d1, real_t d2, real_t& psi,
                                             real_t& g0, real_t& g1, real_t& g2)
{
    const real_t bH = c[0] + c[1] * d0 + c[2] * d1 + c[3] * d2;
    psi = phi * bH;
    g0 = phi * (e[0][0] + e[0][1] * d0 + e[0][2] * d1 + e[0][3] * d2) + q0 * bH;
    g1 = phi * (e[1][0] + e[1][1] * d0 + e[1][2] * d1 + e[1][3] * d2) + q1 * bH;
    g2 = phi * (e[2][0] + e[2][1] * d0 + e[2][2] * d1 + e[2][3] * d2) + q2 * bH;
}

/// evaluate's pivot test on an Eigen LDL^T: every pivot above 1e-12 of the largest in magnitude
template <int m> inline bool pivots_ok(const Eigen::LDLT<Eigen::Matrix<real_t, m, m>>& ldlt)
{
    const auto D = ldlt.vectorD();
    return ldlt.info() == Eigen::Success && D.minCoeff() > 1e-12 * D.cwiseAbs().maxCoeff();
}

/// LDL^T of a moment matrix with evaluate's pivot test; b = M^-1 e_0.
template <int m> inline bool solve_moments(const Eigen::Matrix<real_t, m, m>& M, Eigen::Matrix<real_t, m, 1>& b)
{
    const Eigen::LDLT<Eigen::Matrix<real_t, m, m>> ldlt(M);
    if (!pivots_ok<m>(ldlt))
        return false;
    Eigen::Matrix<real_t, m, 1> e0 = Eigen::Matrix<real_t, m, 1>::Zero();
    e0[0] = 1.0;
    b = ldlt.solve(e0);
    return true;
}
/// The order-1 moment matrix M factored, with solve_moments' pivot test: a failed test names
/// x and its covering count, as RkShapeFunctions::evaluate does.
inline Ldlt4 factor_moments(const RkShapeFunctions& rk, const Vec3& x, real_t n_cover, const Eigen::Matrix4d& M)
{
    Ldlt4 ldlt(M);
    if (!ldlt.pivots_ok())
        rk.throw_singular(x, static_cast<index_t>(n_cover), "pivot ratio below 1e-12");
    return ldlt;
}
} // namespace rkfem::rk_region_detail

namespace rkfem
{
using namespace rk_region_detail;

template <KernelType K, SupportShape S> void RkRegionValues::slopes(const Vec3& x)
{
    const std::size_t n = ids_.size();
    const real_t x0 = x[0], x1 = x[1], x2 = x[2];
    const real_t *px = px_.data(), *py = py_.data(), *pz = pz_.data(), *ia = inv_a_.data(), *ra = a_.data();
    real_t *dx = dx_.data(), *dy = dy_.data(), *dz = dz_.data(), *phi_out = phi_.data(), *kept = kept_.data();
    real_t *g0_out = dphi_[0].data(), *g1_out = dphi_[1].data(), *g2_out = dphi_[2].data();
    real_t s0 = 0, s1 = 0, s2 = 0, s3 = 0, s11 = 0, s12 = 0, s13 = 0, s22 = 0, s23 = 0, s33 = 0;
    // t[i][.]: the same sums with the window's gradient component i in place of the window
    real_t t00 = 0, t01 = 0, t02 = 0, t03 = 0, t011 = 0, t012 = 0, t013 = 0, t022 = 0, t023 = 0, t033 = 0;
    real_t t10 = 0, t11 = 0, t12 = 0, t13 = 0, t111 = 0, t112 = 0, t113 = 0, t122 = 0, t123 = 0, t133 = 0;
    real_t t20 = 0, t21 = 0, t22 = 0, t23 = 0, t211 = 0, t212 = 0, t213 = 0, t222 = 0, t223 = 0, t233 = 0;
    real_t count = 0, a_min = std::numeric_limits<real_t>::infinity();
    RKFEM_SIMD(reduction(+ : s0, s1, s2, s3, s11, s12, s13, s22, s23, s33, count, t00, t01, t02, t03, t011, t012, t013, t022, t023, t033, t10, t11, t12, t13, t111, t112, t113, t122, t123, t133, t20, t21, t22, t23, t211, t212, t213, t222, t223, t233) reduction(min : a_min))
    for (std::size_t k = 0; k < n; ++k)
    {
        const real_t d0 = x0 - px[k], d1 = x1 - py[k], d2 = x2 - pz[k];
        const real_t inv_a = ia[k];
        real_t phi, g0, g1, g2;
        window_gradient_at<K, S>(d0, d1, d2, inv_a, phi, g0, g1, g2);
        const bool covers = phi > 0.0;
        phi = covers ? phi : 0.0;
        g0 = covers ? g0 : 0.0;
        g1 = covers ? g1 : 0.0;
        g2 = covers ? g2 : 0.0;
        const real_t a = ra[k];
        dx[k] = d0;
        dy[k] = d1;
        dz[k] = d2;
        phi_out[k] = phi;
        g0_out[k] = g0;
        g1_out[k] = g1;
        g2_out[k] = g2;
        kept[k] = covers ? 1.0 : 0.0;
        count += covers ? 1.0 : 0.0;
        a_min = std::min(a_min, covers ? a : std::numeric_limits<real_t>::infinity());
        add_moments(phi, d0, d1, d2, s0, s1, s2, s3, s11, s12, s13, s22, s23, s33);
        add_moments(g0, d0, d1, d2, t00, t01, t02, t03, t011, t012, t013, t022, t023, t033);
        add_moments(g1, d0, d1, d2, t10, t11, t12, t13, t111, t112, t113, t122, t123, t133);
        add_moments(g2, d0, d1, d2, t20, t21, t22, t23, t211, t212, t213, t222, t223, t233);
    }
    const real_t sums[10] = {s0, s1, s2, s3, s11, s12, s13, s22, s23, s33};
    const real_t slope_sums[3][10] = {{t00, t01, t02, t03, t011, t012, t013, t022, t023, t033},
                                      {t10, t11, t12, t13, t111, t112, t113, t122, t123, t133},
                                      {t20, t21, t22, t23, t211, t212, t213, t222, t223, t233}};
    std::copy(sums, sums + 10, sum_);
    for (int i = 0; i < 3; ++i)
        std::copy(slope_sums[i], slope_sums[i] + 10, slope_sum_[i]);
    n_cover_ = count;
    a_min_ = a_min;
}
} // namespace rkfem

#pragma GCC diagnostic pop
