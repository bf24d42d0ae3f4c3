// Shared stencils (integration/stencil_table.hpp): the classes a lattice must give, what the
// snap may move, that the snapped operator keeps linear completeness and the integration
// constraint, that a jittered cloud keeps its own stencils, and that the force pass reads the
// table exactly as it would read the operator.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include <omp.h>

#include "nodal_common.hpp"
#include "rkfem/approximation/rk/kinematic_map.hpp"
#include "rkfem/discretization/generators.hpp"
#include "rkfem/integration/stencil_table.hpp"
#include "rkfem/model/nodal_block_build.hpp"
#include "rkfem/operators/nodal_block.hpp"
#include "rkfem/operators/nodal_force.hpp"

using namespace rkfem;
using namespace rkfem::test;

namespace
{
/// An elastic concrete-like RK part with the given stabilization.
PartSpec elastic_rk_part(const char* stabilization)
{
    PartSpec ps;
    ps.formulation = Formulation::Rkpm;
    ps.material.model = "elastic";
    ps.material.rho = 2400.0;
    ps.material.E = 30e9;
    ps.material.nu = 0.2;
    ps.nodal.stabilization = stabilization;
    return ps;
}

/// The mesh's nodes with a smooth, non-polynomial displacement and velocity.
NodeSet wavy_motion(const HexMesh& mesh)
{
    NodeSet nodes;
    nodes.resize(mesh.n_nodes());
    nodes.x0 = nodes.x = mesh.x;
    for (std::size_t i = 0; i < mesh.x.size(); ++i)
    {
        nodes.v[i] = std::sin(300.0 * mesh.x[i] + static_cast<real_t>(i % 3));
        nodes.u[i] = 1e-5 * std::cos(200.0 * mesh.x[i] + static_cast<real_t>(i % 5));
    }
    return nodes;
}

/// max over nodes of |sum_p V_p g_I(p)| h / V outside the boundary layer of width `layer`: the
/// integration constraint, whose boundary term vanishes for nodes whose functions do not reach
/// the surface.
real_t interior_divergence_error(const HexMesh& mesh, const IntegrationOperator& op, real_t h, real_t layer)
{
    std::vector<Vec3> sum(static_cast<std::size_t>(mesh.n_nodes()), Vec3::Zero());
    real_t vol = 0.0;
    for (index_t p = 0; p < op.n_points(); ++p)
    {
        vol += op.weight[p];
        for (index_t k = op.offsets[p]; k < op.offsets[p + 1]; ++k)
            sum[op.nodes[k]] += op.weight[p] * op.gradient(k);
    }
    const Vec3 hi = mesh.node(mesh.n_nodes() - 1);
    real_t err = 0.0;
    for (index_t i = 0; i < mesh.n_nodes(); ++i)
    {
        const Vec3 x = mesh.node(i);
        if ((x.array() > layer).all() && (x.array() < hi.array() - layer).all())
            err = std::max(err, sum[i].norm());
    }
    return err * h / vol;
}

/// The largest |g_snapped - g_own| / max |g_own| over the points' stencils.
real_t largest_snap(const IntegrationOperator& own, const IntegrationOperator& snapped)
{
    real_t worst = 0.0;
    for (index_t p = 0; p < own.n_points(); ++p)
    {
        real_t scale = 0.0, diff = 0.0;
        for (index_t k = 3 * own.offsets[p]; k < 3 * own.offsets[p + 1]; ++k)
        {
            scale = std::max(scale, std::abs(own.grad[k]));
            diff = std::max(diff, std::abs(snapped.grad[k] - own.grad[k]));
        }
        worst = std::max(worst, diff / scale);
    }
    return worst;
}

/// Full batches of 8 points with one class and consecutive bases (the whole-vector path).
index_t uniform_batches(index_t n_points, const std::vector<index_t>& cls, const std::vector<index_t>& base)
{
    index_t n = 0;
    for (index_t b = 0; b < n_points / 8; ++b)
    {
        bool same = true;
        for (int l = 1; l < 8; ++l)
            same = same && cls[8 * b + l] == cls[8 * b] && base[8 * b + l] == base[8 * b] + l;
        n += same;
    }
    return n;
}

/// One force pass of `blk` from `nodes` (and its assembly), and what it wrote.
struct PassBits
{
    ForcePassResult r;
    std::vector<real_t> f, stab_stress, stab_energy;
    LineVector<real_t> stress;
};
PassBits pass_bits(NodalBlock& blk, NodeSet& nodes, real_t dt)
{
    PassBits p;
    p.r = nodal_internal_force(blk, nodes, dt);
    assemble_nodal_forces(blk, nodes);
    p.f = nodes.f_int;
    p.stress = blk.stress_trial;
    p.stab_stress = blk.stab_stress_trial;
    p.stab_energy = blk.stab_energy;
    return p;
}
/// Two passes gave the same bits.
void expect_same_bits(const PassBits& a, const PassBits& b, const std::string& name)
{
    EXPECT_EQ(a.f, b.f) << name;
    EXPECT_TRUE(a.stress == b.stress) << name;
    EXPECT_EQ(a.stab_stress, b.stab_stress) << name;
    EXPECT_EQ(a.stab_energy, b.stab_energy) << name;
    EXPECT_EQ(a.r.d_internal, b.r.d_internal) << name;
    EXPECT_EQ(a.r.d_hourglass, b.r.d_hourglass) << name;
    EXPECT_EQ(a.r.dt_stable, b.r.dt_stable) << name;
}

IntegrationOperator scni_on(const HexMesh& mesh, Formulation f, real_t support)
{
    if (f == Formulation::FemNodal)
        return build_scni(mesh, FemShapes(mesh));
    RkParams rp;
    rp.normalized_support = support;
    return build_scni(mesh, RkShapes(rkfem::rk_on_mesh(mesh, rp)));
}
} // namespace

