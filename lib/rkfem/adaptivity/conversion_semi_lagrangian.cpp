// Conversion into semi-Lagrangian particles (issue #48: a converting target that penetrates as
// the seed's KC-FEMFRE does; PartSpec::converts_to_semi_lagrangian). A fem-1pt part with
// `kinematics: semi-lagrangian` and `conversion` is its 1-point FE block and a block of
// semi-Lagrangian particles, one per node, dormant at the start. The particles' unknowns are the
// nodes' velocities (semi_lagrangian_block.hpp), so the FE elements that stay and the particles
// share nodes with no map between them. An event:
//   - each converted element's 8 corner octants (reference volume V0 / 8 each) go to the
//     particles at its corners; a particle takes the volume-weighted mean of its octants' stress,
//     volume ratio and history (its own state where it was active, one share of V0 its reference
//     volume; damage measures the largest: PlasticPoints::blend_point);
//   - its cell (SNNI's parallelepiped) is the box, along the axes, of the particle and the
//     current centroids of all its converted elements (a box mesh's dual cell where all have
//     converted, the part of it on the converted side otherwise), scaled to the volume its
//     material has (ratio times reference volume); its support's stretch is measured from the
//     same box in the reference configuration;
//   - the elements leave the FE block (as eroded ones do, recorded as converted: the impact
//     measures read their damage from the particles), the nodes keep their masses and velocities,
//     so mass and momentum carry over exactly; the elements' hourglass forces are dropped;
//   - a particle that has separated takes no octant: the material of those octants is left
//     with the fragment's mass at the node (stated, not measured: rare where separation follows
//     conversion).
// Where FE elements meet particles the integration is non-conforming: the cells end at the
// converted elements' faces, the FE elements' gradients reach the particles' nodes as FE
// functions, and the particles' functions are built from the particles alone. Linear fields are
// reproduced on both sides (each interpolates the nodal velocities exactly for them), so the
// patch test's strain is exact (ConversionSemiLagrangian's linear field: the stress to round-off,
// the internal forces summing to zero); the integration constraint across the interface is not
// kept, and no test measures its force residual there yet.
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "rkfem/core/error.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/operators/semi_lagrangian_block.hpp"

