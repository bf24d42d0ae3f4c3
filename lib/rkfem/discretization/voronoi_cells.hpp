#pragma once
/// @file voronoi_cells.hpp
/// Voronoi cells of a point cloud clipped to a convex body (intersection of half-spaces), for
/// particle clouds that do not come from a hex mesh (imported points, refinement). Each cell is
/// a convex polyhedron; its facets are fanned into triangles from the facet centroid and each
/// triangle carries one quadrature point (centroid, n dA), which integrates linear fields exactly,
/// so the cell volume (1/3) sum x . n dA and SCNI gradients of linear fields are exact. Facets
/// shared by two cells are built from the same polygon on both sides (IC1 up to round-off).
/// CGAL (Delaunay_triangulation_3 for the neighbours; halfspace_intersection_3 for the cells'
/// exact twin) is confined to voronoi_cells.cpp; the cells themselves are cut in doubles
/// (convex_cell.hpp).
#include <vector>

#include "rkfem/core/types.hpp"

namespace rkfem
{
/// The half-space n . x <= d (n outward unit normal).
struct HalfSpace
{
    Vec3 normal;
    real_t offset = 0.0;
};

/// The six half-spaces of an axis-aligned box.
std::vector<HalfSpace> box_halfspaces(const Vec3& lo, const Vec3& hi);

/// The prism of `sides` planes tangent to the cylinder (axis +z from `origin`, the bottom
/// centre; radius, height), and its two caps: a convex body that holds the whole cylinder, with
/// the volume of the cylinder times sides tan(pi / sides) / pi (1 + (pi / sides)^2 / 3 + ...).
std::vector<HalfSpace> cylinder_halfspaces(const Vec3& origin, real_t radius, real_t height, int sides);

struct CellFacetPoint
{
    Vec3 x;                   ///< quadrature point
    Vec3 nda;                 ///< outward normal times area of its triangle
    index_t neighbour = -1;   ///< particle on the other side, -1 on the body boundary
    bool starts_face = false; ///< the first point of its face polygon (the cell's points run face by face)
};

struct VoronoiCells
{
    std::vector<real_t> volume;      ///< per particle
    std::vector<index_t> offsets{0}; ///< per particle: facet points [offsets[i], offsets[i+1])
    std::vector<CellFacetPoint> points;
    std::vector<real_t> spacing; ///< per particle: largest distance to a facet neighbour
    /// Sub-cells (for MSCNI): one pyramid per facet polygon of a cell, apex at the average of the
    /// cell's vertices, pyramids under 1e-3 of the cell's volume joined to the cell's largest; its
    /// boundary points are sub_points [begin, end) (the facets' triangles and one side triangle
    /// per polygon edge, centroid and outward n dA; neighbour unused).
    struct SubCell
    {
        index_t cell = 0;
        real_t volume = 0.0;
        index_t begin = 0, end = 0;
    };
    std::vector<SubCell> sub_cells;
    std::vector<CellFacetPoint> sub_points;
    /// Cells built again with every body plane: the first try leaves out the body planes farther
    /// than twice the farthest Delaunay neighbour, and a cell that reaches past one is redone.
    index_t rebuilt_with_all_planes = 0;
    index_t size() const { return static_cast<index_t>(volume.size()); }
    /// The end of the face whose points start at q, a point of cell i that starts a face: the
    /// next point of the cell that starts one, or the cell's end.
    index_t face_end(index_t i, index_t q) const
    {
        index_t r = q + 1;
        while (r < offsets[static_cast<std::size_t>(i) + 1] && !points[static_cast<std::size_t>(r)].starts_face)
            ++r;
        return r;
    }
};

/// How each cell's polyhedron is built from its planes. Clip: a box cut by each plane in doubles
/// (discretization/convex_cell.hpp); Exact: CGAL's dual construction in exact arithmetic
/// (halfspace_intersection_3), the plain twin, far slower a cell
/// (measurements: docs/performance.md). Either way each vertex is then solved again from the
/// planes through it, so the cells agree to round-off.
enum class VoronoiHull
{
    Clip,
    Exact,
};

/// One quadrature point per face polygon instead of one per triangle of its fan: the face's area
/// centroid with the face's n dA (the sum of its triangles'). A planar polygon integrates linear
/// fields exactly at its centroid, so the cell volume and SCNI's gradients of linear fields stay
/// exact and a shared face is still the same point from both sides (to round-off); about 5
/// times fewer points, and fewer RK evaluations, than the triangles. The sub-cells' points are
/// left as they are.
void merge_face_points(VoronoiCells& cells);

/// Cells of the points x (n x 3) in the convex body (on its surface allowed); throws Error for
/// points outside it or duplicated. Without with_sub_cells, sub_cells and sub_points stay empty
/// (only SD-SCNI and MSCNI read them; they hold twice the facet points).
VoronoiCells voronoi_cells(const std::vector<real_t>& x, const std::vector<HalfSpace>& body,
                           VoronoiHull hull = VoronoiHull::Clip, bool with_sub_cells = true);
} // namespace rkfem
