#pragma once
/// @file rk_shape.hpp
/// Reproducing kernel (RK) shape functions in 3-D with a shifted and scaled monomial basis of
/// order 1 (m = 4) or 2 (m = 10), and their direct gradients.
///
///   Psi_I(x) = b(x)^T H((x - x_I)/s) phi_a(x - x_I),   M(x) b(x) = H(0),
///   M(x) = sum_I H((x - x_I)/s) H^T((x - x_I)/s) phi_a(x - x_I),
/// with one scale s per evaluation point (the smallest support radius among the particles that
/// cover it), so that M is O(1). Direct gradients: b_,i = -M^-1 M_,i b. The moment matrix is
/// factored by LDL^T; a pivot ratio below 1e-12 (too few or coplanar neighbours) throws
/// SingularMomentError naming the point. Liu, Jun & Zhang 1995, IJNMF 20; Chen, Pan, Wu & Liu 1996,
/// CMAME 139.
#include <vector>

#include "rkfem/approximation/rk/kernel.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/discretization/cell_list.hpp"
#include "rkfem/discretization/hex_mesh.hpp"

namespace rkfem
{
struct RkParams
{
    int order = 1; ///< basis order: 1 (linear) or 2 (quadratic)
    KernelType kernel = KernelType::CubicBSpline;
    SupportShape support = SupportShape::Box;
    real_t normalized_support = 1.51; ///< a / h; never an integer on uniform grids

    int basis_size() const { return order == 1 ? 4 : 10; }
};

/// The moment matrix at a point could not be inverted.
class SingularMomentError : public Error
{
  public:
    explicit SingularMomentError(const std::string& what) : Error(what) {}
};

/// Shape functions (and gradients) of every particle that covers one evaluation point.
struct RkSample
{
    std::vector<index_t> nodes; ///< covering particles, ascending within each bin visit
    std::vector<real_t> psi;    ///< Psi_I(x)
    std::vector<Vec3> grad;     ///< grad Psi_I(x) (when requested)
    // workspace
    std::vector<real_t> phi;
    std::vector<Vec3> dphi;
    std::vector<Vec3> dx;
    void clear()
    {
        nodes.clear();
        psi.clear();
        grad.clear();
        phi.clear();
        dphi.clear();
        dx.clear();
    }
    index_t size() const { return static_cast<index_t>(nodes.size()); }
};

/// Other functions that share the reproducing conditions at a point (FE functions of an
/// interface element): their values w_k and offsets dx_k = x - x_k from their nodes.
struct RkOthers
{
    std::vector<real_t> weight;
    std::vector<Vec3> dx;
    void clear()
    {
        weight.clear();
        dx.clear();
    }
};

class RkShapeFunctions
{
  public:
    RkShapeFunctions() = default;
    /// x: particle positions (n x 3); radius: support radius a_I per particle [m].
    RkShapeFunctions(std::vector<real_t> x, std::vector<real_t> radius, RkParams params);

    /// Psi_I(x) for every covering particle, and grad Psi_I(x) when `gradients`.
    void evaluate(const Vec3& x, bool gradients, RkSample& out) const;
    /// Psi_I(x) that complete the reproduction of other functions (Huerta & Fernandez-Mendez
    /// 2000): M(x) b(x) = H(0) - sum_k w_k H((x - x_k)/s), so sum_k w_k H(x - x_k) + sum_I Psi_I
    /// H(x - x_I) = H(0). Where the others reproduce the basis by themselves every Psi is 0 (and M
    /// is not needed). Values only.
    void evaluate_completing(const Vec3& x, const RkOthers& others, RkSample& out) const;
    /// Second derivatives H_I = grad grad Psi_I(x) (symmetric, H_I(i, j) = d2 Psi_I / dx_i dx_j)
    /// of every particle that covers x or a point within delta of it, by central differences of
    /// the direct gradients with delta = 1e-3 times the smallest support radius covering x:
    /// truncation error O(delta^2) (about 1e-6 relative), round-off about 1e-13 relative. The
    /// differences of the reproducing identities keep sum_I H_I = 0 and sum_I H_I (x) x_I = 0 to
    /// round-off (order 1 and 2), and order 2 reproduces the second derivatives of quadratics
    /// to the truncation error. Set-up only (naturally stabilized nodal integration).
    void hessians(const Vec3& x, std::vector<index_t>& nodes, std::vector<Mat3>& H) const;

