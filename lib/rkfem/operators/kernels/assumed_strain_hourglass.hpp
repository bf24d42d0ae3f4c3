#pragma once
/// @file assumed_strain_hourglass.hpp
/// Hourglass control by assumed strain (Belytschko & Bindeman 1993, ASQBI; LS-DYNA's IHQ 6
/// analog), in the element's co-rotational frame, for the 1-point hexahedron. T is real_t (the
/// plain twin in hex1pt_reference.cpp) or a lane vector (hex_fast.hpp).
///
/// The hourglass velocities qdot_a = sum_I v_I gamma_aI (Flanagan-Belytschko gamma, modes
/// a = xi eta, eta zeta, zeta xi, xi eta zeta as hex8_modes.hpp orders them) are turned into the
/// frame e_1, e_2, e_3 of the element's axes r = sum xi_I x_I, s = sum eta_I x_I, t = sum zeta_I x_I
/// (each normalised, then three passes of e_1 <- e_2 x e_3 + e_1 (and cyclic) and a Gram-Schmidt
/// close, so the frame turns with the element and is the same for any node numbering of a box),
/// where the element's sizes are J_1 = e_1 . r, J_2 = e_2 . s, J_3 = e_3 . t (4 L_i for a box of
/// edges L_i). With q = qdot / 8 in that frame, the step's hourglass stress increment is
///   dS_ai = dt QM (G / 3) q_ai / J_i,   T_ai = J_i dS_ai,
/// and the generalized forces grow (stored in the frame, so they turn with it) by, with H_11 = J_2 J_3 / J_1 (cyclic),
/// H_12 = J_3, H_13 = J_2, H_23 = J_1, c1 = 2 / (1 - nu), c2 = 2 nu / (1 - nu), c3 = 2 (1 + nu) / 3 (subscripts: the
/// component x, y, z and the mode 1 = eta zeta, 2 = zeta xi, 3 = xi eta, 4 = xi eta zeta),
///   shear:   Q_x1 = (H_22 + H_33) T_x1 + H_12 T_y2 + H_13 T_z3   (and cyclic for Q_y2, Q_z3),
///   bending: Q_x2 = c1 H_11 T_x2 + c2 H_12 T_y1,  Q_x3 = c1 H_11 T_x3 + c2 H_13 T_z1,
///            Q_y1 = c1 H_22 T_y1 + c2 H_12 T_x2,  Q_y3 = c1 H_22 T_y3 + c2 H_23 T_z2,
///            Q_z1 = c1 H_33 T_z1 + c2 H_13 T_x3,  Q_z2 = c1 H_33 T_z2 + c2 H_23 T_y3,
///   warping: Q_i4 = c3 H_ii T_i4,
/// and f_iI = sum_a Q_ai gamma_aI / 8 back in the global frame. The forces, not the stress, are
/// stored (as the FB stiffness form stores its Q): a stored stress turned into forces with the
/// present sizes changed the forces of a flattening element with no work to account for it (the
/// Taylor bar at QM 1 broke the energy check, 6 % at 21 us); the increments take the present
/// shape's stiffness. For a box of edges L_i these are
/// the energies of the assumed strain fields exactly (at QM = 1): the bending modes carry
/// E / (1 - nu^2) 4 V / (3 L_x^2) (pure bending with the transverse normal stress free, no
/// parasitic shear, no volumetric locking as nu -> 1/2), the shear modes G (4 V / 3)(1 / L_y^2 +
/// 1 / L_z^2) with their couplings, the warping modes E 4 V / (9 L_x^2). The closed form is the
/// one OpenRadioss's HEPH solid uses (its szhour3.F); LS-DYNA documents IHQ 6 as this stabilization
/// in a co-rotational frame (QM = 1: accurate coarse-mesh bending) but not its frame or how its
/// stiffness scales with plasticity. Ours, two rules so that the form never gives back more than
/// it took: for materials with history a load of a stored force is scaled by the share of the
/// deviatoric strain increment the point's update took elastically (assumed_strain_tangent_share),
/// so a crushed element stores no elastic hourglass energy, while an unload takes the whole
/// increment (scaled_hourglass_update); and the stored forces follow their stiffness as the
/// element's shape changes (assumed_strain_keep), so their spring energy never grows without work.
#include "rkfem/core/simd.hpp"
#include "rkfem/core/types.hpp"
#include "rkfem/materials/objective_rate.hpp"

