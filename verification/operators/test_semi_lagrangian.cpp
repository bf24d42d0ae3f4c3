// Semi-Lagrangian RK particles (operators/semi_lagrangian_block.hpp): SNNI's linear
// reproduction and integration constraint, the face-gradient stabilization of SNNI's zero-energy
// sawtooth, the uniaxial-strain wave plateau, a spinning block's momenta, thread-count
// independence and the deck's checks.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <map>
#include <random>

#include "../support.hpp"
#include "rkfem/operators/nodal_step_estimate.hpp"
#include "rkfem/operators/semi_lagrangian_block.hpp"
#include "rkfem/run/simulation.hpp"

using namespace rkfem;

namespace
{
/// A free steel block of particles, 1 mm apart, semi-Lagrangian.
const char* block_deck = R"(
title: semi-Lagrangian block
time: {end: 1 us}
parts:
  block:
    generator: {type: box, size: [8 mm, 8 mm, 8 mm], element_size: 1 mm}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: rkpm
    kinematics: semi-lagrangian
    bulk_viscosity: {linear: 0, quadratic: 0}
)";

/// The largest sum_L V_L b_J(x_L) (ic, 3 per particle) at the particles whose supports stay clear
/// of the block's surface (2 spacings in), relative to a gradient's size times a cell's volume, h^2.
real_t interior_constraint(const Model& m, const std::vector<real_t>& ic, real_t h)
{
    real_t worst = 0.0;
    for (index_t i = 0; i < m.nodes.size(); ++i)
    {
        bool deep = true;
        for (int d = 0; d < 3; ++d)
            deep = deep && m.nodes.x0[3 * i + d] > 2.9e-3 && m.nodes.x0[3 * i + d] < 5.1e-3;
        if (deep)
            for (int d = 0; d < 3; ++d)
                worst = std::max(worst, std::abs(ic[3 * static_cast<std::size_t>(i) + d]) / (h * h));
    }
    return worst;
}

/// Positions moved by a jitter of up to `jitter` spacings per axis (interior particles only).
void jitter_positions(Model& m, real_t h, real_t jitter, real_t lo, real_t hi)
{
    std::mt19937 gen(11);
    std::uniform_real_distribution<real_t> u(-jitter * h, jitter * h);
    for (index_t i = 0; i < m.nodes.size(); ++i)
    {
        bool interior = true;
        for (int d = 0; d < 3; ++d)
            interior = interior && m.nodes.x0[3 * i + d] > lo + 1e-9 && m.nodes.x0[3 * i + d] < hi - 1e-9;
        for (int d = 0; d < 3; ++d)
            m.nodes.x[3 * i + d] = m.nodes.x0[3 * i + d] + (interior ? u(gen) : 0.0);
    }
}

/// The sawtooth v_x = (-1)^(i + j + k) on the lattice of spacing h (a zero-energy mode of plain SNNI).
void sawtooth_velocity(Model& m, real_t h)
{
    for (index_t i = 0; i < m.nodes.size(); ++i)
    {
        int parity = 0;
        for (int d = 0; d < 3; ++d)
            parity += static_cast<int>(std::lround(m.nodes.x0[3 * i + d] / h));
        m.nodes.v[3 * i] = parity % 2 ? 1.0 : -1.0;
    }
}
} // namespace

// SNNI's smoothed gradient reproduces linear fields exactly (sum_J x_J (x) b_J = 1, sum_J b_J =
// 0) at every particle, regular or jittered, interior or on the surface. The integration
// constraint sum_L V_L b_J(x_L) = (boundary term) holds on a lattice, whose cubes tile space, and
// fails on a jittered cloud, whose cubes overlap and leave gaps: what SNNI loses.
TEST(SemiLagrangian, SnniReproducesLinearFieldsAndLosesTheIntegrationConstraintOffALattice)
{
    for (real_t jitter : {0.0, 0.2})
    {
        Model m = test::model_from(block_deck);
        SemiLagrangianForceBlock& b = test::sl_block(m);
        const real_t h = 1e-3;
        jitter_positions(m, h, jitter, 0.0, 8e-3);
        const index_t np = b.n_particles();
        std::vector<real_t> ic(3 * static_cast<std::size_t>(np), 0.0);
        real_t worst_linear = 0.0;
        std::vector<index_t> nodes;
        std::vector<real_t> grad;
        for (index_t p = 0; p < np; ++p)
        {
            ASSERT_TRUE(b.smoothed_gradient(p, m.nodes.x, nodes, grad)) << "particle " << p;
            Mat3 xg = Mat3::Zero();
            Vec3 sum = Vec3::Zero();
            for (std::size_t k = 0; k < nodes.size(); ++k)
            {
                const Vec3 g(grad[3 * k], grad[3 * k + 1], grad[3 * k + 2]);
                const std::size_t n = static_cast<std::size_t>(nodes[k]);
                xg += Vec3(m.nodes.x[3 * n], m.nodes.x[3 * n + 1], m.nodes.x[3 * n + 2]) * g.transpose();
                sum += g;
                for (int d = 0; d < 3; ++d)
                    ic[3 * n + d] += b.volume(p) * g[d];
            }
            worst_linear = std::max(worst_linear, (xg - Mat3::Identity()).cwiseAbs().maxCoeff());
            worst_linear = std::max(worst_linear, h * sum.cwiseAbs().maxCoeff());
        }
        EXPECT_LT(worst_linear, 1e-11) << "jitter " << jitter;
        const real_t worst_ic = interior_constraint(m, ic, h);
        std::printf("jitter %.1f: linear reproduction %.2e, integration constraint at interior particles %.2e h^2\n",
                    jitter, worst_linear, worst_ic);
        if (jitter == 0.0)
            EXPECT_LT(worst_ic, 1e-12);
        else
            EXPECT_GT(worst_ic, 1e-3); // overlapping cubes: SNNI loses the constraint
    }
}

