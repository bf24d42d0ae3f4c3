#pragma once
/// @file convex_cell.hpp
/// A convex polyhedron cut down by half-spaces, in doubles: the Voronoi cells' construction
/// (voronoi_cells.cpp), as voro++ builds its cells. It starts as a box and each cut n . x <= c
/// keeps the side within it: the vertices beyond the plane go, every edge that crosses it gets
/// a new vertex, each face is clipped to the kept side, and the cross-section becomes a new face
/// tagged with the cut. A vertex within `eps` of the plane counts as on it (kept, and a corner of
/// the new face), so the planes of a regular lattice, many through one vertex, give one vertex,
/// not slivers of round-off.
///
/// Faces list their vertices counter-clockwise seen from outside (their right-hand normal points
/// out). The plain twin is CGAL's exact dual construction (halfspace_intersection_3, kept in
/// voronoi_cells.cpp as VoronoiHull::Exact): the same cells, vertex positions to round-off.
#include <vector>

#include "rkfem/core/types.hpp"

namespace rkfem
{
class ConvexCell
{
  public:
    /// The box [lo, hi]; its faces are tagged kBox.
    void reset_box(const Vec3& lo, const Vec3& hi);
    /// Keeps n . x <= c (n need not be unit: eps is a distance times |n|); the new face, if the
    /// plane cuts, is tagged `tag`. Returns false when the plane cuts nothing off (every vertex
    /// within it, up to eps). Throws Error when nothing is left (every vertex beyond or on it).
    bool cut(const Vec3& n, real_t c, int tag, real_t eps);

    static constexpr int kBox = -2;
    const std::vector<Vec3>& vertices() const { return x_; }
    /// face f: vertices face_vertices[face_offsets[f] .. face_offsets[f + 1]), counter-clockwise
    /// seen from outside; face_tag[f]: the cut that made it (kBox: one of the box's)
    const std::vector<int>& face_offsets() const { return face_offsets_; }
    const std::vector<int>& face_vertices() const { return face_vertices_; }
    const std::vector<int>& face_tag() const { return face_tag_; }
    int n_faces() const { return static_cast<int>(face_tag_.size()); }

  private:
    std::vector<Vec3> x_;
    std::vector<int> face_offsets_{0}, face_vertices_, face_tag_;
    // scratch of cut(), kept for its capacity
    std::vector<real_t> dist_;
    std::vector<int> side_, new_id_, edge_vertex_;
    std::vector<Vec3> new_x_;
    std::vector<int> new_offsets_, new_vertices_, new_tags_, section_;
    std::vector<real_t> angle_;
};
} // namespace rkfem
