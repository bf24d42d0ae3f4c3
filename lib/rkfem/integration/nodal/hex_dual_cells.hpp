#pragma once
/// @file hex_dual_cells.hpp
/// Conforming nodal cells from a hex mesh (the smoothing cells of SCNI, Chen, Wu, Yoon & You 2001,
/// IJNME 50, built here from element sub-volumes):
/// node I's cell is the union over its elements e of the sub-hex Omega_I^e, the image of the
/// natural octant between node I and the element centre. Each sub-hex has 3 internal facets
/// (natural planes xi_d = 0, shared with the sub-hex of the node across that edge) and 3 external
/// facets (on element faces). Every facet is a bilinear patch integrated by 2x2 Gauss points, which
/// integrates x (n dA) exactly, so the cell volume (1/3) sum x . n dA and the smoothed gradient of
/// any linear field are exact to round-off.
#include <array>
#include <vector>

#include "rkfem/discretization/hex_mesh.hpp"

namespace rkfem
{
struct FacetPoint
{
    Vec3 xi;  ///< natural coordinates in the element
    Vec3 x;   ///< position
    Vec3 nda; ///< outward normal times quadrature weight times area Jacobian
};

struct SubHex
{
    /// facet f = 2 d + side: d = natural direction, side 0 the internal facet (xi_d = 0), side 1
    /// the external facet (on the element face); 4 points per facet.
    std::array<std::array<FacetPoint, 4>, 6> facets;
    std::array<int, 6> element_face; ///< local element face (hex_faces) of external facets, -1 internal
    real_t volume = 0.0;             ///< (1/3) sum over all 24 points x . n dA
};

/// The sub-hex of element e (coordinates xe[8][3]) at local node a.
void build_sub_hex(const real_t xe[8][3], int a, SubHex& out);
/// Facet f of that sub-hex alone (the same points as build_sub_hex's facets[f]), and its local
/// element face (SubHex::element_face).
void build_sub_hex_facet(const real_t xe[8][3], int a, int f, std::array<FacetPoint, 4>& out);
int sub_hex_element_face(int a, int f);
/// The sub-hex's volume as the integral of det J over its natural octant by 2 x 2 x 2 Gauss
/// points (exact: det J of a trilinear map is at most quadratic in each coordinate); the same
/// as SubHex::volume to round-off, and cheaper (measurements: docs/performance.md). Its 8 points
/// at once (sub_hex_points).
real_t sub_hex_volume(const real_t xe[8][3], int a);
/// Its plain twin, point by point: the same volume to round-off.
real_t sub_hex_volume_plain(const real_t xe[8][3], int a);
/// Sub-hex a's 2 x 2 x 2 Gauss points (sub_hex_gauss) at once, point q in lane q of each array
/// (one vector register of eight doubles): det J there (J(b, d) = dx_d / dxi_b, the element's
/// map; the sub-hex's Jacobian is 1/8 of it) and, where x is given, the points' positions x[d][q].
void sub_hex_points(const real_t xe[8][3], int a, real_t det[8], real_t (*x)[8] = nullptr);

/// The 2 x 2 x 2 Gauss points of every sub-hex in the element's natural coordinates (sub-hex
/// a, point q: xi_d = s_ad (1 + n_qd / sqrt 3) / 2) with the shape functions and their natural
/// derivatives there, computed once (hex8_shape, hex8_shape_derivatives: the same values).
struct SubHexGauss
{
    real_t xi[8][8][3];
    real_t N[8][8][8];
    real_t dN[8][8][8][3];
};
const SubHexGauss& sub_hex_gauss();

/// For every element face (6 e + f), the neighbouring element across it, or -1 on the boundary.
std::vector<index_t> face_neighbours(const HexMesh& mesh);

/// Node -> (element, local node) incidence as CSR: slots 8 e + a for node i in
/// [offsets[i], offsets[i + 1]), ascending.
void node_element_incidence(const HexMesh& mesh, std::vector<index_t>& offsets, std::vector<index_t>& slots);
} // namespace rkfem