namespace rkfem
{
SemiLagrangianForceBlock* Model::semi_lagrangian_block(index_t part)
{
    return const_cast<SemiLagrangianForceBlock*>(std::as_const(*this).semi_lagrangian_block(part));
}

index_t Model::rk_element_count(index_t part) const
{
    if (deck_.parts[static_cast<std::size_t>(part)].converts_to_semi_lagrangian())
        return static_cast<index_t>(converted_[static_cast<std::size_t>(part)].volume0.size());
    const std::vector<char>& rk = rk_elements_[static_cast<std::size_t>(part)];
    return static_cast<index_t>(std::count(rk.begin(), rk.end(), char{1}));
}

real_t Model::converted_element_damage(index_t block, std::size_t k) const
{
    const SemiLagrangianForceBlock* sl = semi_lagrangian_block(block);
    const NodalBlock& st = *sl->nodal_points();
    if (!st.plastic.active())
        return 0.0;
    const ErodedElements& took = converted_[static_cast<std::size_t>(block)];
    real_t d = 0.0;
    for (int a = 0; a < 8; ++a)
        d += st.plastic.damage(static_cast<std::size_t>(took.conn[8 * k + a] - st.node_begin));
    return d / 8.0;
}

index_t Model::convert_to_semi_lagrangian(index_t part, const std::vector<char>& convert)
{
    const PartSpec& ps = deck_.parts[static_cast<std::size_t>(part)];
    HexBlock& blk = meshes[static_cast<std::size_t>(part)];
    SemiLagrangianForceBlock* slp = semi_lagrangian_block(part);
    RKFEM_REQUIRE(slp && blk.points_per_element() == 1,
                  "semi-Lagrangian conversion: part '" << ps.name << "' is not a fem-1pt part with particles");
    SemiLagrangianForceBlock& sl = *slp;
    NodalBlock& st = *sl.nodal_points();
    const index_t begin = parts[static_cast<std::size_t>(part)].node_begin;
    const std::size_t n = static_cast<std::size_t>(parts[static_cast<std::size_t>(part)].node_end - begin);
    const index_t ne = blk.n_elements();
    RKFEM_REQUIRE(static_cast<index_t>(convert.size()) == ne,
                  "semi-Lagrangian conversion: " << convert.size() << " flags for " << ne << " elements");
    converted_.resize(meshes.size());
    ErodedElements& took = converted_[static_cast<std::size_t>(part)];

    // the particles that take octants now: the new elements' corners (separated ones excepted)
    std::vector<char> takes(n, 0);
    index_t count = 0;
    for (index_t e = 0; e < ne; ++e)
        if (convert[e])
        {
            ++count;
            for (int a = 0; a < 8; ++a)
            {
                const index_t i = blk.conn[8 * static_cast<std::size_t>(e) + a] - begin;
                takes[static_cast<std::size_t>(i)] = !sl.separated(i);
            }
        }
    if (count == 0)
        return 0;

    // each taking particle's box about its converted elements' centroids, now and at rest
    std::vector<real_t> lo(6 * n), hi(6 * n);
    auto position = [&](const std::vector<real_t>& x, index_t g, int d)
    { return x[3 * static_cast<std::size_t>(g) + d]; };
    for (std::size_t i = 0; i < n; ++i)
        if (takes[i])
            for (int d = 0; d < 3; ++d)
            {
                lo[6 * i + d] = hi[6 * i + d] = position(nodes.x, begin + static_cast<index_t>(i), d);
                lo[6 * i + 3 + d] = hi[6 * i + 3 + d] = position(nodes.x0, begin + static_cast<index_t>(i), d);
            }
    auto widen = [&](const index_t* corners)
    {
        real_t c[6] = {0, 0, 0, 0, 0, 0};
        for (int a = 0; a < 8; ++a)
            for (int d = 0; d < 3; ++d)
            {
                c[d] += position(nodes.x, corners[a], d) / 8.0;
                c[3 + d] += position(nodes.x0, corners[a], d) / 8.0;
            }
        for (int a = 0; a < 8; ++a)
        {
            const std::size_t i = static_cast<std::size_t>(corners[a] - begin);
            if (!takes[i])
                continue;
            for (int d = 0; d < 6; ++d)
            {
                lo[6 * i + d] = std::min(lo[6 * i + d], c[d]);
                hi[6 * i + d] = std::max(hi[6 * i + d], c[d]);
            }
        }
    };
    for (std::size_t k = 0; k < took.volume0.size(); ++k)
        widen(took.conn.data() + 8 * k);
    for (index_t e = 0; e < ne; ++e)
        if (convert[e])
            widen(blk.conn.data() + 8 * static_cast<std::size_t>(e));

    // each taking particle's material: its own (if active) and its new octants', blended
    std::vector<PlasticPoints::Share> history;
    for (std::size_t i = 0; i < n; ++i)
    {
        if (!takes[i])
            continue;
        const index_t p = static_cast<index_t>(i);
        history.clear();
        real_t total = 0.0, J = 0.0, sig[6] = {0, 0, 0, 0, 0, 0};
        auto share = [&](const PlasticPoints& from, std::size_t point, real_t w, const real_t* stress,
                         std::size_t stride, real_t ratio)
        {
            history.push_back({&from, point, w});
            total += w;
            J += w * ratio;
            for (int k = 0; k < 6; ++k)
                sig[k] += w * stress[k * stride + point];
        };
        if (!sl.dormant(p))
            share(st.plastic, i, st.points.weight[i], st.stress.data(), st.stress_stride, st.jacobian[i]);
        const index_t i0 = blk.node_elem_offsets[i], i1 = blk.node_elem_offsets[i + 1];
        for (index_t s = i0; s < i1; ++s)
        {
            const index_t e = blk.node_elem_slots[s] / 8;
            if (convert[e])
                share(blk.plastic, static_cast<std::size_t>(e), blk.volume0[e] / 8.0, blk.stress.data(),
                      blk.stress_stride, element_volume(blk, nodes, e) / blk.volume0[e]);
        }
        RKFEM_REQUIRE(total > 0.0,
                      "semi-Lagrangian conversion: particle " << p << " of part '" << ps.name << "' takes no material");
        J /= total;
        for (int k = 0; k < 6; ++k)
            st.stress[k * st.stress_stride + i] = st.stress_trial[k * st.stress_stride + i] = sig[k] / total;
        if (st.plastic.active())
            st.plastic.blend_point(history.data(), history.size(), i);
        // the cell: the box now, scaled to the material's volume; the width: the box at rest
        real_t cell[12] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
        real_t box = 1.0, box0 = 1.0, w0 = 0.0;
        for (int d = 0; d < 3; ++d)
        {
            box *= hi[6 * i + d] - lo[6 * i + d];
            box0 *= hi[6 * i + 3 + d] - lo[6 * i + 3 + d];
        }
        RKFEM_REQUIRE(box > 0.0 && box0 > 0.0, "semi-Lagrangian conversion: particle "
                                                   << p << " of part '" << ps.name << "' has a flat box about its "
                                                   << "elements (volume " << box << " m^3 now, " << box0
                                                   << " at rest)");
        const real_t scale = std::cbrt(J * total / box), scale0 = std::cbrt(total / box0);
        for (int d = 0; d < 3; ++d)
        {
            cell[d] = 0.5 * (lo[6 * i + d] + hi[6 * i + d]) - position(nodes.x, begin + p, d);
            cell[3 + 4 * d] = 0.5 * scale * (hi[6 * i + d] - lo[6 * i + d]);
            w0 = std::max(w0, 0.5 * scale0 * (hi[6 * i + 3 + d] - lo[6 * i + 3 + d]));
        }
        sl.activate(p, cell, total, w0);
    }

    // the elements leave the FE block
    std::vector<char> keep(static_cast<std::size_t>(ne));
    for (index_t e = 0; e < ne; ++e)
        keep[static_cast<std::size_t>(e)] = !convert[e];
    drop_elements(part, keep, took);
    converted_elements_ += count;
    return count;
}
} // namespace rkfem
