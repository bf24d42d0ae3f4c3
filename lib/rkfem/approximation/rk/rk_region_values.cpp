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

namespace rkfem
{
namespace
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
Eigen::Matrix4d scaled_moments(const real_t sums[10], real_t inv_s)
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
    bool pivots_ok() const
    {
        real_t lo = D_[0], big = std::abs(D_[0]);
        for (int k = 1; k < 4; ++k)
        {
            lo = std::min(lo, D_[k]);
            big = std::max(big, std::abs(D_[k]));
        }
        return lo > 1e-12 * big;
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

/// evaluate's pivot test on an Eigen LDL^T: every pivot above 1e-12 of the largest in magnitude
template <int m> bool pivots_ok(const Eigen::LDLT<Eigen::Matrix<real_t, m, m>>& ldlt)
{
    const auto D = ldlt.vectorD();
    return ldlt.info() == Eigen::Success && D.minCoeff() > 1e-12 * D.cwiseAbs().maxCoeff();
}

/// LDL^T of a moment matrix with evaluate's pivot test; b = M^-1 e_0.
template <int m> bool solve_moments(const Eigen::Matrix<real_t, m, m>& M, Eigen::Matrix<real_t, m, 1>& b)
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
Ldlt4 factor_moments(const RkShapeFunctions& rk, const Vec3& x, real_t n_cover, const Eigen::Matrix4d& M)
{
    Ldlt4 ldlt(M);
    if (!ldlt.pivots_ok())
        rk.throw_singular(x, static_cast<index_t>(n_cover), "pivot ratio below 1e-12");
    return ldlt;
}
} // namespace

RkRegionValues::RkRegionValues(const RkShapeFunctions& rk, real_t drop_tolerance) : rk_(rk), tau_(drop_tolerance)
{
    const RkParams& p = rk.params();
    const bool box = p.support == SupportShape::Box;
    switch (p.kernel)
    {
    case KernelType::CubicBSpline:
        windows_ = box ? &RkRegionValues::windows<KernelType::CubicBSpline, SupportShape::Box>
                       : &RkRegionValues::windows<KernelType::CubicBSpline, SupportShape::Sphere>;
        slopes_ = box ? &RkRegionValues::slopes<KernelType::CubicBSpline, SupportShape::Box>
                      : &RkRegionValues::slopes<KernelType::CubicBSpline, SupportShape::Sphere>;
        break;
    case KernelType::QuinticBSpline:
        windows_ = box ? &RkRegionValues::windows<KernelType::QuinticBSpline, SupportShape::Box>
                       : &RkRegionValues::windows<KernelType::QuinticBSpline, SupportShape::Sphere>;
        slopes_ = box ? &RkRegionValues::slopes<KernelType::QuinticBSpline, SupportShape::Box>
                      : &RkRegionValues::slopes<KernelType::QuinticBSpline, SupportShape::Sphere>;
        break;
    case KernelType::Gaussian:
        windows_ = box ? &RkRegionValues::windows<KernelType::Gaussian, SupportShape::Box>
                       : &RkRegionValues::windows<KernelType::Gaussian, SupportShape::Sphere>;
        slopes_ = box ? &RkRegionValues::slopes<KernelType::Gaussian, SupportShape::Box>
                      : &RkRegionValues::slopes<KernelType::Gaussian, SupportShape::Sphere>;
        break;
    }
}

template <class Keep> void RkRegionValues::select(Keep&& keep)
{
    const std::size_t nr = region_ids_.size();
    for (auto* v : {&px_, &py_, &pz_, &inv_a_, &a_})
        v->resize(nr);
    ids_.resize(nr);
    slots_.resize(nr);
    resize_candidates(copy_kept(0, 0, keep));
}

/// Region particles k0.. with keep(k) appended to the candidates from position n; the new count.
template <class Keep> std::size_t RkRegionValues::copy_kept(std::size_t k0, std::size_t n, Keep&& keep)
{
    for (std::size_t k = k0; k < region_ids_.size(); ++k)
    {
        // written whether kept or not, kept by advancing: no branch on the test
        ids_[n] = region_ids_[k];
        slots_[n] = static_cast<index_t>(k);
        px_[n] = region_x_[0][k];
        py_[n] = region_x_[1][k];
        pz_[n] = region_x_[2][k];
        a_[n] = region_a_[k];
        inv_a_[n] = region_inv_a_[k];
        n += keep(k) ? 1 : 0;
    }
    return n;
}

void RkRegionValues::resize_candidates(std::size_t n)
{
    for (auto* v : {&px_, &py_, &pz_, &inv_a_, &a_})
        v->resize(n);
    ids_.resize(n);
    slots_.resize(n);
    for (auto* v :
         {&dx_, &dy_, &dz_, &phi_, &psi_, &kept_, &dphi_[0], &dphi_[1], &dphi_[2], &grad_[0], &grad_[1], &grad_[2]})
        v->resize(n);
}

void RkRegionValues::gather(const Vec3& lo, const Vec3& hi)
{
    rk_.particles_near_box(lo, hi, region_ids_);
    take_region();
}

void RkRegionValues::gather(const index_t* ids, std::size_t n)
{
    region_ids_.assign(ids, ids + n);
    take_region();
}

void RkRegionValues::take_region()
{
    const std::size_t n = region_ids_.size();
    for (auto* v : {&region_x_[0], &region_x_[1], &region_x_[2], &region_a_, &region_inv_a_})
        v->resize(n);
    for (std::size_t k = 0; k < n; ++k)
    {
        const Vec3 p = rk_.position(region_ids_[k]);
        for (int d = 0; d < 3; ++d)
            region_x_[d][k] = p[d];
        region_a_[k] = rk_.radius(region_ids_[k]);
        region_inv_a_[k] = 1.0 / region_a_[k]; // as kernel_3d computes it
    }
    select([](std::size_t) { return true; });
}

/// particles_near_box's test on region particle k: does its support reach the box [lo, hi]?
inline bool RkRegionValues::reaches(std::size_t k, const Vec3& lo, const Vec3& hi) const
{
    const real_t reach = region_a_[k] * (1.0 + 1e-12);
    bool in = true;
    for (int d = 0; d < 3; ++d)
        in &= !(region_x_[d][k] + reach < lo[d]) & !(region_x_[d][k] - reach > hi[d]);
    return in;
}

void RkRegionValues::focus(const Vec3& lo, const Vec3& hi)
{
#if defined(__AVX512F__)
    focus_wide(lo, hi);
#else
    focus_plain(lo, hi);
#endif
}

void RkRegionValues::focus_plain(const Vec3& lo, const Vec3& hi)
{
    select([&](std::size_t k) { return reaches(k, lo, hi); });
}

#if defined(__AVX512F__)
/// focus, 8 region particles at a time: the test in lanes (the same operations: a product, a
/// sum or difference and an unordered compare, which keeps a NaN in as the scalar test does),
/// then each array's kept lanes compressed in a register and stored whole (the arrays have a
/// vector's room past their end), the rest of the region as select does it.
void RkRegionValues::focus_wide(const Vec3& lo, const Vec3& hi)
{
    const std::size_t nr = region_ids_.size();
    for (auto* v : {&px_, &py_, &pz_, &inv_a_, &a_})
        v->resize(nr + 8);
    ids_.resize(nr + 8);
    slots_.resize(nr + 8);
    const __m512d grow = _mm512_set1_pd(1.0 + 1e-12);
    const __m512d lo0 = _mm512_set1_pd(lo[0]), lo1 = _mm512_set1_pd(lo[1]), lo2 = _mm512_set1_pd(lo[2]);
    const __m512d hi0 = _mm512_set1_pd(hi[0]), hi1 = _mm512_set1_pd(hi[1]), hi2 = _mm512_set1_pd(hi[2]);
    const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    std::size_t n = 0, k = 0;
    for (; k + 8 <= nr; k += 8)
    {
        const __m512d a = _mm512_loadu_pd(region_a_.data() + k);
        const __m512d reach = _mm512_mul_pd(a, grow);
        const __m512d x0 = _mm512_loadu_pd(region_x_[0].data() + k), x1 = _mm512_loadu_pd(region_x_[1].data() + k),
                      x2 = _mm512_loadu_pd(region_x_[2].data() + k);
        __mmask8 m = _mm512_cmp_pd_mask(_mm512_add_pd(x0, reach), lo0, _CMP_NLT_UQ);
        m &= _mm512_cmp_pd_mask(_mm512_sub_pd(x0, reach), hi0, _CMP_NGT_UQ);
        m &= _mm512_cmp_pd_mask(_mm512_add_pd(x1, reach), lo1, _CMP_NLT_UQ);
        m &= _mm512_cmp_pd_mask(_mm512_sub_pd(x1, reach), hi1, _CMP_NGT_UQ);
        m &= _mm512_cmp_pd_mask(_mm512_add_pd(x2, reach), lo2, _CMP_NLT_UQ);
        m &= _mm512_cmp_pd_mask(_mm512_sub_pd(x2, reach), hi2, _CMP_NGT_UQ);
        if (m == 0)
            continue;
        const __m256i ids = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(region_ids_.data() + k));
        const __m256i slots = _mm256_add_epi32(_mm256_set1_epi32(static_cast<int>(k)), lane);
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(ids_.data() + n), _mm256_maskz_compress_epi32(m, ids));
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(slots_.data() + n), _mm256_maskz_compress_epi32(m, slots));
        _mm512_storeu_pd(px_.data() + n, _mm512_maskz_compress_pd(m, x0));
        _mm512_storeu_pd(py_.data() + n, _mm512_maskz_compress_pd(m, x1));
        _mm512_storeu_pd(pz_.data() + n, _mm512_maskz_compress_pd(m, x2));
        _mm512_storeu_pd(a_.data() + n, _mm512_maskz_compress_pd(m, a));
        _mm512_storeu_pd(inv_a_.data() + n, _mm512_maskz_compress_pd(m, _mm512_loadu_pd(region_inv_a_.data() + k)));
        n += static_cast<std::size_t>(__builtin_popcount(m));
    }
    resize_candidates(copy_kept(k, n, [&](std::size_t j) { return reaches(j, lo, hi); }));
}
#endif

