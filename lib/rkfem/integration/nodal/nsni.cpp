/// @file nsni.cpp
/// Naturally stabilized nodal integration (NSNI): the gradients' Taylor terms at three
/// sub-points per particle, as an operator or as shared triplets.
#include "rkfem/integration/nodal/nodal_common.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <utility>

#include <omp.h>

#include "rkfem/approximation/rk/rk_region_values.hpp"
#include "rkfem/approximation/rk/rk_translates.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/core/mark_set.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/setup_progress.hpp"
#include "rkfem/integration/stencil_table.hpp"

namespace rkfem
{
using namespace nodal_detail;

RkTranslates particle_translates(const RkShapeFunctions& rk, bool share)
{
    const Vec3 reach = RkRegionValues::hessian_reach(rk);
    return find_rk_translates(
        rk, rk.size(),
        [&](index_t p, Vec3& lo, Vec3& hi, Vec3& ref, std::vector<real_t>&)
        {
            ref = rk.position(p);
            lo = ref - reach;
            hi = ref + reach;
        },
        share);
}

IntegrationOperator build_nsni_stabilization(const IntegrationOperator& points, const RkShapeFunctions& rk,
                                             const std::vector<real_t>& moments, real_t drop_tolerance,
                                             bool share_translates)
{
    return build_nsni_stabilization(points, rk, moments, drop_tolerance, particle_translates(rk, share_translates));
}

namespace
{
/// NSNI's matrices at the source particles (particle_translates): per source its nodes and the
/// six distinct values of each node's symmetric matrix (00, 01, 02, 11, 12, 22), in one store
/// reserved at the sources' region sizes (a bound on their entries: memory reserved and never
/// written costs no page). Sources go in blocks of 1024: each block's lists (per source: its
/// nodes and their matrices, 76 bytes per entry) are packed into the store (52 bytes per entry)
/// before the next block is evaluated, so the set-up holds the store and one block's lists,
/// whose storage is reused.
class NsniSources
{
  public:
    NsniSources(const IntegrationOperator& points, const RkShapeFunctions& rk, const std::vector<real_t>& moments,
                real_t drop_tolerance, const RkTranslates& translates)
        : translates_(translates), source_index_(static_cast<std::size_t>(points.n_points()), -1)
    {
        const index_t np = points.n_points();
        RKFEM_REQUIRE(moments.size() == 3 * static_cast<std::size_t>(np),
                      "NSNI: " << moments.size() << " second moments for " << np << " points");
        RKFEM_REQUIRE(translates.size() == rk.size() && np == rk.size(),
                      "NSNI: " << np << " points and " << translates.size() << " particle neighbourhoods for "
                               << rk.size() << " particles");
        std::vector<index_t> sources, served(static_cast<std::size_t>(np), 0);
        for (index_t p = 0; p < np; ++p)
        {
            RKFEM_REQUIRE(points.owner[p] == p,
                          "NSNI: point " << p << " is not at particle " << p << " (node-ordered points)");
            ++served[translates.source[p]];
            if (translates.computed(p))
            {
                source_index_[p] = static_cast<index_t>(sources.size());
                sources.push_back(p);
            }
        }
        // room for the entries: the first block's own at their exact count, then, from the
        // share of its region particles it kept, the others' with a margin of 1/16 (the sharing
        // keeps the table when at most that is spare: a jittered cloud's table is not copied
        // once more to shed the region sizes' bound, 150 MB at 24k particles)
        std::vector<std::size_t> bound_from(sources.size() + 1, 0); // region particles of sources [k, end)
        for (std::size_t k = sources.size(); k-- > 0;)
            bound_from[k] = bound_from[k + 1] + static_cast<std::size_t>(translates.region_size(sources[k]));
        offsets_.reserve(sources.size() + 1);
        const std::size_t n_blocks = (sources.size() + kBlock - 1) / kBlock;
        const std::size_t nl = std::min(sources.size(), kBlock);
        std::vector<std::vector<index_t>> nodes(nl);
        std::vector<std::vector<Mat3>> hess(nl);
        ParallelErrors errors;
        bool failed = false;
#pragma omp parallel
        {
            // the particles near each point gathered once for its six gradient evaluations
            // (RkRegionValues::hessians; RkShapeFunctions::hessians is its plain twin)
            RkRegionValues region(rk, 0.0);
            for (std::size_t b = 0; b < n_blocks && !failed; ++b)
            {
                const std::size_t k0 = b * kBlock, k1 = std::min(sources.size(), k0 + kBlock);
#pragma omp for schedule(dynamic, 64)
                for (std::size_t k = k0; k < k1; ++k)
                {
                    const index_t p = sources[k];
                    try
                    {
                        std::vector<index_t>& n = nodes[k - k0];
                        std::vector<Mat3>& h = hess[k - k0];
                        const Vec3 x = rk.position(p);
                        region.hessians(x, translates.region(p), static_cast<std::size_t>(translates.region_size(p)), n,
                                        h);
                        if (drop_tolerance > 0.0)
                            prune_rk_hessians(rk, x, drop_tolerance, n, h);
                        setup_progress::advance(served[p]);
                    }
                    catch (...)
                    {
                        errors.capture();
#pragma omp atomic write
                        failed = true;
                    }
                }
                // (the loop's barrier: every list of the block is written, `failed` is seen)
#pragma omp single
                if (!failed)
                {
                    try // (an allocation that fails is the builder's error, not the team's)
                    {
                        if (b == 1 || (b == 0 && n_blocks == 1))
                        {
                            // the kept share of the region particles so far (block 0), applied to the rest
                            const std::size_t so_far = nodes_.size(), regions = bound_from[0] - bound_from[k0];
                            std::size_t expect = 0;
                            for (std::size_t k = k0; k < k1; ++k)
                                expect += nodes[k - k0].size();
                            if (regions > 0)
                            {
                                const std::size_t rest = static_cast<std::size_t>(static_cast<double>(bound_from[k1]) *
                                                                                  static_cast<double>(so_far) /
                                                                                  static_cast<double>(regions));
                                expect += rest + rest / 16;
                            }
                            nodes_.reserve(so_far + expect);
                            h_.reserve(6 * (so_far + expect));
                        }
                        for (std::size_t k = k0; k < k1; ++k)
                        {
                            nodes_.insert(nodes_.end(), nodes[k - k0].begin(), nodes[k - k0].end());
                            for (const Mat3& m : hess[k - k0]) // symmetric bit for bit (hessians, prune)
                                h_.insert(h_.end(), {m(0, 0), m(0, 1), m(0, 2), m(1, 1), m(1, 2), m(2, 2)});
                            offsets_.push_back(static_cast<index_t>(nodes_.size()));
                        }
                    }
                    catch (...)
                    {
                        errors.capture();
                        failed = true;
                    }
                }
            }
        }
        errors.rethrow();
    }

