#pragma once
/// @file generators.hpp
/// Structured hex meshes from a generator spec: box, cylinder (butterfly or O-grid core, no
/// degenerate elements) and a flat-nosed cylindrical projectile. Each names its boundary faces
/// (box: xmin..zmax, top = zmax, bottom = zmin, side; cylinder: top, bottom, side; projectile:
/// nose, tail, side).
#include "rkfem/discretization/generator_spec.hpp"
#include "rkfem/discretization/hex_mesh.hpp"

namespace rkfem
{
HexMesh generate_box(const Vec3& origin, const Vec3& size, const std::array<int, 3>& divisions);

/// Cylinder along +z from `origin` (centre of the bottom face): the disk mesh swept along z.
/// Numbering: the disk's nodes in a sweep (ascending x, then y), each node's column of heights
/// consecutive (node (i, k) = (nz + 1) i + k, height fastest); elements the same way, the disk's
/// quads by their nodes' numbers.
HexMesh generate_cylinder(const Vec3& origin, real_t radius, real_t height, real_t element_size, bool ogrid_core);

/// Tube along +z from `origin` (centre of the bottom face), radii inner < outer: a structured
/// (r, theta, z) mesh of about element_size (theta divisions a multiple of 4, at least 8).
/// Named faces: top, bottom, side (the outer surface), inner (the bore).
HexMesh generate_tube(const Vec3& origin, real_t outer_radius, real_t inner_radius, real_t height, real_t element_size);

/// The particles of a cloud part (`type: cloud`) as a mesh without elements. Box body (origin,
/// size): a lattice of about `element_size` spacing, each coordinate jittered by a uniform
/// +-jitter spacing (seeded) except where the particle lies on the box's face normal to it, so
/// that boundary particles stay on the surface. Cylinder body (origin = bottom centre, radius,
/// height): the nodes of generate_cylinder (butterfly core) jittered the same way, side particles
/// kept on the circle and cap particles on their cap. Or the points of a CSV file (x,y,z per
/// line, times points_unit; blank lines and lines starting with # skipped), which must lie in the
/// body (points within 1e-9 of its size outside are moved onto it).
/// Named node groups: box xmin..zmax, top (= zmax), bottom (= zmin), side (x and y faces);
/// cylinder top, bottom, side. Throws DeckError naming generator.points for a file that is
/// missing, malformed or has points outside the body.
HexMesh generate_cloud(const GeneratorSpec& spec);

/// Builds the mesh a part's generator describes.
HexMesh generate(const GeneratorSpec& spec);
} // namespace rkfem
