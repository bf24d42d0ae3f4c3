// `rkfem study`: the study driver through the real executable (cases reproduce their own runs
// exactly, reruns skip, a changed override reruns one case, a failing case is recorded and the
// study goes on, bad study files get one located line) and every metric extractor on a history
// whose values are known.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "../executable.hpp"
#include "rkfem/analysis/timoshenko_beam.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/run/study.hpp"

namespace fs = std::filesystem;
using rkfem::real_t;
using rkfem::test::run;

namespace
{
const std::string column_deck = std::string(RKFEM_SOURCE_DIR) + "/studies/decks/column_wave.yaml";

fs::path scratch(const std::string& name)
{
    const fs::path d = fs::temp_directory_path() / "rkfem_test_study" / name;
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

std::string write(const fs::path& p, const std::string& text)
{
    std::ofstream(p) << text;
    return p.string();
}

/// The column deck at CI size (2 x 2 x 200 mm) with element size `h`.
std::string column_study(const std::string& h1, const std::string& h2, bool with_failing_case)
{
    std::string s = "title: column study\ndeck: " + column_deck + R"(
metrics:
  plateau: {kind: at, column: quarter_szz, time: 15 us, unit: MPa}
  peak_time: {kind: time_of_min, column: quarter_szz, unit: us}
  steps: {kind: summary, key: steps}
  dt: {kind: summary, key: dt_first, unit: us}
  total: {kind: summary, key: energy.kinetic}
cases:
)";
    if (with_failing_case)
        s += "  - {name: bad, set: {parts.column.material.nu: 0.7}}\n";
    s += "  - name: a\n    set: {parts.column.generator.size: \"[2 mm, 2 mm, 200 mm]\", "
         "parts.column.generator.element_size: " +
         h1 + "}\n    published: {plateau: {value: -459.7 MPa, source: \"rho c v\"}}\n";
    s += "  - name: b\n    set: [\"parts.column.generator.size=[2 mm, 2 mm, 200 mm]\", "
         "\"parts.column.generator.element_size=" +
         h2 + "\"]\n    published: {plateau: {value: -459.7, source: \"rho c v\"}}\n";
    return s;
}

real_t x_or_nan(const std::string& s)
{
    return s.empty() ? std::nan("") : std::stod(s);
}

YAML::Node summary_of(const fs::path& dir)
{
    return YAML::LoadFile((dir / "summary.json").string());
}

/// table.csv's "ours" for case and metric.
real_t table_value(const fs::path& out, const std::string& c, const std::string& m)
{
    std::ifstream in(out / "table.csv");
    std::string line;
    while (std::getline(in, line))
        if (line.rfind(c + "," + m + ",", 0) == 0)
        {
            std::stringstream ss(line);
            std::string f[4];
            for (auto& x : f)
                std::getline(ss, x, ',');
            return x_or_nan(f[3]);
        }
    return std::nan("");
}
} // namespace

