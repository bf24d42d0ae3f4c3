#include "rkfem/integration/nodal/nodal_integration.hpp"

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
namespace
{
using Entries = std::vector<std::pair<index_t, Vec3>>;

/// Merges duplicate nodes (each node's contributions summed in the order they come) and sorts
/// by node; scales by `scale`. A per-thread node -> slot table does the merging in one pass, so
/// only the distinct nodes are sorted (a node's raw list holds tens of contributions per node:
/// every facet point's whole support); the sums are those of a stable sort and a sweep, bit for bit.
void merge(Entries& e, real_t scale)
{
    thread_local std::vector<index_t> slot; // node -> its entry in `out`, -1: none yet
    thread_local Entries out;
    out.clear();
    for (const auto& [n, g] : e)
    {
        if (static_cast<std::size_t>(n) >= slot.size())
            slot.resize(static_cast<std::size_t>(n) + 1, -1);
        index_t& k = slot[static_cast<std::size_t>(n)];
        if (k < 0)
        {
            k = static_cast<index_t>(out.size());
            out.emplace_back(n, g);
        }
        else
            out[static_cast<std::size_t>(k)].second += g;
    }
    for (const auto& [n, g] : out)
        slot[static_cast<std::size_t>(n)] = -1;
    std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    e.assign(out.begin(), out.end());
    for (auto& [n, g] : e)
        g *= scale;
}

void element_coordinates(const HexMesh& mesh, index_t e, real_t xe[8][3])
{
    for (int I = 0; I < 8; ++I)
        for (int d = 0; d < 3; ++d)
            xe[I][d] = mesh.x[3 * static_cast<std::size_t>(mesh.conn[8 * e + I]) + d];
}

/// Adds sum_q Psi(x_q) n dA_q over the given facets of sub-hex `sh` in element e.
void add_facets(const ShapeEvaluator& shapes, index_t e, const SubHex& sh, const bool use[6], Entries& out,
                std::vector<index_t>& nodes, std::vector<real_t>& psi)
{
    for (int f = 0; f < 6; ++f)
    {
        if (!use[f])
            continue;
        for (const FacetPoint& fp : sh.facets[f])
        {
            shapes.values(e, fp.xi, fp.x, nodes, psi);
            for (std::size_t k = 0; k < nodes.size(); ++k)
                out.emplace_back(nodes[k], psi[k] * fp.nda);
        }
    }
}

IntegrationOperator pack(std::vector<Entries>& entries, std::vector<real_t> weight, std::vector<real_t> position,
                         std::vector<index_t> owner);

/// Appends a point's row to op: its nodes, their gradients (3 each), the point's end offset.
void append_row(IntegrationOperator& op, const Entries& row)
{
    for (const auto& [n, g] : row)
    {
        op.nodes.push_back(n);
        op.grad.insert(op.grad.end(), {g[0], g[1], g[2]});
    }
    op.offsets.push_back(op.n_entries());
}

/// The centroid of sub-hex a of an element: the natural centre of its octant.
Vec3 sub_hex_centroid(const real_t xe[8][3], int a)
{
    real_t N[8];
    const real_t xi[3] = {0.5 * hex8_nodes[a][0], 0.5 * hex8_nodes[a][1], 0.5 * hex8_nodes[a][2]};
    hex8_shape(xi, N);
    Vec3 pos = Vec3::Zero();
    for (int I = 0; I < 8; ++I)
        pos += N[I] * Vec3(xe[I][0], xe[I][1], xe[I][2]);
    return pos;
}

/// Builds an operator from per-point entry lists (parallel over points, concatenated in order).
template <class PointFn> IntegrationOperator assemble(index_t n_points, PointFn&& fn)
{
    std::vector<Entries> entries(static_cast<std::size_t>(n_points));
    std::vector<real_t> weight(static_cast<std::size_t>(n_points)), position(3 * static_cast<std::size_t>(n_points));
    std::vector<index_t> owner(static_cast<std::size_t>(n_points));
    ParallelErrors errors;
#pragma omp parallel
    {
        std::vector<index_t> nodes;
        std::vector<real_t> psi;
        // the raw facet contributions (every facet point times every node of its support,
        // tens of times the merged count) go to one scratch list per thread; each point keeps
        // an exactly sized copy of its merged entries
        Entries scratch;
#pragma omp for schedule(dynamic, 64)
        for (index_t p = 0; p < n_points; ++p)
        {
            try
            {
                Vec3 pos;
                scratch.clear();
                fn(p, scratch, weight[p], pos, owner[p], nodes, psi);
                entries[p].assign(scratch.begin(), scratch.end());
                for (int d = 0; d < 3; ++d)
                    position[3 * p + d] = pos[d];
                setup_progress::advance();
            }
            catch (...)
            {
                errors.capture();
            }
        }
    }
    errors.rethrow(); // the first failure, with its type (SingularMomentError)
    return pack(entries, std::move(weight), std::move(position), std::move(owner));
}

/// The operator of per-point merged entry lists (freed as they are copied).
IntegrationOperator pack(std::vector<Entries>& entries, std::vector<real_t> weight, std::vector<real_t> position,
                         std::vector<index_t> owner)
{
    IntegrationOperator op;
    op.weight = std::move(weight);
    op.position = std::move(position);
    op.owner = std::move(owner);
    op.offsets.assign(1, 0);
    std::size_t total = 0;
    for (const auto& e : entries)
        total += e.size();
    op.nodes.reserve(total);
    op.grad.reserve(3 * total);
    op.offsets.reserve(entries.size() + 1);
    for (auto& e : entries)
    {
        append_row(op, e);
        Entries().swap(e); // free as we go
    }
    return op;
}
} // namespace

