#pragma once
/// @file hex_gauss.hpp
/// Tensor Gauss quadrature on a hex mesh as an integration operator: n^3 points per element
/// (n = 1 or 2), each with weight w_i w_j w_k det J, its 8 nodes and their trilinear gradients at
/// the point. Element order, then point order (xi fastest). No owners (state is not at nodes).
/// The static solver uses 2x2x2 as the trilinear FE stiffness that preconditions nodal schemes
/// on the same nodes (operators/linear_static.hpp).
#include "rkfem/discretization/hex_mesh.hpp"
#include "rkfem/integration/integration_operator.hpp"

namespace rkfem
{
IntegrationOperator build_hex_gauss(const HexMesh& mesh, int points_per_direction);
} // namespace rkfem
