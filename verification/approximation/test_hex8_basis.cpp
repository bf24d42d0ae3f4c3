// Hex8 basis on distorted elements: partition of unity, linear completeness and gradient
// consistency to round-off; the Flanagan-Belytschko volume gradient equals the exact integral of
// grad N over the element (2x2x2 Gauss is exact for it).
#include <gtest/gtest.h>
#include <random>

#include "rkfem/approximation/fem/hex8_basis.hpp"
#include "rkfem/approximation/fem/hex8_volume_gradient.hpp"

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

TEST(Hex8VolumeGradient, CompileTimeTableEqualsTheComputedOne)
{
    // the kernels' constant table (Hex8VolumeGradientFixed) is the computed table term by term:
    // same pairs, and for each node the same nine (pair, coefficient) terms, coefficients +-1/12
    const auto& tab = hex8_volume_gradient_table();
    using VG = Hex8VolumeGradientFixed;
    ASSERT_EQ(tab.n_pairs, VG::n_pairs);
    for (int p = 0; p < VG::n_pairs; ++p)
    {
        EXPECT_EQ(tab.pair_k[p], VG::pairs[p][0]) << p;
        EXPECT_EQ(tab.pair_l[p], VG::pairs[p][1]) << p;
    }
    for (int I = 0; I < 8; ++I)
    {
        ASSERT_EQ(tab.node_offsets[I + 1] - tab.node_offsets[I], 9) << I;
        for (int t = 0; t < 9; ++t)
        {
            const int k = tab.node_offsets[I] + t;
            EXPECT_EQ(tab.term_pair[k], VG::terms[I][t][0]) << I << " " << t;
            EXPECT_EQ(tab.term_coef[k], VG::terms[I][t][1] / 12.0) << I << " " << t;
        }
    }
}

// The hourglass butterflies equal the sums over the base vectors (exactly, on integers; to
// round-off on reals): s_a = sum_J Gamma_aJ y_J, and the transpose y_J = sum_a Gamma_aJ s_a.
TEST(Hex8Basis, HourglassButterfliesEqualTheBaseVectorSums)
{
    std::mt19937 gen(2);
    std::uniform_int_distribution<int> k(-1000, 1000);
    for (int trial = 0; trial < 100; ++trial)
    {
        real_t y[8], q[4];
        for (auto& v : y)
            v = k(gen);
        for (auto& v : q)
            v = k(gen);
        real_t s[4], z[8];
        hourglass_sums(y[0], y[1], y[2], y[3], y[4], y[5], y[6], y[7], s[0], s[1], s[2], s[3]);
        hourglass_spread(q[0], q[1], q[2], q[3], z[0], z[1], z[2], z[3], z[4], z[5], z[6], z[7]);
        for (int a = 0; a < 4; ++a)
        {
            real_t ref = 0.0;
            for (int J = 0; J < 8; ++J)
                ref += hex8_hourglass_base[a][J] * y[J];
            ASSERT_EQ(s[a], ref) << "mode " << a;
        }
        for (int J = 0; J < 8; ++J)
        {
            real_t ref = 0.0;
            for (int a = 0; a < 4; ++a)
                ref += hex8_hourglass_base[a][J] * q[a];
            ASSERT_EQ(z[J], ref) << "node " << J;
        }
    }
}