    /// Point p's entries, its source's: their count, the source's nodes and their six values each.
    index_t entries(index_t p, const index_t*& nodes, const real_t*& h) const
    {
        const std::size_t k = static_cast<std::size_t>(source_index_[translates_.source[p]]);
        const index_t j0 = offsets_[k];
        nodes = nodes_.data() + j0;
        h = h_.data() + 6 * static_cast<std::size_t>(j0);
        return offsets_[k + 1] - j0;
    }

    /// The sub-points' frame: 3 p + i of point p with p's count of entries, weight moments[3 p + i],
    /// owner and parent p; positions and entries left to the caller.
    IntegrationOperator frame(const IntegrationOperator& points, const std::vector<real_t>& moments) const
    {
        const index_t np = points.n_points();
        const std::size_t ns = 3 * static_cast<std::size_t>(np);
        IntegrationOperator op;
        op.offsets.assign(ns + 1, 0);
        op.owner.resize(ns);
        op.parent.resize(ns);
        for (index_t p = 0; p < np; ++p)
        {
            const index_t* n;
            const real_t* h;
            const index_t count = entries(p, n, h);
            for (std::size_t q = 3 * static_cast<std::size_t>(p); q < 3 * static_cast<std::size_t>(p) + 3; ++q)
            {
                op.offsets[q + 1] = op.offsets[q] + count;
                op.owner[q] = points.owner[p];
                op.parent[q] = p;
            }
        }
        op.weight = moments;
        return op;
    }

