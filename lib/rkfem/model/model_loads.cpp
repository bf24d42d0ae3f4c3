// Loads: the dofs they reach, and f_ext at a time (nodal forces, pressure on FE, RK and cloud faces).
#include "rkfem/model/model.hpp"

#include <cmath>

namespace rkfem
{
void Model::collect_loaded_dofs()
{
    std::vector<char> loaded(nodes.f_ext.size(), 0);
    auto node_dofs = [&](index_t n)
    {
        for (int k = 0; k < 3; ++k)
            loaded[3 * static_cast<std::size_t>(n) + k] = 1;
    };
    for (const auto& [load, ids] : nodal_loads_)
        for (int k = 0; k < 3; ++k)
            if (load->active[k])
                for (index_t n : ids)
                    kinematics.for_row(n, [&](index_t j, real_t) { loaded[3 * static_cast<std::size_t>(j) + k] = 1; });
    for (std::size_t il = 0; il < pressure_loads_.size(); ++il)
    {
        for (index_t n : cloud_face_loads_[il].nodes)
            node_dofs(n);
        const RkFaceLoads& rl = rk_face_loads_[il];
        const std::vector<Quad>& faces = *pressure_loads_[il].second;
        for (std::size_t fi = 0; fi < faces.size(); ++fi)
            if (!rl.is_rk[fi])
                for (index_t n : faces[fi])
                    kinematics.for_row(n, [&](index_t j, real_t) { node_dofs(j); });
        for (index_t n : rl.nodes)
            node_dofs(n);
    }
    loaded_dofs_.clear();
    for (std::size_t j = 0; j < loaded.size(); ++j)
        if (loaded[j])
            loaded_dofs_.push_back(static_cast<index_t>(j));
    f_ext_prev_.assign(loaded_dofs_.size(), 0.0);
}

void Model::apply_external_forces(real_t t)
{
    // f_ext is zero at every dof but the loaded ones; a load added here must add the dofs it
    // writes in collect_loaded_dofs()
    for (const index_t j : loaded_dofs_)
        nodes.f_ext[j] = 0.0;
    for (const auto& [load, ids] : nodal_loads_)
        for (int k = 0; k < 3; ++k)
            if (load->active[k])
            {
                real_t f = load->force[k](t);
                if (load->total)
                    f /= static_cast<real_t>(ids.size());
                for (index_t n : ids)
                {
                    // a force at the node's physical point (RK particles: spread to the
                    // coefficients through the kinematic map)
                    Vec3 fk = Vec3::Zero();
                    fk[k] = f;
                    kinematics.spread(n, fk, nodes.f_ext.data());
                }
            }
    for (std::size_t il = 0; il < pressure_loads_.size(); ++il)
    {
        const auto& [load, faces] = pressure_loads_[il];
        const real_t p = load->pressure(t);
        if (p == 0.0)
            continue;
        // cloud facets: -p Psi_I n da on the current facet, n da = J F^-T N dA (Nanson) with
        // F = 1 + sum_I d_I (x) grad Psi_I at the facet point
        const CloudFaceLoads& cl = cloud_face_loads_[il];
        for (std::size_t q = 0; q < cl.nda.size(); ++q)
        {
            Mat3 F = Mat3::Identity();
            for (index_t k = cl.offsets[q]; k < cl.offsets[q + 1]; ++k)
                F += Vec3(nodes.u[3 * cl.nodes[k]], nodes.u[3 * cl.nodes[k] + 1], nodes.u[3 * cl.nodes[k] + 2]) *
                     cl.grad[k].transpose();
            const Vec3 nda = F.determinant() * F.inverse().transpose() * cl.nda[q];
            for (index_t k = cl.offsets[q]; k < cl.offsets[q + 1]; ++k)
                for (int d = 0; d < 3; ++d)
                    nodes.f_ext[3 * cl.nodes[k] + d] -= p * cl.psi[k] * nda[d];
        }
        const RkFaceLoads& rl = rk_face_loads_[il];
        for (std::size_t fi = 0; fi < faces->size(); ++fi)
        {
            const Quad& q = (*faces)[fi];
            if (!rl.is_rk[fi])
            {
                // area-weighted, outward, on the physical corners (coupled parts' particles carry
                // coefficients)
                Vec3 n = quad_normal(nodes.x, q);
                if (kinematics.carries_coefficients(q[0]) || kinematics.carries_coefficients(q[1]) ||
                    kinematics.carries_coefficients(q[2]) || kinematics.carries_coefficients(q[3]))
                {
                    Vec3 xc[4];
                    for (int c = 0; c < 4; ++c)
                        xc[c] = kinematics.position(nodes.x0, nodes.u, q[c]);
                    n = 0.5 * (xc[2] - xc[0]).cross(xc[3] - xc[1]);
                }
                for (index_t node : q)
                    kinematics.spread(node, -0.25 * p * n, nodes.f_ext.data()); // the node itself on FE parts
                continue;
            }
            // RK face: bilinear patch through the physical corner positions, 2x2 Gauss points,
            // force -p n dA distributed with Psi_I(X_K)
            Vec3 xc[4];
            for (int c = 0; c < 4; ++c)
                xc[c] =
                    Vec3(nodes.x0[3 * q[c]], nodes.x0[3 * q[c] + 1], nodes.x0[3 * q[c] + 2]) + physical(nodes.u, q[c]);
            const real_t g = 1.0 / std::sqrt(3.0);
            for (int gp = 0; gp < 4; ++gp)
            {
                const real_t r = gp % 2 ? g : -g, s = gp / 2 ? g : -g;
                // corners in order (-1,-1), (1,-1), (1,1), (-1,1)
                const Vec3 xr = 0.25 * ((1 - s) * (xc[1] - xc[0]) + (1 + s) * (xc[2] - xc[3]));
                const Vec3 xs = 0.25 * ((1 - r) * (xc[3] - xc[0]) + (1 + r) * (xc[2] - xc[1]));
                const Vec3 nda = xr.cross(xs); // weight 1 per Gauss point on [-1, 1]^2
                const std::size_t pt = 4 * fi + gp;
                for (index_t k = rl.point_offsets[pt]; k < rl.point_offsets[pt + 1]; ++k)
                    for (int d = 0; d < 3; ++d)
                        nodes.f_ext[3 * rl.nodes[k] + d] -= p * rl.psi[k] * nda[d];
            }
        }
    }
}
} // namespace rkfem