// SD-SNNI (SemiLagrangianForceBlock::snni_operators with the sub-cells): each of a cell's eight
// sub-cells is an SNNI cell of its own, so its gradient b^s_J (the points' row plus the sub-cell's)
// reproduces linear fields at every particle; the sub-cells' rows average to the points' row
// (sum_s V_s (b^s_J - b_J) = 0, which makes c_s = 1 SD-SNNI's stiffness exactly); the integration
// constraint holds on the lattice and is lost on the jittered cloud, as SNNI's is (the cells are
// the same). A sawtooth velocity, which plain SNNI misses, has sub-cell strain rates of 1 / h.
TEST(SemiLagrangian, SdSnniSubCellsReproduceLinearFieldsAndSeeTheSawtooth)
{
    for (real_t jitter : {0.0, 0.2})
    {
        Model m = test::model_from(block_deck);
        SemiLagrangianForceBlock& b = test::sl_block(m);
        const real_t h = 1e-3;
        jitter_positions(m, h, jitter, 0.0, 8e-3);
        IntegrationOperator pts, sub;
        ASSERT_TRUE(b.snni_operators(m.nodes.x, SemiLagrangianForceBlock::SubPoints::SubCells, pts, sub));
        const index_t np = b.n_particles();
        ASSERT_EQ(pts.n_points(), np);
        ASSERT_EQ(sub.n_points(), 8 * np);
        auto row = [&](const IntegrationOperator& op, index_t q, std::map<index_t, Vec3>& out)
        {
            for (index_t k = op.offsets[q]; k < op.offsets[q + 1]; ++k)
                out.try_emplace(op.nodes[k], Vec3::Zero()).first->second += op.gradient(k);
        };
        auto position = [&](index_t j) { return Vec3(m.nodes.x[3 * j], m.nodes.x[3 * j + 1], m.nodes.x[3 * j + 2]); };
        real_t worst_linear = 0.0, worst_mean = 0.0, least_sawtooth = kNoLimit;
        std::vector<real_t> ic(3 * static_cast<std::size_t>(np), 0.0);
        for (index_t p = 0; p < np; ++p)
        {
            std::map<index_t, Vec3> main, mean;
            row(pts, p, main);
            for (const auto& [j, g] : main)
                for (int d = 0; d < 3; ++d)
                    ic[3 * static_cast<std::size_t>(j) + d] += pts.weight[p] * g[d];
            real_t largest = 0.0;
            for (index_t s = 0; s < 8; ++s)
            {
                ASSERT_EQ(sub.parent[8 * p + s], p);
                EXPECT_NEAR(sub.weight[8 * p + s], pts.weight[p] / 8.0, 1e-15 * pts.weight[p]);
                std::map<index_t, Vec3> bs = main, g;
                row(sub, 8 * p + s, g);
                Mat3 xg = Mat3::Zero(), saw = Mat3::Zero();
                Vec3 sum = Vec3::Zero();
                for (const auto& [j, gj] : g)
                {
                    bs.try_emplace(j, Vec3::Zero()).first->second += gj;
                    mean.try_emplace(j, Vec3::Zero()).first->second += gj / 8.0;
                }
                for (const auto& [j, bj] : bs)
                {
                    xg += position(j) * bj.transpose();
                    sum += bj;
                    int parity = 0;
                    for (int d = 0; d < 3; ++d)
                        parity += static_cast<int>(std::lround(m.nodes.x0[3 * j + d] / h));
                    saw += Vec3(parity % 2 ? 1.0 : -1.0, 0.0, 0.0) * bj.transpose();
                }
                worst_linear = std::max(
                    {worst_linear, (xg - Mat3::Identity()).cwiseAbs().maxCoeff(), h * sum.cwiseAbs().maxCoeff()});
                largest = std::max(largest, h * (0.5 * (saw + saw.transpose())).cwiseAbs().maxCoeff());
            }
            for (const auto& [j, g] : mean)
                worst_mean = std::max(worst_mean, h * g.cwiseAbs().maxCoeff());
            bool interior = true;
            for (int d = 0; d < 3; ++d)
                interior = interior && m.nodes.x0[3 * p + d] > 1.9e-3 && m.nodes.x0[3 * p + d] < 6.1e-3;
            if (interior)
                least_sawtooth = std::min(least_sawtooth, largest);
        }
        const real_t worst_ic = interior_constraint(m, ic, h);
        std::printf("SD-SNNI, jitter %.1f: sub-cells' linear reproduction %.2e, their mean's departure from the "
                    "points' row %.2e / h, integration constraint at interior particles %.2e h^2, sawtooth |D_s| h "
                    "at least %.3f\n",
                    jitter, worst_linear, worst_mean, worst_ic, least_sawtooth);
        EXPECT_LT(worst_linear, 1e-11) << "jitter " << jitter;
        EXPECT_LT(worst_mean, 1e-12) << "jitter " << jitter;
        if (jitter == 0.0)
        {
            EXPECT_LT(worst_ic, 1e-12);
            EXPECT_GT(least_sawtooth, 0.1); // the sub-cells see the sawtooth that SNNI's face centres miss
        }
        else
            EXPECT_GT(worst_ic, 1e-3);
    }
}

// A sawtooth velocity (v_x = (-1)^(i+j+k) on the lattice) vanishes at every face centre of an
// interior particle, so plain SNNI sees no strain rate there (a zero-energy mode: |L| at round-off
// of 1 / h); the face-gradient term's strain rates sym(sum_J v_J (x) (grad Psi_J(x_f) - b_J))
// are of the size of 1 / h, so the stabilization takes work from it.
TEST(SemiLagrangian, FaceGradientStabilizationSeesTheSawtoothThatSnniMisses)
{
    Model m = test::model_from(block_deck);
    const real_t h = 1e-3;
    sawtooth_velocity(m, h);
    SemiLagrangianForceBlock& b = test::sl_block(m);
    real_t worst_snni = 0.0, least_face = kNoLimit;
    std::vector<index_t> nodes;
    std::vector<real_t> grad, faces;
    int deep = 0;
    for (index_t p = 0; p < b.n_particles(); ++p)
    {
        bool interior = true;
        for (int d = 0; d < 3; ++d)
            interior = interior && m.nodes.x0[3 * p + d] > 1.9e-3 && m.nodes.x0[3 * p + d] < 6.1e-3;
        if (!interior)
            continue;
        ++deep;
        ASSERT_TRUE(b.smoothed_gradient(p, m.nodes.x, nodes, grad, &faces));
        Mat3 L = Mat3::Zero(), Lf[6];
        for (auto& l : Lf)
            l.setZero();
        for (std::size_t k = 0; k < nodes.size(); ++k)
        {
            const Vec3 v(m.nodes.v[3 * nodes[k]], m.nodes.v[3 * nodes[k] + 1], m.nodes.v[3 * nodes[k] + 2]);
            const Vec3 g(grad[3 * k], grad[3 * k + 1], grad[3 * k + 2]);
            L += v * g.transpose();
            for (int f = 0; f < 6; ++f)
                Lf[f] +=
                    v *
                    (Vec3(faces[18 * k + 3 * f], faces[18 * k + 3 * f + 1], faces[18 * k + 3 * f + 2]) - g).transpose();
        }
        worst_snni = std::max(worst_snni, h * L.cwiseAbs().maxCoeff());
        real_t largest = 0.0;
        for (const Mat3& l : Lf)
            largest = std::max(largest, h * (0.5 * (l + l.transpose())).cwiseAbs().maxCoeff());
        least_face = std::min(least_face, largest);
    }
    std::printf("sawtooth at %d interior particles: SNNI |L| h at most %.2e, the face terms' |D_f| h at least %.3f\n",
                deep, worst_snni, least_face);
    EXPECT_EQ(deep, 125);
    EXPECT_LT(worst_snni, 1e-11);
    EXPECT_GT(least_face, 0.1);
}

