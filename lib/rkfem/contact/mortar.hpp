#pragma once
/// @file mortar.hpp
/// Penalty segment-to-segment (mortar) contact between two surfaces, in the style of LS-DYNA's
/// *CONTACT_AUTOMATIC_SURFACE_TO_SURFACE_MORTAR: the contact pressure is integrated over the
/// overlap of the segments instead of being lumped at nodes, so a uniform pressure crosses a
/// non-matching interface as a uniform pressure (the contact patch test, which node-to-segment
/// contact fails: Taylor & Papadopoulos 1991; Puso & Laursen 2004).
///
/// Per pass (each surface is slave once, the other master; each pass carries half the penalty,
/// so the pair is symmetric and a matched interface has the stiffness of one pass), per slave
/// segment S and candidate master segment M, with the current physical positions:
///   - S's centre c and unit normal n (its area vector at the centre), and a basis (e1, e2) of
///     the plane through c normal to n; M must face S (n_M . n < 0);
///   - both segments projected along n onto that plane; M's polygon clipped by S's two triangles
///     (Sutherland-Hodgman; each triangle is convex, so a warped S works too), the clipped
///     polygons split into fans of triangles, 6 Gauss points per triangle (degree 4);
///   - at each point q: the parameters of S and of M that project onto q (Newton on the bilinear
///     map in the plane), the points x_S, x_M there, the gap g = (x_M - x_S) . n (positive: apart)
///     and the penetration p = thickness - g; where 0 < p < max_penetration min(h_S, h_M), the
///     pressure  k_A p  with the penalty per unit area
///       segment:  k_A = penalty_scale K_M / h_M  (LS-DYNA's SLSFAC K A^2 / V over A),
///       soft:     k_A = max(segment, soft_scale mu* / dt0^2),  mu* = mu_S mu_M / (mu_S + mu_M),
///                 mu the mass per unit area at the point (nodal mass over tributary area,
///                 interpolated), dt0 the first critical step the contact sees (SOFT = 1);
///   - the force w k_A p n pushes S back (on S's nodes -N_a^S of it) and M away (+N_b^M), plus
///     Coulomb friction on the relative tangential velocity with the traction bounded by the one
///     that stops the slip within dt0 (mu* |v_t| / dt0; contact_algorithm.hpp, Friction);
///     optionally a dashpot on the closing speed (NormalDamping: max(0, k_A p + c v_n) with
///     c = 2 zeta sqrt(k_A mu* / 2), each pass carrying half the pair).
/// The step bound is node-to-segment's, k a node's share of the penalty (sum over points of
/// k_A w N, both passes).
/// What it does not do (node-to-segment does): single-surface (self) contact, and holding
/// initial penetrations as offsets (LS-DYNA's IGNORE): a mortar pair that starts inside is
/// pushed apart. Forces are computed in parallel per slave segment into fixed slots, then added
/// to the channel in segment order: the bits do not depend on the thread count.
#include <vector>

#include "rkfem/contact/contact_algorithm.hpp"
#include "rkfem/contact/node_to_segment.hpp"
#include "rkfem/contact/segment_buckets.hpp"
#include "rkfem/contact/surface_contact_state.hpp"

namespace rkfem
{
/// An integration point of the overlap of a slave and a master segment: its weight (an area in
/// the slave's plane) and both segments' shape functions there.
struct OverlapPoint
{
    real_t w = 0.0;
    real_t Ns[4] = {0.0, 0.0, 0.0, 0.0};
    real_t Nm[4] = {0.0, 0.0, 0.0, 0.0};
};
/// The most points overlap_points() writes: two clip triangles, each clipping a quadrilateral
/// into at most 13 vertices (7 when the projected master is convex), so 11 fan triangles, 6
/// points per triangle.
inline constexpr int max_overlap_points = 2 * 11 * 6;

/// The integration points of the overlap of slave segment s and master segment m, both
/// projected along the slave's unit normal n (written to *normal) onto the plane through the
/// slave's centre. Returns their number (0: no overlap); weights sum to the overlap's area.
int overlap_points(const Vec3 (&s)[4], const Vec3 (&m)[4], OverlapPoint* out, Vec3* normal);

/// A slave segment's plane: unit normal n (its area vector), centre c, in-plane basis e1, e2, and
/// its corners in that basis with their bounding box.
struct SlaveFrame
{
    Vec3 n, c, e1, e2;
    real_t p[4][2];
    real_t lo[2], hi[2];
    /// False for a segment without area.
    bool set(const Vec3 (&s)[4]);
};
/// The same for a slave frame computed once for all its candidate masters.
int overlap_points(const SlaveFrame& slave, const Vec3 (&m)[4], OverlapPoint* out);

class MortarContact final : public SurfaceContact
{
  public:
    /// Two surfaces (surface-to-surface).
    MortarContact(std::vector<ContactSurface> surfaces, const ContactParameters& p);
    void add_forces(const PhysicalNodes& nodes, const ContactClock& clock, ContactChannel& channel) override;
    void set_surfaces(std::vector<ContactSurface> surfaces) override;
    void save_state(StateArchive& archive, const std::string& prefix) const override;
    void load_state(const StateArchive& archive, const std::string& prefix) override;
    bool holds_initial_penetrations() const override { return false; }

  private:
    struct Pass
    {
        int slave = 0, master = 0;
        std::vector<index_t> offsets, candidates; ///< per slave segment (CSR): master segments
        std::vector<Vec3> f_slave;                ///< 4 per slave segment: forces on its corners
        std::vector<Vec3> f_master;               ///< 4 per candidate pair: forces on the master's corners
        std::vector<real_t> k_slave, k_master;    ///< stiffness on those corners: sum of k_A w N
        SegmentBuckets buckets;
    };
    void search(const PhysicalNodes& nodes);
    void update_areas(const PhysicalNodes& nodes);
    void evaluate(Pass& pass, const PhysicalNodes& nodes);

    std::vector<ContactSurface> surfaces_;
    std::vector<std::vector<index_t>> corner_slot_; ///< per surface: 4 per segment, the corner's index in nodes
    std::vector<std::vector<real_t>> node_area_;    ///< per surface and node: current tributary area
    ContactParameters p_;
    std::vector<Pass> passes_;
    std::vector<index_t> all_nodes_;
    std::vector<char> touched_;  ///< per model node: scratch for counting active nodes
    std::vector<real_t> node_k_; ///< per model node: scratch, contact stiffness this evaluation
    real_t margin_ = 0.0, reach_ = 0.0;
    std::vector<real_t> lo_, hi_; ///< scratch: segment boxes
};
} // namespace rkfem
