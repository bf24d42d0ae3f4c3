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

/// b[I][d] = dV/dx_{I,d} for element coordinates xe[I][d]; returns V.
real_t hex8_volume_gradient(const real_t xe[8][3], real_t b[8][3]);
} // namespace rkfem
