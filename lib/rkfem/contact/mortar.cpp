#include "rkfem/contact/mortar.hpp"

#include <algorithm>
#include <cmath>

#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/state_archive.hpp"

namespace rkfem
{
namespace
{
struct P2
{
    real_t x, y;
};

/// Twice the signed area of triangle (a, b, c): positive counter-clockwise.
real_t cross2(const P2& a, const P2& b, const P2& c)
{
    return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

/// The part of polygon `in` (n vertices) left of the directed line a -> b (Sutherland-Hodgman,
/// one edge); returns the number of vertices written to out (at most n + 1 for a convex polygon,
/// 1.5 n for any).
int clip_by_edge(const P2* in, int n, const P2& a, const P2& b, P2* out)
{
    int m = 0;
    for (int i = 0; i < n; ++i)
    {
        const P2& p = in[i];
        const P2& q = in[(i + 1) % n];
        const real_t dp = cross2(a, b, p), dq = cross2(a, b, q);
        if (dp >= 0.0)
            out[m++] = p;
        if ((dp >= 0.0) != (dq >= 0.0))
        {
            const real_t t = dp / (dp - dq);
            out[m++] = {p.x + t * (q.x - p.x), p.y + t * (q.y - p.y)};
        }
    }
    return m;
}

/// The bilinear shape functions at (xi, eta), corners counter-clockwise from (-1, -1).
void bilinear(real_t xi, real_t eta, real_t (&N)[4])
{
    N[0] = 0.25 * (1 - xi) * (1 - eta);
    N[1] = 0.25 * (1 + xi) * (1 - eta);
    N[2] = 0.25 * (1 + xi) * (1 + eta);
    N[3] = 0.25 * (1 - xi) * (1 + eta);
}

/// The bilinear map of a plane quadrilateral with corners c (counter-clockwise from (-1, -1)):
/// x = a0 + a1 xi + a2 eta + a3 xi eta.
struct Bilinear2
{
    real_t a0x, a0y, a1x, a1y, a2x, a2y, a3x, a3y;
    bool affine; ///< a3 = 0 (a parallelogram): the map is linear
    explicit Bilinear2(const P2 (&c)[4])
        : a0x(0.25 * (c[0].x + c[1].x + c[2].x + c[3].x)), a0y(0.25 * (c[0].y + c[1].y + c[2].y + c[3].y)),
          a1x(0.25 * (-c[0].x + c[1].x + c[2].x - c[3].x)), a1y(0.25 * (-c[0].y + c[1].y + c[2].y - c[3].y)),
          a2x(0.25 * (-c[0].x - c[1].x + c[2].x + c[3].x)), a2y(0.25 * (-c[0].y - c[1].y + c[2].y + c[3].y)),
          a3x(0.25 * (c[0].x - c[1].x + c[2].x - c[3].x)), a3y(0.25 * (c[0].y - c[1].y + c[2].y - c[3].y)),
          affine(a3x == 0.0 && a3y == 0.0)
    {
    }
    /// The parameters at which the map reaches q (Newton from the centre; one solve for a
    /// parallelogram), clamped to [-1, 1]^2 (overlap points lie in both segments up to
    /// round-off), as shape functions.
    void inverse(const P2& q, real_t (&N)[4]) const
    {
        real_t xi = 0.0, eta = 0.0;
        for (int it = 0; it < 20; ++it)
        {
            const real_t rx = a0x + a1x * xi + a2x * eta + a3x * xi * eta - q.x;
            const real_t ry = a0y + a1y * xi + a2y * eta + a3y * xi * eta - q.y;
            const real_t j11 = a1x + a3x * eta, j12 = a2x + a3x * xi;
            const real_t j21 = a1y + a3y * eta, j22 = a2y + a3y * xi;
            const real_t det = j11 * j22 - j12 * j21;
            if (!(std::abs(det) > 0.0))
                break;
            const real_t dxi = (j22 * rx - j12 * ry) / det, deta = (j11 * ry - j21 * rx) / det;
            xi -= dxi;
            eta -= deta;
            if (affine || std::abs(dxi) + std::abs(deta) < 1e-13)
                break;
        }
        bilinear(std::clamp(xi, -1.0, 1.0), std::clamp(eta, -1.0, 1.0), N);
    }
};

// Dunavant's 6-point rule on a triangle (degree 4): barycentric coordinates and weights (sum 1)
constexpr real_t ga = 0.445948490915965, gb = 0.108103018168070, gw1 = 0.223381589678011;
constexpr real_t gc = 0.091576213509771, gd = 0.816847572980459, gw2 = 0.109951743655322;
constexpr real_t gauss[6][4] = {{ga, ga, gb, gw1}, {ga, gb, ga, gw1}, {gb, ga, ga, gw1},
                                {gc, gc, gd, gw2}, {gc, gd, gc, gw2}, {gd, gc, gc, gw2}};
} // namespace

bool SlaveFrame::set(const Vec3 (&s)[4])
{
    const Vec3 area = 0.5 * (s[2] - s[0]).cross(s[3] - s[1]);
    const real_t len = area.norm();
    if (!(len > 0.0))
        return false;
    n = area / len;
    c = 0.25 * (s[0] + s[1] + s[2] + s[3]);
    e1 = (s[1] - s[0]) + (s[2] - s[3]);
    e1 -= e1.dot(n) * n;
    if (!(e1.norm() > 0.0))
        return false;
    e1.normalize();
    e2 = n.cross(e1);
    lo[0] = lo[1] = kNoLimit;
    hi[0] = hi[1] = -kNoLimit;
    for (int a = 0; a < 4; ++a)
    {
        p[a][0] = (s[a] - c).dot(e1);
        p[a][1] = (s[a] - c).dot(e2);
        for (int d = 0; d < 2; ++d)
        {
            lo[d] = std::min(lo[d], p[a][d]);
            hi[d] = std::max(hi[d], p[a][d]);
        }
    }
    return true;
}

int overlap_points(const SlaveFrame& f, const Vec3 (&m)[4], OverlapPoint* out)
{
    P2 sp[4], mp[4];
    real_t mlo[2] = {kNoLimit, kNoLimit}, mhi[2] = {-kNoLimit, -kNoLimit};
    for (int a = 0; a < 4; ++a)
    {
        sp[a] = {f.p[a][0], f.p[a][1]};
        mp[a] = {(m[a] - f.c).dot(f.e1), (m[a] - f.c).dot(f.e2)};
        mlo[0] = std::min(mlo[0], mp[a].x), mhi[0] = std::max(mhi[0], mp[a].x);
        mlo[1] = std::min(mlo[1], mp[a].y), mhi[1] = std::max(mhi[1], mp[a].y);
    }
    // boxes apart, or meeting at an edge (within round-off of the segment's size): no area
    const real_t tol = 1e-12 * (f.hi[0] - f.lo[0] + f.hi[1] - f.lo[1]);
    for (int d = 0; d < 2; ++d)
        if (mlo[d] >= f.hi[d] - tol || mhi[d] <= f.lo[d] + tol)
            return 0;
    // the master polygon's orientation (it faces the slave: clockwise here)
    const real_t m_area = cross2(mp[0], mp[1], mp[2]) + cross2(mp[0], mp[2], mp[3]);
    if (m_area == 0.0)
        return 0;
    const real_t sign = m_area > 0.0 ? 1.0 : -1.0;
    // the slave as two counter-clockwise triangles: split along the diagonal that keeps both positive
    int tri[2][3] = {{0, 1, 2}, {0, 2, 3}};
    if (!(cross2(sp[0], sp[1], sp[2]) > 0.0 && cross2(sp[0], sp[2], sp[3]) > 0.0))
    {
        tri[0][0] = 1, tri[0][1] = 2, tri[0][2] = 3;
        tri[1][0] = 1, tri[1][1] = 3, tri[1][2] = 0;
    }
    const Bilinear2 s_map(sp), m_map(mp);
    int count = 0;
    for (const auto& t : tri)
    {
        if (!(cross2(sp[t[0]], sp[t[1]], sp[t[2]]) > 0.0))
            continue; // a degenerate slave half
        // a clip of an n-gon keeps at most 1.5 n vertices (n for a convex one, plus one): 4, 6,
        // 9, 13 for a projected master that is not convex
        P2 a[16], b[16];
        int na = 4;
        std::copy(mp, mp + 4, a);
        na = clip_by_edge(a, na, sp[t[0]], sp[t[1]], b);
        na = clip_by_edge(b, na, sp[t[1]], sp[t[2]], a);
        na = clip_by_edge(a, na, sp[t[2]], sp[t[0]], b);
        for (int i = 1; i + 1 < na; ++i)
        {
            const real_t tri_area = 0.5 * sign * cross2(b[0], b[i], b[i + 1]);
            if (tri_area == 0.0)
                continue;
            for (const auto& g : gauss)
            {
                const P2 q{g[0] * b[0].x + g[1] * b[i].x + g[2] * b[i + 1].x,
                           g[0] * b[0].y + g[1] * b[i].y + g[2] * b[i + 1].y};
                OverlapPoint& o = out[count++];
                o.w = g[3] * tri_area;
                s_map.inverse(q, o.Ns);
                m_map.inverse(q, o.Nm);
            }
        }
    }
    return count;
}

int overlap_points(const Vec3 (&s)[4], const Vec3 (&m)[4], OverlapPoint* out, Vec3* normal)
{
    SlaveFrame f;
    if (!f.set(s))
        return 0;
    *normal = f.n;
    return overlap_points(f, m, out);
}

MortarContact::MortarContact(std::vector<ContactSurface> surfaces, const ContactParameters& p) : p_(p)
{
    set_surfaces(std::move(surfaces));
}

void MortarContact::set_surfaces(std::vector<ContactSurface> surfaces)
{
    if (surfaces.size() != 2)
        throw Error("mortar contact takes two surfaces (surface-to-surface)");
    surfaces_ = std::move(surfaces);
    passes_.assign(2, Pass{});
    passes_[0].slave = 0, passes_[0].master = 1;
    passes_[1].slave = 1, passes_[1].master = 0;
    all_nodes_.clear();
    real_t size = 0.0, deepest = 0.0;
    index_t n_seg = 0;
    corner_slot_.assign(2, {});
    node_area_.assign(2, {});
    for (std::size_t k = 0; k < 2; ++k)
    {
        const ContactSurface& s = surfaces_[k];
        all_nodes_.insert(all_nodes_.end(), s.nodes.begin(), s.nodes.end());
        for (index_t f = 0; f < s.n_segments(); ++f)
            deepest = std::max(deepest, s.depth[f]);
        size += s.area;
        n_seg += s.n_segments();
        for (const Quad& q : s.segments)
            for (index_t n : q)
                corner_slot_[k].push_back(
                    static_cast<index_t>(std::lower_bound(s.nodes.begin(), s.nodes.end(), n) - s.nodes.begin()));
        node_area_[k].assign(s.nodes.size(), 0.0);
    }
    std::sort(all_nodes_.begin(), all_nodes_.end());
    all_nodes_.erase(std::unique(all_nodes_.begin(), all_nodes_.end()), all_nodes_.end());
    margin_ = n_seg > 0 ? 0.25 * std::sqrt(size / static_cast<real_t>(n_seg)) : 0.0;
    reach_ = margin_ + p_.max_penetration * deepest + p_.thickness;
    s_.searched = false;
    s_.active = 0;
    s_.resultant = Vec3::Zero();
}

void MortarContact::search(const PhysicalNodes& nodes)
{
    s_.record_search(nodes, all_nodes_);
    auto box = [&](const Quad& q, Vec3& lo, Vec3& hi)
    {
        lo = Vec3::Constant(kNoLimit), hi = Vec3::Constant(-kNoLimit);
        for (index_t n : q)
        {
            const Vec3 x = nodes.x(n);
            lo = lo.cwiseMin(x);
            hi = hi.cwiseMax(x);
        }
    };
    for (Pass& pass : passes_)
    {
        const ContactSurface& master = surfaces_[static_cast<std::size_t>(pass.master)];
        const ContactSurface& slave = surfaces_[static_cast<std::size_t>(pass.slave)];
        const index_t nm = master.n_segments(), ns = slave.n_segments();
        // a slave segment's boxes: its centre finds the master boxes inflated by the reach and
        // the largest half-extent of a slave box; the boxes themselves then decide
        real_t half = 0.0;
        for (index_t s = 0; s < ns; ++s)
        {
            Vec3 lo, hi;
            box(slave.segments[s], lo, hi);
            half = std::max(half, 0.5 * (hi - lo).maxCoeff());
        }
        lo_.resize(3 * static_cast<std::size_t>(nm));
        hi_.resize(3 * static_cast<std::size_t>(nm));
        for (index_t s = 0; s < nm; ++s)
        {
            Vec3 lo, hi;
            box(master.segments[s], lo, hi);
            for (int d = 0; d < 3; ++d)
            {
                lo_[3 * s + d] = lo[d];
                hi_[3 * s + d] = hi[d];
            }
        }
        pass.buckets.build(lo_, hi_, reach_ + half);
        pass.offsets.assign(static_cast<std::size_t>(ns) + 1, 0);
        pass.candidates.clear();
        for (index_t s = 0; s < ns; ++s)
        {
            Vec3 lo, hi;
            box(slave.segments[s], lo, hi);
            pass.buckets.for_candidates(0.5 * (lo + hi),
                                        [&](index_t m)
                                        {
                                            for (int d = 0; d < 3; ++d)
                                                if (lo[d] > hi_[3 * m + d] + reach_ || hi[d] < lo_[3 * m + d] - reach_)
                                                    return;
                                            pass.candidates.push_back(m);
                                        });
            pass.offsets[s + 1] = static_cast<index_t>(pass.candidates.size());
        }
        pass.f_slave.assign(4 * static_cast<std::size_t>(ns), Vec3::Zero());
        pass.f_master.assign(4 * pass.candidates.size(), Vec3::Zero());
        pass.k_slave.assign(4 * static_cast<std::size_t>(ns), 0.0);
        pass.k_master.assign(4 * pass.candidates.size(), 0.0);
    }
}

void MortarContact::update_areas(const PhysicalNodes& nodes)
{
    for (std::size_t k = 0; k < surfaces_.size(); ++k)
    {
        const ContactSurface& s = surfaces_[k];
        std::vector<real_t>& a = node_area_[k];
        std::fill(a.begin(), a.end(), 0.0);
        for (index_t f = 0; f < s.n_segments(); ++f)
        {
            const Quad& q = s.segments[f];
            const real_t area = 0.5 * (nodes.x(q[2]) - nodes.x(q[0])).cross(nodes.x(q[3]) - nodes.x(q[1])).norm();
            for (int c = 0; c < 4; ++c)
                a[static_cast<std::size_t>(corner_slot_[k][4 * static_cast<std::size_t>(f) + c])] += 0.25 * area;
        }
    }
}

void MortarContact::evaluate(Pass& pass, const PhysicalNodes& nodes)
{
    const std::size_t is = static_cast<std::size_t>(pass.slave), im = static_cast<std::size_t>(pass.master);
    const ContactSurface& master = surfaces_[im];
    const ContactSurface& slave = surfaces_[is];
    const bool soft = p_.soft && s_.dt0 > 0.0 && s_.dt0 < kNoLimit;
    parallel_for(
        "rkfem::contact_mortar", slave.n_segments(),
        [&](index_t s)
        {
            const std::size_t s4 = 4 * static_cast<std::size_t>(s);
            Vec3* fs = &pass.f_slave[s4];
            for (int a = 0; a < 4; ++a)
                fs[a] = Vec3::Zero();
            real_t* ks = &pass.k_slave[s4];
            for (int a = 0; a < 4; ++a)
                ks[a] = 0.0;
            const Quad& qs = slave.segments[s];
            const Vec3 xs[4] = {nodes.x(qs[0]), nodes.x(qs[1]), nodes.x(qs[2]), nodes.x(qs[3])};
            real_t mu_s[4];
            for (int a = 0; a < 4; ++a)
                mu_s[a] = nodes.mass(qs[a]) / node_area_[is][static_cast<std::size_t>(corner_slot_[is][s4 + a])];
            const Vec3 lo_s = xs[0].cwiseMin(xs[1]).cwiseMin(xs[2].cwiseMin(xs[3]));
            const Vec3 hi_s = xs[0].cwiseMax(xs[1]).cwiseMax(xs[2].cwiseMax(xs[3]));
            Vec3 vs[4];
            bool have_vs = false;
            OverlapPoint pts[max_overlap_points];
            SlaveFrame frame;
            if (!frame.set(xs))
            {
                for (index_t c = pass.offsets[s]; c < pass.offsets[s + 1]; ++c)
                    for (int b = 0; b < 4; ++b)
                    {
                        pass.f_master[4 * static_cast<std::size_t>(c) + b] = Vec3::Zero();
                        pass.k_master[4 * static_cast<std::size_t>(c) + b] = 0.0;
                    }
                return; // a collapsed slave segment takes no load
            }
            const Vec3& n = frame.n;
            // the slave corners' greatest height over its centre plane (the gap bound below)
            real_t s_hi = -kNoLimit;
            for (int a = 0; a < 4; ++a)
                s_hi = std::max(s_hi, (xs[a] - frame.c).dot(n));
            for (index_t c = pass.offsets[s]; c < pass.offsets[s + 1]; ++c)
            {
                Vec3* fm = &pass.f_master[4 * static_cast<std::size_t>(c)];
                real_t* km = &pass.k_master[4 * static_cast<std::size_t>(c)];
                for (int b = 0; b < 4; ++b)
                {
                    fm[b] = Vec3::Zero();
                    km[b] = 0.0;
                }
                const index_t m = pass.candidates[c];
                const Quad& qm = master.segments[m];
                const Vec3 xm[4] = {nodes.x(qm[0]), nodes.x(qm[1]), nodes.x(qm[2]), nodes.x(qm[3])};
                const real_t limit = p_.max_penetration * std::min(slave.depth[s], master.depth[m]) + p_.thickness;
                const Vec3 lo_m = xm[0].cwiseMin(xm[1]).cwiseMin(xm[2].cwiseMin(xm[3]));
                const Vec3 hi_m = xm[0].cwiseMax(xm[1]).cwiseMax(xm[2].cwiseMax(xm[3]));
                if ((lo_s.array() > hi_m.array() + limit).any() || (hi_s.array() < lo_m.array() - limit).any())
                    continue;
                if (!((xm[2] - xm[0]).cross(xm[3] - xm[1]).dot(n) < 0.0))
                    continue; // not facing
                // the gap anywhere between them is at least the master corners' least
                // height over the slave's centre plane less the slave corners' greatest
                real_t m_lo = kNoLimit;
                for (int a = 0; a < 4; ++a)
                    m_lo = std::min(m_lo, (xm[a] - frame.c).dot(n));
                if (m_lo - s_hi >= p_.thickness)
                    continue; // apart everywhere
                const int np = overlap_points(frame, xm, pts);
                if (np == 0)
                    continue;
                real_t mu_m[4];
                for (int b = 0; b < 4; ++b)
                    mu_m[b] =
                        nodes.mass(qm[b]) /
                        node_area_[im][static_cast<std::size_t>(corner_slot_[im][4 * static_cast<std::size_t>(m) + b])];
                Vec3 vm[4];
                bool have_vm = false;
                const real_t k_segment = 0.5 * p_.penalty_scale * master.bulk_modulus[m] / master.depth[m];
                // the corners' heights along n: the gap at a point is their interpolation
                real_t hs[4], hm[4];
                for (int a = 0; a < 4; ++a)
                {
                    hs[a] = xs[a].dot(n);
                    hm[a] = xm[a].dot(n);
                }
                for (int ip = 0; ip < np; ++ip)
                {
                    const OverlapPoint& o = pts[ip];
                    real_t gap = 0.0;
                    for (int a = 0; a < 4; ++a)
                        gap += o.Nm[a] * hm[a] - o.Ns[a] * hs[a];
                    const real_t pen = p_.thickness - gap;
                    if (!(pen > 0.0) || pen > limit)
                        continue;
                    real_t ms = 0.0, mm = 0.0;
                    for (int a = 0; a < 4; ++a)
                    {
                        ms += o.Ns[a] * mu_s[a];
                        mm += o.Nm[a] * mu_m[a];
                    }
                    const real_t mu_star = ms * mm / (ms + mm);
                    real_t k_a = k_segment;
                    if (soft)
                        k_a = std::max(k_a, 0.5 * p_.soft_scale * mu_star / (s_.dt0 * s_.dt0));

                    const bool friction = p_.friction.active() && s_.dt0 > 0.0;
                    Vec3 v_rel = Vec3::Zero();
                    if (friction || p_.damping.active())
                    {
                        if (!have_vs)
                            for (int a = 0; a < 4; ++a)
                                vs[a] = nodes.v(qs[a]);
                        if (!have_vm)
                            for (int b = 0; b < 4; ++b)
                                vm[b] = nodes.v(qm[b]);
                        have_vs = have_vm = true;
                        for (int a = 0; a < 4; ++a)
                            v_rel += o.Ns[a] * vs[a] - o.Nm[a] * vm[a];
                    }
                    // each pass carries half the pair's spring, so half its reduced mass (the
                    // slave closes on the master while (v_S - v_M) . n > 0)
                    const real_t pressure =
                        p_.damping.active() ? p_.damping.force(k_a, pen, v_rel.dot(n), 0.5 * mu_star) : k_a * pen;
                    Vec3 f = (-o.w * pressure) * n; // on the slave
                    if (friction)
                    {
                        const Vec3 v_t = v_rel - v_rel.dot(n) * n;
                        f += o.w * p_.friction.force(v_t, pressure, 0.5 * mu_star, s_.dt0);
                    }
                    for (int a = 0; a < 4; ++a)
                    {
                        fs[a] += o.Ns[a] * f;
                        fm[a] -= o.Nm[a] * f;
                        ks[a] += o.Ns[a] * o.w * k_a;
                        km[a] += o.Nm[a] * o.w * k_a;
                    }
                }
            }
        });
}

void MortarContact::add_forces(const PhysicalNodes& nodes, const ContactClock& clock, ContactChannel& channel)
{
    s_.see(clock);
    if (s_.search_due(nodes, all_nodes_, margin_))
        search(nodes);
    update_areas(nodes);
    touched_.resize(static_cast<std::size_t>(nodes.size()), 0);
    node_k_.resize(static_cast<std::size_t>(nodes.size()), 0.0);
    s_.resultant = Vec3::Zero();
    s_.active = 0;
    auto add = [&](index_t node, const Vec3& f, real_t k)
    {
        if (f[0] == 0.0 && f[1] == 0.0 && f[2] == 0.0)
            return;
        channel.add(node, f);
        char& t = touched_[static_cast<std::size_t>(node)];
        s_.active += t == 0;
        t = 1;
        node_k_[static_cast<std::size_t>(node)] += k;
    };
    for (Pass& pass : passes_)
    {
        evaluate(pass, nodes);
        const ContactSurface& master = surfaces_[static_cast<std::size_t>(pass.master)];
        const ContactSurface& slave = surfaces_[static_cast<std::size_t>(pass.slave)];
        for (index_t s = 0; s < slave.n_segments(); ++s)
        {
            const std::size_t s4 = 4 * static_cast<std::size_t>(s);
            for (int a = 0; a < 4; ++a)
            {
                add(slave.segments[s][a], pass.f_slave[s4 + a], pass.k_slave[s4 + a]);
                if (pass.slave == 0)
                    s_.resultant += pass.f_slave[s4 + a];
            }
            if (pass.k_slave[s4] + pass.k_slave[s4 + 1] + pass.k_slave[s4 + 2] + pass.k_slave[s4 + 3] == 0.0)
                continue; // no point of this slave segment touched: nor did its masters'
            for (index_t c = pass.offsets[s]; c < pass.offsets[s + 1]; ++c)
                for (int b = 0; b < 4; ++b)
                {
                    const std::size_t cb = 4 * static_cast<std::size_t>(c) + static_cast<std::size_t>(b);
                    add(master.segments[pass.candidates[c]][b], pass.f_master[cb], pass.k_master[cb]);
                    if (pass.master == 0)
                        s_.resultant += pass.f_master[cb];
                }
        }
    }
    // the first evaluation: the nodes with a force started inside
    if (!s_.started)
    {
        s_.initial_penetrations = s_.active;
        s_.started = true;
    }
    // A node's contact stiffness k (both passes' k_A w N) against its mass, the largest over the
    // nodes in contact, in node_to_segment.cpp's bound. The marks and stiffnesses are cleared for
    // the next evaluation.
    real_t k_over_m = 0.0;
    for (const index_t i : all_nodes_)
    {
        const std::size_t ii = static_cast<std::size_t>(i);
        if (touched_[ii])
            k_over_m = std::max(k_over_m, node_k_[ii] / nodes.mass(i));
        touched_[ii] = 0;
        node_k_[ii] = 0.0;
    }
    s_.bound_step(k_over_m, p_.damping.step_factor());
}

void MortarContact::save_state(StateArchive& a, const std::string& prefix) const
{
    for (std::size_t k = 0; k < passes_.size(); ++k)
    {
        const std::string pp = prefix + "pass." + std::to_string(k) + ".";
        a.put(pp + "offsets", passes_[k].offsets);
        a.put(pp + "candidates", passes_[k].candidates);
    }
    s_.save(a, prefix);
}

void MortarContact::load_state(const StateArchive& a, const std::string& prefix)
{
    for (std::size_t k = 0; k < passes_.size(); ++k)
    {
        Pass& pass = passes_[k];
        const std::string pp = prefix + "pass." + std::to_string(k) + ".";
        a.get(pp + "offsets", pass.offsets);
        a.get(pp + "candidates", pass.candidates);
        const std::size_t ns = pass.offsets.empty() ? 0 : pass.offsets.size() - 1;
        pass.f_slave.assign(4 * ns, Vec3::Zero());
        pass.f_master.assign(4 * pass.candidates.size(), Vec3::Zero());
        pass.k_slave.assign(4 * ns, 0.0);
        pass.k_master.assign(4 * pass.candidates.size(), 0.0);
    }
    s_.load(a, prefix);
}
} // namespace rkfem
