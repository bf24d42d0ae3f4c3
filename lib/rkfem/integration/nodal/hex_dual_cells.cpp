#include "rkfem/integration/nodal/hex_dual_cells.hpp"

#include <algorithm>
#include <cmath>

#include "rkfem/approximation/fem/hex8_basis.hpp"

namespace rkfem
{
namespace
{
/// Local element face lying on natural plane xi_d = sign (see hex_faces).
int element_face_of(int d, real_t sign)
{
    static constexpr int table[3][2] = {{5, 3}, {2, 4}, {0, 1}}; // [d][sign > 0]
    return table[d][sign > 0 ? 1 : 0];
}
} // namespace

void build_sub_hex_facet(const real_t xe[8][3], int a, int f, std::array<FacetPoint, 4>& out)
{
    const real_t g = 1.0 / std::sqrt(3.0);
    const real_t s[3] = {hex8_nodes[a][0], hex8_nodes[a][1], hex8_nodes[a][2]};
    const int d = f / 2, side = f % 2;
    const int p = (d + 1) % 3, q = (d + 2) % 3;
    const real_t xi_d = side == 0 ? 0.0 : s[d];
    // outward in natural space: -s_d on the internal facet, +s_d on the external one
    const real_t orient = side == 0 ? -s[d] : s[d];
    int k = 0;
    for (int i = 0; i < 2; ++i)
        for (int j = 0; j < 2; ++j, ++k)
        {
            real_t xi[3];
            xi[d] = xi_d;
            xi[p] = s[p] * 0.5 * (1.0 + (i == 0 ? -g : g));
            xi[q] = s[q] * 0.5 * (1.0 + (j == 0 ? -g : g));
            real_t N[8], dN[8][3];
            hex8_shape(xi, N);
            hex8_shape_derivatives(xi, dN);
            Vec3 x = Vec3::Zero(), xp = Vec3::Zero(), xq = Vec3::Zero();
            for (int I = 0; I < 8; ++I)
                for (int c = 0; c < 3; ++c)
                {
                    x[c] += N[I] * xe[I][c];
                    xp[c] += dN[I][p] * xe[I][c];
                    xq[c] += dN[I][q] * xe[I][c];
                }
            FacetPoint& fp = out[k];
            fp.xi = Vec3(xi[0], xi[1], xi[2]);
            fp.x = x;
            // (p, q) follow d cyclically, so x_p x x_q points along +xi_d; the facet spans
            // half the natural range in p and q: weight 1/4 per Gauss point
            fp.nda = 0.25 * orient * xp.cross(xq);
        }
}

int sub_hex_element_face(int a, int f)
{
    return f % 2 == 0 ? -1 : element_face_of(f / 2, hex8_nodes[a][f / 2]);
}

const SubHexGauss& sub_hex_gauss()
{
    static const SubHexGauss table = []
    {
        SubHexGauss t;
        const real_t g = 1.0 / std::sqrt(3.0);
        for (int a = 0; a < 8; ++a)
            for (int q = 0; q < 8; ++q)
            {
                // the octant between node a and the centre: Jacobian 1/8 of the element's
                for (int d = 0; d < 3; ++d)
                    t.xi[a][q][d] = 0.5 * hex8_nodes[a][d] * (1.0 + g * hex8_nodes[q][d]);
                hex8_shape(t.xi[a][q], t.N[a][q]);
                hex8_shape_derivatives(t.xi[a][q], t.dN[a][q]);
            }
        return t;
    }();
    return table;
}

namespace
{
/// sub_hex_gauss's tables with the points innermost: N[a][I][q], dN[a][I][b][q].
struct SubHexLanes
{
    alignas(64) real_t N[8][8][8];
    alignas(64) real_t dN[8][8][3][8];
};

const SubHexLanes& sub_hex_lanes()
{
    static const SubHexLanes table = []
    {
        const SubHexGauss& g = sub_hex_gauss();
        SubHexLanes t;
        for (int a = 0; a < 8; ++a)
            for (int I = 0; I < 8; ++I)
                for (int q = 0; q < 8; ++q)
                {
                    t.N[a][I][q] = g.N[a][q][I];
                    for (int b = 0; b < 3; ++b)
                        t.dN[a][I][b][q] = g.dN[a][q][I][b];
                }
        return t;
    }();
    return table;
}
} // namespace

void sub_hex_points(const real_t xe[8][3], int a, real_t det[8], real_t (*x)[8])
{
    // every loop over q runs in the lanes of one vector (the compiler's, at -O3)
    const SubHexLanes& t = sub_hex_lanes();
    alignas(64) real_t J[3][3][8] = {};
    for (int I = 0; I < 8; ++I)
        for (int b = 0; b < 3; ++b)
            for (int d = 0; d < 3; ++d)
                for (int q = 0; q < 8; ++q)
                    J[b][d][q] += t.dN[a][I][b][q] * xe[I][d];
    for (int q = 0; q < 8; ++q)
        det[q] = J[0][0][q] * (J[1][1][q] * J[2][2][q] - J[1][2][q] * J[2][1][q]) -
                 J[0][1][q] * (J[1][0][q] * J[2][2][q] - J[1][2][q] * J[2][0][q]) +
                 J[0][2][q] * (J[1][0][q] * J[2][1][q] - J[1][1][q] * J[2][0][q]);
    if (x == nullptr)
        return;
    for (int d = 0; d < 3; ++d)
        for (int q = 0; q < 8; ++q)
            x[d][q] = 0.0;
    for (int I = 0; I < 8; ++I)
        for (int d = 0; d < 3; ++d)
            for (int q = 0; q < 8; ++q)
                x[d][q] += t.N[a][I][q] * xe[I][d];
}

real_t sub_hex_volume(const real_t xe[8][3], int a)
{
    alignas(64) real_t det[8];
    sub_hex_points(xe, a, det);
    real_t vol = 0.0;
    for (int q = 0; q < 8; ++q)
        vol += det[q];
    return 0.125 * vol;
}

real_t sub_hex_volume_plain(const real_t xe[8][3], int a)
{
    const SubHexGauss& gauss = sub_hex_gauss();
    real_t vol = 0.0;
    for (int q = 0; q < 8; ++q)
    {
        const real_t(&dN)[8][3] = gauss.dN[a][q];
        real_t J[3][3] = {};
        for (int I = 0; I < 8; ++I)
            for (int r = 0; r < 3; ++r)
                for (int c = 0; c < 3; ++c)
                    J[r][c] += xe[I][r] * dN[I][c];
        vol += J[0][0] * (J[1][1] * J[2][2] - J[1][2] * J[2][1]) - J[0][1] * (J[1][0] * J[2][2] - J[1][2] * J[2][0]) +
               J[0][2] * (J[1][0] * J[2][1] - J[1][1] * J[2][0]);
    }
    return 0.125 * vol;
}

void build_sub_hex(const real_t xe[8][3], int a, SubHex& out)
{
    real_t vol = 0.0;
    for (int f = 0; f < 6; ++f)
    {
        build_sub_hex_facet(xe, a, f, out.facets[f]);
        out.element_face[f] = sub_hex_element_face(a, f);
        for (const FacetPoint& fp : out.facets[f])
            vol += fp.x.dot(fp.nda);
    }
    out.volume = vol / 3.0;
}

std::vector<index_t> face_neighbours(const HexMesh& mesh)
{
    // each face pairs with its earlier twin (the later of a non-manifold three overwrites the
    // first's neighbour, as a map of the faces in element order did)
    const std::vector<index_t> twin = earlier_twin_faces(mesh.conn);
    std::vector<index_t> nb(twin.size(), -1);
    for (std::size_t j = 0; j < twin.size(); ++j)
        if (twin[j] >= 0)
        {
            nb[j] = twin[j] / 6;
            nb[static_cast<std::size_t>(twin[j])] = static_cast<index_t>(j / 6);
        }
    return nb;
}

void node_element_incidence(const HexMesh& mesh, std::vector<index_t>& offsets, std::vector<index_t>& slots)
{
    const index_t nn = mesh.n_nodes(), ne = mesh.n_elements();
    offsets.assign(static_cast<std::size_t>(nn) + 1, 0);
    for (index_t k = 0; k < 8 * ne; ++k)
        ++offsets[mesh.conn[k] + 1];
    for (index_t i = 0; i < nn; ++i)
        offsets[i + 1] += offsets[i];
    slots.resize(static_cast<std::size_t>(8 * ne));
    std::vector<index_t> fill(offsets.begin(), offsets.end() - 1);
    for (index_t k = 0; k < 8 * ne; ++k)
        slots[fill[mesh.conn[k]]++] = k;
}
} // namespace rkfem
