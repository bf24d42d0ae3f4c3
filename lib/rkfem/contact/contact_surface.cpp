#include "rkfem/contact/contact_surface.hpp"

#include <algorithm>
#include <cmath>

namespace rkfem
{
namespace
{
Vec3 point(const std::vector<real_t>& x, index_t i)
{
    return {x[3 * i], x[3 * i + 1], x[3 * i + 2]};
}

/// Volume of a hex by the divergence theorem over its six faces, each taken planar through its
/// centroid with its averaged area vector: exact for hexes with planar faces.
real_t hex_volume(const std::vector<index_t>& conn, index_t e, const std::vector<real_t>& x)
{
    real_t v = 0.0;
    for (const auto& f : hex_faces)
    {
        Quad q;
        Vec3 c = Vec3::Zero();
        for (int j = 0; j < 4; ++j)
        {
            q[j] = conn[8 * e + f[j]];
            c += 0.25 * point(x, q[j]);
        }
        v += c.dot(quad_normal(x, q)) / 3.0;
    }
    return v;
}
} // namespace

void ContactSurface::add(const std::vector<Quad>& faces, const std::vector<index_t>& owner,
                         const std::vector<index_t>& conn, const std::vector<real_t>& x0, real_t K)
{
    for (std::size_t f = 0; f < faces.size(); ++f)
    {
        const real_t face_area = quad_normal(x0, faces[f]).norm();
        real_t h = std::sqrt(face_area);
        if (!owner.empty() && face_area > 0.0)
            h = hex_volume(conn, owner[f], x0) / face_area;
        segments.push_back(faces[f]);
        bulk_modulus.push_back(K);
        depth.push_back(h);
        area += face_area;
    }
}

void ContactSurface::finish()
{
    nodes.clear();
    for (const Quad& q : segments)
        nodes.insert(nodes.end(), q.begin(), q.end());
    std::sort(nodes.begin(), nodes.end());
    nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
}

SegmentPoint project_on_segment(const Vec3 (&c)[4], const Vec3& p, real_t tolerance)
{
    // x(xi, eta) = sum_a N_a x_a, N_a = (1 + xi_a xi)(1 + eta_a eta) / 4, corners counter-clockwise
    // from (-1, -1): x = a0 + a1 xi + a2 eta + a3 xi eta
    const Vec3 a0 = 0.25 * (c[0] + c[1] + c[2] + c[3]);
    const Vec3 a1 = 0.25 * (-c[0] + c[1] + c[2] - c[3]);
    const Vec3 a2 = 0.25 * (-c[0] - c[1] + c[2] + c[3]);
    const Vec3 a3 = 0.25 * (c[0] - c[1] + c[2] - c[3]);
    real_t xi = 0.0, eta = 0.0;
    for (int it = 0; it < 8; ++it)
    {
        const Vec3 x = a0 + a1 * xi + a2 * eta + a3 * (xi * eta);
        const Vec3 t1 = a1 + a3 * eta, t2 = a2 + a3 * xi;
        const Vec3 r = x - p;
        // gradient and Hessian of |x - p|^2 / 2
        const real_t g1 = t1.dot(r), g2 = t2.dot(r);
        const real_t h11 = t1.dot(t1), h22 = t2.dot(t2), h12 = t1.dot(t2) + a3.dot(r);
        const real_t det = h11 * h22 - h12 * h12;
        if (!(std::abs(det) > 1e-300))
            break;
        const real_t dxi = (h22 * g1 - h12 * g2) / det, deta = (h11 * g2 - h12 * g1) / det;
        xi -= dxi;
        eta -= deta;
        // a point far outside (beyond the neighbouring segment's width) is outside for certain:
        // stop there, clamped below
        if (std::abs(xi) > 3.0 || std::abs(eta) > 3.0)
            break;
        if (std::abs(dxi) + std::abs(deta) < 1e-12)
            break;
    }
    SegmentPoint s;
    s.inside = std::abs(xi) <= 1.0 + tolerance && std::abs(eta) <= 1.0 + tolerance;
    s.xi = std::clamp(xi, -1.0, 1.0);
    s.eta = std::clamp(eta, -1.0, 1.0);
    s.N[0] = 0.25 * (1 - s.xi) * (1 - s.eta);
    s.N[1] = 0.25 * (1 + s.xi) * (1 - s.eta);
    s.N[2] = 0.25 * (1 + s.xi) * (1 + s.eta);
    s.N[3] = 0.25 * (1 - s.xi) * (1 + s.eta);
    s.x = a0 + a1 * s.xi + a2 * s.eta + a3 * (s.xi * s.eta);
    const Vec3 n = (a1 + a3 * s.eta).cross(a2 + a3 * s.xi);
    const real_t len = n.norm();
    s.normal = len > 0.0 ? Vec3(n / len) : Vec3::Zero();
    return s;
}
} // namespace rkfem
