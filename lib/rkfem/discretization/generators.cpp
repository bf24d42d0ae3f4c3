#include "rkfem/discretization/generators.hpp"
#include "rkfem/discretization/gmsh_mesh.hpp"
#include "rkfem/discretization/keyword_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <numeric>
#include <random>
#include <sstream>

#include "rkfem/core/error.hpp"

namespace rkfem
{
namespace
{
void name_faces_by_normal(HexMesh& m, const std::vector<std::pair<std::string, Vec3>>& by_normal,
                          const std::string& rest)
{
    for (index_t f = 0; f < static_cast<index_t>(m.faces.size()); ++f)
    {
        Vec3 n = quad_normal(m.x, m.faces[f]);
        n.normalize();
        bool named = false;
        for (const auto& [name, dir] : by_normal)
            if (n.dot(dir) > 0.999)
            {
                m.named_faces[name].push_back(f);
                named = true;
                break;
            }
        if (!named && !rest.empty())
            m.named_faces[rest].push_back(f);
    }
}

int divisions_for(real_t length, real_t h)
{
    return std::max(1, static_cast<int>(std::lround(length / h)));
}

/// Quadrilateral mesh of a disk of radius R: a core block (straight or bulged edges) and four
/// blocks between the core and the circle. Returns points (n x 2) and CCW quads.
void disk_mesh(real_t R, real_t h, bool ogrid, std::vector<real_t>& pts, std::vector<index_t>& quads)
{
    const real_t a = 0.5 * R; // half-width of the core square
    const int nc = std::max(2, static_cast<int>(std::lround(M_PI * R / (2.0 * h))));
    const int nr = std::max(1, static_cast<int>(std::lround(0.4 * R / h)));
    const real_t bulge = ogrid ? 0.35 : 0.0;

    // Core edge point for side s (0:+x, 1:+y, 2:-x, 3:-y) at parameter t in [0,1], CCW.
    auto edge = [&](int s, real_t t)
    {
        const real_t theta = -M_PI / 4 + t * M_PI / 2;
        const real_t sx = a, sy = a * std::tan(theta); // straight edge, equal-angle spacing
        const real_t r = a * std::sqrt(2.0);
        const real_t cx = (1 - bulge) * sx + bulge * r * std::cos(theta);
        const real_t cy = (1 - bulge) * sy + bulge * r * std::sin(theta);
        const real_t c = std::cos(s * M_PI / 2), sn = std::sin(s * M_PI / 2);
        return std::array<real_t, 2>{c * cx - sn * cy, sn * cx + c * cy};
    };
    auto add_block = [&](int ni, int nj, auto&& point)
    {
        const index_t base = static_cast<index_t>(pts.size() / 2);
        for (int j = 0; j <= nj; ++j)
            for (int i = 0; i <= ni; ++i)
            {
                const auto p = point(real_t(i) / ni, real_t(j) / nj);
                pts.push_back(p[0]);
                pts.push_back(p[1]);
            }
        for (int j = 0; j < nj; ++j)
            for (int i = 0; i < ni; ++i)
            {
                index_t q[4] = {base + j * (ni + 1) + i, base + j * (ni + 1) + i + 1, base + (j + 1) * (ni + 1) + i + 1,
                                base + (j + 1) * (ni + 1) + i};
                // orientation fixed later
                quads.insert(quads.end(), q, q + 4);
            }
    };
    // Core: Coons patch over the four core edges. u along +x, v along +y.
    add_block(nc, nc,
              [&](real_t u, real_t v)
              {
                  const auto e = edge(0, v);       // x = +a side, param along +y
                  const auto w = edge(2, 1.0 - v); // x = -a side, param reversed
                  const auto n = edge(1, 1.0 - u); // y = +a side
                  const auto s = edge(3, u);       // y = -a side
                  const auto c00 = edge(3, 0.0), c10 = edge(3, 1.0), c11 = edge(1, 0.0), c01 = edge(1, 1.0);
                  std::array<real_t, 2> p;
                  for (int d = 0; d < 2; ++d)
                      p[d] =
                          (1 - u) * w[d] + u * e[d] + (1 - v) * s[d] + v * n[d] -
                          ((1 - u) * (1 - v) * c00[d] + u * (1 - v) * c10[d] + u * v * c11[d] + (1 - u) * v * c01[d]);
                  return p;
              });
    for (int side = 0; side < 4; ++side)
        add_block(nc, nr,
                  [&](real_t t, real_t s)
                  {
                      const auto p = edge(side, t);
                      const real_t theta = -M_PI / 4 + t * M_PI / 2 + side * M_PI / 2;
                      return std::array<real_t, 2>{(1 - s) * p[0] + s * R * std::cos(theta),
                                                   (1 - s) * p[1] + s * R * std::sin(theta)};
                  });
    // orient CCW
    for (std::size_t q = 0; q < quads.size(); q += 4)
    {
        real_t area2 = 0;
        for (int k = 0; k < 4; ++k)
        {
            const index_t i = quads[q + k], j = quads[q + (k + 1) % 4];
            area2 += pts[2 * i] * pts[2 * j + 1] - pts[2 * j] * pts[2 * i + 1];
        }
        if (area2 < 0)
            std::swap(quads[q + 1], quads[q + 3]);
    }
}
} // namespace

HexMesh generate_box(const Vec3& origin, const Vec3& size, const std::array<int, 3>& n)
{
    HexMesh m;
    const index_t nx = n[0] + 1, ny = n[1] + 1, nz = n[2] + 1;
    m.x.resize(static_cast<std::size_t>(nx) * ny * nz * 3);
    for (index_t k = 0; k < nz; ++k)
        for (index_t j = 0; j < ny; ++j)
            for (index_t i = 0; i < nx; ++i)
            {
                const std::size_t id = static_cast<std::size_t>(i + nx * (j + ny * k));
                m.x[3 * id + 0] = origin[0] + size[0] * i / n[0];
                m.x[3 * id + 1] = origin[1] + size[1] * j / n[1];
                m.x[3 * id + 2] = origin[2] + size[2] * k / n[2];
            }
    m.conn.reserve(static_cast<std::size_t>(n[0]) * n[1] * n[2] * 8);
    auto id = [&](index_t i, index_t j, index_t k) { return i + nx * (j + ny * k); };
    for (index_t k = 0; k < n[2]; ++k)
        for (index_t j = 0; j < n[1]; ++j)
            for (index_t i = 0; i < n[0]; ++i)
            {
                const index_t e[8] = {
                    id(i, j, k),     id(i + 1, j, k),     id(i + 1, j + 1, k),     id(i, j + 1, k),
                    id(i, j, k + 1), id(i + 1, j, k + 1), id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)};
                m.conn.insert(m.conn.end(), e, e + 8);
            }
    m.faces = extract_boundary_faces(m.conn);
    name_faces_by_normal(m,
                         {{"xmin", -Vec3::UnitX()},
                          {"xmax", Vec3::UnitX()},
                          {"ymin", -Vec3::UnitY()},
                          {"ymax", Vec3::UnitY()},
                          {"zmin", -Vec3::UnitZ()},
                          {"zmax", Vec3::UnitZ()}},
                         "");
    m.named_faces["top"] = m.named_faces["zmax"];
    m.named_faces["bottom"] = m.named_faces["zmin"];
    auto& side = m.named_faces["side"];
    for (const char* s : {"xmin", "xmax", "ymin", "ymax"})
        side.insert(side.end(), m.named_faces[s].begin(), m.named_faces[s].end());
    std::sort(side.begin(), side.end());
    return m;
}

