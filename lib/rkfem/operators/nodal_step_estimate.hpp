#pragma once
/// @file nodal_step_estimate.hpp
/// The stable step of a nodal block from its highest frequency. A nodal block steps at
/// dt = alpha J^(1/3) l0 / c per point (kernels/nodal_fast.hpp); its default alpha (rkpm 1.0,
/// fem-nodal 0.95) is calibrated in the test suite (verification/operators/
/// test_nodal_dynamics.cpp, NodalTimeStep) for the default RK functions and stabilization
/// coefficients only. Outside them the critical alpha moves, and NSNI's falls steeply with the
/// support: on a regular free block with the box at a/h 1.41 it is 0.86, at 1.35 0.68, at 1.25
/// 0.38 (1.04 at the default 1.51), so such a part stepped at alpha 1 went unstable (P3 as rkpm at
/// a/h 1.35: det F < 0 at step 40). There the set-up measures alpha_crit from dt_crit = 2 / omega_max
/// (Belytschko, Liu & Moran 2000, Nonlinear Finite Elements for Continua and Structures; Lanczos
/// in place of a power iteration): omega_max^2 is the largest eigenvalue of M^-1 K, whose
/// product K w is the block's own force pass answering velocities w from its stress-free
/// reference state (every stabilization and material the pass has, elastic at that size).
#include <string>

#include "rkfem/approximation/rk/rk_spec.hpp"
#include "rkfem/discretization/formulation.hpp"
#include "rkfem/discretization/node_set.hpp"
#include "rkfem/integration/nodal/nodal_integration_spec.hpp"
#include "rkfem/operators/nodal_block.hpp"

namespace rkfem
{
struct HighestFrequency
{
    real_t omega_max = 0.0;  ///< [rad/s]: sqrt of the largest eigenvalue of M^-1 K found
    real_t alpha_crit = 0.0; ///< 2 / omega_max x c / min_p l0_p: the alpha whose step is critical
    int passes = 0;          ///< force passes the iteration took
};

/// omega_max of the block's free stiffness against the lumped masses `mass` (per node, global
/// numbering): Lanczos from a fixed pseudo-random start, one force pass per step, until the
/// largest Ritz value's residual bound is under `tolerance` of it (at most max_passes). The
/// Ritz value approaches the largest eigenvalue from below. The block's state is left as it
/// was: the passes write only its trial arrays and scratch, from the reference configuration
/// with the bulk viscosity off; the model's nodes are not touched.
HighestFrequency nodal_highest_frequency(NodalBlock& blk, const std::vector<real_t>& mass, int max_passes = 60,
                                         real_t tolerance = 1e-3);

/// Whether the test suite holds the default alpha below alpha_crit: a nodal part of
/// `formulation` with the default RK functions (order 1, cubic B-spline, box at a/h 1.51; rkpm),
/// or, on a lattice cloud jittered by at least kCloudJitterForSmallSupport (`jittered_cloud`),
/// at the clouds' a/h kCloudNormalizedSupport (alpha_crit 1.06-1.53 over jitters 0.2-0.45 and
/// three seeds, NSNI and MSCNI: test_nodal_dynamics), and the default stabilization coefficient.
/// Elsewhere the set-up measures alpha_crit.
bool nodal_step_calibrated(Formulation formulation, const NodalIntegrationSpec& nodal, const RkSpec& rk,
                           bool jittered_cloud = false);

/// The fraction of the measured alpha_crit a part without a calibrated default steps at (the
/// quotient approaches omega_max from below; time.dt_scale applies on top, as for every part).
inline constexpr real_t kMeasuredStepShare = 0.95;
} // namespace rkfem
