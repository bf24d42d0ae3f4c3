#pragma once
/// @file hourglass.hpp
/// Hourglass control of 1-point hexahedra (deck key `hourglass`): the forms and their coefficient.
#include "rkfem/core/types.hpp"

namespace rkfem
{
enum class HourglassType
{
    None,          ///< no control (hourglass modes are free)
    Viscous,       ///< Flanagan-Belytschko viscous, exact volume integration (LS-DYNA IHQ 3)
    Stiffness,     ///< Flanagan-Belytschko stiffness, exact volume integration (LS-DYNA IHQ 5)
    ViscousPlain,  ///< viscous on the raw base vectors Gamma (LS-DYNA IHQ 1 analog): fails the patch test
    AssumedStrain, ///< Belytschko-Bindeman assumed strain, co-rotational stiffness (LS-DYNA IHQ 6)
};

struct HourglassSpec
{
    HourglassType type = HourglassType::Viscous;
    real_t coefficient = 0.1; ///< QM
    /// stiffness forms, materials with history: each increment scaled by the share of the
    /// step's deviatoric strain the point's update took elastically (assumed_strain_hourglass.hpp);
    /// default on for assumed-strain, off for stiffness (LS-DYNA's IHQ 5 as documented)
    bool plastic_scaling = true;
};
} // namespace rkfem