// The uniaxial-strain wave: rho 7850, E 200 GPa, nu 0.3, c_p 5856.4 m/s, end driven at 10 m/s:
// plateau sigma_zz = -rho c_p v = -459.7 MPa behind the front, lateral lambda / (lambda + 2 mu)
// of it.
namespace
{
void check_wave(const std::vector<std::string>& overrides)
{
    Model m = test::model_from(R"(
title: semi-Lagrangian column wave
time: {end: 14 us, dt_scale: 0.9}
parts:
  column:
    generator: {type: box, size: [3 mm, 3 mm, 100 mm], element_size: 1 mm}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: rkpm
    kinematics: semi-lagrangian
    bulk_viscosity: {linear: 0.06, quadratic: 1.5}
node_sets:
  all: {select: {type: named, name: all}}
  end: {select: {type: named, name: bottom}}
boundary_conditions:
  - {node_set: all, fixed: [x, y]}
  - {node_set: end, velocity: {z: 10 m/s}}
)",
                               overrides);
    const real_t c = 5856.4, plateau = -7850 * c * 10.0;
    const test::RunWithBalance r = test::run_with_balance(m, 3e-6);
    ASSERT_EQ(r.summary.status, "completed") << r.summary.message;
    // each 10 mm slab's mean behind the front (10 to 60 mm; the front is at 82 mm), as the
    // Lagrangian cloud's test measures it: single particles ring about it by up to 5 % (the
    // Lagrangian RK column of this deck by up to 6 %)
    const ElasticParams mat = m.nodal_block(0)->material;
    const real_t ratio = mat.lambda / mat.plane_wave_modulus();
    real_t worst = 0.0, worst_lateral = 0.0, worst_particle = 0.0;
    for (int slab = 1; slab < 6; ++slab)
    {
        real_t zz = 0.0, xx = 0.0;
        int n = 0;
        for (index_t i = 0; i < m.nodes.size(); ++i)
        {
            const real_t z = m.nodes.x0[3 * i + 2];
            if (z < slab * 10e-3 - 1e-9 || z > slab * 10e-3 + 9.5e-3)
                continue;
            const Sym6 st = m.nodal_stress(i);
            zz += st[ZZ], xx += st[XX], ++n;
            worst_particle = std::max(worst_particle, std::abs(st[ZZ] / plateau - 1));
        }
        worst = std::max(worst, std::abs(zz / n / plateau - 1));
        worst_lateral = std::max(worst_lateral, std::abs(xx / n / (ratio * plateau) - 1));
    }
    std::printf("semi-Lagrangian wave: 10 mm slabs' plateau within %.2e, lateral within %.2e (single particles "
                "within %.2e), balance error %.2e, %d rebuilds\n",
                worst, worst_lateral, worst_particle, r.balance, test::sl_block(m).rebuilds());
    EXPECT_LT(worst, 0.02);
    EXPECT_LT(worst_lateral, 0.02);
    EXPECT_LT(r.balance, 0.01);
}
} // namespace

TEST(SemiLagrangian, UniaxialStrainWavePlateauMatchesTheory)
{
    check_wave({});
}

// Lagrangian RK integrated by SNNI (kinematics: lagrangian, scheme snni: the tables of the
// start, never reset): the same plateau
TEST(SemiLagrangian, LagrangianSnniGivesTheSameWavePlateau)
{
    check_wave({"parts.column.kinematics=lagrangian", "parts.column.nodal_integration={scheme: snni}"});
}

// Lagrangian RK reset to the current configuration every 10 steps: the same plateau
TEST(SemiLagrangian, ReferenceResetsGiveTheSameWavePlateau)
{
    check_wave({"parts.column.semi_lagrangian={reset_interval: 10}"});
}

// A free block spinning at omega = 2.5e4 1/s (its corners at 141 m/s) through a quarter turn:
// no force from outside, so the momenta of the unknowns stay as they were, linear to 1e-10 of
// sum m |v| and angular (sum m (x - c) x v about a fixed point c) to 1e-10 of sum m |x - c| |v|; the
// stress stays of the size of the rotation's centripetal load, rho omega^2 R^2 (R the half-width),
// where a rate without objectivity would build stresses of E times the rotation.
namespace
{
void check_spin(std::vector<std::string> overrides, real_t angular_tolerance)
{
    const real_t omega = 2.5e4, R = 4e-3, t_end = 0.5 * M_PI / omega;
    overrides.push_back("time.end=" + std::to_string(t_end * 1e6) + " us");
    Model m = test::model_from(block_deck, overrides);
    const Vec3 centre(4e-3, 4e-3, 4e-3), vt(3.0, -2.0, 1.0);
    auto angular = [&](const NodeSet& n, real_t& scale)
    {
        Vec3 L = Vec3::Zero();
        scale = 0.0;
        for (index_t i = 0; i < n.size(); ++i)
        {
            const Vec3 r = Vec3(n.x[3 * i], n.x[3 * i + 1], n.x[3 * i + 2]) - centre;
            const Vec3 v(n.v[3 * i], n.v[3 * i + 1], n.v[3 * i + 2]);
            L += n.mass[i] * r.cross(v);
            scale += n.mass[i] * r.norm() * v.norm();
        }
        return L;
    };
    for (index_t i = 0; i < m.nodes.size(); ++i)
    {
        const Vec3 r = Vec3(m.nodes.x0[3 * i], m.nodes.x0[3 * i + 1], m.nodes.x0[3 * i + 2]) - centre;
        const Vec3 v = vt + Vec3(0, 0, omega).cross(r);
        for (int d = 0; d < 3; ++d)
            m.nodes.v[3 * i + d] = v[d];
    }
    const Vec3 p0 = test::momentum(m.nodes);
    const real_t pscale = test::momentum_scale(m.nodes);
    real_t lscale = 0.0;
    const Vec3 L0 = angular(m.nodes, lscale);
    real_t worst_p = 0.0, worst_L = 0.0, worst_stress = 0.0;
    RunOptions opt;
    opt.progress = false;
    const RunSummary s = run_simulation(m, opt,
                                        [&](const Model& mm, real_t, real_t, std::int64_t)
                                        {
                                            real_t unused = 0.0;
                                            worst_p = std::max(worst_p, (test::momentum(mm.nodes) - p0).norm());
                                            worst_L = std::max(worst_L, (angular(mm.nodes, unused) - L0).norm());
                                            for (index_t i = 0; i < mm.nodes.size(); ++i)
                                                worst_stress =
                                                    std::max(worst_stress, mm.nodal_stress(i).cwiseAbs().maxCoeff());
                                        });
    ASSERT_EQ(s.status, "completed") << s.message;
    const real_t centripetal = 7850 * omega * omega * R * R;
    std::printf("spinning block, %d steps: linear momentum %.2e, angular %.2e (relative), largest stress %.3e Pa "
                "(rho omega^2 R^2 = %.3e Pa), %d rebuilds\n",
                static_cast<int>(s.steps), worst_p / pscale, worst_L / lscale, worst_stress, centripetal,
                test::sl_block(m).rebuilds());
    EXPECT_LT(worst_p / pscale, 1e-10);
    EXPECT_LT(worst_L / lscale, angular_tolerance);
    EXPECT_LT(worst_stress, 10.0 * centripetal);
}
} // namespace

