#include "rkfem/contact/surface_contact_state.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "rkfem/core/state_archive.hpp"

namespace rkfem
{
bool SurfaceContactState::search_due(const PhysicalNodes& nodes, const std::vector<index_t>& surface_nodes,
                                     real_t margin) const
{
    if (!searched)
        return true;
    const real_t limit = 0.25 * margin * margin; // half the margin, squared
    for (std::size_t k = 0; k < surface_nodes.size(); ++k)
    {
        const Vec3 x = nodes.x(surface_nodes[k]);
        const Vec3 x0(x_search[3 * k], x_search[3 * k + 1], x_search[3 * k + 2]);
        if ((x - x0).squaredNorm() > limit)
            return true;
    }
    return false;
}

void SurfaceContactState::record_search(const PhysicalNodes& nodes, const std::vector<index_t>& surface_nodes)
{
    x_search.resize(3 * surface_nodes.size());
    for (std::size_t k = 0; k < surface_nodes.size(); ++k)
    {
        const Vec3 x = nodes.x(surface_nodes[k]);
        for (int d = 0; d < 3; ++d)
            x_search[3 * k + d] = x[d];
    }
    searched = true;
    ++searches;
}

void SurfaceContactState::bound_step(real_t kappa, real_t factor)
{
    // The bound holds from the first contact on: it acts one step late, and a node that touches
    // at every other step would otherwise take every first step at the elements' step
    if (kappa > 0.0 && dt0 > 0.0)
        dt_bound = std::min(dt_bound, factor * dt0 / std::sqrt(1.0 + 0.5 * kappa * dt0 * dt0));
}

void SurfaceContactState::save(StateArchive& a, const std::string& prefix) const
{
    a.put(prefix + "x_search", x_search);
    a.put_value(prefix + "dt0", dt0);
    a.put_value(prefix + "dt_bound", dt_bound);
    a.put_value(prefix + "resultant", std::array<real_t, 3>{resultant[0], resultant[1], resultant[2]});
    a.put_value(prefix + "active", active);
    a.put_value(prefix + "searches", searches);
    a.put_value(prefix + "initial_penetrations", initial_penetrations);
    a.put_value(prefix + "searched", searched);
    a.put_value(prefix + "started", started);
}

void SurfaceContactState::load(const StateArchive& a, const std::string& prefix)
{
    a.get(prefix + "x_search", x_search);
    dt0 = a.value<real_t>(prefix + "dt0");
    dt_bound = a.value<real_t>(prefix + "dt_bound");
    const auto r = a.value<std::array<real_t, 3>>(prefix + "resultant");
    resultant = Vec3(r[0], r[1], r[2]);
    active = a.value<index_t>(prefix + "active");
    searches = a.value<index_t>(prefix + "searches");
    initial_penetrations = a.value<index_t>(prefix + "initial_penetrations");
    searched = a.value<bool>(prefix + "searched");
    started = a.value<bool>(prefix + "started");
}
} // namespace rkfem
