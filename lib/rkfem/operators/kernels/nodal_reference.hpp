#pragma once
/// @file nodal_reference.hpp
/// The force pass of a nodal block (RK particles or nodal-integrated FE, total Lagrangian), one
/// point at a time in plain scalar code: read this first. The fast pass (nodal_fast.hpp) runs
/// the same algebra for 8 points at once over structure-of-arrays scratch, with shared stencils,
/// whole-vector paths along lattice rows and a chunked scatter; a test holds it to this one
/// (verification/operators/test_reference_kernels.cpp).
///
/// Per stress point p with reference volume V0_p and gradients g_pI:
///   F = 1 + sum_I u_I (x) g_pI,  Fdot = sum_I v_I (x) g_pI,  J = det F,  L = Fdot F^-1;
///   sigma_new = material update with (d, w) = (sym L, skew L) from sigma_old: hypoelastic, or the
///     block's inelastic model (J2, K&C, CSCM: PlasticPoints::update) where J > 0;
///   l = alpha J^(1/3) l0_p (stable-step length), q = bulk viscosity with rho = rho0 / J;
///   f_I += V0 J (sigma_new - q 1) F^-T g_pI;
///   energies over dt: V0 J (sigma_old + sigma_new)/2 : d, -V0 J q tr d; step l / (Q + sqrt(Q^2 + c^2)).
/// Per MSCNI sub-cell s of parent point P (gradients g_sI = b_sI - b_PI):
///   D_s = sym((sum_I v_I (x) g_sI) F_P^-1), sigma_s += c_s-scaled elastic update with P's spin;
///   f_I += V0_s J_P sigma_s F_P^-T g_sI; its energy is the stabilization work.
/// The fast pass takes J2 points that stay elastic 8 at a time (PlasticPoints::j2_elastic_lanes,
/// the same operations per lane) and calls the point update for the rest.
#include <vector>

#include "rkfem/operators/nodal_block.hpp"

namespace rkfem
{
struct NodalPass
{
    std::vector<real_t> f;           ///< 3 x nodes of the node set (the block's entries only) [N]
    std::vector<real_t> stress;      ///< 6 per stress point, Voigt [Pa]
    std::vector<real_t> stab_stress; ///< 6 per sub-cell
    real_t d_internal = 0.0, d_bulk_viscosity = 0.0, d_stabilization = 0.0; ///< [J] over dt
    real_t dt_stable = kNoLimit;                                            ///< [s]
};

/// The pass over step dt from the committed state and the nodes' u and v. Reads only the block;
/// an inelastic block's point updates write their trial history into `history` (a copy of
/// blk.plastic the caller owns), which must then be given.
NodalPass nodal_reference(const NodalBlock& blk, const NodeSet& nodes, real_t dt, PlasticPoints* history = nullptr);
} // namespace rkfem
