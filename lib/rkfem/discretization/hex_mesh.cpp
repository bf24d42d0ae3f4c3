#include "rkfem/discretization/hex_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace rkfem
{
namespace
{
/// Per local node: its neighbours along xi, eta, zeta and the sign of xi * eta * zeta there
constexpr int kCornerEdges[8][4] = {{1, 3, 4, -1}, {0, 2, 5, 1},  {3, 1, 6, -1}, {2, 0, 7, 1},
                                    {5, 7, 0, 1},  {4, 6, 1, -1}, {7, 5, 2, 1},  {6, 4, 3, -1}};
} // namespace

real_t largest_face_area(const real_t (&x)[8][3])
{
    real_t area = 0.0;
    for (const auto& f : hex_faces)
    {
        const Vec3 p0(x[f[0]][0], x[f[0]][1], x[f[0]][2]), p1(x[f[1]][0], x[f[1]][1], x[f[1]][2]);
        const Vec3 p2(x[f[2]][0], x[f[2]][1], x[f[2]][2]), p3(x[f[3]][0], x[f[3]][1], x[f[3]][2]);
        area = std::max(area, 0.5 * (p2 - p0).cross(p3 - p1).norm());
    }
    return area;
}

real_t corner_scaled_jacobian(const real_t (&x)[8][3], const index_t* c, int a)
{
    // a corner of a degenerate solid (a wedge or tetrahedron written as a hex) where an edge
    // collapses has no Jacobian of its own: its other corners are checked
    for (int k = 0; k < 3; ++k)
        if (c[kCornerEdges[a][k]] == c[a])
            return kNoLimit;
    const Vec3 xa(x[a][0], x[a][1], x[a][2]);
    Vec3 edge[3];
    real_t length = 1.0;
    for (int k = 0; k < 3; ++k)
    {
        const int b = kCornerEdges[a][k];
        edge[k] = Vec3(x[b][0], x[b][1], x[b][2]) - xa;
        length *= edge[k].norm();
    }
    // d x / d xi along an edge from a corner at xi = s runs against s: the product of
    // the three edge directions carries -s_xi s_eta s_zeta
    const real_t triple = -kCornerEdges[a][3] * edge[0].dot(edge[1].cross(edge[2]));
    return length > 0.0 ? triple / length : 0.0;
}

real_t smallest_scaled_jacobian(const real_t (&x)[8][3], const index_t* c)
{
    real_t least = kNoLimit;
    for (int a = 0; a < 8; ++a)
        least = std::min(least, corner_scaled_jacobian(x, c, a));
    return least;
}

real_t edge_aspect_ratio(const real_t (&x)[8][3], const index_t* c)
{
    static constexpr int kEdge[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                                         {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
    real_t lo = kNoLimit, hi = 0.0;
    for (const auto& [a, b] : kEdge)
    {
        if (c[a] == c[b])
            continue;
        const real_t l = std::hypot(x[a][0] - x[b][0], x[a][1] - x[b][1], x[a][2] - x[b][2]);
        lo = std::min(lo, l);
        hi = std::max(hi, l);
    }
    return lo > 0.0 && lo < kNoLimit ? hi / lo : kNoLimit;
}

HexCorner worst_corner(const HexMesh& m)
{
    HexCorner worst;
    for (index_t e = 0; e < m.n_elements(); ++e)
    {
        const index_t* c = m.conn.data() + 8 * static_cast<std::size_t>(e);
        real_t x[8][3];
        for (int a = 0; a < 8; ++a)
            for (int d = 0; d < 3; ++d)
                x[a][d] = m.x[3 * static_cast<std::size_t>(c[a]) + d];
        for (int a = 0; a < 8; ++a)
        {
            const real_t scaled = corner_scaled_jacobian(x, c, a);
            if (scaled == kNoLimit)
                continue;
            if (worst.element < 0 || !(scaled >= worst.scaled_jacobian))
                worst = {e, a, scaled};
        }
    }
    return worst;
}

std::vector<index_t> earlier_twin_faces(const std::vector<index_t>& conn)
{
    const index_t ne = static_cast<index_t>(conn.size() / 8);
    const std::size_t nf = 6 * static_cast<std::size_t>(ne);
    std::vector<std::array<index_t, 4>> key(nf);
    index_t nn = 0;
    for (index_t e = 0; e < ne; ++e)
        for (int f = 0; f < 6; ++f)
        {
            std::array<index_t, 4>& k = key[6 * static_cast<std::size_t>(e) + static_cast<std::size_t>(f)];
            for (int j = 0; j < 4; ++j)
                k[j] = conn[8 * static_cast<std::size_t>(e) + static_cast<std::size_t>(hex_faces[f][j])];
            std::sort(k.begin(), k.end());
            nn = std::max(nn, k[3] + 1);
            // a degenerate solid's face is keyed by its distinct nodes: a triangle that one
            // tetrahedron writes a b d d and its neighbour a b b d is one face
            std::fill(std::unique(k.begin(), k.end()), k.end(), index_t(-1));
        }
    // a face's twins have its smallest node: faces bucketed by it (a counting sort, a dozen
    // faces per node, each bucket in face order) are compared within their bucket only (a sort
    // of all 6 n_e keys, or a map of them, took most of the time of a 71k-element mesh)
    std::vector<index_t> start(static_cast<std::size_t>(nn) + 1, 0), bucket(nf);
    for (std::size_t i = 0; i < nf; ++i)
        ++start[static_cast<std::size_t>(key[i][0]) + 1];
    for (std::size_t k = 0; k < static_cast<std::size_t>(nn); ++k)
        start[k + 1] += start[k];
    {
        std::vector<index_t> fill(start.begin(), start.end() - 1);
        for (std::size_t i = 0; i < nf; ++i)
            bucket[static_cast<std::size_t>(fill[static_cast<std::size_t>(key[i][0])]++)] = static_cast<index_t>(i);
    }
    std::vector<index_t> twin(nf, -1);
    for (std::size_t k = 0; k < static_cast<std::size_t>(nn); ++k)
        for (index_t b = start[k]; b < start[k + 1]; ++b)
        {
            const std::size_t j = static_cast<std::size_t>(bucket[static_cast<std::size_t>(b)]);
            for (index_t a = start[k]; a < b; ++a)
            {
                const index_t i = bucket[static_cast<std::size_t>(a)];
                if (key[static_cast<std::size_t>(i)] == key[j])
                {
                    twin[j] = i;
                    break;
                }
            }
        }
    return twin;
}

bool has_degenerate_solids(const HexMesh& m)
{
    for (index_t e = 0; e < m.n_elements(); ++e)
        if (distinct_nodes(m.conn.data() + 8 * static_cast<std::size_t>(e)) < 8)
            return true;
    return false;
}

index_t canonical_tetrahedra(HexMesh& m)
{
    index_t changed = 0;
    for (index_t e = 0; e < m.n_elements(); ++e)
    {
        index_t* c = m.conn.data() + 8 * static_cast<std::size_t>(e);
        if (distinct_nodes(c) != 4)
            continue;
        std::array<index_t, 8> sorted;
        std::copy(c, c + 8, sorted.begin());
        std::sort(sorted.begin(), sorted.end());
        index_t v[4];
        std::copy(sorted.begin(), std::unique(sorted.begin(), sorted.end()), v);
        index_t a = v[0], b = v[1];
        const index_t cc = v[2], d = v[3];
        if ((m.node(b) - m.node(a)).cross(m.node(cc) - m.node(a)).dot(m.node(d) - m.node(a)) < 0.0)
            std::swap(a, b);
        const std::array<index_t, 8> canonical{a, b, cc, cc, d, d, d, d};
        if (!std::equal(canonical.begin(), canonical.end(), c))
        {
            std::copy(canonical.begin(), canonical.end(), c);
            ++changed;
        }
    }
    return changed;
}

std::array<index_t, 4> unmatched_triangle(const HexMesh& m)
{
    const std::vector<index_t> twin = earlier_twin_faces(m.conn);
    // the node a face of 3 distinct nodes repeats (-1 for any other face)
    auto repeated = [&](std::size_t face)
    {
        const index_t* c = m.conn.data() + 8 * (face / 6);
        const auto& f = hex_faces[face % 6];
        index_t r = -1;
        int distinct = 0;
        for (int j = 0; j < 4; ++j)
        {
            bool seen = false;
            for (int k = 0; k < j; ++k)
                if (c[f[k]] == c[f[j]])
                {
                    seen = true;
                    r = c[f[j]];
                }
            distinct += !seen;
        }
        return distinct == 3 ? r : index_t(-1);
    };
    for (std::size_t j = 0; j < twin.size(); ++j)
        if (twin[j] >= 0)
        {
            const std::size_t i = static_cast<std::size_t>(twin[j]);
            if (const index_t r = repeated(j); r >= 0 && r != repeated(i))
                return {static_cast<index_t>(i / 6), static_cast<index_t>(i % 6), static_cast<index_t>(j / 6),
                        static_cast<index_t>(j % 6)};
        }
    return {-1, -1, -1, -1};
}

std::vector<Quad> extract_boundary_faces(const std::vector<index_t>& conn, std::vector<index_t>* owner)
{
    // a face is on the boundary when no other element face has its four nodes
    const std::vector<index_t> twin = earlier_twin_faces(conn);
    std::vector<char> boundary(twin.size(), 1);
    for (std::size_t j = 0; j < twin.size(); ++j)
        if (twin[j] >= 0)
            boundary[j] = boundary[static_cast<std::size_t>(twin[j])] = 0;
    std::vector<Quad> faces;
    if (owner)
        owner->clear();
    for (std::size_t i = 0; i < twin.size(); ++i)
        if (boundary[i])
        {
            const index_t e = static_cast<index_t>(i / 6);
            const int f = static_cast<int>(i % 6);
            const Quad q{conn[8 * e + hex_faces[f][0]], conn[8 * e + hex_faces[f][1]], conn[8 * e + hex_faces[f][2]],
                         conn[8 * e + hex_faces[f][3]]};
            // a degenerate solid's face collapsed to an edge or a point has no area: not a face
            const int distinct =
                1 + (q[1] != q[0]) + (q[2] != q[0] && q[2] != q[1]) + (q[3] != q[0] && q[3] != q[1] && q[3] != q[2]);
            if (distinct < 3)
                continue;
            if (owner)
                owner->push_back(e);
            faces.push_back(q);
        }
    return faces;
}

Vec3 quad_normal(const std::vector<real_t>& x, const Quad& q)
{
    auto p = [&](int j) { return Vec3(x[3 * q[j]], x[3 * q[j] + 1], x[3 * q[j] + 2]); };
    return 0.5 * (p(2) - p(0)).cross(p(3) - p(1));
}

index_t merge_coincident_nodes(std::vector<real_t>& x, std::vector<index_t>& conn, real_t tol)
{
    const index_t n = static_cast<index_t>(x.size() / 3);
    struct KeyHash
    {
        std::size_t operator()(const std::array<long long, 3>& k) const
        {
            return std::hash<long long>()(k[0] * 73856093LL ^ k[1] * 19349663LL ^ k[2] * 83492791LL);
        }
    };
    std::unordered_map<std::array<long long, 3>, std::vector<index_t>, KeyHash> grid;
    std::vector<index_t> new_id(n, -1);
    std::vector<real_t> kept;
    index_t n_kept = 0;
    const real_t cell = 2.0 * tol;
    for (index_t i = 0; i < n; ++i)
    {
        std::array<long long, 3> c;
        for (int d = 0; d < 3; ++d)
            c[d] = static_cast<long long>(std::floor(x[3 * i + d] / cell));
        index_t found = -1;
        for (int dx = -1; dx <= 1 && found < 0; ++dx)
            for (int dy = -1; dy <= 1 && found < 0; ++dy)
                for (int dz = -1; dz <= 1 && found < 0; ++dz)
                {
                    auto it = grid.find({c[0] + dx, c[1] + dy, c[2] + dz});
                    if (it == grid.end())
                        continue;
                    for (index_t k : it->second)
                    {
                        real_t d2 = 0;
                        for (int d = 0; d < 3; ++d)
                            d2 += (kept[3 * k + d] - x[3 * i + d]) * (kept[3 * k + d] - x[3 * i + d]);
                        if (d2 <= tol * tol)
                        {
                            found = k;
                            break;
                        }
                    }
                }
        if (found < 0)
        {
            found = n_kept++;
            for (int d = 0; d < 3; ++d)
                kept.push_back(x[3 * i + d]);
            grid[c].push_back(found);
        }
        new_id[i] = found;
    }
    for (auto& c : conn)
        c = new_id[c];
    x.swap(kept);
    return n_kept;
}
} // namespace rkfem
