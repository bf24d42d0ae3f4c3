/// @file scni_cloud.cpp
/// Nodal integration of particle clouds on Voronoi cells: SCNI (FE-style and RK), SD sub-cells,
/// DNI.
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

/// A face's sums that a cell hands on to the cell across (build_scni_cells_rk).
struct FaceSums
{
    index_t to = -1;                ///< the cell across
    int pool = 0;                   ///< in pools[pool], entries [begin, end): by particle,
    std::size_t begin = 0, end = 0; ///< ascending, where some point of the face kept it
};

/// One thread's work on build_scni_cells_rk's rows: its region values, its sums (per region
/// particle: acc / hit, the same of one face) and scratch for a merge; the cells' outboxes.
struct RowWork
{
    const VoronoiCells& cells;
    RkRegionValues& values;
    std::vector<real_t>& acc;
    std::vector<real_t>& hit;
    std::vector<real_t>& face_acc;
    std::vector<real_t>& face_hit;
    Entries& merged;
    std::vector<std::vector<FaceSums>>& outbox;
    const index_t block;

    /// Whether cells i and j share their face's sums (no further apart than a block).
    bool shared(index_t i, index_t j) const { return j >= 0 && std::abs(i - j) <= block; }

    /// the region of the box of points [q0, q1) of a cell gathered, and acc / hit zeroed over it
    std::size_t gather_region(index_t q0, index_t q1)
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
    }

    /// the region's particles that some point reached, with their sums, onto out (ascending)
    void collect_hits(Entries& out)
    {
        append_marked(out, values.region_particles().data(), acc.data(), hit.data(), values.region_size());
    }

    /// row += sign * sums[0 .. m), both by particle ascending (a merge)
    void add_sums(Entries& row, const std::pair<index_t, Vec3>* sums, std::size_t m, real_t sign)
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
    }

    /// Cell i's own faces into its row, the sums of those it hands on onto pool (my_pool) and its
    /// outbox, and the first points of those it takes from earlier cells into take.
    void own_faces(index_t i, Entries& row, std::vector<index_t>& take, Entries& pool, int my_pool)
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
                    add_point_values(values, cells.points[q].x, cells.points[q].nda, face_acc.data(), face_hit.data());
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
                    add_point_values(values, cells.points[q].x, cells.points[q].nda, acc.data(), hit.data());
            f0 = f1;
        }
        collect_hits(row);
    }
};

/// The operator's weights, positions and owners, one row per cell (the rows still to come).
void init_cell_operator(IntegrationOperator& op, const VoronoiCells& cells, const std::vector<real_t>& x, index_t n)
{
    op.weight = cells.volume;
    op.position.assign(x.begin(), x.begin() + 3 * static_cast<std::ptrdiff_t>(n));
    op.owner.resize(static_cast<std::size_t>(n));
    for (index_t i = 0; i < n; ++i)
        op.owner[i] = i;
    op.offsets.assign(1, 0);
    op.offsets.reserve(static_cast<std::size_t>(n) + 1);
}

/// The rows of cells [b0, b1) appended to op, with room for the rest where the block does not fit.
void append_block_rows(IntegrationOperator& op, std::vector<Entries>& rows, index_t b0, index_t b1, index_t n)
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
}
} // namespace

IntegrationOperator build_scni_cells_rk(const VoronoiCells& cells, const std::vector<real_t>& x,
                                        const RkShapeFunctions& rk, real_t drop_tolerance, index_t block)
{
    RKFEM_REQUIRE(block > 0, "build_scni_cells_rk: blocks of " << block << " cells");
    const index_t n = cells.size();
    IntegrationOperator op;
    init_cell_operator(op, cells, x, n);
    // The rows a block of cells at a time, appended in cell order as they come. A face between
    // cells i < j no further apart than a block is evaluated once, by i: its points are the same
    // from both sides (each triangle of a face's centroid fan is an edge and the centroid, up to
    // the vertices' round-off) and j's normals are i's reversed, so i hands j its face sums
    // (particle, sum psi n dA) and j subtracts them instead of evaluating the face again. A face
    // that i does not see (a sliver one side's round-off kept) j evaluates itself.
    // The sums go to a pool per thread and block parity, reused two blocks on (a block's cells
    // take only from their own block and the one before): sums held in vectors of their own came
    // back from the heap fragmented and raised the set-up's peak by a tenth.
    std::vector<std::vector<FaceSums>> outbox(static_cast<std::size_t>(n)); // per cell: its faces' sums for later cells
    std::vector<Entries> pools(2 * static_cast<std::size_t>(omp_get_max_threads()));
    std::vector<Entries> rows(static_cast<std::size_t>(std::min(n, block)));
    std::vector<std::vector<index_t>> taken(
        rows.size()); // per cell of the block: its faces' first points, to take from earlier cells
    ParallelErrors errors;
#pragma omp parallel
    {
        RkRegionValues values(rk, drop_tolerance);
        // per region particle: sum psi n dA [component][particle], hit (0 / 1); the same of one face
        std::vector<real_t> acc, hit, face_acc, face_hit;
        Entries merged;
        RowWork work{cells, values, acc, hit, face_acc, face_hit, merged, outbox, block};
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
                    work.own_faces(i, row, take, pool, my_pool);
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
                            work.add_sums(row, pools[static_cast<std::size_t>(from->pool)].data() + from->begin,
                                          from->end - from->begin, -1.0);
                            continue;
                        }
                        const index_t f1 = cells.face_end(i, f0);
                        work.gather_region(f0, f1);
                        for (index_t q = f0; q < f1; ++q)
                            add_point_values(values, cells.points[q].x, cells.points[q].nda, acc.data(), hit.data());
                        Entries own;
                        work.collect_hits(own);
                        work.add_sums(row, own.data(), own.size(), 1.0);
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
                append_block_rows(op, rows, b0, b1, n);
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

} // namespace rkfem
