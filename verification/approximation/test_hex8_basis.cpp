// Hex8 basis on distorted elements: partition of unity, linear completeness and gradient
// consistency to round-off; the Flanagan-Belytschko volume gradient equals the exact integral of
// grad N over the element (2x2x2 Gauss is exact for it).
#include <cmath>
#include <gtest/gtest.h>
#include <limits>
#include <random>

#include "rkfem/approximation/fem/hex8_basis.hpp"
#include "rkfem/approximation/fem/hex8_modes.hpp"
#include "rkfem/approximation/fem/hex8_volume_gradient.hpp"
#include "rkfem/core/simd.hpp"
#include "rkfem/discretization/hex_mesh.hpp"

using namespace rkfem;

namespace
{
void distorted_element(unsigned seed, real_t xe[8][3])
{
    std::mt19937 gen(seed);
    std::uniform_real_distribution<real_t> jitter(-0.2, 0.2);
    for (int I = 0; I < 8; ++I)
        for (int d = 0; d < 3; ++d)
            xe[I][d] = 0.5 * (1 + hex8_nodes[I][d]) * (1.0 + 0.3 * d) + jitter(gen);
}
} // namespace

TEST(Hex8Basis, PartitionOfUnityAndLinearCompletenessOnDistortedElements)
{
    const real_t A[3][3] = {{0.3, -1.2, 0.7}, {2.0, 0.1, -0.4}, {-0.9, 0.5, 1.1}};
    const real_t c[3] = {0.25, -3.0, 1.5};
    for (unsigned seed = 1; seed <= 20; ++seed)
    {
        real_t xe[8][3];
        distorted_element(seed, xe);
        const real_t pts[3][3] = {{0.1, -0.7, 0.4}, {-0.55, 0.3, 0.9}, {0.0, 0.0, 0.0}};
        for (const auto& xi : pts)
        {
            real_t N[8], dNdx[8][3];
            hex8_shape(xi, N);
            const real_t detj = hex8_gradients(xe, xi, dNdx);
            ASSERT_GT(detj, 0.0);
            real_t sum = 0, gsum[3] = {0, 0, 0};
            real_t x[3] = {0, 0, 0};
            for (int I = 0; I < 8; ++I)
            {
                sum += N[I];
                for (int d = 0; d < 3; ++d)
                {
                    gsum[d] += dNdx[I][d];
                    x[d] += N[I] * xe[I][d];
                }
            }
            EXPECT_NEAR(sum, 1.0, 1e-14);
            for (int d = 0; d < 3; ++d)
                EXPECT_NEAR(gsum[d], 0.0, 1e-12);
            // linear field u = A x + c: interpolation and gradient exact
            for (int i = 0; i < 3; ++i)
            {
                real_t u = 0, exact = c[i], grad[3] = {0, 0, 0};
                for (int j = 0; j < 3; ++j)
                    exact += A[i][j] * x[j];
                for (int I = 0; I < 8; ++I)
                {
                    real_t uI = c[i];
                    for (int j = 0; j < 3; ++j)
                        uI += A[i][j] * xe[I][j];
                    u += N[I] * uI;
                    for (int j = 0; j < 3; ++j)
                        grad[j] += dNdx[I][j] * uI;
                }
                EXPECT_NEAR(u, exact, 1e-12);
                for (int j = 0; j < 3; ++j)
                    EXPECT_NEAR(grad[j], A[i][j], 1e-12);
            }
        }
    }
}

TEST(Hex8VolumeGradient, EqualsExactIntegralOfShapeGradients)
{
    const auto& tab = hex8_volume_gradient_table();
    EXPECT_EQ(tab.n_terms % 8, 0); // each node has the same number of terms (symmetry)
    for (unsigned seed = 1; seed <= 20; ++seed)
    {
        real_t xe[8][3], b[8][3];
        distorted_element(seed, xe);
        const real_t V = hex8_volume_gradient(xe, b);
        // reference: 2x2x2 Gauss of grad N_I det J (exact: integrand is cubic per direction at most)
        real_t Vg = 0, bg[8][3] = {};
        const real_t g = 1.0 / std::sqrt(3.0);
        for (const auto& n : hex8_nodes)
        {
            const real_t xi[3] = {g * n[0], g * n[1], g * n[2]};
            real_t dNdx[8][3];
            const real_t detj = hex8_gradients(xe, xi, dNdx);
            Vg += detj;
            for (int I = 0; I < 8; ++I)
                for (int d = 0; d < 3; ++d)
                    bg[I][d] += dNdx[I][d] * detj;
        }
        EXPECT_NEAR(V, Vg, 1e-13 * Vg);
        real_t bscale = std::cbrt(Vg * Vg);
        real_t sum[3] = {0, 0, 0};
        real_t xb[3][3] = {};
        for (int I = 0; I < 8; ++I)
            for (int d = 0; d < 3; ++d)
            {
                EXPECT_NEAR(b[I][d], bg[I][d], 1e-13 * bscale) << "node " << I << " dir " << d;
                sum[d] += b[I][d];
                for (int j = 0; j < 3; ++j)
                    xb[j][d] += xe[I][j] * b[I][d];
            }
        // sum_I b_I = 0 (a rigid translation does not change V); sum_I x_jI b_iI = V delta_ij
        for (int d = 0; d < 3; ++d)
        {
            EXPECT_NEAR(sum[d], 0.0, 1e-13 * bscale);
            for (int j = 0; j < 3; ++j)
                EXPECT_NEAR(xb[j][d], j == d ? V : 0.0, 1e-13 * V);
        }
    }
}

