// Blocks that share nodes add into one force vector: a distorted box cut at a layer into a
// 1-point hex block below and a nodal-integrated FE block (SCNI + MSCNI) above, sharing the
// interface layer's nodes. Under a linear velocity field every point's stress is the same, so
// the net force on every node that is not on the outer boundary vanishes, the interface nodes
// included, where it is the sum of the two blocks' forces: the linear patch test to 1e-10. The
// result does not depend on the thread count (bitwise), and a block that overwrites the other's
// sums instead of adding to them fails it (the negative control).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <omp.h>

#include "../support.hpp"
#include "rkfem/core/simd.hpp"
#include "rkfem/model/nodal_block_build.hpp"
#include "rkfem/operators/hex_block.hpp"
#include "rkfem/operators/nodal_block.hpp"
#include "rkfem/operators/nodal_force.hpp"

using namespace rkfem;

namespace
{
struct SharedBox
{
    HexMesh full;
    NodeSet nodes;
    HexBlock lower;   ///< fem-1pt, nodes [0, interface layer end)
    NodalBlock upper; ///< fem-nodal, nodes [interface layer begin, end)
    real_t h = 0.01;
    int n = 0;
};

SharedBox make_shared_box(int n, int cut)
{
    SharedBox s;
    s.n = n;
    s.full = test::distorted_box(n, s.h, 0.25);
    const index_t layer = static_cast<index_t>(n + 1) * (n + 1); // nodes per z layer
    const index_t lower_nodes = (cut + 1) * layer, upper_offset = cut * layer;
    const index_t lower_elems = static_cast<index_t>(n) * n * cut;
    s.nodes.resize(s.full.n_nodes());
    s.nodes.x0 = s.nodes.x = s.full.x;

    HexBlock& b = s.lower;
    b.formulation = Formulation::Fem1pt;
    b.hourglass = {HourglassType::Stiffness, 0.05};
    b.material = ElasticParams::from_E_nu(7850, 200e9, 0.3);
    b.conn.assign(s.full.conn.begin(), s.full.conn.begin() + 8 * lower_elems);
    b.node_begin = 0;
    b.node_end = lower_nodes;
    b.initialize(s.nodes);
    add_lumped_mass(b, s.nodes);

    HexMesh up;
    up.x.assign(s.full.x.begin() + 3 * upper_offset, s.full.x.end());
    up.conn.assign(s.full.conn.begin() + 8 * lower_elems, s.full.conn.end());
    for (index_t& c : up.conn)
        c -= upper_offset;
    up.faces = extract_boundary_faces(up.conn);
    const PartSpec ps = test::steel_nodal_part(Formulation::FemNodal);
    s.upper = build_nodal_block(ps, up, upper_offset);
    add_nodal_mass(s.upper, s.nodes);
    return s;
}

/// Five steps of the linear velocity field v = A x0 with both blocks assembled (adding, or the
/// upper block overwriting); returns f_int.
std::vector<real_t> linear_steps(SharedBox& s, bool add)
{
    const real_t A[3][3] = {{1.0, 0.3, -0.2}, {0.1, -0.5, 0.4}, {0.25, 0.2, 0.7}}; // 1/s
    const real_t dt = 1e-7;
    NodeSet& nodes = s.nodes;
    for (int step = 0; step < 5; ++step)
    {
        test::linear_velocity_step(nodes, A, dt);
        hex_internal_force(s.lower, nodes, dt);
        nodal_internal_force(s.upper, nodes, dt);
        std::fill(nodes.f_int.begin(), nodes.f_int.end(), 0.0);
        assemble_block_forces(s.lower, nodes, add);
        assemble_nodal_forces(s.upper, nodes, add);
        s.lower.commit();
        s.upper.commit();
    }
    return nodes.f_int;
}

struct Residual
{
    real_t interior = 0.0;  ///< max over nodes off the outer boundary, / force scale
    real_t interface = 0.0; ///< max over the interface layer's interior nodes, / force scale
};

Residual residual(const SharedBox& s, const std::vector<real_t>& f, int cut)
{
    const real_t sxx = s.lower.stress[0]; // a stress component of the first point
    real_t sref = 0.0;
    for (int k = 0; k < 6; ++k)
        sref = std::max(sref, std::abs(s.lower.stress[k * s.lower.stress_stride]));
    EXPECT_GT(std::abs(sxx) + sref, 0.0);
    const real_t scale = sref * s.h * s.h;
    const index_t layer = static_cast<index_t>(s.n + 1) * (s.n + 1);
    Residual r;
    for (index_t i = 0; i < s.nodes.size(); ++i)
        if (test::is_interior(s.full, i, 0.5 * s.h, (s.n - 0.5) * s.h))
            for (int d = 0; d < 3; ++d)
            {
                const real_t e = std::abs(f[3 * i + d]) / scale;
                r.interior = std::max(r.interior, e);
                if (i / layer == cut)
                    r.interface = std::max(r.interface, e);
            }
    return r;
}
} // namespace

