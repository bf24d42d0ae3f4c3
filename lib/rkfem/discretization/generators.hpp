#pragma once
/// @file generators.hpp
/// Structured hex meshes from a generator spec: box, cylinder (butterfly or O-grid core, no
/// degenerate elements) and a flat-nosed cylindrical projectile. Each names its boundary faces
/// (box: xmin..zmax, top = zmax, bottom = zmin, side; cylinder: top, bottom, side; projectile:
/// nose, tail, side).
#include "rkfem/config/deck.hpp"
#include "rkfem/discretization/hex_mesh.hpp"

namespace rkfem
{
HexMesh generate_box(const Vec3& origin, const Vec3& size, const std::array<int, 3>& divisions);

/// Cylinder along +z from `origin` (centre of the bottom face).
HexMesh generate_cylinder(const Vec3& origin, real_t radius, real_t height, real_t element_size,
                          bool ogrid_core);

/// Builds the mesh a part's generator describes.
HexMesh generate(const GeneratorSpec& spec);
} // namespace rkfem
