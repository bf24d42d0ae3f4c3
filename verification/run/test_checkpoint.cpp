// Checkpoints and restart through the executable: `rkfem run DECK --checkpoint-interval T` writes
// DIR/checkpoint.h5 (the newest N kept), and `rkfem restart DIR --from FILE` continues from any
// of them with the same bits as the run that was not interrupted: every field of every frame,
// history.csv byte for byte, summary.json but for its clocks. Erosion (J2 elements removed
// mid-run), K&C, RK particles on a mesh and on a Voronoi cloud (pressure on cloud facets, RK
// collocation of the rollers), a projectile eroding its way into a block through penalty contact,
// with the three steppers. A run killed while writing a checkpoint leaves a .tmp file that
// restart never reads; a damaged or missing checkpoint and bad times are refused with one line,
// exit 2.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <hdf5.h>
#include <iterator>
#include <regex>
#include <string>
#include <vector>

#include "../executable.hpp"

namespace fs = std::filesystem;
using rkfem::test::Result;
using rkfem::test::run;

namespace
{
std::string slurp(const fs::path& p)
{
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// summary.json without the lines that hold wall-clock times and what follows from them (the
/// thread governor's switches and one-thread steps: they differ from run to run with the load).
std::string summary_without_clocks(const fs::path& dir)
{
    std::istringstream in(slurp(dir / "summary.json"));
    std::string out;
    for (std::string line; std::getline(in, line);)
        if (line.find("seconds") == std::string::npos && line.find("ns_per_element_cycle") == std::string::npos &&
            line.find("\"thread_switches\"") == std::string::npos &&
            line.find("\"steps_on_one_thread\"") == std::string::npos)
            out += line + "\n";
    return out;
}

/// Every frame's datasets of results.h5, as raw bytes, frame by frame; the frames' times.
struct Frames
{
    std::vector<std::string> data;
    std::vector<double> times;
};

Frames read_frames(const fs::path& dir)
{
    Frames f;
    const hid_t file = H5Fopen((dir / "results.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    EXPECT_GE(file, 0) << dir;
    if (file < 0)
        return f;
    const hid_t steps = H5Gopen2(file, "steps", H5P_DEFAULT);
    hsize_t n = 0;
    H5Gget_num_objs(steps, &n);
    for (hsize_t i = 0; i < n; ++i)
    {
        char name[64];
        H5Gget_objname_by_idx(steps, i, name, sizeof name);
        const hid_t g = H5Gopen2(steps, name, H5P_DEFAULT);
        double t = 0;
        const hid_t a = H5Aopen(g, "time", H5P_DEFAULT);
        H5Aread(a, H5T_NATIVE_DOUBLE, &t);
        H5Aclose(a);
        f.times.push_back(t);
        std::string bytes;
        hsize_t m = 0;
        H5Gget_num_objs(g, &m);
        for (hsize_t k = 0; k < m; ++k)
        {
            char field[64];
            H5Gget_objname_by_idx(g, k, field, sizeof field);
            const hid_t d = H5Dopen2(g, field, H5P_DEFAULT);
            const hid_t s = H5Dget_space(d);
            std::vector<double> v(static_cast<std::size_t>(H5Sget_simple_extent_npoints(s)));
            H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
            bytes += std::string(field) + ":" +
                     std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(double));
            H5Sclose(s);
            H5Dclose(d);
        }
        f.data.push_back(bytes);
        H5Gclose(g);
    }
    H5Gclose(steps);
    H5Fclose(file);
    return f;
}

std::string deck_path(const char* name)
{
    return (fs::path(RKFEM_SOURCE_DIR) / "studies/decks" / name).string();
}

/// Runs DECK uninterrupted with checkpoints every `interval` (all kept), then restarts a copy of
/// its directory from each checkpoint but the last (the end of the run) and compares.
void expect_restarts_reproduce(const std::string& label, const std::string& deck, const std::string& sets,
                               const std::string& interval)
{
    const fs::path u = fs::temp_directory_path() / ("rkfem_ckpt_" + label);
    fs::remove_all(u);
    const Result r = run("run " + deck + " --out " + u.string() + " --quiet --set output.precision=double " + sets +
                         " --checkpoint-interval '" + interval + "' --checkpoint-keep 50");
    ASSERT_EQ(r.code, 0) << label << ": " << r.output;
    int n = 0;
    while (fs::exists(u / ("checkpoint." + std::to_string(n + 1) + ".h5")))
        ++n;
    ASSERT_GE(n, 2) << label << ": expected at least two checkpoints before the end";
    const Frames whole = read_frames(u);
    const std::string history = slurp(u / "history.csv"), summary = summary_without_clocks(u);
    for (int k = 1; k <= n; ++k)
    {
        const fs::path c = fs::temp_directory_path() / ("rkfem_ckpt_" + label + "_restart");
        fs::remove_all(c);
        fs::copy(u, c);
        // a checkpoint that a killed run was writing: never read
        std::ofstream(c / "checkpoint.h5.tmp") << "half a file";
        const Result rs = run("restart " + c.string() + " --quiet --from " +
                              (u / ("checkpoint." + std::to_string(k) + ".h5")).string());
        ASSERT_EQ(rs.code, 0) << label << " from checkpoint." << k << ": " << rs.output;
        const Frames again = read_frames(c);
        ASSERT_EQ(again.times, whole.times) << label << " from checkpoint." << k;
        std::size_t differ = 0;
        for (std::size_t f = 0; f < whole.data.size(); ++f)
            differ += whole.data[f] != again.data[f];
        std::printf("%s: restarted from checkpoint.%d.h5: %zu frames, %zu differ; history %s, summary %s\n",
                    label.c_str(), k, whole.data.size(), differ,
                    slurp(c / "history.csv") == history ? "same bytes" : "DIFFERS",
                    summary_without_clocks(c) == summary ? "same" : "DIFFERS");
        EXPECT_EQ(differ, 0u) << label << " from checkpoint." << k;
        EXPECT_EQ(slurp(c / "history.csv"), history) << label << " from checkpoint." << k;
        EXPECT_EQ(summary_without_clocks(c), summary) << label << " from checkpoint." << k;
    }
}
} // namespace

TEST(Checkpoint, ErodingJ2BarRestartsWithTheSameBitsWithEachStepper)
{
    for (const char* stepper : {"central-difference", "arkode-cd", "arkode-erk"})
        expect_restarts_reproduce(std::string("erosion_") + stepper, deck_path("bar_erosion.yaml"),
                                  std::string("--set time.stepper=") + stepper, "3 us");
}

TEST(Checkpoint, ConcreteBarRestartsWithTheSameBits)
{
    expect_restarts_reproduce("kcc", deck_path("concrete_bar_kcc.yaml"), "", "10 us");
}

// Evolutionary coupling: the restart converts the elements the run had converted (the points'
// state then loads as it was saved), and conversion goes on after it, at the checks' times
TEST(Checkpoint, ConvertingConcreteBarRestartsWithTheSameBits)
{
    for (const char* stepper : {"central-difference", "arkode-cd"})
        expect_restarts_reproduce(std::string("conversion_") + stepper, deck_path("concrete_bar_conversion.yaml"),
                                  std::string("--set parts.bar.generator.element_size=5mm --set time.end=20us "
                                              "--set parts.bar.conversion.interval=3us --set time.stepper=") +
                                      stepper,
                                  "5 us");
}

// The same bar as fem-1pt: the restart builds the FE side and nodal block of the saved RK
// elements, whose state then loads as it was saved
TEST(Checkpoint, ConvertingFem1ptBarRestartsWithTheSameBits)
{
    expect_restarts_reproduce("conversion_1pt", deck_path("concrete_bar_conversion.yaml"),
                              "--set parts.bar.formulation=fem-1pt --set parts.bar.generator.element_size=5mm "
                              "--set time.end=20us --set parts.bar.conversion.interval=3us",
                              "5 us");
}

// The same bar converting into semi-Lagrangian particles: the restart removes the converted
// elements from the FE block as the run had, then loads the particles' cells, volumes, state and
// activation as they were saved
TEST(Checkpoint, ConvertingIntoSemiLagrangianParticlesRestartsWithTheSameBits)
{
    expect_restarts_reproduce("conversion_sl", deck_path("concrete_bar_conversion.yaml"),
                              "--set parts.bar.formulation=fem-1pt --set parts.bar.transition=~ "
                              "--set parts.bar.kinematics=semi-lagrangian --set parts.bar.generator.element_size=5mm "
                              "--set time.end=40us --set parts.bar.conversion.interval=3us",
                              "10 us");
}

// RK back to FE: a block sheared and back converts at 173 us and reverts at 298 us; restarts
// from checkpoints before the conversion, while it is RK and after the reversion give the same bits
TEST(Checkpoint, ConversionAndReversionRestartWithTheSameBits)
{
    expect_restarts_reproduce("reversion", deck_path("shear_and_back_reversion.yaml"), "", "60 us");
}

TEST(Checkpoint, RkParticlesOnAMeshAndOnACloudRestartWithTheSameBits)
{
    expect_restarts_reproduce("rkpm_mesh", deck_path("column_wave_rkpm.yaml"),
                              "--set time.end=3us --set time.stepper=central-difference", "1 us");
    expect_restarts_reproduce("rkpm_cloud", deck_path("cylinder_cloud_pressure.yaml"), "--set time.end=3us", "1 us");
}

// Semi-Lagrangian particles: the cells, volumes and face stresses load as they were saved, and
// the neighbour lists, rebuilt at the restart's positions, hold every particle the kernels reach
// (the forces are summed over them in particle order), so the lists' build times do not matter.
// The K&C bar adds the material history.
TEST(Checkpoint, SemiLagrangianParticlesRestartWithTheSameBits)
{
    const std::string sl = " --set parts.{}.formulation=rkpm --set parts.{}.kinematics=semi-lagrangian"
                           " --set 'parts.{}.nodal_integration={scheme: snni}'";
    auto for_part = [&](const std::string& part)
    {
        std::string s = sl;
        for (std::size_t at; (at = s.find("{}")) != std::string::npos;)
            s.replace(at, 2, part);
        return s;
    };
    expect_restarts_reproduce("sl_column", deck_path("column_wave_rkpm.yaml"),
                              "--set time.end=3us --set time.stepper=central-difference" + for_part("column"), "1 us");
    // reference resets every 4 steps: the tables of the saved reference are built again
    expect_restarts_reproduce("sl_reset", deck_path("column_wave_rkpm.yaml"),
                              "--set time.end=3us --set time.stepper=central-difference" + for_part("column") +
                                  " --set 'parts.column.semi_lagrangian={reset_interval: 4}'",
                              "1 us");
    // SD-SNNI: eight sub-cell stresses per particle
    expect_restarts_reproduce("sl_sd_snni", deck_path("column_wave_rkpm.yaml"),
                              "--set time.end=3us --set time.stepper=central-difference" + for_part("column") +
                                  " --set 'parts.column.nodal_integration={scheme: sd-snni}'",
                              "1 us");
    expect_restarts_reproduce("sl_sd_snni_reset", deck_path("column_wave_rkpm.yaml"),
                              "--set time.end=3us --set time.stepper=central-difference" + for_part("column") +
                                  " --set 'parts.column.nodal_integration={scheme: sd-snni}'"
                                  " --set 'parts.column.semi_lagrangian={reset_interval: 4}'",
                              "1 us");
    expect_restarts_reproduce("sl_kcc", deck_path("concrete_bar_kcc.yaml"),
                              "--set time.end=12us --set parts.bar.generator.size=[10mm,10mm,60mm]" + for_part("bar"),
                              "4 us");
}

// Refinement: particles split as the column wave's front passes 100 MPa near the driven end,
// before and after the checkpoints (and, behind a pulse, merge back); the restart loads the
// particles' reference positions, masses, cells, supports, levels and families as saved, and the
// children's conditions (the column's lateral hold, inherited) are made again from the families
TEST(Checkpoint, RefiningParticlesRestartWithTheSameBits)
{
    expect_restarts_reproduce("sl_refinement", deck_path("column_wave_rkpm.yaml"),
                              "--set time.end=4us --set time.stepper=central-difference"
                              " --set parts.column.formulation=rkpm --set parts.column.kinematics=semi-lagrangian"
                              " --set 'parts.column.nodal_integration={scheme: snni}'"
                              " --set 'parts.column.refinement={pressure: 100 MPa, max_new_particles: 7000, region: "
                              "[{select: {type: box, min: [-1 mm, -1 mm, 2 mm], max: [5 mm, 5 mm, 30 mm]}}]}'",
                              "1 us");
    // and merging back behind a 1 us pulse: restarts before, among and after the merges (the
    // families that are left, and the pool's particles given back)
    expect_restarts_reproduce("sl_coarsening", deck_path("column_wave_rkpm.yaml"),
                              "--set time.end=8us --set time.stepper=central-difference"
                              " --set parts.column.generator.size=[4mm,4mm,40mm]"
                              " --set parts.column.formulation=rkpm --set parts.column.kinematics=semi-lagrangian"
                              " --set 'parts.column.nodal_integration={scheme: snni}'"
                              " --set 'boundary_conditions.1.velocity={z: {curve: [[0, 10 m/s], [1 us, 10 m/s], "
                              "[1.5 us, 0], [1 s, 0]]}}'"
                              " --set 'parts.column.refinement={pressure: 100 MPa, coarsen_fraction: 0.25, "
                              "max_new_particles: 3500, region: [{select: {type: box, min: [-1 mm, -1 mm, 5 mm], max: "
                              "[5 mm, 5 mm, 25 mm]}}]}'",
                              "2 us");
}

// Kernel contact between two semi-Lagrangian RK bars, restarted while they are in contact: its
// pairs are found again at the restart's positions and summed in particle order, so only the
// step bound of the last evaluation is state (and its counts, for the histories)
TEST(Checkpoint, KernelContactRestartsWithTheSameBits)
{
    expect_restarts_reproduce("kernel_contact", deck_path("rk_bars_kernel_contact.yaml"), "--set time.end=9us", "3 us");
}

// A projectile into an eroding K&C block: penalty contact (search lists, spring offsets, the soft
// penalty's step) and elements eroding throughout; the checkpoint at 40 us falls on a step whose
// erosion restarted the stepper, so ARKODE's first evaluation after the restart is a real one.
TEST(Checkpoint, ErodingContactImpactRestartsWithTheSameBits)
{
    expect_restarts_reproduce("impact_arkode-cd", deck_path("fsp_impact.yaml"),
                              "--set time.end=45us --set time.stepper=arkode-cd", "20 us");
    expect_restarts_reproduce("impact_central-difference", deck_path("fsp_impact.yaml"),
                              "--set time.end=25us --set time.stepper=central-difference", "10 us");
    expect_restarts_reproduce(
        "impact_mortar", deck_path("fsp_impact.yaml"),
        "--set time.end=25us --set time.stepper=central-difference --set contacts.0.formulation=mortar", "10 us");
}

TEST(Checkpoint, RestartContinuesPastTheEndWithUntil)
{
    // a run that ended (its checkpoint at the end) goes on to a later time: the frames and
    // history rows before the checkpoint stay, new ones follow
    const fs::path u = fs::temp_directory_path() / "rkfem_ckpt_until";
    fs::remove_all(u);
    ASSERT_EQ(run("run " + deck_path("bar_erosion.yaml") + " --out " + u.string() +
                  " --quiet --set time.end=4us --checkpoint-interval '10 us'")
                  .code,
              0);
    const Frames before = read_frames(u);
    const Result r = run("restart " + u.string() + " --quiet --until '6 us'");
    ASSERT_EQ(r.code, 0) << r.output;
    const Frames after = read_frames(u);
    ASSERT_EQ(before.times.size(), 5u); // 0 .. 4 us
    ASSERT_EQ(after.times.size(), 7u);  // .. 6 us
    for (std::size_t f = 0; f < before.data.size(); ++f)
        EXPECT_EQ(after.data[f], before.data[f]) << "frame " << f;
    EXPECT_DOUBLE_EQ(after.times.back(), 6e-6);
    EXPECT_NE(summary_without_clocks(u).find("\"end_time\": 6e-06"), std::string::npos) << summary_without_clocks(u);
}

TEST(Checkpoint, WhatCannotBeRestartedIsRefusedWithOneLine)
{
    const fs::path u = fs::temp_directory_path() / "rkfem_ckpt_errors";
    fs::remove_all(u);
    fs::create_directories(u);
    auto expect_refused = [](const std::string& args, const std::string& needle)
    {
        const Result r = run(args);
        EXPECT_EQ(r.code, 2) << args << "\n" << r.output;
        EXPECT_NE(r.output.find(needle), std::string::npos) << args << "\n" << r.output;
        EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    };
    expect_refused("restart " + u.string(), "no checkpoint");
    std::ofstream(u / "checkpoint.h5") << "not an HDF5 file";
    expect_refused("restart " + u.string(), "cannot open checkpoint");
    expect_refused("run " + deck_path("bar_erosion.yaml") + " --out " + u.string() + " --checkpoint-interval 2m",
                   "expected a time");
    expect_refused("run " + deck_path("bar_erosion.yaml") + " --out " + u.string() + " --checkpoint-interval -1s",
                   "expected a positive, finite time");
    expect_refused("restart " + u.string() + " --set time.end=1s", "takes no --set");
    // a checkpoint at the end of a run, restarted to an earlier time
    const fs::path d = fs::temp_directory_path() / "rkfem_ckpt_done";
    fs::remove_all(d);
    ASSERT_EQ(run("run " + deck_path("bar_erosion.yaml") + " --out " + d.string() +
                  " --quiet --set time.end=2us --checkpoint-interval '10 us'")
                  .code,
              0);
    expect_refused("restart " + d.string() + " --until '1 us'", "expected --until past the checkpoint");
    // a checkpoint that is a link to itself is no checkpoint (was exit 1, "filesystem error: Too
    // many levels of symbolic links"); a results.h5 that is damaged or gone leaves the checkpoint
    // without its run (was exit 1, "cannot continue")
    const fs::path loop = fs::temp_directory_path() / "rkfem_ckpt_loop";
    fs::remove_all(loop);
    fs::copy(d, loop, fs::copy_options::recursive);
    fs::remove(loop / "checkpoint.h5");
    fs::create_symlink("checkpoint.h5", loop / "checkpoint.h5");
    expect_refused("restart " + loop.string() + " --from " + (loop / "checkpoint.h5").string(), "no checkpoint");
    fs::remove_all(loop);
    fs::copy(d, loop, fs::copy_options::recursive);
    fs::resize_file(loop / "results.h5", fs::file_size(loop / "results.h5") - 8);
    expect_refused("restart " + loop.string() + " --until '20 us'",
                   "the results.h5 beside it to run (none: results.h5 is missing or cannot be read)");
    fs::remove(loop / "results.h5");
    expect_refused("restart " + loop.string() + " --until '20 us'", "results.h5 is missing or cannot be read");
}

// SIGINT and SIGTERM: the run finishes the step it is in, writes that state (a frame, the history
// row, a checkpoint when checkpoints are on), marks summary.json interrupted, says so on one line
// and exits 5; restarting from that checkpoint gives, at every time the uninterrupted run wrote,
// the same bits (the interrupted run's own frame and row at the signal's time stay beside them).
TEST(Checkpoint, ASignalStopsTheRunAtAStepAndItsStateRestarts)
{
    // the column wave at 2 mm, run to 1.5 ms (about 4 s)
    const std::string deck = deck_path("column_wave.yaml");
    const std::string sets = " --quiet --set output.precision=double --set parts.column.generator.element_size=2mm "
                             "--set time.end=1.5ms --set time.output_interval=0.15ms";
    const fs::path u = fs::temp_directory_path() / "rkfem_signal_whole";
    fs::remove_all(u);
    ASSERT_EQ(run("run " + deck + " --out " + u.string() + sets).code, 0);
    const Frames whole = read_frames(u);
    for (const char* sig : {"INT", "TERM"})
    {
        const fs::path d = fs::temp_directory_path() / (std::string("rkfem_signal_") + sig);
        fs::remove_all(d);
        // the signal arrives once the run has written its first frame (it is stepping then)
        const Result r = rkfem::test::run_shell(
            std::string(RKFEM_EXE) + " run " + deck + " --out " + d.string() + sets +
            " --checkpoint-interval 0.5ms > " + d.string() + ".log 2>&1 & p=$!; for i in $(seq 200); do [ -s " +
            (d / "history.csv").string() + " ] && break; sleep 0.05; done; sleep 0.3; kill -" + sig +
            " $p; wait $p; echo rc=$?; cat " + d.string() + ".log");
        std::printf("SIG%s: %s", sig, r.output.c_str());
        EXPECT_NE(r.output.find("rc=5"), std::string::npos) << r.output;
        EXPECT_NE(r.output.find(std::string("interrupted by SIG") + sig + " at t = "), std::string::npos) << r.output;
        EXPECT_NE(slurp(d / "summary.json").find("\"status\": \"interrupted\""), std::string::npos);
        const Frames cut = read_frames(d);
        ASSERT_FALSE(cut.times.empty());
        ASSERT_TRUE(fs::exists(d / "checkpoint.h5"));
        EXPECT_LT(cut.times.back(), 1.5e-3) << "the signal came after the end";
        const Result rs = run("restart " + d.string() + " --quiet");
        ASSERT_EQ(rs.code, 0) << rs.output;
        const Frames again = read_frames(d);
        std::size_t common = 0, differ = 0;
        for (std::size_t f = 0; f < again.times.size(); ++f)
            for (std::size_t g = 0; g < whole.times.size(); ++g)
                if (again.times[f] == whole.times[g])
                {
                    ++common;
                    differ += again.data[f] != whole.data[g];
                }
        std::printf(
            "SIG%s: stopped at t = %.6g s; restarted: %zu frames, %zu at the uninterrupted run's times, %zu differ\n",
            sig, cut.times.back(), again.times.size(), common, differ);
        EXPECT_EQ(common, whole.times.size());
        EXPECT_EQ(differ, 0u);
        EXPECT_LE(again.times.size(), whole.times.size() + 1);
    }
}

// One run owns its directory: a second run (or a restart) on a directory a run is writing in is
// refused before it touches anything (exit 2, one line naming the other process), and the first
// run finishes with a results.h5 that opens, every frame in it.
TEST(Checkpoint, ASecondRunOnTheSameDirectoryIsRefusedBeforeItWrites)
{
    const std::string deck = deck_path("column_wave.yaml");
    const std::string sets = " --quiet --set parts.column.generator.element_size=2mm --set time.end=1.5ms "
                             "--set time.output_interval=0.15ms";
    const fs::path d = fs::temp_directory_path() / "rkfem_two_runs";
    fs::remove_all(d);
    const Result r = rkfem::test::run_shell(
        std::string(RKFEM_EXE) + " run " + deck + " --out " + d.string() + sets + " --checkpoint-interval 0.1ms > " +
        d.string() + ".a.log 2>&1 & p=$!; for i in $(seq 200); do [ -s " + (d / "checkpoint.h5").string() +
        " ] && break; sleep 0.05; done; " + RKFEM_EXE + " run " + deck + " --out " + d.string() + sets +
        " 2>&1; echo second=$?; " + RKFEM_EXE + " restart " + d.string() +
        " 2>&1; echo restart=$?; wait $p; echo first=$?");
    std::printf("%s", r.output.c_str());
    EXPECT_NE(r.output.find("second=2"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("another rkfem (pid "), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("restart=2"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("rkfem: restart " + d.string() + ": another rkfem (pid "), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("first=0"), std::string::npos) << r.output;
    EXPECT_EQ(read_frames(d).times.size(), 11u);
}

// A restart refuses a checkpoint that another run wrote: run A with checkpoints, then run B
// without into the same directory (A's checkpoint.h5 stays), then restart: exit 2, one line
// naming both runs, and B's results.h5 and history untouched (they spliced A's state onto B's
// mesh before, exit 0).
TEST(Checkpoint, ARestartRefusesTheCheckpointOfAnotherRun)
{
    const fs::path d = fs::temp_directory_path() / "rkfem_stale_checkpoint";
    fs::remove_all(d);
    ASSERT_EQ(
        run("run " + deck_path("column_wave.yaml") + " --out " + d.string() +
            " --quiet --set parts.column.generator.element_size=2mm --set time.end=40us --checkpoint-interval 20us")
            .code,
        0);
    ASSERT_TRUE(fs::exists(d / "checkpoint.h5"));
    ASSERT_EQ(run("run " + deck_path("concrete_bar_kcc.yaml") + " --out " + d.string() + " --quiet").code, 0);
    const std::string results = slurp(d / "results.h5"), history = slurp(d / "history.csv");
    const Result r = run("restart " + d.string() + " --until 80us");
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_NE(r.output.find("the checkpoint belongs to run "), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_EQ(slurp(d / "results.h5"), results);
    EXPECT_EQ(slurp(d / "history.csv"), history);
}

// A run stopped between the renames of a rotation (--checkpoint-keep above 1) has no
// checkpoint.h5: the newest whole checkpoint is checkpoint.new.h5 (renamed there only once
// whole), the one before checkpoint.1.h5. `restart DIR` takes the newest there is; it answered
// "no checkpoint" before.
TEST(Checkpoint, ARestartFindsTheNewestWholeCheckpointOfAnInterruptedRotation)
{
    const fs::path d = fs::temp_directory_path() / "rkfem_rotation";
    fs::remove_all(d);
    ASSERT_EQ(
        run("run " + deck_path("column_wave.yaml") + " --out " + d.string() +
            " --quiet --set parts.column.generator.element_size=2mm --set time.end=40us --checkpoint-interval 10us "
            "--checkpoint-keep 3")
            .code,
        0);
    fs::rename(d / "checkpoint.h5", d / "checkpoint.new.h5"); // the state a kill between the renames leaves
    const Result a = run("restart " + d.string() + " --until 50us --quiet");
    EXPECT_EQ(a.code, 0) << a.output;
    EXPECT_NE(slurp(d / "summary.json").find("\"end_time\": 5e-05"), std::string::npos) << slurp(d / "summary.json");
    fs::remove(d / "checkpoint.h5");
    fs::remove(d / "checkpoint.new.h5");
    const Result b = run("restart " + d.string() + " --until 60us --quiet"); // checkpoint.1.h5 is left
    EXPECT_EQ(b.code, 0) << b.output;
}

// An output that cannot be written where it goes (a directory in the way) is refused before the
// run starts: exit 2, one line naming the file, nothing written (summary.json and history.csv
// were skipped with exit 0, results.xdmf gave an internal error after the whole run); a study
// whose table.csv cannot be written likewise (it exited 0).
TEST(Checkpoint, AnOutputThatCannotBeWrittenIsRefusedBeforeTheRun)
{
    const std::string deck = deck_path("column_wave.yaml");
    for (const char* name : {"summary.json", "history.csv", "results.xdmf", "results.h5"})
    {
        const fs::path d = fs::temp_directory_path() / "rkfem_unwritable";
        fs::remove_all(d);
        fs::create_directories(d / name);
        const Result r = run("run " + deck + " --out " + d.string() +
                             " --quiet --set parts.column.generator.element_size=2mm --set time.end=4us");
        EXPECT_EQ(r.code, 2) << name << ": " << r.output;
        EXPECT_NE(r.output.find((d / name).string() + " exists and is not a regular file"), std::string::npos)
            << r.output;
        EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
        EXPECT_EQ(std::string(name) == "results.h5", fs::exists(d / "results.h5")) << name;
        EXPECT_FALSE(fs::exists(d / "history.csv") && std::string(name) != "history.csv") << name;
    }
    const fs::path s = fs::temp_directory_path() / "rkfem_unwritable_study";
    fs::remove_all(s);
    fs::create_directories(s / "table.csv");
    const Result r = run("study " + (fs::path(RKFEM_SOURCE_DIR) / "studies/tables/table3_p6.yaml").string() +
                         " --out " + s.string() + " --only 1.5 --quiet");
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_NE(r.output.find("table.csv exists and is not a regular file"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(s / "cases")) << "a case ran";
}

// A full disk (a 2 MB tmpfs, where the machine lets the test mount one): the run stops at the
// first output that does not fit with exit 1 and one line naming results.h5 and the frame,
// results.h5 opens with the frames before it, results.xdmf indexes them, and the process ends
// cleanly (it printed 2,800 lines of HDF5 diagnostics, then 'done', and crashed in HDF5's
// clean-up at exit, rc 139); a checkpoint that does not fit is said likewise.
TEST(Checkpoint, AFullDiskStopsTheRunWithOneLineAndKeepsTheFramesBefore)
{
    const fs::path mnt = fs::temp_directory_path() / "rkfem_full_disk";
    fs::create_directories(mnt);
    if (rkfem::test::run_shell("mount -t tmpfs -o size=2m tmpfs " + mnt.string() + " 2>&1").code != 0)
        GTEST_SKIP() << "cannot mount a tmpfs here (not root, or no CAP_SYS_ADMIN): the full-disk test did not run";
    struct Unmount
    {
        fs::path p;
        ~Unmount() { rkfem::test::run_shell("umount " + p.string()); }
    } unmount{mnt};
    const std::string deck = deck_path("column_wave.yaml");
    const Result r = run(
        "run " + deck + " --out " + (mnt / "a").string() +
        " --quiet --set parts.column.generator.element_size=4mm --set time.end=80us --set time.output_interval=2us");
    std::printf("%s", r.output.c_str());
    EXPECT_EQ(r.code, 1) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_NE(r.output.find("into " + (mnt / "a").string() + "/results.h5: "), std::string::npos) << r.output;
    const Frames f = read_frames(mnt / "a");
    const std::string xdmf = slurp(mnt / "a" / "results.xdmf");
    std::size_t grids = 0;
    for (std::size_t p = xdmf.find("<Time Value="); p != std::string::npos; p = xdmf.find("<Time Value=", p + 1))
        ++grids;
    std::printf("full disk: results.h5 holds %zu frames, results.xdmf indexes %zu\n", f.times.size(), grids);
    EXPECT_GE(grids, 2u);
    EXPECT_LE(grids, f.times.size()); // every indexed frame is there
    EXPECT_NE(r.output.find("results.xdmf indexes the " + std::to_string(grids) + " frame(s)"), std::string::npos);
    fs::remove_all(mnt / "a");
    const Result c =
        run("run " + deck + " --out " + (mnt / "b").string() +
            " --quiet --set parts.column.generator.element_size=4mm --set time.end=40us --checkpoint-interval 2us");
    std::printf("%s", c.output.c_str());
    EXPECT_EQ(c.code, 1) << c.output;
    EXPECT_EQ(std::count(c.output.begin(), c.output.end(), '\n'), 1) << c.output;
}

// Every checkpoint entry carries a Fletcher-32 checksum: one byte changed inside the data of an
// entry (the step count, the history, a block's stresses) makes the restart refuse the
// checkpoint, exit 2 with one line; before, 8 of 21 such edits restarted with exit 0 and other
// results.
TEST(Checkpoint, AChangedByteInACheckpointIsRefused)
{
    const fs::path u = fs::temp_directory_path() / "rkfem_ckpt_flip";
    fs::remove_all(u);
    ASSERT_EQ(
        run("run " + deck_path("column_wave.yaml") + " --out " + u.string() +
            " --quiet --set parts.column.generator.element_size=4mm --set time.end=20us --checkpoint-interval 10us "
            "--checkpoint-keep 3")
            .code,
        0);
    for (const char* entry : {"run.step", "run.history", "block.0.stress"})
    {
        const fs::path d = fs::temp_directory_path() / "rkfem_ckpt_flip_copy";
        fs::remove_all(d);
        fs::copy(u, d);
        // the entry's first chunk's address in the file
        haddr_t addr = HADDR_UNDEF;
        hsize_t size = 0;
        {
            const hid_t f = H5Fopen((d / "checkpoint.1.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
            ASSERT_GE(f, 0);
            const hid_t set = H5Dopen2(f, (std::string("state/") + entry).c_str(), H5P_DEFAULT);
            ASSERT_GE(set, 0) << entry;
            const hid_t space = H5Dget_space(set);
            hsize_t offset[1] = {0};
            unsigned mask = 0;
            ASSERT_GE(H5Dget_chunk_info(set, space, 0, offset, &mask, &addr, &size), 0) << entry;
            H5Sclose(space);
            H5Dclose(set);
            H5Fclose(f);
        }
        ASSERT_NE(addr, HADDR_UNDEF);
        {
            std::fstream io(d / "checkpoint.1.h5", std::ios::in | std::ios::out | std::ios::binary);
            io.seekg(static_cast<std::streamoff>(addr + size / 2));
            char c = 0;
            io.read(&c, 1);
            c = static_cast<char>(c ^ 0x5a);
            io.seekp(static_cast<std::streamoff>(addr + size / 2));
            io.write(&c, 1);
        }
        const Result r = run("restart " + d.string() + " --from " + (d / "checkpoint.1.h5").string() + " --quiet");
        EXPECT_EQ(r.code, 2) << entry << ": " << r.output;
        EXPECT_NE(r.output.find("its checksum does not match"), std::string::npos) << entry << ": " << r.output;
        EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    }
}

// The data files a deck reads (keyword meshes and the files they *INCLUDE, point files) are hashed
// into the checkpoint and resolved from the deck's folder as the run found it: a restart from
// another working folder finds them (it could not), and one whose mesh file or included file
// changed since the run is refused, exit 2 with one line naming the file (a mesh whose coordinates
// moved restarted silently with other results; until 2026-12-07 so did one whose included nodes
// moved).
TEST(Checkpoint, ARestartReadsTheDataFilesTheRunReadOrRefuses)
{
    const fs::path d = fs::temp_directory_path() / "rkfem_ckpt_kmesh";
    fs::remove_all(d);
    fs::create_directories(d / "model");
    auto write_mesh = [&](double dz, const char* comment = "")
    {
        // the nodes in a file the mesh includes
        std::ofstream nodes(d / "model" / "nodes.k");
        nodes << "*KEYWORD\n*NODE\n";
        int id = 1;
        for (int z = 0; z < 3; ++z)
            for (int y = 0; y < 3; ++y)
                for (int x = 0; x < 3; ++x)
                    nodes << id++ << "," << x << "," << y << "," << z + (z == 2 ? dz : 0.0) << "\n";
        nodes << "*END\n";
        std::ofstream k(d / "model" / "mesh.k");
        k << "*KEYWORD\n" << comment << "*INCLUDE\nnodes.k\n";
        k << "*ELEMENT_SOLID\n";
        int e = 1;
        auto n = [](int x, int y, int z) { return 1 + x + 3 * y + 9 * z; };
        for (int z = 0; z < 2; ++z)
            for (int y = 0; y < 2; ++y)
                for (int x = 0; x < 2; ++x)
                    k << e++ << ",1," << n(x, y, z) << "," << n(x + 1, y, z) << "," << n(x + 1, y + 1, z) << ","
                      << n(x, y + 1, z) << "," << n(x, y, z + 1) << "," << n(x + 1, y, z + 1) << ","
                      << n(x + 1, y + 1, z + 1) << "," << n(x, y + 1, z + 1) << "\n";
        k << "*END\n";
    };
    write_mesh(0.0);
    std::ofstream(d / "model" / "deck.yaml") << R"(title: keyword block
time: {end: 2 us, output_interval: 0.5 us}
parts:
  blk:
    generator: {type: keyword, file: mesh.k, unit: mm}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: fem-1pt
node_sets:
  bot: {part: blk, select: {type: plane, point: [0, 0, 0], normal: [0, 0, 1], tolerance: 1e-6}}
loads:
  - {type: nodal_force, node_set: bot, force: {z: 1 kN}, total: true}
)";
    // run from the model's folder with a relative deck path, restart from elsewhere
    const Result r = rkfem::test::run_shell("cd " + (d / "model").string() + " && " + RKFEM_EXE +
                                            " run deck.yaml --out ../out --quiet --checkpoint-interval 0.5us "
                                            "--checkpoint-keep 5 2>&1");
    ASSERT_EQ(r.code, 0) << r.output;
    fs::copy(d / "out", d / "out2");
    fs::copy(d / "out", d / "out3");
    const Result a = rkfem::test::run_shell("cd / && " + std::string(RKFEM_EXE) + " restart " + (d / "out").string() +
                                            " --from " + (d / "out" / "checkpoint.2.h5").string() + " --quiet 2>&1");
    EXPECT_EQ(a.code, 0) << a.output;
    write_mesh(0.01); // the top nodes 1 % higher, in the included file
    const Result b = run("restart " + (d / "out2").string() + " --from " + (d / "out2" / "checkpoint.2.h5").string());
    EXPECT_EQ(b.code, 2) << b.output;
    EXPECT_NE(b.output.find("the data file " + (d / "model" / "nodes.k").string() + " is not the one the run read"),
              std::string::npos)
        << b.output;
    EXPECT_EQ(std::count(b.output.begin(), b.output.end(), '\n'), 1) << b.output;
    write_mesh(0.0, "$ a comment\n"); // the nodes as they were, the including file changed
    const Result c = run("restart " + (d / "out3").string() + " --from " + (d / "out3" / "checkpoint.2.h5").string());
    EXPECT_EQ(c.code, 2) << c.output;
    EXPECT_NE(c.output.find("the data file " + (d / "model" / "mesh.k").string() + " is not the one the run read"),
              std::string::npos)
        << c.output;
}
