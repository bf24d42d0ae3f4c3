#pragma once
/// @file hex8_modes.hpp
/// The 8-node hex in its mode basis. A nodal field y_I is
///   y(xi, eta, zeta) = (1/8) sum_k Y_k phi_k,  phi = 1, xi, eta, zeta, xi eta, eta zeta, zeta xi, xi eta zeta,
///   Y_k = sum_I phi_k(node I) y_I,
/// and the phi_k at the nodes are orthogonal (sum_I phi_k phi_m = 8 delta_km). Modes 4-7 are the
/// Flanagan-Belytschko hourglass base vectors (hex8_hourglass_base, in that order), so the
/// hourglass sums over the nodes are modes too. The butterflies below go from nodes to modes and
/// back in 23 additions per component each way.
///
/// In modes, the uniform gradient with exact volume integration (Flanagan-Belytschko, as
/// hex8_volume_gradient) is short. With x = (1/8) sum_k A_k phi_k, the volume
///   V = integral of det(dx/dxi) = (1/64) [A1 . (A2 x A3) + (1/3) (A1 . (A4 x A6) + A2 . (A5 x A4) + A3 . (A6 x A5))]
/// (of the 64 products in the determinant only these have even powers of every coordinate; the
/// twist mode A7 drops out), so B_k = dV/dA_k takes 12 cross products and the nodal gradient is
///   b_I = dV/dx_I = sum_k phi_k(I) B_k  (B_0 = B_7 = 0),
/// one inverse butterfly. Kernels stay in modes: L = (1/V) sum_k U_k (x) B_k with U the modes of
/// the velocity, and the nodal force sum_j T_ij b_jI + sum_a Gamma_aI Q_ai is the inverse
/// butterfly of F_ik = T_ij B_kj plus Q in the hourglass modes.
///
/// T is real_t or a lane vector (simd::dvec); simd::mul_add fuses on vectors only.
#include "rkfem/core/simd.hpp"
#include "rkfem/core/types.hpp"

