// The energy ledger through the explicit operator: a stepper started again in the middle of a run
// (what an event that changes the discretization does) continues the ledger, so the balance keeps
// the bound of the uninterrupted run, for both central-difference steppers and for FE and RK
// parts; the contact channel books the work of forces on nodes that change from step to step.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "../support.hpp"
#include "rkfem/core/state_archive.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/time/arkode_stepper.hpp"
#include "rkfem/time/central_difference.hpp"

using namespace rkfem;

namespace
{
// a bar driven at one end (the external work enters through the reactions): the balance error
// is measured against that work, so a ledger that restarts its origin but keeps the work is off
// by about the whole work done before the restart
const char* driven_bar = R"(
title: bar driven at one end
time: {end: 1 s}
parts:
  bar:
    generator: {type: box, size: [2 mm, 2 mm, 40 mm], divisions: [2, 2, 40]}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: fem-1pt
    hourglass: {type: stiffness, coefficient: 0.05}
    bulk_viscosity: {linear: 0, quadratic: 0}
node_sets:
  end: {select: {type: named, name: bottom}}
boundary_conditions:
  - {node_set: end, velocity: {z: 20 m/s, x: 2 m/s}}
)";

std::unique_ptr<TimeStepper> stepper(const std::string& name, const TimeSpec& ts)
{
    if (name == "central-difference")
        return std::make_unique<CentralDifference>();
    return std::make_unique<ArkodeStepper>(ArkodeStepper::Mode::CentralDifference, ts);
}

struct Ledger
{
    std::vector<real_t> error; ///< balance error after each step
    real_t work = 0.0;         ///< external work at the end
};

/// 600 steps at a fixed dt; the stepper is started again before step `restart` (0: never).
Ledger run(const std::string& stepper_name, const std::string& formulation, int restart)
{
    std::vector<std::string> ov = {"parts.bar.formulation=" + formulation};
    if (formulation == "rkpm")
        ov.push_back("parts.bar.hourglass=~");
    Model m = test::model_from(driven_bar, ov);
    const TimeSpec ts = m.deck().time;
    auto st = stepper(stepper_name, ts);
    const real_t dt = 0.5 * next_time_step(ts, 0.0, st->initialize(m, 0.0).dt_stable);
    Ledger out;
    real_t t = 0.0;
    for (int k = 1; k <= 600; ++k)
    {
        if (k == restart)
            st->initialize(m, t);
        t = st->step(m, t, dt, k).t;
        out.error.push_back(m.energy.balance_error());
    }
    out.work = m.energy.external_work;
    return out;
}
} // namespace

class ReinitializedLedger : public ::testing::TestWithParam<std::tuple<const char*, const char*>>
{
};

TEST_P(ReinitializedLedger, KeepsTheBoundOfTheUninterruptedRun)
{
    const auto [st, form] = GetParam();
    const Ledger a = run(st, form, 0), b = run(st, form, 300);
    real_t max_a = 0.0, max_b = 0.0, diff = 0.0;
    for (std::size_t k = 0; k < a.error.size(); ++k)
    {
        max_a = std::max(max_a, a.error[k]);
        max_b = std::max(max_b, b.error[k]);
        diff = std::max(diff, std::abs(a.error[k] - b.error[k]));
    }
    std::printf("%s, %s: external work %.4e J; max balance error uninterrupted %.3e, restarted at step 300 "
                "%.3e (largest difference %.1e)\n",
                st, form, a.work, max_a, max_b, diff);
    ASSERT_GT(a.work, 0.0);
    EXPECT_LT(max_a, 1e-2);
    // the same bound: the restart changes the balance only by the kinetic-energy correction it
    // cannot form at its first step, O((omega dt)^2) of the kinetic energy
    EXPECT_LE(max_b, 1.05 * max_a + 1e-9);
    EXPECT_LT(diff, 1e-3);
    EXPECT_NEAR(b.work, a.work, 1e-9 * a.work);
}

INSTANTIATE_TEST_SUITE_P(Steppers, ReinitializedLedger,
                         ::testing::Combine(::testing::Values("central-difference", "arkode-cd"),
                                            ::testing::Values("fem-1pt", "rkpm")),
                         [](const auto& info)
                         {
                             std::string s = std::string(std::get<0>(info.param)) + "_" + std::get<1>(info.param);
                             for (char& c : s)
                                 if (c == '-')
                                     c = '_';
                             return s;
                         });

