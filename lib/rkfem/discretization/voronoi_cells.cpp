#include "rkfem/discretization/voronoi_cells.hpp"

#include <CGAL/Convex_hull_3/dual/halfspace_intersection_3.h>
#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Exact_rational.h>
#include <CGAL/Polyhedron_3.h>
#include <CGAL/QP_functions.h>
#include <CGAL/QP_models.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>
#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <numeric>
#include <unordered_map>

#include "rkfem/core/error.hpp"
#include "rkfem/core/setup_progress.hpp"
#include "rkfem/discretization/convex_cell.hpp"

namespace rkfem
{
namespace
{
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Triangulation_vertex_base_with_info_3<index_t, K>;
using Tds = CGAL::Triangulation_data_structure_3<Vb>;
using Delaunay = CGAL::Delaunay_triangulation_3<K, Tds>;
// the cells in exact constructions: the bisector planes of a regular lattice meet many at a
// vertex, and the dual hull's inexact constructions could put a vertex far outside the body
using EK = CGAL::Exact_predicates_exact_constructions_kernel;
using Polyhedron = CGAL::Polyhedron_3<EK>;

Vec3 vec(const EK::Point_3& p)
{
    return {CGAL::to_double(p.x()), CGAL::to_double(p.y()), CGAL::to_double(p.z())};
}

/// The half-space n . x + d <= 0 (n not normalized: a bisector's is the offset to the neighbour).
struct Plane
{
    Vec3 n;
    real_t d = 0.0;
};
} // namespace

namespace
{
/// A vertex of a cell, from CGAL's approximation p: the intersection of the three planes through
/// it (within tol) that meet at the widest angles (the largest |det| of their unit normals; the
/// first such triple in the planes' order), solved in doubles. The same planes give the same
/// bits whatever CGAL computed before; p itself when fewer than three independent planes pass.
/// Built once per cell: each plane's length and offset are formed once for all the cell's
/// vertices (the same operations as per vertex, so the same bits).
class CornerSolver
{
  public:
    explicit CornerSolver(const std::vector<Plane>& planes)
    {
        planes_.reserve(planes.size());
        for (const Plane& q : planes)
        {
            const real_t len = q.n.norm();
            planes_.push_back({q.n, len, -q.d / len, q.n / len});
        }
    }
    Vec3 operator()(const Vec3& p, real_t tol)
    {
        through_.clear(); // unit normal, offset: n . x = c
        for (const Unit& q : planes_)
            if (std::abs(q.n.dot(p) / q.len - q.c) <= tol)
                through_.emplace_back(q.unit, q.c);
        real_t best = 1e-6;
        std::array<std::size_t, 3> pick{0, 0, 0};
        bool found = false;
        for (std::size_t a = 0; a < through_.size(); ++a)
            for (std::size_t b = a + 1; b < through_.size(); ++b)
                for (std::size_t c = b + 1; c < through_.size(); ++c)
                {
                    const real_t det = std::abs(through_[a].first.dot(through_[b].first.cross(through_[c].first)));
                    if (det > best)
                    {
                        best = det;
                        pick = {a, b, c};
                        found = true;
                    }
                }
        if (!found)
            return p;
        Mat3 A;
        Vec3 rhs;
        for (int r = 0; r < 3; ++r)
        {
            A.row(r) = through_[pick[r]].first.transpose();
            rhs[r] = through_[pick[r]].second;
        }
        return A.partialPivLu().solve(rhs);
    }

