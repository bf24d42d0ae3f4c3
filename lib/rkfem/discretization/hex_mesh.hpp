#pragma once
/// @file hex_mesh.hpp
/// A hexahedral mesh as flat arrays, the boundary faces it exposes, and named face groups.
///
/// Node order in an element is LS-DYNA's *ELEMENT_SOLID and VTK_HEXAHEDRON order: nodes 0-3 are
/// the face at natural coordinate zeta = -1, counter-clockwise seen from +zeta; nodes 4-7 lie
/// above them. Natural coordinates of node I are hex8_nodes[I] (approximation/fem/hex8_basis.hpp).
#include <array>
#include <map>
#include <string>
#include <vector>

#include "rkfem/core/types.hpp"

namespace rkfem
{
using Quad = std::array<index_t, 4>; ///< boundary face, outward normal by the right-hand rule

struct HexMesh
{
    std::vector<real_t> x;                                   ///< n_nodes x 3, node-major (x0 y0 z0 x1 y1 z1 ...)
    std::vector<index_t> conn;                               ///< n_elements x 8
    std::vector<Quad> faces;                                 ///< boundary faces (each appears in exactly one element)
    std::map<std::string, std::vector<index_t>> named_faces; ///< name -> indices into `faces`
    /// Node groups of a cloud (no elements, no faces): xmin..zmax, top, bottom, side
    std::map<std::string, std::vector<index_t>> named_nodes;
    /// The file's element and node ids (keyword meshes; empty for generated ones), the names
    /// messages use
    std::vector<long long> element_ids, node_ids;

    index_t n_nodes() const { return static_cast<index_t>(x.size() / 3); }
    index_t n_elements() const { return static_cast<index_t>(conn.size() / 8); }
    Vec3 node(index_t i) const { return {x[3 * i], x[3 * i + 1], x[3 * i + 2]}; }
    /// How messages name element e and node i: the file's id, or the 0-based index (results.h5's order)
    long long element_label(index_t e) const
    {
        return element_ids.empty() ? e : element_ids[static_cast<std::size_t>(e)];
    }
    long long node_label(index_t i) const { return node_ids.empty() ? i : node_ids[static_cast<std::size_t>(i)]; }
};

/// The six faces of a hex as local node indices, outward normals.
inline constexpr std::array<std::array<int, 4>, 6> hex_faces{{
    {0, 3, 2, 1}, // zeta = -1
    {4, 5, 6, 7}, // zeta = +1
    {0, 1, 5, 4}, // eta = -1
    {1, 2, 6, 5}, // xi = +1
    {2, 3, 7, 6}, // eta = +1
    {3, 0, 4, 7}, // xi = -1
}};

/// Per element face 6 e + f (local faces hex_faces): the first earlier face in that order with
/// the same nodes, or -1 (a face of a conforming mesh has at most one twin). A degenerate solid's
/// face is compared by its distinct nodes (a triangle written a b d d is the a b b d of the
/// tetrahedron across it).
std::vector<index_t> earlier_twin_faces(const std::vector<index_t>& conn);

/// Finds faces that belong to one element only. Order: by element, then by local face. With
/// `owner`, the element of each face (an index into conn / 8).
std::vector<Quad> extract_boundary_faces(const std::vector<index_t>& conn, std::vector<index_t>* owner = nullptr);

/// Area-weighted normal of a quad (|n| = area for a planar quad): (x2 - x0) x (x3 - x1) / 2.
Vec3 quad_normal(const std::vector<real_t>& x, const Quad& q);

/// The worst corner of a hex mesh by the scaled Jacobian: at a corner, the triple product of
/// the unit edges to its xi, eta and zeta neighbours (signed so that a right-handed element in
/// LS-DYNA's node order is positive; 1 for a cube, 0 for a flat corner or an edge of no length,
/// negative where the corner is inverted). The trilinear map of the element is one to one
/// where every corner is positive, and inverted or singular somewhere where one is not. A
/// degenerate solid (a node repeated: a wedge, pyramid or tetrahedron written as a hex, as
/// pre-processors write them for LS-DYNA) is checked at its corners whose three edges are all
/// there; the corners where an edge collapses are skipped.
struct HexCorner
{
    index_t element = -1; ///< -1: no elements
    int corner = -1;      ///< local node 0-7
    real_t scaled_jacobian = 1.0;
};
HexCorner worst_corner(const HexMesh& m);
/// worst_corner's measure at corner a of one hex, corners x[8][3] and node ids c[8]; kNoLimit
/// where an edge at the corner collapses (a degenerate solid's corner, skipped).
real_t corner_scaled_jacobian(const real_t (&x)[8][3], const index_t* c, int a);
/// The smallest over a hex's corners (its collapsed corners skipped): 1 for a box, 1 / sqrt(1 +
/// gamma^2) for a box sheared by gamma, <= 0 inverted.
real_t smallest_scaled_jacobian(const real_t (&x)[8][3], const index_t* c);
/// The longest of a hex's 12 edges over the shortest, the edges between repeated nodes (a
/// degenerate solid's) left out.
real_t edge_aspect_ratio(const real_t (&x)[8][3], const index_t* c);
/// The largest of a hex's six face areas (each |(x2 - x0) x (x3 - x1)| / 2), corners x[8][3]: the
/// A_max of the element step V / A_max / c.
real_t largest_face_area(const real_t (&x)[8][3]);
/// The number of distinct nodes of the 8 of a solid (8 for a hex; 6 a wedge, 5 a pyramid, 4 a
/// tetrahedron written as a hex).
template <class Id> int distinct_nodes(const Id* c)
{
    int n = 0;
    for (int a = 0; a < 8; ++a)
    {
        bool seen = false;
        for (int b = 0; b < a; ++b)
            seen = seen || c[b] == c[a];
        n += !seen;
    }
    return n;
}
/// At or below this scaled Jacobian a corner is degenerate (a solid refused at set-up)
inline constexpr real_t kDegenerateScaledJacobian = 1e-6;

/// Whether any solid of m repeats a node (a wedge, pyramid or tetrahedron written as a hex).
bool has_degenerate_solids(const HexMesh& m);

/// Writes every tetrahedron (a solid of 4 distinct nodes, in any degenerate form) as a b c c d d d d
/// with its nodes in the mesh's order (d the last, c the one before, a and b right-handed), so
/// that each triangle repeats its last node whichever of its two tetrahedra writes it: the nodal
/// cells are images of the solids' natural octants, and a shared triangle's facets meet only
/// when both sides divide it alike. Returns the number of solids rewritten.
index_t canonical_tetrahedra(HexMesh& m);

/// A triangle (a face of 3 distinct nodes) that its two solids write with different nodes
/// repeated, as (element, local face, element across, its local face); all -1 when there is
/// none. Such a triangle's facets do not meet, and the nodal cells on it are not closed.
std::array<index_t, 4> unmatched_triangle(const HexMesh& m);

/// Merges nodes closer than `tol` and renumbers `conn`; returns the number of nodes kept.
index_t merge_coincident_nodes(std::vector<real_t>& x, std::vector<index_t>& conn, real_t tol);
} // namespace rkfem
