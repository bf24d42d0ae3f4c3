// Hourglass modes of a 1-point hex: a pure hourglass velocity produces no strain (so no stress
// and no force without control), is resisted by the viscous form with the exact force
// a_h gamma (gamma . v), and the stiffness form stores exactly the work done on it.
#include <gtest/gtest.h>

#include "../support.hpp"
#include "rkfem/approximation/fem/hex8_basis.hpp"

using namespace rkfem;

namespace
{
constexpr real_t h = 0.1;

struct OneElement
{
    HexMesh mesh = generate_box(Vec3::Zero(), Vec3::Constant(h), {1, 1, 1});
    NodeSet nodes;
    HexBlock blk;
    ElasticParams mat = ElasticParams::from_E_nu(7850, 200e9, 0.3);
    explicit OneElement(HourglassType t, real_t qm = 0.1)
    {
        blk = test::make_block(mesh, nodes, Formulation::Fem1pt, {t, qm}, mat);
    }
    void set_hourglass_velocity(int mode, int dir, real_t amp)
    {
        for (int I = 0; I < 8; ++I)
            for (int d = 0; d < 3; ++d)
                nodes.v[3 * blk.conn[I] + d] = d == dir ? amp * hex8_hourglass_base[mode][I] : 0.0;
    }
};
} // namespace

TEST(Hourglass, PureModeProducesNoStrainWithoutControl)
{
    for (int mode = 0; mode < 4; ++mode)
        for (int dir = 0; dir < 3; ++dir)
        {
            OneElement e(HourglassType::None);
            e.set_hourglass_velocity(mode, dir, 1.0);
            hex_internal_force(e.blk, e.nodes, 1e-6);
            assemble_block_forces(e.blk, e.nodes);
            for (int k = 0; k < 6; ++k)
                // round-off of E * (amp / h) * dt = 2e6 Pa
                EXPECT_NEAR(e.blk.stress_trial[k * e.blk.stress_stride], 0.0, 1e-14 * 200e9 * (1.0 / h) * 1e-6) << "mode " << mode << " dir " << dir;
            for (real_t f : e.nodes.f_int)
                EXPECT_NEAR(f, 0.0, 1e-6); // stress E*D*dt ~ 1e5 Pa would give ~1e3 N
        }
}

TEST(Hourglass, ViscousFormResistsWithTheExactForce)
{
    OneElement e(HourglassType::Viscous, 0.1);
    const real_t amp = 2.0;
    e.set_hourglass_velocity(1, 2, amp);
    const ForcePassResult r = hex_internal_force(e.blk, e.nodes, 1e-6);
    assemble_block_forces(e.blk, e.nodes);
    // cube: gamma = Gamma, qdot = sum v gamma = 8 amp, f_I = a_h Gamma_I qdot, a_h = QM rho c l^2 / 4
    const real_t ah = 0.25 * 0.1 * e.mat.rho * e.mat.wave_speed() * h * h;
    real_t power = 0.0;
    for (int I = 0; I < 8; ++I)
    {
        const index_t n = e.blk.conn[I];
        EXPECT_NEAR(e.nodes.f_int[3 * n + 2], ah * hex8_hourglass_base[1][I] * 8 * amp,
                    1e-12 * ah * 8 * amp);
        EXPECT_NEAR(e.nodes.f_int[3 * n + 0], 0.0, 1e-12 * ah * 8 * amp);
        power += e.nodes.f_int[3 * n + 2] * e.nodes.v[3 * n + 2];
    }
    EXPECT_GT(power, 0.0); // resisting: the force does negative work on the motion
    EXPECT_NEAR(r.d_hourglass, power * 1e-6, 1e-12 * power * 1e-6);
}

TEST(Hourglass, StiffnessFormStoresTheWorkDoneOnIt)
{
    OneElement e(HourglassType::Stiffness, 0.05);
    const real_t dt = 1e-8, rate = 1e-3; // hourglass amplitude grows to ~1e-9 h: geometry ~ fixed
    real_t work = 0.0, stored = 0.0;
    std::vector<real_t> f_old(e.nodes.f_int.size(), 0.0);
    for (int step = 0; step < 200; ++step)
    {
        e.set_hourglass_velocity(0, 0, rate);
        std::vector<real_t> du(e.nodes.u.size());
        for (std::size_t j = 0; j < du.size(); ++j)
        {
            du[j] = dt * e.nodes.v[j];
            e.nodes.u[j] += du[j];
            e.nodes.x[j] = e.nodes.x0[j] + e.nodes.u[j];
        }
        stored += hex_internal_force(e.blk, e.nodes, dt).d_hourglass;
        assemble_block_forces(e.blk, e.nodes);
        e.blk.commit();
        for (std::size_t j = 0; j < du.size(); ++j)
            work += 0.5 * (f_old[j] + e.nodes.f_int[j]) * du[j];
        f_old = e.nodes.f_int;
    }
    // analytic: E = 1/2 k q^2 with q = 8 rate t, k = QM (lambda + 2 mu) sum|b|^2 / (3V); cube:
    // b_I = (h^2/4)(+-1, +-1, +-1), sum|b|^2 = 1.5 h^4, so k = QM (lambda + 2 mu) h / 2
    const real_t k = 0.05 * e.mat.plane_wave_modulus() * h / 2;
    const real_t q = 8 * rate * 200 * dt;
    EXPECT_GT(stored, 0.0);
    EXPECT_NEAR(stored, work, 1e-9 * work);
    EXPECT_NEAR(stored, 0.5 * k * q * q, 1e-6 * stored);
}