  private:
    struct Unit
    {
        Vec3 n;
        real_t len, c;
        Vec3 unit;
    };
    std::vector<Unit> planes_;
    std::vector<std::pair<Vec3, real_t>> through_;
};

/// The centre of the largest ball inside the bisectors and the whole body around x_i: maximize r
/// subject to n_k . p + r <= c_k for every unit-normal plane (CGAL's LP solver, exact). Throws
/// when the cell has no interior.
Vec3 deepest_point(const std::vector<Plane>& bisectors, const std::vector<HalfSpace>& body, const Vec3& xi, index_t i)
{
    CGAL::Quadratic_program<double> lp(CGAL::SMALLER, false, 0, false, 0);
    int row = 0;
    auto add = [&](const Vec3& n, real_t c) // n . p <= c, |n| = 1
    {
        for (int d = 0; d < 3; ++d)
            lp.set_a(d, row, n[d]);
        lp.set_a(3, row, 1.0);
        lp.set_b(row, c);
        ++row;
    };
    // in coordinates relative to x_i (the cell's size sets the scale, not its position)
    for (const Plane& q : bisectors)
    {
        const real_t len = q.n.norm();
        add(q.n / len, -(q.d + q.n.dot(xi)) / len);
    }
    for (const HalfSpace& h : body)
        add(h.normal, h.offset - h.normal.dot(xi));
    lp.set_c(3, -1.0); // maximize r
    const auto solution = CGAL::solve_linear_program(lp, CGAL::Exact_rational());
    RKFEM_REQUIRE(solution.is_optimal(),
                  "Voronoi cells: the cell of point " << i << " (" << xi.transpose() << ") has no interior");
    real_t v[4];
    int k = 0;
    for (auto it = solution.variable_values_begin(); it != solution.variable_values_end() && k < 4; ++it)
        v[k++] = CGAL::to_double(*it);
    const Vec3 p(v[0], v[1], v[2]);
    RKFEM_REQUIRE(v[3] > 0.0, "Voronoi cells: the cell of point " << i << " (" << xi.transpose()
                                                                  << ") is flat: no room inside the body");
    return xi + p;
}

/// What every cell of voronoi_cells reads: the points, the body, the hull, the points' tolerance,
/// the box a cut cell starts from and each point's Delaunay neighbours (ascending).
struct CellInputs
{
    const std::vector<real_t>& x;
    const std::vector<HalfSpace>& body;
    VoronoiHull hull;
    bool with_sub_cells;
    real_t tol;
    Vec3 box_lo, box_hi;
    const std::vector<index_t>& adj_offsets;
    const std::vector<index_t>& adj_ids;
};

/// One point's cell under construction, into its part `cells` (the inputs copied in, for the
/// cell's own use).
struct CellBuild : CellInputs
{
    CellBuild(const CellInputs& in, index_t point, VoronoiCells& part)
        : CellInputs(in), i(point), xi(x[3 * i], x[3 * i + 1], x[3 * i + 2]), cells(part)
    {
    }

    const index_t i;
    const Vec3 xi;
    VoronoiCells& cells;
    // half-spaces: bisectors with the Delaunay neighbours, then the body; origin at x_i
    std::vector<Plane> planes;
    ConvexCell cell;
    std::vector<int> cut_order;
    std::vector<index_t> owner; // neighbour per plane, -1 body
    real_t dmin = kNoLimit, dmax = 0.0;
    std::size_t n_bisectors = 0;
    // The cell in an order of its own: CGAL's hull lists vertices and facets, and starts each
    // facet, in an order that follows memory addresses, which vary from run to run
    // (address-space randomization), and a vertex's double (its lazy construction's interval)
    // depended on which of the planes through it the hull used; every sum below then rounded
    // differently from run to run. Each vertex is solved again from the planes through it
    // (CornerSolver), facets start at their smallest vertex, and both are sorted. The cut
    // cell's vertices are solved again the same way.
    std::vector<Vec3> corners;
    std::vector<std::vector<Vec3>> polygons;

    /// The bisectors with the Delaunay neighbours, and the neighbours' least and largest distance.
    void add_bisectors()
    {
        const index_t* adj_begin = adj_ids.data() + adj_offsets[i];
        const index_t* adj_end = adj_ids.data() + adj_offsets[i + 1];
        for (const index_t* v = adj_begin; v != adj_end; ++v)
        {
            const index_t j = *v;
            const Vec3 xj(x[3 * j], x[3 * j + 1], x[3 * j + 2]);
            const Vec3 nrm = xj - xi;
            const Vec3 mid = 0.5 * (xi + xj);
            // a x + b y + c z + d <= 0 on x_i's side
            planes.push_back({nrm, -nrm.dot(mid)});
            owner.push_back(j);
        }
        // the body's planes that can cut the cell: within twice the farthest Delaunay neighbour
        // (a faceted body has many, and each plane costs every cell's construction); checked
        // below, all planes when the cell would reach past one left out
        for (const index_t* v = adj_begin; v != adj_end; ++v)
        {
            const index_t j = *v;
            const real_t d = (Vec3(x[3 * j], x[3 * j + 1], x[3 * j + 2]) - xi).norm();
            dmin = std::min(dmin, d);
            dmax = std::max(dmax, d);
        }
        n_bisectors = planes.size();
    }