// On an n^3 lattice a point's SCNI stencil depends only on the nodes within the reach of its
// cell's functions (cell half-width + the moment matrices' support): about 1.75 h for a/h 1.25
// and 2.01 h for a/h 1.51 and for fem-nodal 1.5 h. Per axis, the points closer than that to a face
// differ and the rest are translates: 3 classes per axis (faces, interior) for a/h 1.25 and
// FE, 5 for a/h 1.51, so exactly 27 and 125 stencils.
TEST(StencilTable, LatticeSharesOneStencilPerBoundaryClass)
{
    const int n = 14;
    const real_t h = 0.01;
    const HexMesh mesh = generate_box(Vec3::Zero(), Vec3::Constant(n * h), {n, n, n});
    struct Case
    {
        const char* name;
        Formulation f;
        real_t support;
        index_t classes;
    };
    for (const Case& c :
         {Case{"rkpm a/h 1.25", Formulation::Rkpm, 1.25, 27}, Case{"rkpm a/h 1.51", Formulation::Rkpm, 1.51, 125},
          Case{"fem-nodal", Formulation::FemNodal, 0.0, 27}})
    {
        const IntegrationOperator own = scni_on(mesh, c.f, c.support);
        IntegrationOperator op = own;
        const StencilTable t = share_stencils(op);
        ASSERT_FALSE(t.empty()) << c.name;
        EXPECT_EQ(t.n_stencils(), c.classes) << c.name;
        // the table is the snapped operator, entry for entry and bit for bit
        for (index_t p = 0; p < op.n_points(); ++p)
        {
            const StencilView s = t.view(p);
            ASSERT_EQ(s.size, op.offsets[p + 1] - op.offsets[p]);
            for (index_t k = 0; k < s.size; ++k)
            {
                const index_t e = op.offsets[p] + k;
                ASSERT_EQ(s.base + s.offset[k], op.nodes[e]);
                for (int d = 0; d < 3; ++d)
                    ASSERT_EQ(s.grad[3 * k + d], op.grad[3 * e + d]);
            }
        }
        const real_t snap = largest_snap(own, op);
        const real_t c_own = linear_gradient_error(mesh, own, h), c_shared = linear_gradient_error(mesh, op, h);
        const real_t layer = 2.6 * h; // beyond the reach of every function of the boundary nodes
        const real_t d_own = interior_divergence_error(mesh, own, h, layer),
                     d_shared = interior_divergence_error(mesh, op, h, layer);
        std::printf("%-14s %d stencils for %d points (%.1f%% of the entries); largest snap %.2e; completeness "
                    "%.4e -> %.4e; interior divergence %.2e -> %.2e\n",
                    c.name, t.n_stencils(), op.n_points(), 100.0 * t.n_entries() / op.n_entries(), snap, c_own,
                    c_shared, d_own, d_shared);
        // the snap stays within the tolerance it was given, and here within the round-off of
        // building the stencils (coordinates up to 14 h from the origin)
        EXPECT_LE(snap, 1e-13);
        // linear completeness stays at the round-off of sum X_I g_I (terms 14 times the result):
        // the kept stencils are translates built nearer the origin
        EXPECT_LT(c_shared, 2.0 * c_own);
        EXPECT_LT(c_shared, 1e-12);
        // the integration constraint: each V_p g moves by at most snap V_p / h, and a node sums
        // at most 125 points, so the normalized sum moves by under 125 snap / n_points, 1e-15
        EXPECT_LT(d_shared, 1e-15);
    }
}

TEST(StencilTable, JitteredCloudKeepsItsOwnStencils)
{
    const HexMesh mesh = distorted_box(8, 0.01, 0.3);
    const IntegrationOperator own = scni_on(mesh, Formulation::Rkpm, 1.25);
    IntegrationOperator op = own;
    const StencilTable t = share_stencils(op);
    EXPECT_TRUE(t.empty()) << t.n_stencils() << " stencils";
    EXPECT_EQ(op.grad, own.grad);
    EXPECT_EQ(op.nodes, own.nodes);
}

// A thin beam (P3's mesh: 4 x 4 elements across, 55 along, the deck's RK and drop tolerance):
// with a/h 1.51 every one of the 5 node positions across is within reach of a face, so 5 x 5
// classes across times 5 along (2 at each end, the interior), exactly 125 stencils. Rows across
// with one node-offset pattern but different gradients (mirror images) fill one pattern with
// classes: the search must still find each row's own among them. A row's 56 points are 7
// batches of 8, of which the 5 between its ends are uniform (the whole-vector path).
TEST(StencilTable, ThinBeamSharesOneStencilPerBoundaryClass)
{
    const real_t h = 0.0254;
    const HexMesh mesh = generate_box(Vec3::Zero(), Vec3(55 * h, 4 * h, 4 * h), {55, 4, 4});
    const NodalBlock blk = build_nodal_block(elastic_rk_part("nsni"), mesh, 0);
    const StencilTable& t = blk.point_stencils;
    ASSERT_FALSE(t.empty());
    EXPECT_EQ(t.n_stencils(), 125);
    EXPECT_EQ(uniform_batches(blk.n_points(), t.point_stencil, t.point_base), 25 * 5);
}

