/// @file nodal_block_coupled.cpp
/// Coupled parts: FE, transition and RK elements in one nodal block, built and updated as
/// conversion changes the RK elements.
#include "rkfem/model/nodal_block_build_detail.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <map>
#include <memory>
#include <optional>

#include <omp.h>

#include "rkfem/approximation/coupling/coupled_shapes.hpp"
#include "rkfem/approximation/rk/rk_region_values.hpp"
#include "rkfem/approximation/shape_evaluator.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/setup_progress.hpp"
#include "rkfem/discretization/cell_list.hpp"
#include "rkfem/discretization/voronoi_cells.hpp"
#include "rkfem/integration/nodal/nodal_integration.hpp"

namespace rkfem
{
using namespace nodal_build_detail;

namespace
{
/// The coupled shapes seen through a sub-mesh of some of the part's elements: element e of the
/// sub-mesh is element elements[e] of the part (node ids stay the part's).
class SubMeshShapes final : public ShapeEvaluator
{
  public:
    SubMeshShapes(const CoupledShapes& shapes, const std::vector<index_t>& elements) : s_(shapes), e_(elements) {}
    void values(index_t e, const Vec3& xi, const Vec3& x, std::vector<index_t>& nodes,
                std::vector<real_t>& psi) const override
    {
        s_.values(e_[static_cast<std::size_t>(e)], xi, x, nodes, psi);
    }
    void gradients_at_node(index_t i, std::vector<index_t>& nodes, std::vector<Vec3>& grad) const override
    {
        s_.gradients_at_node(i, nodes, grad);
    }
    void focus(index_t e, const Vec3& lo, const Vec3& hi) const override
    {
        s_.focus(e_[static_cast<std::size_t>(e)], lo, hi);
    }

