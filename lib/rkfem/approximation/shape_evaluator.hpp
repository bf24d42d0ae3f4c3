#pragma once
/// @file shape_evaluator.hpp
/// The approximation a nodal-integration builder samples: the values of every shape function
/// that is non-zero at a point known to lie in hex element e at natural coordinates xi, and
/// (where defined) the gradients at a node. Two implementations: trilinear FE functions of a hex
/// mesh (`fem-nodal`) and RK shape functions over the mesh nodes (`rkpm`). Set-up only.
#include <vector>

#include "rkfem/approximation/fem/hex8_basis.hpp"
#include "rkfem/approximation/rk/rk_shape.hpp"
#include "rkfem/discretization/hex_mesh.hpp"

namespace rkfem
{
class ShapeEvaluator
{
  public:
    virtual ~ShapeEvaluator() = default;
    /// Values at x = x(e, xi): node ids and Psi, appended after clearing.
    virtual void values(index_t e, const Vec3& xi, const Vec3& x, std::vector<index_t>& nodes,
                        std::vector<real_t>& psi) const = 0;
    /// Gradients at node i's position (direct nodal integration). Throws Error if undefined.
    virtual void gradients_at_node(index_t i, std::vector<index_t>& nodes, std::vector<Vec3>& grad) const = 0;
    /// A hint: the next values() calls are at points of element e in the box [lo, hi] (an
    /// evaluator may narrow its search to the functions that reach the box; a point outside it
    /// is still answered right). By default nothing.
    virtual void focus(index_t /*e*/, const Vec3& /*lo*/, const Vec3& /*hi*/) const {}
};

/// Trilinear hex functions: C0, so the value on a shared face is the same from either element.
class FemShapes final : public ShapeEvaluator
{
  public:
    explicit FemShapes(const HexMesh& mesh) : mesh_(mesh) {}
    void values(index_t e, const Vec3& xi, const Vec3&, std::vector<index_t>& nodes,
                std::vector<real_t>& psi) const override
    {
        real_t N[8];
        const real_t z[3] = {xi[0], xi[1], xi[2]};
        hex8_shape(z, N);
        nodes.assign(mesh_.conn.begin() + 8 * e, mesh_.conn.begin() + 8 * e + 8);
        psi.assign(N, N + 8);
    }
    void gradients_at_node(index_t i, std::vector<index_t>&, std::vector<Vec3>&) const override;

  private:
    const HexMesh& mesh_;
};

/// RK shape functions (the element and xi are not needed). With a drop tolerance tau > 0 the
/// values at a point lose the functions below tau times the largest there, and the rest are
/// corrected to reproduce 1 and x at the point again (prune_rk_values): the smoothed gradients
/// built from them keep linear consistency and, since a facet point shared by two cells gets the
/// same values from both, the integration constraint; their stencils shrink (at a/h = 1.51 on a
/// lattice the 98 of 125 SCNI neighbours that only touch a cell's faces from 1.5 h away, with
/// values about 6e-7 of the largest, go: 27 are left).
class RkShapes final : public ShapeEvaluator
{
  public:
    explicit RkShapes(const RkShapeFunctions& rk, real_t drop_tolerance = 0.0) : rk_(rk), tau_(drop_tolerance) {}
    void values(index_t, const Vec3&, const Vec3& x, std::vector<index_t>& nodes,
                std::vector<real_t>& psi) const override
    {
        thread_local RkSample s;
        rk_.evaluate(x, false, s);
        nodes = s.nodes;
        psi = s.psi;
        if (tau_ > 0.0)
            prune_rk_values(rk_, x, tau_, nodes, psi);
    }
    void gradients_at_node(index_t i, std::vector<index_t>& nodes, std::vector<Vec3>& grad) const override
    {
        thread_local RkSample s;
        rk_.evaluate(rk_.position(i), true, s);
        nodes = s.nodes;
        grad = s.grad;
    }

  private:
    const RkShapeFunctions& rk_;
    real_t tau_ = 0.0;
};
} // namespace rkfem
