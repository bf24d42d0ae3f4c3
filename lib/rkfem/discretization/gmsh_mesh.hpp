#pragma once
/// @file gmsh_mesh.hpp
/// Meshes written by Gmsh (a part's `generator: {type: gmsh, file: MESH.msh, unit: mm, physical:
/// [names or tags]}`): the ASCII MSH formats 4.1 and 2.2, read by our own reader (Debian's
/// libgmsh would bring OpenCASCADE and the whole of Gmsh into the build for what is a text
/// format; binary files are refused with the command that rewrites them as text).
///
/// What is read:
///   - volume elements: 8-node hexahedra (type 5) as they are (Gmsh's node order is LS-DYNA's),
///     6-node prisms (6), 5-node pyramids (7) and 4-node tetrahedra (4) as degenerate hexes (the
///     way LS-DYNA writes them: N1 N2 N3 N3 N4 N5 N6 N6; N1 N2 N3 N4 N5 N5 N5 N5; N1 N2 N3 N3 N4 N4
///     N4 N4), which fem-1pt and fem-2x2x2 parts run; of the volumes in the named physical groups
///     (default: every volume element). Higher-order elements are refused by type.
///   - physical groups: of surfaces, the boundary faces their triangles and quadrangles cover
///     (named faces, usable in face and node sets: `{type: named, name: GROUP}`); of points and
///     curves, their nodes (named nodes). Groups without a name are named by their tag.
///   - the file's node and element numbers, so `ids` selectors and messages use them.
/// Checked, naming the file's line: a section out of order or cut short, a number that is not one,
/// an element naming an undefined node, an inverted or degenerate element (as keyword meshes).
#include "rkfem/discretization/generator_spec.hpp"
#include "rkfem/discretization/hex_mesh.hpp"

namespace rkfem
{
HexMesh read_gmsh_mesh(const GeneratorSpec& spec);
} // namespace rkfem
