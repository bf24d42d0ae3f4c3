#include "rkfem/operators/nodal_block.hpp"

#include <algorithm>
#include <cmath>
#include <memory>

#include "rkfem/core/error.hpp"
#include "rkfem/core/huge_pages.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/simd.hpp"
#include "rkfem/core/stream_stores.hpp"
#include "rkfem/operators/bulk_viscosity.hpp"

namespace rkfem
{
void NodalBlock::initialize(Assembly assembly)
{
    build_tables(assembly);
    const index_t np = n_points(), ns = n_stab();
    stress_stride = batch8_stride(static_cast<std::size_t>(np));
    stress.assign(6 * stress_stride, 0.0);
    if (plastic.active())
        plastic.resize(static_cast<std::size_t>(np));
    stress_trial = stress;
    stab_stress.assign(6 * static_cast<std::size_t>(ns), 0.0);
    stab_stress_trial = stab_stress;
    use_huge_pages(stress);
    use_huge_pages(stress_trial);
    use_huge_pages(stab_stress);
    use_huge_pages(stab_stress_trial);
}

namespace
{
/// The entries of `op` written back from `table` (point p: node = base + offset, its gradients).
void expand_from(IntegrationOperator& op, const StencilTable& table)
{
    const index_t np = op.n_points();
    op.nodes.resize(static_cast<std::size_t>(op.offsets[np]));
    op.grad.resize(3 * op.nodes.size());
    for (index_t p = 0; p < np; ++p)
    {
        const StencilView v = table.view(p);
        const index_t k0 = op.offsets[p];
        RKFEM_REQUIRE(op.offsets[p + 1] - k0 == v.size, "expand_operators: point "
                                                            << p << " has " << op.offsets[p + 1] - k0
                                                            << " entries, its stencil " << v.size);
        for (index_t j = 0; j < v.size; ++j)
        {
            op.nodes[k0 + j] = v.base + v.offset[j];
            for (int d = 0; d < 3; ++d)
                op.grad[3 * static_cast<std::size_t>(k0 + j) + d] = v.grad[3 * j + d];
        }
    }
}

void release_entries(IntegrationOperator& op)
{
    std::vector<index_t>().swap(op.nodes);
    std::vector<real_t>().swap(op.grad);
}
} // namespace

void NodalBlock::expand_operators()
{
    if (points_in_table)
        expand_from(points, point_stencils);
    if (stab_in_table)
        expand_from(stabilization, stab_stencils);
    if (stab_in_triplets)
    {
        expand_triplets(stabilization, stab_triplets);
        // the sub-points' positions: their parents' (build_nsni_stabilization)
        stabilization.position.resize(3 * static_cast<std::size_t>(stabilization.n_points()));
        for (index_t s = 0; s < stabilization.n_points(); ++s)
            for (int d = 0; d < 3; ++d)
                stabilization.position[3 * static_cast<std::size_t>(s) + d] =
                    points.position[3 * static_cast<std::size_t>(stabilization.parent[s]) + d];
    }
    points_in_table = stab_in_table = stab_in_triplets = false;
}

namespace
{
/// NSNI's layout (build_nsni_stabilization): sub-points 3 p + i of parent p, with one node list;
/// held as triplets alone, one triplet per point.
void check_nsni_layout(const NodalBlock& b, bool held_as_triplets)
{
    const index_t np = b.n_points(), ns = b.n_stab();
    if (b.stabilization_triplets && held_as_triplets)
        RKFEM_REQUIRE(ns == 3 * np && b.stab_triplets.point_triplet.size() == static_cast<std::size_t>(np),
                      "nodal block: " << ns << " NSNI sub-points and " << b.stab_triplets.point_triplet.size()
                                      << " triplets for " << np << " points");
    else if (b.stabilization_triplets)
    {
        RKFEM_REQUIRE(ns == 3 * np, "nodal block: " << ns << " NSNI sub-points for " << np << " points");
        for (index_t t = 0; t < np; ++t)
        {
            const index_t k0 = b.stabilization.offsets[3 * t], n = b.stabilization.offsets[3 * t + 1] - k0;
            for (int i = 0; i < 3; ++i)
            {
                const index_t ki = b.stabilization.offsets[3 * t + i];
                RKFEM_REQUIRE(
                    b.stabilization.parent[3 * t + i] == t && b.stabilization.offsets[3 * t + i + 1] - ki == n &&
                        std::equal(b.stabilization.nodes.begin() + k0, b.stabilization.nodes.begin() + k0 + n,
                                   b.stabilization.nodes.begin() + ki),
                    "nodal block: NSNI sub-point " << 3 * t + i << " does not share the nodes of its point " << t);
            }
        }
    }
}

/// Shared stencils (they snap the operators' gradients, which the transposes copy) and NSNI's
/// triplets.
void share_tables(NodalBlock& b, bool points_held, bool held_as_triplets, bool share)
{
    if (!points_held)
        b.point_stencils.clear();
    b.stab_stencils.clear();
    if (share)
    {
        if (!points_held)
            b.point_stencils = rkfem::share_stencils(b.points);
        if (!held_as_triplets)
            b.stab_stencils = rkfem::share_stencils(b.stabilization);
    }
    // NSNI's triplets: per entry the six values the pass reads. They snap the operator, as
    // shared stencils do (whose sub-points, snapped one class at a time, differ from symmetry by
    // up to the sharing's tolerance), so that every reader, the transposes below included, sees
    // one symmetric operator; they replace the sub-points' shared stencils.
    if (!held_as_triplets)
    {
        b.stab_triplets.clear();
        if (b.stabilization_triplets)
            b.stab_triplets = build_triplets(b.stabilization, b.stab_stencils);
        if (!b.stab_triplets.empty())
        {
            b.stab_stencils.clear();
            expand_triplets(b.stabilization, b.stab_triplets);
        }
    }
}

/// The chunked scatter's chunks (or none: the transpose gather); returns whether the pass
/// scatters.
bool cut_scatter_chunks(NodalBlock& b, Assembly assembly, bool points_held)
{
    const index_t np = b.n_points(), nn = b.node_end - b.node_begin;
    // chunked scatter: fixed chunks of stress points, then of stabilization points, each with
    // the node range its entries touch. About n / 16 stress points per chunk (at least 512) first,
    // so that a part of a few thousand particles has work for every thread; where their node
    // ranges overlap too much (the reduce would sum over more than 3 buffers per node: small
    // lattices with wide supports, a mesh numbered column by column, whose chunks are thin
    // bundles of columns with a wide halo), chunks twice as large, and so on up to 2048 points
    // or a quarter of the block, whichever is larger (a random order stays non-local at every
    // size that leaves the threads chunks to share: the transpose gather then). Either way the
    // chunks are a function of the operators only, never of the thread count.
    // the last cut's largest buffers per node and largest mean share of the block a chunk
    // covers (over points and stabilization)
    real_t worst = 0.0, spread = 0.0;
    auto cut_chunks = [&](index_t point_chunk)
    {
        bool local = true;
        worst = spread = 0.0;
        b.scatter.clear();
        b.scatter.node_begin = b.node_begin;
        b.scatter.node_end = b.node_end;
        b.n_point_chunks = 0;
        local = true;
        for (const IntegrationOperator* op : {&b.points, &b.stabilization})
        {
            // NSNI triplets run in their point's batch (nsni_batch): the point chunks cover their nodes
            if (op == &b.stabilization && b.stabilization_triplets)
                continue;
            // stabilization chunks cover as many nodes as stress-point chunks (about 8 sub-cells
            // per node)
            const index_t n = op->n_points();
            const index_t size = point_chunk * std::max<index_t>(1, np > 0 ? n / np : 1);
            const std::size_t added = b.scatter.add_chunks(
                n, size,
                [&](index_t first, index_t last, index_t& lo, index_t& hi)
                {
                    // NSNI's triplets run in their points' batches: their nodes too
                    if (op == &b.points && b.stabilization_triplets && !b.stab_triplets.empty())
                        for (index_t t = first; t < last; ++t)
                        {
                            const TripletView v = b.stab_triplets.view(t);
                            for (index_t k = 0; k < v.size; ++k)
                            {
                                lo = std::min(lo, v.base + v.offset[k]);
                                hi = std::max(hi, v.base + v.offset[k] + 1);
                            }
                        }
                    else if (op == &b.points && b.stabilization_triplets)
                        for (index_t k = b.stabilization.offsets[3 * first]; k < b.stabilization.offsets[3 * last]; ++k)
                        {
                            lo = std::min(lo, b.stabilization.nodes[k]);
                            hi = std::max(hi, b.stabilization.nodes[k] + 1);
                        }
                    auto touch = [&](index_t node)
                    {
                        RKFEM_REQUIRE(node >= b.node_begin && node < b.node_end,
                                      "nodal block: entry touches node " << node << " outside the part's range ["
                                                                         << b.node_begin << ", " << b.node_end << ")");
                        lo = std::min(lo, node);
                        hi = std::max(hi, node + 1);
                    };
                    if (op == &b.points && points_held)
                        for (index_t p = first; p < last; ++p)
                        {
                            const StencilView v = b.point_view(p);
                            for (index_t k = 0; k < v.size; ++k)
                                touch(v.base + v.offset[k]);
                        }
                    else
                        for (index_t k = op->offsets[first]; k < op->offsets[last]; ++k)
                            touch(op->nodes[k]);
                });
            if (op == &b.points)
                b.n_point_chunks = static_cast<index_t>(b.scatter.chunks.size());
            // a point order without locality (an imported cloud in random order) makes every
            // chunk's range the whole block: then the transpose gather
            local = local && ChunkedScatter::local(added, nn);
            const real_t per_node = static_cast<real_t>(added) / (4.0 * static_cast<real_t>(std::max<index_t>(nn, 1)));
            const std::size_t n_chunks =
                b.scatter.chunks.size() - (op == &b.points ? 0 : static_cast<std::size_t>(b.n_point_chunks));
            worst = std::max(worst, per_node);
            spread = std::max(spread, n_chunks > 0 ? per_node / static_cast<real_t>(n_chunks) : 0.0);
        }
        return local;
    };
    index_t point_chunk = ChunkedScatter::chunk_size(np, kPointLanes, 512);
    const bool local = ChunkedScatter::cut_until_local(point_chunk, std::max<index_t>(2048, np / 4), cut_chunks);
    // where no size gets down to 3 buffers per node, the last (largest) cut still scatters if it
    // takes at most 8 buffers per node and a chunk covers at most 3/4 of the block on average:
    // seed P5 at 1 in with RK regions (a 49 x 49 x 7 node slab numbered layer by layer, 2.2 h
    // stencils across two layers) ends at 4.6 and 6.1 buffers per node, chunks covering 58 and 68 %,
    // and its steps took 1.43 s for 90 against 2.04 s with the transpose gather (2 threads,
    // 2026-12-07); an order with no locality (a shuffled cloud) has every chunk cover the block
    const bool fallback = worst <= 8.0 && spread <= 0.75;
    const bool use_scatter = assembly == Assembly::Scatter || (assembly == Assembly::Automatic && (local || fallback));
    if (use_scatter)
        b.scatter.finish();
    else
    {
        b.scatter.clear();
        b.n_point_chunks = 0;
    }
    return use_scatter;
}

/// The transpose (node -> entries) for the gather assembly, which reads the sub-point entries.
void build_gather_transpose(NodalBlock& b, bool use_scatter, bool held_in_tables)
{
    const index_t np = b.n_points(), ns = b.n_stab(), nn = b.node_end - b.node_begin;
    b.node_entry_offsets.clear();
    b.node_point.clear();
    b.node_grad.clear();
    if (!use_scatter && held_in_tables)
        b.expand_operators();
    const index_t ne_p = b.points.n_entries(), ne_s = b.stabilization.n_entries();
    if (!use_scatter)
    {
        std::vector<index_t> entry_point(static_cast<std::size_t>(ne_p + ne_s));
        for (index_t p = 0; p < np; ++p)
            for (index_t k = b.points.offsets[p]; k < b.points.offsets[p + 1]; ++k)
                entry_point[k] = p;
        for (index_t s = 0; s < ns; ++s)
            for (index_t k = b.stabilization.offsets[s]; k < b.stabilization.offsets[s + 1]; ++k)
                entry_point[ne_p + k] = np + s;
        b.node_entry_offsets.assign(static_cast<std::size_t>(nn) + 1, 0);
        auto node_of = [&](index_t k) { return k < ne_p ? b.points.nodes[k] : b.stabilization.nodes[k - ne_p]; };
        for (index_t k = 0; k < ne_p + ne_s; ++k)
        {
            const index_t n = node_of(k);
            ++b.node_entry_offsets[n - b.node_begin + 1];
        }
        for (index_t i = 0; i < nn; ++i)
            b.node_entry_offsets[i + 1] += b.node_entry_offsets[i];
        b.node_point.resize(static_cast<std::size_t>(ne_p + ne_s));
        b.node_grad.resize(3 * static_cast<std::size_t>(ne_p + ne_s));
        std::vector<index_t> fill(b.node_entry_offsets.begin(), b.node_entry_offsets.end() - 1);
        for (index_t k = 0; k < ne_p + ne_s; ++k)
        {
            const index_t q = fill[node_of(k) - b.node_begin]++;
            b.node_point[q] = entry_point[k];
            const real_t* g = k < ne_p ? &b.points.grad[3 * static_cast<std::size_t>(k)]
                                       : &b.stabilization.grad[3 * static_cast<std::size_t>(k - ne_p)];
            for (int d = 0; d < 3; ++d)
                b.node_grad[3 * static_cast<std::size_t>(q) + d] = g[d];
        }
    }
}

/// The points each node owns (CSR).
void build_owner_lists(NodalBlock& b)
{
    const index_t np = b.n_points(), nn = b.node_end - b.node_begin;
    b.owner_offsets.assign(static_cast<std::size_t>(nn) + 1, 0);
    for (index_t p = 0; p < np; ++p)
        ++b.owner_offsets[b.points.owner[p] - b.node_begin + 1];
    for (index_t i = 0; i < nn; ++i)
        b.owner_offsets[i + 1] += b.owner_offsets[i];
    b.owner_points.resize(static_cast<std::size_t>(np));
    {
        std::vector<index_t> f(b.owner_offsets.begin(), b.owner_offsets.end() - 1);
        for (index_t p = 0; p < np; ++p)
            b.owner_points[f[b.points.owner[p] - b.node_begin]++] = p;
    }
}

/// The per-step scratch: Jacobians, the gather's point tensors, the stabilization's own pass's
/// F^-1 and spin, the batch sums.
void size_step_scratch(NodalBlock& b, bool use_scatter)
{
    const index_t np = b.n_points(), ns = b.n_stab();
    b.jacobian.assign(static_cast<std::size_t>(np), 1.0);
    b.point_tensor.assign(use_scatter ? 0 : 9 * static_cast<std::size_t>(np + ns), 0.0);
    // the parents' F^-1 and spin for the stabilization's own pass (NSNI with the chunked scatter
    // runs in the points' batches and needs neither)
    const bool own_stab_pass = ns > 0 && !(b.stabilization_triplets && use_scatter);
    b.finv.assign(own_stab_pass ? 9 * static_cast<std::size_t>(np) : 0, 0.0);
    b.spin.assign(own_stab_pass ? 3 * static_cast<std::size_t>(np) : 0, 0.0);
    const std::size_t nb = static_cast<std::size_t>((np + kPointLanes - 1) / kPointLanes);
    b.batch_sums.assign(4 * nb, 0.0);
    b.batch_idx.assign(2 * nb, -1);
    b.stab_energy.assign(own_stab_pass ? static_cast<std::size_t>(ns) : 0, 0.0);
    b.stab_share.assign(b.stab_plastic_scaling && ns > 0 && b.plastic.active() ? static_cast<std::size_t>(np) : 0, 1.0);
}
} // namespace

void NodalBlock::build_tables(Assembly assembly)
{
    // NSNI held as triplets alone (build_nsni_triplets, or an earlier build of a compact block)
    // stays so: the triplets are already shared, and the sub-point entries are formed only if
    // the gather assembly below needs them
    const bool held_as_triplets = stab_in_triplets && stabilization_triplets && options_.compact_operators;
    // the stress points held in shared stencils from the start (build_scni_rk's rows straight
    // into the table) stay so too: the table is the one share_stencils would find
    const bool points_held =
        points_in_table && options_.compact_operators && options_.share_stencils && !point_stencils.empty();
    stab_in_triplets = stab_in_triplets && !held_as_triplets;
    points_in_table = points_in_table && !points_held;
    expand_operators();
    stab_in_triplets = held_as_triplets;
    points_in_table = points_held;
    check_nsni_layout(*this, held_as_triplets);
    share_tables(*this, points_held, held_as_triplets, options_.share_stencils);
    const bool use_scatter = cut_scatter_chunks(*this, assembly, points_held);
    build_gather_transpose(*this, use_scatter, held_as_triplets || points_held);
    build_owner_lists(*this);
    size_step_scratch(*this, use_scatter);
    // the batches the force pass takes as whole vectors, and the order they add a stencil's
    // entries in (kernels/nodal_fast.hpp)
    auto batches = [](auto& table, const std::vector<index_t>& point_class, index_t n_classes)
    {
        table.uniform = uniform_batches(point_class, table.point_base, kPointLanes);
        table.add_order = uniform_add_order(table.offsets, table.node_offset, kPointLanes,
                                            uniform_batch_stencils(table.uniform, point_class, n_classes, kPointLanes));
    };
    batches(point_stencils, point_stencils.point_stencil, point_stencils.n_stencils());
    batches(stab_triplets, stab_triplets.point_triplet, stab_triplets.n_triplets());
    if (options_.compact_operators && !point_stencils.empty())
    {
        release_entries(points);
        points_in_table = true;
    }
    // NSNI in the points' batches reads the triplets (52 bytes per entry for 84); the gather
    // assembly's own pass reads the (snapped) operator and its transposes
    if (!use_scatter)
        stab_triplets.clear();
    // prefetch_points' rule: the bytes the pass streams per step from each table
    {
        const std::size_t point_bytes =
            point_stencils.empty() ? points.nodes.size() * (sizeof(index_t) + 3 * sizeof(real_t)) : 0;
        const std::size_t triplet_bytes = stab_triplets.node_offset.size() * (sizeof(index_t) + 6 * sizeof(real_t));
        const bool streams = point_bytes + triplet_bytes > prefetch_bytes;
        options_.prefetch_points = streams && point_bytes > (std::size_t{1} << 20);
        options_.prefetch_triplets = streams && triplet_bytes > (std::size_t{1} << 20);
    }
    if (options_.compact_operators && !stab_triplets.empty())
    {
        release_entries(stabilization);
        // NSNI's sub-points sit at their parents (the checks above hold the layout); nothing in
        // the step reads their positions: 72 bytes per particle, written back by expand_operators
        std::vector<real_t>().swap(stabilization.position);
        stab_in_triplets = true;
    }
    else if (options_.compact_operators && !stab_stencils.empty())
    {
        release_entries(stabilization);
        stab_in_table = true;
    }
    for (IntegrationOperator* op : {&points, &stabilization})
    {
        use_huge_pages(op->nodes);
        use_huge_pages(op->grad);
        use_huge_pages(op->weight);
    }
    for (auto* a : {&node_grad, &jacobian, &point_tensor, &finv, &spin, &stab_energy, &length0})
        use_huge_pages(*a);
    use_huge_pages(node_point);
}
} // namespace rkfem
