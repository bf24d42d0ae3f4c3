#include "rkfem/operators/energy_ledger.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

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
} // namespace rkfem
