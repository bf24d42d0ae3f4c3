#pragma once
/// @file spall.hpp
/// Spall at a back face (deck key spall): a compressive pulse that reflects from a free face as
/// tension cracks the material some depth inside it, and the layer behind the crack flies off.
/// Along the line from a point p of the back face into the part (direction d), in the reference:
///   - the column: the part's nodes within 1e-6 of the part's size of the line, by depth
///     s = (X - p) . d (the back face at s = 0), and the segments between neighbours;
///   - each segment's damage: the largest over the part's elements that hold both its ends (a
///     crack in one element is that element's damage, not smeared over its neighbours), else,
///     between two particles, the mean of theirs (PlasticPoints::damage); 1 where nothing holds
///     it any more;
///   - the spall thickness: the middle of the first segment, going in from the back face, whose
///     damage is at or above the threshold (0: none is);
///   - the fly-off velocity: the mass-weighted mean velocity along -d (out of the back face) of the
///     column's nodes between the back face and that segment (0 without a spall);
///   - the back face's velocity along -d (its node at s = 0).
/// Theory (verification/analysis/test_impact.cpp, Spall): a rectangular pulse of length L and
/// amplitude above the tensile strength reflects from the free end of a bar as net tension first at
/// the depth L / 2; the layer there takes the pulse's momentum and flies off at twice the pulse's
/// particle velocity (less what the crack's fracture energy takes).
#include <vector>

#include "rkfem/core/types.hpp"

namespace rkfem
{
class Model;
struct SpallSpec;

struct SpallMeasures
{
    real_t thickness = 0.0;          ///< [m]
    real_t fly_off_velocity = 0.0;   ///< [m/s]
    real_t back_face_velocity = 0.0; ///< [m/s]
};

class SpallAnalysis
{
  public:
    /// Finds the column. Throws DeckError (at the spall key) when fewer than two nodes of the part
    /// lie on the line or none at the point.
    SpallAnalysis(const Model& model, const SpallSpec& spec);
    SpallMeasures measure(const Model& model) const;
    /// The column's nodes, back face first, and their depths [m].
    const std::vector<index_t>& column() const { return column_; }
    const std::vector<real_t>& depths() const { return depth_; }

  private:
    /// The damage of the segment between column nodes k and k + 1 (see the file's note).
    real_t segment_damage(const Model& model, std::size_t k) const;
    const SpallSpec& spec_;
    index_t part_ = -1;
    std::vector<index_t> column_;
    std::vector<real_t> depth_;
};
} // namespace rkfem