/// One pass over the candidates: offsets, windows (0 outside the support) and the order-1
/// moment sums, the covering count and the smallest covering radius.
template <KernelType K, SupportShape S> void RkRegionValues::windows(const Vec3& x)
{
    const std::size_t n = ids_.size();
    const real_t x0 = x[0], x1 = x[1], x2 = x[2];
    const real_t *px = px_.data(), *py = py_.data(), *pz = pz_.data(), *ia = inv_a_.data(), *ra = a_.data();
    real_t *dx = dx_.data(), *dy = dy_.data(), *dz = dz_.data(), *phi_out = phi_.data(), *kept = kept_.data();
    real_t s0 = 0, s1 = 0, s2 = 0, s3 = 0, s11 = 0, s12 = 0, s13 = 0, s22 = 0, s23 = 0, s33 = 0;
    real_t count = 0, a_min = std::numeric_limits<real_t>::infinity();
#pragma omp simd reduction(+ : s0, s1, s2, s3, s11, s12, s13, s22, s23, s33, count) reduction(min : a_min)
    for (std::size_t k = 0; k < n; ++k)
    {
        const real_t d0 = x0 - px[k], d1 = x1 - py[k], d2 = x2 - pz[k];
        real_t phi;
        if constexpr (S == SupportShape::Box)
            phi = window<K>(std::abs(d0) * ia[k]) * window<K>(std::abs(d1) * ia[k]) * window<K>(std::abs(d2) * ia[k]);
        else
            phi = window<K>(std::sqrt(d0 * d0 + d1 * d1 + d2 * d2) * ia[k]);
        const bool covers = phi > 0.0; // the truncated Gaussian can round to <= 0 at the edge
        phi = covers ? phi : 0.0;
        const real_t a = ra[k]; // loaded whether or not it covers: no branch in the loop
        dx[k] = d0;
        dy[k] = d1;
        dz[k] = d2;
        phi_out[k] = phi;
        kept[k] = covers ? 1.0 : 0.0;
        count += covers ? 1.0 : 0.0;
        a_min = std::min(a_min, covers ? a : std::numeric_limits<real_t>::infinity());
        add_moments(phi, d0, d1, d2, s0, s1, s2, s3, s11, s12, s13, s22, s23, s33);
    }
    const real_t sums[10] = {s0, s1, s2, s3, s11, s12, s13, s22, s23, s33};
    std::copy(sums, sums + 10, sum_);
    n_cover_ = count;
    a_min_ = a_min;
}