TEST(Study, CasesReproduceTheirOwnRunsRerunsSkipAndAChangedOverrideRerunsOne)
{
    const fs::path d = scratch("reproduce");
    const std::string study = write(d / "study.yaml", column_study("1 mm", "0.5 mm", false));
    const auto r1 = run("study " + study + " --out " + (d / "out").string() + " --quiet");
    ASSERT_EQ(r1.code, 0) << r1.output;
    // each case against `rkfem run` of the same deck and overrides: the same numbers, exactly
    const auto direct = run("run " + column_deck + " --out " + (d / "direct").string() +
                            " --quiet --set 'parts.column.generator.size=[2 mm, 2 mm, 200 mm]' --set "
                            "parts.column.generator.element_size=0.5mm");
    ASSERT_EQ(direct.code, 0) << direct.output;
    const YAML::Node a = summary_of(d / "direct"), b = summary_of(d / "out/cases/b");
    EXPECT_EQ(a["deck_hash"].as<std::string>(), b["deck_hash"].as<std::string>());
    for (const char* key : {"steps", "end_time", "dt_first", "balance_error", "max_plastic_strain"})
        EXPECT_EQ(a[key].as<std::string>(), b[key].as<std::string>()) << key;
    EXPECT_EQ(a["energy"]["kinetic"].as<std::string>(), b["energy"]["kinetic"].as<std::string>());
    EXPECT_EQ(table_value(d / "out", "b", "steps"), a["steps"].as<real_t>());
    EXPECT_EQ(table_value(d / "out", "b", "total"), a["energy"]["kinetic"].as<real_t>());
    EXPECT_NEAR(table_value(d / "out", "b", "dt"), 1e6 * a["dt_first"].as<real_t>(), 1e-9);
    // the plateau is the analytic -rho c_p v = -459.7 MPa (benchmark-problems.md), within 0.2%
    for (const char* c : {"a", "b"})
        EXPECT_NEAR(table_value(d / "out", c, "plateau"), -459.7, 0.002 * 459.7) << c;
    // a rerun runs nothing: both summaries untouched
    const auto t_a = fs::last_write_time(d / "out/cases/a/summary.json");
    const auto t_b = fs::last_write_time(d / "out/cases/b/summary.json");
    const auto r2 = run("study " + study + " --out " + (d / "out").string());
    ASSERT_EQ(r2.code, 0) << r2.output;
    EXPECT_NE(r2.output.find("[1/2] a: reused"), std::string::npos) << r2.output;
    EXPECT_NE(r2.output.find("[2/2] b: reused"), std::string::npos) << r2.output;
    EXPECT_EQ(fs::last_write_time(d / "out/cases/a/summary.json"), t_a);
    EXPECT_EQ(fs::last_write_time(d / "out/cases/b/summary.json"), t_b);
    // the same table again
    EXPECT_EQ(table_value(d / "out", "b", "steps"), a["steps"].as<real_t>());
    // one changed override reruns that case only
    write(d / "study.yaml", column_study("1 mm", "0.4 mm", false));
    const auto r3 = run("study " + study + " --out " + (d / "out").string());
    ASSERT_EQ(r3.code, 0) << r3.output;
    EXPECT_NE(r3.output.find("[1/2] a: reused"), std::string::npos) << r3.output;
    EXPECT_NE(r3.output.find("[2/2] b: running"), std::string::npos) << r3.output;
    EXPECT_EQ(fs::last_write_time(d / "out/cases/a/summary.json"), t_a);
    EXPECT_GT(table_value(d / "out", "b", "steps"), a["steps"].as<real_t>());
    // table.md sets published beside ours; study.h5 is written
    std::ifstream md(d / "out/table.md");
    const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("(-459.7[1], "), std::string::npos) << text;
    EXPECT_NE(text.find("[1] a / plateau: rho c v"), std::string::npos) << text;
    EXPECT_TRUE(fs::file_size(d / "out/study.h5") > 0);
}

