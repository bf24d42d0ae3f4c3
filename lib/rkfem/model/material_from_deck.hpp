#pragma once
/// @file material_from_deck.hpp
/// The deck's material spec translated into the materials' own parameter types: J2 (with its
/// EOS), K&C concrete (generated from f'c, then the deck's overrides) and the CSCM. The
/// materials know nothing of the deck; this is the one place that reads a MaterialSpec for them.
#include "rkfem/config/deck.hpp"
#include "rkfem/materials/point_history.hpp"

namespace rkfem
{
/// J2 parameters of a deck material (empty curve, i.e. inactive, for model elastic).
J2Params j2_params(const MaterialSpec& m);

/// The K&C model of a deck material: generated from f'c, then the deck's named overrides, damage
/// table, EOS_8 table, rate law and fracture energy.
KccModel kcc_model(const MaterialSpec& m);

/// The CSCM of a deck material: Murray's fits from f'c, then the deck's overrides by name.
CscmModel cscm_model(const MaterialSpec& m);

/// Points of a deck material: J2, K&C or CSCM history; left inactive for model elastic.
void configure_points(PlasticPoints& points, const MaterialSpec& m);
} // namespace rkfem
