#include "rkfem/operators/kernels/nodal_reference.hpp"

#include <cmath>

#include "rkfem/core/error.hpp"
#include "rkfem/materials/elastic.hpp"
#include "rkfem/operators/bulk_viscosity.hpp"
#include "rkfem/operators/kernels/assumed_strain_hourglass.hpp"
#include "rkfem/operators/kernels/rate_form.hpp"

namespace rkfem
{
namespace
{
/// F = 1 + sum u (x) g (or, with identity = false, sum v (x) g) over the entries of a stencil
/// (a point's nodes and gradients, integration/stencil_table.hpp: node = base + offset).
Mat3 stencil_sum(const StencilView& st, const std::vector<real_t>& field, bool identity)
{
    Mat3 M = Mat3::Zero();
    if (identity)
        M = Mat3::Identity();
    for (index_t j = 0; j < st.size; ++j)
    {
        const std::size_t n = 3 * static_cast<std::size_t>(st.base + st.offset[j]);
        M += Vec3(field[n], field[n + 1], field[n + 2]) *
             Vec3(st.grad[3 * j], st.grad[3 * j + 1], st.grad[3 * j + 2]).transpose();
    }
    return M;
}

/// f_I += P g for every entry of a stencil (P = V0 J sigma F^-T).
void scatter(const StencilView& st, const Mat3& P, std::vector<real_t>& f)
{
    for (index_t j = 0; j < st.size; ++j)
    {
        const Vec3 fi = P * Vec3(st.grad[3 * j], st.grad[3 * j + 1], st.grad[3 * j + 2]);
        for (int a = 0; a < 3; ++a)
            f[3 * static_cast<std::size_t>(st.base + st.offset[j]) + a] += fi[a];
    }
}

Mat3 tensor(const real_t s[6])
{
    Mat3 S;
    S << s[0], s[3], s[5], s[3], s[1], s[4], s[5], s[4], s[2];
    return S;
}

} // namespace

NodalPass nodal_reference(const NodalBlock& blk, const NodeSet& nodes, real_t dt, PlasticPoints* history)
{
    const bool inelastic = blk.plastic.active();
    RKFEM_REQUIRE(!inelastic || history != nullptr, "nodal_reference: an inelastic block needs a history copy");
    NodalPass out;
    out.f.assign(nodes.f_int.size(), 0.0);
    const IntegrationOperator& op = blk.points;
    const index_t np = blk.n_points(), ns = blk.n_stab();
    const ElasticParams mat = blk.material;
    const real_t c = mat.wave_speed();
    const real_t q1 = blk.bulk_viscosity.quadratic, q2 = blk.bulk_viscosity.linear;
    std::vector<Mat3> finv(static_cast<std::size_t>(np));
    std::vector<Vec3> spin(static_cast<std::size_t>(np));
    std::vector<real_t> jac(static_cast<std::size_t>(np));
    // plastic scaling: the share of the step each point's material took elastically
    const bool scaled = inelastic && blk.stab_plastic_scaling && ns > 0;
    std::vector<real_t> share(scaled ? static_cast<std::size_t>(np) : 0, 1.0);
    out.stress.resize(6 * static_cast<std::size_t>(np));
    for (index_t p = 0; p < np; ++p)
    {
        const Mat3 F = stencil_sum(blk.point_view(p), nodes.u, true),
                   Fd = stencil_sum(blk.point_view(p), nodes.v, false);
        const real_t J = F.determinant();
        const Mat3 Fi = F.inverse();
        real_t d[6], w[3], s_old[6];
        split_rate(Fd * Fi, d, w);
        real_t* s = &out.stress[6 * static_cast<std::size_t>(p)];
        for (int k = 0; k < 6; ++k)
            s_old[k] = s[k] = blk.stress[k * blk.stress_stride + static_cast<std::size_t>(p)];
        if (!inelastic)
            elastic_update(mat, d, w, dt, s);
        else if (J > 0.0)
            history->update(static_cast<std::size_t>(p), d, w, dt, s);
        if (scaled)
            share[p] = assumed_strain_tangent_share<real_t>(s_old, s, d, w, mat.mu, dt);
        // q on the point's length; the step alpha times the element form's on it (alpha
        // calibrates the step, not the viscosity)
        const real_t len = std::cbrt(J) * blk.length0[static_cast<std::size_t>(p)];
        const real_t trd = d[0] + d[1] + d[2];
        const real_t q = bulk_q(mat.rho / J, c, len, trd, q1, q2);
        out.dt_stable = std::min(out.dt_stable, blk.dt_factor * element_dt(c, len, trd, q1, q2));
        const real_t VJ = op.weight[p] * J;
        out.d_internal += dt * VJ * stress_power(s_old, s, d);
        out.d_bulk_viscosity += -dt * VJ * q * trd;
        scatter(blk.point_view(p), VJ * (tensor(s) - q * Mat3::Identity()) * Fi.transpose(), out.f);
        finv[p] = Fi;
        spin[p] = Vec3(w[0], w[1], w[2]);
        jac[p] = J;
    }
    // MSCNI: each sub-cell's stress from its own strain rate, with its parent's F^-1 and spin
    const IntegrationOperator& st = blk.stabilization;
    ElasticParams smat = mat;
    smat.lambda *= blk.stabilization_coefficient;
    smat.mu *= blk.stabilization_coefficient;
    out.stab_stress.resize(6 * static_cast<std::size_t>(ns));
    // NSNI held as triplets (NodalBlock::stab_in_triplets): sub-point i's gradient at entry k is
    // row i of the entry's symmetric matrix, written out here one sub-point at a time
    std::vector<index_t> sub_offset;
    std::vector<real_t> sub_grad;
    auto stab_view = [&](index_t s) -> StencilView
    {
        if (!blk.stab_in_triplets)
            return blk.stab_view(s);
        const TripletView t = blk.stab_triplets.view(s / 3);
        const int i = static_cast<int>(s % 3);
        constexpr int row[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};
        sub_offset.assign(t.offset, t.offset + t.size);
        sub_grad.resize(3 * static_cast<std::size_t>(t.size));
        for (index_t k = 0; k < t.size; ++k)
            for (int d = 0; d < 3; ++d)
                sub_grad[3 * static_cast<std::size_t>(k) + d] = t.hess[6 * static_cast<std::size_t>(k) + row[i][d]];
        return {sub_offset.data(), sub_grad.data(), t.size, t.base};
    };
    for (index_t s = 0; s < ns; ++s)
    {
        const index_t P = st.parent[s];
        real_t d[6], w_unused[3], s_old[6];
        const StencilView sv = stab_view(s);
        split_rate(stencil_sum(sv, nodes.v, false) * finv[P], d, w_unused);
        const real_t w[3] = {spin[P][0], spin[P][1], spin[P][2]};
        real_t* sg = &out.stab_stress[6 * static_cast<std::size_t>(s)];
        for (int k = 0; k < 6; ++k)
            s_old[k] = sg[k] = blk.stab_stress[k * static_cast<std::size_t>(ns) + static_cast<std::size_t>(s)];
        elastic_update(smat, d, w, dt, sg);
        if (scaled)
            scale_stabilization_load(hughes_winget(w[0], w[1], w[2], dt), s_old, share[P], sg);
        const real_t VJ = st.weight[s] * jac[P];
        out.d_stabilization += dt * VJ * stress_power(s_old, sg, d);
        scatter(sv, VJ * tensor(sg) * finv[P].transpose(), out.f);
    }
    return out;
}
} // namespace rkfem