TEST(SemiLagrangian, SpinningBlockKeepsItsMomentaAndBuildsNoSpuriousStress)
{
    check_spin({}, 1e-10);
}

// With reference resets every 10 steps the nodal blocks' pass runs between them (F on the
// tables of the last reset): linear momentum as exactly, no stress beyond the centripetal load's.
// Angular momentum is not exact there: the stabilization's forces V0 J sigma_f F^-T g_f use the
// particle's F, and sum_J g_fJ (x) x_J = (F_f - F)^T, the face's deformation since the reset
// against the particle's, so their torque is of the size of sigma_f (F_f - F) (the Lagrangian
// blocks' MSCNI has the same term); at most 1e-6 of sum m |x - c| |v| here (2.8e-8 measured)
TEST(SemiLagrangian, SpinningBlockWithReferenceResetsKeepsItsMomenta)
{
    check_spin({"parts.block.semi_lagrangian={reset_interval: 10}"}, 1e-6);
}

// Forces are summed per particle over its neighbour list in a fixed order: one thread or two,
// the same bits.
TEST(SemiLagrangian, ResultsDoNotDependOnThreadCount)
{
    auto run = [](int threads)
    {
        return test::displacements_on_threads(block_deck, {"time.end=3 us"}, threads,
                                              [](Model& m) { test::deforming_column_velocity(m.nodes); });
    };
    const auto u1 = run(1), u2 = run(2);
    ASSERT_EQ(u1.size(), u2.size());
    for (std::size_t i = 0; i < u1.size(); ++i)
        ASSERT_EQ(u1[i], u2[i]) << "dof " << i;
}

// The chunked scatter (chunks of particles in order, each adding into a buffer of its own, summed
// in chunk order) against the per-pair gather (each particle sums its row's pair forces): one
// pass on the struck block with a deforming velocity field, the same forces to round-off
TEST(SemiLagrangian, ChunkedScatterAssemblesTheForcesOfTheGather)
{
    auto forces = [](Assembly a)
    {
        Model m = test::model_from(block_deck, {"parts.block.generator.element_size=0.5mm"});
        test::deforming_column_velocity(m.nodes);
        SemiLagrangianForceBlock& b = test::sl_block(m);
        b.set_assembly(a);
        b.add_forces(m.nodes, 1e-8, false);
        EXPECT_EQ(b.scatters(), a == Assembly::Scatter);
        return m.nodes.f_int;
    };
    const std::vector<real_t> s = forces(Assembly::Scatter), g = forces(Assembly::Gather);
    real_t fmax = 0.0, df = 0.0;
    for (std::size_t i = 0; i < s.size(); ++i)
    {
        fmax = std::max(fmax, std::abs(g[i]));
        df = std::max(df, std::abs(s[i] - g[i]));
    }
    std::printf("chunked scatter against the gather: forces within %.2e of the largest\n", df / fmax);
    EXPECT_GT(fmax, 0.0);
    EXPECT_LT(df / fmax, 1e-13);
}

// The fast pass (each face centre's covering particles listed once, their RK functions on flat
// arrays, L from the face velocities, each particle's force summed over the faces) against the
// plain one (the algebra as written, over each particle's whole row). A K&C block struck at
// 30 m/s is run 44 steps by the fast pass (crushed, damaged, its cells sheared); then one pass
// of each on that state gives the same forces to round-off. Compared over the run instead, the
// softening material amplifies the passes' round-off differences unevenly (at c_s 1: stresses
// within 8e-11 of their largest after 10 steps, then anywhere from 3e-9 to 3e-5 by 19-44 steps
// as the summation order changes), so the runs' trajectories are held over the first 10 steps
// only. The face terms are checked at c_s 1, the default, where they weigh most.
TEST(SemiLagrangian, FastPassMatchesThePlainOne)
{
    const char* deck = R"(
title: struck K&C block
time: {end: 10 us}
parts:
  block:
    generator: {type: box, size: [6 mm, 6 mm, 12 mm], element_size: 1 mm}
    material: {model: kcc, rho: 2400 kg/m^3, fc: 45.6 MPa}
    formulation: rkpm
    kinematics: semi-lagrangian
    nodal_integration: {scheme: snni, stabilization_coefficient: 1}
node_sets:
  struck: {select: {type: named, name: bottom}}
boundary_conditions:
  - {node_set: struck, velocity: {z: 30 m/s}}
)";
    auto model = [&](const char* end, bool plain)
    {
        Model m = test::model_from(deck, {std::string("time.end=") + end});
        test::sl_block(m).set_plain(plain);
        // the passes' algebra compared, not the assembly's order of sums (the softening material
        // amplifies that too; ChunkedScatterAssemblesTheForcesOfTheGather holds the scatter)
        test::sl_block(m).set_assembly(Assembly::Gather);
        return m;
    };
    auto largest_difference = [](const std::vector<real_t>& a, const std::vector<real_t>& b)
    {
        real_t big = 0.0, d = 0.0;
        for (std::size_t i = 0; i < a.size(); ++i)
        {
            big = std::max(big, std::abs(b[i]));
            d = std::max(d, std::abs(a[i] - b[i]));
        }
        return d / big;
    };
    RunOptions opt;
    opt.progress = false;
    // the first 10 steps' trajectories
    auto run = [&](bool plain)
    {
        Model m = model("2.3 us", plain);
        const RunSummary s = run_simulation(m, opt);
        EXPECT_EQ(s.status, "completed") << s.message;
        std::vector<real_t> stress;
        for (index_t i = 0; i < m.nodes.size(); ++i)
        {
            const Sym6 st = m.nodal_stress(i);
            stress.insert(stress.end(), st.data(), st.data() + 6);
        }
        return std::tuple{m.nodes.u, stress, s.steps};
    };
    const auto [u_fast, s_fast, steps_fast] = run(false);
    const auto [u_plain, s_plain, steps_plain] = run(true);
    ASSERT_EQ(steps_fast, steps_plain);
    const real_t du = largest_difference(u_fast, u_plain), ds = largest_difference(s_fast, s_plain);
    // one pass of each on the state 44 steps in
    Model m = model("10 us", false);
    const RunSummary s = run_simulation(m, opt);
    ASSERT_EQ(s.status, "completed") << s.message;
    SemiLagrangianForceBlock& b = test::sl_block(m);
    b.add_forces(m.nodes, 1e-8, false);
    const std::vector<real_t> f_fast = m.nodes.f_int;
    b.set_plain(true);
    b.add_forces(m.nodes, 1e-8, false);
    const real_t df = largest_difference(f_fast, m.nodes.f_int);
    std::printf("fast against plain pass: %d steps' displacements within %.2e and stresses within %.2e of their "
                "largest; one pass after %d steps (%zu of %zu particles separated): forces within %.2e\n",
                static_cast<int>(steps_fast), du, ds, static_cast<int>(s.steps),
                static_cast<std::size_t>(b.free_particles()), static_cast<std::size_t>(b.n_particles()), df);
    EXPECT_GE(steps_fast, 10);
    EXPECT_LT(du, 1e-10);
    EXPECT_LT(ds, 1e-9);
    EXPECT_LT(df, 1e-11);
}