    /// The body's planes after the bisectors: all, or those within twice the farthest neighbour.
    void add_body_planes(bool all)
    {
        planes.resize(n_bisectors);
        owner.resize(n_bisectors);
        for (const HalfSpace& h : body)
            if (all || h.offset - h.normal.dot(xi) <= 2.0 * dmax)
            {
                planes.push_back({h.normal, -h.offset});
                owner.push_back(-1);
            }
    }

    // the point inside the cell that CGAL's dual construction starts from: x_i, pushed to at
    // least 0.2 d_min (d_min: its nearest neighbour's distance) from every body face, the
    // nearest face first. The dual points scale with 1 / (distance of the point to each
    // plane), so a point on or near a face (a generated boundary particle, an imported point)
    // made the construction ill-conditioned: an unoptimized build got cells reaching outside
    // the body. The push is at most about sqrt(3) 0.2 d_min (a box corner), inside the
    // bisectors (d_min / 2 away).
    /// p's least distance to a body face.
    real_t min_body_distance(const Vec3& p) const
    {
        real_t d = kNoLimit;
        for (const HalfSpace& h : body)
            d = std::min(d, h.offset - h.normal.dot(p));
        return d;
    }

    // (for the exact construction only)
    /// The start point: x_i pushed off the body's faces, or the centre of the largest ball in the cell.
    Vec3 start_point() const
    {
        Vec3 xin = xi;
        for (int pass = 0; pass < 8; ++pass)
        {
            const HalfSpace* nearest = nullptr;
            real_t nearest_dist = 0.2 * dmin;
            for (const HalfSpace& h : body)
            {
                const real_t dist = h.offset - h.normal.dot(xin); // unit normals
                if (dist < nearest_dist)
                {
                    nearest_dist = dist;
                    nearest = &h;
                }
            }
            if (nearest == nullptr)
                break;
            xin -= (0.2 * dmin - nearest_dist) * nearest->normal;
        }
        // a body thinner than 0.2 d_min across (a cloud one spacing thick, a point file of a
        // plate) has no room for that push: it left the start point outside a face, a broken
        // precondition on which CGAL's hull freed an invalid pointer or never returned. There the
        // start point is the centre of the largest ball in the cell (a small linear programme on
        // the normalized planes, exact)
        if (min_body_distance(xin) < 0.1 * dmin)
            xin = deepest_point(planes, body, xi, i);
        return xin;
    }

    /// Whether p is inside the body (within tol).
    bool inside(const Vec3& p) const
    {
        bool in = true;
        for (const HalfSpace& h : body)
            in = in && h.normal.dot(p) <= h.offset + tol;
        return in;
    }

    /// The cell as CGAL's dual hull of its planes (VoronoiHull::Exact): its corners and polygons.
    void exact_hull()
    {
        const Vec3 xin = start_point();
        std::vector<EK::Plane_3> exact;
        auto hull_of_planes = [&](Polyhedron& P)
        {
            exact.clear();
            for (const Plane& q : planes)
                exact.emplace_back(q.n[0], q.n[1], q.n[2], q.d);
            CGAL::halfspace_intersection_3(exact.begin(), exact.end(), P, EK::Point_3(xin[0], xin[1], xin[2]));
        };
        Polyhedron P;
        add_body_planes(false);
        hull_of_planes(P);
        bool inside_body = true;
        for (auto v = P.vertices_begin(); v != P.vertices_end() && inside_body; ++v)
            inside_body = inside(vec(v->point()));
        if (!inside_body)
        {
            ++cells.rebuilt_with_all_planes;
            P.clear();
            add_body_planes(true);
            hull_of_planes(P);
        }
        std::unordered_map<const void*, std::size_t> corner_of;
        CornerSolver corner_point(planes);
        for (auto v = P.vertices_begin(); v != P.vertices_end(); ++v)
        {
            corner_of[&*v] = corners.size();
            corners.push_back(corner_point(vec(v->point()), 1e-9 * dmax));
        }
        for (auto f = P.facets_begin(); f != P.facets_end(); ++f)
        {
            std::vector<Vec3> poly;
            auto h = f->facet_begin();
            do
            {
                poly.push_back(corners[corner_of.at(&*h->vertex())]);
            } while (++h != f->facet_begin());
            polygons.push_back(std::move(poly));
        }
    }

