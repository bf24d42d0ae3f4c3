/// @file scni_rk_mesh.cpp
/// SCNI and its sub-cells on hex-dual cells for RK shape functions: facet sums per element over
/// its region, rows merged by particle in a fixed order.
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

namespace
{
/// An element's facet sums over its region: list a (local node a's row, then with sub-cells
/// sub-hex a's as list 8 + a) holds the region slots slot[start[a] .. start[a + 1]) its facets
/// hit, ascending, and their sums g (3 per entry) of psi n dA.
struct FacetSums
{
    std::array<index_t, 17> start{};
    std::vector<index_t> slot;
    std::vector<real_t> g;
};

/// Appends the entries of a dense partial row (sums (acc[k], acc[n + k], acc[2 n + k]) over the
/// region's n slots, present where hit[k] != 0) to `into`.
void append_partial_row(FacetSums& into, std::size_t n, const real_t* acc, const real_t* hit)
{
    for (std::size_t k = 0; k < n; ++k)
        if (hit[k] != 0.0)
        {
            into.slot.push_back(static_cast<index_t>(k));
            into.g.insert(into.g.end(), {acc[k], acc[n + k], acc[2 * n + k]});
        }
}

/// partner[a][d]: the local node across natural direction d from node a (the sub-hex that shares
/// a's internal facet f = 2 d).
struct FacetPartners
{
    int partner[8][3];
    FacetPartners()
    {
        for (int a = 0; a < 8; ++a)
            for (int d = 0; d < 3; ++d)
                for (int b = 0; b < 8; ++b)
                {
                    bool across = true;
                    for (int c = 0; c < 3; ++c)
                        across = across && (c == d ? hex8_nodes[b][c] == -hex8_nodes[a][c]
                                                   : hex8_nodes[b][c] == hex8_nodes[a][c]);
                    if (across)
                        partner[a][d] = b;
                }
    }
};

/// The facet sums of one element over its region (values: gathered on it): each internal facet
/// once for the pair of sub-hexes it separates, external facets for the node rows where the
/// element face is on the boundary and for the sub-cells always (with_sub).
class ElementFacetSums
{
  public:
    ElementFacetSums(const RkShapeFunctions& rk, real_t drop_tolerance) : values_(rk, drop_tolerance) {}

    RkRegionValues& values() { return values_; }

    void compute(const real_t (&xe)[8][3], const bool boundary_face[6], bool with_sub, FacetSums& out)
    {
        static const FacetPartners facets;
        const std::size_t nr = values_.region_size();
        acc_.assign(8 * 3 * nr, 0.0);
        hit_.assign(8 * nr, 0.0);
        if (with_sub)
        {
            sub_acc_.assign(8 * 3 * nr, 0.0);
            sub_hit_.assign(8 * nr, 0.0);
        }
        for (int a = 0; a < 8; ++a)
            for (int d = 0; d < 3; ++d)
            {
                // the internal facet, once for the pair of sub-hexes it separates (the partner's
                // facet has the same points and the opposite normal)
                const int b = facets.partner[a][d];
                if (a < b)
                {
                    build_sub_hex_facet(xe, a, 2 * d, points_);
                    add_facet(a, b, true, with_sub);
                }
                // the external facet: the node's row where the element face is on the boundary
                // (inside, it is interior to the nodal cell), the sub-cell's always
                const bool boundary = boundary_face[sub_hex_element_face(a, 2 * d + 1)];
                if (boundary || with_sub)
                {
                    build_sub_hex_facet(xe, a, 2 * d + 1, points_);
                    add_facet(a, -1, boundary, with_sub);
                }
            }
        out.slot.clear();
        out.g.clear();
        // room for every entry at once (a source's sums are built once and kept until the rows
        // merge: grown by doubling they were copied about ten times, into fresh pages)
        std::size_t entries = 0;
        for (std::size_t k = 0; k < 8 * nr; ++k)
            entries += hit_[k] != 0.0;
        if (with_sub)
            for (std::size_t k = 0; k < 8 * nr; ++k)
                entries += sub_hit_[k] != 0.0;
        out.slot.reserve(entries);
        out.g.reserve(3 * entries);
        for (int a = 0; a < 16; ++a)
        {
            out.start[a] = static_cast<index_t>(out.slot.size());
            if (a < 8)
                append_partial_row(out, nr, acc_.data() + 3 * nr * a, hit_.data() + nr * a);
            else if (with_sub)
                append_partial_row(out, nr, sub_acc_.data() + 3 * nr * (a - 8), sub_hit_.data() + nr * (a - 8));
        }
        out.start[16] = static_cast<index_t>(out.slot.size());
    }

