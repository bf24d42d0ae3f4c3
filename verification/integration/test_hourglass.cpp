// Hourglass modes of a 1-point hex: a pure hourglass velocity produces no strain (so no stress
// and no force without control), is resisted by the viscous form with the exact force
// a_h gamma (gamma . v), and the stiffness form stores exactly the work done on it.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <array>
#include <cstdio>

#include "../support.hpp"
#include "rkfem/approximation/fem/hex8_basis.hpp"
#include "rkfem/core/state_archive.hpp"
#include "rkfem/materials/j2_plasticity.hpp"
#include "rkfem/model/material_from_deck.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/operators/kernels/assumed_strain_hourglass.hpp"
#include "rkfem/operators/linear_static.hpp"
#include "rkfem/time/central_difference.hpp"

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

/// The largest stored hourglass force of `hg` (a block's committed or trial state): its 12 force
/// rows per element (the assumed-strain form's frame sizes follow them).
real_t largest_hourglass_force(const HexBlock& blk, const std::vector<real_t>& hg)
{
    real_t largest = 0.0;
    for (std::size_t k = 0; k < 12 * static_cast<std::size_t>(blk.n_elements()); ++k)
        largest = std::max(largest, std::abs(hg[k]));
    return largest;
}

/// One 1 cm cube of J2 steel without hardening (yield 300 MPa, crack band 1 cm) with a stiffness
/// form `t` at QM 0.1, its plastic scaling on or off.
HexBlock perfectly_plastic_cube(HourglassType t, bool scaled, const HexMesh& mesh, NodeSet& nodes)
{
    const MaterialSpec ms = test::j2_material(7850, 200e9, 0.3, 300e6, 0.0);
    HourglassSpec hg{t, 0.1};
    hg.plastic_scaling = scaled;
    HexBlock blk =
        test::make_block(mesh, nodes, Formulation::Fem1pt, hg, ElasticParams::from_E_nu(ms.rho, ms.E, ms.nu));
    configure_points(blk.plastic, ms);
    blk.initialize(nodes);
    blk.plastic.set_lengths(std::vector<real_t>(1, 0.01));
    return blk;
}

/// Loads the element of (blk, nodes) by moving its nodes 20 steps of dt at their velocities, then
/// turns it rigidly by a quarter turn about the z line through c in `steps` steps (x = R(theta)
/// x1, v = omega z-hat x (x - c)), committing each step. Returns the hourglass work during the
/// turn, the largest force at rest before it (`scale`), and the largest difference of the forces
/// at rest after it from those before turned by the quarter turn ((fx, fy) -> (-fy, fx)).
struct QuarterTurn
{
    real_t work = 0.0, scale = 0.0, error = 0.0;
};