    /// The cell as the body's box cut by its planes (VoronoiHull::Clip): its corners and polygons.
    void cut_box()
    {
        // the body's box cut by the bisectors, nearest first, then by the body's
        // planes; a vertex within 1e-10 of the farthest neighbour's distance of a
        // plane is on it
        auto cut_cell = [&]()
        {
            cell.reset_box(box_lo, box_hi);
            cut_order.resize(planes.size());
            std::iota(cut_order.begin(), cut_order.end(), 0);
            std::stable_sort(cut_order.begin(), cut_order.begin() + static_cast<std::ptrdiff_t>(n_bisectors),
                             [&](int a, int b) { return planes[a].n.squaredNorm() < planes[b].n.squaredNorm(); });
            try
            {
                for (const int q : cut_order)
                    cell.cut(planes[q].n, -planes[q].d, q, 1e-10 * dmax * planes[q].n.norm());
            }
            catch (const Error&)
            {
                throw Error("Voronoi cells: the cell of point " + std::to_string(i) +
                            " has no interior (a cut left nothing of it)");
            }
        };
        add_body_planes(false);
        cut_cell();
        bool inside_body = true;
        for (const Vec3& p : cell.vertices())
            inside_body = inside_body && inside(p);
        if (!inside_body)
        {
            ++cells.rebuilt_with_all_planes;
            add_body_planes(true);
            cut_cell();
        }
        for (const int t : cell.face_tag())
            RKFEM_REQUIRE(t != ConvexCell::kBox, "Voronoi cells: the cell of point " << i << " (" << xi.transpose()
                                                                                     << ") reaches past the body");
        CornerSolver corner_point(planes);
        for (const Vec3& p : cell.vertices())
            corners.push_back(corner_point(p, 1e-9 * dmax));
        for (int f = 0; f < cell.n_faces(); ++f)
        {
            std::vector<Vec3> poly;
            for (int k = cell.face_offsets()[f]; k < cell.face_offsets()[f + 1]; ++k)
                poly.push_back(corners[static_cast<std::size_t>(cell.face_vertices()[k])]);
            polygons.push_back(std::move(poly));
        }
    }

    /// The polygons in an order of their own (each from its smallest vertex, sorted); returns the
    /// sub-cells' apex.
    Vec3 sort_facets()
    {
        auto before = [](const Vec3& a, const Vec3& b)
        { return std::lexicographical_compare(a.begin(), a.end(), b.begin(), b.end()); };
        for (std::vector<Vec3>& poly : polygons)
            std::rotate(poly.begin(), std::min_element(poly.begin(), poly.end(), before), poly.end());
        std::sort(polygons.begin(), polygons.end(),
                  [&](const std::vector<Vec3>& a, const std::vector<Vec3>& b)
                  { return std::lexicographical_compare(a.begin(), a.end(), b.begin(), b.end(), before); });
        // apex of the sub-cells: the average of the cell's vertices (inside a convex cell)
        std::vector<Vec3> sorted_corners = corners;
        std::sort(sorted_corners.begin(), sorted_corners.end(), before);
        Vec3 apex = Vec3::Zero();
        for (const Vec3& p : sorted_corners)
            apex += p;
        apex /= static_cast<real_t>(corners.size());
        return apex;
    }