std::vector<real_t> nodal_volumes(const HexMesh& mesh)
{
    std::vector<real_t> v(static_cast<std::size_t>(mesh.n_nodes()), 0.0);
    SubHex sh;
    real_t xe[8][3];
    for (index_t e = 0; e < mesh.n_elements(); ++e)
    {
        element_coordinates(mesh, e, xe);
        for (int a = 0; a < 8; ++a)
        {
            build_sub_hex(xe, a, sh);
            v[mesh.conn[8 * e + a]] += sh.volume;
        }
    }
    return v;
}

IntegrationOperator build_dni(const HexMesh& mesh, const ShapeEvaluator& shapes)
{
    return build_dni_cells(nodal_volumes(mesh), mesh.x, shapes);
}

IntegrationOperator build_scni(const HexMesh& mesh, const ShapeEvaluator& shapes)
{
    IntegrationOperator scni;
    build_scni_sd(mesh, shapes, scni, nullptr);
    return scni;
}

void build_scni_sd(const HexMesh& mesh, const ShapeEvaluator& shapes, IntegrationOperator& scni,
                   IntegrationOperator* sd)
{
    std::vector<index_t> offsets, slots;
    node_element_incidence(mesh, offsets, slots);
    const std::vector<index_t> nb = face_neighbours(mesh);
    const std::size_t n_sub = sd ? 8 * static_cast<std::size_t>(mesh.n_elements()) : 0;
    std::vector<Entries> sub_entries(n_sub);
    std::vector<real_t> sub_weight(n_sub), sub_position(3 * n_sub);
    std::vector<index_t> sub_owner(n_sub);
    scni = assemble(
        mesh.n_nodes(),
        [&](index_t i, Entries& out, real_t& w, Vec3& pos, index_t& owner, std::vector<index_t>& nodes,
            std::vector<real_t>& psi)
        {
            real_t vol = 0.0;
            SubHex sh;
            real_t xe[8][3];
            for (index_t k = offsets[i]; k < offsets[i + 1]; ++k)
            {
                const index_t e = slots[k] / 8;
                const int a = slots[k] % 8;
                element_coordinates(mesh, e, xe);
                build_sub_hex(xe, a, sh);
                vol += sh.volume;
                // facets on element faces shared with another element of the cell
                // are interior to the nodal cell: skip them
                bool use[6];
                for (int f = 0; f < 6; ++f)
                    use[f] = sh.element_face[f] < 0 || nb[6 * e + sh.element_face[f]] < 0;
                if (!sd)
                {
                    add_facets(shapes, e, sh, use, out, nodes, psi);
                    continue;
                }
                // with the sub-cells: every facet evaluated once, the sub-cell's row
                // from all six (as build_sd_scni), the node's from those it uses
                const std::size_t s = static_cast<std::size_t>(slots[k]);
                Entries& sub = sub_entries[s];
                for (int f = 0; f < 6; ++f)
                {
                    const std::size_t begin = sub.size();
                    bool one[6] = {};
                    one[f] = true;
                    add_facets(shapes, e, sh, one, sub, nodes, psi);
                    if (use[f])
                        out.insert(out.end(), sub.begin() + static_cast<std::ptrdiff_t>(begin), sub.end());
                }
                RKFEM_REQUIRE(sh.volume > 0.0, "SD-SCNI: sub-cell " << a << " of element " << e
                                                                    << " has non-positive volume " << sh.volume);
                merge(sub, 1.0 / sh.volume);
                sub_weight[s] = sh.volume;
                const Vec3 c = sub_hex_centroid(xe, a);
                for (int d = 0; d < 3; ++d)
                    sub_position[3 * s + d] = c[d];
                sub_owner[s] = i;
            }
            RKFEM_REQUIRE(vol > 0.0, "SCNI: nodal cell of node " << i << " has non-positive volume " << vol);
            merge(out, 1.0 / vol);
            w = vol;
            pos = mesh.node(i);
            owner = i;
        });
    if (sd)
        *sd = pack(sub_entries, std::move(sub_weight), std::move(sub_position), std::move(sub_owner));
}