TEST(SemiLagrangian, DeckErrorsNameTheKey)
{
    auto error_of = [](const std::vector<std::string>& overrides) { return test::model_error(block_deck, overrides); };
    EXPECT_NE(error_of({"parts.block.formulation=fem-1pt"}).find("parts.block.kinematics"), std::string::npos);
    EXPECT_NE(error_of({"parts.block.nodal_integration={scheme: scni}"}).find("expected scheme: snni"),
              std::string::npos);
    EXPECT_NE(error_of({"parts.block.nodal_integration={stabilization: nsni}"}).find("face-gradient"),
              std::string::npos);
    EXPECT_NE(error_of({"parts.block.kinematics=lagrangian", "parts.block.semi_lagrangian={neighbour_skin: 0.2}"})
                  .find("parts.block.semi_lagrangian"),
              std::string::npos);
    EXPECT_NE(error_of({"parts.block.semi_lagrangian={neighbour_skin: -1}"}).find("neighbour_skin"), std::string::npos);
    EXPECT_NE(error_of({"parts.block.formulation=fem-nodal", "parts.block.kinematics=lagrangian",
                        "parts.block.nodal_integration={scheme: snni}"})
                  .find("expected scheme: scni, sd-scni or dni on a fem-nodal part"),
              std::string::npos);
    EXPECT_NE(error_of({"parts.block.semi_lagrangian={reset_interval: 2.5}"}).find("reset_interval"),
              std::string::npos);
    EXPECT_NE(error_of({"parts.block.semi_lagrangian={reset_interval: 5, plastic_scaling: true}"})
                  .find("expected reset_interval: 1 with plastic_scaling: true"),
              std::string::npos);
    EXPECT_NE(error_of({"parts.block.semi_lagrangian={reset_interval: 5, separation_damage: 0.99}"})
                  .find("expected reset_interval: 1 with separation_damage"),
              std::string::npos);
    // SD-SNNI: stabilized by its sub-cells; rkpm parts only
    EXPECT_NE(error_of({"parts.block.nodal_integration={scheme: sd-snni, stabilization: face-gradient}"})
                  .find("expected stabilization: sub-cells or none"),
              std::string::npos);
    EXPECT_NE(error_of({"parts.block.nodal_integration={scheme: snni, stabilization: sub-cells}"})
                  .find("expected stabilization: face-gradient or none"),
              std::string::npos);
    EXPECT_NE(error_of({"parts.block.formulation=fem-nodal", "parts.block.kinematics=lagrangian",
                        "parts.block.nodal_integration={scheme: sd-snni}"})
                  .find("expected scheme: scni, sd-scni or dni on a fem-nodal part"),
              std::string::npos);
}

// Dynamic SD-SNNI (scheme sd-snni): each cell's eight sub-cells, 36 face-centre points per cell.
// One pass under a linear velocity field A x: every particle's stress is the uniform one to
// round-off (each sub-cell's gradient reproduces A on any parallelepiped), the sub-cells'
// stabilization stresses stay at round-off (L_s = L), and interior particles carry no force
// (the box mesh's cells tile the block at the start, so the integration constraint holds there).
TEST(SemiLagrangian, SdSnniKeepsALinearFieldsStressUniformWithNoInteriorForce)
{
    Model m = test::model_from(block_deck, {"parts.block.nodal_integration={scheme: sd-snni}"});
    const real_t A[3][3] = {{1.0, 0.3, -0.2}, {0.1, -0.5, 0.4}, {0.25, 0.2, 0.7}}; // 1/s
    for (index_t i = 0; i < m.nodes.size(); ++i)
        for (int d = 0; d < 3; ++d)
            m.nodes.v[3 * i + d] =
                A[d][0] * m.nodes.x0[3 * i] + A[d][1] * m.nodes.x0[3 * i + 1] + A[d][2] * m.nodes.x0[3 * i + 2];
    SemiLagrangianForceBlock& b = test::sl_block(m);
    const ForcePassResult r = b.add_forces(m.nodes, 1e-8, false);
    ASSERT_LT(r.bad_element, 0);
    const NodalBlock& nb = *b.nodal_points();
    const std::size_t n = static_cast<std::size_t>(b.n_particles()), ns = 8 * n;
    ASSERT_EQ(nb.stab_stress_trial.size(), 6 * ns);
    real_t smax = 0.0, ds = 0.0, sub = 0.0, fmax = 0.0, interior = 0.0;
    for (int k = 0; k < 6; ++k)
        for (std::size_t p = 0; p < n; ++p)
        {
            const real_t s0 = nb.stress_trial[k * nb.stress_stride], sp = nb.stress_trial[k * nb.stress_stride + p];
            smax = std::max(smax, std::abs(s0));
            ds = std::max(ds, std::abs(sp - s0));
            for (std::size_t q = 0; q < 8; ++q)
                sub = std::max(sub, std::abs(nb.stab_stress_trial[k * ns + 8 * p + q]));
        }
    int deep = 0;
    for (index_t i = 0; i < m.nodes.size(); ++i)
    {
        bool inside = true;
        for (int d = 0; d < 3; ++d)
        {
            fmax = std::max(fmax, std::abs(m.nodes.f_int[3 * i + d]));
            inside = inside && m.nodes.x0[3 * i + d] > 1.9e-3 && m.nodes.x0[3 * i + d] < 6.1e-3;
        }
        if (!inside)
            continue;
        ++deep;
        for (int d = 0; d < 3; ++d)
            interior = std::max(interior, std::abs(m.nodes.f_int[3 * i + d]));
    }
    std::printf("SD-SNNI under a linear field: stress off the uniform %.2e of it, sub-cell stresses %.2e of it, "
                "forces on %d interior particles %.2e of the largest\n",
                ds / smax, sub / smax, deep, interior / fmax);
    EXPECT_EQ(deep, 125);
    EXPECT_LT(ds / smax, 1e-10);
    EXPECT_LT(sub / smax, 1e-10);
    EXPECT_LT(interior / fmax, 1e-10);
}