QuarterTurn load_then_quarter_turn(HexBlock& blk, NodeSet& nodes, const Vec3& c, int steps, real_t dt)
{
    for (int n = 0; n < 20; ++n)
    {
        for (std::size_t j = 0; j < nodes.x.size(); ++j)
            nodes.x[j] += dt * nodes.v[j];
        hex_internal_force(blk, nodes, dt);
        blk.commit();
    }
    const std::vector<real_t> x1 = nodes.x;
    // the force of the loaded state, at rest
    std::fill(nodes.v.begin(), nodes.v.end(), 0.0);
    QuarterTurn t;
    t.work += hex_internal_force(blk, nodes, dt).d_hourglass;
    assemble_block_forces(blk, nodes);
    const std::vector<real_t> f0 = nodes.f_int;
    const real_t omega = 0.5 * M_PI / (steps * dt);
    for (int n = 1; n <= steps; ++n)
    {
        const real_t th = n * dt * omega;
        for (int I = 0; I < 8; ++I)
        {
            const Vec3 r(x1[3 * I] - c[0], x1[3 * I + 1] - c[1], x1[3 * I + 2] - c[2]);
            const Vec3 xr(std::cos(th) * r[0] - std::sin(th) * r[1], std::sin(th) * r[0] + std::cos(th) * r[1], r[2]);
            for (int d = 0; d < 3; ++d)
                nodes.x[3 * I + d] = c[d] + xr[d];
            nodes.v[3 * I] = -omega * xr[1];
            nodes.v[3 * I + 1] = omega * xr[0];
            nodes.v[3 * I + 2] = 0.0;
        }
        t.work += hex_internal_force(blk, nodes, dt).d_hourglass;
        blk.commit();
    }
    std::fill(nodes.v.begin(), nodes.v.end(), 0.0);
    hex_internal_force(blk, nodes, dt);
    assemble_block_forces(blk, nodes);
    for (int I = 0; I < 8; ++I)
    {
        const Vec3 want(-f0[3 * I + 1], f0[3 * I], f0[3 * I + 2]);
        const Vec3 got(nodes.f_int[3 * I], nodes.f_int[3 * I + 1], nodes.f_int[3 * I + 2]);
        t.error = std::max(t.error, (got - want).norm());
        t.scale = std::max(t.scale, want.norm());
    }
    return t;
}
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
                EXPECT_NEAR(e.blk.stress_trial[k * e.blk.stress_stride], 0.0, 1e-14 * 200e9 * (1.0 / h) * 1e-6)
                    << "mode " << mode << " dir " << dir;
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
        EXPECT_NEAR(e.nodes.f_int[3 * n + 2], ah * hex8_hourglass_base[1][I] * 8 * amp, 1e-12 * ah * 8 * amp);
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
    // analytic: E = 1/2 k q^2 with q = 8 rate t on the +-1 base vector, k = QM (lambda + 2 mu)
    // sum|b|^2 / (24 V) (Flanagan-Belytschko's / (3 V) on the mode normalized by 1/sqrt(8)); cube:
    // b_I = (h^2/4)(+-1, +-1, +-1), sum|b|^2 = 1.5 h^4, so k = QM (lambda + 2 mu) h / 16
    const real_t k = 0.05 * e.mat.plane_wave_modulus() * h / 16;
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
    e.set_hourglass_velocity(0, 0, 1.0);
    const QuarterTurn t = load_then_quarter_turn(e.blk, e.nodes, Vec3(0.5 * h, 0.5 * h, 0.5 * h), 2000, 1e-8);
    const real_t err = t.error, scale = t.scale, e_hg = t.work;
    std::printf("stiffness hourglass after a quarter turn: forces within %.2e of the turned ones (relative), "
                "hourglass work during the turn %.2e J\n",
                err / scale, e_hg);
    EXPECT_LT(err / scale, 1e-3); // first-order rotation: (1 + (omega dt)^2)^(n/2) - 1 = 3e-4
    EXPECT_LT(std::abs(e_hg), 1e-12 * scale * h);
}

// ---- assumed strain (Belytschko-Bindeman ASQBI, LS-DYNA IHQ 6 analog) ----

namespace
{
/// A box of edges (lx, ly, lz) turned by `rot`, one element, the assumed-strain form at QM 1.
struct TurnedBox
{
    HexMesh mesh;
    NodeSet nodes;
    HexBlock blk;
    Eigen::Matrix3d rot;
    TurnedBox(const Vec3& edges, const Eigen::Matrix3d& r, real_t E, real_t nu) : rot(r)
    {
        mesh = generate_box(Vec3::Zero(), edges, {1, 1, 1});
        for (index_t i = 0; i < mesh.n_nodes(); ++i)
        {
            const Vec3 x = rot * mesh.node(i);
            for (int d = 0; d < 3; ++d)
                mesh.x[3 * i + d] = x[d];
        }
        blk = test::make_block(mesh, nodes, Formulation::Fem1pt, {HourglassType::AssumedStrain, 1.0},
                               ElasticParams::from_E_nu(7850, E, nu));
    }
    /// node velocities of the displacement rate u_dir = H_mode(xi, eta, zeta) in the box's frame
    void set_mode(int mode, int dir)
    {
        for (int I = 0; I < 8; ++I)
        {
            const Vec3 local = Vec3::Unit(dir) * hex8_hourglass_base[mode][I];
            const Vec3 v = rot * local;
            for (int d = 0; d < 3; ++d)
                nodes.v[3 * blk.conn[I] + d] = v[d];
        }
    }
};

Eigen::Matrix3d some_rotation()
{
    return (Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()) * Eigen::AngleAxisd(-0.4, Vec3::UnitX()))
        .toRotationMatrix();
}
} // namespace