void colour_elements(const HexMesh& mesh, std::vector<index_t>& offsets, std::vector<index_t>& elements)
{
    std::vector<index_t> inc_offsets, slots;
    node_element_incidence(mesh, inc_offsets, slots);
    const index_t ne = mesh.n_elements();
    std::vector<index_t> colour(static_cast<std::size_t>(ne), -1);
    std::vector<char> taken;
    index_t n_colours = 0;
    for (index_t e = 0; e < ne; ++e)
    {
        taken.assign(static_cast<std::size_t>(n_colours) + 1, 0);
        for (int a = 0; a < 8; ++a)
        {
            const index_t L = mesh.conn[8 * e + a];
            for (index_t k = inc_offsets[L]; k < inc_offsets[L + 1]; ++k)
            {
                const index_t c = colour[slots[k] / 8];
                if (c >= 0)
                    taken[static_cast<std::size_t>(c)] = 1;
            }
        }
        index_t c = 0;
        while (taken[static_cast<std::size_t>(c)])
            ++c;
        colour[e] = c;
        n_colours = std::max(n_colours, c + 1);
    }
    offsets.assign(static_cast<std::size_t>(n_colours) + 1, 0);
    for (index_t e = 0; e < ne; ++e)
        ++offsets[colour[e] + 1];
    for (index_t c = 0; c < n_colours; ++c)
        offsets[c + 1] += offsets[c];
    elements.resize(static_cast<std::size_t>(ne));
    std::vector<index_t> fill(offsets.begin(), offsets.end() - 1);
    for (index_t e = 0; e < ne; ++e)
        elements[fill[colour[e]]++] = e;
}

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

