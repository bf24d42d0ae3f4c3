#pragma once
/// @file keyword_export.hpp
/// A model as an LS-DYNA keyword deck (`rkfem export DECK > MODEL.k`): the built meshes as
/// *NODE and *ELEMENT_SOLID, sets as node lists and segments, and the deck's parts, materials,
/// hourglass control, conditions, loads and contacts as the keywords config/keyword_deck.hpp
/// reads back, in m-s-kg-N with 17 digits, so that `rkfem run MODEL.k --units m-s-kg-N` is the
/// same run as the deck's (round trip). What LS-DYNA has no card for is refused by its deck key
/// (particle clouds, nodal FE, coupled parts, kernel contact, user-set concrete parameters, a
/// triangular pulse) or, where it changes nothing LS-DYNA would compute (outputs, probes, the
/// stepper), listed as comments at the top of the file.
#include <string>

namespace rkfem
{
class Model;

/// The keyword text of `model` (built from its deck). Throws DeckError naming the deck key that
/// has no keyword form.
std::string export_keyword_deck(const Model& model);
} // namespace rkfem