namespace
{
/// The disk's nodes renumbered in a sweep across the disk, by ascending x, then y, and its quads
/// by their lowest, then highest, node number. The block-by-block order of disk_mesh puts a core
/// edge node and its neighbours in the ring block beyond it hundreds of nodes apart; in the
/// sweep a node's neighbours lie within about two chords (about 2 R / h nodes each) of it, so
/// that a run of the cylinder's columns touches a narrow band of node ids (the chunked scatter's
/// ranges, ChunkedScatter::add_chunks). The coordinates are compared rounded to 1e-9 R, so that
/// round-off in the input (0.5 in against 0.0127 m) does not reorder nodes whose x agree
/// (mirror images, the axis).
void sweep_order(real_t R, std::vector<real_t>& pts, std::vector<index_t>& quads)
{
    const std::size_t np = pts.size() / 2, nq = quads.size() / 4;
    // the items in ascending order of their keys (ties in their own order)
    auto ascending = [](const auto& key)
    {
        std::vector<index_t> order(key.size());
        std::iota(order.begin(), order.end(), index_t{0});
        std::stable_sort(order.begin(), order.end(),
                         [&](index_t a, index_t b)
                         { return key[static_cast<std::size_t>(a)] < key[static_cast<std::size_t>(b)]; });
        return order;
    };
    const real_t quantum = 1e-9 * R;
    std::vector<std::pair<long long, long long>> at(np);
    for (std::size_t i = 0; i < np; ++i)
        at[i] = {std::llround(pts[2 * i] / quantum), std::llround(pts[2 * i + 1] / quantum)};
    const std::vector<index_t> order = ascending(at);
    std::vector<index_t> rank(np);
    std::vector<real_t> moved(pts.size());
    for (std::size_t r = 0; r < np; ++r)
    {
        const std::size_t i = static_cast<std::size_t>(order[r]);
        rank[i] = static_cast<index_t>(r);
        moved[2 * r] = pts[2 * i];
        moved[2 * r + 1] = pts[2 * i + 1];
    }
    pts.swap(moved);
    std::vector<std::pair<index_t, index_t>> key(nq);
    for (std::size_t q = 0; q < nq; ++q)
    {
        key[q] = {std::numeric_limits<index_t>::max(), 0};
        for (int j = 0; j < 4; ++j)
        {
            index_t& n = quads[4 * q + j];
            n = rank[static_cast<std::size_t>(n)];
            key[q] = {std::min(key[q].first, n), std::max(key[q].second, n)};
        }
    }
    const std::vector<index_t> quad_order = ascending(key);
    std::vector<index_t> reordered(quads.size());
    for (std::size_t r = 0; r < nq; ++r)
        for (int j = 0; j < 4; ++j)
            reordered[4 * r + j] = quads[4 * static_cast<std::size_t>(quad_order[r]) + j];
    quads.swap(reordered);
}

/// generate_cylinder with the disk in disk_mesh's block order (sweep = false: the order the
/// cylinder cloud's particles and jitter follow) or in the sweep (sweep_order).
HexMesh cylinder_mesh(const Vec3& origin, real_t radius, real_t height, real_t h, bool ogrid, bool sweep)
{
    std::vector<real_t> pts;
    std::vector<index_t> quads;
    disk_mesh(radius, h, ogrid, pts, quads);
    // merge the shared block edges in 2D
    {
        std::vector<real_t> p3;
        for (std::size_t i = 0; i < pts.size() / 2; ++i)
            p3.insert(p3.end(), {pts[2 * i], pts[2 * i + 1], 0.0});
        merge_coincident_nodes(p3, quads, 1e-9 * radius);
        pts.clear();
        for (std::size_t i = 0; i < p3.size() / 3; ++i)
            pts.insert(pts.end(), {p3[3 * i], p3[3 * i + 1]});
    }
    if (sweep)
        sweep_order(radius, pts, quads);
    const index_t np = static_cast<index_t>(pts.size() / 2);
    const int nz = divisions_for(height, h);
    HexMesh m;
    // node (i, k) of disk node i at height k is (nz + 1) i + k, element (q, k) is nz q + k: the
    // height varies fastest, so a column's particles are consecutive and translates of each
    // other (their stencils are shared, and batches of 8 along a column read 8 consecutive
    // nodes), as are its elements
    const auto id = [&](index_t i, int k) { return static_cast<index_t>((nz + 1) * i + k); };
    m.x.reserve(static_cast<std::size_t>(np) * (nz + 1) * 3);
    for (index_t i = 0; i < np; ++i)
        for (int k = 0; k <= nz; ++k)
            m.x.insert(m.x.end(), {origin[0] + pts[2 * i], origin[1] + pts[2 * i + 1], origin[2] + height * k / nz});
    const std::size_t nq = quads.size() / 4;
    for (std::size_t q = 0; q < nq; ++q)
        for (int k = 0; k < nz; ++k)
        {
            index_t e[8];
            for (int j = 0; j < 4; ++j)
            {
                e[j] = id(quads[4 * q + j], k);
                e[j + 4] = id(quads[4 * q + j], k + 1);
            }
            m.conn.insert(m.conn.end(), e, e + 8);
        }
    m.faces = extract_boundary_faces(m.conn);
    name_faces_by_normal(m, {{"top", Vec3::UnitZ()}, {"bottom", -Vec3::UnitZ()}}, "side");
    return m;
}
} // namespace