    /// The particles whose support reaches the box [lo, hi] along every axis, ascending: every
    /// particle that covers some point of the box (and those whose support box only meets it).
    /// It scans the bins' particles as runs of a copy in bin order (positions and reaches), eight
    /// at a time with AVX-512.
    void particles_near_box(const Vec3& lo, const Vec3& hi, std::vector<index_t>& out) const;
    /// Its plain twin, particle by particle through the cell list: the same list.
    void particles_near_box_plain(const Vec3& lo, const Vec3& hi, std::vector<index_t>& out) const;
    /// Throws the SingularMomentError of point x, which n particles cover (`why`: the test failed).
    [[noreturn]] void throw_singular(const Vec3& x, index_t n, const char* why) const;

    index_t size() const { return static_cast<index_t>(a_.size()); }
    real_t radius(index_t i) const { return a_[static_cast<std::size_t>(i)]; }
    real_t max_radius() const { return a_max_; }
    Vec3 position(index_t i) const { return {x_[3 * i], x_[3 * i + 1], x_[3 * i + 2]}; }
    const RkParams& params() const { return p_; }

  private:
    void evaluate_impl(const Vec3& x, bool gradients, RkSample& out, const RkOthers* others) const;
    std::vector<real_t> x_, a_;
    real_t a_max_ = 0.0;
    RkParams p_;
    CellList cells_;
    /// per particle in the cell list's bin order: x, y, z and the reach of the box test,
    /// a (1 + 1e-12) (particles_near_box), 32 bytes per particle
    std::vector<real_t> binned_;
};

/// Psi_k (and, with `gradients`, their direct gradients) at a point from the kernels of the
/// particles that cover it, which `sample` holds (phi, dphi and dx = x - x_k per entry; its
/// `nodes` are the caller's labels, not read), with basis scale s (RkShapeFunctions' rule: the
/// smallest covering support). Returns false, leaving psi and grad unset, where the moment
/// matrix is singular (fewer entries than the basis, or a pivot ratio below `pivot`, the
/// RkShapeFunctions' 1e-12 by default). For callers with their own neighbour search (the
/// semi-Lagrangian block's moving particles).
bool rk_solve_sample(RkSample& sample, real_t s, int order, bool gradients, real_t pivot = 1e-12);

/// Drops the values psi_k < tau max |psi| of the functions at x (nodes, psi from evaluate) and
/// corrects the rest, psi_k += |psi_k| H_k . c with H_k = (1, (x_k - x) / s), so that they
/// reproduce 1 and x at x again (a 4 x 4 solve). Nothing changes when nothing is dropped.
void prune_rk_values(const RkShapeFunctions& rk, const Vec3& x, real_t tau, std::vector<index_t>& nodes,
                     std::vector<real_t>& psi);

/// The same for second derivatives (hessians): drops H_k with max |H_k| < tau max_k max |H_k| and
/// corrects the rest, H_k += w_k sum_a B_ka C_a (w_k = max |H_k|, B_k = (1, (x_k - x) / s)), so
/// that sum H = 0 and sum H (x) x_k = 0 hold again; H stays symmetric.
void prune_rk_hessians(const RkShapeFunctions& rk, const Vec3& x, real_t tau, std::vector<index_t>& nodes,
                       std::vector<Mat3>& H);

/// h_I = the longest (or, with longest = false, the shortest) mesh edge incident to node I, per
/// node, in the mesh's configuration.
std::vector<real_t> nodal_spacing(const HexMesh& mesh, bool longest = true);

/// RK functions over the nodes of a mesh, support a_I = params.normalized_support x h_I.
RkShapeFunctions rk_on_mesh(const HexMesh& mesh, const RkParams& params);
} // namespace rkfem
