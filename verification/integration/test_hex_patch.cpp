// Patch test on a distorted 3x3x3 patch: a linear velocity field, held for several steps, gives
// uniform rate of deformation and stress (to 1e-10 relative) and zero force on the 8 interior
// nodes (below 1e-10 of the force scale), for 1-point integration with each hourglass form that
// projects out linear fields (none, viscous IHQ 3, stiffness IHQ 5, assumed strain IHQ 6) and for 2x2x2. The viscous
// form on the raw base vectors (LS-DYNA IHQ 1 analog) is shown to fail, as Schwer et al. (2005)
// report for LS-DYNA's default.
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <omp.h>
#include <random>

#include "../support.hpp"
#include "rkfem/core/stream_stores.hpp"

using namespace rkfem;

namespace
{
struct PatchResult
{
    real_t stress_spread = 0;     ///< max |sigma_p - sigma_ref| / |sigma_ref|
    real_t interior_residual = 0; ///< max |f_I| over interior nodes / force scale
};

PatchResult run_patch(Formulation f, HourglassType hg, int n = 3, bool wedges = false)
{
    const real_t h = 0.01;
    const HexMesh mesh =
        wedges ? test::split_into_wedges(test::distorted_box(n, h, 0.25)) : test::distorted_box(n, h, 0.25);
    NodeSet nodes;
    const ElasticParams mat = ElasticParams::from_E_nu(7850, 200e9, 0.3);
    HexBlock blk = test::make_block(mesh, nodes, f, {hg, 0.1}, mat);
    const real_t A[3][3] = {{1.0, 0.3, -0.2}, {0.1, -0.5, 0.4}, {0.25, 0.2, 0.7}}; // 1/s
    const real_t dt = 1e-7;
    PatchResult r;
    for (int step = 0; step < 5; ++step)
    {
        // v = A x0, displacement advanced so geometry stays a linear map of x0
        test::linear_velocity_step(nodes, A, dt);
        hex_internal_force(blk, nodes, dt);
        assemble_block_forces(blk, nodes);
        blk.commit();
    }
    const std::size_t np = static_cast<std::size_t>(blk.n_points());
    Sym6 ref;
    for (int k = 0; k < 6; ++k)
        ref[k] = blk.stress[k * blk.stress_stride];
    const real_t sref = ref.norm();
    for (std::size_t p = 0; p < np; ++p)
    {
        Sym6 s;
        for (int k = 0; k < 6; ++k)
            s[k] = blk.stress[k * blk.stress_stride + p];
        r.stress_spread = std::max(r.stress_spread, (s - ref).norm() / sref);
    }
    const real_t force_scale = sref * h * h;
    for (index_t i = 0; i < nodes.size(); ++i)
        if (test::is_interior(mesh, i, 0.5 * h, (n - 0.5) * h))
            for (int d = 0; d < 3; ++d)
                r.interior_residual = std::max(r.interior_residual, std::abs(nodes.f_int[3 * i + d]) / force_scale);
    return r;
}
} // namespace

TEST(HexPatch, OnePointWithoutHourglassControlPasses)
{
    const PatchResult r = run_patch(Formulation::Fem1pt, HourglassType::None);
    EXPECT_LT(r.stress_spread, 1e-10);
    EXPECT_LT(r.interior_residual, 1e-10);
}

TEST(HexPatch, OnePointViscousExactVolumeIHQ3Passes)
{
    const PatchResult r = run_patch(Formulation::Fem1pt, HourglassType::Viscous);
    EXPECT_LT(r.stress_spread, 1e-10);
    EXPECT_LT(r.interior_residual, 1e-10);
}

TEST(HexPatch, OnePointStiffnessExactVolumeIHQ5Passes)
{
    const PatchResult r = run_patch(Formulation::Fem1pt, HourglassType::Stiffness);
    EXPECT_LT(r.stress_spread, 1e-10);
    EXPECT_LT(r.interior_residual, 1e-10);
}

TEST(HexPatch, OnePointAssumedStrainIHQ6Passes)
{
    const PatchResult r = run_patch(Formulation::Fem1pt, HourglassType::AssumedStrain);
    EXPECT_LT(r.stress_spread, 1e-10);
    EXPECT_LT(r.interior_residual, 1e-10);
}