// The order a uniform batch adds a stencil's entries in (uniform_add_order), on the P3 beam's
// tables, for the stencils its uniform batches read (uniform_batch_stencils; the others keep
// last to first) and for every stencil: a permutation of each stencil's entries in which two entries whose windows of 8
// nodes overlap keep their last-to-first order (so every node takes its lanes' terms in lane order, the bits of last to
// first; ForcePassReadsTheTableAsTheOperator holds the pass to the plain one), and in which an entry overlaps the one
// added just before it only where no other was ready: far less often than last to first, where the row neighbours o -
// 1, o, o + 1 follow each other (32 times for 1,352 in the SCNI stencils, 16 for 196 in the triplets).
TEST(StencilTable, UniformAddOrderKeepsTheLaneOrderAndSeparatesNeighbours)
{
    const real_t h = 0.0254;
    const HexMesh mesh = generate_box(Vec3::Zero(), Vec3(55 * h, 4 * h, 4 * h), {55, 4, 4});
    const NodalBlock blk = build_nodal_block(elastic_rk_part("nsni"), mesh, 0);
    auto check = [](const std::vector<index_t>& offsets, const std::vector<index_t>& node_offset,
                    const std::vector<index_t>& cls, const std::vector<index_t>& base, const AddOrder& block_order,
                    const char* what)
    {
        // the block orders the stencils its uniform batches read (and holds no order for the
        // others: last to first)
        const index_t n_stencils = static_cast<index_t>(offsets.size()) - 1;
        const std::vector<char> wanted = uniform_batch_stencils(uniform_batches(cls, base, 8), cls, n_stencils, 8);
        const index_t n_wanted = static_cast<index_t>(std::count(wanted.begin(), wanted.end(), 1));
        EXPECT_GT(n_wanted, 0) << what;
        EXPECT_LT(n_wanted, n_stencils) << what;
        const AddOrder all = uniform_add_order(offsets, node_offset, 8); // every stencil's
        std::size_t held = 0;
        for (index_t s = 0; s < n_stencils; ++s)
        {
            ASSERT_EQ(block_order.of(s) != nullptr, wanted[s] != 0) << what;
            ASSERT_NE(all.of(s), nullptr) << what;
            if (wanted[s])
            {
                held += static_cast<std::size_t>(offsets[s + 1] - offsets[s]);
                ASSERT_TRUE(std::equal(all.of(s), all.of(s) + (offsets[s + 1] - offsets[s]), block_order.of(s)))
                    << what;
            }
        }
        EXPECT_EQ(block_order.order.size(), held) << what;
        index_t back_to_back = 0, back_to_back_last_first = 0;
        for (std::size_t s = 0; s + 1 < offsets.size(); ++s)
        {
            const index_t k0 = offsets[s], n = offsets[s + 1] - k0;
            const index_t* o = node_offset.data() + k0;
            const std::uint16_t* a = all.of(static_cast<index_t>(s));
            std::vector<index_t> at(static_cast<std::size_t>(n), -1); // entry -> its place in the order
            for (index_t e = 0; e < n; ++e)
            {
                ASSERT_TRUE(a[e] >= 0 && a[e] < n && at[a[e]] < 0) << what << ": not a permutation";
                at[a[e]] = e;
            }
            for (index_t i = 0; i < n; ++i)
                for (index_t j = i + 1; j < n; ++j)
                    if (std::abs(o[i] - o[j]) < 8)
                    {
                        ASSERT_LT(at[j], at[i])
                            << what << ": overlapping entries " << i << ", " << j << " out of order";
                    }
            for (index_t e = 0; e + 1 < n; ++e)
            {
                back_to_back_last_first += std::abs(o[n - 1 - e] - o[n - 2 - e]) < 8;
                if (std::abs(o[a[e]] - o[a[e + 1]]) >= 8)
                    continue;
                ++back_to_back;
                // only where no choice was left: every entry that could follow a[e] (not added,
                // and no later overlapping entry pending) overlaps it
                for (index_t k = 0; k < n; ++k)
                {
                    bool ready = at[k] > e;
                    for (index_t j = k + 1; j < n && ready; ++j)
                        ready = at[j] <= e || std::abs(o[j] - o[k]) >= 8;
                    if (ready)
                    {
                        EXPECT_LT(std::abs(o[k] - o[a[e]]), 8) << what << ": entry " << k << " was apart and ready";
                    }
                }
            }
        }
        std::printf("%s: %d overlapping back-to-back adds, %d last to first\n", what, back_to_back,
                    back_to_back_last_first);
        EXPECT_LT(back_to_back, back_to_back_last_first) << what;
    };
    ASSERT_FALSE(blk.point_stencils.empty());
    ASSERT_FALSE(blk.stab_triplets.empty());
    const StencilTable& st = blk.point_stencils;
    const TripletTable& tt = blk.stab_triplets;
    check(st.offsets, st.node_offset, st.point_stencil, st.point_base, st.add_order, "SCNI stencils");
    check(tt.offsets, tt.node_offset, tt.point_triplet, tt.point_base, tt.add_order, "NSNI triplets");
}

