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
    const simd::dvec grow = simd::broadcast(1.0 + 1e-12);
    const double lo3[3] = {lo[0], lo[1], lo[2]}, hi3[3] = {hi[0], hi[1], hi[2]};
    std::size_t n = 0, k = 0;
    for (; k + 8 <= nr; k += 8)
    {
        const simd::dvec a = simd::load(region_a_.data() + k);
        const simd::dvec x0 = simd::load(region_x_[0].data() + k), x1 = simd::load(region_x_[1].data() + k),
                         x2 = simd::load(region_x_[2].data() + k);
        const auto m = simd::boxes_reach(x0, x1, x2, a * grow, lo3, hi3);
        if (m == 0)
            continue;
        simd::compress_store(ids_.data() + n, m, region_ids_.data() + k);
        simd::compress_store_iota(slots_.data() + n, m, static_cast<std::int32_t>(k));
        simd::compress_store(px_.data() + n, m, x0);
        simd::compress_store(py_.data() + n, m, x1);
        simd::compress_store(pz_.data() + n, m, x2);
        simd::compress_store(a_.data() + n, m, a);
        simd::compress_store(inv_a_.data() + n, m, simd::load(region_inv_a_.data() + k));
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
    RKFEM_SIMD(reduction(+ : s0, s1, s2, s3, s11, s12, s13, s22, s23, s33, count) reduction(min : a_min))
    for (std::size_t k = 0; k < n; ++k)
    {
        const real_t d0 = x0 - px[k], d1 = x1 - py[k], d2 = x2 - pz[k];
        real_t phi = window_at<K, S>(d0, d1, d2, ia[k]);
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
    linear_values(ldlt.solve(Eigen::Vector4d(1.0, 0.0, 0.0, 0.0)), inv_s);
}

/// psi_k = phi_k (b_0 + b_i d_ik / s) over the candidates, and the largest |psi|.
void RkRegionValues::linear_values(const Eigen::Vector4d& b, real_t inv_s)
{
    const real_t c0 = b[0], c1 = b[1] * inv_s, c2 = b[2] * inv_s, c3 = b[3] * inv_s;
    const std::size_t n = ids_.size();
    const real_t *dx = dx_.data(), *dy = dy_.data(), *dz = dz_.data(), *phi = phi_.data();
    real_t* psi = psi_.data();
    real_t big = 0.0;
    RKFEM_SIMD(reduction(max : big))
    for (std::size_t k = 0; k < n; ++k)
    {
        psi[k] = phi[k] * (c0 + c1 * dx[k] + c2 * dy[k] + c3 * dz[k]);
        big = larger(big, std::abs(psi[k]));
    }
    big_ = big;
}

void RkRegionValues::evaluate_completing(const Vec3& x, const RkOthers& others)
{
    RKFEM_REQUIRE(rk_.params().basis_size() == 4, "RkRegionValues::evaluate_completing: order 1 only");
    (this->*windows_)(x);
    // the basis scaled by the smallest covering radius (none covering: the twin's 1 / kNoLimit,
    // to round-off 0)
    const real_t inv_s = n_cover_ > 0.0 ? 1.0 / a_min_ : 0.0;
    Eigen::Vector4d rhs(1.0, 0.0, 0.0, 0.0);
    for (std::size_t k = 0; k < others.weight.size(); ++k)
    {
        const Vec3 d = others.dx[k] * inv_s;
        rhs -= others.weight[k] * Eigen::Vector4d(1.0, d[0], d[1], d[2]);
    }
    const std::size_t n = ids_.size();
    real_t* psi = psi_.data();
    if (rhs.cwiseAbs().maxCoeff() < 1e-13)
    {
        std::fill(psi, psi + n, 0.0);
        big_ = 0.0;
        return;
    }
    const Eigen::Matrix4d M = scaled_moments(sum_, inv_s);
    const Ldlt4 ldlt = factor_moments(rk_, x, n_cover_, M);
    linear_values(ldlt.solve(rhs), inv_s);
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
    RKFEM_SIMD(reduction(+ : n_dropped, w0, w1, w2, w3, w11, w12, w13, w22, w23, w33, p0, p1, p2, p3) reduction(max : s))
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
    RKFEM_SIMD()
    for (std::size_t k = 0; k < n; ++k)
        psi[k] += std::abs(psi[k]) * (c0 - c1 * dx[k] - c2 * dy[k] - c3 * dz[k]);
}
/// The pass of windows with the window's gradient too, and the order-1 sums of the gradient.
} // namespace rkfem
