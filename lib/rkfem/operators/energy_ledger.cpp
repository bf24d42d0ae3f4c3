#include "rkfem/operators/energy_ledger.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "rkfem/core/parallel.hpp"

namespace rkfem
{
real_t Energies::balance_error() const
{
    const real_t lhs =
        kinetic + kinetic_correction + internal + hourglass + bulk_viscosity + contact + damping + eroded;
    const real_t err = std::abs(lhs - kinetic0 - internal0 - external_work);
    const real_t scale =
        std::max({std::abs(kinetic) + std::abs(internal) + std::abs(hourglass) + std::abs(bulk_viscosity) +
                      std::abs(contact) + std::abs(damping) + std::abs(eroded),
                  std::abs(external_work), std::abs(kinetic0 + internal0), std::numeric_limits<real_t>::min()});
    return err / scale;
}

real_t Energies::hourglass_ratio() const
{
    const real_t denom = internal + hourglass;
    return denom > 0 ? hourglass / denom : 0.0;
}

void Energies::book_event(const NodeSet& n, const std::vector<real_t>& a_old, real_t dt)
{
    const real_t h = 0.5 * dt;
    const real_t change = parallel_reduce_sum("rkfem::event_energy", n.size(),
                                              [&](index_t i)
                                              {
                                                  real_t s = 0.0;
                                                  for (int d = 0; d < 3; ++d)
                                                  {
                                                      const std::size_t j = 3 * static_cast<std::size_t>(i) + d;
                                                      const real_t v_half = n.v[j] - h * a_old[j];
                                                      s += v_half * (n.a[j] - a_old[j]);
                                                  }
                                                  return 0.5 * n.mass[i] * h * s;
                                              });
    eroded -= change;
    // the restart measured the kinetic energy without the leapfrog correction (it has no step);
    // the step just taken gives it, with the new accelerations, so the balance holds at the
    // event as well as after it
    kinetic_correction = -0.125 * dt * dt *
                         parallel_reduce_sum("rkfem::event_kinetic_correction", n.size(),
                                             [&](index_t i)
                                             {
                                                 const std::size_t j = 3 * static_cast<std::size_t>(i);
                                                 return n.mass[i] * (n.a[j] * n.a[j] + n.a[j + 1] * n.a[j + 1] +
                                                                     n.a[j + 2] * n.a[j + 2]);
                                             });
}
} // namespace rkfem