// The P1 cylinder at 0.5 in (172 columns of 25 particles, numbered column by column): in each
// column the particles away from the caps are translates along the axis, so they share their
// column's middle stencil with consecutive bases, and every batch of 8 points inside one such
// run is a uniform batch (the force pass's whole-vector path), for the points' stencils and for
// NSNI's triplets alike. Layer by layer numbering gave none.
TEST(StencilTable, CylinderColumnsShareStencilsAlongTheAxis)
{
    const HexMesh mesh = generate_cylinder(Vec3::Zero(), 0.0762, 0.3048, 0.0127, false);
    const NodalBlock blk = build_nodal_block(elastic_rk_part("nsni"), mesh, 0);
    const index_t L = 25, np = blk.n_points();
    ASSERT_EQ(np % L, 0);
    ASSERT_FALSE(blk.point_stencils.empty());
    ASSERT_FALSE(blk.stab_triplets.empty());
    auto check = [&](const std::vector<index_t>& cls, const std::vector<index_t>& base, const char* what)
    {
        // per point: does it share its column's middle class, with the base one step per layer?
        std::vector<char> in_run(static_cast<std::size_t>(np), 0);
        for (index_t c = 0; c < np / L; ++c)
        {
            const index_t mid = c * L + L / 2;
            for (index_t p = c * L; p < (c + 1) * L; ++p)
                in_run[p] = cls[p] == cls[mid] && base[p] == base[mid] + (p - mid);
            EXPECT_TRUE(in_run[mid - 1] && in_run[mid + 1]) << what << ": column " << c;
        }
        index_t predicted = 0;
        for (index_t b = 0; b < np / 8; ++b)
        {
            bool all = (8 * b) / L == (8 * b + 7) / L; // one column
            for (int l = 0; l < 8; ++l)
                all = all && in_run[8 * b + l];
            predicted += all;
        }
        EXPECT_EQ(uniform_batches(np, cls, base), predicted) << what;
        EXPECT_GT(2 * predicted, np / 8) << what << ": most batches lie inside a column's run";
    };
    check(blk.point_stencils.point_stencil, blk.point_stencils.point_base, "points");
    check(blk.stab_triplets.point_triplet, blk.stab_triplets.point_base, "NSNI triplets");
}

// The P1 cylinder at 0.25 in (38,220 particles, the seed's finest assumed mesh), numbered
// column by column: chunks of n / 16 points are thin bundles of columns whose stencils reach
// far beyond them (over 3 buffers per node), so the block doubles the chunks until their
// ranges add up to at most 3 nodes per node, and keeps the chunked scatter with NSNI in the
// points' batches; with chunks of n / 16 alone it fell back to the transpose gather, which held
// 13.5 KB per particle against 1.6 KB.
TEST(StencilTable, FineCylinderKeepsTheChunkedScatter)
{
    const HexMesh mesh = generate_cylinder(Vec3::Zero(), 0.0762, 0.3048, 0.00635, false);
    const NodalBlock blk = build_nodal_block(elastic_rk_part("nsni"), mesh, 0);
    const index_t np = blk.n_points();
    ASSERT_EQ(np, 38220);
    ASSERT_TRUE(blk.scatter_assembly());
    EXPECT_FALSE(blk.stab_triplets.empty());
    EXPECT_TRUE(blk.finv.empty()) << "NSNI runs in the points' batches, not in a pass of its own";
    const index_t first = ChunkedScatter::chunk_size(np, kPointLanes, 512);
    const ChunkedScatter::Chunk& c0 = blk.scatter.chunks.front();
    EXPECT_GT(c0.last - c0.first, first) << "the chunks of n / 16 points are not local";
    std::size_t covered = 0;
    for (const ChunkedScatter::Chunk& c : blk.scatter.chunks)
        covered += static_cast<std::size_t>(c.hi - c.lo);
    EXPECT_LE(covered, 3 * static_cast<std::size_t>(np));
    EXPECT_GE(blk.scatter.chunks.size(), 4u) << "work for the threads";
}

// Three points with the same node offsets: the second differs from the first by half the
// tolerance (shared), the third by twice it (its own); a fourth holds a NaN (never shared).
TEST(StencilTable, ToleranceDecidesWhatIsShared)
{
    const real_t tol = 1e-11;
    IntegrationOperator op;
    const real_t g[6] = {1.0, -2.0, 0.5, -1.0, 2.0, -0.5};
    for (int p = 0; p < 4; ++p)
    {
        op.weight.push_back(1.0);
        op.nodes.push_back(10 * p);
        op.nodes.push_back(10 * p + 3);
        op.grad.insert(op.grad.end(), g, g + 6);
        op.offsets.push_back(op.n_entries());
    }
    op.grad[6 + 1] += 0.5 * tol * 2.0; // scale: the largest |g| is 2
    op.grad[12 + 4] -= 2.0 * tol * 2.0;
    op.grad[18 + 2] = std::numeric_limits<real_t>::quiet_NaN();
    StencilSharing opts;
    opts.relative_tolerance = tol;
    opts.max_entry_fraction = 1.0;
    const StencilTable t = share_stencils(op, opts);
    ASSERT_EQ(t.n_stencils(), 3);
    EXPECT_EQ(t.point_stencil, (std::vector<index_t>{0, 0, 1, 2}));
    EXPECT_EQ(t.point_base, (std::vector<index_t>{0, 10, 20, 30}));
    EXPECT_EQ(op.grad[6 + 1], g[1]) << "a shared point takes its class's gradients";
    EXPECT_EQ(op.grad[12 + 4], g[4] - 2.0 * tol * 2.0) << "a point outside the tolerance keeps its own";
    EXPECT_TRUE(std::isnan(op.grad[18 + 2]));
    // a sharing that does not pay leaves the operator alone
    IntegrationOperator op2 = op;
    opts.max_entry_fraction = 0.5;
    EXPECT_TRUE(share_stencils(op2, opts).empty());
    EXPECT_EQ(op2.nodes, op.nodes);
}