TEST(HexPatch, FullyIntegratedPasses)
{
    const PatchResult r = run_patch(Formulation::Fem2x2x2, HourglassType::None);
    EXPECT_LT(r.stress_spread, 1e-10);
    EXPECT_LT(r.interior_residual, 1e-10);
}

// Wedges written as hexes with a repeated node (what LS-PrePost and other pre-processors write for
// LS-DYNA): the exact-volume gradients b_I = int dN_I / dx dV still satisfy sum_I b_I x_I^T = V I on
// any trilinear map, degenerate or not, and the hourglass vectors stay orthogonal to linear fields,
// so the patch test holds as on hexes
TEST(HexPatch, DegenerateWedgesPassWithEveryForm)
{
    for (const HourglassType hg :
         {HourglassType::None, HourglassType::Viscous, HourglassType::Stiffness, HourglassType::AssumedStrain})
    {
        const PatchResult r = run_patch(Formulation::Fem1pt, hg, 3, true);
        EXPECT_LT(r.stress_spread, 1e-10) << static_cast<int>(hg);
        EXPECT_LT(r.interior_residual, 1e-10) << static_cast<int>(hg);
    }
    const PatchResult r = run_patch(Formulation::Fem2x2x2, HourglassType::None, 3, true);
    EXPECT_LT(r.stress_spread, 1e-10);
    EXPECT_LT(r.interior_residual, 1e-10);
}

TEST(HexPatch, OnePointPassesWhereTheStressIsStreamed)
{
    // 56^3 elements: the stress field passes kStreamBytes, so the kernel writes it with streaming
    // stores (whole cache lines, no read for ownership) where the CPU has AVX-512
    const HexMesh probe = test::distorted_box(56, 0.01, 0.0);
    NodeSet nodes;
    const HexBlock blk = test::make_block(probe, nodes, Formulation::Fem1pt, {HourglassType::Viscous, 0.1},
                                          ElasticParams::from_E_nu(7850, 200e9, 0.3));
    ASSERT_EQ(blk.stress_stride % 8, 0u);
    ASSERT_EQ(reinterpret_cast<std::uintptr_t>(blk.stress.data()) % 64, 0u);
    ASSERT_FALSE(blk.scatter.empty()) << "streaming needs the chunked scatter (it fences each chunk)";
    // without AVX-512 both paths store plainly: the patch and the comparison still run (and the
    // comparison is then between two plain passes)
    std::printf("stress stores: %s\n",
                stream_pays(static_cast<index_t>(6 * blk.stress_stride)) ? "streamed" : "plain (no AVX-512 here)");
    const PatchResult r = run_patch(Formulation::Fem1pt, HourglassType::Viscous, 56);
    EXPECT_LT(r.stress_spread, 1e-10);
    EXPECT_LT(r.interior_residual, 1e-10);
    // streamed stores move the same values: one pass from a random state, streamed and plain
    HexBlock plain = blk, streamed = blk;
    plain.stream_stress = false;
    std::mt19937 gen(5);
    std::uniform_real_distribution<real_t> rnd(-1.0, 1.0);
    for (std::size_t j = 0; j < nodes.v.size(); ++j)
    {
        nodes.x[j] = nodes.x0[j] + 1e-5 * rnd(gen);
        nodes.v[j] = 10.0 * rnd(gen);
    }
    const ForcePassResult a = hex_internal_force(streamed, nodes, 1e-8), b = hex_internal_force(plain, nodes, 1e-8);
    EXPECT_TRUE(streamed.stress_trial == plain.stress_trial) << "streamed and plain stress stores differ";
    EXPECT_EQ(a.d_internal, b.d_internal);
}

TEST(HexPatch, ViscousOnRawBaseVectorsFails)
{
    // Gamma is not orthogonal to linear fields on distorted elements: a linear velocity drives
    // hourglass forces. Recorded residual on this patch is printed for the note.
    const PatchResult r = run_patch(Formulation::Fem1pt, HourglassType::ViscousPlain);
    std::printf("viscous-plain interior residual / force scale = %.3e\n", r.interior_residual);
    EXPECT_LT(r.stress_spread, 1e-10); // stress itself is uniform
    EXPECT_GT(r.interior_residual, 1e-4);
}

