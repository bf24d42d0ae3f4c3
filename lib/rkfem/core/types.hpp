#pragma once
/// @file types.hpp
/// One real type, one index type, and the small fixed-size tensors used at points.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cstdint>

namespace rkfem
{
using real_t = double;       ///< every floating-point quantity (SI units inside the library)
using index_t = std::int32_t; ///< node, element and point indices

using Vec3 = Eigen::Matrix<real_t, 3, 1>;
using Mat3 = Eigen::Matrix<real_t, 3, 3>;

/// Symmetric tensor in Voigt order (xx, yy, zz, xy, yz, zx); shear entries are tensor components
/// (not engineering strains).
using Sym6 = Eigen::Matrix<real_t, 6, 1>;

enum Voigt : int
{
    XX = 0,
    YY = 1,
    ZZ = 2,
    XY = 3,
    YZ = 4,
    ZX = 5
};
} // namespace rkfem