    /// The facet points of the polygons' triangles (with sub-cells, each polygon's pyramid's
    /// boundary too) and the spacing; returns the cell's volume.
    real_t facet_points(const Vec3& apex, std::vector<std::vector<CellFacetPoint>>& pyramids)
    {
        real_t vol = 0.0;
        for (const std::vector<Vec3>& poly : polygons)
        {
            Vec3 c = Vec3::Zero();
            for (const Vec3& p : poly)
                c += p;
            c /= static_cast<real_t>(poly.size());
            // which plane this facet lies on: the one with the smallest distance of the centroid
            // and a normal parallel to the facet's
            Vec3 area = Vec3::Zero();
            for (std::size_t k = 0; k < poly.size(); ++k)
                area += 0.5 * (poly[k] - c).cross(poly[(k + 1) % poly.size()] - c);
            if (area.norm() == 0.0)
                continue;
            index_t nb = -1;
            real_t best = kNoLimit;
            for (std::size_t q = 0; q < planes.size(); ++q)
            {
                const Vec3& pn = planes[q].n;
                const real_t dist = std::abs(pn.dot(c) + planes[q].d) / pn.norm();
                if (pn.dot(area) > 0 && dist < best)
                {
                    best = dist;
                    nb = owner[q];
                }
            }
            // the facet's sub-cell: the pyramid from the apex over the polygon, bounded by the
            // facet's triangles and one side triangle per polygon edge (shared, with the opposite
            // normal, by the neighbouring pyramid of the same cell)
            if (with_sub_cells)
                pyramids.emplace_back();
            for (std::size_t k = 0; k < poly.size(); ++k)
            {
                const Vec3& a = poly[k];
                const Vec3& b = poly[(k + 1) % poly.size()];
                const Vec3 nda = 0.5 * (a - c).cross(b - c);
                const Vec3 xq = (a + b + c) / 3.0;
                cells.points.push_back({xq, nda, nb, k == 0});
                vol += xq.dot(nda) / 3.0;
                if (!with_sub_cells)
                    continue;
                std::vector<CellFacetPoint>& pyr = pyramids.back();
                pyr.push_back({xq, nda, nb});
                // side (apex, b, a): outward from the pyramid when the base's normal is outward
                pyr.push_back({(apex + a + b) / 3.0, 0.5 * (b - apex).cross(a - apex), -1});
            }
            if (nb >= 0)
                cells.spacing[0] =
                    std::max(cells.spacing[0], (Vec3(x[3 * nb], x[3 * nb + 1], x[3 * nb + 2]) - xi).norm());
        }
        return vol;
    }

