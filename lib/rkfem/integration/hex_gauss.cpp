#include "rkfem/integration/hex_gauss.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "rkfem/approximation/fem/hex8_basis.hpp"
#include "rkfem/core/error.hpp"

namespace rkfem
{
IntegrationOperator build_hex_gauss(const HexMesh& mesh, int n)
{
    RKFEM_REQUIRE(n == 1 || n == 2, "hex Gauss operator: " << n << " points per direction; expected 1 or 2");
    const real_t g = n == 1 ? 0.0 : 1.0 / std::sqrt(3.0);
    const real_t wg = n == 1 ? 2.0 : 1.0;
    const index_t ne = mesh.n_elements();
    const std::size_t np = static_cast<std::size_t>(ne) * n * n * n;
    IntegrationOperator op;
    op.weight.reserve(np);
    op.position.reserve(3 * np);
    op.owner.assign(np, -1);
    op.offsets.reserve(np + 1);
    op.nodes.reserve(8 * np);
    op.grad.reserve(24 * np);
    for (index_t e = 0; e < ne; ++e)
    {
        real_t xe[8][3];
        std::array<int, 8> order{};
        for (int I = 0; I < 8; ++I)
        {
            order[I] = I;
            for (int d = 0; d < 3; ++d)
                xe[I][d] = mesh.x[3 * mesh.conn[8 * e + I] + d];
        }
        // entries of a point are in ascending node order
        std::sort(order.begin(), order.end(),
                  [&](int a, int b) { return mesh.conn[8 * e + a] < mesh.conn[8 * e + b]; });
        for (int k = 0; k < n; ++k)
            for (int j = 0; j < n; ++j)
                for (int i = 0; i < n; ++i)
                {
                    const real_t xi[3] = {(2 * i - 1) * g, (2 * j - 1) * g, (2 * k - 1) * g}; // g = 0: centre
                    real_t N[8], dNdx[8][3];
                    hex8_shape(xi, N);
                    const real_t detJ = hex8_gradients(xe, xi, dNdx);
                    RKFEM_REQUIRE(detJ > 0, "hex Gauss operator: element " << e << " has det J = " << detJ
                                                                           << " at a Gauss point (inverted)");
                    op.weight.push_back(wg * wg * wg * detJ);
                    for (int d = 0; d < 3; ++d)
                    {
                        real_t x = 0;
                        for (int I = 0; I < 8; ++I)
                            x += N[I] * xe[I][d];
                        op.position.push_back(x);
                    }
                    for (int I : order)
                    {
                        op.nodes.push_back(mesh.conn[8 * e + I]);
                        for (int d = 0; d < 3; ++d)
                            op.grad.push_back(dNdx[I][d]);
                    }
                    op.offsets.push_back(op.n_entries());
                }
    }
    return op;
}
} // namespace rkfem
