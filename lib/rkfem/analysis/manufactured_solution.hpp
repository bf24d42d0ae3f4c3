#pragma once
/// @file manufactured_solution.hpp
/// Static manufactured-solution problem for 3-D linear elasticity on the unit cube,
///   u_i = sin(pi x) sin(pi y) sin(pi z)  (i = 1, 2, 3),
/// body force b = -div sigma(u), and on the boundary either the exact traction sigma(u) n with
/// the six rigid-body dofs pinned at three corners (where u = 0), or u = 0 (MmsBoundary). Solved
/// on an n^3 box mesh with any nodal formulation: by CHOLMOD on the assembled K (UMFPACK with
/// collocation constraints), or, for large cases, by conjugate gradients on the matrix-free K
/// preconditioned with the factored trilinear 2x2x2 FE stiffness of the same nodes
/// (operators/linear_static.hpp), to a relative residual of 1e-10 by default. Errors against the
/// exact field with 4^3 Gauss points per element:
///   L2 = ||u_h - u|| / ||u||,  H1 = |u_h - u|_1 / |u|_1  (u_h = physical field, direct gradients).
#include <string>

#include "rkfem/approximation/rk/rk_shape.hpp"
#include "rkfem/discretization/formulation.hpp"

namespace rkfem
{
enum class MmsSolver
{
    Auto,   ///< direct up to pcg_above_dofs, PCG above
    Direct, ///< CHOLMOD on the assembled stiffness
    Pcg,    ///< matrix-free conjugate gradients, FE-preconditioned
};

enum class MmsBoundary
{
    Traction,  ///< exact traction on the whole boundary, rigid motion pinned at three corners
    Dirichlet, ///< u = 0 on the whole boundary (the exact field vanishes there): RK by collocation
               ///< u_h(X_b) = 0 at the boundary particles, FE nodes pinned
};

struct MmsCase
{
    Formulation formulation = Formulation::Rkpm; ///< rkpm or fem-nodal
    /// dni | scni | sd-scni, or (rkpm) snni | sd-snni: the semi-Lagrangian block's SNNI tables on
    /// its cells at the start (the boxes of the nodes' dual cells; SemiLagrangianForceBlock::
    /// snni_operators), sd-snni with its eight sub-cells
    std::string scheme = "scni";
    real_t stabilization = 0.0; ///< c_s of MSCNI (scheme scni) or of the face-gradient term (snni), 0: none
    RkParams rk;
    int n = 8; ///< elements per side, h = 1/n
    real_t E = 1.0, nu = 0.3;
    MmsSolver solver = MmsSolver::Auto;
    MmsBoundary boundary = MmsBoundary::Traction;
    real_t pcg_rtol = 1e-10;
    int pcg_max_iterations = 20000;
    static constexpr index_t pcg_above_dofs = 10000; ///< h = 1/16 and finer (PCG is the faster there)
    std::string label() const;
    /// The case's table name (HDF5 group): the label plus every parameter that sets it apart
    /// (a/h, kernel, support, order for RK; c_s other than 1; an explicit solver).
    std::string table_name() const;
};

struct MmsResult
{
    int n = 0;
    real_t h = 0.0;
    index_t dofs = 0;
    real_t l2 = 0.0, h1 = 0.0;
    real_t seconds = 0.0;
    int iterations = 0; ///< PCG iterations (0: direct solve)
};

MmsResult solve_mms(const MmsCase& c);

/// Observed rate log(e1 / e2) / log(h1 / h2).
inline real_t observed_rate(real_t e_coarse, real_t e_fine, real_t h_coarse, real_t h_fine)
{
    return std::log(e_coarse / e_fine) / std::log(h_coarse / h_fine);
}
} // namespace rkfem