// The sawtooth of FaceGradientStabilizationSeesTheSawtoothThatSnniMisses under SD-SNNI: the
// sub-cells' departures from the particle's gradient are of the size of 1 / h, so their
// stabilization stresses, dt c_s C : sym(L_s - L), are of the size of E dt / h at every interior
// particle; with stabilization none they stay zero.
TEST(SemiLagrangian, SdSnniSubCellsSeeTheSawtooth)
{
    const real_t h = 1e-3, dt = 1e-9, E = 200e9;
    for (const char* stab : {"sub-cells", "none"})
    {
        Model m = test::model_from(block_deck, {std::string("parts.block.nodal_integration={scheme: sd-snni, "
                                                            "stabilization: ") +
                                                stab + "}"});
        sawtooth_velocity(m, h);
        SemiLagrangianForceBlock& b = test::sl_block(m);
        const ForcePassResult r = b.add_forces(m.nodes, dt, false);
        ASSERT_LT(r.bad_element, 0);
        const NodalBlock& nb = *b.nodal_points();
        const std::size_t n = static_cast<std::size_t>(b.n_particles()), ns = 8 * n;
        real_t least = kNoLimit, largest = 0.0;
        int deep = 0;
        for (std::size_t p = 0; p < n; ++p)
        {
            bool interior = true;
            for (int d = 0; d < 3; ++d)
                interior = interior && m.nodes.x0[3 * p + d] > 1.9e-3 && m.nodes.x0[3 * p + d] < 6.1e-3;
            if (!interior)
                continue;
            ++deep;
            real_t s = 0.0;
            for (int k = 0; k < 6; ++k)
                for (std::size_t q = 0; q < 8; ++q)
                    s = std::max(s, std::abs(nb.stab_stress_trial[k * ns + 8 * p + q]));
            least = std::min(least, s / (E * dt / h));
            largest = std::max(largest, s / (E * dt / h));
        }
        std::printf("sawtooth, stabilization %s: sub-cell stresses at %d interior particles from %.3f to %.3f of E dt "
                    "/ h, stabilization work %.3e J\n",
                    stab, deep, least, largest, r.d_hourglass);
        EXPECT_EQ(deep, 125);
        if (std::string(stab) == "none")
            EXPECT_EQ(largest, 0.0);
        else
        {
            EXPECT_GT(least, 0.05);
            EXPECT_GT(r.d_hourglass, 0.0);
        }
    }
}

// The dynamic pass is SD-SNNI's stiffness: from zero stress, one pass with velocities v over a
// small dt gives the forces K (v dt), K = sum_p V_p B_p^T C B_p over the static SubCells tables'
// points (rows b_J) and sub-cells (V / 8, rows b^s_J - b_J; c_s = 1), to the pass's geometric
// terms, of the order of dt |L| (1e-8 here). On a jittered cloud (cells that no longer tile).
TEST(SemiLagrangian, SdSnniPassIsTheStiffnessOfTheStaticSubCellTables)
{
    // as built (axis-aligned cells), and the whole block turned about z by 45 degrees and about x
    // by 30 (positions and cells): a rotated cell's sub-cell face centres lie outside the box of
    // its face centres, so the pass must look for covering particles over the whole cell
    for (const bool rotated : {false, true})
    {
        Model m = test::model_from(block_deck, {"parts.block.nodal_integration={scheme: sd-snni}"});
        SemiLagrangianForceBlock& b = test::sl_block(m);
        jitter_positions(m, 1e-3, 0.2, 0.0, 8e-3);
        if (rotated)
        {
            const Mat3 R = (Eigen::AngleAxisd(M_PI / 6, Vec3::UnitX()) * Eigen::AngleAxisd(M_PI / 4, Vec3::UnitZ()))
                               .toRotationMatrix();
            const Vec3 centre(4e-3, 4e-3, 4e-3);
            for (index_t i = 0; i < m.nodes.size(); ++i)
            {
                const Vec3 x =
                    centre + R * (Vec3(m.nodes.x[3 * i], m.nodes.x[3 * i + 1], m.nodes.x[3 * i + 2]) - centre);
                for (int d = 0; d < 3; ++d)
                    m.nodes.x[3 * i + d] = x[d];
            }
            std::vector<real_t>& cells = b.nodal_points()->cells;
            for (std::size_t p = 0; p < cells.size() / 12; ++p)
                for (int v = 0; v < 4; ++v)
                {
                    const Vec3 e =
                        R * Vec3(cells[12 * p + 3 * v], cells[12 * p + 3 * v + 1], cells[12 * p + 3 * v + 2]);
                    for (int d = 0; d < 3; ++d)
                        cells[12 * p + 3 * v + d] = e[d];
                }
            b.nodal_points()->cells_trial = cells;
        }
        for (std::size_t i = 0; i < m.nodes.v.size(); ++i)
            m.nodes.v[i] = std::sin(1.7 * static_cast<double>(i)) + 0.3 * std::cos(0.9 * m.nodes.x[i] * 1e3);
        const real_t dt = 1e-12;
        IntegrationOperator pts, sub;
        ASSERT_TRUE(b.snni_operators(m.nodes.x, SemiLagrangianForceBlock::SubPoints::SubCells, pts, sub));
        const ElasticParams mat = m.nodal_block(0)->material;
        std::vector<real_t> f(m.nodes.f_int.size(), 0.0);
        for (const IntegrationOperator* op : {&pts, &sub})
            for (index_t q = 0; q < op->n_points(); ++q)
            {
                Mat3 G = Mat3::Zero();
                for (index_t k = op->offsets[q]; k < op->offsets[q + 1]; ++k)
                {
                    const std::size_t j = 3 * static_cast<std::size_t>(op->nodes[k]);
                    G += dt * Vec3(m.nodes.v[j], m.nodes.v[j + 1], m.nodes.v[j + 2]) * op->gradient(k).transpose();
                }
                const Mat3 eps = 0.5 * (G + G.transpose());
                const Mat3 sig = mat.lambda * eps.trace() * Mat3::Identity() + 2.0 * mat.mu * eps;
                for (index_t k = op->offsets[q]; k < op->offsets[q + 1]; ++k)
                {
                    const Vec3 t = op->weight[q] * sig * op->gradient(k);
                    for (int d = 0; d < 3; ++d)
                        f[3 * static_cast<std::size_t>(op->nodes[k]) + d] += t[d];
                }
            }
        const ForcePassResult r = b.add_forces(m.nodes, dt, false);
        ASSERT_LT(r.bad_element, 0);
        real_t fmax = 0.0, df = 0.0;
        for (std::size_t i = 0; i < f.size(); ++i)
        {
            fmax = std::max(fmax, std::abs(f[i]));
            df = std::max(df, std::abs(f[i] - m.nodes.f_int[i])); // f_int = K u, the internal force
        }
        std::printf("SD-SNNI pass against K (v dt) of the static sub-cell tables, jittered cloud%s: %.2e of the "
                    "largest\n",
                    rotated ? ", turned" : "", df / fmax);
        EXPECT_GT(fmax, 0.0);
        EXPECT_LT(df / fmax, 1e-6) << (rotated ? "turned" : "as built");
    }
}