// build_scni_rk with a table writes its rows a block at a time straight into shared stencils
// (StencilSharer): the table is share_stencils' on the whole operator bit for bit, and the
// operator keeps its frame (offsets, weights, positions, owners) without entries; on 1 and 2
// threads alike. On the P1 cylinder at 1 in sharing pays; on a jittered mesh it does not, and
// then the table is empty and the operator the plain build's.
TEST(StencilTable, ScniRowsGoStraightIntoTheTableShareStencilsFinds)
{
    const real_t inch = 0.0254;
    struct Case
    {
        const char* name;
        HexMesh mesh;
        bool pays;
    };
    const Case cases[] = {{"cylinder", generate_cylinder(Vec3::Zero(), 3 * inch, 12 * inch, inch, false), true},
                          {"jittered", distorted_box(5, 1e-3, 0.3), false}};
    for (const Case& c : cases)
    {
        const RkShapeFunctions rk = rkfem::rk_on_mesh(c.mesh, RkParams{});
        IntegrationOperator whole = build_scni_rk(c.mesh, rk, 1e-5);
        const IntegrationOperator unsnapped = whole;
        const StencilTable found = share_stencils(whole);
        ASSERT_EQ(found.empty(), !c.pays) << c.name;
        const int threads = omp_get_max_threads();
        for (const int t : {1, 2})
        {
            omp_set_num_threads(t);
            StencilTable direct;
            direct.point_base = {7}; // cleared by the build
            const IntegrationOperator op = build_scni_rk(c.mesh, rk, 1e-5, nullptr, true, &direct);
            omp_set_num_threads(threads);
            EXPECT_EQ(op.offsets, whole.offsets) << c.name;
            EXPECT_EQ(op.weight, whole.weight) << c.name;
            EXPECT_EQ(op.position, whole.position) << c.name;
            EXPECT_EQ(op.owner, whole.owner) << c.name;
            EXPECT_EQ(direct.point_stencil, found.point_stencil) << c.name << ", " << t << " thread(s)";
            EXPECT_EQ(direct.point_base, found.point_base) << c.name;
            EXPECT_EQ(direct.offsets, found.offsets) << c.name;
            EXPECT_EQ(direct.node_offset, found.node_offset) << c.name;
            EXPECT_EQ(direct.grad, found.grad) << c.name;
            if (c.pays)
            {
                EXPECT_TRUE(op.nodes.empty() && op.grad.empty()) << c.name << ": the entries are the table's alone";
                EXPECT_LE(static_cast<double>(direct.n_entries()), 0.6 * whole.n_entries()) << c.name;
                // the table lives as long as its block: no spare room from the budget reserved
                EXPECT_EQ(direct.node_offset.capacity(), direct.node_offset.size()) << c.name;
                EXPECT_EQ(direct.grad.capacity(), direct.grad.size()) << c.name;
            }
            else
            {
                EXPECT_EQ(op.nodes, unsnapped.nodes) << c.name;
                EXPECT_EQ(op.grad, unsnapped.grad) << c.name;
            }
        }
        std::printf("%s: %d points, %d entries, %d in %d shared stencils\n", c.name, whole.n_points(),
                    whole.n_entries(), found.n_entries(), found.n_stencils());
    }
}