TEST(Hourglass, AssumedStrainModesCarryTheEnergiesOfTheirStrainFields)
{
    // one step of dt from rest with the nodes moving as mode H (u = d H with d = dt) stores
    // W = 1/2 K d^2, K the energy of the assumed strain field of a box of edges L (V = Lx Ly Lz):
    //   bending u_x = zeta xi d or xi eta d: E / (1 - nu^2) 4 V / (3 Lx^2) (transverse normal stress
    //     free, no parasitic shear), u_y = xi eta d: E / (1 - nu^2) 4 V / (3 Ly^2), ...
    //   warping u_x = xi eta zeta d: E 4 V / (9 Lx^2) (uniaxial)
    //   shear u_x = eta zeta d: G 4 V / 3 (1 / Ly^2 + 1 / Lz^2)
    // for a box turned in space (the co-rotational frame finds its axes), to round-off
    const real_t E = 200e9, nu = 0.3, G = E / (2 * (1 + nu)), dt = 1e-9;
    const Vec3 Lv(0.02, 0.05, 0.03);
    const real_t V = Lv.prod();
    const Eigen::Matrix3d rot = some_rotation();
    for (int mode = 0; mode < 4; ++mode) // hex8 order: xi eta, eta zeta, zeta xi, xi eta zeta
        for (int dir = 0; dir < 3; ++dir)
        {
            TurnedBox b(Lv, rot, E, nu);
            b.set_mode(mode, dir);
            const ForcePassResult r = hex_internal_force(b.blk, b.nodes, dt);
            // which natural coordinates the mode holds (xi, eta, zeta: 0, 1, 2)
            static constexpr int has[4][3] = {{1, 1, 0}, {0, 1, 1}, {1, 0, 1}, {1, 1, 1}};
            real_t K;
            if (mode == 3)
                K = E * 4 * V / (9 * Lv[dir] * Lv[dir]);
            else if (has[mode][dir])
                K = E / (1 - nu * nu) * 4 * V / (3 * Lv[dir] * Lv[dir]);
            else
            {
                const int o1 = (dir + 1) % 3, o2 = (dir + 2) % 3;
                K = G * 4 * V / 3 * (1 / (Lv[o1] * Lv[o1]) + 1 / (Lv[o2] * Lv[o2]));
            }
            const real_t want = 0.5 * K * dt * dt;
            EXPECT_NEAR(r.d_hourglass, want, 1e-12 * want) << "mode " << mode << " direction " << dir;
            EXPECT_NEAR(r.d_internal, 0.0, 1e-12 * want) << "a pure hourglass rate strains nothing";
        }
}

TEST(Hourglass, AssumedStrainPassesThePatchTestAndIsObjective)
{
    // a linear velocity field has no hourglass rate in the FB projection, so the stored stress
    // stays zero on a distorted patch; and a loaded element turned rigidly keeps its energy and
    // turns its forces (the stored stress lives in the element's frame)
    const HexMesh mesh = test::distorted_box(3, 0.01, 0.25);
    NodeSet nodes;
    HexBlock blk = test::make_block(mesh, nodes, Formulation::Fem1pt, {HourglassType::AssumedStrain, 1.0},
                                    ElasticParams::from_E_nu(7850, 200e9, 0.3));
    const real_t A[3][3] = {{1.0, 0.3, -0.2}, {0.1, -0.5, 0.4}, {0.25, 0.2, 0.7}};
    for (int step = 0; step < 5; ++step)
    {
        test::linear_velocity_step(nodes, A, 1e-7);
        EXPECT_NEAR(hex_internal_force(blk, nodes, 1e-7).d_hourglass, 0.0, 1e-20);
        blk.commit();
    }
    const real_t stored = largest_hourglass_force(blk, blk.hg_force);
    EXPECT_LT(stored, 1e-6) << "hourglass stress under a linear field (Pa x m: would be ~1e6 if it leaked)";

    // objectivity: load bending mode zeta xi along x, then turn the element a quarter turn about z
    TurnedBox b(Vec3(0.02, 0.05, 0.03), Eigen::Matrix3d::Identity(), 200e9, 0.3);
    b.set_mode(2, 0);
    const QuarterTurn t = load_then_quarter_turn(b.blk, b.nodes, Vec3(0.01, 0.025, 0.015), 500, 1e-8);
    const real_t err = t.error, scale = t.scale, e_hg = t.work;
    EXPECT_LT(err, 1e-6 * scale) << "the frame turns exactly with a rigid rotation";
    EXPECT_LT(std::abs(e_hg), 1e-12) << "a rigid rotation does no hourglass work";
}