HexMesh generate_cylinder(const Vec3& origin, real_t radius, real_t height, real_t h, bool ogrid)
{
    return cylinder_mesh(origin, radius, height, h, ogrid, true);
}

HexMesh generate_tube(const Vec3& origin, real_t R, real_t Ri, real_t height, real_t h)
{
    const int nr = divisions_for(R - Ri, h);
    const int nt = std::max(8, 4 * divisions_for(M_PI * (R + Ri) / 4, h)); // mean circumference / h, by quarters
    const int nz = divisions_for(height, h);
    HexMesh m;
    // node (i, j, k): radius i, angle j (periodic), height k
    auto id = [&](int i, int j, int k) { return static_cast<index_t>(i + (nr + 1) * ((j % nt) + nt * k)); };
    m.x.reserve(static_cast<std::size_t>(nr + 1) * nt * (nz + 1) * 3);
    for (int k = 0; k <= nz; ++k)
        for (int j = 0; j < nt; ++j)
            for (int i = 0; i <= nr; ++i)
            {
                const real_t r = Ri + (R - Ri) * i / nr, a = 2 * M_PI * j / nt;
                m.x.insert(m.x.end(),
                           {origin[0] + r * std::cos(a), origin[1] + r * std::sin(a), origin[2] + height * k / nz});
            }
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < nt; ++j)
            for (int i = 0; i < nr; ++i)
            {
                // counter-clockwise in (r, theta) seen from +z: positive volume
                const index_t e[8] = {
                    id(i, j, k),     id(i + 1, j, k),     id(i + 1, j + 1, k),     id(i, j + 1, k),
                    id(i, j, k + 1), id(i + 1, j, k + 1), id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)};
                m.conn.insert(m.conn.end(), e, e + 8);
            }
    m.faces = extract_boundary_faces(m.conn);
    name_faces_by_normal(m, {{"top", Vec3::UnitZ()}, {"bottom", -Vec3::UnitZ()}}, "");
    // the curved faces by their own outward normal: away from the axis on the outer surface,
    // towards it on the bore (a centroid's radius cannot tell them apart on a thin tube: a
    // chord's centroid falls inside the mid-radius once the wall is thinner than the sagitta)
    for (index_t f = 0; f < static_cast<index_t>(m.faces.size()); ++f)
    {
        Vec3 c = Vec3::Zero();
        for (index_t n : m.faces[f])
            c += m.node(n);
        c /= 4;
        const Vec3 n = quad_normal(m.x, m.faces[f]).normalized();
        if (std::abs(n[2]) > 0.999)
            continue;
        const real_t radial = n[0] * (c[0] - origin[0]) + n[1] * (c[1] - origin[1]);
        m.named_faces[radial > 0 ? "side" : "inner"].push_back(f);
    }
    return m;
}