TEST(Hourglass, StiffnessFormIsObjectiveUnderRigidRotation)
{
    // load hourglass mode 0 along x in the stiffness form, then turn the element rigidly by a
    // quarter turn about z in 2000 steps (x = R(theta) x1, v = omega x z-hat cross x): the
    // hourglass velocity is zero throughout (g_a = W h_a = L h_a), so the stored energy stays,
    // and the stored forces must turn with the element (Q += dt W Q each step); kept in the
    // global frame they would still point along x (an error of sqrt(2) of the force)
    OneElement e(HourglassType::Stiffness, 0.1);
    const real_t dt = 1e-8;
    e.set_hourglass_velocity(0, 0, 1.0);
    for (int n = 0; n < 20; ++n)
    {
        for (std::size_t j = 0; j < e.nodes.x.size(); ++j)
            e.nodes.x[j] += dt * e.nodes.v[j];
        hex_internal_force(e.blk, e.nodes, dt);
        e.blk.commit();
    }
    const std::vector<real_t> x1 = e.nodes.x;
    // the force of the loaded state, at rest
    std::fill(e.nodes.v.begin(), e.nodes.v.end(), 0.0);
    real_t e_hg = 0.0;
    e_hg += hex_internal_force(e.blk, e.nodes, dt).d_hourglass;
    assemble_block_forces(e.blk, e.nodes);
    const std::vector<real_t> f0 = e.nodes.f_int;
    const int steps = 2000;
    const real_t omega = 0.5 * M_PI / (steps * dt);
    const Vec3 c(0.5 * h, 0.5 * h, 0.5 * h); // turn about the element's centre line
    for (int n = 1; n <= steps; ++n)
    {
        const real_t th = n * dt * omega;
        for (int I = 0; I < 8; ++I)
        {
            const Vec3 r(x1[3 * I] - c[0], x1[3 * I + 1] - c[1], x1[3 * I + 2] - c[2]);
            const Vec3 xr(std::cos(th) * r[0] - std::sin(th) * r[1], std::sin(th) * r[0] + std::cos(th) * r[1], r[2]);
            for (int d = 0; d < 3; ++d)
                e.nodes.x[3 * I + d] = c[d] + xr[d];
            e.nodes.v[3 * I] = -omega * xr[1];
            e.nodes.v[3 * I + 1] = omega * xr[0];
            e.nodes.v[3 * I + 2] = 0.0;
        }
        e_hg += hex_internal_force(e.blk, e.nodes, dt).d_hourglass;
        e.blk.commit();
    }
    std::fill(e.nodes.v.begin(), e.nodes.v.end(), 0.0);
    hex_internal_force(e.blk, e.nodes, dt);
    assemble_block_forces(e.blk, e.nodes);
    // f1 should be f0 turned by a quarter turn: (fx, fy) -> (-fy, fx)
    real_t err = 0.0, scale = 0.0;
    for (int I = 0; I < 8; ++I)
    {
        const Vec3 want(-f0[3 * I + 1], f0[3 * I], f0[3 * I + 2]);
        const Vec3 got(e.nodes.f_int[3 * I], e.nodes.f_int[3 * I + 1], e.nodes.f_int[3 * I + 2]);
        err = std::max(err, (got - want).norm());
        scale = std::max(scale, want.norm());
    }
    std::printf("stiffness hourglass after a quarter turn: forces within %.2e of the turned ones (relative), "
                "hourglass work during the turn %.2e J\n",
                err / scale, e_hg);
    EXPECT_LT(err / scale, 1e-3); // first-order rotation: (1 + (omega dt)^2)^(n/2) - 1 = 3e-4
    EXPECT_LT(std::abs(e_hg), 1e-12 * scale * h);
}