namespace
{
/// One internal-force pass and assembly of a copy of the block, with `threads` threads.
std::vector<real_t> hex_force_pass(HexBlock blk, NodeSet nodes, int threads)
{
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    hex_internal_force(blk, nodes, 1e-8);
    assemble_block_forces(blk, nodes);
    omp_set_num_threads(saved);
    return nodes.f_int;
}
} // namespace

// 1-point blocks assemble by chunked scatter (chunks of elements, each into a buffer of its own)
// unless their element order has no locality; the transpose gather sums the same terms in
// another order. Each is bitwise independent of the thread count, and they agree to round-off,
// with every hourglass form and a partial last batch of lanes.
TEST(HexAssembly, ScatterAndGatherAgreeAndDoNotDependOnThreads)
{
    const HexMesh mesh = test::distorted_box(29, 1e-3, 0.25); // 24389 elements: 12 chunks, 5 lanes left over
    const ElasticParams mat = ElasticParams::from_E_nu(7850, 200e9, 0.3);
    for (HourglassType hg : {HourglassType::None, HourglassType::Viscous, HourglassType::Stiffness})
    {
        NodeSet nodes;
        HexBlock blk = test::make_block(mesh, nodes, Formulation::Fem1pt, {hg, 0.1}, mat, {0.06, 1.5});
        ASSERT_GE(blk.scatter.chunks.size(), 2u);
        std::mt19937 gen(3);
        std::uniform_real_distribution<real_t> r(-1.0, 1.0);
        for (std::size_t j = 0; j < nodes.v.size(); ++j)
        {
            nodes.x[j] = nodes.x0[j] + 1e-6 * r(gen);
            nodes.v[j] = 10.0 * r(gen);
        }
        HexBlock gather = blk;
        gather.initialize(nodes, Assembly::Gather);
        ASSERT_TRUE(gather.scatter.empty());
        const std::vector<real_t> s1 = hex_force_pass(blk, nodes, 1), s2 = hex_force_pass(blk, nodes, 2);
        const std::vector<real_t> g1 = hex_force_pass(gather, nodes, 1), g2 = hex_force_pass(gather, nodes, 2);
        const real_t rel = test::assembly_difference(s1, s2, g1, g2);
        std::printf("hourglass %d: scatter vs gather max |f_s - f_g| / max |f| = %.2e over %zu dofs\n",
                    static_cast<int>(hg), rel, s1.size());
        EXPECT_LT(rel, 1e-13);
    }
    // elements in random order: every chunk would touch nearly every node, so the gather
    HexMesh shuffled = mesh;
    std::vector<index_t> order(static_cast<std::size_t>(mesh.n_elements()));
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), std::mt19937(9));
    for (std::size_t e = 0; e < order.size(); ++e)
        for (int I = 0; I < 8; ++I)
            shuffled.conn[8 * e + I] = mesh.conn[8 * static_cast<std::size_t>(order[e]) + I];
    NodeSet nodes;
    const HexBlock random = test::make_block(shuffled, nodes, Formulation::Fem1pt, {HourglassType::Viscous, 0.1}, mat);
    EXPECT_TRUE(random.scatter.empty());
}

