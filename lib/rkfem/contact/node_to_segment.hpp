#pragma once
/// @file node_to_segment.hpp
/// Penalty node-to-segment contact in the style of LS-DYNA's *CONTACT_AUTOMATIC_SURFACE_TO_SURFACE
/// (two surfaces, both passes: each surface's nodes against the other's segments) and
/// *CONTACT_AUTOMATIC_SINGLE_SURFACE (one surface's nodes against its own segments, less those
/// that hold the node).
///
/// Per pass and slave node s, with the current physical positions:
///   - candidates: the master segments whose bounding box, inflated by the search margin, held s
///     at the last search (segment_buckets.hpp); the search is redone when a surface node has
///     moved more than half the margin since, so no pair that can touch is missed;
///   - the closest point of each candidate (project_on_segment), its outward normal n and the
///     gap g = (x_s - x_c) . n; s is in contact with the candidate whose projection lies in the
///     segment, which faces s's own surface (n . n_s < 0, n_s the mean outward normal of the
///     slave segments around s: a node on an edge of its part is not caught by the side face of
///     the other part that it slides along), and whose penetration p = thickness - g is positive
///     and smallest, provided it is below max_penetration times the depth of the element behind
///     the segment (deeper: the node has passed through and is released);
///   - a particle slave (ContactSurface::particles: a semi-Lagrangian RK part's particles behind its
///     surface) is a sphere of radius r about its centre: p = thickness + r - g where its centre
///     projects into the segment; where it projects outside, the sphere meets the segment's
///     closest point, along the line d from there to the centre (n = d / |d|, p = thickness + r -
///     |d|, centre on the segment's outer side); no normal test (a particle has no surface), and a
///     body's particles never meet its own segments (single-surface passes skip them);
///   - normal force f_n = k p on s along n, and -N_a f on the segment's nodes, with the stiffness
///       segment:  k = penalty_scale K A_s / h   (LS-DYNA's SLSFAC K A^2 / V, with A_s the slave
///                 node's tributary area facing the segment, sum over its slave segments f of
///                 max(0, -a_f . n) / 4 with a_f the area vector: a uniform pressure then gives a
///                 uniform penetration, and a node on an edge counts only its face that touches;
///                 a particle: (2 r)^2, its cube's face);
///       soft:     k = max(segment, soft_scale m* / dt0^2)  (LS-DYNA SOFT = 1), m* = m_s m_m / (m_s
///                 + m_m), m_m = sum N_a m_a, dt0 the first critical step the contact sees;
///   - optionally a dashpot on the closing speed, f_n = max(0, k p + c v_n), c = 2 zeta sqrt(k m*)
///     (contact_algorithm.hpp, NormalDamping; LS-DYNA's VDC);
///   - Coulomb friction on the relative tangential velocity (contact_algorithm.hpp, Friction);
///   - the depth acts as far as the node's approach explains it: per evaluation the depth may
///     grow by 1.5 dt0 |v_rel . n| (one step of approach, with room); growth beyond that (a node
///     that came in sideways across a segment's edge, penetrations at the start, faces an erosion
///     event exposed with nodes already inside) is held as an offset the spring starts from
///     (LS-DYNA's IGNORE = 1), which shrinks as the node moves out and is gone when it leaves. So
///     the force never jumps up by more than one step of approach, and contact does not create
///     energy.
/// The step: the contact bounds it at dt0 / sqrt(1 + kappa dt0^2 / 2), kappa the largest k / m over
/// the nodes in contact (k the springs on a node, m its mass; node_to_segment.cpp says why), times
/// NormalDamping::step_factor with a dashpot.
/// Forces are computed in parallel per slave node into a fixed slot each, then added to the
/// channel in node order: the bits do not depend on the thread count.
#include <vector>

#include "rkfem/contact/contact_algorithm.hpp"
#include "rkfem/contact/segment_buckets.hpp"
#include "rkfem/contact/surface_contact_state.hpp"

namespace rkfem
{
struct ContactParameters
{
    bool soft = true;             ///< stiffness max(segment, soft); false: segment only
    real_t penalty_scale = 0.1;   ///< SLSFAC
    real_t soft_scale = 0.1;      ///< SOFSCL
    real_t thickness = 0.0;       ///< contact starts at this gap [m]
    real_t max_penetration = 0.5; ///< of the element depth behind a segment; deeper is released
    Friction friction;
    NormalDamping damping;
};

class NodeToSegmentContact final : public SurfaceContact
{
  public:
    /// Two surfaces: surface-to-surface (both passes). One surface: single-surface.
    NodeToSegmentContact(std::vector<ContactSurface> surfaces, const ContactParameters& p);
    void add_forces(const PhysicalNodes& nodes, const ContactClock& clock, ContactChannel& channel) override;
    void set_surfaces(std::vector<ContactSurface> surfaces) override;
    void save_state(StateArchive& archive, const std::string& prefix) const override;
    void load_state(const StateArchive& archive, const std::string& prefix) override;

  private:
    struct Hit
    {
        index_t segment = -1;
        real_t N[4] = {0.0, 0.0, 0.0, 0.0};
        Vec3 f = Vec3::Zero(); ///< on the slave node
        real_t k = 0.0;        ///< the spring's stiffness (stable step)
    };
    struct Pass
    {
        int slave = 0, master = 0;
        std::vector<index_t> offsets, candidates; ///< per slave node (CSR)
        std::vector<Hit> hits;                    ///< per slave node
        std::vector<real_t> offset;               ///< per slave node: penetration the spring starts from
        std::vector<real_t> last_penetration;     ///< per slave node: geometric depth at the last evaluation
        SegmentBuckets buckets;
    };
    void search(const PhysicalNodes& nodes);
    /// The current mean outward normal at every node of every surface.
    void update_node_normals(const PhysicalNodes& nodes);
    void evaluate(Pass& pass, const PhysicalNodes& nodes) const;

    std::vector<ContactSurface> surfaces_;
    std::vector<std::vector<index_t>> corner_slot_; ///< per surface: 4 per segment, the corner's index in nodes
    std::vector<std::vector<Vec3>> node_normal_;    ///< per surface and node: unit mean outward normal
    std::vector<std::vector<Vec3>> segment_area_;   ///< per surface and segment: current area vector
    std::vector<std::vector<index_t>> node_segment_offsets_, node_segments_; ///< per surface: node -> segments (CSR)
    ContactParameters p_;
    std::vector<Pass> passes_;
    std::vector<index_t> all_nodes_; ///< the surfaces' nodes, ascending
    real_t margin_ = 0.0;            ///< motion allowed between searches (both sides together)
    real_t reach_ = 0.0;             ///< inflation of segment boxes: margin + deepest release depth + thickness
    bool fresh_ = true;              ///< the next evaluation is the first on these surfaces
    /// per pass: the slave nodes in contact at the last evaluation before new surfaces, with their
    /// penetration (sorted by node)
    struct Before
    {
        index_t node;
        real_t penetration, offset;
    };
    std::vector<std::vector<Before>> before_;
    std::vector<real_t> lo_, hi_; ///< scratch: segment boxes
    std::vector<real_t> node_k_;  ///< scratch per model node: the contact springs' stiffness on it
};
} // namespace rkfem