namespace
{
/// One cube of edge h with the assumed-strain form (QM 1) through a closed cycle: the nodes move
/// in hourglass mode 1 (eta zeta) along x for n steps, the element is squashed along x to
/// half its length (a linear velocity field, no hourglass rate of its own), the hourglass motion
/// is reversed for n steps, and the element is stretched back. Returns the hourglass work of each
/// leg (Energies' booking: the work of the hourglass forces against the motion). With `forget`
/// the frame sizes the forces were stored at are cleared before every step (the stored forces
/// are then held whatever the stiffness does, the rule before assumed_strain_keep).
std::array<real_t, 4> hourglass_cycle(bool forget)
{
    OneElement e(HourglassType::AssumedStrain, 1.0);
    const real_t dt = 1e-7, amp = 0.2; // 8 x 400 steps x 2e-8 m: the mode's amplitude about 1e-5 h
    const int n = 400;
    std::array<real_t, 4> work{};
    auto step = [&](int leg)
    {
        if (forget)
            for (int i = 0; i < 3; ++i)
                e.blk.hg_force[HexBlock::kHgSizeRow + i] = 0.0;
        for (std::size_t j = 0; j < e.nodes.x.size(); ++j)
            e.nodes.x[j] += dt * e.nodes.v[j];
        work[static_cast<std::size_t>(leg)] += hex_internal_force(e.blk, e.nodes, dt).d_hourglass;
        e.blk.commit();
    };
    auto squash = [&](int leg, real_t to)
    {
        // x = x1 s(t) about x = 0, s linear from 1 to `to`: v_x = x1 ds/dt
        const std::vector<real_t> x1 = e.nodes.x;
        for (int k = 1; k <= n; ++k)
        {
            for (int I = 0; I < 8; ++I)
            {
                const index_t node = e.blk.conn[I];
                e.nodes.v[3 * node] = x1[3 * node] * (to - 1.0) / (n * dt);
                e.nodes.v[3 * node + 1] = e.nodes.v[3 * node + 2] = 0.0;
            }
            step(leg);
        }
    };
    e.set_hourglass_velocity(1, 0, amp);
    for (int k = 0; k < n; ++k)
        step(0);
    squash(1, 0.5);
    e.set_hourglass_velocity(1, 0, -amp);
    for (int k = 0; k < n; ++k)
        step(2);
    squash(3, 2.0);
    return work;
}
} // namespace

TEST(Hourglass, AssumedStrainGivesBackNoMoreThanItStored)
{
    // The stored shear force Q_x1 is a spring of stiffness k ~ H_22 + H_33 = J_1 (J_3 / J_2 +
    // J_2 / J_3): squashing the element to half its length along x halves k (a linear field: no
    // hourglass rate, no work). Loading stores Q0 = k0 d with work W = Q0 d / 2; unloading at the
    // same rate runs Q down by (k0 / 2) d.
    //   held (the forces kept as stored): Q0 -> Q0 / 2, the unloading returns (3/4) Q0 d = 1.5 W
    //     and the cycle ends at -W / 2: the form did work on the element;
    //   kept (assumed_strain_keep: Q0 -> Q0 / sqrt 2 at the squash, the spring's energy Q^2 / 2k
    //     unchanged): the unloading returns (Q0 / sqrt 2 - Q0 / 4) d = (sqrt 2 - 1/2) W and the
    //     cycle ends at (3/2 - sqrt 2) W = 0.0858 W, between 0 and W.
    // The stretch back does no hourglass work either way (to round-off).
    const std::array<real_t, 4> kept = hourglass_cycle(false), held = hourglass_cycle(true);
    const real_t load = kept[0];
    const real_t net_kept = kept[0] + kept[1] + kept[2] + kept[3], net_held = held[0] + held[1] + held[2] + held[3];
    std::printf("hourglass work per leg [J]: kept (load, squash, unload, stretch) %.4e %.4e %.4e %.4e, net %.4e "
                "(%.5f W); held %.4e %.4e %.4e %.4e, net %.4e (%.5f W)\n",
                kept[0], kept[1], kept[2], kept[3], net_kept, net_kept / load, held[0], held[1], held[2], held[3],
                net_held, net_held / load);
    ASSERT_GT(load, 0.0);
    EXPECT_NEAR(held[0], load, 1e-12 * load); // the legs before the squash are the same
    // the mode's amplitude is about 1e-5 h, so the element's shape (and k) moves by that much
    EXPECT_NEAR(net_held / load, -0.5, 1e-4) << "the defect the rule removes";
    EXPECT_NEAR(net_kept / load, 1.5 - std::sqrt(2.0), 1e-4);
    EXPECT_GE(net_kept, 0.0);
    EXPECT_LE(net_kept, load);
}