HexMesh generate_cloud(const GeneratorSpec& g)
{
    const bool cyl = g.body == GeneratorSpec::Body::Cylinder;
    const Vec3 lo = g.origin, hi = g.origin + g.size; // box body
    const real_t tol = 1e-9 * (cyl ? std::hypot(2 * g.radius, g.height) : g.size.norm());
    const char* body_name = cyl ? "cylinder body" : "box body";
    // the body: inside (to tol), and the nearest point of the body for points on its surface
    auto inside = [&](const Vec3& p)
    {
        if (!cyl)
            return (p.array() >= lo.array() - tol).all() && (p.array() <= hi.array() + tol).all();
        const real_t z = p[2] - g.origin[2];
        return std::hypot(p[0] - g.origin[0], p[1] - g.origin[1]) <= g.radius + tol && z >= -tol && z <= g.height + tol;
    };
    auto clamp = [&](Vec3 p)
    {
        if (!cyl)
            return Vec3(p.cwiseMax(lo).cwiseMin(hi));
        const real_t r = std::hypot(p[0] - g.origin[0], p[1] - g.origin[1]);
        if (r > g.radius)
            for (int d = 0; d < 2; ++d)
                p[d] = g.origin[d] + (p[d] - g.origin[d]) * g.radius / r;
        p[2] = std::clamp(p[2], g.origin[2], g.origin[2] + g.height);
        return p;
    };
    HexMesh m;
    const SourceLocation where{g.loc.where, g.loc.path + ".points"};
    if (!g.points_file.empty())
    {
        std::ifstream in(g.points_file);
        if (!in)
            throw DeckError(where, "cannot open '" + g.points_file + "'", "expected a CSV file of x,y,z per line");
        std::string line;
        for (int ln = 1; std::getline(in, line); ++ln)
        {
            if (line.find_first_not_of(" \t\r") == std::string::npos || line[line.find_first_not_of(" \t")] == '#')
                continue;
            std::replace(line.begin(), line.end(), ',', ' ');
            std::istringstream is(line);
            real_t c[3];
            std::string rest;
            if (!(is >> c[0] >> c[1] >> c[2]) || (is >> rest))
                throw DeckError(where, g.points_file + ":" + std::to_string(ln) + " is not three numbers",
                                "expected x,y,z per line");
            const Vec3 p = g.points_unit * Vec3(c[0], c[1], c[2]);
            if (!inside(p))
                throw DeckError(where, g.points_file + ":" + std::to_string(ln) + " lies outside the " + body_name,
                                cyl ? "expected every point within radius of the axis and 0 .. height above origin"
                                    : "expected every point within origin .. origin + size");
            const Vec3 q = clamp(p);
            m.x.insert(m.x.end(), {q[0], q[1], q[2]});
        }
        if (m.n_nodes() < 8)
            throw DeckError(where, g.points_file + " has " + std::to_string(m.n_nodes()) + " points",
                            "expected at least 8 points");
    }
    else if (!cyl)
    {
        std::array<int, 3> n;
        Vec3 h;
        for (int d = 0; d < 3; ++d)
        {
            n[d] = divisions_for(g.size[d], g.element_size);
            h[d] = g.size[d] / n[d];
        }
        std::mt19937 gen(static_cast<unsigned>(g.seed));
        std::uniform_real_distribution<real_t> jit(-g.jitter, g.jitter);
        for (int k = 0; k <= n[2]; ++k)
            for (int j = 0; j <= n[1]; ++j)
                for (int i = 0; i <= n[0]; ++i)
                {
                    const int idx[3] = {i, j, k};
                    for (int d = 0; d < 3; ++d)
                    {
                        const real_t r = jit(gen); // drawn for every coordinate: the cloud depends on the seed only
                        const bool on_face = idx[d] == 0 || idx[d] == n[d];
                        m.x.push_back(lo[d] + (idx[d] + (on_face ? 0.0 : r)) * h[d]);
                    }
                }
    }
    else
    {
        // the nodes of the cylinder mesh generator (butterfly core: no clustering at the axis),
        // jittered by +-jitter spacing; a particle on the side keeps its radius (its angle, and
        // off the caps its height, are jittered), one on a cap keeps its height
        const HexMesh c = cylinder_mesh(g.origin, g.radius, g.height, g.element_size, false, false);
        const real_t h = g.element_size;
        std::mt19937 gen(static_cast<unsigned>(g.seed));
        std::uniform_real_distribution<real_t> jit(-g.jitter, g.jitter);
        // the particles layer by layer (the mesh numbers them column by column): the cloud of a
        // seed, and its order, are those of the layered numbering
        const index_t layers = divisions_for(g.height, g.element_size) + 1, per_layer = c.n_nodes() / layers;
        for (index_t n = 0; n < c.n_nodes(); ++n)
        {
            Vec3 p = c.node(layers * (n % per_layer) + n / per_layer);
            const real_t r0 = jit(gen), r1 = jit(gen), r2 = jit(gen); // three per particle: seed only
            const real_t dx = p[0] - g.origin[0], dy = p[1] - g.origin[1], z = p[2] - g.origin[2];
            const real_t r = std::hypot(dx, dy);
            const bool on_side = std::abs(r - g.radius) <= tol;
            const bool on_cap = std::abs(z) <= tol || std::abs(z - g.height) <= tol;
            if (on_side)
            {
                const real_t a = std::atan2(dy, dx) + r0 * h / g.radius;
                p[0] = g.origin[0] + g.radius * std::cos(a);
                p[1] = g.origin[1] + g.radius * std::sin(a);
            }
            else
            {
                p[0] += r0 * h;
                p[1] += r1 * h;
            }
            if (!on_cap)
                p[2] += r2 * h;
            p = clamp(p);
            m.x.insert(m.x.end(), {p[0], p[1], p[2]});
        }
    }
    for (index_t i = 0; i < m.n_nodes(); ++i)
    {
        const Vec3 p = m.node(i);
        if (cyl)
        {
            if (std::abs(p[2] - g.origin[2]) <= tol)
                m.named_nodes["bottom"].push_back(i);
            if (std::abs(p[2] - g.origin[2] - g.height) <= tol)
                m.named_nodes["top"].push_back(i);
            if (std::abs(std::hypot(p[0] - g.origin[0], p[1] - g.origin[1]) - g.radius) <= tol)
                m.named_nodes["side"].push_back(i);
            continue;
        }
        static const char* names[3][2] = {{"xmin", "xmax"}, {"ymin", "ymax"}, {"zmin", "zmax"}};
        bool side = false;
        for (int d = 0; d < 3; ++d)
            for (int e = 0; e < 2; ++e)
                if (std::abs(p[d] - (e ? hi[d] : lo[d])) <= tol)
                {
                    m.named_nodes[names[d][e]].push_back(i);
                    side = side || d < 2;
                }
        if (side)
            m.named_nodes["side"].push_back(i);
    }
    if (!cyl)
    {
        m.named_nodes["top"] = m.named_nodes["zmax"];
        m.named_nodes["bottom"] = m.named_nodes["zmin"];
    }
    return m;
}