TEST(ContactChannel, BooksTheTrapezoidWorkOverChangingNodes)
{
    // forces on a different random set of nodes at each end of the step: the channel's work is
    // sum 1/2 (f(n) + f(n+1)) . du over every dof, as a dense sum gives it
    const index_t n = 200;
    ContactChannel ch;
    ch.resize(n);
    std::mt19937 gen(3);
    std::uniform_real_distribution<real_t> rnd(-1.0, 1.0);
    std::vector<real_t> f_prev(3 * n, 0.0), u_prev(3 * n), u(3 * n);
    for (int step = 0; step < 5; ++step)
    {
        for (int pass = 0; pass < 2; ++pass) // a stepper may evaluate twice; the last pass counts
        {
            ch.clear();
            for (int k = 0; k < 30; ++k)
            {
                const index_t i = static_cast<index_t>(gen() % n);
                ch.add(i, Vec3(rnd(gen), rnd(gen), rnd(gen)));
            }
        }
        for (index_t j = 0; j < 3 * n; ++j)
        {
            u_prev[j] = rnd(gen);
            u[j] = u_prev[j] + rnd(gen);
        }
        real_t dense = 0.0;
        for (index_t j = 0; j < 3 * n; ++j)
            dense += 0.5 * (f_prev[j] + ch.f[j]) * (u[j] - u_prev[j]);
        const real_t w = ch.step_work(u.data(), u_prev.data());
        EXPECT_NEAR(w, dense, 1e-13 * std::max(1.0, std::abs(dense))) << "step " << step;
        // untouched nodes carry no force
        index_t nonzero = 0;
        for (index_t j = 0; j < 3 * n; ++j)
            nonzero += ch.f[j] != 0.0;
        EXPECT_LE(nonzero, 3 * static_cast<index_t>(ch.nodes().size()));
        ch.commit();
        f_prev = ch.f;
    }
}

// The channel holds no arrays until a force reaches it (a model without contact keeps none,
// 25 bytes a node): force() reads 0 before, the first force allocates them, and a checkpoint
// taken before it restores an empty channel into one that had forces, and back.
TEST(ContactChannel, HoldsNoArraysUntilAForceArrives)
{
    const index_t n = 50;
    ContactChannel ch;
    ch.resize(n);
    EXPECT_TRUE(ch.f.empty());
    EXPECT_EQ(ch.force(7), 0.0);
    StateArchive before;
    ch.save_state(before);
    ch.clear();
    ch.add(7, Vec3(1.0, 2.0, 3.0));
    ASSERT_EQ(ch.f.size(), 3u * n);
    EXPECT_EQ(ch.force(3 * 7 + 1), 2.0);
    EXPECT_EQ(ch.force(3 * 8), 0.0);
    ch.commit();
    StateArchive after;
    ch.save_state(after);
    ch.load_state(before);
    EXPECT_TRUE(ch.f.empty());
    EXPECT_TRUE(ch.nodes().empty());
    EXPECT_EQ(ch.step_work(std::vector<real_t>(3 * n, 1.0).data(), std::vector<real_t>(3 * n, 0.0).data()), 0.0);
    ch.load_state(after);
    ASSERT_EQ(ch.f.size(), 3u * n);
    EXPECT_EQ(ch.force(3 * 7 + 2), 3.0);
    ASSERT_EQ(ch.nodes().size(), 1u);
    // a model built from a deck without contact: its channel holds nothing
    const Model m = test::model_from(driven_bar, {});
    EXPECT_TRUE(m.contacts.empty());
    EXPECT_TRUE(m.contact.f.empty());
}

namespace
{
/// A frictionless penalty wall at z = z_wall: each node below it is pushed back with k (z_wall - z).
class PenaltyWall final : public ContactAlgorithm
{
  public:
    PenaltyWall(real_t z_wall, real_t k) : z_(z_wall), k_(k) {}
    void set_surfaces(std::vector<ContactSurface>) override {}
    Vec3 resultant() const override { return Vec3::Zero(); }
    index_t active_nodes() const override { return 0; }
    void add_forces(const PhysicalNodes& nodes, const ContactClock&, ContactChannel& ch) override
    {
        for (index_t i = 0; i < nodes.size(); ++i)
        {
            const real_t g = nodes.x(i)[2] - z_;
            if (g < 0)
                ch.add(i, Vec3(0, 0, -k_ * g));
        }
    }

  private:
    real_t z_, k_;
};

const char* falling_bar = R"(
title: bar moving onto a wall
time: {end: 1 s}
parts:
  bar:
    generator: {type: box, origin: [0, 0, 0.1 mm], size: [2 mm, 2 mm, 20 mm], divisions: [2, 2, 20]}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: fem-1pt
    hourglass: {type: stiffness, coefficient: 0.05}
    bulk_viscosity: {linear: 0, quadratic: 0}
    initial_velocity: [0, 0, -10 m/s]
)";
} // namespace

