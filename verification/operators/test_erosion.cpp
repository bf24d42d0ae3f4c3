// Element erosion as an event between steps (Model::apply_events, deck key parts.*.erosion):
// two halves of a J2 steel bar (no conditions, no loads) driven into each other by their initial
// velocities; elements in the middle reach the plastic-strain limit and are removed. Through
// the events the nodes keep their mass, momentum is conserved to round-off, the energy ledger
// continues (the balance keeps the bound of the run without erosion), a limit never reached
// gives the bits of the run without erosion, and results.h5 gets a mesh per topology. Point
// state moves between block kinds whole (operators/point_state.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <hdf5.h>

#include "../support.hpp"
#include "rkfem/model/material_from_deck.hpp"
#include "rkfem/model/nodal_block_build.hpp"
#include "rkfem/operators/point_state.hpp"
#include "rkfem/run/simulation.hpp"
#include "rkfem/time/stepper.hpp"

using namespace rkfem;

namespace
{
const char* deck = R"(
title: colliding halves
time: {end: 8 us, stepper: central-difference}
parts:
  bar:
    generator: {type: box, size: [2 mm, 2 mm, 20 mm], divisions: [2, 2, 20]}
    material: {model: j2, rho: 7850 kg/m^3, E: 205 GPa, nu: 0.29, sigy: 500 MPa, etan: 1 GPa}
    formulation: fem-1pt
    hourglass: {type: stiffness, coefficient: 0.05}
    bulk_viscosity: {linear: 0, quadratic: 0}
    erosion: {effective_plastic_strain: 0.01}
)";

struct ErosionRun
{
    RunSummary summary;
    std::vector<real_t> u;
    real_t mass = 0.0, mass0 = 0.0;
    real_t momentum_drift = 0.0; ///< max |p - p0| / sum m |v0| over the run
    real_t worst_balance = 0.0;  ///< after step 50
    index_t eroded = 0;
};

ErosionRun run(const std::vector<std::string>& overrides, const std::string& out = "")
{
    Model m = test::model_from(deck, overrides);
    ErosionRun r;
    real_t scale = 0.0;
    for (index_t i = 0; i < m.nodes.size(); ++i)
    {
        const real_t z = m.nodes.x0[3 * i + 2];
        m.nodes.v[3 * i + 2] = z < 0.01 - 1e-6 ? 150.0 : z > 0.01 + 1e-6 ? -150.0 : 0.0;
        r.mass0 += m.nodes.mass[i];
        scale += m.nodes.mass[i] * 150.0;
    }
    RunOptions opt;
    opt.progress = false;
    opt.out_dir = out;
    r.summary = run_simulation(m, opt,
                               [&](const Model& mm, real_t, real_t, std::int64_t step)
                               {
                                   Vec3 p = Vec3::Zero();
                                   for (index_t i = 0; i < mm.nodes.size(); ++i)
                                       p += mm.nodes.mass[i] *
                                            Vec3(mm.nodes.v[3 * i], mm.nodes.v[3 * i + 1], mm.nodes.v[3 * i + 2]);
                                   r.momentum_drift = std::max(r.momentum_drift, p.norm() / scale);
                                   if (step > 50)
                                       r.worst_balance = std::max(r.worst_balance, mm.energy.balance_error());
                               });
    for (index_t i = 0; i < m.nodes.size(); ++i)
        r.mass += m.nodes.mass[i];
    r.u = m.nodes.u;
    r.eroded = m.eroded_elements();
    return r;
}
} // namespace