void RkRegionValues::evaluate(const Vec3& x)
{
    values_at(x);
    if (tau_ > 0.0)
        drop(x);
}

/// The functions at x before any drop (the twin's evaluate(x, false)): windows, the covering
/// count's test, the moment solve and the values.
void RkRegionValues::values_at(const Vec3& x)
{
    (this->*windows_)(x);
    if (checked_basis_size(x) == 4)
        values_linear(x);
    else
        values_quadratic(x);
}

int RkRegionValues::checked_basis_size(const Vec3& x) const
{
    const int m = rk_.params().basis_size();
    if (n_cover_ < m)
        rk_.throw_singular(x, static_cast<index_t>(n_cover_), "too few neighbours");
    return m;
}

/// Order 1: M = sum phi H H^T with H = (1, d / s) from the sums, then psi_k = phi_k b . H_k.
void RkRegionValues::values_linear(const Vec3& x)
{
    const real_t inv_s = 1.0 / a_min_;
    const Eigen::Matrix4d M = scaled_moments(sum_, inv_s);
    const Ldlt4 ldlt = factor_moments(rk_, x, n_cover_, M);
    const Eigen::Vector4d b = ldlt.solve(Eigen::Vector4d(1.0, 0.0, 0.0, 0.0));
    const real_t c0 = b[0], c1 = b[1] * inv_s, c2 = b[2] * inv_s, c3 = b[3] * inv_s;
    const std::size_t n = ids_.size();
    const real_t *dx = dx_.data(), *dy = dy_.data(), *dz = dz_.data(), *phi = phi_.data();
    real_t* psi = psi_.data();
    real_t big = 0.0;
#pragma omp simd reduction(max : big)
    for (std::size_t k = 0; k < n; ++k)
    {
        psi[k] = phi[k] * (c0 + c1 * dx[k] + c2 * dy[k] + c3 * dz[k]);
        big = larger(big, std::abs(psi[k]));
    }
    big_ = big;
}