/// Evaluates the functions at x and adds psi n dA over the current candidates k into the flat
/// sums (g[k], g[n + k], g[2 n + k]) and kept into hit[k] (n = values.size()).
void add_point_values(RkRegionValues& values, const Vec3& x, const Vec3& nda, real_t* g, real_t* hit)
{
    values.evaluate(x);
    const std::size_t n = values.size();
    const real_t n0 = nda[0], n1 = nda[1], n2 = nda[2];
    const real_t *psi = values.psi(), *kept = values.kept();
    real_t *g0 = g, *g1 = g + n, *g2 = g + 2 * n;
#pragma omp simd
    for (std::size_t k = 0; k < n; ++k)
    {
        g0[k] += psi[k] * n0;
        g1[k] += psi[k] * n1;
        g2[k] += psi[k] * n2;
        hit[k] = hit[k] < kept[k] ? kept[k] : hit[k];
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
} // namespace

IntegrationOperator build_scni_rk(const HexMesh& mesh, const RkShapeFunctions& rk, real_t drop_tolerance,
                                  IntegrationOperator* sd, bool share_translates, StencilTable* shared)
{
    const std::vector<index_t> nb = face_neighbours(mesh);
    const index_t nn = mesh.n_nodes(), ne = mesh.n_elements();
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
    const RkTranslates translates = find_rk_translates(rk, ne, frame, share_translates);
    // the sources' facet sums, each with the count of elements it serves (the progress count)
    std::vector<index_t> sources, served(static_cast<std::size_t>(ne), 0);
    for (index_t e = 0; e < ne; ++e)
    {
        if (translates.computed(e))
            sources.push_back(e);
        ++served[translates.source[e]];
    }
    std::vector<index_t> sums_of(static_cast<std::size_t>(ne), -1);
    for (std::size_t k = 0; k < sources.size(); ++k)
        sums_of[sources[k]] = static_cast<index_t>(k);
    std::vector<FacetSums> sums(sources.size());
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
    // Sub-hex volumes, and with sd the sub-cells' rows (each one list of its element's sums,
    // read through the element's own region), weights, centroids and owners, per slot 8 e + a.
    std::vector<real_t> slot_volume(8 * static_cast<std::size_t>(ne));
    const std::size_t n_sub = sd ? 8 * static_cast<std::size_t>(ne) : 0;
    std::vector<Entries> sub_rows(n_sub);
    std::vector<real_t> sub_position(3 * n_sub);
    std::vector<index_t> sub_owner(n_sub);
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
    // nodal volumes: each node's sub-hexes in incidence order (the same bits on any thread count)
    std::vector<index_t> inc_offsets, slots;
    node_element_incidence(mesh, inc_offsets, slots);
    IntegrationOperator op;
    op.weight.assign(static_cast<std::size_t>(nn), 0.0);
    for (index_t i = 0; i < nn; ++i)
    {
        for (index_t k = inc_offsets[i]; k < inc_offsets[i + 1]; ++k)
            op.weight[i] += slot_volume[slots[k]];
        RKFEM_REQUIRE(op.weight[i] > 0.0,
                      "SCNI: nodal cell of node " << i << " has non-positive volume " << op.weight[i]);
    }
    // Each node's row: the sums of its sub-hexes merged by particle, each particle's terms added
    // in the order of their elements' colours (a fixed order, so the same bits on any number of
    // threads), then scaled by 1 / V: a pass that counts each row's particles, then one that
    // writes the rows at their offsets.
    std::vector<index_t> colour_offsets, by_colour;
    colour_elements(mesh, colour_offsets, by_colour);
    std::vector<index_t> colour_of(static_cast<std::size_t>(ne));
    for (std::size_t c = 0; c + 1 < colour_offsets.size(); ++c)
        for (index_t q = colour_offsets[c]; q < colour_offsets[c + 1]; ++q)
            colour_of[by_colour[q]] = static_cast<index_t>(c);
    // per node: its sub-hexes' lists in colour order (a count pass, then a pass that writes the
    // merged rows)
    auto lists_of = [&](index_t i, std::vector<RowMerger::List>& lists)
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
    };
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
    // node i's row into nodes[0, count), grad[0, 3 count)
    auto write_row =
        [&](index_t i, RowMerger& merger, std::vector<RowMerger::List>& lists, index_t* nodes, real_t* grad)
    {
        lists_of(i, lists);
        merger.merge(lists, 1.0 / op.weight[i], nodes, grad);
    };
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
            room =
                std::max(room, static_cast<std::size_t>(op.offsets[std::min(nn, i0 + kBlockNodes)] - op.offsets[i0]));
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
    std::vector<FacetSums>().swap(sums);
    if (sd)
        *sd = pack(sub_rows, slot_volume, std::move(sub_position), std::move(sub_owner));
    return op;
}

IntegrationOperator build_sd_scni(const HexMesh& mesh, const ShapeEvaluator& shapes)
{
    return assemble(8 * mesh.n_elements(),
                    [&](index_t p, Entries& out, real_t& w, Vec3& pos, index_t& owner, std::vector<index_t>& nodes,
                        std::vector<real_t>& psi)
                    {
                        const index_t e = p / 8;
                        const int a = p % 8;
                        SubHex sh;
                        real_t xe[8][3];
                        element_coordinates(mesh, e, xe);
                        build_sub_hex(xe, a, sh);
                        const bool use[6] = {true, true, true, true, true, true};
                        add_facets(shapes, e, sh, use, out, nodes, psi);
                        RKFEM_REQUIRE(sh.volume > 0.0, "SD-SCNI: sub-cell " << a << " of element " << e
                                                                            << " has non-positive volume "
                                                                            << sh.volume);
                        merge(out, 1.0 / sh.volume);
                        w = sh.volume;
                        pos = sub_hex_centroid(xe, a);
                        owner = mesh.conn[8 * e + a];
                    });
}

IntegrationOperator build_nodal(NodalScheme scheme, const HexMesh& mesh, const ShapeEvaluator& shapes)
{
    switch (scheme)
    {
    case NodalScheme::Dni:
        return build_dni(mesh, shapes);
    case NodalScheme::Scni:
        return build_scni(mesh, shapes);
    case NodalScheme::SdScni:
        return build_sd_scni(mesh, shapes);
    }
    return {};
}

