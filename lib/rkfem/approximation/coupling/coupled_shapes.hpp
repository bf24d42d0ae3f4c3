#pragma once
/// @file coupled_shapes.hpp
/// The approximation of a part that is FE in some elements and RK in others (seed Table 1,
/// feature 3; Huerta & Fernandez-Mendez 2000, IJNME 48; Belytschko, Organ & Krongauz 1995, Comput
/// Mech 17). Elements are of three kinds:
///   RK         in an RK region: its 8 nodes are particles, u = sum_J Psi_J d_J;
///   FE         no particle node: u = sum_i N_i u_i (trilinear);
///   interface  an FE element with at least one particle node: the transition.
/// Particles are the nodes of RK elements; their unknowns are generalized coefficients. FE nodes
/// keep the Kronecker property (their unknowns are physical values), so conditions and FE
/// contact on them are unchanged.
///
/// Two transition treatments in interface elements:
///   mixed (Huerta & Fernandez-Mendez 2000, the default): u = sum_{i in F} N_i u_i + sum_J Psi_J d_J
///     with M(x) b(x) = H(0) - sum_{i in F} N_i(x) H(x - x_i): the RK functions fill exactly the
///     reproduction the missing FE nodes leave, and vanish where the FE functions are complete
///     (every face shared with an FE element). Linear fields are reproduced everywhere.
///   ramp (Belytschko, Organ & Krongauz 1995): u = (1 - R) sum_{k in e} N_k u_k + R sum_J Psi_J d_J,
///     R = sum_{k in e, particle} N_k, the standard RK functions blended in; at particle nodes u_k
///     is the node's unknown (its coefficient), so the FE part is not a physical interpolant there.
/// Particles of RK elements that share a node with an interface element get a support of at
/// least kInterfaceSupport x their spacing, so that every point of an interface element is
/// covered by particles out of one plane (M(x) regular there, as the mixed interpolation requires).
#include <memory>
#include <vector>

#include "rkfem/approximation/rk/rk_region_values.hpp"
#include "rkfem/approximation/shape_evaluator.hpp"

namespace rkfem
{
enum class Transition
{
    Mixed,
    Ramp,
};

class CoupledShapes final : public ShapeEvaluator
{
  public:
    enum class Kind : char
    {
        Fe,
        Interface,
        Rk,
    };
    /// Normalized support of the particles next to interface elements (at least).
    static constexpr real_t kInterfaceSupport = 2.2;

    /// mesh: the whole part (local numbering); rk_element[e] != 0: element e lies in an RK region.
    /// Throws Error when no element is RK (every element may be: conversion can get there).
    CoupledShapes(const HexMesh& mesh, const std::vector<char>& rk_element, const RkParams& params,
                  Transition transition);
    // the per-thread regions refer to this object's RK functions: not copied or moved
    CoupledShapes(const CoupledShapes&) = delete;
    CoupledShapes& operator=(const CoupledShapes&) = delete;

    /// In RK elements (and interface elements of the mixed transition at order 1) the functions
    /// come from the particles gathered once on the element's box
    /// (RkRegionValues, one per thread, kept while the thread stays in the element): the
    /// builders visit an element's facet points together, tens of them, so one neighbour search
    /// serves them all. values_plain is the twin (a cell-list search per point); the two agree
    /// to round-off (the moment sums run in another order).
    void values(index_t e, const Vec3& xi, const Vec3& x, std::vector<index_t>& nodes,
                std::vector<real_t>& psi) const override;
    void values_plain(index_t e, const Vec3& xi, const Vec3& x, std::vector<index_t>& nodes,
                      std::vector<real_t>& psi) const;
    /// In RK elements: the thread's candidates narrowed to the particles that reach [lo, hi]
    /// (RkRegionValues::focus), until a point outside it or another element.
    void focus(index_t e, const Vec3& lo, const Vec3& hi) const override;
    /// Undefined on coupled parts (DNI is not offered there).
    void gradients_at_node(index_t i, std::vector<index_t>& nodes, std::vector<Vec3>& grad) const override;

    Kind kind(index_t e) const { return kind_[static_cast<std::size_t>(e)]; }
    bool is_particle(index_t node) const { return particle_of_[static_cast<std::size_t>(node)] >= 0; }

    /// Physical value at node I: the row sum_k N_k(X_I) d_k (identity at FE nodes, the RK
    /// interpolant sum_J Psi_J(X_I) d_J at particles), appended to (nodes, values).
    void node_row(index_t node, std::vector<index_t>& nodes, std::vector<real_t>& values) const;

    /// Support radius of a particle (0 for FE nodes).
    real_t radius(index_t node) const { return radius_[static_cast<std::size_t>(node)]; }

  private:
    const HexMesh& mesh_;
    std::vector<Kind> kind_;
    std::vector<index_t> particle_of_;   ///< per node: particle index, -1 for FE nodes
    std::vector<index_t> particle_node_; ///< per particle: node
    std::vector<real_t> radius_;         ///< per node: support radius, 0 for FE nodes
    RkShapeFunctions rk_;
    Transition transition_;
    /// per thread: the RK element whose particles `values` holds (-1: none yet)
    struct Region
    {
        index_t element = -1;
        std::unique_ptr<RkRegionValues> values;
        bool focused = false; ///< candidates: those reaching [lo, hi], not the whole element's
        Vec3 lo, hi;
    };
    mutable std::vector<Region> regions_;
    /// The calling thread's region gathered on element e (an RK element), or nullptr where the
    /// thread has none (more threads than at construction).
    Region* region(index_t e) const;
    /// Whether values() takes the fast path in element e (else values_plain).
    bool fast(index_t e) const;
    /// Mixed transition in interface element e (trilinear functions N at x): the FE nodes'
    /// functions appended to (nodes, psi), and as `others` the reproduction the RK functions complete.
    void fe_functions(index_t e, const real_t (&N)[8], const Vec3& x, std::vector<index_t>& nodes,
                      std::vector<real_t>& psi, RkOthers& others) const;
};
/// What the coupled shapes of an RK element set are made of, without building them: per element
/// its kind, per node its support radius as a particle (0: an FE node). Two sets' approximations
/// differ only in elements whose kind differs or that a changed support reaches.
struct CoupledLayout
{
    std::vector<CoupledShapes::Kind> kind;
    std::vector<real_t> radius;
};
CoupledLayout coupled_layout(const HexMesh& mesh, const std::vector<char>& rk_element, const RkParams& params);
} // namespace rkfem
