#pragma once
/// @file contact_algorithm.hpp
/// One contact definition (a rigid wall, a pair of surfaces, a surface with itself): it reads the
/// current nodal state and adds its nodal forces to the contact channel. Penalty algorithms also
/// bound the stable step.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "rkfem/approximation/rk/kinematic_map.hpp"
#include "rkfem/contact/contact_surface.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/discretization/node_set.hpp"
#include "rkfem/operators/contact_channel.hpp"

namespace rkfem
{
class StateArchive;
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

/// When contact forces are evaluated: the time and the elements' critical step at that
/// evaluation (the soft penalty's stiffness m / dt^2 takes the first one it sees and keeps it,
/// as LS-DYNA's SOFT = 1 takes the initial step).
struct ContactClock
{
    real_t t = 0.0;
    real_t dt_critical = 0.0;
    real_t dt = 0.0; ///< the step that led to t (0 at the start)
};

/// Coulomb friction, LS-DYNA's FS, FD and DC: mu = mu_d + (mu_s - mu_d) exp(-decay |v_t|). Stick is
/// regularized: the tangential force never exceeds the one that stops the relative sliding within
/// one critical step (m* |v_t| / dt), so there is no tangential spring with a history.
struct Friction
{
    real_t mu_static = 0.0, mu_dynamic = 0.0;
    real_t decay = 0.0; ///< [s/m]
    bool active() const { return mu_static > 0.0 || mu_dynamic > 0.0; }
    real_t coefficient(real_t slip_speed) const
    {
        return mu_dynamic + (mu_static - mu_dynamic) * std::exp(-decay * slip_speed);
    }
    /// The tangential force on a point of reduced mass m* sliding at v_t under normal force fn.
    Vec3 force(const Vec3& v_t, real_t fn, real_t m_star, real_t dt) const
    {
        const real_t s = v_t.norm();
        if (!active() || !(s > 0.0))
            return Vec3::Zero();
        const real_t ft = std::min(coefficient(s) * fn, m_star * s / dt);
        return (-ft / s) * v_t;
    }
};

/// Viscous damping of the normal approach (LS-DYNA's VDC, as a fraction): a dashpot beside each
/// penalty spring, c = 2 zeta sqrt(k m*) with m* the reduced mass the spring joins (zeta of the
/// critical damping of that pair; LS-DYNA writes 2 min(m_s, m_m) omega, which is the same against a
/// rigid or much heavier master and twice it for equal masses), acting on the closing speed v_n
/// (positive closing): the normal force is max(0, k p + c v_n), so the dashpot never pulls the
/// surfaces together. Two bodies whose springs and dashpots act alone leave each other with the
/// restitution coefficient e = exp(-zeta theta / sqrt(1 - zeta^2)), theta = pi - atan(2 zeta
/// sqrt(1 - zeta^2) / (1 - 2 zeta^2)) (zeta < 1/sqrt 2; Schwager & Poschel 2007, Granular Matter 9,
/// 465: the force reaches zero before the overlap does).
struct NormalDamping
{
    real_t zeta = 0.0; ///< fraction of critical, 0..1
    bool active() const { return zeta > 0.0; }
    /// The damped normal force of a spring k at penetration p closing at v_n between reduced mass m*.
    real_t force(real_t k, real_t p, real_t v_n, real_t m_star) const
    {
        return std::max(0.0, k * p + 2.0 * zeta * std::sqrt(k * m_star) * v_n);
    }
    /// Central difference with the dashpot on the half-step velocity is stable up to
    /// omega dt = 2 (sqrt(1 + zeta^2) - zeta) (from 2 undamped): the factor on a step bound.
    real_t step_factor() const { return std::sqrt(1.0 + zeta * zeta) - zeta; }
};

class ContactAlgorithm
{
  public:
    virtual ~ContactAlgorithm() = default;
    /// Adds the forces at clock.t from the current physical positions and velocities; the
    /// channel takes forces at physical points.
    virtual void add_forces(const PhysicalNodes& nodes, const ContactClock& clock, ContactChannel& channel) = 0;
    /// The largest stable step the contact stiffness allows (kNoLimit: no bound).
    virtual real_t stable_step() const { return kNoLimit; }
    /// The surfaces again, after an event changed them (erosion exposes new faces); the same
    /// number and order as at construction.
    virtual void set_surfaces(std::vector<ContactSurface> surfaces) = 0;
    /// What a checkpoint holds between steps, under `prefix` (search lists and the positions they
    /// were found at, spring offsets, the soft penalty's step, the last forces and counts), and
    /// putting it back into the same definition built from the same deck.
    /// (A definition without them cannot be checkpointed: Error.)
    virtual void save_state(StateArchive& /*archive*/, const std::string& /*prefix*/) const
    {
        throw Error("checkpoints do not cover this contact definition");
    }
    virtual void load_state(const StateArchive& /*archive*/, const std::string& /*prefix*/)
    {
        throw Error("checkpoints do not cover this contact definition");
    }
    /// The resultant force the contact put on its first surface's nodes in the last evaluation
    /// (slave side of a wall), for histories (LS-DYNA's RCFORC / RWFORC).
    virtual Vec3 resultant() const = 0;
    /// Nodes in contact in the last evaluation.
    virtual index_t active_nodes() const = 0;
    /// Nodes found inside the other surface at the first evaluation...
    virtual index_t initial_penetrations() const { return 0; }
    /// ...which are held at that depth (true) or pushed out (false).
    virtual bool holds_initial_penetrations() const { return true; }
};
} // namespace rkfem
