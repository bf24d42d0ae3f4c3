#include "rkfem/analysis/spall.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "rkfem/analysis/analysis_detail.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/model/model.hpp"

namespace rkfem
{
SpallAnalysis::SpallAnalysis(const Model& model, const SpallSpec& spec) : spec_(spec)
{
    part_ = analysis_detail::part_index(model, spec.part);
    if (part_ < 0)
        throw DeckError({spec.loc.where, spec.loc.path + ".part"}, "unknown part '" + spec.part + "'",
                        "expected a part of the deck");
    const PartInfo& part = model.parts[static_cast<std::size_t>(part_)];
    const real_t tol = analysis_detail::on_line_tolerance(model, part_);
    std::vector<std::pair<real_t, index_t>> on;
    for (index_t i = part.node_begin; i < part.mesh_node_end; ++i)
    {
        const Vec3 r = analysis_detail::reference(model, i) - spec.point;
        const real_t s = r.dot(spec.direction);
        if ((r - s * spec.direction).norm() <= tol && s >= -tol)
            on.emplace_back(std::max(s, 0.0), i);
    }
    std::sort(on.begin(), on.end());
    if (on.size() < 2 || on[0].first > tol)
        throw DeckError({spec.loc.where, spec.loc.path + ".point"},
                        std::to_string(on.size()) + " node(s) of part '" + spec.part +
                            "' on the line from the point along the direction" +
                            (on.empty() || on[0].first <= tol ? "" : ", none at the point"),
                        "expected a point of the part's back face on a line of its nodes, and the direction into "
                        "the part");
    for (const auto& [s, i] : on)
    {
        depth_.push_back(s);
        column_.push_back(i);
    }
}

real_t SpallAnalysis::segment_damage(const Model& model, std::size_t k) const
{
    const index_t a = column_[k], b = column_[k + 1];
    // FE: the largest damage of the part's elements that hold both ends
    const HexBlock& blk = model.meshes[static_cast<std::size_t>(part_)];
    const index_t l = a - blk.node_begin;
    real_t d = -1.0;
    for (index_t s = blk.node_elem_offsets[l]; s < blk.node_elem_offsets[l + 1]; ++s)
    {
        const index_t e = blk.node_elem_slots[s] / 8;
        const index_t* c = blk.conn.data() + 8 * static_cast<std::size_t>(e);
        if (std::find(c, c + 8, b) != c + 8)
            d = std::max(d, model.element_history(part_, e, Model::History::Damage));
    }
    if (d >= 0.0)
        return d;
    // particles: the mean of the two ends'
    if (model.particle_points(a) && model.particle_points(b))
        return 0.5 * (model.nodal_history(a, Model::History::Damage) + model.nodal_history(b, Model::History::Damage));
    return 1.0; // nothing holds the segment any more
}

SpallMeasures SpallAnalysis::measure(const Model& model) const
{
    SpallMeasures r;
    const Vec3 out = -spec_.direction;
    r.back_face_velocity = model.physical(model.nodes.v, column_[0]).dot(out);
    std::size_t k = 0;
    while (k + 1 < column_.size() && segment_damage(model, k) < spec_.damage)
        ++k;
    if (k + 1 == column_.size())
        return r; // no crack along the line
    r.thickness = 0.5 * (depth_[k] + depth_[k + 1]);
    real_t p = 0.0, m = 0.0;
    for (std::size_t j = 0; j <= k; ++j)
    {
        const real_t mj = model.nodes.mass[column_[j]];
        p += mj * model.physical(model.nodes.v, column_[j]).dot(out);
        m += mj;
    }
    r.fly_off_velocity = p / m;
    return r;
}
} // namespace rkfem