namespace rkfem
{
/// The FB hourglass mode a (hex8_modes order: xi eta, eta zeta, zeta xi, xi eta zeta) of the
/// assumed-strain mode m (1 = eta zeta, 2 = zeta xi, 3 = xi eta, 4 = xi eta zeta, 0-based here)
inline constexpr int kAssumedStrainMode[4] = {1, 2, 0, 3};

/// The co-rotational frame e[i][d] and sizes J[i] of an element from its axes r, s, t.
template <class T>
RKFEM_LANE_INLINE void assumed_strain_frame(const T r[3], const T s[3], const T t[3], T e[3][3], T J[3])
{
    auto normalize = [](T v[3])
    {
        const T inv = 1.0 / simd::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        for (int d = 0; d < 3; ++d)
            v[d] = v[d] * inv;
    };
    auto cross = [](const T a[3], const T b[3], T c[3])
    {
        c[0] = a[1] * b[2] - a[2] * b[1];
        c[1] = a[2] * b[0] - a[0] * b[2];
        c[2] = a[0] * b[1] - a[1] * b[0];
    };
    T u[3] = {r[0], r[1], r[2]}, v[3] = {s[0], s[1], s[2]}, w[3] = {t[0], t[1], t[2]};
    normalize(u);
    normalize(v);
    normalize(w);
    for (int pass = 0; pass < 3; ++pass)
    {
        T a[3], b[3], c[3];
        cross(v, w, a);
        cross(w, u, b);
        cross(u, v, c);
        for (int d = 0; d < 3; ++d)
        {
            u[d] = u[d] + a[d];
            v[d] = v[d] + b[d];
            w[d] = w[d] + c[d];
        }
        normalize(u);
        normalize(v);
        normalize(w);
    }
    cross(u, v, w);
    normalize(w);
    cross(w, u, v);
    for (int d = 0; d < 3; ++d)
    {
        e[0][d] = u[d];
        e[1][d] = v[d];
        e[2][d] = w[d];
    }
    J[0] = e[0][0] * r[0] + e[0][1] * r[1] + e[0][2] * r[2];
    J[1] = e[1][0] * s[0] + e[1][1] * s[1] + e[1][2] * s[2];
    J[2] = e[2][0] * t[0] + e[2][1] * t[1] + e[2][2] * t[2];
}

/// The share of the element's deviatoric strain increment dt d' that its own stress update took
/// elastically, r = (sigma_new - sigma_old - dt (W sigma_old - sigma_old W)) : d' / (2 mu dt d' : d')
/// in [0, 1] (Voigt, shear components d_ij and w = (W_01, W_12, W_20) of the tensors; the spin's
/// first-order turn of the old stress is not the material's): 1 for an elastic step, H / (3 mu +
/// H) for J2 flow with hardening modulus H along the flow direction, 0 on a perfectly plastic or
/// softening surface; 1 where d' vanishes (a pure hourglass or rigid motion). For materials with
/// history the hourglass stress grows by r times the elastic increment, so an element that flows
/// does not store elastic energy its material cannot hold.
template <class T>
RKFEM_LANE_INLINE T assumed_strain_tangent_share(const T so[6], const T sn[6], const T d[6], const T w[3], real_t mu,
                                                 real_t dt)
{
    // old stress as a tensor, and its turn W s - s W
    const T S[3][3] = {{so[0], so[3], so[5]}, {so[3], so[1], so[4]}, {so[5], so[4], so[2]}};
    const T zero = so[0] - so[0];
    const T Wt[3][3] = {{zero, w[0], -w[2]}, {-w[0], zero, w[1]}, {w[2], -w[1], zero}};
    T turn[3][3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
        {
            T t = zero;
            for (int k = 0; k < 3; ++k)
                t = t + Wt[i][k] * S[k][j] - S[i][k] * Wt[k][j];
            turn[i][j] = t;
        }
    const T ds[6] = {sn[0] - so[0] - dt * turn[0][0], sn[1] - so[1] - dt * turn[1][1], sn[2] - so[2] - dt * turn[2][2],
                     sn[3] - so[3] - dt * turn[0][1], sn[4] - so[4] - dt * turn[1][2], sn[5] - so[5] - dt * turn[2][0]};
    const T m = (d[0] + d[1] + d[2]) * (1.0 / 3.0);
    const T d0 = d[0] - m, d1 = d[1] - m, d2 = d[2] - m;
    const T num = ds[0] * d0 + ds[1] * d1 + ds[2] * d2 + 2.0 * (ds[3] * d[3] + ds[4] * d[4] + ds[5] * d[5]);
    const T dd = d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * (d[3] * d[3] + d[4] * d[4] + d[5] * d[5]);
    // eps: a strain rate of 1e-10 1/s squared, far below any a run resolves
    const real_t eps = 2.0 * mu * dt * 1e-20 + 1e-300; // (and dt = 0: the first pass)
    const T r = (num + eps) / (2.0 * mu * dt * dd + eps);
    return simd::min(simd::max(r, zero), zero + 1.0);
}

/// The generalized forces Q[m][i] (frame components, assumed-strain modes m) of an hourglass
/// stress S[m][i] (an increment), for sizes J and Poisson's ratio nu.
template <class T> RKFEM_LANE_INLINE void assumed_strain_forces(const T S[4][3], const T J[3], real_t nu, T Q[4][3])
{
    const real_t c1 = 2.0 / (1.0 - nu), c2 = 2.0 * nu / (1.0 - nu), c3 = 2.0 * (1.0 + nu) / 3.0;
    T Tm[4][3];
    for (int m = 0; m < 4; ++m)
        for (int i = 0; i < 3; ++i)
            Tm[m][i] = J[i] * S[m][i];
    const T H11 = J[1] * J[2] / J[0], H22 = J[0] * J[2] / J[1], H33 = J[0] * J[1] / J[2];
    const T H12 = J[2], H13 = J[1], H23 = J[0];
    // shear (x1, y2, z3)
    Q[0][0] = (H22 + H33) * Tm[0][0] + H12 * Tm[1][1] + H13 * Tm[2][2];
    Q[1][1] = (H11 + H33) * Tm[1][1] + H12 * Tm[0][0] + H23 * Tm[2][2];
    Q[2][2] = (H11 + H22) * Tm[2][2] + H13 * Tm[0][0] + H23 * Tm[1][1];
    // bending, coupled in pairs through Poisson's ratio
    Q[1][0] = c1 * H11 * Tm[1][0] + c2 * H12 * Tm[0][1]; // x2, y1
    Q[0][1] = c1 * H22 * Tm[0][1] + c2 * H12 * Tm[1][0];
    Q[2][0] = c1 * H11 * Tm[2][0] + c2 * H13 * Tm[0][2]; // x3, z1
    Q[0][2] = c1 * H33 * Tm[0][2] + c2 * H13 * Tm[2][0];
    Q[2][1] = c1 * H22 * Tm[2][1] + c2 * H23 * Tm[1][2]; // y3, z2
    Q[1][2] = c1 * H33 * Tm[1][2] + c2 * H23 * Tm[2][1];
    // warping
    Q[3][0] = c3 * H11 * Tm[3][0];
    Q[3][1] = c3 * H22 * Tm[3][1];
    Q[3][2] = c3 * H33 * Tm[3][2];
}

/// The share keep[m][i] of each stored generalized force an element keeps as its shape goes from
/// sizes Jo (when the forces were last updated; 0: never) to Jn, before the step's increment:
///   keep = min(1, sqrt(k(Jn) / k(Jo))),
/// k the component's own stiffness, the diagonal of assumed_strain_forces (shear x1: H_22 + H_33,
/// bending x2: H_11, warping x4: H_11, and cyclic; the constants cancel). A stored component is a
/// spring of energy Q^2 / 2k: where its stiffness falls (a crushed element's H_22 = J_1 J_3 / J_2
/// as J_1 shrinks) the kept force holds that energy, so it never grows without work; where the
/// stiffness rises the force is kept and the difference is dissipated. The increment then adds
/// k dq, and the step's work (Q_kept + Q_new) / 2 . dq is exactly the change of Q^2 / 2k: the
/// hourglass work of a component never falls below its stored energy, so the form cannot give
/// back more than it took (the couplings between components, through nu and the off-diagonal
/// H_ij, are left out of the rule). Without it, forces stored while an element was stiff did
/// work as it flattened: Table 3's case 1.2 at 1/4 in booked -1,977 J of hourglass energy.
template <class T> RKFEM_LANE_INLINE void assumed_strain_keep(const T Jo[3], const T Jn[3], T keep[4][3])
{
    auto diagonal = [](const T J[3], T k[4][3])
    {
        const T H11 = J[1] * J[2] / J[0], H22 = J[0] * J[2] / J[1], H33 = J[0] * J[1] / J[2];
        k[0][0] = H22 + H33; // shear x1, y2, z3
        k[1][1] = H11 + H33;
        k[2][2] = H11 + H22;
        k[1][0] = H11; // bending x2, y1, x3, z1, y3, z2
        k[0][1] = H22;
        k[2][0] = H11;
        k[0][2] = H33;
        k[2][1] = H22;
        k[1][2] = H33;
        k[3][0] = H11; // warping
        k[3][1] = H22;
        k[3][2] = H33;
    };
    T ko[4][3], kn[4][3];
    diagonal(Jo, ko); // Jo = 0: NaN, and min keeps the whole force
    diagonal(Jn, kn);
    const T one = Jn[0] - Jn[0] + 1.0;
    for (int m = 0; m < 4; ++m)
        for (int i = 0; i < 3; ++i)
            keep[m][i] = simd::min(one, simd::sqrt(kn[m][i] / ko[m][i]));
}

/// A stored hourglass force Q after the step's increment dQ of the full (elastic) stiffness, in
/// a material that took the share r of the step elastically (assumed_strain_tangent_share): a
/// load (|Q| grows) takes r dQ; an unload takes the whole dQ back towards zero, and r of what
/// goes past it. A spring loaded while the material was elastic so gives back what it stored
/// even where the material flows now: scaling the unloads too left the stored force in place as
/// its displacement went back, and it then did work on the element (Table 3's case 1.2 at 1/4 in:
/// -1.2 kJ of target hourglass energy). Written with selects as products, so that T may be a lane
/// vector: where_negative(x, 1) is 1 where x < 0.
template <class T> RKFEM_LANE_INLINE T scaled_hourglass_update(T Q, T dQ, T r)
{
    const T one = Q - Q + 1.0;
    const T full = Q + dQ;
    const T unloading = simd::where_negative(Q * dQ, one);  // the increment runs against Q
    const T crossing = simd::where_negative(full * Q, one); // and past zero
    const T unloaded = full - crossing * (one - r) * full;
    return (one - unloading) * simd::mul_add(r, dQ, Q) + unloading * unloaded;
}

/// A stabilization stress (nodal MSCNI sub-cell, NSNI sub-point, semi-Lagrangian face) after its
/// elastic update `s` from `old` (rotated by the parent's R, then the elastic increment), with
/// the increment's load taken at the parent material's elastic share r, component by component
/// as scaled_hourglass_update takes a hourglass force's: the old stress turned with the parent
/// is the stored force, the rest the increment.
template <class T> RKFEM_LANE_INLINE void scale_stabilization_load(const Rotation<T>& R, const T old[6], T r, T s[6])
{
    T t0 = old[0], t1 = old[1], t2 = old[2], t3 = old[3], t4 = old[4], t5 = old[5];
    rotate_stress(R, t0, t1, t2, t3, t4, t5);
    const T turned[6] = {t0, t1, t2, t3, t4, t5};
    for (int k = 0; k < 6; ++k)
        s[k] = scaled_hourglass_update(turned[k], s[k] - turned[k], r);
}
} // namespace rkfem