TEST(SemiLagrangian, SdSnniWavePlateauMatchesTheory)
{
    check_wave({"parts.column.nodal_integration={scheme: sd-snni}"});
}

TEST(SemiLagrangian, SdSnniSpinningBlockKeepsItsMomentaAndBuildsNoSpuriousStress)
{
    check_spin({"parts.block.nodal_integration={scheme: sd-snni}"}, 1e-10);
}

// SD-SNNI on the tables of a reference (snni_operators' sub-cells, the nodal blocks' pass between
// resets): reset every 10 steps, and Lagrangian (the start's tables, never reset): the same
// plateau; the spinning block's momenta as with the face-centre resets (angular to 1e-6: the
// stabilization's torque, see SpinningBlockWithReferenceResetsKeepsItsMomenta)
TEST(SemiLagrangian, SdSnniWithReferenceResetsAndLagrangianGiveTheSameWavePlateau)
{
    check_wave(
        {"parts.column.nodal_integration={scheme: sd-snni}", "parts.column.semi_lagrangian={reset_interval: 10}"});
    check_wave({"parts.column.kinematics=lagrangian", "parts.column.nodal_integration={scheme: sd-snni}"});
}

TEST(SemiLagrangian, SdSnniSpinningBlockWithReferenceResetsKeepsItsMomenta)
{
    check_spin({"parts.block.nodal_integration={scheme: sd-snni}", "parts.block.semi_lagrangian={reset_interval: 10}"},
               1e-6);
}

// The critical step factor of the SNNI operator with the face-gradient term, on the free 8 mm
// block at the start (the tables the reset mode builds are the every-step pass's operator):
// alpha_crit = 2 / omega_max x c / min l0 (nodal_step_estimate.hpp) above the default alpha 1 at
// c_s 0.1, 0.25, 0.5 and 1 (the default; the term stiffens the highest mode, so alpha_crit
// falls as c_s grows).
TEST(SemiLagrangian, DefaultStepFactorIsBelowTheCriticalOne)
{
    for (const real_t cs : {0.1, 0.25, 0.5, 1.0})
    {
        Model m = test::model_from(block_deck, {"parts.block.semi_lagrangian={reset_interval: 2}",
                                                "parts.block.nodal_integration={scheme: snni, "
                                                "stabilization_coefficient: " +
                                                    std::to_string(cs) + "}"});
        SemiLagrangianForceBlock& b = test::sl_block(m);
        ASSERT_LT(b.add_forces(m.nodes, 1e-9, false).bad_element, 0); // builds the tables
        NodalBlock& nb = *m.nodal_block(0);
        const HighestFrequency hf = nodal_highest_frequency(nb, m.nodes.mass, 200, 1e-6);
        std::printf("c_s %.2f: alpha_crit %.3f (default alpha %.3f), %d passes\n", cs, hf.alpha_crit, nb.dt_factor,
                    hf.passes);
        EXPECT_GT(hf.alpha_crit, nb.dt_factor) << "c_s " << cs; // measured 1.138, 1.122, 1.095, 1.041
    }
}

