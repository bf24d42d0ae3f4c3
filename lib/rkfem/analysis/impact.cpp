#include "rkfem/analysis/impact.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <unordered_map>

#include "rkfem/core/error.hpp"

namespace rkfem
{
namespace
{
index_t part_index(const Model& m, const std::string& name)
{
    for (std::size_t i = 0; i < m.parts.size(); ++i)
        if (m.parts[i].name == name)
            return static_cast<index_t>(i);
    return -1;
}

Vec3 reference(const Model& m, index_t i) { return {m.nodes.x0[3 * i], m.nodes.x0[3 * i + 1], m.nodes.x0[3 * i + 2]}; }

/// A face as the sorted ids of its 4 nodes.
using FaceKey = std::array<index_t, 4>;
struct FaceHash
{
    std::size_t operator()(const FaceKey& k) const
    {
        std::size_t h = 1469598103934665603ull;
        for (index_t v : k)
            h = (h ^ static_cast<std::size_t>(v)) * 1099511628211ull;
        return h;
    }
};
} // namespace

ImpactAnalysis::ImpactAnalysis(const Model& model, const ImpactSpec& spec) : spec_(spec)
{
    target_ = part_index(model, spec.target);
    projectile_ = spec.projectile.empty() ? -1 : part_index(model, spec.projectile);
    RKFEM_REQUIRE(target_ >= 0, "impact: no part '" << spec.target << "'");
    const PartInfo& part = model.parts[static_cast<std::size_t>(target_)];
    Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
    for (index_t i = part.node_begin; i < part.node_end; ++i)
    {
        lo = lo.cwiseMin(reference(model, i));
        hi = hi.cwiseMax(reference(model, i));
    }
    tolerance_ = 1e-6 * (hi - lo).norm();
    real_t best = 1e300;
    for (index_t i = part.node_begin; i < part.node_end; ++i)
    {
        const Vec3 r = reference(model, i) - spec.point;
        if (std::abs(r.dot(spec.direction)) > tolerance_)
            continue;
        if (r.norm() < best)
        {
            best = r.norm();
            surface_node_ = i;
        }
    }
    if (surface_node_ < 0)
        throw DeckError({spec.loc.where, spec.loc.path + ".point"},
                        "no node of part '" + spec.target + "' lies on the plane through the point normal to the direction",
                        "expected the point of impact on the target's original surface");
}

real_t ImpactAnalysis::apparent_depth(const Model& model) const
{
    return model.physical(model.nodes.u, surface_node_).dot(spec_.direction);
}

real_t ImpactAnalysis::residual_velocity(const Model& model) const
{
    if (projectile_ < 0)
        return 0.0;
    const PartInfo& part = model.parts[static_cast<std::size_t>(projectile_)];
    real_t p = 0.0, m = 0.0;
    for (index_t i = part.node_begin; i < part.node_end; ++i)
    {
        p += model.nodes.mass[i] * model.physical(model.nodes.v, i).dot(spec_.direction);
        m += model.nodes.mass[i];
    }
    return m > 0.0 ? p / m : 0.0;
}

bool ImpactAnalysis::removed(const Model& model, index_t e) const
{
    return model.element_history(target_, e, Model::History::Damage) >= spec_.damage;
}

real_t ImpactAnalysis::actual_depth(const Model& model) const
{
    // the removed elements of the target: eroded ones, then damaged ones still in the block
    const HexBlock& blk = model.blocks[static_cast<std::size_t>(target_)];
    const Model::ErodedElements& gone = model.eroded(target_);
    std::vector<const index_t*> cells;
    for (std::size_t k = 0; k < gone.volume0.size(); ++k)
        cells.push_back(gone.conn.data() + 8 * k);
    for (index_t e = 0; e < blk.n_elements(); ++e)
        if (removed(model, e))
            cells.push_back(blk.conn.data() + 8 * e);
    if (cells.empty())
        return 0.0;
    // faces shared between removed cells join them; a face on the original surface seeds
    std::unordered_map<FaceKey, std::vector<index_t>, FaceHash> faces;
    std::vector<index_t> stack;
    std::vector<char> in_crater(cells.size(), 0);
    for (std::size_t c = 0; c < cells.size(); ++c)
        for (const auto& f : hex_faces)
        {
            FaceKey k;
            bool on_surface = true;
            for (int j = 0; j < 4; ++j)
            {
                k[j] = cells[c][f[j]];
                on_surface = on_surface &&
                             std::abs((reference(model, k[j]) - spec_.point).dot(spec_.direction)) <= tolerance_;
            }
            std::sort(k.begin(), k.end());
            faces[k].push_back(static_cast<index_t>(c));
            if (on_surface && !in_crater[c])
            {
                in_crater[c] = 1;
                stack.push_back(static_cast<index_t>(c));
            }
        }
    real_t depth = 0.0;
    while (!stack.empty())
    {
        const index_t c = stack.back();
        stack.pop_back();
        for (int j = 0; j < 8; ++j)
            depth = std::max(depth, (reference(model, cells[c][j]) - spec_.point).dot(spec_.direction));
        for (const auto& f : hex_faces)
        {
            FaceKey k;
            for (int j = 0; j < 4; ++j)
                k[j] = cells[c][f[j]];
            std::sort(k.begin(), k.end());
            for (index_t other : faces[k])
                if (!in_crater[other])
                {
                    in_crater[other] = 1;
                    stack.push_back(other);
                }
        }
    }
    return depth;
}

ImpactMeasures ImpactAnalysis::measure(const Model& model) const
{
    ImpactMeasures r;
    r.apparent_depth = apparent_depth(model);
    r.actual_depth = actual_depth(model);
    r.residual_velocity = residual_velocity(model);
    const PartInfo& target = model.parts[static_cast<std::size_t>(target_)];
    for (index_t i = target.node_begin; i < target.node_end; ++i)
        r.target_momentum += model.nodes.mass[i] * model.physical(model.nodes.v, i).dot(spec_.direction);
    const HexBlock& blk = model.blocks[static_cast<std::size_t>(target_)];
    for (index_t e = 0; e < blk.n_elements(); ++e)
    {
        const real_t d = model.element_history(target_, e, Model::History::Damage);
        const real_t v = blk.volume0[static_cast<std::size_t>(e)];
        r.damaged_volume_half += d > 0.5 ? v : 0.0;
        r.damaged_volume_threshold += d >= spec_.damage ? v : 0.0;
    }
    for (real_t v : model.eroded(target_).volume0)
    {
        r.damaged_volume_half += v;
        r.damaged_volume_threshold += v;
    }
    for (index_t b = 0; b < static_cast<index_t>(model.blocks.size()); ++b)
        for (real_t v : model.eroded(b).volume0)
            r.eroded_mass += model.blocks[static_cast<std::size_t>(b)].material.rho * v;
    if (projectile_ >= 0)
    {
        const HexBlock& pb = model.blocks[static_cast<std::size_t>(projectile_)];
        for (index_t e = 0; e < pb.n_elements(); ++e)
            r.projectile_mass += pb.material.rho * pb.volume0[static_cast<std::size_t>(e)];
    }
    return r;
}
} // namespace rkfem