TEST(Erosion, EventsKeepMassMomentumAndTheLedger)
{
    const ErosionRun none = run({"parts.bar.erosion.effective_plastic_strain=100"});
    const ErosionRun ero = run({});
    std::printf("without erosion: balance error after step 50 at most %.2e, momentum drift %.1e\n", none.worst_balance,
                none.momentum_drift);
    std::printf(
        "with erosion: %ld of 80 elements eroded, eroded energy %.3e J of %.3e J initial kinetic, balance error at "
        "most %.2e, momentum drift %.1e, mass %.6e of %.6e kg\n",
        static_cast<long>(ero.eroded), ero.summary.energy.eroded, ero.summary.energy.kinetic0, ero.worst_balance,
        ero.momentum_drift, ero.mass, ero.mass0);
    ASSERT_EQ(ero.summary.status, "completed") << ero.summary.message;
    EXPECT_GT(ero.eroded, 0);
    EXPECT_LT(ero.eroded, 80);
    EXPECT_EQ(none.eroded, 0);
    EXPECT_EQ(ero.mass, ero.mass0);       // nodes keep their mass
    EXPECT_LT(ero.momentum_drift, 1e-12); // the halves' momenta cancel throughout
    // the ledger continues through the events: the bound of the run without erosion (without
    // booking the eroded energy it was 2.5e-2 here, against 5.7e-3)
    EXPECT_LT(ero.worst_balance, std::max(1.5 * none.worst_balance, 1e-3));
    EXPECT_NE(ero.summary.energy.eroded, 0.0);
}

// J2 failure (material key `fail`, LS-DYNA MAT_024 FAIL) on Gauss-point elements deletes an
// element once all its points have failed, with the books of erosion: no failed element stays
// in the mesh (a failed point carries no shear and no tension; left in, such elements collapse
// and their hourglass modes blew up a P6 FSP at 125 us), on 1-point and 2x2x2 elements alike.
TEST(Erosion, J2FailureDeletesAnElementOnceAllItsPointsHaveFailed)
{
    for (const char* formulation : {"fem-1pt", "fem-2x2x2"})
    {
        SCOPED_TRACE(formulation);
        Model m = test::model_from(deck, {"parts.bar.erosion=~", "parts.bar.material.fail=0.01",
                                          std::string("parts.bar.formulation=") + formulation});
        real_t mass0 = 0.0;
        for (index_t i = 0; i < m.nodes.size(); ++i)
        {
            const real_t z = m.nodes.x0[3 * i + 2];
            m.nodes.v[3 * i + 2] = z < 0.01 - 1e-6 ? 150.0 : z > 0.01 + 1e-6 ? -150.0 : 0.0;
            mass0 += m.nodes.mass[i];
        }
        RunOptions opt;
        opt.progress = false;
        real_t worst_balance = 0.0, drift = 0.0;
        const RunSummary s = run_simulation(
            m, opt,
            [&](const Model& mm, real_t, real_t, std::int64_t step)
            {
                Vec3 p = Vec3::Zero();
                for (index_t i = 0; i < mm.nodes.size(); ++i)
                    p += mm.nodes.mass[i] * Vec3(mm.nodes.v[3 * i], mm.nodes.v[3 * i + 1], mm.nodes.v[3 * i + 2]);
                drift = std::max(drift, p.norm() / (mass0 * 150.0));
                if (step > 50)
                    worst_balance = std::max(worst_balance, mm.energy.balance_error());
            });
        ASSERT_EQ(s.status, "completed") << s.message;
        std::printf("%s: %ld of 80 elements deleted on failure, balance error after step 50 at most %.2e, momentum "
                    "drift %.1e\n",
                    formulation, static_cast<long>(m.eroded_elements()), worst_balance, drift);
        EXPECT_GT(m.eroded_elements(), 0);
        EXPECT_LT(m.eroded_elements(), 80);
        index_t partly = 0;
        for (index_t e = 0; e < m.meshes[0].n_elements(); ++e)
        {
            const real_t failed = m.element_history(0, e, Model::History::Damage);
            EXPECT_LT(failed, 1.0) << "element " << e << " failed at every point and is still in the mesh";
            partly += failed > 0.0;
        }
        if (std::string(formulation) == "fem-2x2x2")
            std::printf("fem-2x2x2: %ld kept elements have some failed points\n", static_cast<long>(partly));
        EXPECT_LT(drift, 1e-12);
        EXPECT_LT(worst_balance, 1e-3); // 7.3e-4 and 7.5e-4 here; 5.7e-3 for the bar that keeps its elements
        EXPECT_NE(s.energy.eroded, 0.0);
    }
}