namespace rkfem
{
/// Mode indices (phi_k above).
enum Hex8Mode : int
{
    mode_const = 0,
    mode_xi = 1,
    mode_eta = 2,
    mode_zeta = 3,
    mode_xi_eta = 4,      ///< hourglass base vector 0
    mode_eta_zeta = 5,    ///< hourglass base vector 1
    mode_zeta_xi = 6,     ///< hourglass base vector 2
    mode_xi_eta_zeta = 7, ///< hourglass base vector 3
};

/// Y[k][d] = sum_I phi_k(I) y[I][d] for all 8 modes.
template <class T> RKFEM_LANE_INLINE void hex8_to_modes(const T y[8][3], T Y[8][3])
{
    for (int d = 0; d < 3; ++d)
    {
        // zeta-even (s) and zeta-odd (t) parts on the face corners j = 0..3 (xi, eta) = (-,-),
        // (+,-), (+,+), (-,+); on a face, xi = (p2 - p0) + (p1 - p3), eta = (p2 - p0) - (p1 - p3)
        const T s0 = y[4][d] + y[0][d], s1 = y[5][d] + y[1][d], s2 = y[6][d] + y[2][d], s3 = y[7][d] + y[3][d];
        const T t0 = y[4][d] - y[0][d], t1 = y[5][d] - y[1][d], t2 = y[6][d] - y[2][d], t3 = y[7][d] - y[3][d];
        const T ds = s2 - s0, es = s1 - s3, ps = s0 + s2, qs = s1 + s3;
        const T dt = t2 - t0, et = t1 - t3, pt = t0 + t2, qt = t1 + t3;
        Y[mode_const][d] = ps + qs;
        Y[mode_xi][d] = ds + es;
        Y[mode_eta][d] = ds - es;
        Y[mode_xi_eta][d] = ps - qs;
        Y[mode_zeta][d] = pt + qt;
        Y[mode_zeta_xi][d] = dt + et;
        Y[mode_eta_zeta][d] = dt - et;
        Y[mode_xi_eta_zeta][d] = pt - qt;
    }
}

/// y[I][d] = sum_k phi_k(I) F[k][d] for a field without constant mode (F[0] is not read: taken
/// as zero, as for the nodal forces of one element, which sum to zero).
template <class T> RKFEM_LANE_INLINE void hex8_from_modes_no_mean(const T F[8][3], T y[8][3])
{
    for (int d = 0; d < 3; ++d)
    {
        // zeta-even part on the face corners: F1 xi + F2 eta + F4 xi eta
        const T a = F[mode_xi][d] + F[mode_eta][d], b = F[mode_xi][d] - F[mode_eta][d];
        const T f4 = F[mode_xi_eta][d];
        const T p0 = f4 - a, p1 = b - f4, p2 = f4 + a, m3 = f4 + b; // p3 = -m3
        // zeta-odd part: F3 + F6 xi + F5 eta + F7 xi eta
        const T ao = F[mode_zeta_xi][d] + F[mode_eta_zeta][d], bo = F[mode_zeta_xi][d] - F[mode_eta_zeta][d];
        const T co = F[mode_zeta][d] + F[mode_xi_eta_zeta][d], dO = F[mode_zeta][d] - F[mode_xi_eta_zeta][d];
        const T t0 = co - ao, t1 = dO + bo, t2 = co + ao, t3 = dO - bo;
        y[0][d] = p0 - t0;
        y[1][d] = p1 - t1;
        y[2][d] = p2 - t2;
        y[3][d] = -(m3 + t3);
        y[4][d] = p0 + t0;
        y[5][d] = p1 + t1;
        y[6][d] = p2 + t2;
        y[7][d] = t3 - m3;
    }
}

namespace detail
{
/// p x q + r per component (two fused steps on vectors)
template <class T> RKFEM_LANE_INLINE void cross_add(const T p[3], const T q[3], const T r[3], T out[3])
{
    out[0] = simd::mul_add(p[1], q[2], simd::neg_mul_add(p[2], q[1], r[0]));
    out[1] = simd::mul_add(p[2], q[0], simd::neg_mul_add(p[0], q[2], r[1]));
    out[2] = simd::mul_add(p[0], q[1], simd::neg_mul_add(p[1], q[0], r[2]));
}
template <class T> RKFEM_LANE_INLINE void cross_scaled(const T p[3], const T q[3], real_t s, T out[3])
{
    for (int d = 0; d < 3; ++d)
    {
        const int e = (d + 1) % 3, f = (d + 2) % 3;
        out[d] = simd::neg_mul_add(p[f], q[e], p[e] * q[f]) * s;
    }
}
} // namespace detail

/// B[k] = dV/dA_k from the position modes A (hex8_to_modes of the coordinates); B[0] = B[7] = 0.
/// Returns V = (1/3) sum_k B_k . A_k (Euler's theorem: V is cubic in A).
template <class T> RKFEM_LANE_INLINE T hex8_mode_volume_gradient(const T A[8][3], T B[8][3])
{
    T c[3];
    // B1 = (1/64) [A2 x A3 + (1/3) A4 x A6], and cyclically
    detail::cross_scaled(A[4], A[6], 1.0 / 3.0, c);
    detail::cross_add(A[2], A[3], c, B[1]);
    detail::cross_scaled(A[5], A[4], 1.0 / 3.0, c);
    detail::cross_add(A[3], A[1], c, B[2]);
    detail::cross_scaled(A[6], A[5], 1.0 / 3.0, c);
    detail::cross_add(A[1], A[2], c, B[3]);
    // B4 = (1/192) [A6 x A1 + A2 x A5], B5 = (1/192) [A4 x A2 + A3 x A6], B6 = (1/192) [A1 x A4 + A5 x A3]
    detail::cross_scaled(A[2], A[5], 1.0, c);
    detail::cross_add(A[6], A[1], c, B[4]);
    detail::cross_scaled(A[3], A[6], 1.0, c);
    detail::cross_add(A[4], A[2], c, B[5]);
    detail::cross_scaled(A[5], A[3], 1.0, c);
    detail::cross_add(A[1], A[4], c, B[6]);
    for (int d = 0; d < 3; ++d)
    {
        B[1][d] = B[1][d] * (1.0 / 64.0);
        B[2][d] = B[2][d] * (1.0 / 64.0);
        B[3][d] = B[3][d] * (1.0 / 64.0);
        B[4][d] = B[4][d] * (1.0 / 192.0);
        B[5][d] = B[5][d] * (1.0 / 192.0);
        B[6][d] = B[6][d] * (1.0 / 192.0);
        B[0][d] = B[7][d] = T{};
    }
    T v = B[1][0] * A[1][0];
    for (int k = 1; k <= 6; ++k)
        for (int d = k == 1 ? 1 : 0; d < 3; ++d)
            v = simd::mul_add(B[k][d], A[k][d], v);
    return v * (1.0 / 3.0);
}

/// The largest face area squared, from the position modes. On the face xi = +-1 the diagonals
/// cross to 8 u x w with u = (A2 +- A4)/8, w = (A3 +- A6)/8 (the face's eta and zeta modes), so
/// area^2 = |(A2 +- A4) x (A3 +- A6)|^2 / 256; the other faces likewise. As the element kernels'
/// characteristic length: area = |d1 x d2| / 2 with d1, d2 the face diagonals.
template <class T> RKFEM_LANE_INLINE T hex8_mode_max_face_area2(const T A[8][3])
{
    // (normal-direction mode pair, in-face mode pairs): xi faces (A2, A4 | A3, A6), eta faces
    // (A1, A4 | A3, A5), zeta faces (A1, A6 | A2, A5)
    static constexpr int face_modes[3][4] = {{2, 4, 3, 6}, {1, 4, 3, 5}, {1, 6, 2, 5}};
    auto area2 = [&](const int fm[4], bool plus) __attribute__((always_inline))
    {
        T u[3], w[3], n[3];
        for (int d = 0; d < 3; ++d)
        {
            u[d] = plus ? A[fm[0]][d] + A[fm[1]][d] : A[fm[0]][d] - A[fm[1]][d];
            w[d] = plus ? A[fm[2]][d] + A[fm[3]][d] : A[fm[2]][d] - A[fm[3]][d];
        }
        detail::cross_scaled(u, w, 1.0 / 16.0, n);
        return simd::mul_add(n[2], n[2], simd::mul_add(n[1], n[1], n[0] * n[0]));
    };
    T amax = area2(face_modes[0], true);
    amax = simd::max(amax, area2(face_modes[0], false));
    for (int f = 1; f < 3; ++f)
    {
        amax = simd::max(amax, area2(face_modes[f], true));
        amax = simd::max(amax, area2(face_modes[f], false));
    }
    return amax;
}
} // namespace rkfem