namespace
{
/// The tip deflection of a cantilever of n x 1 x 1 one-point hexes (length l along x, height t
/// along z, width w) under an end couple M, clamped at x = 0: the linear stiffness from one force
/// pass per degree of freedom (a unit velocity over dt = 1 from rest, geometry fixed), solved by
/// CHOLMOD (operators/linear_static.hpp). Returns the mean |u_z| of the tip nodes.
real_t cantilever_tip(int n, real_t l, real_t t, real_t w, HourglassSpec hg, Formulation f, real_t E, real_t nu,
                      real_t M)
{
    const HexMesh mesh = generate_box(Vec3::Zero(), Vec3(l, w, t), {n, 1, 1});
    NodeSet nodes;
    HexBlock blk = test::make_block(mesh, nodes, f, hg, ElasticParams::from_E_nu(7850, E, nu));
    const int nd = 3 * static_cast<int>(nodes.size());
    std::vector<Eigen::Triplet<real_t>> entries;
    for (int k = 0; k < nd; ++k)
    {
        std::fill(nodes.v.begin(), nodes.v.end(), 0.0);
        nodes.v[static_cast<std::size_t>(k)] = 1.0;
        hex_internal_force(blk, nodes, 1.0); // trial state only: the committed one stays at rest
        std::fill(nodes.f_int.begin(), nodes.f_int.end(), 0.0);
        assemble_block_forces(blk, nodes);
        for (int j = 0; j < nd; ++j)
            if (nodes.f_int[static_cast<std::size_t>(j)] != 0.0)
            {
                // K is symmetric: each column entered as half of itself and half of its transpose
                entries.emplace_back(j, k, 0.5 * nodes.f_int[static_cast<std::size_t>(j)]);
                entries.emplace_back(k, j, 0.5 * nodes.f_int[static_cast<std::size_t>(j)]);
            }
    }
    SparseMatrix K(nd, nd);
    K.setFromTriplets(entries.begin(), entries.end());
    std::vector<real_t> fext(static_cast<std::size_t>(nd), 0.0), fixed_values;
    std::vector<index_t> fixed;
    for (index_t i = 0; i < nodes.size(); ++i)
    {
        const Vec3 x = mesh.node(i);
        if (x[0] > l * (1 - 1e-9)) // the end couple: compression on top
            fext[3 * static_cast<std::size_t>(i)] = (x[2] > 0.5 * t ? -1.0 : 1.0) * M / (2 * t);
        if (x[0] < 1e-9 * l)
            for (int d = 0; d < 3; ++d)
            {
                fixed.push_back(3 * i + d);
                fixed_values.push_back(0.0);
            }
    }
    const std::vector<real_t> u = solve_static(K, fext, fixed, fixed_values);
    real_t tip = 0.0;
    for (index_t i = 0; i < nodes.size(); ++i)
        if (mesh.node(i)[0] > l * (1 - 1e-9))
            tip += std::abs(u[3 * static_cast<std::size_t>(i) + 2]) / 4;
    return tip;
}
} // namespace

