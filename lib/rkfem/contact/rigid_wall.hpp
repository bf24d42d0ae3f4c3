#pragma once
/// @file rigid_wall.hpp
/// A rigid plane, stationary or moving at a constant velocity, in the style of LS-DYNA's
/// *RIGIDWALL_PLANAR (with its penalty option): the plane through p0 + v_w t with unit normal n
/// (pointing to the side the nodes belong on). A node s with gap g = (x_s - p0 - v_w t) . n < 0
/// gets the force
///   f = k (-g) n + friction,   k = scale m_s / dt0^2,
/// dt0 the first critical step the wall sees (the soft penalty of node-to-segment contact with
/// an infinite master mass), and Coulomb friction on v_s - v_w (contact_algorithm.hpp). With a
/// dashpot (NormalDamping, m* = m_s) the normal force is max(0, k (-g) + c v_n) and the wall bounds
/// the step at NormalDamping::step_factor dt0 / sqrt(1 + scale / 2) (node-to-segment's bound for
/// kappa = scale / dt0^2); without one it sets no bound (scale <= 0.8 keeps the step stable). The
/// wall takes the reaction; its resultant is the force on the nodes (LS-DYNA's RWFORC).
#include <vector>

#include "rkfem/contact/contact_algorithm.hpp"

namespace rkfem
{
struct RigidWallParameters
{
    Vec3 point = Vec3::Zero();
    Vec3 normal = Vec3::UnitZ(); ///< unit
    Vec3 velocity = Vec3::Zero();
    real_t scale = 0.1;
    Friction friction;
    NormalDamping damping;
};

class RigidWall final : public ContactAlgorithm
{
  public:
    /// The nodes of the surfaces meet the wall.
    RigidWall(std::vector<ContactSurface> surfaces, const RigidWallParameters& p);
    void add_forces(const PhysicalNodes& nodes, const ContactClock& clock, ContactChannel& channel) override;
    void set_surfaces(std::vector<ContactSurface> surfaces) override;
    void save_state(StateArchive& archive, const std::string& prefix) const override;
    void load_state(const StateArchive& archive, const std::string& prefix) override;
    real_t stable_step() const override;
    Vec3 resultant() const override { return resultant_; }
    index_t active_nodes() const override { return active_; }

  private:
    RigidWallParameters p_;
    std::vector<index_t> nodes_;
    std::vector<Vec3> f_; ///< per node of nodes_, this evaluation (zero: no contact)
    real_t dt0_ = 0.0;
    Vec3 resultant_ = Vec3::Zero();
    index_t active_ = 0;
};
} // namespace rkfem
