#pragma once
/// @file manufactured_solution.hpp
/// Static manufactured-solution problem for 3-D linear elasticity on the unit cube,
///   u_i = sin(pi x) sin(pi y) sin(pi z)  (i = 1, 2, 3),
/// body force b = -div sigma(u), exact traction sigma(u) n on the whole boundary and the six
/// rigid-body dofs pinned at three corners (where u = 0). Solved on an n^3 box mesh with any nodal
/// formulation (CHOLMOD); errors against the exact field with 4^3 Gauss points per element:
///   L2 = ||u_h - u|| / ||u||,  H1 = |u_h - u|_1 / |u|_1  (u_h = physical field, direct gradients).
#include <string>

#include "rkfem/approximation/rk/rk_shape.hpp"
#include "rkfem/config/deck.hpp"

namespace rkfem
{
struct MmsCase
{
    Formulation formulation = Formulation::Rkpm; ///< rkpm or fem-nodal
    std::string scheme = "scni";                 ///< dni | scni | sd-scni
    real_t stabilization = 0.0;                  ///< MSCNI c_s (scheme scni), 0: none
    RkParams rk;
    int n = 8; ///< elements per side, h = 1/n
    real_t E = 1.0, nu = 0.3;
    std::string label() const;
};

struct MmsResult
{
    int n = 0;
    real_t h = 0.0;
    index_t dofs = 0;
    real_t l2 = 0.0, h1 = 0.0;
    real_t seconds = 0.0;
};

MmsResult solve_mms(const MmsCase& c);

/// Observed rate log(e1 / e2) / log(h1 / h2).
inline real_t observed_rate(real_t e_coarse, real_t e_fine, real_t h_coarse, real_t h_fine)
{
    return std::log(e_coarse / e_fine) / std::log(h_coarse / h_fine);
}
} // namespace rkfem
