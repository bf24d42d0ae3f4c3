#pragma once
/// @file hex8_volume_gradient.hpp
/// The Flanagan-Belytschko uniform gradient with exact volume integration:
///   b_I = dV/dx_I = integral over the element of grad N_I dV,
/// written as b_I = sum over node pairs (K < L) of c_IKL (x_K cross x_L). The coefficients are
/// computed once, exactly (2x2x2 Gauss integrates the cubic-per-direction integrand exactly), and
/// stored as a sparse table; the volume follows from Euler's theorem, V = (1/3) sum_I b_I . x_I.
#include <array>

#include "rkfem/core/types.hpp"

namespace rkfem
{
struct Hex8VolumeGradientTable
{
    static constexpr int max_pairs = 28;
    static constexpr int max_terms = 8 * 28;
    int n_pairs = 0;
    std::array<int, max_pairs> pair_k{}; ///< first node of pair p
    std::array<int, max_pairs> pair_l{}; ///< second node of pair p
    int n_terms = 0;
    std::array<int, max_terms> term_node{}; ///< I
    std::array<int, max_terms> term_pair{}; ///< p
    std::array<real_t, max_terms> term_coef{};
    std::array<int, 9> node_offsets{}; ///< terms of node I are [node_offsets[I], node_offsets[I + 1])
};

/// The table (built on first use, thread-safe).
const Hex8VolumeGradientTable& hex8_volume_gradient_table();

/// The same table as compile-time constants for the element kernels (loops over it unroll and
/// keep the cross products in registers): every coefficient is +-1/12, nine terms per node. The
/// verification suite checks it against the computed table term by term.
struct Hex8VolumeGradientFixed
{
    static constexpr int n_pairs = 24;
    static constexpr std::array<std::array<int, 2>, n_pairs> pairs{{
        {1, 2}, {1, 3}, {1, 4}, {1, 5}, {2, 3}, {3, 4}, {3, 7}, {4, 5}, {4, 7}, {0, 2}, {0, 3}, {0, 4},
        {0, 5}, {2, 5}, {2, 6}, {5, 6}, {0, 1}, {1, 6}, {3, 6}, {6, 7}, {0, 7}, {2, 7}, {5, 7}, {4, 6}}};
    /// terms[I][t] = {pair, sign}: b_I = (1/12) sum_t sign x (x_K cross x_L) of the pair
    static constexpr std::array<std::array<std::array<int, 2>, 9>, 8> terms{{
        {{{0, -1}, {1, -1}, {2, 1}, {3, 1}, {4, -1}, {5, -1}, {6, -1}, {7, -1}, {8, 1}}},
        {{{9, 1}, {10, 1}, {11, -1}, {12, -1}, {4, -1}, {13, 1}, {14, 1}, {7, -1}, {15, -1}}},
        {{{16, -1}, {10, 1}, {1, 1}, {3, -1}, {17, -1}, {18, 1}, {6, 1}, {15, -1}, {19, -1}}},
        {{{16, -1}, {9, -1}, {11, 1}, {20, 1}, {0, -1}, {14, -1}, {21, -1}, {8, 1}, {19, -1}}},
        {{{16, 1}, {10, -1}, {12, 1}, {20, -1}, {3, 1}, {6, -1}, {15, 1}, {22, 1}, {19, 1}}},
        {{{16, 1}, {11, -1}, {0, 1}, {2, -1}, {17, 1}, {14, 1}, {23, -1}, {8, -1}, {19, 1}}},
        {{{0, 1}, {3, -1}, {4, 1}, {13, -1}, {21, 1}, {6, 1}, {7, 1}, {8, -1}, {22, -1}}},
        {{{10, -1}, {11, 1}, {4, 1}, {14, -1}, {5, 1}, {18, -1}, {7, 1}, {23, 1}, {15, 1}}}}};
};

/// b[I][d] = dV/dx_{I,d} for element coordinates xe[I][d]; returns V.
real_t hex8_volume_gradient(const real_t xe[8][3], real_t b[8][3]);
} // namespace rkfem