TEST(Hourglass, AssumedStrainBendsOneElementThroughTheThicknessExactly)
{
    // Belytschko & Bindeman's point: with one element through the thickness the assumed strain
    // form bends as the beam does. A cantilever under an end couple (pure bending; with nu = 0
    // 3-D elasticity gives Euler-Bernoulli's u_z = M x^2 / (2 E I) with the clamp satisfied
    // exactly): the tip deflection M L^2 / (2 E I) to round-off with 1, 2 and 5 elements along
    // it; with nu = 0.3 the bending modes are plane strain across the width, so E / (1 - nu^2)
    // sets the hourglass part and the tip lies between the two. The controls: full 2x2x2
    // integration (shear locking, far too stiff) and Flanagan-Belytschko's stiffness form at
    // LS-DYNA's QM 0.1, which bends on its hourglass mode alone: a curvature kappa moves that mode
    // by q = 2 kappa l t (+-1 base vector) against k = QM E sum|b_I|^2 / (24 V), where the beam
    // stores E I kappa^2 l / 2; with b_I = (+-t w, +-l w, +-l t) / 4 on an l x t x w box the tip
    // is w^2 t^2 / (QM (t^2 w^2 + l^2 w^2 + l^2 t^2)) of the beam's: 0.050, 0.196 and 1.111 at
    // 1, 2 and 5 elements (its stiffness follows sum |b_I|^2 / V, where bending needs t / l).
    const real_t E = 200e9, l = 0.1, t = 0.01, w = 0.01, M = 100.0;
    const real_t I = w * t * t * t / 12, exact = M * l * l / (2 * E * I);
    for (int n : {1, 2, 5})
    {
        const real_t asqbi =
            cantilever_tip(n, l, t, w, {HourglassType::AssumedStrain, 1.0}, Formulation::Fem1pt, E, 0.0, M);
        const real_t fb = cantilever_tip(n, l, t, w, {HourglassType::Stiffness, 0.1}, Formulation::Fem1pt, E, 0.0, M);
        const real_t full = cantilever_tip(n, l, t, w, {HourglassType::None, 0.0}, Formulation::Fem2x2x2, E, 0.0, M);
        const real_t nu3 =
            cantilever_tip(n, l, t, w, {HourglassType::AssumedStrain, 1.0}, Formulation::Fem1pt, E, 0.3, M);
        std::printf("cantilever, end couple, %d element(s): tip / beam theory: assumed strain %.12f (nu 0.3: %.4f), "
                    "FB stiffness QM 0.1 %.3f, 2x2x2 %.4f\n",
                    n, asqbi / exact, nu3 / exact, fb / exact, full / exact);
        EXPECT_NEAR(asqbi / exact, 1.0, 1e-9) << n;
        EXPECT_GT(nu3 / exact, 1 - 0.3 * 0.3 - 1e-9) << n;
        EXPECT_LT(nu3 / exact, 1 + 1e-9) << n;
        const real_t le = l / n, fb_theory = w * w * t * t / (0.1 * (t * t * w * w + le * le * (w * w + t * t)));
        EXPECT_NEAR(fb / exact, fb_theory, 1e-9 * fb_theory) << n;
        EXPECT_LT(full / exact, 0.5) << n;
    }
}

TEST(Hourglass, AssumedStrainGrowsByTheShareTheMaterialTakesElastically)
{
    // the plastic scaling of the assumed-strain stiffness: of a deviatoric strain increment, the
    // share r the point's own update took elastically. J2 with linear hardening (plastic modulus
    // H) sheared on its yield surface, with spin: r = H / (3 mu + H); an elastic
    // step (below yield): 1; perfectly plastic: 0; no deviatoric strain rate: 1
    const real_t E = 200e9, nu = 0.3, sigy = 300e6, dt = 1e-7;
    const ElasticParams el = ElasticParams::from_E_nu(7850, E, nu);
    const real_t mu = el.mu;
    for (real_t etan : {20e9, 2e9, 0.0})
    {
        const J2Params p = J2Params::bilinear(el, E, sigy, etan);
        const real_t H = E * etan / (E - etan);
        // on the surface in shear along xy, then more shear (d_xy) with a spin about z
        real_t s[6] = {0, 0, 0, sigy / std::sqrt(3.0), 0, 0};
        real_t eps_p = 0.0, failed = 0.0;
        const real_t d[6] = {0, 0, 0, 100.0, 0, 0}, w[3] = {30.0, 0, 0};
        real_t so[6];
        std::copy(s, s + 6, so);
        j2_update(p, d, w, dt, s, eps_p, failed);
        const real_t r = assumed_strain_tangent_share(so, s, d, w, mu, dt);
        std::printf("J2, etan %.0e Pa: share %.12f, H / (3 mu + H) %.12f\n", etan, r, H / (3 * mu + H));
        // the share removes the spin's first-order turn of the old stress; the update's exact
        // (Hughes-Winget) turn differs by (dt w)^2 sigma / (2 mu dt d) = 1e-11 x 115 here
        EXPECT_NEAR(r, H / (3 * mu + H), 1e-8) << etan;
        EXPECT_GT(eps_p, 0.0);
    }
    real_t s[6] = {1e6, 0, 0, 2e6, 0, 0}, so[6];
    std::copy(s, s + 6, so);
    const real_t d[6] = {10.0, -5.0, -5.0, 3.0, 1.0, 0.0}, w[3] = {0.0, 40.0, -7.0};
    real_t eps_p = 0.0, failed = 0.0;
    j2_update(J2Params::bilinear(el, E, sigy, 2e9), d, w, dt, s, eps_p, failed);
    EXPECT_NEAR(assumed_strain_tangent_share(so, s, d, w, mu, dt), 1.0, 1e-6) << "an elastic step";
    const real_t none[6] = {0.1, 0.1, 0.1, 0, 0, 0}; // volumetric only
    EXPECT_EQ(assumed_strain_tangent_share(so, so, none, w, mu, dt), 1.0);
}

