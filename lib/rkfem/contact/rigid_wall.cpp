#include "rkfem/contact/rigid_wall.hpp"

#include "rkfem/core/state_archive.hpp"

#include <array>

#include <algorithm>
#include <cmath>

#include "rkfem/core/parallel.hpp"

namespace rkfem
{
RigidWall::RigidWall(std::vector<ContactSurface> surfaces, const RigidWallParameters& p) : p_(p)
{
    set_surfaces(std::move(surfaces));
}

void RigidWall::set_surfaces(std::vector<ContactSurface> surfaces)
{
    nodes_.clear();
    for (const ContactSurface& s : surfaces)
        nodes_.insert(nodes_.end(), s.nodes.begin(), s.nodes.end());
    std::sort(nodes_.begin(), nodes_.end());
    nodes_.erase(std::unique(nodes_.begin(), nodes_.end()), nodes_.end());
    f_.assign(nodes_.size(), Vec3::Zero());
}

void RigidWall::add_forces(const PhysicalNodes& nodes, const ContactClock& clock, ContactChannel& channel)
{
    if (dt0_ == 0.0 && clock.dt_critical > 0.0 && clock.dt_critical < kNoLimit)
        dt0_ = clock.dt_critical;
    resultant_ = Vec3::Zero();
    active_ = 0;
    if (dt0_ == 0.0)
        return;
    const Vec3 origin = p_.point + clock.t * p_.velocity;
    const Vec3& n = p_.normal;
    parallel_for("rkfem::rigid_wall", static_cast<index_t>(nodes_.size()),
                 [&](index_t k)
                 {
                     const index_t i = nodes_[k];
                     const real_t gap = (nodes.x(i) - origin).dot(n);
                     Vec3& f = f_[static_cast<std::size_t>(k)];
                     if (!(gap < 0.0))
                     {
                         f = Vec3::Zero();
                         return;
                     }
                     const real_t m = nodes.mass(i);
                     const Vec3 v_rel = nodes.v(i) - p_.velocity;
                     const real_t k_wall = p_.scale * m / (dt0_ * dt0_);
                     const real_t fn =
                         p_.damping.active() ? p_.damping.force(k_wall, -gap, -v_rel.dot(n), m) : -k_wall * gap;
                     f = fn * n;
                     f += p_.friction.force(v_rel - v_rel.dot(n) * n, fn, m, dt0_);
                 });
    for (std::size_t k = 0; k < nodes_.size(); ++k)
        if (f_[k] != Vec3::Zero())
        {
            channel.add(nodes_[k], f_[k]);
            resultant_ += f_[k];
            ++active_;
        }
}

real_t RigidWall::stable_step() const
{
    if (!p_.damping.active() || dt0_ == 0.0)
        return kNoLimit;
    return p_.damping.step_factor() * dt0_ / std::sqrt(1.0 + 0.5 * p_.scale);
}

void RigidWall::save_state(StateArchive& a, const std::string& prefix) const
{
    a.put_raw(prefix + "f", f_);
    a.put_value(prefix + "dt0", dt0_);
    a.put_value(prefix + "resultant", std::array<real_t, 3>{resultant_[0], resultant_[1], resultant_[2]});
    a.put_value(prefix + "active", active_);
}

void RigidWall::load_state(const StateArchive& a, const std::string& prefix)
{
    a.get_raw(prefix + "f", f_);
    dt0_ = a.value<real_t>(prefix + "dt0");
    const auto r = a.value<std::array<real_t, 3>>(prefix + "resultant");
    resultant_ = Vec3(r[0], r[1], r[2]);
    active_ = a.value<index_t>(prefix + "active");
}
} // namespace rkfem
