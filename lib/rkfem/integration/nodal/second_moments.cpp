/// @file second_moments.cpp
/// Nodal second moments of a hex mesh's dual cells (NSNI's weights), and of cubes.
#include "rkfem/integration/nodal/nodal_common.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <utility>

#include <omp.h>

#include "rkfem/approximation/rk/rk_region_values.hpp"
#include "rkfem/approximation/rk/rk_translates.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/core/mark_set.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/setup_progress.hpp"
#include "rkfem/integration/stencil_table.hpp"

namespace rkfem
{
using namespace nodal_detail;

std::vector<real_t> nodal_second_moments(const HexMesh& mesh)
{
    // node by node over its sub-hexes in element order, each sub-hex's 8 Gauss points at once
    // (sub_hex_points), in parallel
    std::vector<index_t> offsets, slots;
    node_element_incidence(mesh, offsets, slots);
    std::vector<real_t> m(3 * static_cast<std::size_t>(mesh.n_nodes()), 0.0);
    parallel_for("rkfem::nodal_second_moments", mesh.n_nodes(),
                 [&](index_t L)
                 {
                     real_t xe[8][3];
                     alignas(64) real_t det[8], x[3][8];
                     for (index_t k = offsets[L]; k < offsets[L + 1]; ++k)
                     {
                         element_coordinates(mesh, slots[k] / 8, xe);
                         sub_hex_points(xe, slots[k] % 8, det, x);
                         for (int d = 0; d < 3; ++d)
                         {
                             // the points' terms in the lanes, summed pairwise
                             const real_t xL = mesh.x[3 * static_cast<std::size_t>(L) + d];
                             alignas(64) real_t t[8];
                             for (int q = 0; q < 8; ++q)
                             {
                                 const real_t r = x[d][q] - xL;
                                 t[q] = det[q] * r * r;
                             }
                             for (int w = 4; w > 0; w /= 2)
                                 for (int q = 0; q < w; ++q)
                                     t[q] += t[q + w];
                             m[3 * static_cast<std::size_t>(L) + d] +=
                                 0.125 * t[0]; // sub-hex Jacobian 1/8 of the element's
                         }
                     }
                 });
    return m;
}

std::vector<real_t> nodal_second_moments_plain(const HexMesh& mesh)
{
    // node by node over its sub-hexes in element order (the incidence lists' order: each node's
    // sums in the order of an element loop), in parallel
    std::vector<index_t> offsets, slots;
    node_element_incidence(mesh, offsets, slots);
    std::vector<real_t> m(3 * static_cast<std::size_t>(mesh.n_nodes()), 0.0);
    const SubHexGauss& gauss = sub_hex_gauss();
    parallel_for("rkfem::nodal_second_moments_plain", mesh.n_nodes(),
                 [&](index_t L)
                 {
                     real_t xe[8][3];
                     for (index_t k = offsets[L]; k < offsets[L + 1]; ++k)
                     {
                         // the sub-hex of local node a: xi_d between 0 and the node's natural coordinate
                         const index_t e = slots[k] / 8;
                         const int a = slots[k] % 8;
                         element_coordinates(mesh, e, xe);
                         for (int q = 0; q < 8; ++q)
                         {
                             // det J as hex8_gradients computes it (J(a, d) = dx_d / dxi_a)
                             const real_t(&N)[8] = gauss.N[a][q];
                             const real_t(&dN)[8][3] = gauss.dN[a][q];
                             Mat3 J = Mat3::Zero();
                             for (int I = 0; I < 8; ++I)
                                 for (int b = 0; b < 3; ++b)
                                     for (int d = 0; d < 3; ++d)
                                         J(b, d) += dN[I][b] * xe[I][d];
                             const real_t w = 0.125 * J.determinant(); // sub-hex Jacobian 1/8 of the element's
                             for (int d = 0; d < 3; ++d)
                             {
                                 real_t x = 0.0;
                                 for (int I = 0; I < 8; ++I)
                                     x += N[I] * xe[I][d];
                                 const real_t r = x - mesh.x[3 * static_cast<std::size_t>(L) + d];
                                 m[3 * static_cast<std::size_t>(L) + d] += w * r * r;
                             }
                         }
                     }
                 });
    return m;
}

std::vector<real_t> cube_second_moments(const std::vector<real_t>& volume)
{
    std::vector<real_t> m(3 * volume.size());
    for (std::size_t i = 0; i < volume.size(); ++i)
    {
        const real_t s = std::cbrt(volume[i]);
        m[3 * i] = m[3 * i + 1] = m[3 * i + 2] = volume[i] * s * s / 12.0;
    }
    return m;
}
} // namespace rkfem