// The force pass with the shared stencils gives the bits of the pass that reads the (snapped)
// operator's own entries: stress, energies and nodal forces, with and without MSCNI, through
// both the whole-vector path of uniform batches and the lane-by-lane one.
TEST(SharedStencils, ForcePassReadsTheTableAsTheOperator)
{
    const int n = 12;
    const real_t h = 0.01;
    const HexMesh mesh = generate_box(Vec3::Zero(), Vec3::Constant(n * h), {n, n, n});
    for (const char* stab : {"none", "mscni", "nsni"})
    {
        const bool nsni = std::string(stab) == "nsni";
        PartSpec ps = elastic_rk_part(stab);
        // the full stencils (125 entries): with the default drop tolerance MSCNI's sub-cell
        // stencils on this small box differ too much between boundary layers to be shared
        ps.rk.drop_tolerance = 0.0;
        NodalBlock blk = build_nodal_block(ps, mesh, 0);
        ASSERT_FALSE(blk.point_stencils.empty()) << stab;
        // batches of 8 points with one stencil and consecutive bases (the whole-vector path)
        // and batches without (the lane-by-lane path) must both occur
        const index_t batches = blk.n_points() / 8;
        const index_t uniform =
            uniform_batches(blk.n_points(), blk.point_stencils.point_stencil, blk.point_stencils.point_base);
        std::printf("%s: %d of %d full batches are uniform\n", stab, uniform, batches);
        ASSERT_GT(uniform, 0);
        ASSERT_LT(uniform, batches);
        // the flags the force pass reads (build_tables) are those batches
        const std::vector<char>& flags = blk.point_stencils.uniform;
        ASSERT_EQ(static_cast<index_t>(flags.size()), batches) << stab;
        EXPECT_EQ(std::count(flags.begin(), flags.end(), 1), uniform) << stab;
        if (blk.n_stab() > 0 && !nsni)
        {
            ASSERT_FALSE(blk.stab_stencils.empty());
        }
        // NSNI: the sub-points' stencils packed as triplets (node and six Hessian values per
        // entry), their only copy in a part of one formulation
        if (nsni)
        {
            ASSERT_FALSE(blk.stab_triplets.empty());
            EXPECT_LT(blk.stab_triplets.n_triplets(), blk.n_points() / 4);
            // the triplets' whole-vector path (one triplet stencil, consecutive bases) and the
            // lane-by-lane one must both occur too
            const index_t uniform_triplets =
                uniform_batches(blk.n_points(), blk.stab_triplets.point_triplet, blk.stab_triplets.point_base);
            std::printf("nsni: %d of %d full batches have uniform triplets\n", uniform_triplets, batches);
            ASSERT_GT(uniform_triplets, 0);
            ASSERT_LT(uniform_triplets, batches);
            const std::vector<char>& tflags = blk.stab_triplets.uniform;
            ASSERT_EQ(static_cast<index_t>(tflags.size()), batches);
            EXPECT_EQ(std::count(tflags.begin(), tflags.end(), 1), uniform_triplets);
            // the table lives as long as the block: its growth's spare capacity is returned
            // (it was a third of the table on the P1 cylinder)
            const TripletTable& t = blk.stab_triplets;
            EXPECT_EQ(t.hess.capacity(), 6 * static_cast<std::size_t>(t.n_entries()));
            EXPECT_EQ(t.node_offset.capacity(), static_cast<std::size_t>(t.n_entries()));
        }
        NodeSet nodes = wavy_motion(mesh);
        const real_t dt = 1e-7;
        const PassBits shared = pass_bits(blk, nodes, dt);
        // the operators' own entries were released to the tables (a part of one formulation);
        // written back, they give the same pass bit for bit
        EXPECT_TRUE(blk.points_in_table && blk.points.nodes.empty() && blk.points.grad.empty()) << stab;
        EXPECT_EQ(blk.stab_in_table, blk.n_stab() > 0 && !nsni) << stab;
        EXPECT_EQ(blk.stab_in_triplets, nsni) << stab;
        EXPECT_TRUE(blk.stabilization.nodes.empty()) << stab; // released, or none
        blk.expand_operators();
        ASSERT_EQ(blk.points.n_entries(), blk.points.offsets.back()) << stab;
        ASSERT_EQ(blk.stabilization.n_entries(), blk.stabilization.offsets.back()) << stab;
        blk.point_stencils.clear();
        blk.stab_stencils.clear();
        blk.stab_triplets.clear(); // NSNI then reads the three sub-point stencils from the operator
        expect_same_bits(shared, pass_bits(blk, nodes, dt), stab);
    }
}

// A jittered mesh shares no stencils: NSNI's sub-points are packed as triplets point by point
// (node and the six distinct Hessian values per entry: 52 bytes for the 84 of three sub-point
// entries), the only copy of them; the pass over the packed triplets equals, bit for bit, the
// pass over the three sub-point stencils written back from them.
TEST(SharedStencils, JitteredNsniPacksEachPointsTriplet)
{
    const HexMesh mesh = distorted_box(8, 0.01, 0.3);
    NodalBlock blk = build_nodal_block(elastic_rk_part("nsni"), mesh, 0);
    ASSERT_TRUE(blk.point_stencils.empty());
    ASSERT_TRUE(blk.stab_in_triplets);
    EXPECT_EQ(blk.stab_triplets.n_triplets(), blk.n_points());
    EXPECT_TRUE(blk.stabilization.nodes.empty() && blk.stabilization.grad.empty());
    EXPECT_TRUE(blk.stabilization.position.empty()); // the parents' positions, not kept
    // no point shares: the table keeps the room its builder reserved from the first block's
    // share of the region particles, at most 1/16 spare (not copied once more to shed it)
    const TripletTable& t = blk.stab_triplets;
    EXPECT_LE(t.node_offset.capacity(), t.node_offset.size() + t.node_offset.size() / 16);
    EXPECT_LE(t.hess.capacity(), t.hess.size() + t.hess.size() / 16 + 6);
    std::printf("jittered NSNI table: %zu entries, room for %zu\n", t.node_offset.size(), t.node_offset.capacity());
    NodeSet nodes = wavy_motion(mesh);
    const real_t dt = 1e-7;
    const ForcePassResult a = nodal_internal_force(blk, nodes, dt);
    assemble_nodal_forces(blk, nodes);
    const std::vector<real_t> f_packed = nodes.f_int;
    const std::vector<real_t> s_packed = blk.stab_stress_trial;
    const index_t packed_entries = blk.stab_triplets.n_entries();
    blk.expand_operators();
    EXPECT_EQ(blk.stabilization.n_entries(), 3 * packed_entries);
    ASSERT_EQ(blk.stabilization.position.size(), 3 * static_cast<std::size_t>(blk.n_stab()));
    for (index_t s = 0; s < blk.n_stab(); ++s)
        ASSERT_EQ(blk.stabilization.point(s), blk.points.point(s / 3)) << s;
    blk.stab_triplets.clear();
    const ForcePassResult b = nodal_internal_force(blk, nodes, dt);
    assemble_nodal_forces(blk, nodes);
    EXPECT_EQ(f_packed, nodes.f_int);
    EXPECT_EQ(s_packed, blk.stab_stress_trial);
    EXPECT_EQ(a.d_hourglass, b.d_hourglass);
    EXPECT_NE(a.d_hourglass, 0.0);
}