IntegrationOperator build_scni_cells(const VoronoiCells& cells, const std::vector<real_t>& x,
                                     const ShapeEvaluator& shapes)
{
    return assemble(cells.size(),
                    [&](index_t i, Entries& out, real_t& w, Vec3& pos, index_t& owner, std::vector<index_t>& nodes,
                        std::vector<real_t>& psi)
                    {
                        for (index_t q = cells.offsets[i]; q < cells.offsets[i + 1]; ++q)
                        {
                            const CellFacetPoint& fp = cells.points[q];
                            shapes.values(-1, Vec3::Zero(), fp.x, nodes, psi);
                            for (std::size_t k = 0; k < nodes.size(); ++k)
                                out.emplace_back(nodes[k], psi[k] * fp.nda);
                        }
                        merge(out, 1.0 / cells.volume[i]);
                        w = cells.volume[i];
                        pos = Vec3(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
                        owner = i;
                    });
}

namespace
{
/// Appends (particle[k], (s[k], s[nr + k], s[2 nr + k])) to out for each k < nr whose mark[k] is
/// not 0, in k order: every entry is written and kept by moving the end on by its mark, without
/// a branch on the marks (a region's hit particles come in short runs)
void append_marked(Entries& out, const index_t* particle, const real_t* s, const real_t* mark, std::size_t nr)
{
    std::size_t m = out.size();
    out.resize(m + nr);
    for (std::size_t k = 0; k < nr; ++k)
    {
        out[m] = {particle[k], Vec3(s[k], s[nr + k], s[2 * nr + k])};
        m += mark[k] != 0.0 ? 1 : 0;
    }
    out.resize(m);
}
} // namespace

IntegrationOperator build_scni_cells_rk(const VoronoiCells& cells, const std::vector<real_t>& x,
                                        const RkShapeFunctions& rk, real_t drop_tolerance, index_t block)
{
    RKFEM_REQUIRE(block > 0, "build_scni_cells_rk: blocks of " << block << " cells");
    const index_t n = cells.size();
    IntegrationOperator op;
    op.weight = cells.volume;
    op.position.assign(x.begin(), x.begin() + 3 * static_cast<std::ptrdiff_t>(n));
    op.owner.resize(static_cast<std::size_t>(n));
    for (index_t i = 0; i < n; ++i)
        op.owner[i] = i;
    op.offsets.assign(1, 0);
    op.offsets.reserve(static_cast<std::size_t>(n) + 1);
    // The rows a block of cells at a time, appended in cell order as they come. A face between
    // cells i < j no further apart than a block is evaluated once, by i: its points are the same
    // from both sides (each triangle of a face's centroid fan is an edge and the centroid, up to
    // the vertices' round-off) and j's normals are i's reversed, so i hands j its face sums
    // (particle, sum psi n dA) and j subtracts them instead of evaluating the face again. A face
    // that i does not see (a sliver one side's round-off kept) j evaluates itself.
    // The sums go to a pool per thread and block parity, reused two blocks on (a block's cells
    // take only from their own block and the one before): sums held in vectors of their own came
    // back from the heap fragmented and raised the set-up's peak by a tenth.
    struct FaceSums
    {
        index_t to = -1;                ///< the cell across
        int pool = 0;                   ///< in pools[pool], entries [begin, end): by particle,
        std::size_t begin = 0, end = 0; ///< ascending, where some point of the face kept it
    };
    std::vector<std::vector<FaceSums>> outbox(static_cast<std::size_t>(n)); // per cell: its faces' sums for later cells
    std::vector<Entries> pools(2 * static_cast<std::size_t>(omp_get_max_threads()));
    std::vector<Entries> rows(static_cast<std::size_t>(std::min(n, block)));
    std::vector<std::vector<index_t>> taken(
        rows.size()); // per cell of the block: its faces' first points, to take from earlier cells
    auto shared = [&](index_t i, index_t j) { return j >= 0 && std::abs(i - j) <= block; };
    ParallelErrors errors;
#pragma omp parallel
    {
        RkRegionValues values(rk, drop_tolerance);
        // per region particle: sum psi n dA [component][particle], hit (0 / 1); the same of one face
        std::vector<real_t> acc, hit, face_acc, face_hit;
        Entries merged;
        // the region of the box of points [q0, q1) of a cell gathered, and acc / hit zeroed over it
        auto gather_region = [&](index_t q0, index_t q1)
        {
            Vec3 lo = Vec3::Constant(std::numeric_limits<real_t>::max()), hi = -lo;
            for (index_t q = q0; q < q1; ++q)
            {
                lo = lo.cwiseMin(cells.points[q].x);
                hi = hi.cwiseMax(cells.points[q].x);
            }
            values.gather(lo, hi);
            const std::size_t nr = values.region_size();
            acc.assign(3 * nr, 0.0);
            hit.assign(nr, 0.0);
            return nr;
        };
        // the region's particles that some point reached, with their sums, onto out (ascending)
        auto collect_hits = [&](Entries& out)
        { append_marked(out, values.region_particles().data(), acc.data(), hit.data(), values.region_size()); };
        // row += sign * sums[0 .. m), both by particle ascending (a merge)
        auto add_sums = [&](Entries& row, const std::pair<index_t, Vec3>* sums, std::size_t m, real_t sign)
        {
            merged.clear();
            std::size_t a = 0, b = 0;
            while (a < row.size() || b < m)
                if (b == m || (a < row.size() && row[a].first < sums[b].first))
                    merged.push_back(row[a++]);
                else if (a == row.size() || sums[b].first < row[a].first)
                {
                    merged.emplace_back(sums[b].first, sign * sums[b].second);
                    ++b;
                }
                else
                {
                    merged.emplace_back(row[a].first, row[a].second + sign * sums[b].second);
                    ++a, ++b;
                }
            row.swap(merged);
        };
        for (index_t b0 = 0; b0 < n; b0 += block)
        {
            const index_t b1 = std::min(n, b0 + block);
            // this thread's pool for the block: it held the sums of two blocks back
            const int my_pool = 2 * omp_get_thread_num() + static_cast<int>((b0 / block) % 2);
            Entries& pool = pools[static_cast<std::size_t>(my_pool)];
            pool.clear();
            // each cell's own faces, and the sums of those it hands on
#pragma omp for schedule(dynamic, 16)
            for (index_t i = b0; i < b1; ++i)
            {
                Entries& row = rows[static_cast<std::size_t>(i - b0)];
                std::vector<index_t>& take = taken[static_cast<std::size_t>(i - b0)];
                row.clear();
                take.clear();
                try
                {
                    const index_t q0 = cells.offsets[i], q1 = cells.offsets[i + 1];
                    const std::size_t nr = gather_region(q0, q1);
                    const index_t* particle = values.region_particles().data();
                    for (index_t f0 = q0; f0 < q1;)
                    {
                        const index_t f1 = cells.face_end(i, f0), j = cells.points[f0].neighbour;
                        if (shared(i, j) && j < i)
                            take.push_back(f0);
                        else if (shared(i, j))
                        {
                            face_acc.assign(3 * nr, 0.0);
                            face_hit.assign(nr, 0.0);
                            for (index_t q = f0; q < f1; ++q)
                                add_point_values(values, cells.points[q].x, cells.points[q].nda, face_acc.data(),
                                                 face_hit.data());
                            FaceSums fs{j, my_pool, pool.size(), 0};
                            for (std::size_t k = 0; k < nr; ++k)
                            {
                                acc[k] += face_acc[k];
                                acc[nr + k] += face_acc[nr + k];
                                acc[2 * nr + k] += face_acc[2 * nr + k];
                                hit[k] = hit[k] < face_hit[k] ? face_hit[k] : hit[k];
                            }
                            append_marked(pool, particle, face_acc.data(), face_hit.data(), nr);
                            fs.end = pool.size();
                            outbox[static_cast<std::size_t>(i)].push_back(fs);
                        }
                        else
                            for (index_t q = f0; q < f1; ++q)
                                add_point_values(values, cells.points[q].x, cells.points[q].nda, acc.data(),
                                                 hit.data());
                        f0 = f1;
                    }
                    collect_hits(row);
                }
                catch (...)
                {
                    errors.capture();
                }
            }
            // the faces earlier cells evaluated, subtracted (their normals are this cell's
            // reversed); then the row over the cell's volume
#pragma omp for schedule(dynamic, 16)
            for (index_t i = b0; i < b1; ++i)
            {
                Entries& row = rows[static_cast<std::size_t>(i - b0)];
                try
                {
                    for (const index_t f0 : taken[static_cast<std::size_t>(i - b0)])
                    {
                        const index_t j = cells.points[f0].neighbour;
                        const FaceSums* from = nullptr;
                        for (const FaceSums& fs : outbox[static_cast<std::size_t>(j)])
                            if (fs.to == i)
                                from = &fs;
                        if (from)
                        {
                            add_sums(row, pools[static_cast<std::size_t>(from->pool)].data() + from->begin,
                                     from->end - from->begin, -1.0);
                            continue;
                        }
                        const index_t f1 = cells.face_end(i, f0);
                        gather_region(f0, f1);
                        for (index_t q = f0; q < f1; ++q)
                            add_point_values(values, cells.points[q].x, cells.points[q].nda, acc.data(), hit.data());
                        Entries own;
                        collect_hits(own);
                        add_sums(row, own.data(), own.size(), 1.0);
                    }
                    const real_t scale = 1.0 / cells.volume[i];
                    for (auto& e : row)
                        e.second *= scale;
                    setup_progress::advance();
                }
                catch (...)
                {
                    errors.capture();
                }
            }
#pragma omp single
            {
                // room for the rest at the entries per cell so far, where the block does not fit
                std::size_t in_block = 0;
                for (index_t i = b0; i < b1; ++i)
                    in_block += rows[static_cast<std::size_t>(i - b0)].size();
                const std::size_t need = op.nodes.size() + in_block;
                if (need > op.nodes.capacity())
                {
                    const std::size_t guess = need / static_cast<std::size_t>(b1) * static_cast<std::size_t>(n);
                    const std::size_t room = std::max(need, guess + guess / 32);
                    op.nodes.reserve(room);
                    op.grad.reserve(3 * room);
                }
                for (index_t i = b0; i < b1; ++i)
                    append_row(op, rows[static_cast<std::size_t>(i - b0)]);
                // the cells a block back: no later cell takes from them
                for (index_t i = std::max<index_t>(0, b0 - block); i < b0; ++i)
                    std::vector<FaceSums>().swap(outbox[static_cast<std::size_t>(i)]);
            }
        }
    }
    errors.rethrow();
    return_spare_room(op.nodes, op.grad); // the estimate's
    return op;
}

IntegrationOperator build_sd_cells(const VoronoiCells& cells, const ShapeEvaluator& shapes)
{
    return assemble(static_cast<index_t>(cells.sub_cells.size()),
                    [&](index_t s, Entries& out, real_t& w, Vec3& pos, index_t& owner, std::vector<index_t>& nodes,
                        std::vector<real_t>& psi)
                    {
                        const VoronoiCells::SubCell& sc = cells.sub_cells[s];
                        pos.setZero();
                        for (index_t q = sc.begin; q < sc.end; ++q)
                        {
                            const CellFacetPoint& fp = cells.sub_points[q];
                            shapes.values(-1, Vec3::Zero(), fp.x, nodes, psi);
                            for (std::size_t k = 0; k < nodes.size(); ++k)
                                out.emplace_back(nodes[k], psi[k] * fp.nda);
                            pos += fp.x;
                        }
                        RKFEM_REQUIRE(sc.volume > 0.0, "SD cells: sub-cell " << s << " of cell " << sc.cell
                                                                             << " has non-positive volume "
                                                                             << sc.volume);
                        merge(out, 1.0 / sc.volume);
                        w = sc.volume;
                        pos /= static_cast<real_t>(sc.end - sc.begin);
                        owner = sc.cell;
                    });
}

IntegrationOperator build_dni_cells(const std::vector<real_t>& volume, const std::vector<real_t>& x,
                                    const ShapeEvaluator& shapes)
{
    return assemble(static_cast<index_t>(volume.size()),
                    [&](index_t i, Entries& out, real_t& w, Vec3& pos, index_t& owner, std::vector<index_t>& nodes,
                        std::vector<real_t>&)
                    {
                        std::vector<Vec3> grad;
                        shapes.gradients_at_node(i, nodes, grad);
                        for (std::size_t k = 0; k < nodes.size(); ++k)
                            out.emplace_back(nodes[k], grad[k]);
                        merge(out, 1.0);
                        w = volume[i];
                        pos = Vec3(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
                        owner = i;
                    });
}

IntegrationOperator build_mscni_stabilization(const IntegrationOperator& scni, const IntegrationOperator& sd)
{
    IntegrationOperator op;
    op.weight = sd.weight;
    op.position = sd.position;
    op.owner = sd.owner;
    op.parent = sd.owner; // SCNI point index = node index
    for (index_t s = 0; s < sd.n_points(); ++s)
    {
        const index_t L = sd.owner[s];
        Entries e;
        for (index_t k = sd.offsets[s]; k < sd.offsets[s + 1]; ++k)
            e.emplace_back(sd.nodes[k], sd.gradient(k));
        for (index_t k = scni.offsets[L]; k < scni.offsets[L + 1]; ++k)
            e.emplace_back(scni.nodes[k], -scni.gradient(k));
        merge(e, 1.0);
        for (const auto& [n, g] : e)
        {
            op.nodes.push_back(n);
            op.grad.insert(op.grad.end(), {g[0], g[1], g[2]});
        }
        op.offsets.push_back(op.n_entries());
    }
    return op;
}

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
        op.offsets.resize(ns + 1);
        op.offsets[0] = 0;
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

std::vector<real_t> nodal_second_moments(const HexMesh& mesh)
{
    // node by node over its sub-hexes in element order, each sub-hex's 8 Gauss points at once
    // (sub_hex_points), in parallel
    std::vector<index_t> offsets, slots;
    node_element_incidence(mesh, offsets, slots);
    std::vector<real_t> m(3 * static_cast<std::size_t>(mesh.n_nodes()), 0.0);
    parallel_for("rkfem::nodal_second_moments", mesh.n_nodes(),
                 [&](index_t L)
                 {
                     real_t xe[8][3];
                     alignas(64) real_t det[8], x[3][8];
                     for (index_t k = offsets[L]; k < offsets[L + 1]; ++k)
                     {
                         element_coordinates(mesh, slots[k] / 8, xe);
                         sub_hex_points(xe, slots[k] % 8, det, x);
                         for (int d = 0; d < 3; ++d)
                         {
                             // the points' terms in the lanes, summed pairwise
                             const real_t xL = mesh.x[3 * static_cast<std::size_t>(L) + d];
                             alignas(64) real_t t[8];
                             for (int q = 0; q < 8; ++q)
                             {
                                 const real_t r = x[d][q] - xL;
                                 t[q] = det[q] * r * r;
                             }
                             for (int w = 4; w > 0; w /= 2)
                                 for (int q = 0; q < w; ++q)
                                     t[q] += t[q + w];
                             m[3 * static_cast<std::size_t>(L) + d] +=
                                 0.125 * t[0]; // sub-hex Jacobian 1/8 of the element's
                         }
                     }
                 });
    return m;
}

std::vector<real_t> nodal_second_moments_plain(const HexMesh& mesh)
{
    // node by node over its sub-hexes in element order (the incidence lists' order: each node's
    // sums in the order of an element loop), in parallel
    std::vector<index_t> offsets, slots;
    node_element_incidence(mesh, offsets, slots);
    std::vector<real_t> m(3 * static_cast<std::size_t>(mesh.n_nodes()), 0.0);
    const SubHexGauss& gauss = sub_hex_gauss();
    parallel_for("rkfem::nodal_second_moments_plain", mesh.n_nodes(),
                 [&](index_t L)
                 {
                     real_t xe[8][3];
                     for (index_t k = offsets[L]; k < offsets[L + 1]; ++k)
                     {
                         // the sub-hex of local node a: xi_d between 0 and the node's natural coordinate
                         const index_t e = slots[k] / 8;
                         const int a = slots[k] % 8;
                         element_coordinates(mesh, e, xe);
                         for (int q = 0; q < 8; ++q)
                         {
                             // det J as hex8_gradients computes it (J(a, d) = dx_d / dxi_a)
                             const real_t(&N)[8] = gauss.N[a][q];
                             const real_t(&dN)[8][3] = gauss.dN[a][q];
                             Mat3 J = Mat3::Zero();
                             for (int I = 0; I < 8; ++I)
                                 for (int b = 0; b < 3; ++b)
                                     for (int d = 0; d < 3; ++d)
                                         J(b, d) += dN[I][b] * xe[I][d];
                             const real_t w = 0.125 * J.determinant(); // sub-hex Jacobian 1/8 of the element's
                             for (int d = 0; d < 3; ++d)
                             {
                                 real_t x = 0.0;
                                 for (int I = 0; I < 8; ++I)
                                     x += N[I] * xe[I][d];
                                 const real_t r = x - mesh.x[3 * static_cast<std::size_t>(L) + d];
                                 m[3 * static_cast<std::size_t>(L) + d] += w * r * r;
                             }
                         }
                     }
                 });
    return m;
}

std::vector<real_t> cube_second_moments(const std::vector<real_t>& volume)
{
    std::vector<real_t> m(3 * volume.size());
    for (std::size_t i = 0; i < volume.size(); ++i)
    {
        const real_t s = std::cbrt(volume[i]);
        m[3 * i] = m[3 * i + 1] = m[3 * i + 2] = volume[i] * s * s / 12.0;
    }
    return m;
}

std::vector<BoundaryPoint> boundary_quadrature(const HexMesh& mesh)
{
    const std::vector<index_t> nb = face_neighbours(mesh);
    std::vector<BoundaryPoint> out;
    SubHex sh;
    real_t xe[8][3];
    for (index_t e = 0; e < mesh.n_elements(); ++e)
    {
        bool any = false;
        for (int f = 0; f < 6; ++f)
            any = any || nb[6 * e + f] < 0;
        if (!any)
            continue;
        element_coordinates(mesh, e, xe);
        for (int a = 0; a < 8; ++a)
        {
            build_sub_hex(xe, a, sh);
            for (int f = 1; f < 6; f += 2) // external facets
                if (nb[6 * e + sh.element_face[f]] < 0)
                    for (const FacetPoint& fp : sh.facets[f])
                        out.push_back({e, mesh.conn[8 * e + a], fp});
        }
    }
    return out;
}
} // namespace rkfem