  private:
    // sum over a facet's 4 points of psi n dA into the rows of local nodes a (+) and b (-, the
    // sub-hex across an internal facet, whose normal is the opposite; b < 0: none) where
    // node_rows, and of their sub-hexes with_sub
    void add_facet(int a, int b, bool node_rows, bool with_sub)
    {
        Vec3 lo = points_[0].x, hi = points_[0].x;
        for (const FacetPoint& fp : points_)
        {
            lo = lo.cwiseMin(fp.x);
            hi = hi.cwiseMax(fp.x);
        }
        values_.focus(lo, hi);
        const std::size_t n = values_.size();
        facet_sum_.assign(3 * n, 0.0);
        facet_hit_.assign(n, 0.0);
        real_t *f0 = facet_sum_.data(), *f1 = f0 + n, *f2 = f1 + n, *fh = facet_hit_.data();
        for (const FacetPoint& fp : points_)
            add_point_values(values_, fp.x, fp.nda, f0, fh);
        const std::size_t nr = values_.region_size();
        const index_t* slot = values_.slots().data();
        auto scatter = [&](std::vector<real_t>& into, std::vector<real_t>& into_hit, int node, real_t sign)
        {
            real_t* g = into.data() + 3 * nr * static_cast<std::size_t>(node);
            real_t* h = into_hit.data() + nr * static_cast<std::size_t>(node);
            for (std::size_t k = 0; k < n; ++k)
            {
                const std::size_t r = static_cast<std::size_t>(slot[k]);
                g[r] += sign * f0[k];
                g[nr + r] += sign * f1[k];
                g[2 * nr + r] += sign * f2[k];
                h[r] = h[r] < fh[k] ? fh[k] : h[r];
            }
        };
        for (const auto& [node, sign] : {std::pair{a, 1.0}, std::pair{b, -1.0}})
        {
            if (node < 0)
                continue;
            if (node_rows)
                scatter(acc_, hit_, node, sign);
            if (with_sub)
                scatter(sub_acc_, sub_hit_, node, sign);
        }
    }

    RkRegionValues values_;
    // per local node a: sum psi n dA [a][component][region slot], hit [a][region slot] (0 / 1);
    // the same per sub-hex a over all six facets (with_sub); per facet: over its candidates
    std::vector<real_t> acc_, hit_, sub_acc_, sub_hit_, facet_sum_, facet_hit_;
    std::array<FacetPoint, 4> points_;
};
/// A node's SCNI row from its sub-hexes' partial rows (lists, each ascending in particle), merged
/// by particle: each particle's terms added in the lists' order (their elements' colours: a
/// fixed order, so the same bits on any number of threads), the row in ascending particle
/// order. The particles a row touches are marked in a bitmap over all particles and their sums
/// held densely, so a row costs its lists' entries, not entries times lists as a k-way merge
/// does; the marks are clear again between rows. One per thread.
class RowMerger
{
  public:
    struct List
    {
        index_t colour, begin, end; ///< entries [begin, end) of the sums
        const index_t *ids, *slot;  ///< entry k's particle: ids[slot[k]]
        const real_t* g;            ///< entry k's three sums: g[3 k .. 3 k + 2]
    };

    explicit RowMerger(index_t n_particles) : sum_(3 * static_cast<std::size_t>(n_particles))
    {
        marks_.reserve(static_cast<std::size_t>(n_particles));
    }

    /// The number of distinct particles in the lists.
    index_t count(const std::vector<List>& lists)
    {
        for (const List& l : lists)
            for (index_t k = l.begin; k < l.end; ++k)
                marks_.insert(l.ids[l.slot[k]]);
        return marks_.drain_count();
    }

    /// Writes the merged row, each sum times `scale`: particles to nodes, sums to grad (3 each).
    void merge(const std::vector<List>& lists, real_t scale, index_t* nodes, real_t* grad)
    {
        for (const List& l : lists)
            for (index_t k = l.begin; k < l.end; ++k)
            {
                const index_t id = l.ids[l.slot[k]];
                const real_t* g = l.g + 3 * static_cast<std::size_t>(k);
                real_t* s = sum_.data() + 3 * static_cast<std::size_t>(id);
                if (marks_.insert(id))
                    for (int d = 0; d < 3; ++d)
                        s[d] = g[d];
                else
                    for (int d = 0; d < 3; ++d)
                        s[d] += g[d];
            }
        std::size_t k = 0;
        marks_.drain(
            [&](index_t id)
            {
                nodes[k] = id;
                for (int d = 0; d < 3; ++d)
                    grad[3 * k + d] = sum_[3 * static_cast<std::size_t>(id) + static_cast<std::size_t>(d)] * scale;
                ++k;
            });
    }