/// Order 2: the moment matrix over the covering candidates, one rank-1 update each.
void RkRegionValues::values_quadratic(const Vec3& x)
{
    using Vec10 = Eigen::Matrix<real_t, 10, 1>;
    const real_t inv_s = 1.0 / a_min_;
    const std::size_t n = ids_.size();
    Eigen::Matrix<real_t, 10, 10> M = Eigen::Matrix<real_t, 10, 10>::Zero();
    Vec10 H, dH[3];
    for (std::size_t k = 0; k < n; ++k)
        if (phi_[k] > 0.0)
        {
            rk_detail::basis<10>(Vec3(dx_[k], dy_[k], dz_[k]) * inv_s, H, dH);
            M.noalias() += phi_[k] * H * H.transpose();
        }
    Vec10 b;
    if (!solve_moments<10>(M, b))
        rk_.throw_singular(x, static_cast<index_t>(n_cover_), "pivot ratio below 1e-12");
    for (std::size_t k = 0; k < n; ++k)
    {
        psi_[k] = 0.0;
        if (phi_[k] > 0.0)
        {
            rk_detail::basis<10>(Vec3(dx_[k], dy_[k], dz_[k]) * inv_s, H, dH);
            psi_[k] = phi_[k] * b.dot(H);
        }
    }
    big_ = 0.0;
    for (std::size_t k = 0; k < n; ++k)
        big_ = std::max(big_, std::abs(psi_[k]));
}

