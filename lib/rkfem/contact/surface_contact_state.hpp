#pragma once
/// @file surface_contact_state.hpp
/// What the surface contacts (node-to-segment and mortar) keep between evaluations besides their
/// pair lists: the surface nodes' positions at the last search and when the next is due, the
/// first critical step (the soft penalty's dt0), the step bound, the last resultant and counts;
/// and how a checkpoint holds them.
#include <string>
#include <vector>

#include "rkfem/contact/contact_algorithm.hpp"

namespace rkfem
{
struct SurfaceContactState
{
    std::vector<real_t> x_search; ///< the surface nodes' positions at the last search (3 each)
    real_t dt0 = 0.0;             ///< the first critical step the contact saw
    real_t dt_bound = kNoLimit;   ///< the contact's bound on the step (kNoLimit: none)
    Vec3 resultant = Vec3::Zero();
    index_t active = 0, searches = 0, initial_penetrations = 0;
    bool searched = false, started = false;

    /// Takes the clock's critical step as dt0 at the first evaluation that has one.
    void see(const ContactClock& clock)
    {
        if (dt0 == 0.0 && clock.dt_critical > 0.0)
            dt0 = clock.dt_critical;
    }
    /// A search is due: none yet, or a node of `nodes` moved more than half the margin since.
    bool search_due(const PhysicalNodes& nodes, const std::vector<index_t>& surface_nodes, real_t margin) const;
    /// Records the positions a search was made at.
    void record_search(const PhysicalNodes& nodes, const std::vector<index_t>& surface_nodes);
    /// Bounds the step from kappa, the largest k / m over the nodes in contact (node_to_segment.cpp
    /// says why): dt0 / sqrt(1 + kappa dt0^2 / 2), held from the first contact on.
    /// With a dashpot, times its factor (NormalDamping::step_factor).
    void bound_step(real_t kappa, real_t factor = 1.0);
    void save(StateArchive& archive, const std::string& prefix) const;
    void load(const StateArchive& archive, const std::string& prefix);
};

/// A contact between surfaces (node-to-segment, mortar): what it reports, from its state.
class SurfaceContact : public ContactAlgorithm
{
  public:
    real_t stable_step() const override { return s_.dt_bound; }
    Vec3 resultant() const override { return s_.resultant; }
    index_t active_nodes() const override { return s_.active; }
    /// Nodes found inside the other surface at the first evaluation.
    index_t initial_penetrations() const override { return s_.initial_penetrations; }
    /// Searches done so far (the first evaluation's included).
    index_t searches() const { return s_.searches; }

  protected:
    SurfaceContactState s_; ///< search positions, dt0, step bound, resultant and counts
};
} // namespace rkfem