// A part whose tables stream from memory asks for the next batch's stencils while it scatters
// (NodalBlock::prefetch_points, prefetch_triplets): prefetches move no number, so the pass with
// them on gives the bits of the pass without, through the chunked scatter with NSNI in the
// batches (the points' stencils asked for while NSNI scatters, the triplets while the points
// do), without a stabilization (the points' stencils while the points scatter), and through the
// transpose gather (while the points store their tensors).
TEST(SharedStencils, AskingForTheNextBatchsStencilsKeepsTheBits)
{
    const HexMesh mesh = distorted_box(8, 0.01, 0.3);
    for (const char* stab : {"nsni", "none"})
        for (const Assembly assembly : {Assembly::Scatter, Assembly::Gather})
        {
            const std::string name = std::string(stab) + (assembly == Assembly::Gather ? ", gather" : ", scatter");
            NodalBlock blk = build_nodal_block(elastic_rk_part(stab), mesh, 0);
            if (assembly == Assembly::Gather)
                blk.build_tables(Assembly::Gather);
            ASSERT_TRUE(blk.point_stencils.empty()) << name;
            ASSERT_EQ(blk.n_point_chunks > 0, assembly == Assembly::Scatter) << name;
            // a small part's tables stay in cache: no prefetch
            EXPECT_FALSE(blk.options().prefetch_points || blk.options().prefetch_triplets) << name;
            NodeSet nodes = wavy_motion(mesh);
            const real_t dt = 1e-7;
            const PassBits plain = pass_bits(blk, nodes, dt);
            EXPECT_NE(plain.r.d_internal, 0.0) << name;
            {
                NodalBlockOptions o = blk.options();
                o.prefetch_points = true;
                o.prefetch_triplets = !blk.stab_triplets.empty();
                blk.set_options(o);
            }
            if (std::string(stab) == "nsni" && assembly == Assembly::Scatter)
            {
                ASSERT_TRUE(blk.options().prefetch_triplets);
            }
            expect_same_bits(plain, pass_bits(blk, nodes, dt), name);
        }
}

// The kinematic map's rows (approximation/rk/kinematic_map.hpp) are shared as stencils are: on a
// structured box the particles' rows repeat, so a few are stored, and every row read back has
// its own columns and values within the sharing's tolerance (1e-11 of its largest), and still
// reproduces what RK reproduces, 1 and x (sum Lambda_IJ = 1, sum Lambda_IJ X_J = X_I), to
// round-off; a jittered mesh's rows are all its own, read back bit for bit.
TEST(SharedStencils, KinematicMapRowsAreSharedWithinTheirTolerance)
{
    struct Case
    {
        const char* name;
        HexMesh mesh;
        bool shares;
    };
    const Case cases[] = {{"box", generate_box(Vec3::Zero(), Vec3(0.2, 0.1, 0.1), {20, 10, 10}), true},
                          {"jittered", distorted_box(8, 0.01, 0.3), false}};
    for (const Case& c : cases)
    {
        NodalBlock blk = build_nodal_block(elastic_rk_part("nsni"), c.mesh, 0);
        const index_t n = c.mesh.n_nodes();
        ASSERT_EQ(static_cast<index_t>(blk.interp_offsets.size()), n + 1);
        KinematicMap map;
        map.reset(n);
        const std::vector<char> all(static_cast<std::size_t>(n), 1);
        map.set_rows(0, n, blk.interp_offsets, blk.interp_nodes, blk.interp_values, &all);
        real_t moved = 0.0, unity = 0.0, linear = 0.0;
        int other_columns = 0;
        for (index_t i = 0; i < n; ++i)
        {
            std::vector<index_t> cols;
            std::vector<real_t> vals;
            map.for_row(i,
                        [&](index_t j, real_t w)
                        {
                            cols.push_back(j);
                            vals.push_back(w);
                        });
            const index_t k0 = blk.interp_offsets[i], m = blk.interp_offsets[i + 1] - k0;
            if (static_cast<index_t>(cols.size()) != m)
            {
                ++other_columns;
                continue;
            }
            real_t largest = 0.0, sum = 0.0;
            Vec3 x = Vec3::Zero();
            for (index_t k = 0; k < m; ++k)
            {
                other_columns += cols[k] != blk.interp_nodes[k0 + k];
                largest = std::max(largest, std::abs(blk.interp_values[k0 + k]));
                sum += vals[k];
                x += vals[k] * c.mesh.node(cols[k]);
            }
            for (index_t k = 0; k < m; ++k)
                moved = std::max(moved, std::abs(vals[k] - blk.interp_values[k0 + k]) / largest);
            unity = std::max(unity, std::abs(sum - 1.0));
            linear = std::max(linear, (x - c.mesh.node(i)).norm() / 0.01);
        }
        std::printf("%s: %zu of %zu row entries stored; values moved by %.1e of their row's largest; "
                    "|sum - 1| %.1e, |sum Lambda X - X| / h %.1e\n",
                    c.name, map.stored_entries(), map.row_entries(), moved, unity, linear);
        EXPECT_EQ(other_columns, 0) << c.name;
        EXPECT_EQ(map.row_entries(), blk.interp_nodes.size()) << c.name;
        if (c.shares)
        {
            EXPECT_LT(map.stored_entries(), map.row_entries() / 4) << c.name;
            EXPECT_LE(moved, 1e-11) << c.name;
        }
        else
        {
            EXPECT_EQ(map.stored_entries(), map.row_entries()) << c.name;
            EXPECT_EQ(moved, 0.0) << c.name;
        }
        EXPECT_LT(unity, 1e-12) << c.name;
        EXPECT_LT(linear, 1e-12) << c.name;
        // rows set again for a middle range (as a conversion does) over the stored ones: the
        // same map as one call with every row, entry for entry
        KinematicMap twice;
        twice.reset(n);
        twice.set_rows(0, n, blk.interp_offsets, blk.interp_nodes, blk.interp_values, &all);
        const index_t b = n / 3, e = 2 * n / 3;
        std::vector<index_t> offsets{0}, columns;
        std::vector<real_t> values;
        for (index_t i = b; i < e; ++i)
        {
            columns.insert(columns.end(), blk.interp_nodes.begin() + blk.interp_offsets[i],
                           blk.interp_nodes.begin() + blk.interp_offsets[i + 1]);
            values.insert(values.end(), blk.interp_values.begin() + blk.interp_offsets[i],
                          blk.interp_values.begin() + blk.interp_offsets[i + 1]);
            offsets.push_back(static_cast<index_t>(columns.size()));
        }
        twice.set_rows(b, e, offsets, columns, values, nullptr);
        EXPECT_EQ(twice.stored_entries(), map.stored_entries()) << c.name;
        EXPECT_EQ(twice.row_entries(), map.row_entries()) << c.name;
        int differ = 0;
        for (index_t i = 0; i < n; ++i)
        {
            std::vector<std::pair<index_t, real_t>> one, two;
            map.for_row(i, [&](index_t j, real_t w) { one.emplace_back(j, w); });
            twice.for_row(i, [&](index_t j, real_t w) { two.emplace_back(j, w); });
            differ += one != two;
        }
        EXPECT_EQ(differ, 0) << c.name;
    }
}

