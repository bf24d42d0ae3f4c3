#pragma once
/// @file nodal_block_build_detail.hpp
/// What the nodal block builders share (internal to model/): nodal_block_build.cpp (mesh parts),
/// nodal_block_coupled.cpp (coupled parts) and nodal_block_cloud.cpp (particle clouds).
#include <memory>
#include <vector>

#include "rkfem/approximation/rk/rk_shape.hpp"
#include "rkfem/approximation/rk/rk_translates.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/integration/nodal/nodal_integration.hpp"
#include "rkfem/model/nodal_block_build.hpp"

namespace rkfem::nodal_build_detail
{
/// A nodal block with the part's material, node range, step factor and bulk viscosity, no points;
/// its K&C crack-band scales `scales` where given (a converting part's, shared through its events).
NodalBlock block_frame(const PartSpec& ps, index_t n_nodes, index_t offset,
                       std::shared_ptr<KccScaleCache> scales = nullptr);
/// RK interpolation Psi_J(X_I) at the particles, for physical nodal values.
void add_interpolation(NodalBlock& nb, const RkShapeFunctions& rk, const RkTranslates& particles, index_t offset);
/// NSNI held as its triplets alone from the start (a compact block's form).
void hold_nsni(NodalBlock& nb, NsniTriplets nsni);
/// The deck error that names the part's RK support when its moment matrix is singular.
DeckError singular_support(const PartSpec& ps, const SingularMomentError& e);
/// Operators to global node ids, l0 per point from the owner node, state arrays, crack bands.
void finish_block(NodalBlock& nb, index_t offset, const std::vector<real_t>& l0, const std::vector<real_t>& band);
} // namespace rkfem::nodal_build_detail
