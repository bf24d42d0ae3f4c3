#pragma once
/// @file linear_static.hpp
/// Small-strain linear elastic stiffness assembled from any integration operator, and a static
/// solve with prescribed degrees of freedom by CHOLMOD (SuiteSparse). Used by the static patch
/// tests, the spurious-mode counts and the manufactured-solution studies; the explicit solver
/// never forms K.
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
} // namespace rkfem