namespace
{
/// phi_k at node I (hex8_modes.hpp): 1, xi, eta, zeta, xi eta, eta zeta, zeta xi, xi eta zeta
real_t mode_at_node(int k, int I)
{
    const real_t x = hex8_nodes[I][0], y = hex8_nodes[I][1], z = hex8_nodes[I][2];
    const real_t phi[8] = {1, x, y, z, x * y, y * z, z * x, x * y * z};
    return phi[k];
}
} // namespace

// The butterflies are the mode sums exactly (integer data: every sum is exact):
// Y_k = sum_I phi_k(I) y_I and y_I = sum_{k >= 1} phi_k(I) F_k; the hourglass modes 4-7 are the
// Flanagan-Belytschko base vectors in hex8_hourglass_base's order; the modes are orthogonal
// (to modes and back gives 8 y less the mean).
TEST(Hex8Modes, ButterfliesAreTheModeSums)
{
    std::mt19937 gen(2);
    std::uniform_int_distribution<int> k(-1000, 1000);
    for (int a = 0; a < 4; ++a)
        for (int I = 0; I < 8; ++I)
            ASSERT_EQ(mode_at_node(mode_xi_eta + a, I), hex8_hourglass_base[a][I]) << a << " " << I;
    for (int trial = 0; trial < 100; ++trial)
    {
        real_t y[8][3], F[8][3], Y[8][3], z[8][3], back[8][3];
        for (int I = 0; I < 8; ++I)
            for (int d = 0; d < 3; ++d)
            {
                y[I][d] = k(gen);
                F[I][d] = k(gen);
            }
        hex8_to_modes(y, Y);
        hex8_from_modes_no_mean(F, z);
        hex8_from_modes_no_mean(Y, back);
        for (int d = 0; d < 3; ++d)
        {
            for (int m = 0; m < 8; ++m)
            {
                real_t ref = 0.0;
                for (int I = 0; I < 8; ++I)
                    ref += mode_at_node(m, I) * y[I][d];
                ASSERT_EQ(Y[m][d], ref) << "mode " << m;
            }
            for (int I = 0; I < 8; ++I)
            {
                real_t ref = 0.0;
                for (int m = 1; m < 8; ++m)
                    ref += mode_at_node(m, I) * F[m][d];
                ASSERT_EQ(z[I][d], ref) << "node " << I;
                ASSERT_EQ(back[I][d], 8 * y[I][d] - Y[mode_const][d]) << "node " << I;
            }
        }
    }
}

// The mode form of the exact-volume gradient (12 cross products of position modes) is the
// nodal form (hex8_volume_gradient, itself checked against 2x2x2 Gauss above) to round-off on
// distorted elements: the same V and b_I = sum_k phi_k(I) B_k. The twist mode has no gradient
// (B_7 = 0): its component of the nodal b, sum_I Gamma_3I b_I, vanishes to round-off. The
// largest face area from the modes is the one from each face's diagonals (area = |d1 x d2| / 2).
TEST(Hex8Modes, VolumeGradientAndFaceAreasEqualTheNodalForms)
{
    for (unsigned seed = 1; seed <= 20; ++seed)
    {
        real_t xe[8][3], b[8][3], A[8][3], B[8][3], bm[8][3];
        distorted_element(seed, xe);
        const real_t V = hex8_volume_gradient(xe, b);
        hex8_to_modes(xe, A);
        const real_t Vm = hex8_mode_volume_gradient(A, B);
        hex8_from_modes_no_mean(B, bm);
        EXPECT_NEAR(Vm, V, 1e-14 * V);
        const real_t bscale = std::cbrt(V * V);
        for (int d = 0; d < 3; ++d)
        {
            EXPECT_EQ(B[mode_const][d], 0.0);
            EXPECT_EQ(B[mode_xi_eta_zeta][d], 0.0);
            real_t twist = 0.0;
            for (int I = 0; I < 8; ++I)
            {
                EXPECT_NEAR(bm[I][d], b[I][d], 1e-14 * bscale) << "node " << I << " dir " << d;
                twist += hex8_hourglass_base[3][I] * b[I][d];
            }
            EXPECT_NEAR(twist, 0.0, 1e-14 * bscale) << "dir " << d;
        }
        real_t amax2 = 0.0;
        for (const auto& f : hex_faces)
        {
            real_t d1[3], d2[3];
            for (int d = 0; d < 3; ++d)
            {
                d1[d] = xe[f[2]][d] - xe[f[0]][d];
                d2[d] = xe[f[3]][d] - xe[f[1]][d];
            }
            const real_t cx = d1[1] * d2[2] - d1[2] * d2[1], cy = d1[2] * d2[0] - d1[0] * d2[2],
                         cz = d1[0] * d2[1] - d1[1] * d2[0];
            amax2 = std::max(amax2, 0.25 * (cx * cx + cy * cy + cz * cz));
        }
        EXPECT_NEAR(hex8_mode_max_face_area2(A), amax2, 1e-14 * amax2);
    }
}

