#pragma once
/// @file linear_static.hpp
/// Small-strain linear elastic stiffness assembled from any integration operator, and a static
/// solve with prescribed degrees of freedom by CHOLMOD (SuiteSparse). Used by the static patch
/// tests, the spurious-mode counts and the manufactured-solution studies; the explicit solver
/// never forms K. For stencils too wide to factor (RK at h = 1/32: K alone is gigabytes, its
/// Cholesky factor does not fit in memory), the same K is applied matrix-free and solved by
/// conjugate gradients preconditioned with the factor of a cheaper stiffness on the same dofs.
///
///   K_IJ = sum_p w_p [ lambda g_I g_J^T + mu (g_I . g_J) 1 + mu g_J g_I^T ]   (g = gradients of p)
/// Degrees of freedom are 3 node + component.
#include <Eigen/SparseCore>
#include <vector>

#include "rkfem/integration/integration_operator.hpp"
#include "rkfem/materials/elastic.hpp"

namespace rkfem
{
using SparseMatrix = Eigen::SparseMatrix<real_t, Eigen::ColMajor, int>;

/// Assembles scale * K of `op` for n_nodes nodes (block sparsity from the operator's stencils).
SparseMatrix assemble_stiffness(const IntegrationOperator& op, const ElasticParams& mat, index_t n_nodes,
                                real_t scale = 1.0);

/// Solves K u = f with u[dof] = value for the prescribed dofs; returns u (all dofs).
/// Throws Error naming the failure when the reduced matrix is not positive definite.
std::vector<real_t> solve_static(const SparseMatrix& K, const std::vector<real_t>& f,
                                 const std::vector<index_t>& prescribed_dofs,
                                 const std::vector<real_t>& prescribed_values);
/// Solves K u = f subject to linear constraints C u = g (C: one row per constraint, e.g. RK
/// collocation sum_J Psi_J(X_b) d_J = g_b for physical boundary values), through the saddle-point
/// system [K C^T; C 0] by UMFPACK (SuiteSparse). Returns u.
std::vector<real_t> solve_static_constrained(const SparseMatrix& K, const std::vector<real_t>& f, const SparseMatrix& C,
                                             const std::vector<real_t>& g);

/// One term of K = sum_t scale_t K(op_t).
struct StiffnessTerm
{
    const IntegrationOperator* op = nullptr;
    real_t scale = 1.0;
};

/// K = sum of terms, applied without forming it: per point, the strain from the gradients, Hooke,
/// the stress weighted by w scale; then per node the sum over the entries that touch it (a
/// transpose gather: no atomics, and the sum does not depend on the number of threads).
/// Memory: 6 stress values per point and two indices per entry. The operators must outlive it;
/// apply() works in that scratch, so one object serves one caller at a time.
class MatrixFreeStiffness
{
  public:
    MatrixFreeStiffness(std::vector<StiffnessTerm> terms, const ElasticParams& mat, index_t n_nodes);
    index_t n_dofs() const { return 3 * n_nodes_; }
    /// out = K u (3 n_nodes each).
    void apply(const real_t* u, real_t* out) const;

  private:
    struct Transposed
    {
        std::vector<index_t> offsets; ///< n_nodes + 1
        std::vector<index_t> entry;   ///< entries of the term that touch each node
        std::vector<index_t> point;   ///< the point of each of those entries
    };
    std::vector<StiffnessTerm> terms_;
    std::vector<Transposed> transposed_;
    ElasticParams mat_;
    index_t n_nodes_;
    mutable std::vector<std::vector<real_t>> stress_; ///< per term, 6 per point (w scale sigma)
};

struct PcgResult
{
    std::vector<real_t> u;
    int iterations = 0;
    real_t relative_residual = 0.0; ///< ||f - K u|| / ||f|| over the free dofs
};

/// Solves K u = f with u = 0 at the pinned dofs by conjugate gradients, preconditioned with the
/// CHOLMOD factor of `preconditioner` restricted to the free dofs (a stiffness on the same dofs
/// that is spectrally close and cheap to factor, e.g. trilinear FE with 2x2x2 Gauss points).
/// With `constraints` C (one row per homogeneous constraint C u = 0, e.g. RK collocation of
/// u_h = 0 at boundary particles), CG runs on the admissible subspace: every vector is projected
/// by v - C^T (C C^T)^-1 C v (C C^T factored by CHOLMOD), and the preconditioner is factored as
/// P + beta C^T C (beta: the ratio of their mean diagonals) so that it is definite on the rigid
/// motions the constraints remove. The residual is the projected one.
/// Stops when ||r|| <= rtol ||f||; throws Error naming the iteration count and residual when it
/// does not get there in max_iterations, or when K is not positive definite on the free dofs.
PcgResult solve_static_pcg(const MatrixFreeStiffness& K, const std::vector<real_t>& f,
                           const std::vector<index_t>& pinned_dofs, const SparseMatrix& preconditioner, real_t rtol,
                           int max_iterations, const SparseMatrix* constraints = nullptr);
} // namespace rkfem
