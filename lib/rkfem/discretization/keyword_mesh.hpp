#pragma once
/// @file keyword_mesh.hpp
/// Hex meshes from LS-DYNA keyword files (a part's `generator: {type: keyword, file, unit, pid}`):
/// the *NODE and *ELEMENT_SOLID cards of meshes that pre-processors (LS-PrePost, TrueGrid,
/// Cubit, gmsh) write.
///
/// What is read:
///   - *NODE: NID, X, Y, Z in fixed columns (8, 16, 16, 16: LS-DYNA's standard format) or
///     separated by commas (free format); TC and RC are ignored (boundary conditions are the
///     deck's). Coordinates are multiplied by the unit (metres per file unit).
///   - *ELEMENT_SOLID: EID, PID, N1..N8 on one card (10 fields of 8 columns, or comma-separated),
///     or EID, PID on one card and the nodes on the next (the two-card format of LS-DYNA R10 and
///     later; its fields 9-10 must be 0). Only solids whose PID is among `pid` (empty: all).
///   - Lines starting with $ are comments; cards of other keywords are skipped; *END ends the file.
///     *INCLUDE is followed, relative to the including file (io/keyword_file.hpp).
/// Checked, with the file's line in the message (DeckError naming generator.file): a field that
/// is not a number, a node defined twice, an element naming a node the file does not define,
/// repeated nodes in an element (degenerate prisms and tetrahedra are not taken: 1-point hexes
/// need eight distinct nodes), an element turned inside out (negative volume at its centre), no
/// elements selected.
/// Only the selected elements' nodes are kept, in the file's order. Named faces: `all` (every
/// boundary face); select others with plane, box, cylinder or sphere selectors.
#include "rkfem/discretization/generator_spec.hpp"
#include "rkfem/discretization/hex_mesh.hpp"

namespace rkfem
{
HexMesh read_keyword_mesh(const GeneratorSpec& spec);
} // namespace rkfem
