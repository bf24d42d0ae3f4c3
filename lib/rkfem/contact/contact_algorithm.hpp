#pragma once
/// @file contact_algorithm.hpp
/// One contact definition (a rigid wall, a pair of surfaces, a surface with itself): it reads the
/// current nodal state and adds its nodal forces to the contact channel. Penalty algorithms also
/// bound the stable step.
#include "rkfem/discretization/node_set.hpp"
#include "rkfem/operators/contact_channel.hpp"

namespace rkfem
{
class ContactAlgorithm
{
  public:
    virtual ~ContactAlgorithm() = default;
    /// Adds the forces at time t from the current positions x and velocities v (physical values).
    virtual void add_forces(const NodeSet& nodes, real_t t, ContactChannel& channel) = 0;
    /// The largest stable step the contact stiffness allows (1e300: no bound).
    virtual real_t stable_step() const { return 1e300; }
};
} // namespace rkfem