// A completed case is reused only when it was run by this build: summary.json carries the
// executable's hash (`build`), and a case whose summary names another build, or none (written
// before builds were recorded), runs again, so that a study rerun after a rebuild does not
// tabulate the old solver's numbers.
TEST(Study, ACaseRunByAnotherBuildRunsAgain)
{
    const fs::path d = scratch("build");
    const std::string study = write(d / "study.yaml", column_study("1 mm", "1 mm", false));
    const auto r1 = run("study " + study + " --out " + (d / "out").string() + " --quiet");
    ASSERT_EQ(r1.code, 0) << r1.output;
    const std::string build = summary_of(d / "out/cases/a")["build"].as<std::string>();
    ASSERT_EQ(build.size(), 16u);
    EXPECT_EQ(build.find_first_not_of("0123456789abcdef"), std::string::npos) << build;
    // the same executable, run directly, records the same build
    const auto direct = run("run " + column_deck + " --out " + (d / "direct").string() +
                            " --quiet --set 'parts.column.generator.size=[2 mm, 2 mm, 200 mm]' --set time.end=1us");
    ASSERT_EQ(direct.code, 0) << direct.output;
    EXPECT_EQ(summary_of(d / "direct")["build"].as<std::string>(), build);
    // a's summary as another build left it, b's as one from before builds were recorded
    auto rewrite = [&](const fs::path& f, const std::string& from, const std::string& to)
    {
        std::ifstream in(f);
        std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        in.close();
        const std::size_t at = text.find(from);
        ASSERT_NE(at, std::string::npos) << f;
        text.replace(at, from.size(), to);
        std::ofstream(f) << text;
    };
    rewrite(d / "out/cases/a/summary.json", "\"build\": \"" + build + "\"", "\"build\": \"0123456789abcdef\"");
    rewrite(d / "out/cases/b/summary.json", "  \"build\": \"" + build + "\",\n", "");
    const auto r2 = run("study " + study + " --out " + (d / "out").string());
    ASSERT_EQ(r2.code, 0) << r2.output;
    EXPECT_NE(r2.output.find("[1/2] a: running"), std::string::npos) << r2.output;
    EXPECT_NE(r2.output.find("[2/2] b: running"), std::string::npos) << r2.output;
    EXPECT_EQ(summary_of(d / "out/cases/a")["build"].as<std::string>(), build);
    EXPECT_EQ(summary_of(d / "out/cases/b")["build"].as<std::string>(), build);
    // and now, by this build, both are reused
    const auto r3 = run("study " + study + " --out " + (d / "out").string());
    ASSERT_EQ(r3.code, 0) << r3.output;
    EXPECT_NE(r3.output.find("[1/2] a: reused"), std::string::npos) << r3.output;
    EXPECT_NE(r3.output.find("[2/2] b: reused"), std::string::npos) << r3.output;
}

// A case whose history.csv was cut short or deleted (its summary.json intact) runs again: its
// metrics came from the rows left (a peak of 0 against the run's, marked reused), and a
// deleted history marked the case failed without running it.
TEST(Study, ACaseWhoseHistoryIsNotWholeRunsAgain)
{
    const fs::path d = scratch("history");
    const std::string study = write(d / "study.yaml", column_study("1 mm", "1 mm", false));
    ASSERT_EQ(run("study " + study + " --out " + (d / "out").string() + " --quiet").code, 0);
    const double steps = table_value(d / "out", "a", "steps");
    const fs::path h = d / "out/cases/a/history.csv";
    fs::resize_file(h, fs::file_size(h) / 2);
    const auto r1 = run("study " + study + " --out " + (d / "out").string());
    ASSERT_EQ(r1.code, 0) << r1.output;
    EXPECT_NE(r1.output.find("[1/2] a: running"), std::string::npos) << r1.output;
    EXPECT_NE(r1.output.find("[2/2] b: reused"), std::string::npos) << r1.output;
    EXPECT_EQ(table_value(d / "out", "a", "steps"), steps);
    fs::remove(h);
    const auto r2 = run("study " + study + " --out " + (d / "out").string());
    ASSERT_EQ(r2.code, 0) << r2.output;
    EXPECT_NE(r2.output.find("[1/2] a: running"), std::string::npos) << r2.output;
    EXPECT_TRUE(fs::exists(h));
}

TEST(Study, OnlyRunsAndTabulatesTheNamedCases)
{
    const fs::path d = scratch("only");
    const std::string study = write(d / "study.yaml", column_study("1 mm", "0.5 mm", true));
    const auto r = run("study " + study + " --out " + (d / "out").string() + " --only b");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("[1/1] b: completed"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(d / "out/cases/a"));
    EXPECT_FALSE(std::isnan(table_value(d / "out", "b", "steps")));
    EXPECT_TRUE(std::isnan(table_value(d / "out", "a", "steps"))); // not in the table
}

