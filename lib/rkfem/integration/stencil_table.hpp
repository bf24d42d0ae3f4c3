#pragma once
/// @file stencil_table.hpp
/// Shared stencils: a compact form of an integration operator for parts whose points repeat one
/// neighbourhood (particles on a lattice, nodes of a structured mesh). Each point's stencil is
/// written relative to its first node: the node offsets n_k - n_0 and the gradients g_k. Points
/// whose offsets agree and whose gradients agree within a tolerance share one stored stencil, so
/// the force pass reads a few table entries from cache instead of streaming 28 bytes per entry
/// per point from memory.
///
/// Sharing snaps the operator: the gradients of every point are overwritten with those of its
/// class's stencil (the first point of the class, in point order), so the operator and the table
/// are the same operator and every consumer of either sees the same numbers. A snap changes a
/// gradient by at most `relative_tolerance` times the largest gradient of its stencil; the
/// stencils that differ that little differ by the round-off of their construction (which grows
/// with |X| / h: 5e-13 at 66 spacings from the origin), and the stencil kept is the one built
/// nearest the start of the point order.
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "rkfem/core/types.hpp"
#include "rkfem/integration/integration_operator.hpp"

namespace rkfem
{
/// One point's stencil: entry k touches node base + offset[k] with gradient grad[3k..3k+2].
struct StencilView
{
    const index_t* offset = nullptr;
    const real_t* grad = nullptr;
    index_t size = 0;
    index_t base = 0;
    /// a table's stencil: the order its uniform batches add the entries in (uniform_add_order),
    /// null where none was set (then last to first)
    const std::uint16_t* add_order = nullptr;
};

/// The order in which a batch of `lanes` points along a lattice row (point l's entry k touches
/// node base + offset[k] + l) adds a stencil's n entries into a force buffer, as local entry
/// indices. Each node takes its lanes' terms in lane order, so two entries whose windows of
/// `lanes` nodes overlap keep their last-to-first order: the bits are those of last to first.
/// The entries of windows apart are interleaved, so that an entry's window does not overlap the
/// last two added where a choice allows. A load of a window that overlaps a store still pending
/// only in part cannot take its values from the store and waits until the store reaches the
/// cache: the neighbours along a row (offsets o - 1, o, o + 1) added back to back made P3's force
/// pass wait on every entry (measurements: docs/performance.md).
struct AddOrder
{
    std::vector<index_t> start;       ///< per stencil: its order's first index in `order`, -1 for none
    std::vector<std::uint16_t> order; ///< the ordered stencils' local entry indices, one after another
    /// stencil s's order, null where it has none (then last to first)
    const std::uint16_t* of(index_t s) const
    {
        if (start.empty())
            return nullptr;
        const index_t i = start[static_cast<std::size_t>(s)];
        return i < 0 ? nullptr : order.data() + i;
    }
};

/// The add orders of a table's stencils (offsets, node_offset as the tables hold them).
/// `wanted` (per stencil; empty: all) names those some uniform batch reads: the others get
/// none, and take no room (a cloud's table holds a stencil per point, and no batch of it is
/// uniform; P1's most), nor do stencils of over 65,535 entries (the indices are 16 bits).
AddOrder uniform_add_order(const std::vector<index_t>& offsets, const std::vector<index_t>& node_offset,
                           index_t lanes = 8, const std::vector<char>& wanted = {});

/// Per full batch of `lanes` consecutive points from a multiple of `lanes` on (a table's
/// per-point classes and bases): 1 where the batch is uniform, its points of one class at
/// consecutive bases (points along a lattice row). Entry k of lane l then touches node base +
/// offset[k] + l, so each entry's nodes are `lanes` consecutive ones, which the force pass reads
/// and writes as whole vectors instead of lane by lane.
std::vector<char> uniform_batches(const std::vector<index_t>& point_class, const std::vector<index_t>& point_base,
                                  index_t lanes = 8);

/// Per stencil of a table: does some uniform batch (`uniform`, uniform_batches') read it? What
/// uniform_add_order's `wanted` takes.
std::vector<char> uniform_batch_stencils(const std::vector<char>& uniform, const std::vector<index_t>& point_class,
                                         index_t n_stencils, index_t lanes = 8);

struct StencilTable
{
    std::vector<index_t> point_stencil; ///< per point: its stencil (empty table: none shared)
    std::vector<index_t> point_base;    ///< per point: its first node
    std::vector<index_t> offsets{0};    ///< stencil s: entries [offsets[s], offsets[s + 1])
    std::vector<index_t> node_offset;   ///< per entry: node - base
    std::vector<real_t> grad;           ///< 3 per entry [1/m]
    AddOrder add_order;                 ///< uniform_add_order's (none: last to first)
    std::vector<char> uniform;          ///< per batch of points: uniform_batches' (empty: none uniform)

