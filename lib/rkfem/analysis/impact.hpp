#pragma once
/// @file impact.hpp
/// What an impact did (deck key impact), in the seed's terms (footnotes 4 and 5 of its Table 3):
///   - apparent crater depth: the displacement along the shot line d of the target's surface node
///     under the point of impact p (the node of the target's original surface, |(X - p) . d|
///     within 1e-6 of the part's size, nearest to p); on a semi-Lagrangian RK target, of the
///     nearest such node that has not separated (a particle that left the kernels is a fragment,
///     not the crater's floor: the measure then moves to its neighbour on the surface);
///   - actual crater depth: the depth below the original surface, along d, of the crater once
///     material at or above the damage threshold (0.95) is removed. Removed: the target's eroded
///     elements and its elements whose mean damage is at or above the threshold (elements a
///     conversion handed to semi-Lagrangian particles: the mean of their corner particles'). The crater: the
///     removed elements joined by shared faces to one with a face on the original surface (all
///     four nodes on the plane through p normal to d). Its depth: the largest (X - p) . d over the
///     crater elements' nodes, X their reference positions (where the material was);
///   - the crater without the mesh's quantization: damage averaged to the nodes (each node the
///     volume-weighted mean over the target elements around it, an eroded element counting as
///     damage 1, a converted one as its particles' mean) and interpolated trilinearly in each element; the crater is
///     the region where that field is at or above the threshold, connected through element edges to the original
///     surface. Its depth: the deepest point, along d, of the crater's nodes and of the threshold's crossings on
///     element edges that leave them (linear along the edge); its diameter: twice the largest distance from the shot
///     line of the crater's outline on the original surface; its volume: the elements touched by it, each sampled at 4
///     x 4 x 4 points of the interpolated field (reference positions throughout);
///   - the projectile's residual velocity (its momentum along d over its mass) and mass (of its
///     remaining elements), the momentum the target carries along d, the target's volume with
///     damage above 0.5 and above the threshold (eroded elements included: they failed), and the
///     eroded mass.
#include <vector>

#include "rkfem/core/types.hpp"

namespace rkfem
{
class Model;
struct ImpactSpec;
struct ImpactMeasures
{
    real_t apparent_depth = 0.0;           ///< [m]
    real_t actual_depth = 0.0;             ///< [m]
    real_t crater_depth = 0.0;             ///< interpolated damage at the threshold [m]
    real_t crater_diameter = 0.0;          ///< at the original surface [m]
    real_t crater_volume = 0.0;            ///< [m^3]
    real_t residual_velocity = 0.0;        ///< projectile, along d [m/s] (0 without a projectile)
    real_t projectile_mass = 0.0;          ///< [kg]
    real_t target_momentum = 0.0;          ///< along d [kg m/s]
    real_t damaged_volume_half = 0.0;      ///< damage > 0.5 [m^3]
    real_t damaged_volume_threshold = 0.0; ///< damage >= threshold [m^3]
    real_t eroded_mass = 0.0;              ///< target and projectile [kg]
};

class ImpactAnalysis
{
  public:
    /// Finds the surface node under the point of impact. Throws DeckError (at the impact key)
    /// when the target has no node on the plane through the point.
    ImpactAnalysis(const Model& model, const ImpactSpec& spec);
    /// The cheap measures (every history row): apparent depth, residual velocity.
    real_t apparent_depth(const Model& model) const;
    real_t residual_velocity(const Model& model) const;
    /// The crater's actual depth (a pass over the target's elements).
    real_t actual_depth(const Model& model) const;
    /// The crater of the interpolated damage: depth, diameter, volume (ImpactMeasures' fields).
    struct Crater
    {
        real_t depth = 0.0, diameter = 0.0, volume = 0.0;
    };
    Crater crater(const Model& model) const;
    /// Everything.
    ImpactMeasures measure(const Model& model) const;
    index_t surface_node() const { return surface_node_; }
    /// The surface node the apparent depth reads now: surface_node(), or on a semi-Lagrangian
    /// target the nearest node on the plane through p (in the reference) whose particle has not
    /// separated (-1: all have).
    index_t attached_surface_node(const Model& model) const;

  private:
    const ImpactSpec& spec_;
    index_t target_ = -1, projectile_ = -1; ///< part (= block) indices
    index_t surface_node_ = -1;
    std::vector<index_t> plane_nodes_; ///< the target's nodes on the plane through p, nearest to p first
    real_t tolerance_ = 0.0;           ///< on the plane through p
    /// Element e of the target's block (-1: its eroded elements, index k) with damage at or above
    /// the threshold, or eroded
    bool removed(const Model& model, index_t e) const;
};
} // namespace rkfem