// The element kernels run the same templates on lane vectors (simd::dvec, fused multiply-adds):
// eight distorted elements in the lanes (one or two vectors) give each element's scalar volume, gradient modes and
// face area to round-off.
TEST(Hex8Modes, LaneVectorsGiveTheScalarResults)
{
    alignas(64) real_t xl[8][3][8];
    real_t Vs[8], Bs[8][8][3], as[8];
    for (int l = 0; l < 8; ++l)
    {
        real_t xe[8][3], A[8][3];
        distorted_element(100 + l, xe);
        for (int I = 0; I < 8; ++I)
            for (int d = 0; d < 3; ++d)
                xl[I][d][l] = xe[I][d];
        hex8_to_modes(xe, A);
        Vs[l] = hex8_mode_volume_gradient(A, Bs[l]);
        as[l] = hex8_mode_max_face_area2(A);
    }
    // the eight elements in batches of simd::kLanes (8 with AVX-512, else 4)
    alignas(64) real_t V[8], a2[8], Bl[8][3][8];
    for (int g = 0; g < 8; g += simd::kLanes)
    {
        simd::dvec x[8][3], A[8][3], B[8][3];
        for (int I = 0; I < 8; ++I)
            for (int d = 0; d < 3; ++d)
                x[I][d] = simd::load(xl[I][d] + g);
        hex8_to_modes(x, A);
        simd::store(V + g, hex8_mode_volume_gradient(A, B));
        simd::store(a2 + g, hex8_mode_max_face_area2(A));
        for (int k = 0; k < 8; ++k)
            for (int d = 0; d < 3; ++d)
                simd::store(Bl[k][d] + g, B[k][d]);
    }
    for (int l = 0; l < 8; ++l)
    {
        EXPECT_NEAR(V[l], Vs[l], 1e-14 * Vs[l]) << "lane " << l;
        EXPECT_NEAR(a2[l], as[l], 1e-14 * as[l]) << "lane " << l;
        const real_t bscale = std::cbrt(Vs[l] * Vs[l]);
        for (int k = 0; k < 8; ++k)
            for (int d = 0; d < 3; ++d)
                EXPECT_NEAR(Bl[k][d][l], Bs[l][k][d], 1e-15 * bscale) << "lane " << l << " mode " << k;
    }
}

// The lane helpers keep std::min / std::max's rule (a NaN first operand is kept: the kernels'
// time step and face-area maxima rely on it), and where_negative selects by sign.
TEST(Simd, LaneHelpersFollowTheScalarRules)
{
    const real_t nan = std::numeric_limits<real_t>::quiet_NaN();
    alignas(64) const real_t a[8] = {1.0, -2.0, nan, 3.0, nan, 0.0, -0.0, 5.0};
    alignas(64) const real_t b[8] = {2.0, -3.0, 1.0, nan, nan, -0.0, 0.0, -5.0};
    alignas(64) real_t mn[8], mx[8], wn[8], fm[8];
    for (int g = 0; g < 8; g += simd::kLanes)
    {
        const simd::dvec va = simd::load(a + g), vb = simd::load(b + g);
        simd::store(mn + g, simd::min(va, vb));
        simd::store(mx + g, simd::max(va, vb));
        simd::store(wn + g, simd::where_negative(va, vb));
        simd::store(fm + g, simd::mul_add(va, vb, simd::broadcast(0.5)));
    }
    for (int l = 0; l < 8; ++l)
    {
        const real_t rmin = std::min(a[l], b[l]), rmax = std::max(a[l], b[l]);
        EXPECT_TRUE(std::isnan(rmin) ? std::isnan(mn[l]) : mn[l] == rmin && std::signbit(mn[l]) == std::signbit(rmin))
            << "lane " << l;
        EXPECT_TRUE(std::isnan(rmax) ? std::isnan(mx[l]) : mx[l] == rmax && std::signbit(mx[l]) == std::signbit(rmax))
            << "lane " << l;
        const real_t rw = a[l] < 0.0 ? b[l] : 0.0;
        EXPECT_TRUE(std::isnan(rw) ? std::isnan(wn[l]) : wn[l] == rw) << "lane " << l;
        const real_t rf = std::fma(a[l], b[l], 0.5);
        EXPECT_TRUE(std::isnan(rf) ? std::isnan(fm[l]) : fm[l] == rf) << "lane " << l;
    }
}
