#pragma once
/// @file keyword_deck.hpp
/// LS-DYNA keyword decks as rkfem decks: `rkfem import MODEL.k --units mm-ms-kg-kN` writes the
/// YAML deck that `rkfem run MODEL.k --units ...` runs. LS-DYNA has no units; the user names the
/// consistent system the model was written in, and every value goes into the deck in SI with
/// its unit. The mesh stays in the keyword file: each *PART becomes a part whose generator is
/// `{type: keyword, file, unit, pid}`; node and segment sets become `ids` and `segments`
/// selectors on the file's numbers.
///
/// The subset (docs/user/keyword-decks.md says what each maps to and what is dropped):
/// *KEYWORD, *TITLE, *NODE, *ELEMENT_SOLID, *PART, *SECTION_SOLID, *MAT_ELASTIC,
/// *MAT_PLASTIC_KINEMATIC, *MAT_PIECEWISE_LINEAR_PLASTICITY, *MAT_JOHNSON_COOK,
/// *MAT_CONCRETE_DAMAGE_REL3 (generated from f'c, or user-set with *EOS_TABULATED_COMPACTION),
/// *MAT_CSCM_CONCRETE, *EOS_GRUNEISEN,
/// *MAT_ADD_EROSION, *HOURGLASS, *CONTROL_HOURGLASS, *CONTROL_BULK_VISCOSITY,
/// *CONTROL_TERMINATION, *CONTROL_TIMESTEP, *DATABASE_BINARY_D3PLOT, *DATABASE_GLSTAT,
/// *CONTACT_AUTOMATIC_SURFACE_TO_SURFACE, *CONTACT_AUTOMATIC_SINGLE_SURFACE and their ERODING_
/// forms, *RIGIDWALL_PLANAR, *SET_NODE_LIST(_GENERATE), *SET_NODE_GENERAL with *DEFINE_BOX, *SET_PART_LIST,
/// *SET_SEGMENT, *DEFINE_COORDINATE_SYSTEM (the global frame only), *CONSTRAINED_GLOBAL,
/// *BOUNDARY_SPC_SET, *BOUNDARY_SPC_NODE, *BOUNDARY_PRESCRIBED_MOTION_SET, *LOAD_SEGMENT_SET,
/// *LOAD_NODE_SET, *DEFINE_CURVE, *INITIAL_VELOCITY_GENERATION, *INITIAL_VELOCITY, *INCLUDE, with
/// _TITLE and _ID options. Any other keyword is refused by name and line, or with
/// `allow_unsupported` listed and skipped; a field we cannot represent (a rotation, a birth time,
/// a kinematic hardening share) is refused or noted, never dropped silently.
#include <string>
#include <vector>

namespace rkfem
{
/// A consistent unit system: SI per model unit of length, time and mass.
struct KeywordUnits
{
    std::string name;
    double length = 1.0, time = 1.0, mass = 1.0;
    std::string length_unit = "m"; ///< the length unit's symbol, for the mesh generator
};

/// The named systems (m-s-kg-N, mm-ms-kg-kN, mm-s-t-N, mm-ms-g-N, cm-us-g-Mbar, in-s-lbf-s2/in-lbf,
/// ft-s-slug-lbf). Throws DeckError (at `--units`) listing them for another name.
KeywordUnits keyword_units(const std::string& name);

struct KeywordImport
{
    std::string yaml;                 ///< the rkfem deck
    std::vector<std::string> skipped; ///< "*KEYWORD (FILE:LINE)" of each unsupported keyword skipped
    std::vector<std::string> notes;   ///< what maps approximately or was left out (also comments in yaml)
};

/// Translates the keyword deck `path` (and the files it includes). `mesh_file` is how the deck names
/// `path` in its generators (relative to the deck's folder, or absolute). Throws DeckError naming the
/// file, line and keyword for anything it cannot translate.
KeywordImport import_keyword_deck(const std::string& path, const KeywordUnits& units, bool allow_unsupported,
                                  const std::string& mesh_file);

/// True for the names `run`, `check` and `import` take as keyword decks (.k, .key, .dyn, .kw).
bool is_keyword_deck(const std::string& path);
} // namespace rkfem