    /// The sub-cells from the pyramids: those under 1e-3 of the cell's volume joined to the largest.
    void add_sub_cells(const std::vector<std::vector<CellFacetPoint>>& pyramids, real_t vol)
    {
        // sub-cells: the pyramids, those under 1e-3 of the cell's volume (over the tiny facets
        // that jitter makes) joined to the largest one. A thin pyramid's boundary terms are large
        // and cancel: alone, its smoothed gradient carries round-off up to 1e-10 of its terms;
        // joined, the union (two closed pieces) still reproduces linear fields exactly.
        // Without sub-cells no pyramid was built (above), and the passes below run on none.
        std::vector<real_t> pv(pyramids.size(), 0.0);
        std::size_t largest = 0;
        for (std::size_t k = 0; k < pyramids.size(); ++k)
        {
            for (const CellFacetPoint& fp : pyramids[k])
                pv[k] += fp.x.dot(fp.nda) / 3.0;
            if (pv[k] > pv[largest])
                largest = k;
        }
        for (std::size_t k = 0; k < pyramids.size(); ++k)
        {
            if (k == largest || pv[k] < 1e-3 * vol)
                continue;
            cells.sub_cells.push_back({i, pv[k], static_cast<index_t>(cells.sub_points.size()), 0});
            cells.sub_points.insert(cells.sub_points.end(), pyramids[k].begin(), pyramids[k].end());
            cells.sub_cells.back().end = static_cast<index_t>(cells.sub_points.size());
        }
        VoronoiCells::SubCell joined{i, 0.0, static_cast<index_t>(cells.sub_points.size()), 0};
        for (std::size_t k = 0; k < pyramids.size(); ++k)
            if (k == largest || pv[k] < 1e-3 * vol)
            {
                joined.volume += pv[k];
                cells.sub_points.insert(cells.sub_points.end(), pyramids[k].begin(), pyramids[k].end());
            }
        joined.end = static_cast<index_t>(cells.sub_points.size());
        if (with_sub_cells)
            cells.sub_cells.push_back(joined);
    }
};

/// Point i's cell into its part `cells`: its facet points, volume, spacing and sub-cells.
void build_cell(const CellInputs& in, index_t i, VoronoiCells& cells)
{
    cells.volume.assign(1, 0.0);
    cells.spacing.assign(1, 0.0);
    CellBuild c(in, i, cells);
    c.add_bisectors();
    if (in.hull == VoronoiHull::Exact)
        c.exact_hull();
    else
        c.cut_box();
    const Vec3 apex = c.sort_facets();
    std::vector<std::vector<CellFacetPoint>> pyramids; // per facet polygon: its pyramid's boundary
    const real_t vol = c.facet_points(apex, pyramids);
    RKFEM_REQUIRE(vol > 0.0, "Voronoi cells: cell " << i << " has non-positive volume " << vol);
    c.add_sub_cells(pyramids, vol);
    cells.volume[0] = vol;
    setup_progress::advance();
}

/// The box a cut cell starts from (VoronoiHull::Clip): the body's, with a margin.
void body_box(const std::vector<HalfSpace>& body, const Vec3& lo, const Vec3& hi, Vec3& box_lo, Vec3& box_hi)
{
    const Vec3 centre = 0.5 * (lo + hi);
    real_t reach = (hi - lo).norm();
    for (const HalfSpace& h : body)
        reach = std::max(reach, std::abs(h.offset - h.normal.dot(centre)));
    ConvexCell whole;
    whole.reset_box(centre - Vec3::Constant(4.0 * reach), centre + Vec3::Constant(4.0 * reach));
    for (std::size_t q = 0; q < body.size(); ++q)
        whole.cut(body[q].normal, body[q].offset, static_cast<int>(q), 1e-12 * reach);
    for (const int t : whole.face_tag())
        RKFEM_REQUIRE(t != ConvexCell::kBox, "Voronoi cells: the body's planes do not bound it within "
                                                 << 4.0 * reach << " of the points' centre");
    box_lo = box_hi = whole.vertices().front();
    for (const Vec3& p : whole.vertices())
    {
        box_lo = box_lo.cwiseMin(p);
        box_hi = box_hi.cwiseMax(p);
    }
    const Vec3 margin = Vec3::Constant(1e-6 * (box_hi - box_lo).norm());
    box_lo -= margin;
    box_hi += margin;
}

/// The Delaunay neighbours of every point, ascending, after checking that each is inside the body.
void delaunay_neighbours(const std::vector<real_t>& x, const std::vector<HalfSpace>& body, index_t n, real_t tol,
                         std::vector<index_t>& adj_offsets, std::vector<index_t>& adj_ids)
{
    std::vector<std::pair<K::Point_3, index_t>> pts;
    for (index_t i = 0; i < n; ++i)
    {
        const Vec3 p(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
        for (const HalfSpace& h : body)
            RKFEM_REQUIRE(h.normal.dot(p) <= h.offset + tol,
                          "Voronoi cells: point " << i << " (" << p.transpose() << ") is not inside the body");
        pts.emplace_back(K::Point_3(p[0], p[1], p[2]), i);
    }
    const Delaunay dt(pts.begin(), pts.end());
    std::vector<Delaunay::Vertex_handle> vh(static_cast<std::size_t>(n));
    for (auto v = dt.finite_vertices_begin(); v != dt.finite_vertices_end(); ++v)
        vh[v->info()] = v;

    // the Delaunay neighbours of every point, first (the triangulation's traversal marks its
    // cells, so it stays on one thread), in the order of the points: CGAL lists them in an order
    // that follows their addresses, which vary from run to run (address-space randomization),
    // and so did the planes' order, the cells' facets and the round-off of every sum over them
    {
        std::vector<Delaunay::Vertex_handle> adj;
        for (index_t i = 0; i < n; ++i)
        {
            RKFEM_REQUIRE(vh[i] != Delaunay::Vertex_handle(),
                          "Voronoi cells: point " << i << " duplicates another point");
            adj.clear();
            dt.finite_adjacent_vertices(vh[i], std::back_inserter(adj));
            const std::size_t first = adj_ids.size();
            for (const auto& v : adj)
                adj_ids.push_back(v->info());
            std::sort(adj_ids.begin() + static_cast<std::ptrdiff_t>(first), adj_ids.end());
            adj_offsets[i + 1] = static_cast<index_t>(adj_ids.size());
        }
    }
}

/// The block's parts [first, last) joined onto cells_out in point order, and emptied.
void join_parts(VoronoiCells& cells_out, std::vector<VoronoiCells>& parts, index_t first, index_t last)
{
    VoronoiCells& cells = cells_out; // the join
    for (index_t i = first; i < last; ++i)
    {
        VoronoiCells& part = parts[static_cast<std::size_t>(i - first)];
        cells.volume[i] = part.volume[0];
        cells.spacing[i] = part.spacing[0];
        cells.points.insert(cells.points.end(), part.points.begin(), part.points.end());
        cells.offsets.push_back(static_cast<index_t>(cells.points.size()));
        const index_t shift = static_cast<index_t>(cells.sub_points.size());
        for (VoronoiCells::SubCell sc : part.sub_cells)
        {
            sc.begin += shift;
            sc.end += shift;
            cells.sub_cells.push_back(sc);
        }
        cells.sub_points.insert(cells.sub_points.end(), part.sub_points.begin(), part.sub_points.end());
        cells.rebuilt_with_all_planes += part.rebuilt_with_all_planes;
        // emptied, its room kept for the next block's cell: freed, a block's 4 MB of parts
        // went back to the system and came again as fresh pages, block after block (a
        // quarter of the 24k-particle column's page zeroing)
        part.points.clear();
        part.sub_cells.clear();
        part.sub_points.clear();
        part.rebuilt_with_all_planes = 0;
    }
}
} // namespace

VoronoiCells voronoi_cells(const std::vector<real_t>& x, const std::vector<HalfSpace>& body, VoronoiHull hull,
                           bool with_sub_cells)
{
    const index_t n = static_cast<index_t>(x.size() / 3);
    RKFEM_REQUIRE(n >= 5, "Voronoi cells: need at least 5 points, got " << n);
    // points may lie on the body's surface (generated clouds keep their boundary particles there)
    Vec3 lo = Vec3::Constant(kNoLimit), hi = Vec3::Constant(-kNoLimit);
    for (index_t i = 0; i < n; ++i)
        for (int d = 0; d < 3; ++d)
        {
            lo[d] = std::min(lo[d], x[3 * i + d]);
            hi[d] = std::max(hi[d], x[3 * i + d]);
        }
    const real_t tol = 1e-9 * (hi - lo).norm();
    // the box every cut cell starts from: the body's (a box around the points' centre, wider than
    // the body's planes are far from it, cut by them)
    Vec3 box_lo = lo, box_hi = hi;
    if (hull == VoronoiHull::Clip)
        body_box(body, lo, hi, box_lo, box_hi);
    std::vector<index_t> adj_offsets(static_cast<std::size_t>(n) + 1, 0), adj_ids;
    delaunay_neighbours(x, body, n, tol, adj_offsets, adj_ids);
    const CellInputs in{x, body, hull, with_sub_cells, tol, box_lo, box_hi, adj_offsets, adj_ids};
    // each cell on its own (its planes, hull and facets are its own; CGAL's lazy exact kernel
    // is thread-safe) into a part of its own, the parts joined in point order: the same cells,
    // bit for bit, on any number of threads; in blocks of points, so that the parts never hold
    // more than a block's cells (each part keeps its room for the next block's)
    VoronoiCells cells_out;
    cells_out.volume.resize(static_cast<std::size_t>(n));
    cells_out.spacing.resize(static_cast<std::size_t>(n));
    constexpr index_t block = 1024;
    std::vector<VoronoiCells> parts(static_cast<std::size_t>(std::min(n, block)));
    for (index_t first = 0; first < n; first += block)
    {
        const index_t last = std::min(n, first + block);
        std::exception_ptr error;
        index_t error_at = n;
#pragma omp parallel for schedule(dynamic, 8)
        for (index_t i = first; i < last; ++i)
        {
            VoronoiCells& cells = parts[static_cast<std::size_t>(i - first)];
            try
            {
                build_cell(in, i, cells);
            }
            catch (...)
            {
#pragma omp critical(rkfem_voronoi_error)
                if (i < error_at) // the first point's error, whatever the threads' order
                {
                    error_at = i;
                    error = std::current_exception();
                }
            }
        }
        if (error)
            std::rethrow_exception(error);
        join_parts(cells_out, parts, first, last);
        // after the first block, room for every cell's points at once from its points per cell,
        // with a margin (grown by doubling, the points were copied into fresh pages about ten
        // times: 200 MB of pages touched for the 100 MB of a 24k-particle column). Memory
        // reserved and never written costs no page; the cells live for the part's set-up only.
        if (first == 0 && last < n)
        {
            const real_t per_cell = static_cast<real_t>(cells_out.points.size()) / static_cast<real_t>(last);
            cells_out.points.reserve(static_cast<std::size_t>(1.25 * per_cell * static_cast<real_t>(n)) + 64);
            const real_t sub_per_cell = static_cast<real_t>(cells_out.sub_points.size()) / static_cast<real_t>(last);
            cells_out.sub_points.reserve(static_cast<std::size_t>(1.25 * sub_per_cell * static_cast<real_t>(n)));
        }
    }
    return cells_out;
}
} // namespace rkfem