TEST(ContactChannel, ClosesTheLedgerThroughAnImpact)
{
    // a bar moving at 10 m/s onto a penalty wall: during contact the springs hold energy that
    // only the channel's work term accounts for; after separation it is given back
    for (const char* st : {"central-difference", "arkode-cd", "central-difference rkpm"})
    {
        // on RK particles the wall sees the physical positions through the kinematic map, and
        // its forces reach the coefficients through the map's transpose
        const bool rk = std::string(st).find("rkpm") != std::string::npos;
        Model m = test::model_from(falling_bar,
                                   rk ? std::vector<std::string>{"parts.bar.formulation=rkpm", "parts.bar.hourglass=~"}
                                      : std::vector<std::string>{});
        const real_t k = 2e8; // N/m per node: stiffer than the bar's 4 nodes' share of E A / h
        m.contacts.push_back(std::make_unique<PenaltyWall>(0.0, k));
        const TimeSpec ts = m.deck().time;
        auto stepper_ = stepper(rk ? "central-difference" : st, ts);
        const real_t dt = 0.5 * next_time_step(ts, 0.0, stepper_->initialize(m, 0.0).dt_stable);
        const real_t e0 = m.energy.kinetic;
        real_t t = 0.0, max_err = 0.0, max_sliding = 0.0, min_z = 1.0;
        // 20 mm steel: 2 L / c = 7.8 us in contact, 10 us to reach the wall
        for (int k_step = 1; t < 30e-6; ++k_step)
        {
            t = stepper_->step(m, t, dt, k_step).t;
            max_err = std::max(max_err, m.energy.balance_error());
            max_sliding = std::max(max_sliding, m.energy.contact);
            for (index_t i = 0; i < m.nodes.size(); ++i)
                min_z = std::min(min_z, m.kinematics.position(m.nodes.x0, m.nodes.u, i)[2]);
        }
        real_t pz = 0.0;
        for (index_t i = 0; i < m.nodes.size(); ++i)
            pz += m.nodes.mass[i] * m.nodes.v[3 * i + 2];
        const real_t mass = 7850 * 2e-3 * 2e-3 * 20e-3;
        std::printf("%s: initial kinetic %.4e J, largest sliding energy %.4e J (%.1f%%), max balance error %.2e, "
                    "deepest point %.3f um, momentum after / before %.4f\n",
                    st, e0, max_sliding, 100 * max_sliding / e0, max_err, 1e6 * min_z, pz / (-mass * 10.0));
        EXPECT_GT(max_sliding, 1e-3 * e0); // the springs held energy during the contact
        EXPECT_LT(max_err, 1e-2);
        EXPECT_LT(std::abs(m.energy.contact), 1e-2 * e0); // given back after separation
        EXPECT_LT(pz / (-mass * 10.0), -0.9);             // it bounced
    }
}

TEST(KinematicMap, SpreadIsTheTransposeOfThePhysicalValues)
{
    // rows of an RK part (rkpm bar): sum_I f_I . u^h(X_I) = sum_J (spread f)_J . d_J for any
    // field, so forces at physical points do the same work in either space; FE nodes are
    // identity rows; the RK rows are partitions of unity
    Model m = test::model_from(driven_bar, {"parts.bar.formulation=rkpm", "parts.bar.hourglass=~"});
    const KinematicMap& map = m.kinematics;
    const index_t n = m.nodes.size();
    std::mt19937 gen(11);
    std::uniform_real_distribution<real_t> rnd(-1.0, 1.0);
    std::vector<real_t> d(3 * n), f(3 * n), spread(3 * n, 0.0), u;
    for (index_t j = 0; j < 3 * n; ++j)
        d[j] = rnd(gen), f[j] = rnd(gen);
    map.physical_field(d, u);
    real_t lhs = 0.0, rhs = 0.0, scale = 0.0, unity = 0.0;
    for (index_t i = 0; i < n; ++i)
    {
        ASSERT_TRUE(map.carries_coefficients(i));
        map.spread(i, Vec3(f[3 * i], f[3 * i + 1], f[3 * i + 2]), spread.data());
        real_t s = 0.0;
        map.for_row(i, [&](index_t, real_t w) { s += w; });
        unity = std::max(unity, std::abs(s - 1.0));
    }
    for (index_t j = 0; j < 3 * n; ++j)
    {
        lhs += f[j] * u[j];
        rhs += spread[j] * d[j];
        scale += std::abs(f[j] * u[j]);
    }
    std::printf("sum f . u^h = %.15e, sum spread(f) . d = %.15e; partition of unity to %.1e\n", lhs, rhs, unity);
    EXPECT_NEAR(lhs, rhs, 1e-13 * scale);
    EXPECT_LT(unity, 1e-13);
    // an FE part: every row is the identity
    Model fe = test::model_from(driven_bar);
    for (index_t i = 0; i < fe.nodes.size(); ++i)
        ASSERT_FALSE(fe.kinematics.carries_coefficients(i));
    EXPECT_TRUE(fe.kinematics.identity());
}