// A part's set-up with rk.share_translates (the default) against the same part evaluated
// element by element and particle by particle (false), on the seed's P1 cylinder at 1 in: the
// interpolation rows have the same particles and values to round-off, and they still reproduce
// 1 and x at every particle (sum Psi_J(X_I) = 1, sum Psi_J(X_I) X_J = X_I); the force pass on a
// wavy motion gives the same nodal forces to round-off of the largest (here the same bits: the
// shared stencils snap both builds' points to the same class stencils, which differ by less
// than the sharing's tolerance).
TEST(SharedStencils, SharingTranslatesKeepsThePartToRoundOff)
{
    const real_t inch = 0.0254;
    const HexMesh mesh = generate_cylinder(Vec3::Zero(), 3 * inch, 12 * inch, inch, false);
    PartSpec ps = elastic_rk_part("nsni");
    NodalBlock shared = build_nodal_block(ps, mesh, 0);
    ps.rk.share_translates = false;
    NodalBlock plain = build_nodal_block(ps, mesh, 0);
    ASSERT_EQ(shared.interp_offsets, plain.interp_offsets);
    ASSERT_EQ(shared.interp_nodes, plain.interp_nodes);
    real_t value = 0.0, reproduction = 0.0;
    for (std::size_t k = 0; k < plain.interp_values.size(); ++k)
        value = std::max(value, std::abs(shared.interp_values[k] - plain.interp_values[k]));
    for (index_t i = 0; i < mesh.n_nodes(); ++i)
    {
        real_t one = 0.0;
        Vec3 x = Vec3::Zero();
        for (index_t k = shared.interp_offsets[i]; k < shared.interp_offsets[i + 1]; ++k)
        {
            one += shared.interp_values[k];
            x += shared.interp_values[k] * mesh.node(shared.interp_nodes[k]);
        }
        reproduction = std::max({reproduction, std::abs(one - 1.0), (x - mesh.node(i)).norm() / inch});
    }
    std::printf("interpolation rows: values differ by %.2e, reproduce 1 and x to %.2e\n", value, reproduction);
    EXPECT_LT(value, 1e-13);        // measured 1.1e-15
    EXPECT_LT(reproduction, 1e-13); // 1.5e-14
    std::vector<real_t> f[2];
    for (int run = 0; run < 2; ++run)
    {
        NodalBlock& blk = run == 0 ? shared : plain;
        NodeSet nodes = wavy_motion(mesh);
        nodal_internal_force(blk, nodes, 1e-7);
        assemble_nodal_forces(blk, nodes);
        f[run] = nodes.f_int;
    }
    real_t worst = 0.0, big = 0.0;
    for (std::size_t k = 0; k < f[0].size(); ++k)
    {
        worst = std::max(worst, std::abs(f[0][k] - f[1][k]));
        big = std::max(big, std::abs(f[1][k]));
    }
    std::printf("nodal forces differ by %.2e of the largest\n", worst / big);
    EXPECT_LT(worst / big, 1e-11);
}