    bool empty() const { return point_stencil.empty(); }
    index_t n_stencils() const { return static_cast<index_t>(offsets.size()) - 1; }
    index_t n_entries() const { return static_cast<index_t>(node_offset.size()); }
    void clear() { *this = StencilTable{}; }

    /// Point p's stencil from the table.
    StencilView view(index_t p) const
    {
        const index_t s = point_stencil[static_cast<std::size_t>(p)];
        const index_t k0 = offsets[static_cast<std::size_t>(s)];
        return {node_offset.data() + k0, grad.data() + 3 * static_cast<std::size_t>(k0),
                offsets[static_cast<std::size_t>(s) + 1] - k0, point_base[static_cast<std::size_t>(p)],
                add_order.of(s)};
    }
};

/// Point p's stencil straight from the operator (base 0: the offsets are the node ids).
inline StencilView stencil_view(const IntegrationOperator& op, index_t p)
{
    const index_t k0 = op.offsets[static_cast<std::size_t>(p)];
    return {op.nodes.data() + k0, op.grad.data() + 3 * static_cast<std::size_t>(k0),
            op.offsets[static_cast<std::size_t>(p) + 1] - k0, 0};
}

/// Point p's stencil from the table when it has one, otherwise from the operator.
inline StencilView stencil_view(const IntegrationOperator& op, const StencilTable& table, index_t p)
{
    return table.empty() ? stencil_view(op, p) : table.view(p);
}

struct StencilSharing
{
    /// gradients that differ by at most this times the largest of their stencil are shared
    real_t relative_tolerance = 1e-11;
    /// sharing is kept only when the table holds at most this fraction of the operator's entries
    /// (the table and its per-point classes replace the operator's entries, so it pays in memory
    /// well past a half; on a structured mesh as thin as P3's 4 x 4 in beam most stencils see a
    /// face; an irregular cloud gives up after 60% of its points, whose search costs little
    /// beside the gradients')
    real_t max_entry_fraction = 0.6;
    /// stencils compared per offset pattern, newest first, before a point's own is stored: the
    /// newest are those of the lattice row a point is on (rows of one offset pattern that differ
    /// in their gradients, as the faces of a thin beam make them, pile up in one pattern)
    int max_candidates = 16;
};

/// NSNI's three sub-points of a point in one stencil (NodalBlock::stabilization_triplets): they
/// touch the same nodes in the same order, and entry k's three gradients are the rows of one
/// symmetric matrix, g_ikj = H_k(i, j), so the entry stores its node and H_k's six distinct values
/// (00, 01, 02, 11, 12, 22): 52 bytes where three sub-point stencils take 84.
struct TripletView
{
    const index_t* offset = nullptr;
    const real_t* hess = nullptr; ///< 6 per entry
    index_t size = 0;
    index_t base = 0;
    const std::uint16_t* add_order = nullptr; ///< as StencilView's
};

struct TripletTable
{
    std::vector<index_t> point_triplet; ///< per point: its triplet stencil (empty table: none)
    std::vector<index_t> point_base;    ///< per point: the node its offsets count from
    std::vector<index_t> offsets{0};    ///< triplet stencil s: entries [offsets[s], offsets[s + 1])
    std::vector<index_t> node_offset;   ///< per entry: node - base
    std::vector<real_t> hess;           ///< 6 per entry [1/m]
    AddOrder add_order;                 ///< uniform_add_order's (none: last to first)
    std::vector<char> uniform;          ///< per batch of points: uniform_batches' (empty: none uniform)