TEST(SharedNodes, TwoBlocksOnOneInterfacePassTheLinearPatchTest)
{
    const int n = 4, cut = 2;
    SharedBox s = make_shared_box(n, cut);
    ASSERT_EQ(s.lower.node_end - s.upper.node_begin, (n + 1) * (n + 1)); // the shared layer
    const Residual r = residual(s, linear_steps(s, true), cut);
    // both blocks see the same uniform stress
    real_t spread = 0.0, sref = 0.0;
    for (int k = 0; k < 6; ++k)
        sref = std::max(sref, std::abs(s.lower.stress[k * s.lower.stress_stride]));
    for (index_t p = 0; p < s.upper.n_points(); ++p)
        for (int k = 0; k < 6; ++k)
            spread = std::max(spread, std::abs(s.upper.stress[k * s.upper.stress_stride + p] -
                                               s.lower.stress[k * s.lower.stress_stride]) /
                                          sref);
    std::printf("1-pt | fem-nodal on a %d^3 distorted box: interior residual %.2e, interface %.2e, stress "
                "spread between the blocks %.2e\n",
                n, r.interior, r.interface, spread);
    EXPECT_LT(spread, 1e-10);
    EXPECT_LT(r.interior, 1e-10);
    EXPECT_LT(r.interface, 1e-10);

    // negative control: the upper block's sums overwrite the lower block's on the shared layer
    SharedBox w = make_shared_box(n, cut);
    const Residual rw = residual(w, linear_steps(w, false), cut);
    std::printf("overwriting instead of adding: interface residual %.2e\n", rw.interface);
    EXPECT_GT(rw.interface, 1e-2);
}

TEST(SharedNodes, AssemblyDoesNotDependOnTheThreadCount)
{
    // large enough for several scatter chunks per block
    const int n = 24, cut = 10;
    std::vector<real_t> f[2];
    for (int threads : {1, 2})
    {
        omp_set_num_threads(threads);
        SharedBox s = make_shared_box(n, cut);
        ASSERT_GT(s.lower.scatter.chunks.size(), 1u);
        f[threads - 1] = linear_steps(s, true);
        const Residual r = residual(s, f[threads - 1], cut);
        std::printf("%d^3, %d thread(s): interior residual %.2e, interface %.2e\n", n, threads, r.interior,
                    r.interface);
        EXPECT_LT(r.interior, 1e-10);
    }
    omp_set_num_threads(1);
    EXPECT_TRUE(f[0] == f[1]) << "forces differ between 1 and 2 threads";
}

// A box numbered column by column (height fastest, the columns row by row): chunks of n / 16
// elements are a quarter of a row of columns, and their nodes reach into the next row, so
// their ranges add up to over 3 nodes per node; chunks of twice that are local, and
// the 1-point block keeps the chunked scatter with them instead of the element force buffer.
TEST(SharedNodes, ColumnNumberedBoxDoublesItsScatterChunks)
{
    const int nx = 160, ny = 4, nz = 100;
    const real_t h = 0.01;
    auto node = [&](int i, int j, int k) { return static_cast<index_t>((j * (nx + 1) + i) * (nz + 1) + k); };
    NodeSet nodes;
    nodes.resize(static_cast<index_t>((nx + 1) * (ny + 1) * (nz + 1)));
    for (int j = 0; j <= ny; ++j)
        for (int i = 0; i <= nx; ++i)
            for (int k = 0; k <= nz; ++k)
                for (int d = 0; d < 3; ++d)
                    nodes.x0[3 * static_cast<std::size_t>(node(i, j, k)) + d] = h * (d == 0 ? i : d == 1 ? j : k);
    nodes.x = nodes.x0;
    HexBlock b;
    b.formulation = Formulation::Fem1pt;
    b.hourglass = {HourglassType::Stiffness, 0.05};
    b.material = ElasticParams::from_E_nu(7850, 200e9, 0.3);
    for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i)
            for (int k = 0; k < nz; ++k)
                for (int c = 0; c < 2; ++c)
                    b.conn.insert(b.conn.end(), {node(i, j, k + c), node(i + 1, j, k + c), node(i + 1, j + 1, k + c),
                                                 node(i, j + 1, k + c)});
    b.node_begin = 0;
    b.node_end = nodes.size();
    b.initialize(nodes);
    const index_t ne = b.n_elements(), first = ChunkedScatter::chunk_size(ne, simd::kLanes);
    ASSERT_EQ(first, 4000);
    auto covered = [&](index_t size)
    {
        std::size_t sum = 0;
        for (index_t e0 = 0; e0 < ne; e0 += size)
        {
            const auto [lo, hi] =
                std::minmax_element(b.conn.begin() + 8 * e0, b.conn.begin() + 8 * std::min(ne, e0 + size));
            sum += static_cast<std::size_t>(*hi + 1 - *lo);
        }
        return static_cast<real_t>(sum) / static_cast<real_t>(nodes.size());
    };
    std::printf("chunk ranges per node: %.2f at %d elements per chunk, %.2f at %d\n", covered(first), first,
                covered(2 * first), 2 * first);
    EXPECT_GT(covered(first), 3.0);
    ASSERT_FALSE(b.scatter.empty()) << "the element force buffer instead of the chunked scatter";
    EXPECT_EQ(b.scatter.chunks.size(), 8u);
    EXPECT_LE(covered(2 * first), 3.0);
}