TEST(Study, ProbePeakAndItsTimeOnTheCantileverMatchTheTimoshenkoModalSolution)
{
    // studies/decks/cantilever.yaml (1000 x 100 x 100 mm steel, 10 kN step at the tip) on 80 x 8 x 8
    // hexes (the deck's 40 x 4 x 4 peaks 4.9 % low, the 1-point hex's bending error at four
    // elements through the depth; see test_p3_cantilever): the extractors min and time_of_min on
    // the tip probe against the beam's modal solution
    const fs::path d = scratch("cantilever");
    const std::string study =
        write(d / "study.yaml", "deck: " + std::string(RKFEM_SOURCE_DIR) + R"(/studies/decks/cantilever.yaml
metrics:
  peak: {kind: min, column: tip_uz, unit: mm}
  peak_time: {kind: time_of_min, column: tip_uz, unit: ms}
  reaction_peak: {kind: max, column: reaction_root_z, unit: kN}
cases:
  - {name: beam, set: {time.end: 8 ms, parts.beam.generator.divisions: "[80, 8, 8]"}}
)");
    const auto r = run("study " + study + " --out " + (d / "out").string() + " --quiet");
    ASSERT_EQ(r.code, 0) << r.output;
    rkfem::TimoshenkoBeam b;
    b.E = 200e9;
    b.nu = 0.3;
    b.rho = 7850;
    b.width = b.depth = 0.1;
    b.length = 1.0;
    // the tip force as a load over the beam model's last element (200 elements: 5 mm)
    const rkfem::StepResponse ref = rkfem::step_response(b, 10e3 / 0.005, 0.995, 0.008);
    const real_t peak = table_value(d / "out", "beam", "peak"), t_peak = table_value(d / "out", "beam", "peak_time");
    EXPECT_NEAR(-peak, 1e3 * ref.peak_tip, 0.03 * 1e3 * ref.peak_tip) << "Timoshenko " << 1e3 * ref.peak_tip << " mm";
    EXPECT_NEAR(t_peak, 1e3 * ref.peak_time, 0.03 * 1e3 * ref.peak_time)
        << "Timoshenko " << 1e3 * ref.peak_time << " ms";
    // the root's reaction peaks above the 10 kN load (dynamic overshoot of the step)
    EXPECT_GT(table_value(d / "out", "beam", "reaction_peak"), 10.0);
}

