#include "rkfem/approximation/fem/hex8_volume_gradient.hpp"

#include <algorithm>
#include <cmath>

#include "rkfem/approximation/fem/hex8_basis.hpp"

namespace rkfem
{
namespace
{
Hex8VolumeGradientTable build_table()
{
    // C[I][K][L] = integral of dN_I/dxi dN_K/deta dN_L/dzeta over the cube, so that
    // V = sum C_IKL x_I . (x_K x x_L).
    static real_t C[8][8][8] = {};
    const real_t g = 1.0 / std::sqrt(3.0);
    for (int a = 0; a < 2; ++a)
        for (int b = 0; b < 2; ++b)
            for (int c = 0; c < 2; ++c)
            {
                const real_t xi[3] = {a ? g : -g, b ? g : -g, c ? g : -g};
                real_t dN[8][3];
                hex8_shape_derivatives(xi, dN);
                for (int I = 0; I < 8; ++I)
                    for (int K = 0; K < 8; ++K)
                        for (int L = 0; L < 8; ++L)
                            C[I][K][L] += dN[I][0] * dN[K][1] * dN[L][2];
            }
    // dV/dx_P = sum_KL A_PKL (x_K x x_L), A_PKL = C_PKL + C_LPK + C_KLP; keep K < L.
    Hex8VolumeGradientTable t;
    int pair_id[8][8];
    for (auto& row : pair_id)
        for (int& v : row)
            v = -1;
    for (int P = 0; P < 8; ++P)
        for (int K = 0; K < 8; ++K)
            for (int L = K + 1; L < 8; ++L)
            {
                const real_t akl = C[P][K][L] + C[L][P][K] + C[K][L][P];
                const real_t alk = C[P][L][K] + C[K][P][L] + C[L][K][P];
                real_t coef = akl - alk;
                // coefficients are multiples of 1/12; snap away quadrature round-off
                if (std::abs(coef * 12.0 - std::round(coef * 12.0)) < 1e-10)
                    coef = std::round(coef * 12.0) / 12.0;
                if (std::abs(coef) < 1e-14)
                    continue;
                if (pair_id[K][L] < 0)
                {
                    pair_id[K][L] = t.n_pairs;
                    t.pair_k[t.n_pairs] = K;
                    t.pair_l[t.n_pairs] = L;
                    ++t.n_pairs;
                }
                t.term_node[t.n_terms] = P;
                t.term_pair[t.n_terms] = pair_id[K][L];
                t.term_coef[t.n_terms] = coef;
                ++t.n_terms;
            }
    // terms are generated node by node
    for (int k = 0; k < t.n_terms; ++k)
        t.node_offsets[t.term_node[k] + 1] = k + 1;
    for (int P = 1; P <= 8; ++P)
        t.node_offsets[P] = std::max(t.node_offsets[P], t.node_offsets[P - 1]);
    return t;
}
} // namespace

const Hex8VolumeGradientTable& hex8_volume_gradient_table()
{
    static const Hex8VolumeGradientTable table = build_table();
    return table;
}

real_t hex8_volume_gradient(const real_t xe[8][3], real_t b[8][3])
{
    const auto& t = hex8_volume_gradient_table();
    real_t cr[Hex8VolumeGradientTable::max_pairs][3];
    for (int p = 0; p < t.n_pairs; ++p)
    {
        const real_t* xk = xe[t.pair_k[p]];
        const real_t* xl = xe[t.pair_l[p]];
        cr[p][0] = xk[1] * xl[2] - xk[2] * xl[1];
        cr[p][1] = xk[2] * xl[0] - xk[0] * xl[2];
        cr[p][2] = xk[0] * xl[1] - xk[1] * xl[0];
    }
    // node by node (the terms are generated so): each b_I summed from zero in term order in
    // registers, not through b in memory term by term
    for (int I = 0; I < 8; ++I)
    {
        real_t s0 = 0.0, s1 = 0.0, s2 = 0.0;
        for (int k = t.node_offsets[I]; k < t.node_offsets[I + 1]; ++k)
        {
            const real_t c = t.term_coef[k];
            const real_t* r = cr[t.term_pair[k]];
            s0 += c * r[0];
            s1 += c * r[1];
            s2 += c * r[2];
        }
        b[I][0] = s0, b[I][1] = s1, b[I][2] = s2;
    }
    real_t V = 0.0;
    for (int I = 0; I < 8; ++I)
        V += b[I][0] * xe[I][0] + b[I][1] * xe[I][1] + b[I][2] * xe[I][2];
    return V / 3.0;
}
} // namespace rkfem
