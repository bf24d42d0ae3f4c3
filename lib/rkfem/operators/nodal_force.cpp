#include "rkfem/operators/nodal_force.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>

#include "rkfem/core/error.hpp"
#include "rkfem/core/huge_pages.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/simd.hpp"
#include "rkfem/core/stream_stores.hpp"
#include "rkfem/operators/bulk_viscosity.hpp"
#include "rkfem/operators/kernels/nodal_fast.hpp"

namespace rkfem
{
namespace nodal_kernels
{
// each material kind's batch kernel is compiled in its own unit (kernels/nodal_points_<kind>.cpp)
RKFEM_NODAL_POINTS_BATCHES(extern, None);
RKFEM_NODAL_POINTS_BATCHES(extern, J2);
RKFEM_NODAL_POINTS_BATCHES(extern, Kcc);
RKFEM_NODAL_POINTS_BATCHES(extern, Cscm);
} // namespace nodal_kernels
using namespace nodal_kernels;

ForcePassResult nodal_internal_force(NodalBlock& blk, const NodeSet& nodes, real_t dt, const real_t* u_from)
{
    const index_t np = blk.n_points(), ns = blk.n_stab();
    const ElasticParams mat = blk.material;
    const real_t* u = u_from ? u_from : nodes.u.data();
    const real_t* v = nodes.v.data();

    auto batch = [&]<PlasticPoints::Kind MK>(index_t b, real_t* buf, index_t lo)
    {
        if ((b + 1) * kPointLanes <= np)
            nodal_points_batch<MK, true>(blk, u, v, b, dt, buf, lo);
        else
            nodal_points_batch<MK, false>(blk, u, v, b, dt, buf, lo);
    };
    // the material chosen once for the block
    dispatch_kind(blk.plastic.kind,
                  [&]<PlasticPoints::Kind MK>()
                  {
                      if (blk.scatter_assembly())
                          blk.scatter.run_chunks("rkfem::nodal_points", 0, blk.n_point_chunks, kPointLanes,
                                                 [&](index_t b, real_t* buf, index_t lo)
                                                 { batch.template operator()<MK>(b, buf, lo); });
                      else
                          parallel_for("rkfem::nodal_points", (np + kPointLanes - 1) / kPointLanes,
                                       [&](index_t b) { batch.template operator()<MK>(b, nullptr, 0); });
                  });

    ForcePassResult r;
    const index_t nb = (np + kPointLanes - 1) / kPointLanes;
    for (index_t b = 0; b < nb; ++b)
    {
        if (blk.batch_idx[2 * b + 1] >= 0)
        {
            r.bad_element = blk.batch_idx[2 * b + 1];
            return r;
        }
        if (blk.batch_sums[4 * b + 2] < r.dt_stable)
        {
            r.dt_stable = blk.batch_sums[4 * b + 2];
            r.dt_element = blk.batch_idx[2 * b];
        }
    }

    // the stabilization's own pass; NSNI with the chunked scatter ran in the points' batches
    // (nsni_batch)
    if (ns > 0 && !(blk.stabilization_triplets && blk.scatter_assembly()))
    {
        const IntegrationOperator& st = blk.stabilization;
        const std::size_t sns = static_cast<std::size_t>(ns);
        ElasticParams smat = mat;
        smat.lambda *= blk.stabilization_coefficient;
        smat.mu *= blk.stabilization_coefficient;
        // sub-point s with velocity gradient G: stress update and V0 J sigma F^-T (by columns);
        // the block's arrays through restrict pointers (stores into the stress would otherwise
        // make the compiler reload every other array's address)
        const real_t* __restrict finv = blk.finv.data();
        const real_t* __restrict spin = blk.spin.data();
        const real_t* __restrict jac = blk.jacobian.data();
        const real_t* __restrict s_in = blk.stab_stress.data();
        real_t* __restrict s_out = blk.stab_stress_trial.data();
        real_t* __restrict energy = blk.stab_energy.data();
        const index_t* __restrict parent = st.parent.data();
        const real_t* __restrict weight = st.weight.data();
        const real_t* __restrict share = blk.stab_share.empty() ? nullptr : blk.stab_share.data();
        auto sub_point = [=](index_t s, const real_t G[3][3], real_t P[9])
        {
            const index_t L = parent[s];
            const real_t* Fi = finv + 9 * static_cast<std::size_t>(L);
            real_t Ls[3][3];
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    Ls[i][j] = G[i][0] * Fi[j] + G[i][1] * Fi[3 + j] + G[i][2] * Fi[6 + j];
            const real_t d[6] = {Ls[0][0],
                                 Ls[1][1],
                                 Ls[2][2],
                                 0.5 * (Ls[0][1] + Ls[1][0]),
                                 0.5 * (Ls[1][2] + Ls[2][1]),
                                 0.5 * (Ls[2][0] + Ls[0][2])};
            const real_t* w = spin + 3 * static_cast<std::size_t>(L);
            real_t s_old[6], sg[6];
            for (int k = 0; k < 6; ++k)
                s_old[k] = sg[k] = s_in[k * sns + s];
            elastic_update(smat, d, w, dt, sg);
            if (share)
                scale_stabilization_load(hughes_winget(w[0], w[1], w[2], dt), s_old, share[L], sg);
            for (int k = 0; k < 6; ++k)
                s_out[k * sns + s] = sg[k];
            real_t power = 0.0;
            for (int k = 0; k < 3; ++k)
                power += 0.5 * (s_old[k] + sg[k]) * d[k] + (s_old[k + 3] + sg[k + 3]) * d[k + 3];
            const real_t VJ = weight[s] * jac[L];
            energy[s] = dt * VJ * power;
            const real_t S[3][3] = {{sg[0], sg[3], sg[5]}, {sg[3], sg[1], sg[4]}, {sg[5], sg[4], sg[2]}};
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    P[3 * j + i] = VJ * (S[i][0] * Fi[3 * j] + S[i][1] * Fi[3 * j + 1] + S[i][2] * Fi[3 * j + 2]);
        };
        auto sub_cell = [&](index_t s, real_t P[9])
        {
            real_t G[3][3];
            gather_velocity_gradient(stencil_view(st, blk.stab_stencils, s), v, G);
            sub_point(s, G, P);
        };
        // NSNI: the three sub-points of point t in one pass over their shared nodes
        auto triplet = [&](index_t t, real_t P[3][9])
        {
            const StencilView sv[3] = {stencil_view(st, blk.stab_stencils, 3 * t),
                                       stencil_view(st, blk.stab_stencils, 3 * t + 1),
                                       stencil_view(st, blk.stab_stencils, 3 * t + 2)};
            real_t G[3][3][3];
            gather_triplet(SubPointTriplet{sv}, v, G);
            for (int i = 0; i < 3; ++i)
                sub_point(3 * t + i, G[i], P[i]);
        };
        if (blk.stabilization_triplets)
            parallel_for("rkfem::nodal_stabilization", ns / 3,
                         [&](index_t t)
                         {
                             real_t P[3][9];
                             triplet(t, P);
                             for (int i = 0; i < 3; ++i)
                                 std::copy(P[i], P[i] + 9,
                                           &blk.point_tensor[9 * (static_cast<std::size_t>(np) + 3 * t + i)]);
                         });
        else if (blk.scatter_assembly())
            blk.scatter.run_chunks("rkfem::nodal_stabilization", blk.n_point_chunks,
                                   static_cast<index_t>(blk.scatter.chunks.size()), 1,
                                   [&](index_t s, real_t* buf, index_t lo)
                                   {
                                       real_t P[9];
                                       sub_cell(s, P);
                                       scatter_point(stencil_view(st, blk.stab_stencils, s), P, buf, lo);
                                   });
        else
            parallel_for("rkfem::nodal_stabilization", ns,
                         [&](index_t s) { sub_cell(s, &blk.point_tensor[9 * (static_cast<std::size_t>(np) + s)]); });
    }

    r.d_internal = parallel_reduce_sum("rkfem::nodal_energy", nb, [&](index_t b) { return blk.batch_sums[4 * b]; });
    r.d_bulk_viscosity =
        parallel_reduce_sum("rkfem::nodal_bv_energy", nb, [&](index_t b) { return blk.batch_sums[4 * b + 1]; });
    // NSNI in the points' batches summed its sub-points' work per batch (nsni_batch)
    if (ns > 0 && blk.stabilization_triplets && blk.scatter_assembly())
        r.d_hourglass =
            parallel_reduce_sum("rkfem::nodal_stab_energy", nb, [&](index_t b) { return blk.batch_sums[4 * b + 3]; });
    else
        r.d_hourglass =
            parallel_reduce_sum("rkfem::nodal_stab_energy", ns, [&](index_t s) { return blk.stab_energy[s]; });
    return r;
}

void assemble_nodal_forces(NodalBlock& blk, NodeSet& nodes, bool add)
{
    const index_t nn = blk.node_end - blk.node_begin;
    if (blk.scatter_assembly())
    {
        blk.scatter.reduce(nodes.f_int, add);
        return;
    }
    parallel_for("rkfem::nodal_assemble", nn,
                 [&](index_t i)
                 {
                     real_t f[3];
                     gather_forces(blk, i, f);
                     const std::size_t n = 3 * static_cast<std::size_t>(blk.node_begin + i);
                     for (int a = 0; a < 3; ++a)
                         nodes.f_int[n + a] = add ? nodes.f_int[n + a] + f[a] : f[a];
                 });
}
} // namespace rkfem