TEST(Erosion, ALimitNeverReachedGivesTheBitsOfNoErosion)
{
    const ErosionRun never = run({"parts.bar.erosion.effective_plastic_strain=100"});
    const ErosionRun off = run({"parts.bar.erosion=~"});
    ASSERT_EQ(never.u.size(), off.u.size());
    EXPECT_TRUE(never.u == off.u);
}

TEST(Erosion, ResultsGetAMeshPerTopology)
{
    const auto dir = std::filesystem::temp_directory_path() / "rkfem_erosion_out";
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    const ErosionRun ero = run({"time.output_interval=1 us"}, dir.string());
    ASSERT_GT(ero.eroded, 0);
    const hid_t f = H5Fopen((dir / "results.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    EXPECT_GT(H5Lexists(f, "mesh", H5P_DEFAULT), 0);
    EXPECT_GT(H5Lexists(f, "mesh_000001", H5P_DEFAULT), 0);
    // the last step points at the last mesh, which holds the elements that are left
    hsize_t n_steps = 0;
    const hid_t steps = H5Gopen2(f, "steps", H5P_DEFAULT);
    H5Gget_num_objs(steps, &n_steps);
    char name[32];
    std::snprintf(name, sizeof name, "%06d", static_cast<int>(n_steps) - 1);
    const hid_t last = H5Gopen2(steps, name, H5P_DEFAULT);
    const hid_t attr = H5Aopen(last, "mesh", H5P_DEFAULT);
    const hid_t type = H5Aget_type(attr);
    std::string mesh(H5Tget_size(type), '\0');
    H5Aread(attr, type, mesh.data());
    const hid_t conn = H5Dopen2(f, (mesh + "/connectivity").c_str(), H5P_DEFAULT);
    const hid_t space = H5Dget_space(conn);
    hsize_t dims[2] = {0, 0};
    H5Sget_simple_extent_dims(space, dims, nullptr);
    std::printf("%llu outputs; the last one's mesh %s has %llu elements\n", static_cast<unsigned long long>(n_steps),
                mesh.c_str(), static_cast<unsigned long long>(dims[0]));
    EXPECT_EQ(static_cast<index_t>(dims[0]), 80 - ero.eroded);
    EXPECT_NE(mesh, "/mesh");
    for (hid_t h : {space})
        H5Sclose(h);
    H5Dclose(conn);
    H5Tclose(type);
    H5Aclose(attr);
    H5Gclose(last);
    H5Gclose(steps);
    H5Fclose(f);
}

TEST(PointState, MovesBetweenBlockKinds)
{
    // J2 state of a 1-point hex block's points copied onto a nodal block's points (what a
    // conversion of elements into particles does): stress and history arrive whole, committed
    // and trial; a block of another model is refused
    const MaterialSpec j2 = test::j2_material(7850, 205e9, 0.29, 500e6, 1e9);
    const HexMesh mesh = test::distorted_box(3, 0.01, 0.2);
    NodeSet nodes;
    HexBlock hex = test::make_block(mesh, nodes, Formulation::Fem1pt, {HourglassType::Viscous, 0.1},
                                    ElasticParams::from_E_nu(j2.rho, j2.E, j2.nu));
    configure_points(hex.plastic, j2);
    hex.plastic.resize(static_cast<std::size_t>(hex.n_points()));
    PartSpec ps = test::steel_nodal_part(Formulation::FemNodal);
    ps.material = j2;
    NodalBlock nodal = build_nodal_block(ps, mesh, 0);
    std::mt19937 gen(3);
    std::uniform_real_distribution<real_t> rnd(0.0, 1.0);
    for (std::size_t k = 0; k < hex.stress.size(); ++k)
        hex.stress[k] = 1e8 * rnd(gen);
    for (std::size_t p = 0; p < hex.plastic.eps_p.size(); ++p)
        hex.plastic.eps_p[p] = 0.1 * rnd(gen);
    const PointState src = point_state(hex), dst = point_state(nodal);
    for (std::size_t q = 0; q < dst.n_points; ++q)
        copy_point_state(src, q % src.n_points, dst, q);
    real_t diff = 0.0;
    for (std::size_t q = 0; q < dst.n_points; ++q)
    {
        const std::size_t e = q % src.n_points;
        diff = std::max(diff, std::abs(nodal.plastic.eps_p[q] - hex.plastic.eps_p[e]) +
                                  std::abs(nodal.plastic.eps_p_trial[q] - hex.plastic.eps_p[e]));
        for (int k = 0; k < 6; ++k)
            diff = std::max(
                diff,
                std::abs(nodal.stress[k * nodal.stress_stride + q] - hex.stress[k * hex.stress_stride + e]) +
                    std::abs(nodal.stress_trial[k * nodal.stress_stride + q] - hex.stress[k * hex.stress_stride + e]));
    }
    EXPECT_EQ(diff, 0.0);
    EXPECT_GT(nodal.plastic.eps_p[0], 0.0);
    NodalBlock elastic = build_nodal_block(test::steel_nodal_part(Formulation::FemNodal), mesh, 0);
    EXPECT_THROW(copy_point_state(src, 0, point_state(elastic), 0), Error);
}

TEST(Erosion, ShapeCriteriaPrincipalStrainVolumetricStrainAndTimeStep)
{
    // an elastic 1 x 1 x 4 bar (shape criteria need no material history) under an affine motion
    // of all its nodes, so every element has the same F: each criterion erodes exactly when its
    // measure passes the limit, on either side of the known value
    const char* bar = R"(
title: shape criteria
time: {end: 1 us}
parts:
  bar:
    generator: {type: box, size: [1 mm, 1 mm, 4 mm], divisions: [1, 1, 4]}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: fem-1pt
    erosion: {principal_strain: 0.1}
)";
    auto eroded_after = [&](const std::string& criterion, real_t stretch_z, real_t stretch_x)
    {
        Model m = test::model_from(bar, {"parts.bar.erosion=~", "parts.bar.erosion." + criterion});
        for (index_t i = 0; i < m.nodes.size(); ++i)
        {
            m.nodes.x[3 * i] = stretch_x * m.nodes.x0[3 * i];
            m.nodes.x[3 * i + 2] = stretch_z * m.nodes.x0[3 * i + 2];
        }
        const Model::ElementShape g = m.element_shape(0, 2);
        EXPECT_EQ(m.element_time_step(0, 2), g.time_step); // the step budget's scan reads it alone
        m.apply_events(0.0, 1);
        return std::make_pair(m.eroded_elements(), g);
    };
    // uniaxial stretch 1.03: ln 1.03 = 0.02956, V / V0 - 1 = 0.03
    const auto [n0, g] = eroded_after("principal_strain=0.0295", 1.03, 1.0);
    std::printf("stretch 1.03: principal strain %.6f, volumetric strain %.6f, element step %.4e s\n",
                g.principal_strain, g.volumetric_strain, g.time_step);
    EXPECT_NEAR(g.principal_strain, std::log(1.03), 1e-14);
    EXPECT_NEAR(g.volumetric_strain, 0.03, 1e-14);
    EXPECT_EQ(n0, 4);
    EXPECT_EQ(eroded_after("principal_strain=0.0296", 1.03, 1.0).first, 0);
    EXPECT_EQ(eroded_after("volumetric_strain=0.0299", 1.03, 1.0).first, 4);
    EXPECT_EQ(eroded_after("volumetric_strain=0.0301", 1.03, 1.0).first, 0);
    // squeezed to half its width in x: V / A_max = 0.5 mm (the face normal to x stays 1 mm^2),
    // step 0.5 mm / c; c = sqrt((lambda + 2 mu) / rho)
    const real_t c = std::sqrt(200e9 * 0.7 / (1.3 * 0.4) / 7850.0);
    const Model::ElementShape sq = eroded_after("time_step=1e-9 s", 1.0, 0.5).second;
    EXPECT_NEAR(sq.time_step, 0.5e-3 / c, 1e-12 * sq.time_step);
    auto seconds = [](real_t v)
    {
        char buf[64];
        std::snprintf(buf, sizeof buf, "%.9e s", v);
        return std::string(buf);
    };
    EXPECT_EQ(eroded_after("time_step=" + seconds(1.01 * 0.5e-3 / c), 1.0, 0.5).first, 4);
    EXPECT_EQ(eroded_after("time_step=" + seconds(0.99 * 0.5e-3 / c), 1.0, 0.5).first, 0);
}

TEST(Restart, KccBarStartedAgainAfterEveryStepRunsAsTheUninterruptedOne)
{
    // every event (conversion, erosion) starts the stepper again, which evaluates forces with
    // dt = 0. The K&C surface depends on the strain rate, and the state's rate at the restart
    // is not the last step's: a material update there returned the stress with no strain
    // increment and added damage at every restart (kinetic energy 5.27 J against 3.25 J, a
    // balance error of 0.15). Materials now keep their history at dt = 0.
    const std::string deck = std::string(RKFEM_SOURCE_DIR) + "/studies/decks/concrete_bar_kcc.yaml";
    auto run = [&](bool restart_every_step)
    {
        Model m = Model::build(read_deck(deck, {"parts.bar.formulation=fem-nodal", "parts.bar.hourglass=~"}));
        RunOptions opt;
        opt.progress = false;
        if (restart_every_step)
            opt.events = [](Model&, real_t, std::int64_t) { return true; };
        EXPECT_EQ(run_simulation(m, opt).status, "completed");
        return m.energy;
    };
    const Energies restarted = run(true), plain = run(false);
    std::printf("K&C bar, stepper started again after every step: kinetic %.4f J, internal %.4f J, balance error %.2e; "
                "uninterrupted %.4f J, %.4f J, %.2e\n",
                restarted.kinetic, restarted.internal, restarted.balance_error(), plain.kinetic, plain.internal,
                plain.balance_error());
    EXPECT_NEAR(restarted.kinetic / plain.kinetic, 1.0, 0.01);
    EXPECT_NEAR(restarted.internal / plain.internal, 1.0, 0.01);
    EXPECT_LT(restarted.balance_error(), 2e-3);
}

// Without observers a run computes the nodes' motion (kinetic energy, the parts' momentum) only
// on the steps that read it (Model::defer_motion): balance checks, history rows, outputs, and
// before an event changes the model. Its history, with elements eroding, is the bits of the run
// that computes it every step (an observer), and a step leaves it for refresh_motion().
TEST(Erosion, MotionComputedWhenReadGivesTheBitsOfEveryStep)
{
    auto run_deck = [](bool observe)
    {
        Model m = test::model_from(deck, {"time.history_interval=0.3us"});
        for (index_t i = 0; i < m.nodes.size(); ++i)
        {
            const real_t z = m.nodes.x0[3 * i + 2];
            m.nodes.v[3 * i + 2] = z < 0.01 - 1e-6 ? 150.0 : z > 0.01 + 1e-6 ? -150.0 : 0.0;
        }
        RunOptions opt;
        opt.progress = false;
        StepObserver none;
        const RunSummary s =
            run_simulation(m, opt, observe ? StepObserver([](const Model&, real_t, real_t, std::int64_t) {}) : none);
        EXPECT_EQ(s.status, "completed") << s.message;
        EXPECT_GT(m.eroded_elements(), 0);
        return s;
    };
    const RunSummary deferred = run_deck(false), every = run_deck(true);
    ASSERT_GT(deferred.history.size(), 20 * deferred.history_columns.size());
    EXPECT_TRUE(deferred.history == every.history);
    EXPECT_EQ(deferred.energy.kinetic, every.energy.kinetic);
    EXPECT_EQ(deferred.energy.kinetic_correction, every.energy.kinetic_correction);

    Model m = test::model_from(deck);
    for (index_t i = 0; i < m.nodes.size(); ++i)
        m.nodes.v[3 * i + 2] = m.nodes.x0[3 * i + 2] < 0.01 ? 150.0 : -150.0;
    auto stepper = make_stepper(m.deck().time);
    const StepReport r = stepper->initialize(m, 0.0);
    m.defer_motion(true);
    stepper->step(m, 0.0, 0.5 * r.dt_stable, 1);
    const real_t before = m.energy.kinetic_correction;
    m.refresh_motion();
    EXPECT_EQ(before, 0.0); // the start's (no step yet), until refreshed
    EXPECT_LT(m.energy.kinetic_correction, 0.0);
}
