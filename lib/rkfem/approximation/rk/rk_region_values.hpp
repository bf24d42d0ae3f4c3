#pragma once
/// @file rk_region_values.hpp
/// RK shape function values at many points of one region (a hex element, a cell) over the
/// particles whose supports reach the region, gathered once per region into flat arrays. The
/// set-up's fast path for smoothed gradients, which evaluate the functions at tens of facet
/// points per element: one branch-free pass over the candidates per point (window values,
/// offsets and moment sums together), the moment solve, and one pass for the values.
///
/// The plain twin is RkShapeFunctions::evaluate followed by prune_rk_values (read it first):
/// the same functions to round-off. The moment sums here run in ascending particle order, the
/// twin's in the cell list's order, and the offsets are scaled after summing.
#include <vector>

#include "rkfem/approximation/rk/rk_shape.hpp"

namespace rkfem
{
class RkRegionValues
{
  public:
    /// drop_tolerance: as RkShapes (prune_rk_values), 0 keeps every covering function.
    RkRegionValues(const RkShapeFunctions& rk, real_t drop_tolerance);

    /// The region: the box [lo, hi] that every later point lies in (particles_near_box). Its
    /// particles are the candidates until focus narrows them.
    void gather(const Vec3& lo, const Vec3& hi);
    /// The region given by its particles, ascending (as gather(lo, hi) finds them: a region
    /// that RkTranslates kept).
    void gather(const index_t* ids, std::size_t n);
    /// Narrows the candidates to the region's particles whose support reaches the box [lo, hi]
    /// (inside the region), for the points that lie in it: a facet's points need about a third
    /// of its element's particles.
    void focus(const Vec3& lo, const Vec3& hi);
    /// focus's plain twin (the particles one by one; focus takes 8 at a time where the CPU has
    /// AVX-512): the same candidates in the same order, the same arrays.
    void focus_plain(const Vec3& lo, const Vec3& hi);
    /// Candidate particles, ascending; candidate k is particle candidates()[k] and the region's
    /// particle slots()[k] (0 .. region_size() - 1).
    const std::vector<index_t>& candidates() const { return ids_; }
    const std::vector<index_t>& slots() const { return slots_; }
    std::size_t size() const { return ids_.size(); }
    /// The region's particles, ascending.
    const std::vector<index_t>& region_particles() const { return region_ids_; }
    std::size_t region_size() const { return region_ids_.size(); }

    /// The functions at x (in the region's box): afterwards psi()[k] is candidate k's value and
    /// kept()[k] is 1 where candidate k is one of the functions at x (it covers x and survives
    /// the drop), else 0 (and psi()[k] is 0). Throws SingularMomentError as evaluate does.
    void evaluate(const Vec3& x);
    const real_t* psi() const { return psi_.data(); }
    const real_t* kept() const { return kept_.data(); }

    /// The functions at x that complete the others' reproduction (order 1 only): M b = H(0) -
    /// sum_i w_i H(x - x_i), as RkShapeFunctions::evaluate_completing (its plain twin) computes
    /// them; every value 0 where the others reproduce the basis by themselves. No drop.
    void evaluate_completing(const Vec3& x, const RkOthers& others);

    /// Values and direct gradients at x (in the region's box), with no drop (as evaluate(x,
    /// true, ...) of the twin): psi()[k], gradient(i)[k] = d Psi_k / dx_i and kept()[k] (covers).
    void evaluate_gradients(const Vec3& x);
    const real_t* gradient(int i) const { return grad_[static_cast<std::size_t>(i)].data(); }

    /// The second derivatives of the functions at particle position x, as
    /// RkShapeFunctions::hessians (its plain twin): central differences of the direct gradients
    /// at x +- delta e_j, delta = 1e-3 times the smallest support radius covering x, over the
    /// particles near x (gathered here: the region becomes the box around x), then symmetrized.
    /// nodes: every particle covering one of the six points, ascending.
    void hessians(const Vec3& x, std::vector<index_t>& nodes, std::vector<Mat3>& H);
    /// The same with the particles near x given (ascending): those whose support reaches the box
    /// x -+ hessian_reach(), as the other form gathers them (a region that RkTranslates kept).
    void hessians(const Vec3& x, const index_t* region, std::size_t n, std::vector<index_t>& nodes,
                  std::vector<Mat3>& H);
    /// The half-width of the box around x whose particles hessians reads: 1e-3 of the largest radius.
    static Vec3 hessian_reach(const RkShapeFunctions& rk) { return Vec3::Constant(1e-3 * rk.max_radius()); }

  private:
    void hessians_in_region(const Vec3& x, std::vector<index_t>& nodes, std::vector<Mat3>& H);
    /// The region's positions and radii from region_ids_, every particle a candidate.
    void take_region();
    /// The candidates: the region's particles k with keep(k).
    template <class Keep> void select(Keep&& keep);
    template <class Keep> std::size_t copy_kept(std::size_t k0, std::size_t n, Keep&& keep);
    bool reaches(std::size_t k, const Vec3& lo, const Vec3& hi) const;
    void resize_candidates(std::size_t n);
#if defined(__AVX512F__)
    void focus_wide(const Vec3& lo, const Vec3& hi);
#endif
    void values_at(const Vec3& x);
    /// The basis size, after the covering count's test at the last point (too few covering
    /// particles throw SingularMomentError naming x)
    int checked_basis_size(const Vec3& x) const;
    template <KernelType K, SupportShape S> void windows(const Vec3& x);
    template <KernelType K, SupportShape S> void slopes(const Vec3& x);
    void gradients_linear(const Vec3& x);
    void gradients_quadratic(const Vec3& x);
    void values_linear(const Vec3& x);
    void linear_values(const Eigen::Vector4d& b, real_t inv_s);
    void values_quadratic(const Vec3& x);
    void drop(const Vec3& x);

    const RkShapeFunctions& rk_;
    real_t tau_;
    // chosen once for the kernel and support
    void (RkRegionValues::*windows_)(const Vec3&) = nullptr;
    void (RkRegionValues::*slopes_)(const Vec3&) = nullptr;
    // per particle of the region (flat): particle, position, radius, 1 / radius
    std::vector<index_t> region_ids_;
    std::vector<real_t> region_x_[3], region_a_, region_inv_a_;
    // per candidate (flat): particle, region slot, position, 1 / radius, radius
    std::vector<index_t> ids_, slots_;
    std::vector<real_t> px_, py_, pz_, inv_a_, a_;
    // per candidate at the last point: offsets x - x_k, window, value, kept (0 / 1)
    std::vector<real_t> dx_, dy_, dz_, phi_, psi_, kept_;
    // with gradients: the window's gradient d phi / dx_i and d Psi / dx_i, per candidate
    std::vector<real_t> dphi_[3], grad_[3];
    // with gradients (order 1): sum dphi_i, sum dphi_i d_j, sum dphi_i d_j d_k, 10 per i
    real_t slope_sum_[3][10] = {};
    // hessians' scratch: per candidate, the column sums of the differences (9 per candidate)
    std::vector<real_t> hess_, hit_;
    // the last point's moment sums sum phi, sum phi d_i, sum phi d_i d_j (order 1), the covering
    // count and the smallest covering radius
    real_t sum_[10] = {};
    real_t n_cover_ = 0.0, a_min_ = 0.0;
    real_t big_ = 0.0; ///< the largest |psi| at the last point (evaluate)
};
} // namespace rkfem