  private:
    MarkSet marks_;
    std::vector<real_t> sum_;
};

/// build_scni_rk's phases and what they share: the elements' translates and the sources' facet
/// sums, the sub-hexes' volumes (with sd the sub-cells' rows), the nodes' sub-hexes, the elements'
/// colours, and the operator `op` the phases fill.
struct ScniRkWork
{
    ScniRkWork(const HexMesh& m, const RkShapeFunctions& r, IntegrationOperator* s, IntegrationOperator& o)
        : mesh(m), rk(r), sd(s), op(o)
    {
    }

    const HexMesh& mesh;
    const RkShapeFunctions& rk;
    IntegrationOperator* const sd;
    IntegrationOperator& op;
    const std::vector<index_t> nb = face_neighbours(mesh);
    const index_t nn = mesh.n_nodes(), ne = mesh.n_elements();
    RkTranslates translates;
    std::vector<index_t> sources, served, sums_of;
    std::vector<FacetSums> sums;
    std::vector<real_t> slot_volume;
    std::size_t n_sub = 0;
    std::vector<Entries> sub_rows;
    std::vector<real_t> sub_position;
    std::vector<index_t> sub_owner;
    std::vector<index_t> inc_offsets, slots, colour_of;

    /// The elements' translates, the sources among them and the count of elements each serves.
    void find_sources(bool share_translates)
    {
        // The region of an element: the particles whose supports reach its box (a trilinear element
        // lies in its nodes' box). Elements whose regions, shapes and boundary faces are translates
        // of an earlier element's take its facet sums (RkTranslates).
        auto frame = [&](index_t e, Vec3& lo, Vec3& hi, Vec3& ref, std::vector<real_t>& own)
        {
            real_t xe[8][3];
            element_coordinates(mesh, e, xe);
            lo = hi = ref = Vec3(xe[0][0], xe[0][1], xe[0][2]);
            for (int a = 1; a < 8; ++a)
                for (int d = 0; d < 3; ++d)
                {
                    lo[d] = std::min(lo[d], xe[a][d]);
                    hi[d] = std::max(hi[d], xe[a][d]);
                    own.push_back(xe[a][d] - xe[0][d]);
                }
            for (int f = 0; f < 6; ++f)
                own.push_back(nb[6 * static_cast<std::size_t>(e) + f] < 0 ? 1.0 : 0.0);
        };
        translates = find_rk_translates(rk, ne, frame, share_translates);
        // the sources' facet sums, each with the count of elements it serves (the progress count)
        served.assign(static_cast<std::size_t>(ne), 0);
        for (index_t e = 0; e < ne; ++e)
        {
            if (translates.computed(e))
                sources.push_back(e);
            ++served[translates.source[e]];
        }
        sums_of.assign(static_cast<std::size_t>(ne), -1);
        for (std::size_t k = 0; k < sources.size(); ++k)
            sums_of[sources[k]] = static_cast<index_t>(k);
        sums.resize(sources.size());
    }

    /// The sources' facet sums, in parallel.
    void compute_facet_sums(real_t drop_tolerance)
    {
        ParallelErrors errors;
#pragma omp parallel
        {
            ElementFacetSums element(rk, drop_tolerance);
            real_t xe[8][3];
            bool boundary_face[6];
#pragma omp for schedule(dynamic, 16)
            for (std::size_t k = 0; k < sources.size(); ++k)
            {
                const index_t e = sources[k];
                try
                {
                    element_coordinates(mesh, e, xe);
                    for (int f = 0; f < 6; ++f)
                        boundary_face[f] = nb[6 * static_cast<std::size_t>(e) + f] < 0;
                    element.values().gather(translates.region(e), static_cast<std::size_t>(translates.region_size(e)));
                    element.compute(xe, boundary_face, sd != nullptr, sums[k]);
                    setup_progress::advance(served[e]);
                }
                catch (...)
                {
                    errors.capture();
                }
            }
        }
        errors.rethrow();
    }