    /// The store as a triplet table (its storage moved, not copied): one stencil per source,
    /// relative to its first node, which a point reads from the first node of its own particles
    /// where they are its source's plus one number; any other point gets its own copy with its
    /// own particles (appended). The store is empty afterwards.
    TripletTable into_triplets()
    {
        const index_t np = static_cast<index_t>(source_index_.size());
        TripletTable t;
        t.point_triplet.resize(static_cast<std::size_t>(np));
        t.point_base.resize(static_cast<std::size_t>(np));
        for (index_t p = 0; p < np; ++p)
        {
            const std::size_t k = static_cast<std::size_t>(source_index_[translates_.source[p]]);
            const index_t j0 = offsets_[k], count = offsets_[k + 1] - j0;
            t.point_base[p] = count == 0 ? 0 : translates_.counterpart(p, nodes_[static_cast<std::size_t>(j0)]);
            if (translates_.computed(p) || translates_.shift[p] != RkTranslates::kNoShift)
            {
                t.point_triplet[p] = static_cast<index_t>(k);
                continue;
            }
            for (index_t j = j0; j < j0 + count; ++j)
            {
                nodes_.push_back(translates_.counterpart(p, nodes_[static_cast<std::size_t>(j)]));
                real_t h[6];
                std::copy_n(h_.begin() + 6 * static_cast<std::ptrdiff_t>(j), 6, h);
                h_.insert(h_.end(), h, h + 6);
            }
            t.point_triplet[p] = static_cast<index_t>(offsets_.size()) - 1;
            offsets_.push_back(static_cast<index_t>(nodes_.size()));
        }
        // every stencil relative to its first node, in place
        for (std::size_t k = 0; k + 1 < offsets_.size(); ++k)
            for (index_t j = offsets_[k + 1] - 1; j >= offsets_[k]; --j)
                nodes_[static_cast<std::size_t>(j)] -= nodes_[static_cast<std::size_t>(offsets_[k])];
        t.offsets = std::move(offsets_);
        t.node_offset = std::move(nodes_);
        t.hess = std::move(h_);
        return t;
    }

  private:
    static constexpr std::size_t kBlock = 1024;
    const RkTranslates& translates_;
    std::vector<index_t> source_index_;
    std::vector<index_t> offsets_{0}, nodes_; // per source k: entries offsets_[k] .. offsets_[k + 1]
    std::vector<real_t> h_;                   // 6 per entry
};
} // namespace

IntegrationOperator build_nsni_stabilization(const IntegrationOperator& points, const RkShapeFunctions& rk,
                                             const std::vector<real_t>& moments, real_t drop_tolerance,
                                             const RkTranslates& translates)
{
    const NsniSources sources(points, rk, moments, drop_tolerance, translates);
    // sub-points 3 p + i of point p, each with p's nodes and row i of each entry's matrix,
    // allocated once at their exact size and filled in parallel; a point that takes its source's
    // matrices reads them with its particles matched to the source's
    IntegrationOperator op = sources.frame(points, moments);
    const index_t np = points.n_points();
    op.position.resize(9 * static_cast<std::size_t>(np));
    op.nodes.resize(static_cast<std::size_t>(op.offsets.back()));
    op.grad.resize(3 * op.nodes.size());
    parallel_for(
        "rkfem::build_nsni_stabilization::fill", np,
        [&](index_t p)
        {
            static constexpr int kSym[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}}; // (i, d) in 00, 01, 02, 11, 12, 22
            const index_t* n;
            const real_t* h;
            const index_t count = sources.entries(p, n, h);
            const bool own = translates.computed(p);
            for (int i = 0; i < 3; ++i)
            {
                const std::size_t q = 3 * static_cast<std::size_t>(p) + static_cast<std::size_t>(i);
                for (int d = 0; d < 3; ++d)
                    op.position[3 * q + d] = points.position[3 * static_cast<std::size_t>(p) + d];
                const std::size_t k0 = static_cast<std::size_t>(op.offsets[q]);
                for (index_t j = 0; j < count; ++j)
                {
                    const std::size_t k = k0 + static_cast<std::size_t>(j);
                    op.nodes[k] = own ? n[j] : i == 0 ? translates.counterpart(p, n[j]) : op.nodes[k - count];
                    for (int d = 0; d < 3; ++d)
                        op.grad[3 * k + d] = h[6 * static_cast<std::size_t>(j) + kSym[i][d]];
                }
            }
        });
    return op;
}

NsniTriplets build_nsni_triplets(const IntegrationOperator& points, const RkShapeFunctions& rk,
                                 const std::vector<real_t>& moments, real_t drop_tolerance,
                                 const RkTranslates& translates)
{
    NsniSources sources(points, rk, moments, drop_tolerance, translates);
    NsniTriplets out;
    out.frame = sources.frame(points, moments);
    out.table = share_triplets(sources.into_triplets());
    return out;
}

} // namespace rkfem