TEST(Hourglass, StiffnessFormsStoreNothingWhereThePointFlowsPerfectlyPlastically)
{
    // plastic_scaling in the fast kernel: one J2 element without hardening, sheared onto its
    // yield surface, then a step of shear flow with an hourglass rate on top. Scaled (the
    // default of assumed-strain, an option of stiffness) the stored forces do not grow (the
    // point took none of the deviatoric increment elastically): no hourglass work; unscaled
    // they grow as in an elastic element
    for (HourglassType t : {HourglassType::Stiffness, HourglassType::AssumedStrain})
    {
        real_t unscaled_stored = 0.0, unscaled_work = 0.0;
        for (bool scaled : {false, true})
        {
            const HexMesh mesh = generate_box(Vec3::Zero(), Vec3::Constant(0.01), {1, 1, 1});
            NodeSet nodes;
            HexBlock blk = perfectly_plastic_cube(t, scaled, mesh, nodes);
            // on the surface in shear xz: the element's stress set there, then shear on along xz
            blk.stress[3 * blk.stress_stride] = 0.0;
            blk.stress[5 * blk.stress_stride] = 300e6 / std::sqrt(3.0) * (1 - 1e-9);
            const real_t dt = 1e-8, gamma_rate = 100.0;
            for (index_t i = 0; i < nodes.size(); ++i)
            {
                const Vec3 x = mesh.node(i);
                nodes.v[3 * i] = gamma_rate * x[2]; // v_x = gamma z: d_xz = gamma / 2
                // and hourglass mode zeta xi along y on top
                const Vec3 xi = 2.0 * x / 0.01 - Vec3::Ones();
                nodes.v[3 * i + 1] = 1.0 * xi[2] * xi[0];
            }
            const ForcePassResult r = hex_internal_force(blk, nodes, dt);
            const real_t stored = largest_hourglass_force(blk, blk.hg_force_trial);
            // the point starts 1e-9 below yield: of the step's 77 kPa of elastic shear increment
            // it takes 0.17 Pa elastically, a share of 2e-6
            const char* name = t == HourglassType::Stiffness ? "stiffness" : "assumed-strain";
            if (scaled)
            {
                std::printf("%s: stored force %.3e of the unscaled one, work %.3e\n", name, stored / unscaled_stored,
                            r.d_hourglass / unscaled_work);
                EXPECT_LT(stored, 1e-5 * unscaled_stored) << name;
                EXPECT_LT(r.d_hourglass, 1e-5 * unscaled_work) << name;
            }
            else
            {
                unscaled_stored = stored;
                unscaled_work = r.d_hourglass;
                EXPECT_GT(stored, 0.0) << name;
                EXPECT_GT(r.d_hourglass, 0.0) << name;
            }
        }
    }
}