HexMesh generate(const GeneratorSpec& g)
{
    switch (g.type)
    {
    case GeneratorSpec::Type::Box:
    {
        std::array<int, 3> n = g.divisions;
        if (n[0] == 0)
            for (int d = 0; d < 3; ++d)
                n[d] = divisions_for(g.size[d], g.element_size);
        return generate_box(g.origin, g.size, n);
    }
    case GeneratorSpec::Type::Cylinder:
        if (g.inner_radius > 0)
            return generate_tube(g.origin, g.radius, g.inner_radius, g.height, g.element_size);
        return generate_cylinder(g.origin, g.radius, g.height, g.element_size, g.core == "ogrid");
    case GeneratorSpec::Type::Cloud:
        return generate_cloud(g);
    case GeneratorSpec::Type::Keyword:
        return read_keyword_mesh(g);
    case GeneratorSpec::Type::Gmsh:
        return read_gmsh_mesh(g);
    case GeneratorSpec::Type::Projectile:
    {
        Vec3 base = g.origin;
        if (g.direction > 0)
            base[2] -= g.height; // nose at origin.z, body below it
        HexMesh m = generate_cylinder(base, g.radius, g.height, g.element_size, false);
        auto top = m.named_faces["top"];
        auto bottom = m.named_faces["bottom"];
        m.named_faces.erase("top");
        m.named_faces.erase("bottom");
        m.named_faces["nose"] = g.direction < 0 ? bottom : top;
        m.named_faces["tail"] = g.direction < 0 ? top : bottom;
        return m;
    }
    }
    throw Error("unknown generator");
}
} // namespace rkfem
