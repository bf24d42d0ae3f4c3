#pragma once
/// @file types.hpp
/// One real type, one index type, and the small fixed-size tensors used at points.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cstdint>

namespace rkfem
{
using real_t = double;        ///< every floating-point quantity (SI units inside the library)
using index_t = std::int32_t; ///< node, element and point indices

/// "No bound": a step nothing limits, the start of a search for a minimum, the corners of an empty
/// box (-kNoLimit for a maximum). Finite, unlike infinity, so that a product with 0, a sum and a
/// comparison stay ordinary numbers; no physical quantity of the library comes near it.
inline constexpr real_t kNoLimit = 1e300;

/// How far below a scheduled time (a frame, a history row, a checkpoint, a conversion check, the
/// end) a step's time may fall and still be at it, relative to the time itself: the round-off
/// that summed steps carry.
inline constexpr real_t kScheduleSlack = 1e-12;

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