// Separation: a K&C bar (4 x 4 x 40 mm, 1 mm spacing) whose halves fly apart at 4 m/s each breaks
// at its middle, where the two release waves meet first; with separation_damage 0.99 the failed
// particles leave the kernels. Nothing acts from outside, so the momenta of the two pieces and
// the free particles add to the initial to round-off of sum m |v|; once the crack has
// opened nothing pulls across it: each piece keeps its momentum over the run's last 10 us.
TEST(SemiLagrangian, AConcreteBarPulledApartSeparatesIntoTwoPieces)
{
    Model m = test::model_from(R"(
title: K&C bar pulled apart
time: {end: 40 us}
parts:
  bar:
    generator: {type: box, size: [4 mm, 4 mm, 40 mm], element_size: 1 mm}
    material: {model: kcc, rho: 2400 kg/m^3, fc: 45.6 MPa}
    formulation: rkpm
    kinematics: semi-lagrangian
    semi_lagrangian: {separation_damage: 0.99}
)");
    const real_t v = 4.0, mid = 20e-3;
    for (index_t i = 0; i < m.nodes.size(); ++i)
        m.nodes.v[3 * i + 2] = m.nodes.x0[3 * i + 2] > mid ? v : -v;
    const real_t scale = test::momentum_scale(m.nodes);
    const Vec3 p0 = test::momentum(m.nodes); // the lower half has one layer more
    // the pieces: particles that started 3 mm or more from the middle
    auto piece = [&](const NodeSet& n, bool top)
    {
        real_t p = 0.0;
        for (index_t i = 0; i < n.size(); ++i)
            if (top ? n.x0[3 * i + 2] > mid + 3e-3 : n.x0[3 * i + 2] < mid - 3e-3)
                p += n.mass[i] * n.v[3 * i + 2];
        return p;
    };
    real_t top_30 = 0.0, bottom_30 = 0.0, worst_total = 0.0;
    RunOptions opt;
    opt.progress = false;
    const RunSummary s = run_simulation(m, opt,
                                        [&](const Model& mm, real_t t, real_t, std::int64_t)
                                        {
                                            worst_total = std::max(worst_total, (test::momentum(mm.nodes) - p0).norm());
                                            if (t <= 30e-6)
                                                top_30 = piece(mm.nodes, true), bottom_30 = piece(mm.nodes, false);
                                        });
    ASSERT_EQ(s.status, "completed") << s.message;
    const index_t free = test::sl_block(m).free_particles();
    const real_t top = piece(m.nodes, true), bottom = piece(m.nodes, false);
    real_t gap = kNoLimit; // the crack's opening: the nearest particles of the two sides along z
    real_t z_below = -kNoLimit, z_above = kNoLimit;
    for (index_t i = 0; i < m.nodes.size(); ++i)
        if (m.nodes.x0[3 * i + 2] < mid - 3e-3)
            z_below = std::max(z_below, m.nodes.x[3 * i + 2]);
        else if (m.nodes.x0[3 * i + 2] > mid + 3e-3)
            z_above = std::min(z_above, m.nodes.x[3 * i + 2]);
    gap = z_above - z_below - 6e-3;
    std::printf("bar pulled apart: %d free particles; momentum %.2e of sum m|v|; pieces' momenta %.4e / %.4e N s, "
                "changed over the last 10 us by %.2e / %.2e; crack opened by %.3f mm\n",
                static_cast<int>(free), worst_total / scale, top, bottom, (top - top_30) / top,
                (bottom - bottom_30) / bottom, gap * 1e3);
    EXPECT_GT(free, 0);
    EXPECT_LT(worst_total / scale, 1e-12);
    EXPECT_GT(top, 0.0);
    EXPECT_LT(bottom, 0.0);
    EXPECT_LT(std::abs(top - top_30), 1e-3 * std::abs(top));
    EXPECT_LT(std::abs(bottom - bottom_30), 1e-3 * std::abs(bottom));
    EXPECT_GT(gap, 0.05e-3);
}

// Large shear: a 4 mm J2 steel block (sigma_y 200 MPa), its bottom held, its top driven along x
// at 20 m/s for 600 us (engineering shear strain 3, the issue's figure; the wave crosses it in
// 0.7 us, so nearly quasi-static). Every particle keeps a positive volume and the energy ledger
// closes within 1 %. With the face terms at c_s 1, tables rebuilt every step and every 10 steps
// (reference resets), both with the face terms unscaled (the reset mode's are the nodal blocks'),
// give the top's reaction along x within 1 % of each other at the end (13,070 and 13,037 N;
// balance 5.7e-4 and 4.5e-4). With their plastic scaling (semi_lagrangian.plastic_scaling:
// true) the reaction falls to that of the 1-point FE block with viscous hourglass control,
// within 5 % (7,139 N against 7,172; the fully integrated hex, which locks, 9,789 N): the
// unscaled elastic face terms resist the flow. At c_s 0.1 (the Taylor bar's setting)
// the unscaled reactions come down to 9,019 N every step and 8,157 N with resets every 10 steps:
// the weaker term leaves the two table modes' low-energy modes freer, and they part by 10 %
// (asserted within 12 %: recorded as found, not a band either should be held to).
// Strain 3 needed the supports to follow the cells' stretch and the cells never to be squared up:
// with supports following the volume only and cells squared to cubes past 4:1, both stopped at a
// strain of 1.38 with the ledger 17-32 % out; with the stretch and squaring at 4:1 to 32:1, at
// 2.0-2.9.
TEST(SemiLagrangian, ABlockShearedToStrainThreeKeepsPositiveVolumes)
{
    auto run = [](const std::string& reset, const std::string& scaling, const std::string& cs)
    {
        Model m = test::model_from(
            R"(
title: sheared block
time: {end: 600 us}
parts:
  block:
    generator: {type: box, size: [4 mm, 4 mm, 4 mm], element_size: 1 mm}
    material: {model: j2, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3, sigy: 200 MPa, etan: 1 GPa}
    formulation: rkpm
    kinematics: semi-lagrangian
node_sets:
  bottom: {select: {type: named, name: bottom}}
  top: {select: {type: named, name: top}}
boundary_conditions:
  - {node_set: bottom, fixed: [x, y, z]}
  - {node_set: top, fixed: [y, z]}
  - {node_set: top, velocity: {x: 20 m/s}}
)",
            {"parts.block.semi_lagrangian={reset_interval: " + reset + ", plastic_scaling: " + scaling + "}",
             "parts.block.nodal_integration={scheme: snni, stabilization_coefficient: " + cs + "}"});
        const test::RunWithBalance r = test::run_with_balance(m, 5e-6);
        EXPECT_EQ(r.summary.status, "completed") << r.summary.message;
        real_t least = kNoLimit;
        for (real_t j : m.nodal_block(0)->jacobian)
            least = std::min(least, j);
        const real_t reaction = m.reaction(2)[0]; // the driven top's
        std::printf("sheared block (reset_interval %s, plastic_scaling %s, c_s %s): %d steps, smallest V / V_ref %.3f, "
                    "balance error %.2e, top's reaction along x %.2f N\n",
                    reset.c_str(), scaling.c_str(), cs.c_str(), static_cast<int>(r.summary.steps), least, r.balance,
                    reaction);
        EXPECT_GT(least, 0.0);
        EXPECT_LT(r.balance, 0.01);
        return reaction;
    };
    const real_t every = run("1", "false", "1"), ten = run("10", "false", "1");
    EXPECT_NEAR(ten / every, 1.0, 0.01);
    const real_t scaled = run("1", "true", "1");
    EXPECT_NEAR(scaled / 7172.0, 1.0, 0.05); // the 1-point FE block's (viscous hourglass, QM 0.1)
    const real_t every_soft = run("1", "false", "0.1"), ten_soft = run("10", "false", "0.1");
    EXPECT_LT(every_soft, every);
    EXPECT_NEAR(ten_soft / every_soft, 1.0, 0.12);
}