/// prune_rk_values on the candidate arrays: drop |psi_k| < tau max |psi|, then correct the
/// kept ones, psi_k += |psi_k| B_k . c with B_k = (1, (x_k - x) / s) (s: the farthest kept
/// offset along an axis), to reproduce 1 and x again. Branch-free passes: a dropped or
/// non-covering candidate has psi_k = 0, which adds nothing to the sums.
void RkRegionValues::drop(const Vec3& x)
{
    const std::size_t n = ids_.size();
    const real_t *dx = dx_.data(), *dy = dy_.data(), *dz = dz_.data();
    real_t *psi = psi_.data(), *kept = kept_.data();
    const real_t cut = tau_ * big_;
    // one pass: the drop, the farthest kept offset s, and (for the correction, needed where
    // any was dropped) the sums of w = |psi| and psi times 1, d_i, d_i d_j over the kept
    real_t n_dropped = 0.0, s = 0.0;
    real_t w0 = 0, w1 = 0, w2 = 0, w3 = 0, w11 = 0, w12 = 0, w13 = 0, w22 = 0, w23 = 0, w33 = 0;
    real_t p0 = 0, p1 = 0, p2 = 0, p3 = 0;
#pragma omp simd reduction(+ : n_dropped, w0, w1, w2, w3, w11, w12, w13, w22, w23, w33, p0, p1, p2, p3) \
    reduction(max : s)
    for (std::size_t k = 0; k < n; ++k)
    {
        const real_t was = kept[k], value = psi[k];
        const real_t keep = std::abs(value) >= cut ? was : 0.0; // 1 or 0
        n_dropped += was - keep;
        kept[k] = keep;
        const real_t v = keep * value, w = std::abs(v);
        psi[k] = v;
        s = larger(s, keep * larger(std::abs(dx[k]), larger(std::abs(dy[k]), std::abs(dz[k]))));
        add_moments(w, dx[k], dy[k], dz[k], w0, w1, w2, w3, w11, w12, w13, w22, w23, w33);
        p0 += v;
        p1 += v * dx[k];
        p2 += v * dy[k];
        p3 += v * dz[k];
    }
    if (n_dropped == 0.0)
        return;
    const real_t is = 1.0 / s, is2 = is * is;
    Eigen::Matrix4d M;
    M << w0, -is * w1, -is * w2, -is * w3,         //
        -is * w1, is2 * w11, is2 * w12, is2 * w13, //
        -is * w2, is2 * w12, is2 * w22, is2 * w23, //
        -is * w3, is2 * w13, is2 * w23, is2 * w33;
    const Eigen::Vector4d r(1.0 - p0, is * p1, is * p2, is * p3);
    const Eigen::Vector4d c = Ldlt4(M).solve(r);
    if (!c.allFinite())
    {
        std::ostringstream os;
        os << "RK drop tolerance: the functions left at x = (" << x[0] << ", " << x[1] << ", " << x[2]
           << ") m after dropping those below " << tau_ << " of the largest do not span a linear field";
        throw SingularMomentError(os.str());
    }
    const real_t c0 = c[0], c1 = is * c[1], c2 = is * c[2], c3 = is * c[3];
#pragma omp simd
    for (std::size_t k = 0; k < n; ++k)
        psi[k] += std::abs(psi[k]) * (c0 - c1 * dx[k] - c2 * dy[k] - c3 * dz[k]);
}
/// The pass of windows with the window's gradient too, and the order-1 sums of the gradient.
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
#pragma omp simd reduction(+ : s0, s1, s2, s3, s11, s12, s13, s22, s23, s33, count, t00, t01, t02, t03, t011, t012, \
                               t013, t022, t023, t033, t10, t11, t12, t13, t111, t112, t113, t122, t123, t133, t20, \
                               t21, t22, t23, t211, t212, t213, t222, t223, t233) reduction(min : a_min)
    for (std::size_t k = 0; k < n; ++k)
    {
        const real_t d0 = x0 - px[k], d1 = x1 - py[k], d2 = x2 - pz[k];
        const real_t inv_a = ia[k];
        real_t phi, g0, g1, g2;
        if constexpr (S == SupportShape::Box)
        {
            // kernel_3d's product: phi = p0 p1 p2, grad = (q0 p1 p2, p0 q1 p2, p0 p1 q2)
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
    const Eigen::Vector4d m0 = M.col(0) * inv_s;
    Eigen::Vector4d db[3];
    for (int i = 0; i < 3; ++i)
    {
        Eigen::Matrix4d dM = scaled_moments(slope_sum_[i], inv_s);
        dM.row(1 + i) += m0.transpose();
        dM.col(1 + i) += m0;
        db[i] = -ldlt.solve(dM * b);
    }
    const real_t c0 = b[0], c1 = b[1] * inv_s, c2 = b[2] * inv_s, c3 = b[3] * inv_s;
    real_t e[3][4];
    for (int i = 0; i < 3; ++i)
    {
        e[i][0] = db[i][0] + b[1 + i] * inv_s; // + b . dH_i / s, constant for order 1
        for (int j = 1; j < 4; ++j)
            e[i][j] = db[i][j] * inv_s;
    }
    const std::size_t n = ids_.size();
    const real_t *dx = dx_.data(), *dy = dy_.data(), *dz = dz_.data(), *phi = phi_.data();
    const real_t *q0 = dphi_[0].data(), *q1 = dphi_[1].data(), *q2 = dphi_[2].data();
    real_t *psi = psi_.data(), *g0 = grad_[0].data(), *g1 = grad_[1].data(), *g2 = grad_[2].data();
#pragma omp simd
    for (std::size_t k = 0; k < n; ++k)
    {
        const real_t bH = c0 + c1 * dx[k] + c2 * dy[k] + c3 * dz[k];
        psi[k] = phi[k] * bH;
        g0[k] = phi[k] * (e[0][0] + e[0][1] * dx[k] + e[0][2] * dy[k] + e[0][3] * dz[k]) + q0[k] * bH;
        g1[k] = phi[k] * (e[1][0] + e[1][1] * dx[k] + e[1][2] * dy[k] + e[1][3] * dz[k]) + q1[k] * bH;
        g2[k] = phi[k] * (e[2][0] + e[2][1] * dx[k] + e[2][2] * dy[k] + e[2][3] * dz[k]) + q2[k] * bH;
    }
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