// Along a structured mesh's rows, node I of a batch's 8 elements is 8 consecutive nodes, which
// the 1-point kernel loads and adds as whole lines instead of by lanes. Renumbering the nodes in
// swapped pairs (2k <-> 2k + 1) breaks every such row but keeps each node's terms and their
// order: the forces must be the same bits, node for node.
TEST(HexAssembly, ConsecutiveNodeRowsGiveTheBitsOfGatheredOnes)
{
    const HexMesh mesh = test::distorted_box(16, 1e-3, 0.25);
    HexMesh swapped = mesh;
    const index_t nn = mesh.n_nodes();
    auto swap_id = [&](index_t n) { return (n ^ 1) < nn ? n ^ 1 : n; };
    for (index_t n = 0; n < nn; ++n)
        for (int d = 0; d < 3; ++d)
            swapped.x[3 * swap_id(n) + d] = mesh.x[3 * n + d];
    for (index_t& c : swapped.conn)
        c = swap_id(c);
    // rows of node ids n, n + 1, ..., n + 7 in the original, none in the renumbered mesh
    auto consecutive_rows = [](const HexMesh& m)
    {
        index_t rows = 0;
        for (index_t b = 0; b < m.n_elements() / 8; ++b)
            for (int I = 0; I < 8; ++I)
            {
                bool row = true;
                for (int l = 1; l < 8; ++l)
                    row = row && m.conn[8 * (8 * b + l) + I] == m.conn[8 * 8 * b + I] + l;
                rows += row;
            }
        return rows;
    };
    const index_t all_rows = 8 * (mesh.n_elements() / 8);
    EXPECT_EQ(consecutive_rows(mesh), all_rows) << "16 elements per row: every batch lies in one row";
    EXPECT_EQ(consecutive_rows(swapped), 0);
    const ElasticParams mat = ElasticParams::from_E_nu(7850, 200e9, 0.3);
    for (HourglassType hg : {HourglassType::Viscous, HourglassType::Stiffness})
    {
        NodeSet n1, n2;
        HexBlock b1 = test::make_block(mesh, n1, Formulation::Fem1pt, {hg, 0.1}, mat, {0.06, 1.5});
        HexBlock b2 = test::make_block(swapped, n2, Formulation::Fem1pt, {hg, 0.1}, mat, {0.06, 1.5});
        ASSERT_FALSE(b1.scatter.empty());
        ASSERT_FALSE(b2.scatter.empty());
        std::mt19937 gen(11);
        std::uniform_real_distribution<real_t> r(-1.0, 1.0);
        for (index_t n = 0; n < nn; ++n)
            for (int d = 0; d < 3; ++d)
            {
                const std::size_t j = 3 * static_cast<std::size_t>(n) + d,
                                  k = 3 * static_cast<std::size_t>(swap_id(n)) + d;
                n1.x[j] = n2.x[k] = n1.x0[j] + 1e-6 * r(gen);
                n1.v[j] = n2.v[k] = 10.0 * r(gen);
            }
        const ForcePassResult a = hex_internal_force(b1, n1, 1e-8), b = hex_internal_force(b2, n2, 1e-8);
        assemble_block_forces(b1, n1);
        assemble_block_forces(b2, n2);
        index_t differ = 0;
        for (index_t n = 0; n < nn; ++n)
            for (int d = 0; d < 3; ++d)
                differ += n1.f_int[3 * n + d] != n2.f_int[3 * swap_id(n) + d];
        EXPECT_EQ(differ, 0) << "hourglass " << static_cast<int>(hg);
        EXPECT_EQ(a.d_internal, b.d_internal);
        EXPECT_EQ(a.d_hourglass, b.d_hourglass);
        EXPECT_TRUE(b1.stress_trial == b2.stress_trial);
    }
}

// The chunk sums are consumed by the assembly (ChunkedScatter::reduce zeroes what it reads), so
// the next pass starts from zero buffers without clearing them: a second pass from the same
// state gives the same bits, and a second assembly of one pass is refused.
TEST(HexAssembly, AssemblyConsumesTheChunkSums)
{
    const HexMesh mesh = test::distorted_box(29, 1e-3, 0.25);
    NodeSet nodes;
    HexBlock blk = test::make_block(mesh, nodes, Formulation::Fem1pt, {HourglassType::Viscous, 0.1},
                                    ElasticParams::from_E_nu(7850, 200e9, 0.3));
    ASSERT_GE(blk.scatter.chunks.size(), 2u);
    std::mt19937 gen(4);
    std::uniform_real_distribution<real_t> r(-1.0, 1.0);
    for (real_t& v : nodes.v)
        v = r(gen);
    hex_internal_force(blk, nodes, 1e-8);
    assemble_block_forces(blk, nodes);
    const std::vector<real_t> first = nodes.f_int;
    for (real_t b : blk.scatter.buffer)
        ASSERT_EQ(b, 0.0);
    EXPECT_THROW(assemble_block_forces(blk, nodes), Error);
    hex_internal_force(blk, nodes, 1e-8);
    assemble_block_forces(blk, nodes);
    EXPECT_EQ(first, nodes.f_int);
}
