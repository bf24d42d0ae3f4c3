#pragma once
/// @file hex1pt_reference.hpp
/// The 1-point hexahedron of a HexBlock, one element at a time, in plain scalar code: read this
/// first. The fast kernel (kernels/hex_fast.hpp, force_1pt_batch) computes the same quantities for 8
/// elements at once in the elements' mode basis with lane vectors; a test holds it to this one
/// to round-off (verification/operators/test_reference_kernels.cpp).
///
/// Per element, with nodal positions x_I and velocities v_I (updated Lagrangian):
///   b_I = dV/dx_I (Flanagan-Belytschko uniform gradient, exact volume integration), V;
///   L = (1/V) sum_I v_I (x) b_I, d = sym L, w = skew L;
///   sigma_new = material update from sigma_old: hypoelastic with the Hughes-Winget rotation, or
///     the block's inelastic model (J2, K&C, CSCM: PlasticPoints::update) for the point;
///   lc = V / (largest face area); q = bulk viscosity with rho = rho0 V0 / V;
///   hourglass (mode a = 0..3, base vectors Gamma_a): h_a = sum_J Gamma_aJ x_J,
///     g_a = sum_J Gamma_aJ v_J, qdot_a = g_a - L h_a (the plain viscous form: g_a);
///     Q_a = c_h qdot_a (viscous, c_h = QM rho0 c lc^2 / 4) or Q_a += c_h dt qdot_a (stiffness,
///     c_h = QM (lambda + 2 mu) sum_I |b_I|^2 / (24 V): Flanagan-Belytschko's / (3 V) on their
///     modes Gamma / sqrt(8), 0.5 QM (lambda + 2 mu) h per node on a cube; with plastic_scaling on
///     an inelastic block
///     the increment is scaled by the share of the step the material took elastically,
///     assumed_strain_tangent_share);
///     assumed strain (LS-DYNA IHQ 6): kernels/assumed_strain_hourglass.hpp, the stored forces
///     first scaled by assumed_strain_keep as the frame sizes change;
///   f_I = (sigma - q 1 - (1/V) sum_a Q_a (x) h_a) b_I + sum_a Gamma_aI Q_a;
///   energies over dt: stress power V (sigma_old + sigma_new)/2 : d, hourglass Q . qdot
///   (stiffness: (Q_old + Q_new)/2 . qdot), bulk viscosity -V q tr d;
///   stable step lc / (Q + sqrt(Q^2 + c^2)).
/// The fast kernel takes J2 points that stay elastic 8 at a time (PlasticPoints::
/// j2_elastic_lanes, the same operations per lane) and calls the point update for the rest.
#include "rkfem/operators/hex_block.hpp"

namespace rkfem
{
struct Hex1ptElement
{
    real_t f[8][3] = {};        ///< nodal internal forces [N]
    real_t stress[6] = {};      ///< trial stress, Voigt (xx yy zz xy yz zx) [Pa]
    real_t hg_force[4][3] = {}; ///< hourglass generalized forces Q_a (stiffness form: trial; assumed
                                ///< strain: the trial stored forces of modes m, frame components)
    real_t hg_size[3] = {};     ///< assumed strain: the frame sizes J_i the trial forces were stored at
    real_t volume = 0.0;
    real_t d_internal = 0.0, d_hourglass = 0.0, d_bulk_viscosity = 0.0; ///< [J] over dt
    real_t dt_stable = 0.0;                                             ///< [s]
};

/// Element e of a 1-point block over a step dt, from the committed state (blk.stress,
/// blk.hg_force) and the nodes' current x and v. Reads only the block; an inelastic block's point
/// update writes its trial history into `history` (a copy of blk.plastic the caller owns), which
/// must then be given.
Hex1ptElement hex1pt_reference(const HexBlock& blk, const NodeSet& nodes, index_t e, real_t dt,
                               PlasticPoints* history = nullptr);
} // namespace rkfem
