#include "rkfem/operators/nodal_block.hpp"

#include <algorithm>
#include <cmath>
#include <immintrin.h>
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

void NodalBlock::build_tables(Assembly assembly)
{
    // NSNI held as triplets alone (build_nsni_triplets, or an earlier build of a compact block)
    // stays so: the triplets are already shared, and the sub-point entries are formed only if
    // the gather assembly below needs them
    const bool held_as_triplets = stab_in_triplets && stabilization_triplets && options.compact_operators;
    // the stress points held in shared stencils from the start (build_scni_rk's rows straight
    // into the table) stay so too: the table is the one share_stencils would find
    const bool points_held =
        points_in_table && options.compact_operators && options.share_stencils && !point_stencils.empty();
    stab_in_triplets = stab_in_triplets && !held_as_triplets;
    points_in_table = points_in_table && !points_held;
    expand_operators();
    stab_in_triplets = held_as_triplets;
    points_in_table = points_held;
    const index_t np = n_points(), ns = n_stab();
    const index_t nn = node_end - node_begin;

    if (stabilization_triplets && held_as_triplets)
        RKFEM_REQUIRE(ns == 3 * np && stab_triplets.point_triplet.size() == static_cast<std::size_t>(np),
                      "nodal block: " << ns << " NSNI sub-points and " << stab_triplets.point_triplet.size()
                                      << " triplets for " << np << " points");
    else if (stabilization_triplets)
    {
        // NSNI's layout (build_nsni_stabilization): sub-points 3 p + i of parent p, with one node list
        RKFEM_REQUIRE(ns == 3 * np, "nodal block: " << ns << " NSNI sub-points for " << np << " points");
        for (index_t t = 0; t < np; ++t)
        {
            const index_t k0 = stabilization.offsets[3 * t], n = stabilization.offsets[3 * t + 1] - k0;
            for (int i = 0; i < 3; ++i)
            {
                const index_t ki = stabilization.offsets[3 * t + i];
                RKFEM_REQUIRE(stabilization.parent[3 * t + i] == t && stabilization.offsets[3 * t + i + 1] - ki == n &&
                                  std::equal(stabilization.nodes.begin() + k0, stabilization.nodes.begin() + k0 + n,
                                             stabilization.nodes.begin() + ki),
                              "nodal block: NSNI sub-point " << 3 * t + i << " does not share the nodes of its point "
                                                             << t);
            }
        }
    }
    // shared stencils first: they snap the operators' gradients, which the transpose copies
    if (!points_held)
        point_stencils.clear();
    stab_stencils.clear();
    if (options.share_stencils)
    {
        if (!points_held)
            point_stencils = rkfem::share_stencils(points);
        if (!held_as_triplets)
            stab_stencils = rkfem::share_stencils(stabilization);
    }
    // NSNI's triplets: per entry the six values the pass reads. They snap the operator, as
    // shared stencils do (whose sub-points, snapped one class at a time, differ from symmetry by
    // up to the sharing's tolerance), so that every reader, the transposes below included, sees
    // one symmetric operator; they replace the sub-points' shared stencils.
    if (!held_as_triplets)
    {
        stab_triplets.clear();
        if (stabilization_triplets)
            stab_triplets = build_triplets(stabilization, stab_stencils);
        if (!stab_triplets.empty())
        {
            stab_stencils.clear();
            expand_triplets(stabilization, stab_triplets);
        }
    }

    // chunked scatter: fixed chunks of stress points, then of stabilization points, each with
    // the node range its entries touch. About n / 16 stress points per chunk (at least 512) first,
    // so that a part of a few thousand particles has work for every thread; where their node
    // ranges overlap too much (the reduce would sum over more than 3 buffers per node: small
    // lattices with wide supports, a mesh numbered column by column, whose chunks are thin
    // bundles of columns with a wide halo), chunks twice as large, and so on up to 2048 points
    // or a quarter of the block, whichever is larger (a random order stays non-local at every
    // size that leaves the threads chunks to share: the transpose gather then). Either way the
    // chunks are a function of the operators only, never of the thread count.
    auto cut_chunks = [&](index_t point_chunk)
    {
        bool local = true;
        scatter.clear();
        scatter.node_begin = node_begin;
        scatter.node_end = node_end;
        n_point_chunks = 0;
        local = true;
        for (const IntegrationOperator* op : {&points, &stabilization})
        {
            // NSNI triplets run in their point's batch (nsni_batch): the point chunks cover their nodes
            if (op == &stabilization && stabilization_triplets)
                continue;
            // stabilization chunks cover as many nodes as stress-point chunks (about 8 sub-cells
            // per node)
            const index_t n = op->n_points();
            const index_t size = point_chunk * std::max<index_t>(1, np > 0 ? n / np : 1);
            const std::size_t added = scatter.add_chunks(
                n, size,
                [&](index_t first, index_t last, index_t& lo, index_t& hi)
                {
                    // NSNI's triplets run in their points' batches: their nodes too
                    if (op == &points && stabilization_triplets && !stab_triplets.empty())
                        for (index_t t = first; t < last; ++t)
                        {
                            const TripletView v = stab_triplets.view(t);
                            for (index_t k = 0; k < v.size; ++k)
                            {
                                lo = std::min(lo, v.base + v.offset[k]);
                                hi = std::max(hi, v.base + v.offset[k] + 1);
                            }
                        }
                    else if (op == &points && stabilization_triplets)
                        for (index_t k = stabilization.offsets[3 * first]; k < stabilization.offsets[3 * last]; ++k)
                        {
                            lo = std::min(lo, stabilization.nodes[k]);
                            hi = std::max(hi, stabilization.nodes[k] + 1);
                        }
                    auto touch = [&](index_t node)
                    {
                        RKFEM_REQUIRE(node >= node_begin && node < node_end,
                                      "nodal block: entry touches node " << node << " outside the part's range ["
                                                                         << node_begin << ", " << node_end << ")");
                        lo = std::min(lo, node);
                        hi = std::max(hi, node + 1);
                    };
                    if (op == &points && points_held)
                        for (index_t p = first; p < last; ++p)
                        {
                            const StencilView v = point_view(p);
                            for (index_t k = 0; k < v.size; ++k)
                                touch(v.base + v.offset[k]);
                        }
                    else
                        for (index_t k = op->offsets[first]; k < op->offsets[last]; ++k)
                            touch(op->nodes[k]);
                });
            if (op == &points)
                n_point_chunks = static_cast<index_t>(scatter.chunks.size());
            // a point order without locality (an imported cloud in random order) makes every
            // chunk's range the whole block: then the transpose gather
            local = local && ChunkedScatter::local(added, nn);
        }
        return local;
    };
    index_t point_chunk = ChunkedScatter::chunk_size(np, kPointLanes, 512);
    const bool local = ChunkedScatter::cut_until_local(point_chunk, std::max<index_t>(2048, np / 4), cut_chunks);
    const bool use_scatter = assembly == Assembly::Scatter || (assembly == Assembly::Automatic && local);
    if (use_scatter)
        scatter.finish();
    else
    {
        scatter.clear();
        n_point_chunks = 0;
    }
    // transpose (node -> entries) for the gather assembly, which reads the sub-point entries
    node_entry_offsets.clear();
    node_point.clear();
    node_grad.clear();
    if (!use_scatter && (held_as_triplets || points_held))
        expand_operators();
    const index_t ne_p = points.n_entries(), ne_s = stabilization.n_entries();
    if (!use_scatter)
    {
        std::vector<index_t> entry_point(static_cast<std::size_t>(ne_p + ne_s));
        for (index_t p = 0; p < np; ++p)
            for (index_t k = points.offsets[p]; k < points.offsets[p + 1]; ++k)
                entry_point[k] = p;
        for (index_t s = 0; s < ns; ++s)
            for (index_t k = stabilization.offsets[s]; k < stabilization.offsets[s + 1]; ++k)
                entry_point[ne_p + k] = np + s;
        node_entry_offsets.assign(static_cast<std::size_t>(nn) + 1, 0);
        auto node_of = [&](index_t k) { return k < ne_p ? points.nodes[k] : stabilization.nodes[k - ne_p]; };
        for (index_t k = 0; k < ne_p + ne_s; ++k)
        {
            const index_t n = node_of(k);
            ++node_entry_offsets[n - node_begin + 1];
        }
        for (index_t i = 0; i < nn; ++i)
            node_entry_offsets[i + 1] += node_entry_offsets[i];
        node_point.resize(static_cast<std::size_t>(ne_p + ne_s));
        node_grad.resize(3 * static_cast<std::size_t>(ne_p + ne_s));
        std::vector<index_t> fill(node_entry_offsets.begin(), node_entry_offsets.end() - 1);
        for (index_t k = 0; k < ne_p + ne_s; ++k)
        {
            const index_t q = fill[node_of(k) - node_begin]++;
            node_point[q] = entry_point[k];
            const real_t* g = k < ne_p ? &points.grad[3 * static_cast<std::size_t>(k)]
                                       : &stabilization.grad[3 * static_cast<std::size_t>(k - ne_p)];
            for (int d = 0; d < 3; ++d)
                node_grad[3 * static_cast<std::size_t>(q) + d] = g[d];
        }
    }

    owner_offsets.assign(static_cast<std::size_t>(nn) + 1, 0);
    for (index_t p = 0; p < np; ++p)
        ++owner_offsets[points.owner[p] - node_begin + 1];
    for (index_t i = 0; i < nn; ++i)
        owner_offsets[i + 1] += owner_offsets[i];
    owner_points.resize(static_cast<std::size_t>(np));
    {
        std::vector<index_t> f(owner_offsets.begin(), owner_offsets.end() - 1);
        for (index_t p = 0; p < np; ++p)
            owner_points[f[points.owner[p] - node_begin]++] = p;
    }

    jacobian.assign(static_cast<std::size_t>(np), 1.0);
    point_tensor.assign(use_scatter ? 0 : 9 * static_cast<std::size_t>(np + ns), 0.0);
    // the parents' F^-1 and spin for the stabilization's own pass (NSNI with the chunked scatter
    // runs in the points' batches and needs neither)
    const bool own_stab_pass = ns > 0 && !(stabilization_triplets && use_scatter);
    finv.assign(own_stab_pass ? 9 * static_cast<std::size_t>(np) : 0, 0.0);
    spin.assign(own_stab_pass ? 3 * static_cast<std::size_t>(np) : 0, 0.0);
    const std::size_t nb = static_cast<std::size_t>((np + kPointLanes - 1) / kPointLanes);
    batch_sums.assign(4 * nb, 0.0);
    batch_idx.assign(2 * nb, -1);
    stab_energy.assign(own_stab_pass ? static_cast<std::size_t>(ns) : 0, 0.0);

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
    if (options.compact_operators && !point_stencils.empty())
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
        options.prefetch_points = streams && point_bytes > (std::size_t{1} << 20);
        options.prefetch_triplets = streams && triplet_bytes > (std::size_t{1} << 20);
    }
    if (options.compact_operators && !stab_triplets.empty())
    {
        release_entries(stabilization);
        // NSNI's sub-points sit at their parents (the checks above hold the layout); nothing in
        // the step reads their positions: 72 bytes per particle, written back by expand_operators
        std::vector<real_t>().swap(stabilization.position);
        stab_in_triplets = true;
    }
    else if (options.compact_operators && !stab_stencils.empty())
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