    /// The sub-hexes' volumes, and with sd the sub-cells' rows, centroids and owners.
    void sub_cells()
    {
        // Sub-hex volumes, and with sd the sub-cells' rows (each one list of its element's sums,
        // read through the element's own region), weights, centroids and owners, per slot 8 e + a.
        slot_volume.resize(8 * static_cast<std::size_t>(ne));
        n_sub = sd ? 8 * static_cast<std::size_t>(ne) : 0;
        sub_rows.resize(n_sub);
        sub_position.resize(3 * n_sub);
        sub_owner.resize(n_sub);
        parallel_for("rkfem::build_scni_rk::sub_cells", ne,
                     [&](index_t e)
                     {
                         real_t xe[8][3];
                         element_coordinates(mesh, e, xe);
                         for (int a = 0; a < 8; ++a)
                             slot_volume[8 * static_cast<std::size_t>(e) + a] = sub_hex_volume(xe, a);
                         if (!sd)
                             return;
                         const FacetSums& from = sums[sums_of[translates.source[e]]];
                         const index_t* ids = translates.region(e);
                         for (int a = 0; a < 8; ++a)
                         {
                             const std::size_t slot = 8 * static_cast<std::size_t>(e) + static_cast<std::size_t>(a);
                             if (!(slot_volume[slot] > 0.0))
                                 continue; // reported below, in element order
                             const real_t scale = 1.0 / slot_volume[slot];
                             for (index_t k = from.start[8 + a]; k < from.start[9 + a]; ++k)
                             {
                                 const real_t* g = from.g.data() + 3 * static_cast<std::size_t>(k);
                                 sub_rows[slot].emplace_back(ids[from.slot[k]], Vec3(g[0], g[1], g[2]) * scale);
                             }
                             const Vec3 c = sub_hex_centroid(xe, a);
                             for (int d = 0; d < 3; ++d)
                                 sub_position[3 * slot + d] = c[d];
                             sub_owner[slot] = mesh.conn[slot];
                         }
                     });
        for (std::size_t slot = 0; slot < n_sub; ++slot)
            RKFEM_REQUIRE(slot_volume[slot] > 0.0, "SD-SCNI: sub-cell " << slot % 8 << " of element " << slot / 8
                                                                        << " has non-positive volume "
                                                                        << slot_volume[slot]);
    }

    /// The nodes' volumes, the op's weights, from their sub-hexes.
    void nodal_volumes()
    {
        // nodal volumes: each node's sub-hexes in incidence order (the same bits on any thread count)
        node_element_incidence(mesh, inc_offsets, slots);
        op.weight.assign(static_cast<std::size_t>(nn), 0.0);
        for (index_t i = 0; i < nn; ++i)
        {
            for (index_t k = inc_offsets[i]; k < inc_offsets[i + 1]; ++k)
                op.weight[i] += slot_volume[slots[k]];
            RKFEM_REQUIRE(op.weight[i] > 0.0,
                          "SCNI: nodal cell of node " << i << " has non-positive volume " << op.weight[i]);
        }
    }

    /// per node: its sub-hexes' lists in colour order (a count pass, then a pass that writes the
    /// merged rows)
    void lists_of(index_t i, std::vector<RowMerger::List>& lists) const
    {
        lists.clear();
        for (index_t k = inc_offsets[i]; k < inc_offsets[i + 1]; ++k)
        {
            const index_t e = slots[k] / 8, a = slots[k] % 8;
            const FacetSums& from = sums[sums_of[translates.source[e]]];
            lists.push_back({colour_of[e], from.start[a], from.start[a + 1], translates.region(e), from.slot.data(),
                             from.g.data()});
        }
        std::sort(lists.begin(), lists.end(),
                  [](const RowMerger::List& p, const RowMerger::List& q) { return p.colour < q.colour; });
    }

    /// The elements' colours and the rows' offsets (a pass that counts each row's particles), and the
    /// op's positions and owners.
    void count_rows()
    {
        // Each node's row: the sums of its sub-hexes merged by particle, each particle's terms added
        // in the order of their elements' colours (a fixed order, so the same bits on any number of
        // threads), then scaled by 1 / V: a pass that counts each row's particles, then one that
        // writes the rows at their offsets.
        std::vector<index_t> colour_offsets, by_colour;
        colour_elements(mesh, colour_offsets, by_colour);
        colour_of.resize(static_cast<std::size_t>(ne));
        for (std::size_t c = 0; c + 1 < colour_offsets.size(); ++c)
            for (index_t q = colour_offsets[c]; q < colour_offsets[c + 1]; ++q)
                colour_of[by_colour[q]] = static_cast<index_t>(c);
        op.offsets.assign(static_cast<std::size_t>(nn) + 1, 0);
#pragma omp parallel
        {
            RowMerger merger(rk.size());
            std::vector<RowMerger::List> lists;
#pragma omp for schedule(static)
            for (index_t i = 0; i < nn; ++i)
            {
                lists_of(i, lists);
                op.offsets[i + 1] = merger.count(lists);
            }
        }
        for (index_t i = 0; i < nn; ++i)
            op.offsets[i + 1] += op.offsets[i];
        op.position = mesh.x;
        op.owner.resize(static_cast<std::size_t>(nn));
        for (index_t i = 0; i < nn; ++i)
            op.owner[i] = i;
    }

