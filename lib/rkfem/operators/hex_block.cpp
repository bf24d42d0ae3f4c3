#include "rkfem/operators/hex_block.hpp"

#include "rkfem/core/error.hpp"

#include <algorithm>
#include <cmath>
#include <type_traits>

#include "rkfem/approximation/fem/hex8_basis.hpp"
#include "rkfem/approximation/fem/hex8_modes.hpp"
#include "rkfem/approximation/fem/hex8_volume_gradient.hpp"
#include "rkfem/core/huge_pages.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/simd.hpp"
#include "rkfem/core/stream_stores.hpp"
#include "rkfem/discretization/hex_mesh.hpp"
#include "rkfem/operators/bulk_viscosity.hpp"
#include "rkfem/operators/kernels/assumed_strain_hourglass.hpp"

// GCC 12's AVX-512 intrinsics (gathers, unpacks, 128-bit shuffles, extracts) start from an
// undefined source written "__m512d __Y = __Y", which -Wmaybe-uninitialized / -Wuninitialized
// report once inlined here; every value used is defined.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

#include "rkfem/operators/kernels/hex_fast.hpp"

namespace rkfem
{
using namespace hex_kernels;

void HexBlock::initialize(const NodeSet& nodes, Assembly assembly)
{
    const index_t ne = mesh_only ? 0 : n_elements();
    const std::size_t np = mesh_only ? 0 : static_cast<std::size_t>(n_points());
    stress_stride = batch8_stride(np);
    stress.assign(6 * stress_stride, 0.0);
    stress_trial.assign(6 * stress_stride, 0.0);
    if (plastic.active())
        plastic.resize(np);
    hg_force.assign(static_cast<std::size_t>(hg_rows()) * ne, 0.0);
    hg_force_trial.assign(static_cast<std::size_t>(hg_rows()) * ne, 0.0);
    build_tables(nodes, assembly);
}

void HexBlock::remove_elements(const std::vector<char>& keep, const NodeSet& nodes)
{
    const index_t ne = n_elements(), npe = points_per_element();
    RKFEM_REQUIRE(static_cast<index_t>(keep.size()) == ne,
                  "remove_elements: " << keep.size() << " flags for " << ne << " elements");
    std::vector<index_t> kept, from_points;
    for (index_t e = 0; e < ne; ++e)
        if (keep[e])
        {
            kept.push_back(e);
            for (index_t g = 0; g < npe; ++g)
                from_points.push_back(e * npe + g);
        }
    const index_t ne2 = static_cast<index_t>(kept.size());
    const std::size_t np2 = from_points.size(), stride2 = batch8_stride(np2);
    // committed state of the kept points, in order; trial = committed (the event falls between
    // steps, after the commit)
    LineVector<real_t> s2(6 * stride2, 0.0);
    for (int k = 0; k < 6; ++k)
        for (std::size_t q = 0; q < np2; ++q)
            s2[k * stride2 + q] = stress[k * stress_stride + static_cast<std::size_t>(from_points[q])];
    stress = s2;
    stress_trial = std::move(s2);
    stress_stride = stride2;
    std::vector<real_t> hg2(static_cast<std::size_t>(hg_rows()) * ne2);
    for (int k = 0; k < hg_rows(); ++k)
        for (index_t q = 0; q < ne2; ++q)
            hg2[static_cast<std::size_t>(k) * ne2 + q] = hg_force[static_cast<std::size_t>(k) * ne + kept[q]];
    hg_force = hg2;
    hg_force_trial = std::move(hg2);
    if (plastic.active())
        plastic.gather(from_points);
    std::vector<index_t> conn2;
    conn2.reserve(8 * kept.size());
    for (index_t e : kept)
        conn2.insert(conn2.end(), conn.begin() + 8 * static_cast<std::ptrdiff_t>(e),
                     conn.begin() + 8 * static_cast<std::ptrdiff_t>(e + 1));
    conn = std::move(conn2);
    build_tables(nodes, scatter.empty() && formulation == Formulation::Fem1pt && ne > 0 ? Assembly::Gather
                                                                                        : Assembly::Automatic);
}

void HexBlock::build_tables(const NodeSet& nodes, Assembly assembly)
{
    const index_t ne = n_elements();
    // 1-point blocks whose element order has locality assemble by chunked scatter (the element
    // forces are never written out): chunks of n / 16 elements (at least 2048), doubled while
    // their ranges add up to over 3 nodes per node, up to 2048 or a quarter of the block,
    // whichever is larger (as nodal blocks do); others (2x2x2, an element order without
    // locality) through the element force buffer
    scatter.clear();
    if (formulation == Formulation::Fem1pt && assembly != Assembly::Gather && !mesh_only)
    {
        auto cut = [&](index_t size)
        {
            scatter.clear();
            scatter.node_begin = node_begin;
            scatter.node_end = node_end;
            const std::size_t covered = scatter.add_chunks(ne, size,
                                                           [&](index_t first, index_t last, index_t& lo, index_t& hi)
                                                           {
                                                               for (std::size_t k = 8 * static_cast<std::size_t>(first);
                                                                    k < 8 * static_cast<std::size_t>(last); ++k)
                                                               {
                                                                   lo = std::min(lo, conn[k]);
                                                                   hi = std::max(hi, conn[k] + 1);
                                                               }
                                                           });
            return ChunkedScatter::local(covered, node_end - node_begin);
        };
        index_t size = ChunkedScatter::chunk_size(ne, W);
        const bool local = ChunkedScatter::cut_until_local(size, std::max<index_t>(2048, ne / 4), cut);
        if (assembly == Assembly::Scatter || local)
            scatter.finish();
        else
            scatter.clear();
    }
    elem_force.assign(scatter.empty() && !mesh_only ? 24 * static_cast<std::size_t>(ne) : 0, 0.0);
    volume0.assign(static_cast<std::size_t>(ne), 0.0);
    const index_t nb = mesh_only ? 0 : formulation == Formulation::Fem1pt ? n_batches(ne) : ne;
    batch_sums.assign(4 * static_cast<std::size_t>(nb), 0.0);
    batch_idx.assign(2 * static_cast<std::size_t>(nb), -1);
    for (index_t e = 0; e < ne; ++e)
    {
        real_t xe[8][3], b[8][3];
        for (int I = 0; I < 8; ++I)
            for (int d = 0; d < 3; ++d)
                xe[I][d] = nodes.x0[3 * static_cast<std::size_t>(conn[8 * e + I]) + d];
        volume0[e] = hex8_volume_gradient(xe, b);
    }
    // node -> (element, local) CSR, counts -> offsets -> slots
    const index_t nn = node_end - node_begin;
    node_elem_offsets.assign(static_cast<std::size_t>(nn) + 1, 0);
    for (index_t s = 0; s < 8 * ne; ++s)
        ++node_elem_offsets[conn[s] - node_begin + 1];
    for (index_t i = 0; i < nn; ++i)
        node_elem_offsets[i + 1] += node_elem_offsets[i];
    node_elem_slots.assign(static_cast<std::size_t>(8) * ne, 0);
    std::vector<index_t> fill(node_elem_offsets.begin(), node_elem_offsets.end() - 1);
    for (index_t s = 0; s < 8 * ne; ++s)
        node_elem_slots[fill[conn[s] - node_begin]++] = s;
        // batch-major gather indices: [64 b + 8 I + l] = 3 x (node I of element 8 b + l), full
        // batches; only the AVX-512 kernel reads them (its vector gathers)
#if defined(__AVX512F__)
    const index_t n_gather = mesh_only ? 0 : ne / W;
#else
    const index_t n_gather = 0;
#endif
    gather_index.assign(64 * static_cast<std::size_t>(n_gather), 0);
    for (index_t b = 0; b < n_gather; ++b)
        for (int I = 0; I < 8; ++I)
            for (int l = 0; l < W; ++l)
                gather_index[64 * static_cast<std::size_t>(b) + 8 * I + l] = 3 * conn[8 * (W * b + l) + I];
    use_huge_pages(gather_index);
    use_huge_pages(stress);
    use_huge_pages(stress_trial);
    for (auto* a : {&hg_force, &hg_force_trial, &elem_force, &volume0})
        use_huge_pages(*a);
    use_huge_pages(conn);
    use_huge_pages(node_elem_slots);
    // elements no other element shares a node with (a single-element model, a fragment erosion
    // left): their breathing mode takes its own step (lone_element_step)
    isolated.clear();
    for (index_t e = 0; e < ne && !mesh_only; ++e)
    {
        bool alone = true;
        for (int a = 0; a < 8 && alone; ++a)
        {
            const index_t i = conn[8 * static_cast<std::size_t>(e) + a] - node_begin;
            for (index_t k = node_elem_offsets[i]; k < node_elem_offsets[i + 1] && alone; ++k)
                alone = node_elem_slots[k] / 8 == e;
        }
        if (alone)
            isolated.push_back(e);
    }
}

real_t lone_element_step(const HexBlock& blk, const NodeSet& nodes, index_t e)
{
    real_t x[8][3];
    for (int I = 0; I < 8; ++I)
        for (int d = 0; d < 3; ++d)
            x[I][d] = nodes.x[3 * static_cast<std::size_t>(blk.conn[8 * static_cast<std::size_t>(e) + I]) + d];
    const real_t area = largest_face_area(x);
    const ElasticParams& m = blk.material;
    // uniform dilation of a lone hex with lumped mass: omega^2 = 4 (3 lambda + 2 mu) / (rho L^2),
    // above the (2 c / L)^2 the step L / c assumes by sqrt(3 K / M) = sqrt((1 + nu) / (1 - nu))
    const real_t factor = std::sqrt(m.plane_wave_modulus() / (3.0 * m.bulk_modulus()));
    return area > 0.0 ? factor * element_volume(blk, nodes, e) / area / m.wave_speed() : 0.0;
}

/// All batches of a 1-point block, with the hourglass form and the material (dispatch_kind) chosen
/// once for the block.
template <HourglassType HG> void run_1pt(HexBlock& blk, const NodeSet& nodes, index_t nb, real_t dt)
{
    const bool partial_last = blk.n_elements() % W != 0;
    auto batch = [&]<PlasticPoints::Kind MK>(index_t b, real_t* buf, index_t lo)
    {
        if (partial_last && b == nb - 1)
            force_1pt_batch<HG, MK, false>(blk, nodes, b, dt, buf, lo);
        else
            force_1pt_batch<HG, MK, true>(blk, nodes, b, dt, buf, lo);
    };
    dispatch_kind(blk.plastic.kind,
                  [&]<PlasticPoints::Kind MK>()
                  {
                      if (!blk.scatter.empty())
                          blk.scatter.run_chunks("rkfem::hex1pt", 0, static_cast<index_t>(blk.scatter.chunks.size()), W,
                                                 [&](index_t b, real_t* buf, index_t lo)
                                                 { batch.template operator()<MK>(b, buf, lo); });
                      else
                          parallel_for("rkfem::hex1pt", nb,
                                       [&](index_t b) { batch.template operator()<MK>(b, nullptr, 0); });
                  });
}

ForcePassResult hex_internal_force(HexBlock& blk, const NodeSet& nodes, real_t dt)
{
    ForcePassResult r;
    const index_t ne = blk.n_elements();
    index_t nb = 0;
    if (blk.formulation == Formulation::Fem1pt)
    {
        nb = n_batches(ne);
        switch (blk.hourglass.type)
        {
        case HourglassType::None:
            run_1pt<HourglassType::None>(blk, nodes, nb, dt);
            break;
        case HourglassType::Viscous:
            run_1pt<HourglassType::Viscous>(blk, nodes, nb, dt);
            break;
        case HourglassType::Stiffness:
            run_1pt<HourglassType::Stiffness>(blk, nodes, nb, dt);
            break;
        case HourglassType::ViscousPlain:
            run_1pt<HourglassType::ViscousPlain>(blk, nodes, nb, dt);
            break;
        case HourglassType::AssumedStrain:
            run_1pt<HourglassType::AssumedStrain>(blk, nodes, nb, dt);
            break;
        }
    }
    else
    {
        nb = ne;
        dispatch_kind(blk.plastic.kind,
                      [&]<PlasticPoints::Kind MK>()
                      {
                          parallel_for("rkfem::hex2x2x2", ne,
                                       [&](index_t e)
                                       {
                                           real_t out[4];
                                           index_t bad = -1;
                                           force_2x2x2_element<MK>(blk, nodes, e, dt, out, bad);
                                           for (int k = 0; k < 4; ++k)
                                               blk.batch_sums[4 * e + k] = out[k];
                                           blk.batch_idx[2 * e] = e;
                                           blk.batch_idx[2 * e + 1] = bad;
                                       });
                      });
    }
    r.d_internal = parallel_reduce_sum("rkfem::hex_energy", nb, [&](index_t b) { return blk.batch_sums[4 * b]; });
    r.d_hourglass = parallel_reduce_sum("rkfem::hex_energy", nb, [&](index_t b) { return blk.batch_sums[4 * b + 1]; });
    r.d_bulk_viscosity =
        parallel_reduce_sum("rkfem::hex_energy", nb, [&](index_t b) { return blk.batch_sums[4 * b + 2]; });
    for (index_t b = 0; b < nb; ++b)
    {
        if (blk.batch_sums[4 * b + 3] < r.dt_stable)
        {
            r.dt_stable = blk.batch_sums[4 * b + 3];
            r.dt_element = blk.batch_idx[2 * b];
        }
        if (r.bad_element < 0 && blk.batch_idx[2 * b + 1] >= 0)
            r.bad_element = blk.batch_idx[2 * b + 1];
        if (std::isnan(blk.batch_sums[4 * b + 3]) && r.bad_element < 0)
            r.bad_element = blk.batch_idx[2 * b];
    }
    for (const index_t e : blk.isolated)
        if (const real_t lone = lone_element_step(blk, nodes, e); lone < r.dt_stable)
        {
            r.dt_stable = lone;
            r.dt_element = e;
        }
    return r;
}

void assemble_block_forces(HexBlock& blk, NodeSet& nodes, bool add)
{
    if (!blk.scatter.empty())
    {
        blk.scatter.reduce(nodes.f_int, add);
        return;
    }
    const index_t nn = blk.node_end - blk.node_begin;
    parallel_for("rkfem::assemble", nn,
                 [&](index_t i)
                 {
                     real_t f0 = 0.0, f1 = 0.0, f2 = 0.0;
                     for (index_t k = blk.node_elem_offsets[i]; k < blk.node_elem_offsets[i + 1]; ++k)
                     {
                         const real_t* fe = &blk.elem_force[3 * static_cast<std::size_t>(blk.node_elem_slots[k])];
                         f0 += fe[0];
                         f1 += fe[1];
                         f2 += fe[2];
                     }
                     const std::size_t n = 3 * static_cast<std::size_t>(blk.node_begin + i);
                     if (add)
                     {
                         f0 += nodes.f_int[n];
                         f1 += nodes.f_int[n + 1];
                         f2 += nodes.f_int[n + 2];
                     }
                     nodes.f_int[n] = f0;
                     nodes.f_int[n + 1] = f1;
                     nodes.f_int[n + 2] = f2;
                 });
}

real_t element_volume(const HexBlock& blk, const NodeSet& nodes, index_t e)
{
    real_t xe[8][3], b[8][3];
    for (int I = 0; I < 8; ++I)
        for (int d = 0; d < 3; ++d)
            xe[I][d] = nodes.x[3 * static_cast<std::size_t>(blk.conn[8 * static_cast<std::size_t>(e) + I]) + d];
    return hex8_volume_gradient(xe, b);
}

void add_lumped_mass(const HexBlock& blk, NodeSet& nodes)
{
    const index_t nn = blk.node_end - blk.node_begin;
    for (index_t i = 0; i < nn; ++i)
    {
        real_t m = 0.0;
        for (index_t k = blk.node_elem_offsets[i]; k < blk.node_elem_offsets[i + 1]; ++k)
        {
            // a degenerate solid's mass goes in equal shares to its distinct nodes (a wedge's sixths)
            const index_t e = blk.node_elem_slots[k] / 8, a = blk.node_elem_slots[k] % 8;
            const index_t* c = blk.conn.data() + 8 * static_cast<std::size_t>(e);
            if (std::find(c, c + a, c[a]) != c + a)
                continue; // the node's second corner in this element
            m += blk.material.rho * blk.volume0[e] / static_cast<real_t>(distinct_nodes(c));
        }
        nodes.mass[blk.node_begin + i] += m;
    }
}
} // namespace rkfem