// A part's nodes are numbered after the parts before it in the deck. An RK part with NSNI (held
// as its triplet table from the start) must give the same forces on its nodes whether it comes
// first or after a FE part: its stencils' node ids are shifted with it. Until the triplets'
// first nodes were shifted too, a second RK part's NSNI read and wrote another part's nodes
// (the P6 target as rkpm crashed in its set-up).
TEST(SharedNodes, AnRkPartAfterAnotherPartHasTheSameForces)
{
    const std::string rk_part = R"(
  block:
    generator: {type: box, origin: [0, 0, 0], size: [6 mm, 6 mm, 12 mm], element_size: 1 mm}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: rkpm
)";
    const std::string fe_part = R"(
  other:
    generator: {type: box, origin: [0, 0, 50 mm], size: [3 mm, 3 mm, 3 mm], element_size: 1 mm}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: fem-1pt
)";
    const std::string head = "title: numbering\ntime: {end: 1 us}\nparts:";
    Model alone = test::model_from(head + rk_part), after = test::model_from(head + fe_part + rk_part);
    ASSERT_TRUE(alone.nodal_block(0) && after.nodal_block(1) && !after.nodal_block(0));
    NodalBlock &a = *alone.nodal_block(0), &b = *after.nodal_block(1);
    ASSERT_TRUE(a.stabilization_triplets && !a.stab_triplets.empty());
    const index_t shift = b.node_begin - a.node_begin, n = a.node_end - a.node_begin;
    ASSERT_GT(shift, 0);
    ASSERT_EQ(b.node_end - b.node_begin, n);
    // the same motion on the part's nodes in both models
    for (index_t i = 0; i < n; ++i)
        for (int d = 0; d < 3; ++d)
        {
            const std::size_t ia = 3 * static_cast<std::size_t>(a.node_begin + i) + d,
                              ib = 3 * static_cast<std::size_t>(b.node_begin + i) + d;
            const real_t x = alone.nodes.x0[ia];
            alone.nodes.v[ia] = after.nodes.v[ib] = 1e-3 * std::sin(1e3 * x + d + i % 7);
            alone.nodes.u[ia] = after.nodes.u[ib] = 1e-9 * std::cos(1e3 * x + d);
        }
    std::fill(alone.nodes.f_int.begin(), alone.nodes.f_int.end(), 0.0);
    std::fill(after.nodes.f_int.begin(), after.nodes.f_int.end(), 0.0);
    const ForcePassResult ra = nodal_internal_force(a, alone.nodes, 1e-8),
                          rb = nodal_internal_force(b, after.nodes, 1e-8);
    assemble_nodal_forces(a, alone.nodes);
    assemble_nodal_forces(b, after.nodes);
    real_t scale = 0.0;
    index_t differ = 0;
    for (index_t i = 0; i < 3 * n; ++i)
    {
        const real_t fa = alone.nodes.f_int[3 * static_cast<std::size_t>(a.node_begin) + i];
        const real_t fb = after.nodes.f_int[3 * static_cast<std::size_t>(b.node_begin) + i];
        scale = std::max(scale, std::abs(fa));
        differ += fa != fb;
    }
    EXPECT_GT(scale, 0.0);
    EXPECT_EQ(differ, 0) << "of " << 3 * n << " force components";
    EXPECT_EQ(ra.d_hourglass, rb.d_hourglass); // NSNI's work
    EXPECT_EQ(ra.d_internal, rb.d_internal);
}
