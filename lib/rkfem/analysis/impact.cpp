#include "rkfem/analysis/impact.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <unordered_map>

#include "rkfem/analysis/analysis_detail.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/operators/semi_lagrangian_block.hpp"

namespace rkfem
{
namespace
{
using analysis_detail::part_index;
using analysis_detail::reference;

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
    tolerance_ = analysis_detail::on_line_tolerance(model, target_);
    std::vector<std::pair<real_t, index_t>> on_plane;
    for (index_t i = part.node_begin; i < part.mesh_node_end; ++i)
    {
        const Vec3 r = reference(model, i) - spec.point;
        if (std::abs(r.dot(spec.direction)) <= tolerance_)
            on_plane.emplace_back(r.norm(), i);
    }
    std::stable_sort(on_plane.begin(), on_plane.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    for (const auto& [distance, i] : on_plane)
        plane_nodes_.push_back(i);
    if (!plane_nodes_.empty())
        surface_node_ = plane_nodes_.front();
    if (surface_node_ < 0)
        throw DeckError({spec.loc.where, spec.loc.path + ".point"},
                        "no node of part '" + spec.target +
                            "' lies on the plane through the point normal to the direction",
                        "expected the point of impact on the target's original surface");
}

index_t ImpactAnalysis::attached_surface_node(const Model& model) const
{
    const SemiLagrangianForceBlock* sl = model.semi_lagrangian_block(target_);
    if (sl == nullptr)
        return surface_node_;
    const PartInfo& part = model.parts[static_cast<std::size_t>(target_)];
    for (const index_t i : plane_nodes_)
        if (!sl->separated(i - part.node_begin))
            return i;
    return -1;
}

real_t ImpactAnalysis::apparent_depth(const Model& model) const
{
    const index_t s = attached_surface_node(model);
    return s < 0 ? 0.0 : model.physical(model.nodes.u, s).dot(spec_.direction);
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
    const HexBlock& blk = model.meshes[static_cast<std::size_t>(target_)];
    const Model::ErodedElements& gone = model.eroded(target_);
    std::vector<const index_t*> cells;
    for (std::size_t k = 0; k < gone.volume0.size(); ++k)
        cells.push_back(gone.conn.data() + 8 * k);
    for (index_t e = 0; e < blk.n_elements(); ++e)
        if (removed(model, e))
            cells.push_back(blk.conn.data() + 8 * e);
    // elements converted into particles: by their particles' damage
    const Model::ErodedElements& converted = model.converted(target_);
    for (std::size_t k = 0; k < converted.volume0.size(); ++k)
        if (model.converted_element_damage(target_, k) >= spec_.damage)
            cells.push_back(converted.conn.data() + 8 * k);
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
                on_surface =
                    on_surface && std::abs((reference(model, k[j]) - spec_.point).dot(spec_.direction)) <= tolerance_;
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

ImpactAnalysis::Crater ImpactAnalysis::crater(const Model& model) const
{
    Crater out;
    const HexBlock& blk = model.meshes[static_cast<std::size_t>(target_)];
    const Model::ErodedElements& gone = model.eroded(target_);
    const PartInfo& part = model.parts[static_cast<std::size_t>(target_)];
    const index_t n0 = part.node_begin, nn = part.node_end - part.node_begin;
    // nodal damage: volume-weighted mean over the elements around each node (eroded: 1)
    std::vector<real_t> sum(static_cast<std::size_t>(nn), 0.0), weight(static_cast<std::size_t>(nn), 0.0);
    auto spread = [&](const index_t* c, real_t d, real_t v)
    {
        for (int j = 0; j < 8; ++j)
        {
            sum[static_cast<std::size_t>(c[j] - n0)] += d * v;
            weight[static_cast<std::size_t>(c[j] - n0)] += v;
        }
    };
    for (index_t e = 0; e < blk.n_elements(); ++e)
        spread(blk.conn.data() + 8 * e, model.element_history(target_, e, Model::History::Damage),
               blk.volume0[static_cast<std::size_t>(e)]);
    for (std::size_t k = 0; k < gone.volume0.size(); ++k)
        spread(gone.conn.data() + 8 * k, 1.0, gone.volume0[k]);
    const Model::ErodedElements& converted = model.converted(target_);
    for (std::size_t k = 0; k < converted.volume0.size(); ++k)
        spread(converted.conn.data() + 8 * k, model.converted_element_damage(target_, k), converted.volume0[k]);
    std::vector<real_t> dn(static_cast<std::size_t>(nn), 0.0);
    for (std::size_t i = 0; i < dn.size(); ++i)
        dn[i] = weight[i] > 0.0 ? sum[i] / weight[i] : 0.0;
    const real_t th = spec_.damage;
    auto d_at = [&](index_t g) { return dn[static_cast<std::size_t>(g - n0)]; };
    auto depth_of = [&](const Vec3& x) { return (x - spec_.point).dot(spec_.direction); };
    auto on_surface = [&](const Vec3& x) { return std::abs(depth_of(x)) <= tolerance_; };
    auto radius_of = [&](const Vec3& x)
    {
        const Vec3 r = x - spec_.point;
        return (r - r.dot(spec_.direction) * spec_.direction).norm();
    };
    // all cells (live, eroded and converted) and the node-to-cell adjacency through their edges
    std::vector<const index_t*> cells;
    for (index_t e = 0; e < blk.n_elements(); ++e)
        cells.push_back(blk.conn.data() + 8 * e);
    for (std::size_t k = 0; k < gone.volume0.size(); ++k)
        cells.push_back(gone.conn.data() + 8 * k);
    for (std::size_t k = 0; k < converted.volume0.size(); ++k)
        cells.push_back(converted.conn.data() + 8 * k);
    static constexpr int edges[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                                         {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
    std::vector<std::vector<index_t>> node_cells(static_cast<std::size_t>(nn));
    for (std::size_t c = 0; c < cells.size(); ++c)
        for (int j = 0; j < 8; ++j)
            node_cells[static_cast<std::size_t>(cells[c][j] - n0)].push_back(static_cast<index_t>(c));
    // the crater's nodes: at or above the threshold, reached from the surface along edges whose
    // both ends are at or above it
    std::vector<char> in(static_cast<std::size_t>(nn), 0);
    std::vector<index_t> stack;
    for (index_t g = part.node_begin; g < part.node_end; ++g)
        if (d_at(g) >= th && on_surface(reference(model, g)) && weight[static_cast<std::size_t>(g - n0)] > 0.0)
        {
            in[static_cast<std::size_t>(g - n0)] = 1;
            stack.push_back(g);
        }
    std::vector<char> touched(cells.size(), 0);
    while (!stack.empty())
    {
        const index_t g = stack.back();
        stack.pop_back();
        const Vec3 xg = reference(model, g);
        out.depth = std::max(out.depth, depth_of(xg));
        if (on_surface(xg))
            out.diameter = std::max(out.diameter, 2.0 * radius_of(xg));
        for (index_t c : node_cells[static_cast<std::size_t>(g - n0)])
        {
            touched[static_cast<std::size_t>(c)] = 1;
            for (const auto& ed : edges)
            {
                const index_t a = cells[c][ed[0]], b = cells[c][ed[1]];
                if (a != g && b != g)
                    continue;
                const index_t o = a == g ? b : a;
                if (d_at(o) >= th)
                {
                    if (!in[static_cast<std::size_t>(o - n0)])
                    {
                        in[static_cast<std::size_t>(o - n0)] = 1;
                        stack.push_back(o);
                    }
                    continue;
                }
                // the threshold's crossing on the edge g -> o
                const real_t t = (d_at(g) - th) / (d_at(g) - d_at(o));
                const Vec3 x = xg + t * (reference(model, o) - xg);
                out.depth = std::max(out.depth, depth_of(x));
                if (on_surface(xg) && on_surface(reference(model, o)))
                    out.diameter = std::max(out.diameter, 2.0 * radius_of(x));
            }
        }
    }
    // volume: the touched cells sampled at 4 x 4 x 4 points of the trilinear field
    static constexpr real_t sx[8] = {-1, 1, 1, -1, -1, 1, 1, -1}, sy[8] = {-1, -1, 1, 1, -1, -1, 1, 1},
                            sz[8] = {-1, -1, -1, -1, 1, 1, 1, 1};
    for (std::size_t c = 0; c < cells.size(); ++c)
    {
        if (!touched[c])
            continue;
        const std::size_t n_live = static_cast<std::size_t>(blk.n_elements()), n_gone = gone.volume0.size();
        const real_t v = c < n_live            ? blk.volume0[c]
                         : c < n_live + n_gone ? gone.volume0[c - n_live]
                                               : converted.volume0[c - n_live - n_gone];
        int hits = 0;
        for (int i = 0; i < 4; ++i)
            for (int j = 0; j < 4; ++j)
                for (int k = 0; k < 4; ++k)
                {
                    const real_t xi = -0.75 + 0.5 * i, eta = -0.75 + 0.5 * j, zeta = -0.75 + 0.5 * k;
                    real_t d = 0.0;
                    for (int a = 0; a < 8; ++a)
                        d += 0.125 * (1 + sx[a] * xi) * (1 + sy[a] * eta) * (1 + sz[a] * zeta) * d_at(cells[c][a]);
                    hits += d >= th;
                }
        out.volume += v * hits / 64.0;
    }
    return out;
}

ImpactMeasures ImpactAnalysis::measure(const Model& model) const
{
    ImpactMeasures r;
    r.apparent_depth = apparent_depth(model);
    r.actual_depth = actual_depth(model);
    const Crater cr = crater(model);
    r.crater_depth = cr.depth;
    r.crater_diameter = cr.diameter;
    r.crater_volume = cr.volume;
    r.residual_velocity = residual_velocity(model);
    const PartInfo& target = model.parts[static_cast<std::size_t>(target_)];
    for (index_t i = target.node_begin; i < target.node_end; ++i)
        r.target_momentum += model.nodes.mass[i] * model.physical(model.nodes.v, i).dot(spec_.direction);
    const HexBlock& blk = model.meshes[static_cast<std::size_t>(target_)];
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
    const Model::ErodedElements& converted = model.converted(target_);
    for (std::size_t k = 0; k < converted.volume0.size(); ++k)
    {
        const real_t d = model.converted_element_damage(target_, k);
        r.damaged_volume_half += d > 0.5 ? converted.volume0[k] : 0.0;
        r.damaged_volume_threshold += d >= spec_.damage ? converted.volume0[k] : 0.0;
    }
    for (index_t b = 0; b < static_cast<index_t>(model.meshes.size()); ++b)
        for (real_t v : model.eroded(b).volume0)
            r.eroded_mass += model.meshes[static_cast<std::size_t>(b)].material.rho * v;
    if (projectile_ >= 0)
    {
        const HexBlock& pb = model.meshes[static_cast<std::size_t>(projectile_)];
        for (index_t e = 0; e < pb.n_elements(); ++e)
            r.projectile_mass += pb.material.rho * pb.volume0[static_cast<std::size_t>(e)];
    }
    return r;
}
} // namespace rkfem