TEST(Hourglass, StiffnessFormsGiveBackWhatTheyStoredWhereThePointFlows)
{
    // One J2 element without hardening: an hourglass rate (mode zeta xi along y) loads the stored
    // forces for n steps while the point is elastic (no deviatoric strain: the whole increment),
    // then the point is put on its yield surface and sheared (it flows: a share of about 0) while
    // the hourglass rate runs back for n steps. The unloads take the whole increment
    // (scaled_hourglass_update), so the stored forces come back to zero with their displacement
    // and give back what was stored: the cycle's hourglass work is zero to the share's 1e-6. Had
    // the unloads been scaled too, the forces would stay as stored while the displacement went
    // back, and the cycle would end at minus the loading's work.
    for (HourglassType t : {HourglassType::Stiffness, HourglassType::AssumedStrain})
    {
        const HexMesh mesh = generate_box(Vec3::Zero(), Vec3::Constant(0.01), {1, 1, 1});
        NodeSet nodes;
        HexBlock blk = perfectly_plastic_cube(t, true, mesh, nodes);
        const real_t dt = 1e-8, gamma_rate = 100.0;
        const int n = 50;
        auto set_velocity = [&](real_t hourglass, real_t shear)
        {
            for (index_t i = 0; i < nodes.size(); ++i)
            {
                const Vec3 x(nodes.x[3 * i], nodes.x[3 * i + 1], nodes.x[3 * i + 2]);
                const Vec3 xi = 2.0 * mesh.node(i) / 0.01 - Vec3::Ones();
                nodes.v[3 * i] = shear * x[2];
                nodes.v[3 * i + 1] = hourglass * xi[2] * xi[0];
                nodes.v[3 * i + 2] = 0.0;
            }
        };
        auto step = [&]
        {
            for (std::size_t j = 0; j < nodes.x.size(); ++j)
                nodes.x[j] += dt * nodes.v[j];
            const real_t w = hex_internal_force(blk, nodes, dt).d_hourglass;
            blk.commit();
            return w;
        };
        real_t load = 0.0, unload = 0.0;
        set_velocity(1.0, 0.0);
        for (int k = 0; k < n; ++k)
            load += step();
        const real_t stored = largest_hourglass_force(blk, blk.hg_force);
        // onto the yield surface in shear xz, then shear flow with the hourglass rate reversed
        for (int k = 0; k < 6; ++k)
            blk.stress[static_cast<std::size_t>(k) * blk.stress_stride] = 0.0;
        blk.stress[5 * blk.stress_stride] = 300e6 / std::sqrt(3.0) * (1 - 1e-9);
        set_velocity(-1.0, gamma_rate);
        for (int k = 0; k < n; ++k)
            unload += step();
        const real_t left = largest_hourglass_force(blk, blk.hg_force);
        const char* name = t == HourglassType::Stiffness ? "stiffness" : "assumed-strain";
        std::printf("%s: loading work %.4e J, unloading %.4e J, net %.2e of it; stored force %.3e N, left %.2e of it\n",
                    name, load, unload, (load + unload) / load, stored, left / stored);
        ASSERT_GT(load, 0.0) << name;
        EXPECT_LT(std::abs(load + unload), 1e-3 * load) << name;
        EXPECT_LT(left, 1e-3 * stored) << name;
    }
}

TEST(Hourglass, AssumedStrainRestartsFromACheckpointWithoutFrameSizes)
{
    // The assumed-strain form keeps, beside its 12 stored forces per element, the 3 frame sizes
    // they were stored at (HexBlock::hg_rows). A checkpoint written before that holds the forces
    // only: it loads with the sizes at 0, as on a block's first step (assumed_strain_keep then
    // keeps the forces whole), and a checkpoint with the sizes loads them.
    const Deck d = read_deck(std::string(RKFEM_SOURCE_DIR) + "/studies/decks/taylor_bar.yaml",
                             {"parts.bar.hourglass.type=assumed-strain", "time.end=2us"});
    Model m = Model::build(d);
    CentralDifference cd;
    real_t t = 0.0;
    StepReport r = cd.initialize(m, t);
    for (int k = 1; k <= 20; ++k)
    {
        const real_t dt = next_time_step(d.time, t, r.dt_stable);
        r = cd.step(m, t, dt, k);
        t = r.t;
    }
    const HexBlock& b = m.meshes[0];
    const std::size_t rows12 = 12 * static_cast<std::size_t>(b.n_elements());
    ASSERT_EQ(b.hg_force.size(), 15 * static_cast<std::size_t>(b.n_elements()));
    real_t largest = 0.0, smallest_size = kNoLimit;
    for (std::size_t k = 0; k < rows12; ++k)
        largest = std::max(largest, std::abs(b.hg_force[k]));
    for (std::size_t k = rows12; k < b.hg_force.size(); ++k)
        smallest_size = std::min(smallest_size, b.hg_force[k]);
    ASSERT_GT(largest, 0.0) << "20 steps of impact store hourglass forces";
    ASSERT_GT(smallest_size, 0.0) << "and the sizes they were stored at";
    StateArchive full;
    m.save_state(full);
    StateArchive old = full;
    old.put("block.0.hg_force", std::vector<real_t>(b.hg_force.begin(), b.hg_force.begin() + rows12));
    Model from_full = Model::build(d), from_old = Model::build(d);
    from_full.load_state(full);
    from_old.load_state(old);
    EXPECT_EQ(from_full.meshes[0].hg_force, b.hg_force);
    const std::vector<real_t>& h = from_old.meshes[0].hg_force;
    ASSERT_EQ(h.size(), b.hg_force.size());
    EXPECT_TRUE(std::equal(h.begin(), h.begin() + static_cast<std::ptrdiff_t>(rows12), b.hg_force.begin()));
    EXPECT_TRUE(
        std::all_of(h.begin() + static_cast<std::ptrdiff_t>(rows12), h.end(), [](real_t v) { return v == 0.0; }));
}
