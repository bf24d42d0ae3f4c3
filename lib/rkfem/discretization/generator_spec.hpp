#pragma once
/// @file generator_spec.hpp
/// What a part's mesh or particles are made from (deck key `generator`): a box, cylinder,
/// projectile, particle cloud or LS-DYNA keyword file.
#include <array>
#include <string>
#include <vector>

#include "rkfem/core/input_error.hpp"
#include "rkfem/core/types.hpp"

namespace rkfem
{
struct GeneratorSpec
{
    enum class Type
    {
        Box,
        Cylinder,
        Projectile,
        Cloud,   ///< particles not from a mesh: a jittered lattice or imported points in a box or cylinder body
        Keyword, ///< *NODE and *ELEMENT_SOLID of an LS-DYNA keyword file (discretization/keyword_mesh.hpp)
        Gmsh,    ///< a Gmsh MSH file's volume elements (discretization/gmsh_mesh.hpp)
    };
    Type type = Type::Box;
    // box
    Vec3 origin = Vec3::Zero();
    Vec3 size = Vec3::Zero();
    std::array<int, 3> divisions{0, 0, 0}; ///< 0: derived from element_size
    // cylinder (axis +z from `origin`, bottom face at origin.z) and projectile
    real_t radius = 0.0;
    real_t height = 0.0;            ///< cylinder height / projectile length
    std::string core = "butterfly"; ///< cylinder core: butterfly | ogrid
    real_t inner_radius = 0.0;      ///< cylinder: > 0 makes it a tube (faces top, bottom, side, inner)
    int direction = -1;             ///< projectile: nose points to -z (-1) or +z (+1); origin = nose centre
    real_t element_size = 0.0;      ///< cloud: lattice spacing
    // cloud: the body is the box (origin, size) or the cylinder (origin = bottom centre, radius,
    // height; axis +z); particles are a lattice of about element_size spacing with interior
    // coordinates jittered by +-jitter spacing (seeded), or the points of a CSV file (x,y,z per
    // line, in points_unit)
    enum class Body
    {
        Box,
        Cylinder,
    };
    Body body = Body::Box;
    real_t jitter = 0.25;
    int seed = 1;
    std::string points_file;            ///< resolved against the deck's directory
    real_t points_unit = 1.0;           ///< metres per file unit
    std::string points_unit_name = "m"; ///< as the deck wrote it (the resolved deck echoes it)
    // keyword: the file (resolved against the deck's directory), metres per file length unit,
    // the PIDs of the solids taken (empty: all)
    std::string mesh_file;
    real_t mesh_unit = 1.0;
    std::string mesh_unit_name = "m"; ///< as the deck wrote it
    std::vector<long long> mesh_pids;
    std::vector<std::string> mesh_groups; ///< gmsh: the volume physical groups taken, by name or tag (empty: all)
    SourceLocation loc;
};
} // namespace rkfem
