/// @file voronoi_geometry.cpp
/// What the Voronoi cells need and give that is not CGAL's: the bodies' half-spaces (a box, a
/// prism around a cylinder) and the merge of a cell's facet points face by face. Kept out of
/// voronoi_cells.cpp, the one translation unit that compiles CGAL.
#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include "rkfem/core/error.hpp"
#include "rkfem/discretization/voronoi_cells.hpp"

namespace rkfem
{
std::vector<HalfSpace> box_halfspaces(const Vec3& lo, const Vec3& hi)
{
    std::vector<HalfSpace> h;
    for (int d = 0; d < 3; ++d)
    {
        Vec3 n = Vec3::Zero();
        n[d] = 1.0;
        h.push_back({n, hi[d]});
        h.push_back({-n, -lo[d]});
    }
    return h;
}

std::vector<HalfSpace> cylinder_halfspaces(const Vec3& origin, real_t radius, real_t height, int sides)
{
    RKFEM_REQUIRE(sides >= 3, "cylinder_halfspaces: " << sides << " sides");
    std::vector<HalfSpace> h;
    for (int k = 0; k < sides; ++k)
    {
        const real_t a = 2.0 * M_PI * k / sides;
        const Vec3 n(std::cos(a), std::sin(a), 0.0);
        h.push_back({n, n.dot(origin) + radius});
    }
    h.push_back({Vec3::UnitZ(), origin[2] + height});
    h.push_back({-Vec3::UnitZ(), -origin[2]});
    return h;
}

void merge_face_points(VoronoiCells& cells)
{
    std::vector<CellFacetPoint> points;
    std::vector<index_t> offsets{0};
    points.reserve(cells.points.size() / 4);
    offsets.reserve(cells.offsets.size());
    for (index_t i = 0; i < cells.size(); ++i)
    {
        for (index_t q = cells.offsets[i]; q < cells.offsets[i + 1];)
        {
            const index_t r = cells.face_end(i, q);
            // the triangles' centroids weighted by their areas: the polygon's centroid
            Vec3 x = Vec3::Zero(), nda = Vec3::Zero();
            real_t area = 0.0;
            for (index_t k = q; k < r; ++k)
            {
                const real_t a = cells.points[k].nda.norm();
                x += a * cells.points[k].x;
                area += a;
                nda += cells.points[k].nda;
            }
            points.push_back({area > 0.0 ? Vec3(x / area) : cells.points[q].x, nda, cells.points[q].neighbour, true});
            q = r;
        }
        offsets.push_back(static_cast<index_t>(points.size()));
    }
    cells.points = std::move(points);
    cells.offsets = std::move(offsets);
}
} // namespace rkfem