    bool empty() const { return point_triplet.empty(); }
    index_t n_triplets() const { return static_cast<index_t>(offsets.size()) - 1; }
    index_t n_entries() const { return static_cast<index_t>(node_offset.size()); }
    void clear() { *this = TripletTable{}; }
    TripletView view(index_t p) const
    {
        const index_t s = point_triplet[static_cast<std::size_t>(p)];
        const index_t k0 = offsets[static_cast<std::size_t>(s)];
        return {node_offset.data() + k0, hess.data() + 6 * static_cast<std::size_t>(k0),
                offsets[static_cast<std::size_t>(s) + 1] - k0, point_base[static_cast<std::size_t>(p)],
                add_order.of(s)};
    }
};

/// The triplet table of an NSNI operator (sub-points 3 p + i, i = 0..2, of point p, with one
/// node list): one triplet stencil per distinct triple of `shared`'s stencils when that table
/// holds them, otherwise one per point (base 0, offsets are the node ids). Each entry keeps the
/// upper triangle of its matrix. The operator's own gradients are symmetric bit for bit; shared
/// stencils, snapped one sub-point at a time, may differ from symmetry by the sharing's
/// tolerance (10x is allowed). Empty when some entry is further from symmetric (then the force
/// pass reads the sub-point stencils).
TripletTable build_triplets(const IntegrationOperator& stab, const StencilTable& shared);

/// The triplet stencils of `table` merged where their node offsets agree and their values
/// agree within opts.relative_tolerance of the largest of the earlier one (compared newest
/// first, opts.max_candidates per offset pattern, as share_stencils does): the earlier stencil
/// is kept and the later one's points read it, so a point's values move by at most that much.
/// The same points and bases.
TripletTable share_triplets(TripletTable table, const StencilSharing& opts = {});

/// Writes the sub-point entries of `stab` from its triplet table: sub-point i of entry k gets
/// row i of the entry's symmetric matrix. It snaps an operator to its table, as sharing does,
/// and writes back the entries of a released one.
void expand_triplets(IntegrationOperator& stab, const TripletTable& table);

/// share_stencils' classes found one point at a time, in point order, for a builder that writes
/// its points' entries a block at a time and keeps only the table (build_scni_rk): each point's
/// entries are read when offered and never again, and the table holds the first point of each
/// class, as share_stencils' does. The same table, bit for bit, as share_stencils on the whole
/// operator.
class StencilSharer
{
  public:
    /// `n_points` points will be offered with `n_entries` entries in all.
    StencilSharer(index_t n_points, std::size_t n_entries, const StencilSharing& opts = {});
    /// The next point's n entries (nodes, 3 gradients each). False once the stencils stored pass
    /// opts.max_entry_fraction of the entries: sharing does not pay, and the sharer is spent.
    bool add(const index_t* nodes, const real_t* grad, index_t n);
    /// The table, once every point was added (add never returned false).
    StencilTable take();

  private:
    StencilSharing opts_;
    StencilTable t_;
    index_t next_ = 0;
    std::size_t budget_ = 0, stored_ = 0;
    std::unordered_map<std::uint64_t, std::vector<index_t>> by_offsets_; ///< offsets hash -> stencils
    std::vector<real_t> scale_; ///< per stencil: its largest |gradient component|
};

/// Finds the shared stencils of `op` and snaps its gradients to them (see the file comment).
/// Returns an empty table, and leaves `op` as it was, when sharing does not pay
/// (max_entry_fraction).
StencilTable share_stencils(IntegrationOperator& op, const StencilSharing& opts = {});
} // namespace rkfem
