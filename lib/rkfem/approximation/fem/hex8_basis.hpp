#pragma once
/// @file hex8_basis.hpp
/// Trilinear 8-node hexahedron: shape functions and natural derivatives at a point, into
/// caller-owned arrays (no allocation). Node I sits at natural coordinates hex8_nodes[I].
#include <array>

#include "rkfem/core/types.hpp"

namespace rkfem
{
inline constexpr std::array<std::array<real_t, 3>, 8> hex8_nodes{{
    {-1, -1, -1},
    {+1, -1, -1},
    {+1, +1, -1},
    {-1, +1, -1},
    {-1, -1, +1},
    {+1, -1, +1},
    {+1, +1, +1},
    {-1, +1, +1},
}};

/// N_I(xi) for I = 0..7.
inline void hex8_shape(const real_t xi[3], real_t N[8])
{
    for (int I = 0; I < 8; ++I)
        N[I] = 0.125 * (1 + hex8_nodes[I][0] * xi[0]) * (1 + hex8_nodes[I][1] * xi[1]) * (1 + hex8_nodes[I][2] * xi[2]);
}

/// dN_I/dxi_a, stored dN[I][a].
inline void hex8_shape_derivatives(const real_t xi[3], real_t dN[8][3])
{
    for (int I = 0; I < 8; ++I)
    {
        const real_t a = hex8_nodes[I][0], b = hex8_nodes[I][1], c = hex8_nodes[I][2];
        dN[I][0] = 0.125 * a * (1 + b * xi[1]) * (1 + c * xi[2]);
        dN[I][1] = 0.125 * b * (1 + a * xi[0]) * (1 + c * xi[2]);
        dN[I][2] = 0.125 * c * (1 + a * xi[0]) * (1 + b * xi[1]);
    }
}

/// Gradients dN_I/dx at natural point xi for an element with nodal coordinates xe[I][d];
/// returns det J. dNdx[I][d].
inline real_t hex8_gradients(const real_t xe[8][3], const real_t xi[3], real_t dNdx[8][3])
{
    real_t dN[8][3];
    hex8_shape_derivatives(xi, dN);
    Mat3 J = Mat3::Zero(); // J(a, d) = dx_d / dxi_a
    for (int I = 0; I < 8; ++I)
        for (int a = 0; a < 3; ++a)
            for (int d = 0; d < 3; ++d)
                J(a, d) += dN[I][a] * xe[I][d];
    const real_t det = J.determinant();
    const Mat3 Jinv = J.inverse();
    for (int I = 0; I < 8; ++I)
        for (int d = 0; d < 3; ++d)
            dNdx[I][d] = Jinv(d, 0) * dN[I][0] + Jinv(d, 1) * dN[I][1] + Jinv(d, 2) * dN[I][2];
    return det;
}

/// Flanagan-Belytschko hourglass base vectors Gamma_alpha (alpha = 0..3) over nodes 0..7:
/// xi*eta, eta*zeta, zeta*xi, xi*eta*zeta evaluated at the nodes.
inline constexpr std::array<std::array<real_t, 8>, 4> hex8_hourglass_base{{
    {+1, -1, +1, -1, +1, -1, +1, -1},
    {+1, +1, -1, -1, -1, -1, +1, +1},
    {+1, -1, -1, +1, -1, +1, +1, -1},
    {-1, +1, -1, +1, +1, -1, +1, -1},
}};

} // namespace rkfem
