#pragma once
/// @file contact_algorithm.hpp
/// One contact definition (a rigid wall, a pair of surfaces, a surface with itself): it reads the
/// current nodal state and adds its nodal forces to the contact channel. Penalty algorithms also
/// bound the stable step.
#include "rkfem/approximation/rk/kinematic_map.hpp"
#include "rkfem/discretization/node_set.hpp"
#include "rkfem/operators/contact_channel.hpp"

namespace rkfem
{
/// The physical positions and velocities of the nodes (through the kinematic map on RK
/// particles; the node set's own x and v elsewhere), as contact sees them.
class PhysicalNodes
{
  public:
    PhysicalNodes(const NodeSet& nodes, const KinematicMap& map) : nodes_(nodes), map_(map) {}
    index_t size() const { return nodes_.size(); }
    Vec3 x(index_t i) const
    {
        if (!map_.carries_coefficients(i))
            return {nodes_.x[3 * i], nodes_.x[3 * i + 1], nodes_.x[3 * i + 2]};
        return map_.position(nodes_.x0, nodes_.u, i);
    }
    Vec3 v(index_t i) const
    {
        if (!map_.carries_coefficients(i))
            return {nodes_.v[3 * i], nodes_.v[3 * i + 1], nodes_.v[3 * i + 2]};
        return map_.physical(nodes_.v.data(), i);
    }
    real_t mass(index_t i) const { return nodes_.mass[static_cast<std::size_t>(i)]; }
    const NodeSet& nodes() const { return nodes_; }

  private:
    const NodeSet& nodes_;
    const KinematicMap& map_;
};

class ContactAlgorithm
{
  public:
    virtual ~ContactAlgorithm() = default;
    /// Adds the forces at time t from the current physical positions and velocities; the
    /// channel takes forces at physical points.
    virtual void add_forces(const PhysicalNodes& nodes, real_t t, ContactChannel& channel) = 0;
    /// The largest stable step the contact stiffness allows (1e300: no bound).
    virtual real_t stable_step() const { return 1e300; }
};
} // namespace rkfem