  private:
    const CoupledShapes& s_;
    const std::vector<index_t>& e_;
};
} // namespace

namespace
{
/// Does a coupled part's nodal block carry MSCNI's stabilization?
bool coupled_mscni(const PartSpec& ps)
{
    return ps.nodal.stabilization == "mscni" && ps.nodal.stabilization_coefficient > 0;
}

/// The block's per-node particle and per-element FE flags from the shapes.
void set_coupled_flags(const CoupledShapes& shapes, index_t nn, index_t ne, NodalBlock& nb)
{
    nb.particle.resize(static_cast<std::size_t>(nn));
    nb.fe_element.resize(static_cast<std::size_t>(ne));
    for (index_t i = 0; i < nn; ++i)
        nb.particle[i] = shapes.is_particle(i);
    for (index_t e = 0; e < ne; ++e)
        nb.fe_element[e] = shapes.kind(e) == CoupledShapes::Kind::Fe;
}

/// The part's elements with keep[e] != 0 as a mesh of their own: element k is elements[k] of the
/// part (element_to_sub the inverse, -1 for the others), node j is sub_to_part[j] (part_to_sub the
/// inverse), boundary faces extracted.
struct SubMesh
{
    HexMesh mesh;
    std::vector<index_t> elements, element_to_sub, sub_to_part, part_to_sub;
};
SubMesh sub_mesh(const HexMesh& mesh, const std::vector<char>& keep)
{
    SubMesh s;
    s.element_to_sub.assign(static_cast<std::size_t>(mesh.n_elements()), -1);
    s.part_to_sub.assign(static_cast<std::size_t>(mesh.n_nodes()), -1);
    for (index_t e = 0; e < mesh.n_elements(); ++e)
    {
        if (!keep[e])
            continue;
        s.element_to_sub[e] = static_cast<index_t>(s.elements.size());
        s.elements.push_back(e);
        for (int a = 0; a < 8; ++a)
        {
            const index_t i = mesh.conn[8 * e + a];
            if (s.part_to_sub[i] < 0)
            {
                s.part_to_sub[i] = static_cast<index_t>(s.sub_to_part.size());
                s.sub_to_part.push_back(i);
                for (int d = 0; d < 3; ++d)
                    s.mesh.x.push_back(mesh.x[3 * i + d]);
            }
            s.mesh.conn.push_back(s.part_to_sub[i]);
        }
    }
    s.mesh.faces = extract_boundary_faces(s.mesh.conn);
    return s;
}
} // namespace

NodalBlock build_coupled_block(const PartSpec& ps, const HexMesh& mesh, index_t offset, const std::vector<char>* rk_set,
                               std::shared_ptr<KccScaleCache> scales)
{
    const std::vector<char> rk_elements = rk_set ? *rk_set : rk_region_elements(ps, mesh);
    index_t n_rk = 0;
    for (char c : rk_elements)
        n_rk += c;
    if (n_rk == 0 && ps.converts())
    {
        // no RK element yet: nodal-integrated FE on the same cells as a coupled block's; with a
        // fem-1pt FE side, no point (every element is the side's)
        NodalBlock nb = block_frame(ps, mesh.n_nodes(), offset, std::move(scales));
        const FemShapes shapes(mesh);
        const bool stabilized = coupled_mscni(ps);
        if (ps.formulation == Formulation::FemNodal && stabilized)
        {
            IntegrationOperator sd;
            build_scni_sd(mesh, shapes, nb.points, &sd);
            nb.stabilization = build_mscni_stabilization(nb.points, sd);
        }
        else if (ps.formulation == Formulation::FemNodal)
            nb.points = build_scni(mesh, shapes);
        if (stabilized)
            nb.stabilization_coefficient = ps.nodal.stabilization_coefficient;
        nb.particle.assign(static_cast<std::size_t>(mesh.n_nodes()), 0);
        nb.fe_element.assign(static_cast<std::size_t>(mesh.n_elements()), 1);
        // physical values: identity rows
        nb.interp_offsets.resize(static_cast<std::size_t>(mesh.n_nodes()) + 1);
        for (index_t i = 0; i <= mesh.n_nodes(); ++i)
            nb.interp_offsets[i] = i;
        for (index_t i = 0; i < mesh.n_nodes(); ++i)
            nb.interp_nodes.push_back(i + offset);
        nb.interp_values.assign(static_cast<std::size_t>(mesh.n_nodes()), 1.0);
        const std::vector<real_t> l0 = nodal_spacing(mesh, false);
        finish_block(nb, offset, l0, l0);
        return nb;
    }
    if (!rk_set && (n_rk == 0 || n_rk == mesh.n_elements()))
        throw DeckError(ps.regions_loc,
                        n_rk == 0 ? "contain no element centroid of the part"
                                  : "contain every element of the part, leaving no FE region",
                        n_rk == 0 ? "expected regions that hold some of the part's elements"
                                  : "expected formulation: rkpm for an all-RK part, or smaller regions");
    NodalBlock nb = block_frame(ps, mesh.n_nodes(), offset, std::move(scales));
    const Transition t = ps.transition == "ramp" ? Transition::Ramp : Transition::Mixed;
    try
    {
        const CoupledShapes shapes(mesh, rk_elements, rk_params(ps.rk), t);
        const bool stabilized = coupled_mscni(ps);
        if (ps.formulation == Formulation::FemNodal)
        {
            // every node's dual cell
            IntegrationOperator sd;
            build_scni_sd(mesh, shapes, nb.points, stabilized ? &sd : nullptr);
            if (stabilized)
                nb.stabilization = build_mscni_stabilization(nb.points, sd);
        }
        else
        {
            // fem-1pt FE side: the FE elements are the part's 1-point block; the nodes of the
            // transition and RK elements get the dual cells of those elements only (their faces
            // with FE elements are the cells' boundary), on a sub-mesh with its own numbering
            std::vector<char> keep(static_cast<std::size_t>(mesh.n_elements()));
            for (index_t e = 0; e < mesh.n_elements(); ++e)
                keep[e] = shapes.kind(e) != CoupledShapes::Kind::Fe;
            const SubMesh sm = sub_mesh(mesh, keep);
            const SubMeshShapes sub_shapes(shapes, sm.elements);
            IntegrationOperator sd;
            build_scni_sd(sm.mesh, sub_shapes, nb.points, stabilized ? &sd : nullptr);
            if (stabilized)
                nb.stabilization = build_mscni_stabilization(nb.points, sd);
            // owners to the part's numbering (the gradients' nodes already are)
            for (auto* op : {&nb.points, &nb.stabilization})
                for (auto& o : op->owner)
                    o = sm.sub_to_part[static_cast<std::size_t>(o)];
        }
        if (stabilized)
            nb.stabilization_coefficient = ps.nodal.stabilization_coefficient;
        // physical values: identity at FE nodes, the RK interpolant at particles
        nb.interp_offsets.assign(1, 0);
        std::vector<index_t> row_nodes;
        std::vector<real_t> row_values;
        for (index_t i = 0; i < mesh.n_nodes(); ++i)
        {
            row_nodes.clear();
            row_values.clear();
            shapes.node_row(i, row_nodes, row_values);
            for (std::size_t k = 0; k < row_nodes.size(); ++k)
            {
                nb.interp_nodes.push_back(row_nodes[k] + offset);
                nb.interp_values.push_back(row_values[k]);
            }
            nb.interp_offsets.push_back(static_cast<index_t>(nb.interp_nodes.size()));
        }
        set_coupled_flags(shapes, mesh.n_nodes(), mesh.n_elements(), nb);
    }
    catch (const SingularMomentError& e)
    {
        throw singular_support(ps, e);
    }
    const std::vector<real_t> l0 = nodal_spacing(mesh, false);
    finish_block(nb, offset, l0, l0);
    return nb;
}

namespace
{
/// Replaces the rows of op's points with replace[p] by rows of `from` (point from_point[p]).
void splice_rows(IntegrationOperator& op, const std::vector<char>& replace, const IntegrationOperator& from,
                 const std::vector<index_t>& from_point)
{
    // In place: the runs of kept rows between replaced ones shift by a constant each. Runs that
    // move left go first, front to back, then those that move right, back to front: a run's
    // destination never meets the source of a run not yet moved (the offsets stay in order).
    // The replaced rows are written last. No fresh operator-sized arrays (at P5 1 in the MSCNI
    // operator is about 0.5 GB: allocated, zeroed and copied per event it cost more than the rebuild).
    const index_t np = op.n_points();
    std::vector<index_t> offsets(static_cast<std::size_t>(np) + 1, 0);
    for (index_t p = 0; p < np; ++p)
    {
        const index_t n = replace[p] ? from.offsets[from_point[p] + 1] - from.offsets[from_point[p]]
                                     : op.offsets[p + 1] - op.offsets[p];
        offsets[p + 1] = offsets[p] + n;
    }
    struct Run
    {
        index_t begin, end, to; ///< old entries [begin, end) go to entry `to`
    };
    std::vector<Run> runs;
    for (index_t p = 0; p < np;)
    {
        if (replace[p])
        {
            ++p;
            continue;
        }
        index_t end = p + 1;
        while (end < np && !replace[end])
            ++end;
        if (op.offsets[p] != offsets[p] && op.offsets[end] > op.offsets[p])
            runs.push_back({op.offsets[p], op.offsets[end], offsets[p]});
        p = end;
    }
    const std::size_t old_n = op.nodes.size(), new_n = static_cast<std::size_t>(offsets[np]);
    if (new_n > old_n)
    {
        // room for the next events too (conversion grows the stencils event after event: grown
        // to the size, the arrays were reallocated, their pages faulted in and copied every time)
        if (new_n > op.nodes.capacity())
        {
            op.nodes.reserve(new_n + new_n / 4);
            op.grad.reserve(3 * (new_n + new_n / 4));
        }
        op.nodes.resize(new_n);
        op.grad.resize(3 * new_n);
    }
    // a run's entries (width 1 in nodes, 3 in grad) to their new place, copied from the end
    // where they move right over themselves
    auto shift = [](auto& v, std::ptrdiff_t width, const Run& r)
    {
        const auto first = v.begin() + width * r.begin, last = v.begin() + width * r.end, to = v.begin() + width * r.to;
        if (r.to < r.begin)
            std::copy(first, last, to);
        else
            std::copy_backward(first, last, to + (last - first));
    };
    for (const Run& r : runs)
        if (r.to < r.begin)
        {
            shift(op.nodes, 1, r);
            shift(op.grad, 3, r);
        }
    for (auto it = runs.rbegin(); it != runs.rend(); ++it)
        if (it->to > it->begin)
        {
            shift(op.nodes, 1, *it);
            shift(op.grad, 3, *it);
        }
    if (new_n < old_n)
    {
        op.nodes.resize(new_n);
        op.grad.resize(3 * new_n);
    }
    for (index_t p = 0; p < np; ++p)
        if (replace[p])
        {
            const index_t q = from_point[p];
            const index_t b = from.offsets[q], e = from.offsets[q + 1];
            std::copy(from.nodes.begin() + b, from.nodes.begin() + e, op.nodes.begin() + offsets[p]);
            std::copy(from.grad.begin() + 3 * static_cast<std::ptrdiff_t>(b),
                      from.grad.begin() + 3 * static_cast<std::ptrdiff_t>(e),
                      op.grad.begin() + 3 * static_cast<std::ptrdiff_t>(offsets[p]));
            op.weight[p] = from.weight[q];
            for (int d = 0; d < 3; ++d)
                op.position[3 * p + d] = from.position[3 * q + d];
        }
    op.offsets = std::move(offsets);
}
} // namespace

namespace
{
/// Where the approximation changes from RK set rk_old to rk_new (update_coupled_block): the nodes
/// whose points change (those of elements whose kind changes, and of transition and RK elements
/// that the support of a particle that appears, disappears or changes its radius reaches, both
/// radii), and every element around them (those that name one of these nodes).
struct ChangeRegion
{
    std::vector<char> node_changes, around;
};
ChangeRegion change_region(const HexMesh& mesh, const RkParams& params, const std::vector<char>& rk_old,
                           const std::vector<char>& rk_new)
{
    const index_t ne = mesh.n_elements(), nn = mesh.n_nodes();
    auto layout = [&](const std::vector<char>& rk)
    {
        for (char c : rk)
            if (c)
                return coupled_layout(mesh, rk, params);
        CoupledLayout all_fe;
        all_fe.kind.assign(static_cast<std::size_t>(ne), CoupledShapes::Kind::Fe);
        all_fe.radius.assign(static_cast<std::size_t>(nn), 0.0);
        return all_fe;
    };
    const CoupledLayout before = layout(rk_old), after = layout(rk_new);
    // particles that appear, disappear or change their support, with the larger radius
    std::vector<index_t> changed;
    std::vector<real_t> changed_x, reach;
    real_t reach_max = 0.0;
    for (index_t i = 0; i < nn; ++i)
        if (before.radius[i] != after.radius[i])
        {
            changed.push_back(i);
            for (int d = 0; d < 3; ++d)
                changed_x.push_back(mesh.x[3 * i + d]);
            reach.push_back(std::max(before.radius[i], after.radius[i]));
            reach_max = std::max(reach_max, reach.back());
        }
    // elements whose approximation changes: another kind, or a transition or RK element whose
    // box meets a changed particle's support box (a box contains the sphere of a sphere support)
    std::vector<char> affected(static_cast<std::size_t>(ne), 0);
    std::vector<Vec3> lo(static_cast<std::size_t>(ne)), hi(static_cast<std::size_t>(ne));
    real_t half_max = 0.0;
    for (index_t e = 0; e < ne; ++e)
    {
        lo[e] = hi[e] = mesh.node(mesh.conn[8 * e]);
        for (int a = 1; a < 8; ++a)
        {
            lo[e] = lo[e].cwiseMin(mesh.node(mesh.conn[8 * e + a]));
            hi[e] = hi[e].cwiseMax(mesh.node(mesh.conn[8 * e + a]));
        }
        half_max = std::max(half_max, 0.5 * (hi[e] - lo[e]).maxCoeff());
        affected[e] = before.kind[e] != after.kind[e];
    }
    if (!changed.empty())
    {
        const CellList bins(changed_x, reach_max + half_max);
        for (index_t e = 0; e < ne; ++e)
        {
            if (affected[e] || after.kind[e] == CoupledShapes::Kind::Fe)
                continue;
            bins.for_each_candidate(0.5 * (lo[e] + hi[e]),
                                    [&](index_t j)
                                    {
                                        const Vec3 x(changed_x[3 * j], changed_x[3 * j + 1], changed_x[3 * j + 2]);
                                        if (((lo[e].array() - reach[j]) <= x.array()).all() &&
                                            (x.array() <= (hi[e].array() + reach[j])).all())
                                            affected[e] = 1;
                                    });
        }
    }
    // the nodes whose points change, and every element around them
    ChangeRegion r;
    std::vector<char>& node_changes = r.node_changes;
    node_changes.assign(static_cast<std::size_t>(nn), 0);
    for (index_t e = 0; e < ne; ++e)
        if (affected[e])
            for (int a = 0; a < 8; ++a)
                node_changes[mesh.conn[8 * e + a]] = 1;
    std::vector<char>& around = r.around;
    around.assign(static_cast<std::size_t>(ne), 0);
    for (index_t e = 0; e < ne; ++e)
        for (int a = 0; a < 8; ++a)
            around[e] = around[e] || node_changes[mesh.conn[8 * e + a]];
    return r;
}

/// The physical-value rows of the nodes with node_changes[i], appended to rows (columns global).
void changed_rows(const CoupledShapes& shapes, const std::vector<char>& node_changes, index_t offset, ChangedRows& rows)
{
    std::vector<index_t> row_nodes;
    std::vector<real_t> row_values;
    for (index_t i = 0; i < static_cast<index_t>(node_changes.size()); ++i)
    {
        if (!node_changes[i])
            continue;
        row_nodes.clear();
        row_values.clear();
        shapes.node_row(i, row_nodes, row_values);
        rows.node.push_back(i);
        for (std::size_t k = 0; k < row_nodes.size(); ++k)
        {
            rows.columns.push_back(row_nodes[k] + offset);
            rows.values.push_back(row_values[k]);
        }
        rows.offsets.push_back(static_cast<index_t>(rows.columns.size()));
    }
}
} // namespace

ChangedRows update_coupled_block(const PartSpec& ps, const HexMesh& mesh, index_t offset,
                                 const std::vector<char>& rk_old, const std::vector<char>& rk_new, NodalBlock& nb)
{
    const index_t ne = mesh.n_elements(), nn = mesh.n_nodes();
    const RkParams params = rk_params(ps.rk);
    const ChangeRegion region = change_region(mesh, params, rk_old, rk_new);
    const std::vector<char>& node_changes = region.node_changes;
    const SubMesh sm = sub_mesh(mesh, region.around);
    ChangedRows rows;
    if (sm.elements.empty())
        return rows;
    const Transition t = ps.transition == "ramp" ? Transition::Ramp : Transition::Mixed;
    try
    {
        const CoupledShapes shapes(mesh, rk_new, params, t);
        const SubMeshShapes sub_shapes(shapes, sm.elements);
        IntegrationOperator scni, sd;
        build_scni_sd(sm.mesh, sub_shapes, scni, nb.n_stab() > 0 ? &sd : nullptr);
        for (auto& n : scni.nodes)
            n += offset;
        // SCNI: point p is node p
        std::vector<index_t> from(static_cast<std::size_t>(nn), -1);
        for (index_t i = 0; i < nn; ++i)
            if (node_changes[i])
                from[i] = sm.part_to_sub[i];
        splice_rows(nb.points, node_changes, scni, from);
        if (nb.n_stab() > 0)
        {
            // MSCNI: sub-cell 8 e + a of the node conn[8 e + a]; the sub-mesh's 8 k + a
            for (auto& n : sd.nodes)
                n += offset;
            const IntegrationOperator stab = build_mscni_stabilization(scni, sd);
            std::vector<char> replace(static_cast<std::size_t>(nb.n_stab()), 0);
            std::vector<index_t> from_stab(replace.size(), -1);
            for (index_t e = 0; e < ne; ++e)
                for (int a = 0; a < 8; ++a)
                    if (node_changes[mesh.conn[8 * e + a]])
                    {
                        replace[8 * e + a] = 1;
                        from_stab[8 * e + a] = 8 * sm.element_to_sub[e] + a;
                    }
            splice_rows(nb.stabilization, replace, stab, from_stab);
        }
        changed_rows(shapes, node_changes, offset, rows);
        set_coupled_flags(shapes, nn, ne, nb);
    }
    catch (const SingularMomentError& e)
    {
        throw singular_support(ps, e);
    }
    nb.build_tables();
    return rows;
}

namespace
{
/// Row q of `from` appended to `to` (weight, position, entries), its nodes less `shift`.
void copy_row(IntegrationOperator& to, const IntegrationOperator& from, index_t q, index_t shift)
{
    for (index_t k = from.offsets[q]; k < from.offsets[q + 1]; ++k)
    {
        to.nodes.push_back(from.nodes[k] - shift);
        for (int d = 0; d < 3; ++d)
            to.grad.push_back(from.grad[3 * k + d]);
    }
    to.offsets.push_back(static_cast<index_t>(to.nodes.size()));
    to.weight.push_back(from.weight[q]);
    for (int d = 0; d < 3; ++d)
        to.position.push_back(from.position[3 * q + d]);
}

} // namespace

std::vector<index_t> coupled_sub_cell_ranks(const std::vector<char>& fe_element)
{
    std::vector<index_t> rank(fe_element.size(), -1);
    index_t k = 0;
    for (std::size_t e = 0; e < fe_element.size(); ++e)
        if (!fe_element[e])
            rank[e] = k++;
    return rank;
}

NodalBlock update_fe_side_block(const PartSpec& ps, const HexMesh& mesh, index_t offset,
                                const std::vector<char>& rk_old, const std::vector<char>& rk_new, const NodalBlock& old,
                                ChangedRows& rows, std::shared_ptr<KccScaleCache> scales)
{
    const index_t ne = mesh.n_elements(), nn = mesh.n_nodes();
    RKFEM_REQUIRE(std::find(rk_new.begin(), rk_new.end(), char{1}) != rk_new.end(),
                  "update_fe_side_block: part '" << ps.name << "' has no RK element (build it whole)");
    rows = ChangedRows{};
    const RkParams params = rk_params(ps.rk);
    const ChangeRegion region = change_region(mesh, params, rk_old, rk_new);
    const std::vector<char>& node_changes = region.node_changes;
    NodalBlock nb = block_frame(ps, nn, offset, std::move(scales));
    const bool stabilized = coupled_mscni(ps);
    if (stabilized)
        nb.stabilization_coefficient = ps.nodal.stabilization_coefficient;
    const Transition t = ps.transition == "ramp" ? Transition::Ramp : Transition::Mixed;
    try
    {
        const CoupledShapes shapes(mesh, rk_new, params, t);
        // the block's elements (transition and RK) and, among them, those around a changed node:
        // the changed nodes' cells are whole there (every element of such a node is around it)
        std::vector<char> keep(static_cast<std::size_t>(ne)), local(static_cast<std::size_t>(ne));
        for (index_t e = 0; e < ne; ++e)
        {
            keep[e] = shapes.kind(e) != CoupledShapes::Kind::Fe;
            local[e] = keep[e] && region.around[e];
        }
        const SubMesh sm = sub_mesh(mesh, local);
        IntegrationOperator scni, sd, stab;
        if (!sm.elements.empty())
        {
            const SubMeshShapes sub_shapes(shapes, sm.elements);
            build_scni_sd(sm.mesh, sub_shapes, scni, stabilized ? &sd : nullptr);
            if (stabilized)
                stab = build_mscni_stabilization(scni, sd);
        }
        // the old block's point of each node (-1: none) and its elements' sub-cell ranks
        std::vector<index_t> old_point(static_cast<std::size_t>(nn), -1);
        for (index_t i = 0; i + 1 < static_cast<index_t>(old.owner_offsets.size()); ++i)
            if (old.owner_offsets[i + 1] > old.owner_offsets[i])
                old_point[i] = old.owner_points[old.owner_offsets[i]];
        const std::vector<index_t> old_rank = coupled_sub_cell_ranks(old.fe_element);
        // the points: one per node of the block's elements, in the order the elements name them
        std::vector<index_t> point_of(static_cast<std::size_t>(nn), -1), order;
        for (index_t e = 0; e < ne; ++e)
            if (keep[e])
                for (int a = 0; a < 8; ++a)
                {
                    const index_t i = mesh.conn[8 * e + a];
                    if (point_of[i] < 0)
                    {
                        point_of[i] = static_cast<index_t>(order.size());
                        order.push_back(i);
                    }
                }
        auto reserve = [](IntegrationOperator& op, index_t n_points, std::size_t n_entries)
        {
            op.weight.reserve(static_cast<std::size_t>(n_points));
            op.position.reserve(3 * static_cast<std::size_t>(n_points));
            op.owner.reserve(static_cast<std::size_t>(n_points));
            op.offsets.reserve(static_cast<std::size_t>(n_points) + 1);
            op.nodes.reserve(n_entries);
            op.grad.reserve(3 * n_entries);
        };
        reserve(nb.points, static_cast<index_t>(order.size()), old.points.nodes.size() + scni.nodes.size());
        for (const index_t i : order)
        {
            if (node_changes[i])
                copy_row(nb.points, scni, sm.part_to_sub[i], 0);
            else
            {
                RKFEM_REQUIRE(old_point[i] >= 0, "fem-1pt conversion: node " << i << " of part '" << ps.name
                                                                             << "' keeps its cell but had no point");
                copy_row(nb.points, old.points, old_point[i], offset);
            }
            nb.points.owner.push_back(i);
        }
        if (stabilized)
        {
            // MSCNI: sub-cell 8 rank + a of each of the block's elements, in element order
            index_t n_keep = 0;
            for (char k : keep)
                n_keep += k;
            reserve(nb.stabilization, 8 * n_keep, old.stabilization.nodes.size() + stab.nodes.size());
            nb.stabilization.parent.reserve(8 * static_cast<std::size_t>(n_keep));
            for (index_t e = 0; e < ne; ++e)
            {
                if (!keep[e])
                    continue;
                for (int a = 0; a < 8; ++a)
                {
                    const index_t i = mesh.conn[8 * e + a];
                    if (node_changes[i])
                        copy_row(nb.stabilization, stab, 8 * sm.element_to_sub[e] + a, 0);
                    else
                    {
                        RKFEM_REQUIRE(old_rank[e] >= 0 && old.n_stab() > 0,
                                      "fem-1pt conversion: element " << e << " of part '" << ps.name
                                                                     << "' keeps its sub-cells but had none");
                        copy_row(nb.stabilization, old.stabilization, 8 * old_rank[e] + a, offset);
                    }
                    nb.stabilization.owner.push_back(i);
                    nb.stabilization.parent.push_back(point_of[i]);
                }
            }
        }
        changed_rows(shapes, node_changes, offset, rows);
        set_coupled_flags(shapes, nn, ne, nb);
    }
    catch (const SingularMomentError& e)
    {
        throw singular_support(ps, e);
    }
    const std::vector<real_t> l0 = nodal_spacing(mesh, false);
    finish_block(nb, offset, l0, l0);
    return nb;
}

} // namespace rkfem