TEST(Study, TableRowsMetricsTransposesTableMd)
{
    const fs::path d = scratch("transposed");
    std::string text = column_study("1 mm", "1 mm", false);
    text.insert(text.find("metrics:"), "table_rows: metrics\n");
    const std::string study = write(d / "study.yaml", text);
    const auto r = run("study " + study + " --out " + (d / "out").string() + " --only a --quiet");
    ASSERT_EQ(r.code, 0) << r.output;
    std::ifstream md(d / "out/table.md");
    const std::string t((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
    EXPECT_NE(t.find("| metric | a |\n|---|---:|\n| status | completed |\n| plateau [MPa] | -459."), std::string::npos)
        << t;
    EXPECT_NE(t.find("(-459.7[1], "), std::string::npos) << t;
}

TEST(Study, AFailingCaseIsRecordedAndTheStudyGoesOn)
{
    const fs::path d = scratch("failing");
    const std::string study = write(d / "study.yaml", column_study("1 mm", "1 mm", true));
    const auto r = run("study " + study + " --out " + (d / "out").string());
    EXPECT_EQ(r.code, 4) << r.output;
    EXPECT_NE(r.output.find("[1/3] bad: failed"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("Poisson's ratio 0.7"), std::string::npos) << r.output;
    EXPECT_NEAR(table_value(d / "out", "a", "plateau"), -459.7, 0.002 * 459.7);
    EXPECT_TRUE(std::isnan(table_value(d / "out", "bad", "plateau")));
    std::ifstream csv(d / "out/table.csv");
    const std::string text((std::istreambuf_iterator<char>(csv)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("bad,plateau,MPa,,,,,failed"), std::string::npos) << text;
    // a rerun runs the failed case again (and reuses the others)
    const auto r2 = run("study " + study + " --out " + (d / "out").string());
    EXPECT_EQ(r2.code, 4);
    EXPECT_NE(r2.output.find("[2/3] a: reused"), std::string::npos) << r2.output;
}

TEST(Study, BadStudyFilesGetOneLocatedLine)
{
    const fs::path d = scratch("bad");
    struct Bad
    {
        std::string text, expect;
    };
    const std::string head = "deck: " + column_deck + "\nmetrics:\n  p: {kind: max, column: quarter_szz, unit: MPa}\n";
    const Bad cases[] = {
        {head + "cases:\n  - {name: a, sett: {x: 1}}\n", ":5: cases.0.sett: unknown key 'sett'; did you mean 'set'?"},
        {head + "cases:\n  - {name: a}\n  - {name: a}\n", ":6: cases.1: case name 'a' given twice"},
        {head + "cases:\n  - {name: a, published: {q: {value: 1, source: x}}}\n",
         ":5: cases.0.published.q: 'q' is not a metric of this study; expected one of p"},
        {head + "cases:\n  - {name: a, published: {p: {value: 3 in, source: x}}}\n", "cases.0.published.p.value: "},
        {head + "cases:\n  - {name: a/b}\n", "cases.0.name: 'a/b' is not a case name"},
        {head + "cases:\n  - {name: a, set: [x]}\n", "cases.0.set.0: is not key.path=value"},
        {"deck: x.yaml\nmetrics:\n  p: {kind: maximum, column: c}\ncases: [{name: a}]\n",
         ":3: metrics.p.kind: 'maximum' is not a valid choice"},
        {"deck: x.yaml\nmetrics:\n  p: {kind: max, column: c, unit: furlongs}\ncases: [{name: a}]\n",
         ":3: metrics.p.unit: 'furlongs' is not a unit"},
        {"deck: x.yaml\nmetrics:\n  p: {kind: summary, key: steps, time: 1 s}\ncases: [{name: a}]\n",
         "metrics.p.time: is not used by kind summary"},
        {"deck: x.yaml\nmetrics:\n  p: {kind: mean, column: c, from: 2 us, to: 1 us}\ncases: [{name: a}]\n",
         ":3: metrics.p.to: is not after from"},
        {"deck: x.yaml\nmetrics:\n  p: {kind: max, column: c, from: 2 us}\ncases: [{name: a}]\n",
         "metrics.p.from: is used by kind mean only"},
        {"deck: x.yaml\nmetrics: {}\ncases: [{name: a}]\n", ":2: metrics: is empty"},
        {"deck: x.yaml\ntable_rows: both\nmetrics:\n  p: {kind: max, column: c}\ncases: [{name: a}]\n",
         ":2: table_rows: 'both' is not a valid choice"},
        {"deck: x.yaml\nmetrics:\n  p: {kind: max, column: c}\n", "cases: missing required key"},
        {"metrics:\n  p: {kind: max, column: c}\ncases: [{name: a}]\n",
         "cases.0.deck: missing, and the study has no deck"},
        {"? [a, b]\n: 1\n", "study.yaml:1"},
        // decks that do not exist (every case ran and failed, exit 4)
        {"deck: x.yaml\nmetrics:\n  p: {kind: max, column: c}\ncases: [{name: a}]\n", ":1: deck: '"},
        {head + "cases:\n  - {name: a, deck: nope.yaml}\n", "cases.0.deck: '"},
        {"deck: [x\n", "study.yaml:"},
    };
    for (const Bad& b : cases)
    {
        const std::string f = write(d / "study.yaml", b.text);
        const auto r = run("study " + f + " --out " + (d / "out").string());
        EXPECT_EQ(r.code, 2) << b.text << r.output;
        EXPECT_NE(r.output.find(b.expect), std::string::npos) << b.text << "\n-> " << r.output;
        EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
        EXPECT_FALSE(fs::exists(d / "out")) << b.text;
    }
    // --only names cases of the study
    const std::string ok = write(d / "ok.yaml", column_study("1 mm", "1 mm", false));
    const auto only = run("study " + ok + " --out " + (d / "out").string() + " --only a,zz");
    EXPECT_EQ(only.code, 2) << only.output;
    EXPECT_NE(only.output.find("--only zz: cases: 'zz' is not a case of " + ok + "; expected one of a, b"),
              std::string::npos)
        << only.output;
    EXPECT_FALSE(fs::exists(d / "out"));
    // a file where the cases' folder goes: refused before any case runs (was exit 1, "cannot create")
    fs::create_directories(d / "in_the_way");
    write(d / "in_the_way" / "cases", "x");
    const auto in_the_way = run("study " + ok + " --out " + (d / "in_the_way").string());
    EXPECT_EQ(in_the_way.code, 2) << in_the_way.output;
    EXPECT_NE(in_the_way.output.find("/cases exists and is not a directory"), std::string::npos) << in_the_way.output;
    EXPECT_EQ(std::count(in_the_way.output.begin(), in_the_way.output.end(), '\n'), 1) << in_the_way.output;
    EXPECT_FALSE(fs::exists(d / "in_the_way" / "table.csv"));
    // --out is required and --set refused
    EXPECT_EQ(run("study " + (d / "study.yaml").string()).code, 2);
    EXPECT_EQ(run("study " + (d / "study.yaml").string() + " --out x --set a=1").code, 2);
}

// ---- extractors on a history whose values are known ----

rkfem::HistoryTable known_history()
{
    // y = sin(2 pi t) on t = 0, 0.05, ..., 1: max 1 at t = 0.25, min -1 at t = 0.75
    rkfem::HistoryTable h;
    h.columns = {"time", "y", "load", "disp"};
    h.values.resize(4);
    for (int i = 0; i <= 20; ++i)
    {
        const real_t t = 0.05 * i;
        h.values[0].push_back(t);
        h.values[1].push_back(std::sin(2 * M_PI * t));
        // bilinear: stiffness 10 to a displacement of 1 (load 10), then 0.5: the event at load 10
        const real_t load = 20 * t;
        h.values[2].push_back(load);
        h.values[3].push_back(load <= 10 ? load / 10 : 1 + (load - 10) / 0.5);
    }
    return h;
}

rkfem::StudyMetric metric(const std::string& kind, const std::string& column, real_t scale = 1)
{
    rkfem::StudyMetric m;
    m.name = "m";
    m.kind = kind;
    m.column = column;
    m.scale = scale;
    return m;
}

TEST(Study, ExtractorsOnAKnownHistory)
{
    const rkfem::HistoryTable h = known_history();
    const YAML::Node none;
    EXPECT_NEAR(rkfem::extract_metric(metric("max", "y"), h, none), 1.0, 1e-12);
    EXPECT_NEAR(rkfem::extract_metric(metric("time_of_max", "y"), h, none), 0.25, 1e-12);
    EXPECT_NEAR(rkfem::extract_metric(metric("min", "y"), h, none), -1.0, 1e-12);
    EXPECT_NEAR(rkfem::extract_metric(metric("time_of_min", "y"), h, none), 0.75, 1e-12);
    // scale -1 turns the minimum into the maximum
    EXPECT_NEAR(rkfem::extract_metric(metric("max", "y", -1), h, none), 1.0, 1e-12);
    EXPECT_NEAR(rkfem::extract_metric(metric("time_of_max", "y", -1), h, none), 0.75, 1e-12);
    EXPECT_NEAR(std::abs(rkfem::extract_metric(metric("abs_max", "y"), h, none)), 1.0, 1e-12);
    EXPECT_NEAR(rkfem::extract_metric(metric("first", "load"), h, none), 0.0, 1e-12);
    EXPECT_NEAR(rkfem::extract_metric(metric("final", "load"), h, none), 20.0, 1e-12);
    rkfem::StudyMetric at = metric("at", "load");
    at.time = 0.125; // between rows: linear interpolation of a linear column is exact
    EXPECT_NEAR(rkfem::extract_metric(at, h, none), 2.5, 1e-12);
    at.time = 2.0; // past the end of the run
    EXPECT_TRUE(std::isnan(rkfem::extract_metric(at, h, none)));
    // the time average of y = sin(2 pi t) over a window is (cos 2 pi a - cos 2 pi b) / (2 pi (b - a));
    // trapezoids on steps h = 0.05 of a function with y'' = -(2 pi)^2 y take h^2 / 12 y'' with
    // them, so they give it times 1 - (2 pi h)^2 / 12 (0.8 % low; measured within 1.2e-4 of that,
    // the ends' partial steps); of the linear load, exactly its value at the window's middle
    rkfem::StudyMetric mean = metric("mean", "y");
    mean.from = 0.1;
    mean.to = 0.3333;
    const real_t exact = (std::cos(2 * M_PI * 0.1) - std::cos(2 * M_PI * 0.3333)) / (2 * M_PI * (0.3333 - 0.1));
    const real_t trapezoids = exact * (1 - std::pow(2 * M_PI * 0.05, 2) / 12);
    EXPECT_NEAR(rkfem::extract_metric(mean, h, none), trapezoids, 5e-4 * exact);
    mean = metric("mean", "load");
    mean.from = 0.125;
    mean.to = 0.6;
    EXPECT_NEAR(rkfem::extract_metric(mean, h, none), 20 * 0.3625, 1e-12);
    mean.to = 1.5; // past the end of the run
    EXPECT_TRUE(std::isnan(rkfem::extract_metric(mean, h, none)));
    rkfem::StudyMetric ev = metric("event_load", "load");
    ev.response = "disp";
    EXPECT_NEAR(rkfem::extract_metric(ev, h, none), 10.0, 1e-12);
    // a linear history has no event
    EXPECT_TRUE(std::isnan(rkfem::event_load({0, 1, 2, 3}, {0, 0.1, 0.2, 0.3}, 0.1)));
    // summary key paths through mappings and lists
    const YAML::Node s = YAML::Load(R"({"steps": 42, "impact": {"actual_depth": 0.025},
                                        "contacts": [{"resultant": [1, 2, 3]}], "gone": null})");
    rkfem::StudyMetric sm;
    sm.name = "s";
    sm.kind = "summary";
    sm.key = "steps";
    EXPECT_EQ(rkfem::extract_metric(sm, h, s), 42.0);
    sm.key = "impact.actual_depth";
    EXPECT_EQ(rkfem::extract_metric(sm, h, s), 0.025);
    sm.key = "contacts.0.resultant.2";
    EXPECT_EQ(rkfem::extract_metric(sm, h, s), 3.0);
    sm.key = "gone";
    EXPECT_TRUE(std::isnan(rkfem::extract_metric(sm, h, s)));
    sm.key = "contacts.1.resultant";
    EXPECT_THROW(rkfem::extract_metric(sm, h, s), rkfem::Error);
    EXPECT_THROW(rkfem::extract_metric(metric("max", "nope"), h, none), rkfem::Error);
}

// summary.json splits the run's time (set-up, stepping, output) and counts the work items of
// each formulation: elements for fem-1pt, particles for rkpm (it divided by the mesh's elements
// before), so ns_per_element_cycle = stepping time / (steps x work items) and seconds_per_step =
// stepping time / steps, exactly as written.
TEST(Study, SummarySplitsTheRunTimeAndCountsTheRightWorkItems)
{
    const fs::path d = scratch("timing");
    for (const char* f : {"fem-1pt", "rkpm"})
    {
        const fs::path out = d / f;
        const auto r = run("run " + column_deck + " --out " + out.string() +
                           " --quiet --set 'parts.column.generator.size=[2 mm, 2 mm, 40 mm]' --set time.end=4us" +
                           " --set parts.column.formulation=" + f);
        ASSERT_EQ(r.code, 0) << r.output;
        const YAML::Node s = summary_of(out);
        const real_t wall = s["wall_seconds"].as<real_t>(), setup = s["setup_seconds"].as<real_t>(),
                     stepping = s["stepping_seconds"].as<real_t>(), output = s["output_seconds"].as<real_t>();
        const long steps = s["steps"].as<long>(), items = s["work_items"].as<long>();
        EXPECT_EQ(items, std::string(f) == "rkpm" ? s["nodes"].as<long>() : s["elements"].as<long>()) << f;
        EXPECT_GT(setup, 0.0);
        EXPECT_GT(stepping, 0.0);
        EXPECT_GT(output, 0.0); // the mesh, the first and last frames and the history rows
        EXPECT_LE(stepping + output, wall * (1 + 1e-9));
        EXPECT_NEAR(s["ns_per_element_cycle"].as<real_t>(), 1e9 * stepping / (static_cast<real_t>(steps) * items),
                    1e-9 * s["ns_per_element_cycle"].as<real_t>());
        EXPECT_NEAR(s["seconds_per_step"].as<real_t>(), stepping / steps, 1e-9 * stepping / steps);
    }
}
