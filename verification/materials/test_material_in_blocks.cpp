// One material serves every discretization: a homogeneous motion x = F(t) X (stretch, shear and
// rotation) of a one-element block gives the same stress history in a fem-1pt element, a
// fem-2x2x2 element and an RK particle block (SCNI), for the elastic, J2, K&C concrete and CSCM models.
#include <gtest/gtest.h>

#include <cstdio>

#include "../support.hpp"
#include "rkfem/model/material_from_deck.hpp"
#include "rkfem/model/nodal_block_build.hpp"
#include "rkfem/operators/hex_block.hpp"
#include "rkfem/operators/nodal_block.hpp"
#include "rkfem/operators/nodal_force.hpp"

using namespace rkfem;

namespace
{
/// Velocity gradient of the homogeneous motion [1/s]: stretch, shear and spin.
Mat3 velocity_gradient()
{
    Mat3 L;
    L << 30.0, 20.0, 0.0, -10.0, -8.0, 5.0, 0.0, -5.0, -6.0;
    return L;
}

/// Stress history (xx and xy at the first point) under x = X + u, v = L x, dt fixed.
std::vector<Sym6> history(const std::string& model, int kind)
{
    const HexMesh mesh = generate_box(Vec3::Zero(), Vec3::Constant(1e-3), {1, 1, 1});
    NodeSet nodes;
    const MaterialSpec ms = test::block_material(model);
    const ElasticParams el = ElasticParams::from_E_nu(ms.rho, ms.E, ms.nu);
    HexBlock hb;
    NodalBlock nb;
    if (kind < 2)
    {
        hb = test::make_block(mesh, nodes, kind == 0 ? Formulation::Fem1pt : Formulation::Fem2x2x2,
                              {HourglassType::None, 0.0}, el, {0.0, 0.0});
        configure_points(hb.plastic, ms);
        hb.initialize(nodes);
        // crack band: the element's V^(1/3) = 1 mm, as the model sets it (and as the particles' spacing)
        hb.plastic.set_lengths(std::vector<real_t>(static_cast<std::size_t>(hb.n_points()), 1e-3));
    }
    else
    {
        nodes.resize(mesh.n_nodes());
        nodes.x0 = nodes.x = mesh.x;
        PartSpec ps;
        ps.formulation = Formulation::Rkpm;
        ps.material = ms;
        ps.nodal.stabilization = "none";
        ps.bulk_viscosity = {0.0, 0.0};
        nb = build_nodal_block(ps, mesh, 0);
    }
    // concrete is driven in compression (in tension it fails at f_t = 3.8 MPa at once)
    const Mat3 L = model == "kcc" || model == "cscm" ? Mat3(-velocity_gradient()) : velocity_gradient();
    const real_t dt = 1e-6;
    std::vector<Sym6> out;
    for (int step = 0; step < 400; ++step) // to about 1.2 % strain, well past yield (0.2 %)
    {
        // exact homogeneous motion: x(t+dt) = exp(L dt) x(t), advanced with the midpoint velocity
        for (index_t i = 0; i < nodes.size(); ++i)
        {
            const Vec3 x(nodes.x[3 * i], nodes.x[3 * i + 1], nodes.x[3 * i + 2]);
            const Vec3 xm = x + 0.5 * dt * L * x;
            const Vec3 v = L * xm;
            for (int d = 0; d < 3; ++d)
            {
                nodes.v[3 * i + d] = v[d];
                nodes.u[3 * i + d] += dt * v[d];
                nodes.x[3 * i + d] = nodes.x0[3 * i + d] + nodes.u[3 * i + d];
            }
        }
        Sym6 s;
        if (kind < 2)
        {
            hex_internal_force(hb, nodes, dt);
            hb.commit();
            for (int k = 0; k < 6; ++k)
                s[k] = hb.stress[k * hb.stress_stride];
        }
        else
        {
            nodal_internal_force(nb, nodes, dt);
            nb.commit();
            for (int k = 0; k < 6; ++k)
                s[k] = nb.stress[k * nb.stress_stride];
        }
        out.push_back(s);
    }
    return out;
}
} // namespace

TEST(MaterialInBlocks, SameStressHistoryInFemAndRkBlocks)
{
    for (const char* model : {"elastic", "j2", "kcc", "cscm"})
    {
        const auto a = history(model, 0), b = history(model, 1), c = history(model, 2);
        real_t d_ab = 0.0, d_ac = 0.0, scale = 0.0;
        for (std::size_t k = 0; k < a.size(); ++k)
        {
            scale = std::max(scale, a[k].cwiseAbs().maxCoeff());
            d_ab = std::max(d_ab, (a[k] - b[k]).cwiseAbs().maxCoeff());
            d_ac = std::max(d_ac, (a[k] - c[k]).cwiseAbs().maxCoeff());
        }
        std::printf("%-7s: max stress %.3e Pa; |fem-1pt - fem-2x2x2| %.2e, |fem-1pt - rkpm| %.2e (relative)\n", model,
                    scale, d_ab / scale, d_ac / scale);
        EXPECT_LT(d_ab / scale, 1e-10) << model;
        EXPECT_LT(d_ac / scale, 1e-10) << model;
    }
}
