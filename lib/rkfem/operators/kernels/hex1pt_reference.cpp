#include "rkfem/operators/kernels/hex1pt_reference.hpp"

#include <algorithm>
#include <cmath>

#include "rkfem/approximation/fem/hex8_basis.hpp"
#include "rkfem/approximation/fem/hex8_volume_gradient.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/discretization/hex_mesh.hpp"
#include "rkfem/materials/elastic.hpp"
#include "rkfem/operators/bulk_viscosity.hpp"
#include "rkfem/operators/kernels/assumed_strain_hourglass.hpp"

namespace rkfem
{
Hex1ptElement hex1pt_reference(const HexBlock& blk, const NodeSet& nodes, index_t e, real_t dt, PlasticPoints* history)
{
    const bool inelastic = blk.plastic.active();
    RKFEM_REQUIRE(!inelastic || history != nullptr, "hex1pt_reference: an inelastic block needs a history copy");
    Hex1ptElement out;
    const ElasticParams mat = blk.material;
    const real_t c = mat.wave_speed();
    const std::size_t ne = static_cast<std::size_t>(blk.n_elements());
    real_t x[8][3], v[8][3];
    for (int I = 0; I < 8; ++I)
        for (int d = 0; d < 3; ++d)
        {
            const std::size_t n = 3 * static_cast<std::size_t>(blk.conn[8 * static_cast<std::size_t>(e) + I]) + d;
            x[I][d] = nodes.x[n];
            v[I][d] = nodes.v[n];
        }

    // uniform gradient, volume, velocity gradient
    real_t b[8][3];
    const real_t V = hex8_volume_gradient(x, b);
    out.volume = V;
    real_t L[3][3] = {};
    for (int I = 0; I < 8; ++I)
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                L[i][j] += v[I][i] * b[I][j] / V;
    const real_t dv[6] = {
        L[0][0], L[1][1], L[2][2], 0.5 * (L[0][1] + L[1][0]), 0.5 * (L[1][2] + L[2][1]), 0.5 * (L[2][0] + L[0][2])};
    const real_t wv[3] = {0.5 * (L[0][1] - L[1][0]), 0.5 * (L[1][2] - L[2][1]), 0.5 * (L[2][0] - L[0][2])};

    // stress update
    real_t s_old[6];
    for (int k = 0; k < 6; ++k)
        s_old[k] = blk.stress[k * blk.stress_stride + static_cast<std::size_t>(e)];
    std::copy(s_old, s_old + 6, out.stress);
    if (inelastic)
        history->update(static_cast<std::size_t>(e), dv, wv, dt, out.stress);
    else
        elastic_update(mat, dv, wv, dt, out.stress);
    // the share of the step the material took elastically: the stiffness forms' loads take it,
    // their unloads do not (scaled_hourglass_update)
    const bool scaled = inelastic && blk.hourglass.plastic_scaling;
    const real_t share = scaled ? assumed_strain_tangent_share<real_t>(s_old, out.stress, dv, wv, mat.mu, dt) : 1.0;

    // characteristic length: volume over the largest face area
    std::vector<real_t> xv(&x[0][0], &x[0][0] + 24);
    real_t area = 0.0;
    for (const auto& face : hex_faces)
        area = std::max(area, quad_normal(xv, {face[0], face[1], face[2], face[3]}).norm());
    const real_t lc = V / area;

    // bulk viscosity, stable step, energies
    const real_t trd = dv[0] + dv[1] + dv[2];
    const real_t rho = mat.rho * blk.volume0[static_cast<std::size_t>(e)] / V;
    const real_t q1 = blk.bulk_viscosity.quadratic, q2 = blk.bulk_viscosity.linear;
    const real_t q = bulk_q(rho, c, lc, trd, q1, q2);
    out.dt_stable = element_dt(c, lc, trd, q1, q2);
    real_t power = 0.0;
    for (int k = 0; k < 6; ++k)
        power += (k < 3 ? 0.5 : 1.0) * (s_old[k] + out.stress[k]) * dv[k];
    out.d_internal = dt * V * power;
    out.d_bulk_viscosity = -dt * V * q * trd;

    // T = sigma - q 1 - (1/V) sum_a Q_a (x) h_a, by rows
    static constexpr int voigt[3][3] = {{0, 3, 5}, {3, 1, 4}, {5, 4, 2}};
    real_t T[3][3];
    real_t Q_fb[4][3] = {}; // the hourglass generalized forces on the FB base vectors (global)
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            T[i][j] = out.stress[voigt[i][j]] - (i == j ? q : 0.0);
    const HourglassType hg = blk.hourglass.type;
    if (hg != HourglassType::None)
    {
        // per FB mode a: h_a = sum_J Gamma_aJ x_J and the hourglass velocity qdot_a = sum_J
        // Gamma_aJ v_J - L h_a (the plain viscous form: without - L h_a)
        real_t h[4][3] = {}, qdot[4][3] = {};
        for (int a = 0; a < 4; ++a)
        {
            for (int J = 0; J < 8; ++J)
                for (int d = 0; d < 3; ++d)
                {
                    h[a][d] += hex8_hourglass_base[a][J] * x[J][d];
                    qdot[a][d] += hex8_hourglass_base[a][J] * v[J][d];
                }
            if (hg != HourglassType::ViscousPlain)
                for (int i = 0; i < 3; ++i)
                    for (int j = 0; j < 3; ++j)
                        qdot[a][i] -= L[i][j] * h[a][j];
        }
        if (hg == HourglassType::AssumedStrain)
        {
            // the element's axes r, s, t give the co-rotational frame and its sizes
            real_t axes[3][3] = {};
            for (int J = 0; J < 8; ++J)
                for (int k = 0; k < 3; ++k)
                    for (int d = 0; d < 3; ++d)
                        axes[k][d] += hex8_nodes[J][k] * x[J][d];
            real_t frame[3][3], Jf[3];
            assumed_strain_frame(axes[0], axes[1], axes[2], frame, Jf);
            const real_t nu = mat.lambda / (2.0 * (mat.lambda + mat.mu));
            // the step's hourglass stress increment dS = QM (G / 3) dt q / J, and the forces it adds
            real_t q[4][3], dS[4][3];
            for (int m = 0; m < 4; ++m)
            {
                const int a = kAssumedStrainMode[m];
                for (int i = 0; i < 3; ++i)
                {
                    q[m][i] = (frame[i][0] * qdot[a][0] + frame[i][1] * qdot[a][1] + frame[i][2] * qdot[a][2]) / 8.0;
                    dS[m][i] = dt * blk.hourglass.coefficient * mat.mu / 3.0 * q[m][i] / Jf[i];
                }
            }
            real_t dQ[4][3];
            assumed_strain_forces(dS, Jf, nu, dQ);
            // the stored forces follow the change of their stiffness since they were stored
            real_t Jo[3], keep[4][3];
            for (int i = 0; i < 3; ++i)
            {
                Jo[i] =
                    blk.hg_force[static_cast<std::size_t>(HexBlock::kHgSizeRow + i) * ne + static_cast<std::size_t>(e)];
                out.hg_size[i] = Jf[i];
            }
            assumed_strain_keep(Jo, Jf, keep);
            for (int m = 0; m < 4; ++m)
            {
                const int a = kAssumedStrainMode[m];
                real_t Q_new[3];
                for (int i = 0; i < 3; ++i)
                {
                    const real_t Q_old =
                        keep[m][i] *
                        blk.hg_force[static_cast<std::size_t>(3 * m + i) * ne + static_cast<std::size_t>(e)];
                    if (scaled)
                    {
                        Q_new[i] = scaled_hourglass_update(Q_old, dQ[m][i], share);
                        out.hg_force[m][i] = Q_new[i];
                        out.d_hourglass += 0.5 * dt * (Q_old + Q_new[i]) * q[m][i];
                    }
                    else
                    {
                        Q_new[i] = Q_old + dQ[m][i];
                        out.hg_force[m][i] = Q_new[i];
                        out.d_hourglass += dt * (Q_old + 0.5 * dQ[m][i]) * q[m][i];
                    }
                }
                // the generalized force on FB mode a, global component j
                for (int j = 0; j < 3; ++j)
                    Q_fb[a][j] = (frame[0][j] * Q_new[0] + frame[1][j] * Q_new[1] + frame[2][j] * Q_new[2]) / 8.0;
            }
        }
        else
        {
            const real_t qm = blk.hourglass.coefficient;
            real_t bb = 0.0;
            for (int I = 0; I < 8; ++I)
                for (int d = 0; d < 3; ++d)
                    bb += b[I][d] * b[I][d];
            // stiffness: Flanagan-Belytschko's k = QM (lambda + 2 mu) sum|b|^2 / (3 V) acts on their
            // normalized modes Gamma / sqrt(8), rate and force both: on our +-1 vectors that is k / 8
            const real_t ch = hg == HourglassType::Stiffness ? qm * mat.plane_wave_modulus() * bb / (24.0 * V)
                                                             : 0.25 * qm * mat.rho * c * lc * lc;
            for (int a = 0; a < 4; ++a)
            {
                // stiffness form: the stored force turns with the element's spin W first (Q += dt W Q,
                // the first-order rotation the Jaumann stress update makes), so it is objective
                real_t Q_rot[3] = {};
                if (hg == HourglassType::Stiffness)
                {
                    real_t Q_old[3];
                    for (int i = 0; i < 3; ++i)
                        Q_old[i] = blk.hg_force[static_cast<std::size_t>(3 * a + i) * ne + static_cast<std::size_t>(e)];
                    for (int i = 0; i < 3; ++i)
                    {
                        Q_rot[i] = Q_old[i];
                        for (int j = 0; j < 3; ++j)
                            Q_rot[i] += dt * 0.5 * (L[i][j] - L[j][i]) * Q_old[j];
                    }
                }
                for (int i = 0; i < 3; ++i)
                {
                    real_t& Q = Q_fb[a][i];
                    if (hg == HourglassType::Stiffness)
                    {
                        Q = scaled ? scaled_hourglass_update(Q_rot[i], ch * dt * qdot[a][i], share)
                                   : Q_rot[i] + ch * dt * qdot[a][i];
                        out.d_hourglass += 0.5 * dt * (Q_rot[i] + Q) * qdot[a][i];
                    }
                    else
                    {
                        Q = ch * qdot[a][i];
                        out.d_hourglass += dt * Q * qdot[a][i];
                    }
                    out.hg_force[a][i] = Q;
                }
            }
        }
        // the hourglass forces' share of the gradient term (not for the plain form)
        if (hg != HourglassType::ViscousPlain)
            for (int a = 0; a < 4; ++a)
                for (int i = 0; i < 3; ++i)
                    for (int j = 0; j < 3; ++j)
                        T[i][j] -= Q_fb[a][i] * h[a][j] / V;
    }

    // nodal forces
    for (int I = 0; I < 8; ++I)
        for (int i = 0; i < 3; ++i)
        {
            real_t f = 0.0;
            for (int j = 0; j < 3; ++j)
                f += T[i][j] * b[I][j];
            if (hg != HourglassType::None)
                for (int a = 0; a < 4; ++a)
                    f += hex8_hourglass_base[a][I] * Q_fb[a][i];
            out.f[I][i] = f;
        }
    return out;
}
} // namespace rkfem
