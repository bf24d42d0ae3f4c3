#pragma once
/// @file contact_surface.hpp
/// A contact surface: quadrilateral segments (outward normals by the right-hand rule, as the
/// mesh's boundary faces are), what the penalty needs per segment, and the surface's nodes with
/// their tributary areas. Built once per discretization in the reference configuration; an
/// event that exposes new faces (erosion) builds it again.
#include <vector>

#include "rkfem/core/types.hpp"
#include "rkfem/discretization/hex_mesh.hpp"

namespace rkfem
{
struct ContactSurface
{
    std::vector<Quad> segments;
    std::vector<real_t> bulk_modulus; ///< per segment: K of the material behind it [Pa]
    std::vector<real_t> depth;        ///< per segment: V / A of the element behind it (reference) [m]
    std::vector<index_t> nodes;       ///< the segments' distinct nodes, ascending
    real_t area = 0.0;                ///< the segments' total area (reference) [m^2]
    /// Particles that take part as slaves only, each a sphere about its centre (node-to-segment
    /// contact): the particles of a semi-Lagrangian RK part that are not nodes of its segments.
    /// Its segments (the generating mesh's boundary faces) are the body's surface at the start;
    /// once an FSP has pushed them in, the particles behind them are what it meets, and a point
    /// slave would let it pass between them (at 1/2 in the FSP's 16.6 mm nose fits between four
    /// particles 12.7 mm apart). Not in `nodes`; ascending.
    std::vector<index_t> particles;
    std::vector<real_t> particle_radius; ///< per particle: its sphere's radius [m]

    index_t n_segments() const { return static_cast<index_t>(segments.size()); }
    /// Slaves: the segments' nodes, then the particles.
    index_t n_slaves() const { return static_cast<index_t>(nodes.size() + particles.size()); }
    index_t slave(index_t k) const
    {
        const std::size_t kk = static_cast<std::size_t>(k);
        return kk < nodes.size() ? nodes[kk] : particles[kk - nodes.size()];
    }
    /// Appends segments: faces of elements of a hex connectivity (owner[f]: the element of face
    /// f, an index into conn / 8; empty: depth from the face alone, its square root of area),
    /// bulk modulus K for all of them. x0: reference coordinates of every node (3 n).
    void add(const std::vector<Quad>& faces, const std::vector<index_t>& owner, const std::vector<index_t>& conn,
             const std::vector<real_t>& x0, real_t K);
    /// Collects `nodes` from the segments (call after the last add()).
    void finish();
};

/// The closest point of a bilinear quadrilateral segment to a point.
struct SegmentPoint
{
    real_t xi = 0.0, eta = 0.0;         ///< in [-1, 1]^2 (clamped)
    real_t N[4] = {0.0, 0.0, 0.0, 0.0}; ///< shape functions there
    Vec3 x = Vec3::Zero();              ///< the point on the segment
    Vec3 normal = Vec3::Zero();         ///< unit outward normal there
    bool inside = false;                ///< the unclamped projection lies in the segment (with a tolerance)
};

/// Projects p on the segment with corners c (Newton on the squared distance, clamped to the
/// parameter square). `tolerance`: how far outside [-1, 1] in (xi, eta) still counts as inside.
SegmentPoint project_on_segment(const Vec3 (&c)[4], const Vec3& p, real_t tolerance = 1e-3);
} // namespace rkfem