    /// node i's row into nodes[0, count), grad[0, 3 count)
    void write_row(index_t i, RowMerger& merger, std::vector<RowMerger::List>& lists, index_t* nodes,
                   real_t* grad) const
    {
        lists_of(i, lists);
        merger.merge(lists, 1.0 / op.weight[i], nodes, grad);
    }

    /// The rows: into shared stencils (with shared, where sharing pays), else into the op.
    void write_rows(StencilTable* shared)
    {
        // Shared stencils straight from the rows: blocks of nodes write their rows in parallel into
        // one buffer, which the sharer reads in node order, so the set-up never holds the whole
        // operator (at P6's target as rkpm, 194 MB of fresh pages, a large share of its set-up;
        // measurements: docs/performance.md). Where sharing does not pay, the rows are written
        // again, into the operator.
        bool shares = shared != nullptr;
        if (shares)
        {
            shared->clear();
            StencilSharer sharer(nn, static_cast<std::size_t>(op.offsets[nn]));
            constexpr index_t kBlockNodes = 2048;
            std::size_t room = 0;
            for (index_t i0 = 0; i0 < nn; i0 += kBlockNodes)
                room = std::max(room,
                                static_cast<std::size_t>(op.offsets[std::min(nn, i0 + kBlockNodes)] - op.offsets[i0]));
            std::vector<index_t> block_nodes(room);
            std::vector<real_t> block_grad(3 * room);
#pragma omp parallel
            {
                RowMerger merger(rk.size());
                std::vector<RowMerger::List> lists;
                for (index_t i0 = 0; i0 < nn && shares; i0 += kBlockNodes)
                {
                    const index_t i1 = std::min(nn, i0 + kBlockNodes);
                    const index_t base = op.offsets[i0];
#pragma omp for schedule(static)
                    for (index_t i = i0; i < i1; ++i)
                        write_row(i, merger, lists, block_nodes.data() + (op.offsets[i] - base),
                                  block_grad.data() + 3 * static_cast<std::size_t>(op.offsets[i] - base));
#pragma omp single
                    for (index_t i = i0; i < i1 && shares; ++i)
                        shares = sharer.add(block_nodes.data() + (op.offsets[i] - base),
                                            block_grad.data() + 3 * static_cast<std::size_t>(op.offsets[i] - base),
                                            op.offsets[i + 1] - op.offsets[i]);
                    // (the single's barrier: every thread sees `shares`)
                }
            }
            if (shares)
                *shared = sharer.take();
        }
        if (!shares)
        {
            op.nodes.resize(static_cast<std::size_t>(op.offsets[nn]));
            op.grad.resize(3 * op.nodes.size());
#pragma omp parallel
            {
                RowMerger merger(rk.size());
                std::vector<RowMerger::List> lists;
#pragma omp for schedule(static)
                for (index_t i = 0; i < nn; ++i)
                    write_row(i, merger, lists, op.nodes.data() + op.offsets[i],
                              op.grad.data() + 3 * static_cast<std::size_t>(op.offsets[i]));
            }
        }
    }
};
} // namespace

IntegrationOperator build_scni_rk(const HexMesh& mesh, const RkShapeFunctions& rk, real_t drop_tolerance,
                                  IntegrationOperator* sd, bool share_translates, StencilTable* shared)
{
    IntegrationOperator op;
    ScniRkWork w(mesh, rk, sd, op);
    w.find_sources(share_translates);
    w.compute_facet_sums(drop_tolerance);
    w.sub_cells();
    w.nodal_volumes();
    w.count_rows();
    w.write_rows(shared);
    std::vector<FacetSums>().swap(w.sums);
    if (sd)
        *sd = pack(w.sub_rows, w.slot_volume, std::move(w.sub_position), std::move(w.sub_owner));
    return op;
}

} // namespace rkfem
