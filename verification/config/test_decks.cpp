// Decks through the real executable: each class of bad input gives one line
// "DECK:LINE: key.path: what is wrong; what is expected", exit code 2 and no output directory;
// every deck in studies/decks passes `rkfem check`, and the resolved deck it prints is itself a
// deck that resolves to the same text (round trip).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <hdf5.h>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "../executable.hpp"

namespace fs = std::filesystem;

namespace
{
using rkfem::test::Result;
using rkfem::test::run;
using rkfem::test::run_shell;

const std::string good = R"(title: small
time:
  end: 1 us
parts:
  col:
    generator: {type: box, size: [1 mm, 1 mm, 10 mm], element_size: 1 mm}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
node_sets:
  end: {part: col, select: {type: plane, point: [0, 0, 0], normal: [0, 0, 1]}}
boundary_conditions:
  - {node_set: end, velocity: {z: 10 m/s}}
)";

std::string write_deck(const std::string& name, const std::string& text)
{
    const fs::path dir = fs::temp_directory_path() / "rkfem_test_decks";
    fs::create_directories(dir);
    const fs::path p = dir / name;
    std::ofstream(p) << text;
    return p.string();
}

std::string replace(std::string s, const std::string& from, const std::string& to)
{
    const auto pos = s.find(from);
    EXPECT_NE(pos, std::string::npos) << from;
    return s.replace(pos, from.size(), to);
}

/// Runs `rkfem run` on a bad deck and checks exit code 2, a single located line containing
/// `key` and `fragment`, and that no output directory was created.
void expect_rejected(const std::string& name, const std::string& text, const std::string& location,
                     const std::string& fragment)
{
    const std::string deck = write_deck(name, text);
    const fs::path out = fs::temp_directory_path() / ("rkfem_out_" + name);
    fs::remove_all(out);
    const Result r = run("run " + deck + " --out " + out.string() + " --quiet");
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_NE(r.output.find(name + location), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(fragment), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(fs::exists(out)) << "partial output directory left behind";
}
} // namespace

TEST(Decks, GoodDeckRuns)
{
    const fs::path out = fs::temp_directory_path() / "rkfem_out_good";
    fs::remove_all(out);
    const Result r = run("run " + write_deck("good.yaml", good) + " --out " + out.string() + " --quiet");
    EXPECT_EQ(r.code, 0) << r.output;
    for (const char* f : {"results.h5", "results.xdmf", "history.csv", "summary.json"})
        EXPECT_TRUE(fs::exists(out / f)) << f;
}

TEST(Decks, UnknownKeySuggestsTheClosest)
{
    expect_rejected("unknown_key.yaml", replace(good, "material:", "materail:"), ":7: parts.col.materail",
                    "did you mean 'material'");
}

TEST(Decks, RepeatedKeyIsRejected)
{
    // YAML leaves repeated keys to the application; yaml-cpp keeps both and reads the first, so
    // the second would be dropped without a word
    expect_rejected("repeated_key.yaml", replace(good, "  end: 1 us\n", "  end: 1 us\n  end: 2 us\n"), ":4: time.end",
                    "key 'end' given twice; each key once (first given on line 3)");
    expect_rejected("repeated_flow_key.yaml", replace(good, "E: 200 GPa", "E: 200 GPa, E: 210 GPa"),
                    ":7: parts.col.material.E", "given twice");
}

TEST(Decks, MissingKey)
{
    expect_rejected("missing_key.yaml", replace(good, "  end: 1 us\n", "  dt_scale: 0.9\n"), ":3: time.end",
                    "missing required key");
}

TEST(Decks, WrongType)
{
    expect_rejected("wrong_type.yaml", replace(good, "size: [1 mm, 1 mm, 10 mm]", "size: 1 mm"),
                    ":6: parts.col.generator.size", "expected [x, y, z]");
}

TEST(Decks, UnknownUnit)
{
    expect_rejected("unknown_unit.yaml", replace(good, "E: 200 GPa", "E: 200 GPascal"), ":7: parts.col.material.E",
                    "unknown unit 'GPascal'");
}

TEST(Decks, MismatchedUnit)
{
    expect_rejected("mismatched_unit.yaml", replace(good, "rho: 7850 kg/m^3", "rho: 7850 m/s"),
                    ":7: parts.col.material.rho", "not a density");
}

TEST(Decks, PoissonRatioOutOfRange)
{
    expect_rejected("nu_range.yaml", replace(good, "nu: 0.3", "nu: 0.5"), ":7: parts.col.material.nu",
                    "expected -1 < nu < 0.5");
}

TEST(Decks, NonPositiveDensity)
{
    expect_rejected("rho_range.yaml", replace(good, "rho: 7850 kg/m^3", "rho: -1 kg/m^3"), ":7: parts.col.material.rho",
                    "expected rho > 0");
}

TEST(Decks, CapModelStrengthOutsideTheFitsIsRejected)
{
    expect_rejected("cscm_fc.yaml",
                    replace(good, "{model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}",
                            "{model: cscm, rho: 2400 kg/m^3, fc: 12 ksi}"),
                    ":7: parts.col.material.fc", "expected 20 MPa <= fc <= 58 MPa");
    expect_rejected("cscm_d1.yaml",
                    replace(good, "{model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}",
                            "{model: cscm, rho: 2400 kg/m^3, fc: 30 MPa, D1: 2.5e-4 MPa}"),
                    ":7: parts.col.material.D1", "not a reciprocal pressure (e.g. 2.5e-4 1/MPa)");
}

TEST(Decks, KccTablesRoundTrip)
{
    const std::string fixed = write_deck(
        "kcc_tables2.yaml",
        replace(good, "{model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}",
                "{model: kcc, rho: 2400 kg/m^3, fc: 45.6 MPa, a0: 14 MPa, eta: [[0, 0], [1e-4, 1], [3e-4, 0]], "
                "eos: {strain: [0, -0.0015, -0.0043, -0.0101, -0.0305, -0.0513, -0.0726, -0.0943, -0.174, -0.208], "
                "pressure: [0 MPa, 33 MPa, 72 MPa, 116 MPa, 220 MPa, 332 MPa, 471 MPa, 721 MPa, 4210 MPa, 6440 MPa], "
                "unload_bulk: [22 GPa, 22 GPa, 22.3 GPa, 23.4 GPa, 27.9 GPa, 32.4 GPa, 36.8 GPa, 40.2 GPa, 90.4 GPa, "
                "110 GPa]}}"));
    const Result first = run("check " + fixed + " --quiet");
    ASSERT_EQ(first.code, 0) << first.output;
    EXPECT_NE(first.output.find("a0: 14000000"), std::string::npos) << first.output;
    // check prints the deck's values beside the generated ones (a0 = 0.29559 f'c at 45.6 MPa)
    const Result report = run("check " + fixed);
    EXPECT_NE(report.output.find("a0 = 1.4e+07 Pa (deck; generated 1.34789e+07)"), std::string::npos) << report.output;
    EXPECT_NE(report.output.find("a1 = 0.4463"), std::string::npos) << report.output;
    EXPECT_EQ(report.output.find("a1 = 0.4463 (deck"), std::string::npos) << report.output;
    EXPECT_NE(report.output.find("eta(lambda) (deck's)"), std::string::npos) << report.output;
    EXPECT_NE(report.output.find("EOS_8 (deck's) ln(V/V0)"), std::string::npos) << report.output;
    EXPECT_NE(first.output.find("eta: [[0, 0], [0.0001, 1], [0.0003, 0]]"), std::string::npos) << first.output;
    EXPECT_NE(first.output.find("pressure: [0, 33000000, 72000000"), std::string::npos) << first.output;
    const Result second = run("check " + write_deck("kcc_tables3.yaml", first.output) + " --quiet");
    ASSERT_EQ(second.code, 0) << second.output;
    EXPECT_EQ(first.output, second.output);
    // a table that never reaches eta = 1 is rejected with its key
    expect_rejected("kcc_eta.yaml",
                    replace(good, "{model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}",
                            "{model: kcc, rho: 2400 kg/m^3, fc: 45.6 MPa, eta: [[0, 0], [1e-4, 0.9], [3e-4, 0]]}"),
                    ":7: parts.col.material.eta", "expected eta = 1 at the peak");
}

TEST(Decks, KccRateLawsRoundTripAndTheirMistakesNameTheKey)
{
    const std::string kcc = "{model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}";
    auto with = [&](const std::string& rate)
    { return replace(good, kcc, "{model: kcc, rho: 2400 kg/m^3, fc: 35 MPa, rate_effects: " + rate + "}"); };
    // true is the capped built-in law; a curve (LCRATE's sign: negative = tension) prints as read
    for (const auto& [name, rate, echoed, dif] : std::array<std::array<std::string, 4>, 3>{
             {{"rate_true.yaml", "true", "rate_effects: {law: ceb-fip, compression_cap: 2.5, tension_cap: 6}",
               "DIF at 1, 10^2, 10^4 1/s: compression 1.3401 2.20268 2.5; tension 1.61026 6 6"},
              {"rate_law.yaml", "{law: ceb-fip, compression_cap: none, tension_cap: 4}",
               "rate_effects: {law: ceb-fip, compression_cap: none, tension_cap: 4}",
               "DIF at 1, 10^2, 10^4 1/s: compression 1.3401 2.20268 10.2239; tension 1.61026 4 4"},
              {"rate_curve.yaml", "{curve: [[-100 1/s, 4], [0, 1], [100 1/s, 2]], compression_cap: 1.5}",
               "rate_effects: {curve: [[-100, 4], [0, 1], [100, 2]], compression_cap: 1.5, tension_cap: none}",
               "DIF(rate [1/s]): (-100, 4) (0, 1) (100, 2)"}}})
    {
        const Result first = run("check " + write_deck(name, with(rate)));
        ASSERT_EQ(first.code, 0) << first.output;
        EXPECT_NE(first.output.find(echoed), std::string::npos) << first.output;
        EXPECT_NE(first.output.find(dif), std::string::npos) << first.output;
        const Result q = run("check " + write_deck(name, with(rate)) + " --quiet");
        const Result second = run("check " + write_deck("again_" + name, q.output) + " --quiet");
        ASSERT_EQ(second.code, 0) << second.output;
        EXPECT_EQ(q.output, second.output);
    }
    // omega 0 (no dilatancy) is a valid K&C input; past 1 it is not
    EXPECT_EQ(run("check " + write_deck("omega0.yaml", with("false, omega: 0"))).code, 0);
    expect_rejected("omega2.yaml", with("false, omega: 1.5"), ":7: parts.col.material.omega",
                    "expected 0 <= omega <= 1");
    // edrop 0 (no post-peak decay) is valid; below 0 it is not
    EXPECT_EQ(run("check " + write_deck("edrop0.yaml", with("false, edrop: 0"))).code, 0);
    expect_rejected("edrop_negative.yaml", with("false, edrop: -1"), ":7: parts.col.material.edrop",
                    "expected edrop >= 0");
    expect_rejected("fc_huge.yaml", replace(good, kcc, "{model: kcc, rho: 2400 kg/m^3, fc: 1e6 MPa}"),
                    ":7: parts.col.material.fc", "expected 1 MPa <= fc <= 500 MPa");
    expect_rejected("rate_cap.yaml", with("{law: ceb-fip, compression_cap: 0.5}"),
                    ":7: parts.col.material.rate_effects.compression_cap", "expected a largest DIF >= 1, or none");
    expect_rejected("rate_both.yaml", with("{law: ceb-fip, curve: [[0, 1], [1, 2]]}"),
                    ":7: parts.col.material.rate_effects.law", "is given beside curve");
    expect_rejected("rate_order.yaml", with("{curve: [[0, 1], [-1 1/s, 2]]}"),
                    ":7: parts.col.material.rate_effects.curve.1", "rates strictly increasing");
    expect_rejected("rate_unit.yaml", with("{curve: [[0, 1], [1 m/s, 2]]}"),
                    ":7: parts.col.material.rate_effects.curve.1.0", "");
    expect_rejected("rate_law_name.yaml", with("{law: tedesco}"), ":7: parts.col.material.rate_effects.law",
                    "expected one of ceb-fip");
    expect_rejected("rate_cscm.yaml",
                    replace(good, kcc, "{model: cscm, rho: 2400 kg/m^3, fc: 35 MPa, rate_effects: {law: ceb-fip}}"),
                    ":7: parts.col.material.rate_effects", "expected true or false");
}

TEST(Decks, CapModelOverridesResolveToSI)
{
    const Result r = run(
        "check " + write_deck("cscm_over.yaml", replace(good, "{model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}",
                                                        "{model: cscm, rho: 2400 kg/m^3, fc: 30 MPa, X0: 95 MPa, "
                                                        "D1: 2.5e-4 1/MPa, D2: 3.5e-7 1/MPa^2}")));
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("X0: 95000000"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("D1: 2.5e-10"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("D2: 3.5e-19"), std::string::npos) << r.output;
    // E from CEB-FIP at 30 MPa: 21.5 GPa x 3^(1/3) = 31.0 GPa
    EXPECT_NE(r.output.find("E: 3.1008"), std::string::npos) << r.output;
}

TEST(Decks, IntegerRkSupportIsRejected)
{
    expect_rejected("rk_integer.yaml",
                    replace(good, "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n",
                            "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n"
                            "    formulation: rkpm\n    rk: {normalized_support: 2}\n"),
                    ":9: parts.col.rk.normalized_support", "expected a non-integer value such as 2.01");
}

TEST(Decks, KeysOfAnotherFormulationAreCheckedThenIgnoredWithAWarning)
{
    // a formulation sweep needs one override per case: nodal_integration on a fem-1pt part (or
    // hourglass on an rkpm part) is read and checked, then ignored with a note in the resolved deck
    const std::string with = replace(good, "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n",
                                     "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n"
                                     "    nodal_integration: {scheme: scni}\n    rk: {order: 1}\n");
    const std::string f = write_deck("nodal_on_fem.yaml", with);
    const Result c = run("check " + f);
    ASSERT_EQ(c.code, 0) << c.output;
    EXPECT_NE(c.output.find("# warning: parts.col.nodal_integration (" + f +
                            ":8): formulation fem-1pt does not use it; ignored"),
              std::string::npos)
        << c.output;
    EXPECT_NE(c.output.find("# warning: parts.col.rk (" + f + ":9)"), std::string::npos) << c.output;
    // the resolved deck is the one without those keys, plus the notes
    const Result plain = run("check " + write_deck("plain.yaml", good));
    std::string stripped;
    std::istringstream lines(c.output);
    for (std::string line; std::getline(lines, line);)
        if (line.find("# warning:") == std::string::npos)
            stripped += line + "\n";
    EXPECT_EQ(stripped, plain.output);
    const fs::path out = fs::temp_directory_path() / "rkfem_test_decks" / "ignored_run";
    const Result r = run("run " + f + " --out " + out.string());
    EXPECT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("rkfem: warning: parts.col.nodal_integration"), std::string::npos) << r.output;
    // what is ignored is still checked
    expect_rejected("hourglass_on_rkpm.yaml",
                    replace(good, "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n",
                            "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n"
                            "    formulation: rkpm\n    hourglass: {type: stiffness, coefficient: -1}\n"),
                    ":9: parts.col.hourglass.coefficient", "expected QM >= 0");
}

TEST(Decks, TooSmallRkSupportNamesTheKey)
{
    // a / h = 1.01 with box support: a point between nodes of a stretched lattice sees fewer than
    // four particles; the singular moment matrix is reported against the deck key
    expect_rejected("rk_small.yaml",
                    replace(replace(good, "element_size: 1 mm", "divisions: [1, 1, 4]"),
                            "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n",
                            "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n"
                            "    formulation: rkpm\n    rk: {normalized_support: 1.01, support: sphere}\n"),
                    ":9: parts.col.rk.normalized_support", "RK moment matrix is singular");
}

TEST(Decks, RkFunctionsTheDropToleranceLeavesShortAreNamedAtTheSupport)
{
    // a / h = 1.01 with the default drop tolerance: near one spacing the functions kept above
    // 1e-5 of the largest do not span a linear field; this ended in exit 1 with no key
    const std::string deck = replace(good, "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n",
                                     "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n"
                                     "    formulation: rkpm\n    rk: {normalized_support: 1.01}\n");
    expect_rejected("rk_drop.yaml", deck, ":9: parts.col.rk.normalized_support",
                    "RK drop tolerance: the functions left at x = (");
    // keeping every function (drop_tolerance: 0) builds the same support
    const Result r =
        run("check " + write_deck("rk_drop_zero.yaml", replace(deck, "normalized_support: 1.01}",
                                                               "normalized_support: 1.01, drop_tolerance: 0}")));
    EXPECT_EQ(r.code, 0) << r.output;
}

TEST(Decks, HourglassPlasticScalingIsForTheStiffnessForms)
{
    const std::string with = replace(good, "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n",
                                     "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n"
                                     "    hourglass: {type: viscous, plastic_scaling: true}\n");
    expect_rejected("hg_scaling.yaml", with, ":8: parts.col.hourglass.plastic_scaling",
                    "applies to the stiffness forms only");
    // the resolved deck says what applies: on for assumed-strain, off for stiffness by default
    const Result a =
        run("check " + write_deck("hg_scaling_as.yaml",
                                  replace(with, "type: viscous, plastic_scaling: true", "type: assumed-strain")));
    EXPECT_NE(a.output.find("hourglass: {type: assumed-strain, coefficient: 0.1, plastic_scaling: true}"),
              std::string::npos)
        << a.output;
    const Result st =
        run("check " +
            write_deck("hg_scaling_st.yaml", replace(with, "type: viscous, plastic_scaling: true", "type: stiffness")));
    EXPECT_NE(st.output.find("hourglass: {type: stiffness, coefficient: 0.1, plastic_scaling: false}"),
              std::string::npos)
        << st.output;
}

TEST(Decks, EmptyNodeSet)
{
    expect_rejected("empty_set.yaml", replace(good, "point: [0, 0, 0]", "point: [0, 0, 5 m]"),
                    ":9: node_sets.end.select", "selects no node");
}

TEST(Decks, ZeroVolumeElement)
{
    expect_rejected("zero_volume.yaml",
                    replace(good, "size: [1 mm, 1 mm, 10 mm], element_size: 1 mm",
                            "size: [1e-200 m, 1e-200 m, 10 mm], divisions: [1, 1, 10]"),
                    ":6: parts.col.generator", "element 0 is degenerate at its local node 0 (scaled Jacobian 0)");
}

TEST(Decks, BadOverrideIsLocatedAtTheSetArgument)
{
    const Result r = run("check " + write_deck("override.yaml", good) + " --set parts.col.material.nu=0.7");
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.output.find("--set parts.col.material.nu=0.7: parts.col.material.nu"), std::string::npos) << r.output;
}

TEST(Decks, OverrideChangesTheResolvedDeck)
{
    const Result r = run("check " + write_deck("override2.yaml", good) + " --set \"parts.col.material.E=30 Msi\"");
    EXPECT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("E: 2.068427188e+11"), std::string::npos) << r.output; // 30e6 psi in Pa
}

TEST(Decks, EveryStudyDeckChecksAndRoundTrips)
{
    int n = 0;
    // and the decks the fuzzer found whose resolved deck did not read back: a title with a quote,
    // part and probe names that YAML must quote (`a: b#c`, `true`)
    std::vector<fs::path> decks;
    for (const auto& entry : fs::directory_iterator(fs::path(RKFEM_SOURCE_DIR) / "studies" / "decks"))
        decks.push_back(entry.path());
    for (const char* f : {"title_with_quote.yaml", "names_that_need_quotes.yaml"})
        decks.push_back(fs::path(RKFEM_SOURCE_DIR) / "verification" / "fuzz_regressions" / f);
    for (const fs::path& path : decks)
    {
        const fs::directory_entry entry(path);
        if (entry.path().extension() != ".yaml")
            continue;
        ++n;
        // --quiet: stdout only (the set-up progress of a slow deck goes to stderr)
        const Result first = run("check " + entry.path().string() + " --quiet");
        ASSERT_EQ(first.code, 0) << entry.path() << "\n" << first.output;
        const std::string resolved = write_deck("resolved_" + entry.path().filename().string(), first.output);
        const Result second = run("check " + resolved + " --quiet");
        ASSERT_EQ(second.code, 0) << second.output;
        EXPECT_EQ(first.output, second.output) << entry.path();
    }
    EXPECT_GE(n, 2);
}

namespace
{
std::string xdmf_text(const fs::path& dir)
{
    std::ifstream xf(dir / "results.xdmf");
    return {std::istreambuf_iterator<char>(xf), std::istreambuf_iterator<char>()};
}

/// The times of an XDMF index's time steps.
std::vector<double> xdmf_times(const std::string& xdmf)
{
    std::vector<double> times;
    const std::regex tv("<Time Value=\"([^\"]+)\"");
    for (auto it = std::sregex_iterator(xdmf.begin(), xdmf.end(), tv); it != std::sregex_iterator(); ++it)
        times.push_back(std::stod((*it)[1].str()));
    return times;
}
} // namespace

TEST(Decks, UnstableRunExitsThreeAndKeepsOutput)
{
    const fs::path out = fs::temp_directory_path() / "rkfem_out_unstable";
    fs::remove_all(out);
    const std::string deck =
        write_deck("unstable.yaml", replace(good, "boundary_conditions:\n  - {node_set: end, velocity: {z: 10 m/s}}\n",
                                            "face_sets:\n  top: {select: {type: named, name: top}}\n"
                                            "loads:\n  - {type: pressure, face_set: top, pressure: 1e16 Pa}\n"));
    const Result r = run("run " + deck + " --out " + out.string() + " --quiet");
    EXPECT_EQ(r.code, 3) << r.output;
    EXPECT_NE(r.output.find("run stopped"), std::string::npos) << r.output;
    // one line: ARKODE's own error lines (it printed them even with --quiet) are not echoed
    EXPECT_EQ(r.output.find("ARKODE ERROR"), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_TRUE(fs::exists(out / "results.xdmf"));
    std::ifstream summary(out / "summary.json");
    std::string text((std::istreambuf_iterator<char>(summary)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("\"status\": \"unstable\""), std::string::npos) << text;

    // the step that failed is not counted (steps and end_time are the last good step's, here the
    // start), and the state it failed in is the last frame, at its own time (it was written at the
    // last good time: two frames at t = 0), with both steppers
    for (const char* stepper : {"arkode-cd", "central-difference"})
    {
        const fs::path o = fs::temp_directory_path() / (std::string("rkfem_out_unstable_") + stepper);
        fs::remove_all(o);
        const Result rs = run("run " + deck + " --out " + o.string() + " --quiet --set time.stepper=" + stepper);
        ASSERT_EQ(rs.code, 3) << rs.output;
        std::ifstream js(o / "summary.json");
        const std::string sj((std::istreambuf_iterator<char>(js)), std::istreambuf_iterator<char>());
        std::smatch m;
        ASSERT_TRUE(std::regex_search(sj, m, std::regex("\"steps\": ([0-9]+),"))) << sj;
        EXPECT_EQ(m[1].str(), "0") << stepper;
        ASSERT_TRUE(std::regex_search(sj, m, std::regex("\"end_time\": ([-0-9.e+]+),"))) << sj;
        EXPECT_EQ(std::stod(m[1].str()), 0.0) << stepper;
        ASSERT_TRUE(std::regex_search(sj, m, std::regex("\"failed_time\": ([-0-9.e+]+),"))) << sj;
        const double failed = std::stod(m[1].str());
        EXPECT_GT(failed, 0.0) << stepper;
        const std::string xdmf = xdmf_text(o);
        const std::vector<double> times = xdmf_times(xdmf);
        ASSERT_EQ(times.size(), 2u) << xdmf;
        EXPECT_EQ(times[0], 0.0);
        EXPECT_NEAR(times[1], failed, 1e-10 * failed) << stepper; // summary.json has 12 digits
    }
}

namespace
{
/// A field of frame `frame` of results.h5 in `dir` (-1: the last), as doubles.
std::vector<double> frame_field(const fs::path& dir, int frame, const std::string& field)
{
    const hid_t f = H5Fopen((dir / "results.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    EXPECT_GE(f, 0) << dir;
    hsize_t n_steps = 0;
    const hid_t steps = H5Gopen2(f, "steps", H5P_DEFAULT);
    H5Gget_num_objs(steps, &n_steps);
    H5Gclose(steps);
    char name[96];
    std::snprintf(name, sizeof name, "steps/%06d/%s", frame < 0 ? static_cast<int>(n_steps) - 1 : frame, field.c_str());
    const hid_t d = H5Dopen2(f, name, H5P_DEFAULT);
    const hid_t sp = H5Dget_space(d);
    std::vector<double> v(static_cast<std::size_t>(H5Sget_simple_extent_npoints(sp)));
    H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
    H5Sclose(sp);
    H5Dclose(d);
    H5Fclose(f);
    return v;
}
} // namespace

// A column whose end is driven at 30 km/s crushes its first element in the second step. The
// output holds the start, then the last good state (step 1, between outputs) at its time, then
// the failed state at its own time (a stage of arkode-erk): the last good frame is, bit for bit,
// the last frame of the same run stopped after step 1 (time.max_steps), with each stepper; the
// failed frame has the crushed element (non-positive volume), the last good one has none. The
// summary's steps and end_time are the last good step's.
TEST(Decks, UnstableRunWritesTheLastGoodStateThenTheFailedOne)
{
    const std::string deck =
        write_deck("unstable_crush.yaml", replace(replace(good, "velocity: {z: 10 m/s}", "velocity: {z: 30000 m/s}"),
                                                  "  end: 1 us\n", "  end: 2 us\n  output_interval: 10 us\n"));
    for (const char* stepper : {"central-difference", "arkode-cd", "arkode-erk"})
    {
        const fs::path o = fs::temp_directory_path() / (std::string("rkfem_out_crush_") + stepper);
        const fs::path m = fs::temp_directory_path() / (std::string("rkfem_out_crush_stop_") + stepper);
        fs::remove_all(o);
        fs::remove_all(m);
        const std::string common = " --quiet --set output.precision=double --set time.stepper=" + std::string(stepper);
        const Result rs = run("run " + deck + " --out " + o.string() + common);
        ASSERT_EQ(rs.code, 3) << rs.output;
        std::ifstream js(o / "summary.json");
        const std::string sj((std::istreambuf_iterator<char>(js)), std::istreambuf_iterator<char>());
        std::smatch mt;
        ASSERT_TRUE(std::regex_search(sj, mt, std::regex("\"steps\": ([0-9]+),"))) << sj;
        const std::string steps = mt[1].str();
        ASSERT_TRUE(std::regex_search(sj, mt, std::regex("\"end_time\": ([-0-9.e+]+),"))) << sj;
        const double end_time = std::stod(mt[1].str());
        ASSERT_TRUE(std::regex_search(sj, mt, std::regex("\"failed_time\": ([-0-9.e+]+),"))) << sj;
        const double failed = std::stod(mt[1].str());
        EXPECT_EQ(steps, "1") << stepper;
        const std::string xdmf = xdmf_text(o);
        const std::vector<double> times = xdmf_times(xdmf);
        ASSERT_EQ(times.size(), 3u) << stepper << "\n" << xdmf;
        EXPECT_EQ(times[0], 0.0);
        EXPECT_NEAR(times[1], end_time, 1e-10 * end_time) << stepper;
        EXPECT_NEAR(times[2], failed, 1e-10 * failed) << stepper;
        EXPECT_GT(failed, end_time);

        const Result rm = run("run " + deck + " --out " + m.string() + common + " --set time.max_steps=" + steps);
        ASSERT_EQ(rm.code, 0) << rm.output;
        for (const char* field : {"coordinates", "displacement", "velocity", "stress", "volume"})
            EXPECT_EQ(frame_field(o, 1, field), frame_field(m, -1, field)) << stepper << ": " << field;
        const std::vector<double> good_volume = frame_field(o, 1, "volume"),
                                  failed_volume = frame_field(o, 2, "volume");
        std::printf("%s: last good frame at %.4e s (smallest element volume %.3e m^3), failed frame at %.4e s "
                    "(%.3e m^3)\n",
                    stepper, times[1], *std::min_element(good_volume.begin(), good_volume.end()), times[2],
                    *std::min_element(failed_volume.begin(), failed_volume.end()));
        EXPECT_GT(*std::min_element(good_volume.begin(), good_volume.end()), 0.0) << stepper;
        EXPECT_LE(*std::min_element(failed_volume.begin(), failed_volume.end()), 0.0) << stepper;
    }
}

TEST(Decks, ConcreteRunsWriteDamageFields)
{
    // the struck K&C bar crushes its end: the 0..1 damage index and the K&C delta (0..2) are
    // written per element, within their ranges, and some elements are past the peak (delta > 1)
    const fs::path out = fs::temp_directory_path() / "rkfem_out_kcc_damage";
    fs::remove_all(out);
    const Result r = run("run " + (fs::path(RKFEM_SOURCE_DIR) / "studies/decks/concrete_bar_kcc.yaml").string() +
                         " --out " + out.string() + " --quiet");
    ASSERT_EQ(r.code, 0) << r.output;
    const hid_t f = H5Fopen((out / "results.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    hsize_t n_steps = 0;
    const hid_t steps = H5Gopen2(f, "steps", H5P_DEFAULT);
    H5Gget_num_objs(steps, &n_steps);
    H5Gclose(steps);
    char name[64];
    std::snprintf(name, sizeof name, "steps/%06d", static_cast<int>(n_steps) - 1);
    auto read = [&](const char* field)
    {
        const hid_t d = H5Dopen2(f, (std::string(name) + "/" + field).c_str(), H5P_DEFAULT);
        const hid_t s = H5Dget_space(d);
        std::vector<double> v(static_cast<std::size_t>(H5Sget_simple_extent_npoints(s)));
        H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
        H5Sclose(s);
        H5Dclose(d);
        return v;
    };
    const auto damage = read("damage"), delta = read("kcc_scaled_damage");
    H5Fclose(f);
    ASSERT_EQ(damage.size(), delta.size());
    int past_peak = 0;
    for (std::size_t e = 0; e < damage.size(); ++e)
    {
        EXPECT_GE(delta[e], 0.0);
        EXPECT_LT(delta[e], 2.0);
        EXPECT_GE(damage[e], 0.0);
        EXPECT_LE(damage[e], 1.0);
        past_peak += delta[e] > 1.0;
    }
    std::printf("%d of %zu elements past the peak (delta > 1)\n", past_peak, delta.size());
    EXPECT_GT(past_peak, 0);
    std::ifstream xdmf(out / "results.xdmf");
    const std::string text((std::istreambuf_iterator<char>(xdmf)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("Name=\"damage\""), std::string::npos);
    EXPECT_NE(text.find("Name=\"kcc_scaled_damage\""), std::string::npos);
}

namespace
{
/// `good` with its box part turned into a cloud part (spacing 1 mm) plus `extra` part keys.
std::string cloud_deck(const std::string& generator_extra, const std::string& part_extra)
{
    return replace(replace(good, "{type: box, size: [1 mm, 1 mm, 10 mm], element_size: 1 mm}",
                           "{type: cloud, size: [1 mm, 1 mm, 10 mm]" + generator_extra + "}"),
                   "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n",
                   "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n" + part_extra);
}
} // namespace

TEST(Decks, CloudPartsRunAndTheirMistakesNameTheKey)
{
    // a good cloud deck runs, with points on the box's faces selected by the plane
    const std::string ok =
        write_deck("cloud_ok.yaml", cloud_deck(", spacing: 0.5 mm, jitter: 0.2", "    formulation: rkpm\n"));
    const fs::path out = fs::temp_directory_path() / "rkfem_out_cloud_ok";
    fs::remove_all(out);
    const Result r = run("run " + ok + " --out " + out.string() + " --quiet");
    EXPECT_EQ(r.code, 0) << r.output;
    EXPECT_TRUE(fs::exists(out / "results.xdmf"));

    // a plate thinner than its spacing, thin in z and in x: CGAL's hull aborted on the first
    // (munmap_chunk) and did not return on the second; both check now
    for (const char* size : {"[4 mm, 4 mm, 12 um]", "[12 um, 4 mm, 4 mm]"})
    {
        const std::string thin = write_deck(
            "cloud_thin.yaml", replace(cloud_deck(", spacing: 1 mm, jitter: 0.25, seed: 1", "    formulation: rkpm\n"),
                                       "size: [1 mm, 1 mm, 10 mm]", std::string("size: ") + size));
        const Result t = run("check " + thin);
        EXPECT_EQ(t.code, 0) << size << ": " << t.output;
    }

    expect_rejected("cloud_fem.yaml", cloud_deck(", spacing: 1 mm", ""), ":6: parts.col.formulation",
                    "expected formulation: rkpm");
    expect_rejected(
        "cloud_sd.yaml",
        cloud_deck(", spacing: 1 mm",
                   "    formulation: rkpm\n    nodal_integration: {scheme: sd-scni, stabilization: mscni}\n"),
        ":9: parts.col.nodal_integration.stabilization", "mscni stabilizes scheme scni only");
    // one SCNI point per Voronoi face runs; a name it does not know is named with the choices
    const std::string per_face = write_deck(
        "cloud_per_face.yaml", cloud_deck(", spacing: 0.5 mm, jitter: 0.2",
                                          "    formulation: rkpm\n    nodal_integration: {facet_points: faces}\n"));
    const Result pf = run("run " + per_face + " --out " + (out.string() + "_faces") + " --quiet");
    EXPECT_EQ(pf.code, 0) << pf.output;
    expect_rejected(
        "cloud_centroid.yaml",
        cloud_deck(", spacing: 1 mm", "    formulation: rkpm\n    nodal_integration: {facet_points: centroid}\n"),
        ":9: parts.col.nodal_integration.facet_points", "expected one of triangles | faces");
    expect_rejected("cloud_jitter.yaml", cloud_deck(", spacing: 1 mm, jitter: 0.6", "    formulation: rkpm\n"),
                    ":6: parts.col.generator.jitter", "is outside [0, 0.45]");
    expect_rejected("cloud_both.yaml", cloud_deck(", spacing: 1 mm, points: p.csv", "    formulation: rkpm\n"),
                    ":6: parts.col.generator.points", "is given with spacing");
    expect_rejected("cloud_nofile.yaml", cloud_deck(", points: no_such_file.csv", "    formulation: rkpm\n"),
                    ":6: parts.col.generator.points", "cannot open");
    expect_rejected("cloud_faces.yaml",
                    cloud_deck(", spacing: 1 mm", "    formulation: rkpm\n") +
                        "face_sets:\n  top: {part: col, select: {type: named, name: nose}}\n",
                    ":14: face_sets.top.select.name", "cloud part 'col' has no face set named 'nose'");
    // a file with a point outside the box: named by file line
    write_deck("outside.csv", "# x, y, z in mm\n0.5, 0.5, 1\n0.5, 0.5, 12\n");
    expect_rejected("cloud_outside.yaml",
                    cloud_deck(", points: outside.csv, points_unit: mm", "    formulation: rkpm\n"),
                    ":6: parts.col.generator.points", "outside.csv:3 lies outside the box body");
}

TEST(Decks, CylinderCloudPartsRunAndTheirMistakesNameTheKey)
{
    auto cyl = [](const std::string& generator)
    {
        return replace(good, "{type: box, size: [1 mm, 1 mm, 10 mm], element_size: 1 mm}",
                       "{type: cloud, body: cylinder" + generator + "}");
    };
    const std::string part = "    formulation: rkpm\n";
    auto with_rkpm = [&](const std::string& deck)
    {
        return replace(deck, "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n",
                       "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n" + part);
    };
    const std::string ok = write_deck("cyl_ok.yaml", with_rkpm(cyl(", radius: 1 mm, height: 6 mm, spacing: 0.5 mm")));
    const fs::path out = fs::temp_directory_path() / "rkfem_out_cyl_ok";
    fs::remove_all(out);
    const Result r = run("run " + ok + " --out " + out.string() + " --quiet");
    EXPECT_EQ(r.code, 0) << r.output;
    EXPECT_TRUE(fs::exists(out / "results.xdmf"));
    expect_rejected("cyl_size.yaml",
                    with_rkpm(cyl(", size: [1 mm, 1 mm, 1 mm], radius: 1 mm, height: 6 mm, spacing: 0.5 mm")),
                    ":6: parts.col.generator.size", "is not used by a cylinder body");
    expect_rejected("cyl_radius.yaml", with_rkpm(cyl(", height: 6 mm, spacing: 0.5 mm")),
                    ":6: parts.col.generator.radius", "missing");
    expect_rejected("box_radius.yaml",
                    with_rkpm(replace(good, "{type: box, size: [1 mm, 1 mm, 10 mm], element_size: 1 mm}",
                                      "{type: cloud, size: [1 mm, 1 mm, 10 mm], radius: 1 mm, spacing: 0.5 mm}")),
                    ":6: parts.col.generator.radius", "is not used by a box body");
    expect_rejected("cyl_body.yaml",
                    with_rkpm(replace(good, "{type: box, size: [1 mm, 1 mm, 10 mm], element_size: 1 mm}",
                                      "{type: cloud, body: sphere, radius: 1 mm, spacing: 0.5 mm}")),
                    ":6: parts.col.generator.body", "expected one of");
    expect_rejected("cyl_faces.yaml",
                    with_rkpm(cyl(", radius: 1 mm, height: 6 mm, spacing: 0.5 mm")) +
                        "face_sets:\n  end: {part: col, select: {type: named, name: xmin}}\n",
                    ":14: face_sets.end.select.name", "expected one of top, bottom, side (a cylinder body)");
    write_deck("cyl_outside.csv", "# x, y, z in mm\n0, 0, 1\n0.9, 0.5, 2\n");
    expect_rejected("cyl_outside.yaml",
                    with_rkpm(cyl(", radius: 1 mm, height: 6 mm, points: cyl_outside.csv, points_unit: mm")),
                    ":6: parts.col.generator.points", "cyl_outside.csv:3 lies outside the cylinder body");
}

TEST(Decks, CoupledPartsRunAndTheirMistakesNameTheKey)
{
    const std::string deck = std::string(RKFEM_SOURCE_DIR) + "/studies/decks/column_wave_coupled.yaml";
    const fs::path out = fs::temp_directory_path() / "rkfem_out_coupled_ok";
    fs::remove_all(out);
    const Result r = run("run " + deck + " --out " + out.string() +
                         " --quiet --set 'parts.column.generator.size=[2 mm, 2 mm, 40 mm]' --set time.end=6us"
                         " --set 'parts.column.regions.0.select.min=[-1 mm, -1 mm, 20 mm]'");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_TRUE(fs::exists(out / "results.xdmf"));
    // every probe reports its own 12 columns (displacements, velocities, stresses)
    std::ifstream in(out / "summary.json");
    const std::string summary((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (const char* probe : {"\"fe_side\": \\{\"node\": [0-9]+, \"ux\"", "\"rk_side\": \\{\"node\": [0-9]+, \"ux\""})
        EXPECT_TRUE(std::regex_search(summary, std::regex(probe))) << probe << "\n" << summary;
    // ... and ends with szx (before the summary gained the contact column, a probe's first
    // column was read one too early)
    const std::regex last_column("\"szx\": \\{[^}]*\\}\\}");
    EXPECT_EQ(std::distance(std::sregex_iterator(summary.begin(), summary.end(), last_column), std::sregex_iterator()),
              2)
        << summary;

    const std::string part = "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n";
    const std::string region = "    regions:\n      - {select: {type: box, min: [0, 0, 0], max: [1 mm, 1 mm, 5 mm]}}\n";
    expect_rejected("coupled_2x2x2.yaml", replace(good, part, part + "    formulation: fem-2x2x2\n" + region),
                    ":10: parts.col.regions", "expected formulation: fem-nodal or fem-1pt on a part with regions");
    expect_rejected("coupled_plane.yaml",
                    replace(good, part,
                            part + "    formulation: fem-nodal\n    regions:\n"
                                   "      - {select: {type: plane, point: [0, 0, 0], normal: [0, 0, 1]}}\n"),
                    ":10: parts.col.regions.0.select", "expected select type box, cylinder or sphere");
    expect_rejected("coupled_transition.yaml", replace(good, part, part + "    transition: ramp\n"),
                    ":8: parts.col.transition", "remove it or add regions");
    expect_rejected("coupled_all.yaml",
                    replace(good, part,
                            part + "    formulation: fem-nodal\n    regions:\n"
                                   "      - {select: {type: sphere, point: [0, 0, 0], radius: 1 m}}\n"),
                    ":10: parts.col.regions", "leaving no FE region");
}

TEST(Decks, ErosionAndConversionMistakesNameTheKey)
{
    const std::string part = "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n";
    const std::string j2 =
        "    material: {model: j2, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3, sigy: 500 MPa, etan: 1 GPa}\n";
    expect_rejected("erosion_elastic.yaml",
                    replace(good, part, part + "    erosion: {effective_plastic_strain: 0.1}\n"),
                    ":8: parts.col.erosion", "expected material model j2, kcc or cscm");
    expect_rejected(
        "erosion_nodal.yaml",
        replace(good, part, j2 + "    formulation: fem-nodal\n    erosion: {effective_plastic_strain: 0.1}\n"),
        ":9: parts.col.erosion", "expected formulation fem-1pt or fem-2x2x2");
    expect_rejected("erosion_damage.yaml", replace(good, part, j2 + "    erosion: {damage: 1.5}\n"),
                    ":8: parts.col.erosion.damage", "is outside [0, 1]");
    expect_rejected("erosion_none.yaml", replace(good, part, j2 + "    erosion: {damage: 0}\n"),
                    ":8: parts.col.erosion", "has no criterion");
    // conversion: the same criteria, on fem-nodal and fem-1pt parts, not beside erosion; a fem-1pt
    // element's state is blended into the particles, which CSCM's has no rule for
    expect_rejected("conversion_2x2x2.yaml",
                    replace(good, part, j2 + "    formulation: fem-2x2x2\n    conversion: {damage: 0.5}\n"),
                    ":9: parts.col.conversion", "expected formulation: fem-nodal or fem-1pt on a part with conversion");
    expect_rejected("conversion_erosion.yaml",
                    replace(good, part, j2 + "    conversion: {damage: 0.5}\n    erosion: {damage: 0.9}\n"),
                    ":9: parts.col.erosion", "expected erosion or conversion on a part, not both");
    expect_rejected(
        "conversion_1pt_cscm.yaml",
        replace(good, part,
                "    material: {model: cscm, rho: 2400 kg/m^3, fc: 35 MPa}\n    conversion: {damage: 0.5}\n"),
        ":8: parts.col.conversion", "expected formulation: fem-nodal for a converting CSCM part");
    expect_rejected("conversion_elastic.yaml",
                    replace(good, part, part + "    formulation: fem-nodal\n    conversion: {damage: 0.5}\n"),
                    ":9: parts.col.conversion", "expected material model j2, kcc or cscm");
    expect_rejected("conversion_none.yaml",
                    replace(good, part, j2 + "    formulation: fem-nodal\n    conversion: {time_step: 0 s}\n"),
                    ":9: parts.col.conversion", "has no criterion");
    expect_rejected("conversion_negative.yaml",
                    replace(good, part, j2 + "    formulation: fem-nodal\n    conversion: {principal_strain: -0.1}\n"),
                    ":9: parts.col.conversion.principal_strain", "expected a value > 0");
    expect_rejected(
        "conversion_interval.yaml",
        replace(good, part, j2 + "    formulation: fem-nodal\n    conversion: {damage: 0.5, interval: -1 us}\n"),
        ":9: parts.col.conversion.interval", "expected a time >= 0");
    expect_rejected("erosion_interval.yaml", replace(good, part, j2 + "    erosion: {damage: 0.5, interval: 1 us}\n"),
                    ":8: parts.col.erosion.interval", "unknown key");
}

TEST(Decks, TinyOutputIntervalsWriteEveryStepAndEnd)
{
    // an output or history interval far below the step (or below the resolution of t) writes
    // at every step; the loop that advanced the next output time used to spin forever
    const std::string deck = write_deck(
        "tiny_intervals.yaml",
        replace(good, "  end: 1 us\n", "  end: 0.3 us\n  history_interval: 1e-20 s\n  output_interval: 1e-20 s\n"));
    const fs::path out = fs::temp_directory_path() / "rkfem_out_tiny_intervals";
    fs::remove_all(out);
    const Result r = run("run " + deck + " --out " + out.string() + " --quiet");
    ASSERT_EQ(r.code, 0) << r.output;
    std::ifstream in(out / "summary.json");
    const std::string summary((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::smatch steps, outputs;
    ASSERT_TRUE(std::regex_search(summary, steps, std::regex("\"steps\": ([0-9]+)")));
    ASSERT_TRUE(std::regex_search(summary, outputs, std::regex("\"outputs\": ([0-9]+)")));
    EXPECT_EQ(std::stoi(outputs[1]), std::stoi(steps[1]) + 1); // the start and every step

    expect_rejected("dt_max_negative.yaml", replace(good, "  end: 1 us\n", "  end: 1 us\n  dt_max: -1 us\n"),
                    ":4: time.dt_max", "is negative");
}

// A run bounded by time.max_steps with an end time of 1e30 s keeps its output and history
// intervals: the same frames and rows as the same steps with an end of 1 ms (the schedule's
// tolerance was 1e-12 of the end time, 1e18 s: frames at the start and the last step only, a row
// every step)
TEST(Decks, AHugeEndTimeBoundedByMaxStepsKeepsTheIntervals)
{
    auto counts = [&](const std::string& end)
    {
        const fs::path out = fs::temp_directory_path() / ("rkfem_out_end_" + end);
        fs::remove_all(out);
        const Result r = run(
            "run " + write_deck("huge_end.yaml", good) + " --out " + out.string() + " --quiet --set time.end=" + end +
            " --set time.max_steps=45 --set time.output_interval=0.2us --set time.history_interval=0.2us");
        EXPECT_EQ(r.code, 0) << r.output;
        std::ifstream in(out / "history.csv");
        const std::string h((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        std::ifstream sj(out / "summary.json");
        const std::string summary((std::istreambuf_iterator<char>(sj)), std::istreambuf_iterator<char>());
        std::smatch outputs;
        EXPECT_TRUE(std::regex_search(summary, outputs, std::regex("\"outputs\": ([0-9]+)")));
        return std::make_pair(std::stoi(outputs[1]), std::count(h.begin(), h.end(), '\n'));
    };
    const auto huge = counts("1e30"), small = counts("1e-3");
    std::printf("end 1e30 s: %d frames, %ld lines; end 1 ms: %d frames, %ld lines\n", huge.first,
                static_cast<long>(huge.second), small.first, static_cast<long>(small.second));
    EXPECT_EQ(huge, small);
    EXPECT_GT(small.first, 3);
    EXPECT_LT(small.second, 40); // not a row every step
}

// A run whose stable step collapses stops as unstable (exit 3, one line) once the step falls
// below time.dt_min_fraction of the first (default 1e-5): the small column of single 1-point hexes
// buckles through its zero-energy bending modes under its 400 MPa wave by 2.5 us; with the energy
// check loosened, its step fell to 1e-13 s and the run went on for good (minutes of steps to move
// a picosecond)
TEST(Decks, ACollapsingTimeStepStopsTheRun)
{
    const std::string deck =
        write_deck("collapse.yaml", replace(good, "  end: 1 us\n", "  end: 5 us\n  energy_error_limit: 100\n"));
    const fs::path out = fs::temp_directory_path() / "rkfem_out_collapse";
    fs::remove_all(out);
    const Result r = run("run " + deck + " --out " + out.string() + " --quiet");
    EXPECT_EQ(r.code, 3) << r.output;
    EXPECT_NE(r.output.find("below time.dt_min_fraction 1e-05 of the first step"), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    expect_rejected("dt_min_fraction.yaml", replace(good, "  end: 1 us\n", "  end: 1 us\n  dt_min_fraction: 1\n"),
                    ":4: time.dt_min_fraction", "expected 0 <= dt_min_fraction < 1");
}

// Material constants outside their model's validity are refused with the range (a Gruneisen s of
// -5 and gamma0 of -20 were accepted, exit 0)
TEST(Decks, GruneisenConstantsOutsideTheirRangeAreRefused)
{
    const std::string mat = "{model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}";
    auto with = [&](const std::string& eos)
    {
        return replace(
            good, mat,
            "{model: j2, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3, sigy: 300 MPa, etan: 1 GPa, eos: {type: gruneisen, "
            "c0: 4569 m/s, " +
                eos + "}}");
    };
    expect_rejected("eos_s.yaml", with("s: -5, gamma0: 2"), ":7: parts.col.material.eos.s", "expected 0 <= s <= 10");
    expect_rejected("eos_g.yaml", with("s: 1.5, gamma0: -20"), ":7: parts.col.material.eos.gamma0",
                    "expected 0 <= gamma0 <= 10");
    EXPECT_EQ(run("check " + write_deck("eos_ok.yaml", with("s: 1.49, gamma0: 2.17, a: 0.46"))).code, 0);
}

TEST(Decks, QuantitiesMustBeFiniteAndDecksOneDocument)
{
    // a value that overflows to infinity through its unit, and a second YAML document, were
    // accepted silently
    expect_rejected("infinite_E.yaml", replace(good, "E: 200 GPa", "E: 1e300 GPa"), ":7: parts.col.material.E",
                    "is not a finite number in SI units");
    expect_rejected("two_documents.yaml", good + "---\ntitle: second\n", ":12", "holds more than one YAML document");
    // yaml-cpp 0.7's LoadAll never returned on this one (the deck fuzzer's find)
    expect_rejected("loadall.yaml", "# x: \"y\": 1, 40 xts:\n , name: bo)\n    ttom}}\nbog\n", ":2",
                    "holds more than one YAML document");
}

TEST(Decks, ContactsAreCheckedWithTheirLines)
{
    // each contact entry names its surfaces (parts or face sets) and its own keys; a mistake is
    // one line naming the entry
    const std::string wall =
        good + "contacts:\n  - {type: rigid-wall, surfaces: [col], point: [0, 0, 0], normal: [0, 0, 1]}\n";
    expect_rejected("contact_unknown_surface.yaml", replace(wall, "surfaces: [col]", "surfaces: [colum]"),
                    ":13: contacts.0.surfaces.0", "unknown surface 'colum'");
    expect_rejected("contact_zero_normal.yaml", replace(wall, "normal: [0, 0, 1]}\n", "normal: [0, 0, 0]}\n"),
                    ":13: contacts.0.normal", "is the zero vector");
    expect_rejected("contact_bad_type.yaml", replace(wall, "rigid-wall", "rigid_wall"), ":13: contacts.0.type",
                    "'rigid_wall' is not a valid choice");
    expect_rejected("contact_wall_key.yaml",
                    replace(wall, "normal: [0, 0, 1]}\n", "normal: [0, 0, 1], thickness: 1 mm}\n"),
                    ":13: contacts.0.thickness", "unknown key 'thickness'");
    expect_rejected("contact_penalty.yaml",
                    replace(wall, "normal: [0, 0, 1]}\n", "normal: [0, 0, 1], penalty_scale: 2}\n"),
                    ":13: contacts.0.penalty_scale", "is outside (0, 0.80]");
    const std::string pair = good + "contacts:\n  - {type: surface-to-surface, surfaces: [col]}\n";
    expect_rejected("contact_one_surface.yaml", pair, ":13: contacts.0.surfaces", "does not name two surfaces");
    expect_rejected("contact_friction.yaml",
                    replace(pair, "surfaces: [col]", "surfaces: [col, col], friction: {static: -0.1}"),
                    ":13: contacts.0.friction.static", "is negative");
    expect_rejected("contact_damping.yaml", replace(pair, "surfaces: [col]", "surfaces: [col, col], damping: 120 %"),
                    ":13: contacts.0.damping", "is outside [0, 1]");
    // two parts that overlap at the start: the run says how many nodes start inside (held at
    // that depth, not pushed out) and summary.json records them
    {
        const std::string overlap = R"(title: overlap
time: {end: 2 us}
parts:
  a:
    generator: {type: box, size: [2 mm, 2 mm, 2 mm], divisions: [2, 2, 2]}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
  b:
    generator: {type: box, origin: [0, 0, 1.9 mm], size: [2 mm, 2 mm, 2 mm], divisions: [2, 2, 2]}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
contacts:
  - {type: surface-to-surface, surfaces: [a, b]}
)";
        const fs::path out = fs::temp_directory_path() / "rkfem_out_overlap";
        fs::remove_all(out);
        const Result r = run("run " + write_deck("overlap.yaml", overlap) + " --out " + out.string());
        EXPECT_EQ(r.code, 0) << r.output;
        // 9 nodes of each part's face lie 0.1 mm inside the other part
        EXPECT_NE(r.output.find("warning: contacts.0: 18 node(s) start inside the other surface"), std::string::npos)
            << r.output;
        std::ifstream in(out / "summary.json");
        const std::string summary((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        EXPECT_NE(summary.find("\"initial_penetrations\": 18"), std::string::npos);
        // mortar contact holds no offsets: the same nodes, pushed out
        const Result rm = run("run " + write_deck("overlap.yaml", overlap) + " --out " + out.string() +
                              " --set contacts.0.formulation=mortar");
        EXPECT_EQ(rm.code, 0) << rm.output;
        EXPECT_NE(rm.output.find("warning: contacts.0: 18 node(s) start inside the other surface; they are pushed out"),
                  std::string::npos)
            << rm.output;
    }
    // parts that overlap deeper than the contact reaches (max_penetration 0.5 of a 1 mm element
    // behind the surface) are refused at the contact, with the count: b's bottom face 1.1 mm
    // into a's 2 mm cube leaves one node of b out of reach (the face's centre, 0.9 mm above a's
    // bottom, its nearest surface); the face's edge and corner nodes lie on a's sides and its
    // nodes 0.1 mm under a's top are within reach (held); a's nodes inside b come second
    {
        const std::string deep = R"(title: overlap
time: {end: 2 us}
parts:
  a:
    generator: {type: box, size: [2 mm, 2 mm, 2 mm], divisions: [2, 2, 2]}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
  b:
    generator: {type: box, origin: [0, 0, 0.9 mm], size: [2 mm, 2 mm, 2 mm], divisions: [2, 2, 2]}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
contacts:
  - {type: surface-to-surface, surfaces: [a, b]}
)";
        expect_rejected("overlap_deep.yaml", deep, ":11: contacts.0",
                        "1 node(s) of part 'b' start inside part 'a' deeper than the contact reaches (first: node 4 "
                        "of part 'b' (0-based; node 31 in results.h5), 0.0009 m behind its surface)");
        expect_rejected("overlap_deep_single.yaml", replace(deep, "type: surface-to-surface", "type: single-surface"),
                        ":11: contacts.0", "1 node(s) of part 'b' start inside part 'a'");
        // a larger max_penetration reaches the node: held, not refused
        const Result held =
            run("check " + write_deck("overlap_held.yaml",
                                      replace(deep, "surfaces: [a, b]}", "surfaces: [a, b], max_penetration: 1}")));
        EXPECT_EQ(held.code, 0) << held.output;
    }
    // a single-surface contact over clouds alone has no surface
    expect_rejected("contact_clouds.yaml",
                    cloud_deck(", spacing: 1 mm", "    formulation: rkpm\n") +
                        "contacts:\n  - {type: single-surface}\n",
                    ":14: contacts.0.surfaces", "has no surface: every part it names is a particle cloud");
    // mortar contact holds no offsets: it says the nodes are pushed out
    {
        const std::string mortar =
            good + "contacts:\n  - {type: surface-to-surface, surfaces: [col, col], formulation: mortar}\n";
        const Result r = run("check " + write_deck("contact_mortar.yaml", mortar));
        EXPECT_EQ(r.code, 0) << r.output;
        expect_rejected("contact_mortar_single.yaml",
                        replace(wall, "type: rigid-wall, surfaces: [col], point: [0, 0, 0], normal: [0, 0, 1]",
                                "type: single-surface, surfaces: [col], formulation: mortar"),
                        ":13: contacts.0.formulation", "'mortar' is for surface-to-surface contact only");
    }
    // a good contact deck runs, and check echoes the resolved contact
    const std::string deck = write_deck("contact_good.yaml", wall);
    const Result r = run("check " + deck);
    EXPECT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("- {type: rigid-wall, surfaces: [col], point: [0, 0, 0], normal: [0, 0, 1]"),
              std::string::npos)
        << r.output;
}

TEST(Decks, HelpPrintsUsageAndExitsZero)
{
    const Result all = run("--help");
    EXPECT_EQ(all.code, 0) << all.output;
    for (const char* c :
         {"rkfem check DECK", "rkfem run DECK --out DIR", "rkfem convergence SWEEP", "rkfem material-point"})
        EXPECT_NE(all.output.find(c), std::string::npos) << all.output;
    const Result one = run("run --help");
    EXPECT_EQ(one.code, 0) << one.output;
    EXPECT_NE(one.output.find("usage: rkfem run DECK --out DIR"), std::string::npos) << one.output;
    EXPECT_EQ(one.output.find("convergence"), std::string::npos) << one.output;
    EXPECT_EQ(run("").code, 2); // no arguments: usage on stderr, exit 2
}

TEST(Decks, RepeatedPartSetAndProbeNamesAreRefused)
{
    // names are mapping keys: a repeated one was read once and the second silently dropped (two
    // probes of one name made the run fail at its end in HDF5)
    const std::string part = "  col:\n    generator: {type: box, size: [1 mm, 1 mm, 10 mm], element_size: 1 mm}\n"
                             "    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n";
    expect_rejected("repeated_part.yaml", replace(good, "node_sets:", part + "node_sets:"), ":8: parts.col",
                    "key 'col' given twice; each key once (first given on line 5)");
    expect_rejected("repeated_set.yaml",
                    replace(good, "boundary_conditions:",
                            "  end: {part: col, select: {type: named, name: top}}\nboundary_conditions:"),
                    ":10: node_sets.end", "key 'end' given twice");
    expect_rejected("repeated_probe.yaml", good + "probes:\n  p: {point: [0, 0, 0]}\n  p: {point: [0, 0, 1 mm]}\n",
                    ":14: probes.p", "key 'p' given twice; each key once (first given on line 13)");
}

TEST(Decks, DevicesFifosAndDirectoriesAreRefusedNotRead)
{
    // check on /dev/zero or on a FIFO with no writer hung; a directory gave no line
    ::unlink("/tmp/rkfem_test_fifo");
    ASSERT_EQ(::mkfifo("/tmp/rkfem_test_fifo", 0600), 0);
    for (const std::string f : {"/dev/zero", "/tmp/rkfem_test_fifo", "/tmp"})
        for (const char* cmd : {"check ", "convergence ", "material-point "})
        {
            // the executable behind timeout, so a regression fails instead of hanging
            const std::string out = std::string(cmd) == "check " ? "" : " --out /tmp/rkfem_never";
            const Result r = run_shell(std::string("timeout 20 ") + RKFEM_EXE + " " + cmd + f + out + " 2>&1");
            EXPECT_EQ(r.code, 2) << cmd << f << ": " << r.output;
            EXPECT_NE(r.output.find(f + ": "), std::string::npos) << r.output;
            EXPECT_NE(r.output.find("is not a regular file"), std::string::npos) << r.output;
        }
    ::unlink("/tmp/rkfem_test_fifo");
}

TEST(Decks, MeshesThatCannotFitAreRefusedBeforeAllocation)
{
    // element_size 1e-30 m overflowed the division count to one element; 0.1 mm (1e8 hexes,
    // about 150 GB) ran until the allocator failed with "internal error: std::bad_alloc"
    expect_rejected("tiny_elements.yaml", replace(good, "element_size: 1 mm", "element_size: 1e-30 m"),
                    ":6: parts.col.generator", "cells; expected fewer than 2.5e8 cells per part");
    // 2e8 hexes: within the 32-bit indices, about 300 GB
    const std::string big = replace(replace(good, "size: [1 mm, 1 mm, 10 mm]", "size: [20 mm, 20 mm, 500 mm]"),
                                    "element_size: 1 mm", "element_size: 0.1 mm");
    expect_rejected("huge_mesh.yaml", big, ":6: parts.col.generator", "GB");
    // under a process limit the machine's memory is not what counts: 1e7 hexes (about 15 GB)
    // under `ulimit -v` of 2 GB ended in "internal error: std::bad_alloc"
    const std::string ten_million =
        write_deck("ulimit_mesh.yaml", replace(good, "element_size: 1 mm", "divisions: [215, 215, 215]"));
    const Result r = run_shell("ulimit -v 2000000 && " + std::string(RKFEM_EXE) + " check " + ten_million + " 2>&1");
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_NE(r.output.find("ulimit_mesh.yaml:6: parts.col.generator: needs about"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("GB this process may use (ulimit -v (address space))"), std::string::npos) << r.output;
}

TEST(Decks, OptionsASubcommandDoesNotTakeAreRefused)
{
    // material-point and convergence accepted and ignored --set; check ignored --out
    const std::string mp = std::string(RKFEM_SOURCE_DIR) + "/studies/material_points/steel_uniaxial.yaml";
    Result r = run("material-point " + mp + " --out /tmp/rkfem_never --set material.E=1");
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_NE(r.output.find("material-point takes no --set"), std::string::npos) << r.output;
    r = run("convergence " + std::string(RKFEM_SOURCE_DIR) +
            "/studies/sweeps/mms_smoke.yaml --out /tmp/rkfem_never --set a=1");
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_NE(r.output.find("convergence takes no --set"), std::string::npos) << r.output;
    r = run("check " + write_deck("good_check.yaml", good) + " --out /tmp/rkfem_never");
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_NE(r.output.find("check writes nothing and takes no --out"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists("/tmp/rkfem_never"));
}

TEST(Decks, TubeKeysAreChecked)
{
    const std::string tube =
        replace(good, "generator: {type: box, size: [1 mm, 1 mm, 10 mm], element_size: 1 mm}",
                "generator: {type: cylinder, radius: 5 mm, inner_radius: 5 mm, height: 10 mm, element_size: 1 mm}");
    expect_rejected("tube_r.yaml", tube, ":6: parts.col.generator.inner_radius", "expected 0 < inner_radius < radius");
    expect_rejected("tube_core.yaml", replace(tube, "inner_radius: 5 mm", "inner_radius: 4 mm, core: ogrid"),
                    ":6: parts.col.generator.core", "a tube has no core");
}

namespace
{
/// history.csv of a run: its column names and its rows.
struct History
{
    std::vector<std::string> columns;
    std::vector<std::vector<double>> rows;
    /// The index of a column (columns.size() when there is none).
    std::size_t column(const std::string& name) const
    {
        return static_cast<std::size_t>(std::find(columns.begin(), columns.end(), name) - columns.begin());
    }
};
History read_history(const fs::path& file)
{
    History h;
    std::ifstream csv(file);
    std::string header;
    std::getline(csv, header);
    std::stringstream hs(header);
    for (std::string c; std::getline(hs, c, ',');)
        h.columns.push_back(c);
    for (std::string line; std::getline(csv, line);)
    {
        std::stringstream ls(line);
        std::vector<double>& v = h.rows.emplace_back();
        for (std::string c; std::getline(ls, c, ',');)
            v.push_back(std::stod(c));
    }
    return h;
}
} // namespace

TEST(Decks, HistoryCountsTheRkElementsOfAConvertingPart)
{
    // evolutionary coupling: part_bar_rk_elements grows from 0 and ends at the summary's count
    const fs::path out = fs::temp_directory_path() / "rkfem_test_decks" / "rk_elements_column";
    const Result r = run("run " + std::string(RKFEM_SOURCE_DIR) + "/studies/decks/concrete_bar_conversion.yaml --out " +
                         out.string() + " --quiet --set parts.bar.generator.element_size=5mm --set time.end=20us");
    ASSERT_EQ(r.code, 0) << r.output;
    const History h = read_history(out / "history.csv");
    const std::size_t k = h.column("part_bar_rk_elements");
    ASSERT_LT(k, h.columns.size());
    ASSERT_FALSE(h.rows.empty());
    double previous = 0;
    for (const auto& v : h.rows)
    {
        EXPECT_GE(v[k], previous);
        previous = v[k];
    }
    std::ifstream js(out / "summary.json");
    const std::string summary((std::istreambuf_iterator<char>(js)), std::istreambuf_iterator<char>());
    std::smatch mt;
    ASSERT_TRUE(std::regex_search(summary, mt, std::regex("\"converted_elements\": ([0-9]+)")));
    EXPECT_EQ(h.rows.front()[k], 0.0);
    EXPECT_GT(h.rows.back()[k], 0.0);
    EXPECT_EQ(h.rows.back()[k], std::stod(mt[1].str()));
}

TEST(Decks, HistoryCarriesEachLoadsValue)
{
    // a pressure ramp on the tube of the P2 deck: the column load_outer is the curve at each row
    const fs::path out = fs::temp_directory_path() / "rkfem_test_decks" / "load_column";
    const Result r = run("run " + std::string(RKFEM_SOURCE_DIR) + "/studies/decks/p2_implosion.yaml --out " +
                         out.string() + " --quiet --set parts.tube.generator.element_size=0.8in --set time.end=0.2ms");
    ASSERT_EQ(r.code, 0) << r.output;
    const History h = read_history(out / "history.csv");
    const std::size_t k = h.column("load_outer");
    ASSERT_LT(k, h.columns.size());
    EXPECT_LT(h.column("load_end"), h.columns.size());
    for (std::size_t row = 0; row < h.rows.size(); ++row)
    {
        const auto& v = h.rows[row];
        // 4,000 psi over 20 ms
        EXPECT_NEAR(v[k], 4000 * 6894.757293168361 * v[0] / 0.02, 1e-6 * 4000 * 6894.757) << "row " << row;
    }
    EXPECT_GT(h.rows.size(), 5u);
}

TEST(Decks, EveryPartOfTheMultiPartDecksChecksAsRkpm)
{
    // each part of the shipped two-part decks as rkpm: `check` builds the whole model (its RK part
    // numbered after the other), and either passes or refuses the deck with an input error; it
    // never crashes (P6's target as rkpm once corrupted the heap: its NSNI triplets kept the
    // part's own node numbers)
    struct Case
    {
        const char* deck;
        const char* part;
        int code;
    };
    for (const Case& c : {Case{"p6_fsp_cylinder.yaml", "fsp", 0}, Case{"p6_fsp_cylinder.yaml", "target", 0},
                          Case{"fsp_impact.yaml", "fsp", 0}, Case{"fsp_impact.yaml", "panel", 2}})
    {
        const Result r = run(std::string("check ") + RKFEM_SOURCE_DIR + "/studies/decks/" + c.deck + " --set parts." +
                             c.part + ".formulation=rkpm");
        EXPECT_EQ(r.code, c.code) << c.deck << ", part " << c.part << " as rkpm:\n" << r.output.substr(0, 2000);
        if (c.code == 2) // panel: erosion needs Gauss-point elements
        {
            EXPECT_NE(r.output.find("parts.panel.erosion"), std::string::npos) << r.output;
        }
    }
}

TEST(Decks, CheckEchoesGeneratedParametersAndWhatSetsTheStep)
{
    // K&C f'c 45.6 MPa on 2.5 mm cubes (concrete_bar_kcc.yaml): the generated parameters with
    // units, and the stable step of a cube, h / c_L with c_L from the printed K1 and G
    const Result r = run("check " + std::string(RKFEM_SOURCE_DIR) + "/studies/decks/concrete_bar_kcc.yaml");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("#  part bar:\n#   K&C concrete Release III (MAT_072R3), generated from f'c:"),
              std::string::npos)
        << r.output;
    for (const char* key : {"fc = 4.56e+07 Pa", "a2 = ", "1/Pa", "b1 = ", "EOS_8 pressure [Pa]:", "eta(lambda):"})
        EXPECT_NE(r.output.find(key), std::string::npos) << key;
    auto number_after = [&](const std::string& key)
    {
        const auto p = r.output.find(key);
        EXPECT_NE(p, std::string::npos) << key;
        return p == std::string::npos ? 0.0 : std::stod(r.output.substr(p + key.size()));
    };
    const double K = number_after("K1 = "), G = number_after(" G = "), ft = number_after("ft = ");
    // f_t = 1.58 (f'c^2)^(1/3) psi (Malvar et al.; materials.md)
    const double psi = 6894.757293168361, fc_psi = 4.56e7 / psi;
    EXPECT_NEAR(ft, 1.58 * std::cbrt(fc_psi * fc_psi) * psi, 1e-3 * ft);
    const double dt = number_after("# time step: ");
    EXPECT_NEAR(dt, 2.5e-3 / std::sqrt((K + 4 * G / 3) / 2400), 1e-5 * dt);
    EXPECT_NE(r.output.find("x time.dt_scale 0.9 = "), std::string::npos);
    EXPECT_NE(r.output.find(", set by part 'bar' element "), std::string::npos) << r.output;
    // an elastic deck has nothing generated
    const Result e = run("check " + write_deck("plain_check.yaml", good));
    EXPECT_NE(e.output.find("#   none (every material's parameters are the deck's own)"), std::string::npos)
        << e.output;
}

TEST(Decks, SectionKeysAreChecked)
{
    expect_rejected("section_normal.yaml", good + "sections:\n  s: {point: [0, 0, 5 mm], normal: [0, 0, 0]}\n",
                    ":13: sections.s.normal", "expected the plane's normal");
    expect_rejected("section_part.yaml",
                    good + "sections:\n  s: {point: [0, 0, 5 mm], normal: [0, 0, 1], part: nope}\n",
                    ":13: sections.s.part", "expected the name of a part");
    expect_rejected(
        "section_twice.yaml",
        good +
            "sections:\n  s: {point: [0, 0, 5 mm], normal: [0, 0, 1]}\n  s: {point: [0, 0, 6 mm], normal: [0, 0, 1]}\n",
        ":14: sections.s", "each key once");
}

TEST(Decks, UnitMismatchSaysWhatIsExpected)
{
    expect_rejected("unit_mismatch.yaml", replace(good, "E: 200 GPa", "E: 200 m"), ":7: parts.col.material.E",
                    "not a pressure or stress (e.g. 5000 psi, 200 GPa); expected a pressure");
    // and through --set
    const Result r = run("check " + write_deck("unit_set.yaml", good) + " --set 'parts.col.material.rho=3 m/s'");
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.output.find("--set parts.col.material.rho=3 m/s: parts.col.material.rho: "), std::string::npos)
        << r.output;
    EXPECT_NE(r.output.find("; expected a density"), std::string::npos) << r.output;
}

TEST(Decks, AnOutputPathThatCannotBeADirectoryIsRefusedBeforeTheRun)
{
    const fs::path file = fs::temp_directory_path() / "rkfem_test_decks" / "a_file";
    fs::create_directories(file.parent_path());
    std::ofstream(file) << "x";
    for (const std::string& out : std::vector<std::string>{file.string(), file.string() + "/below"})
    {
        const Result r = run("run " + write_deck("out_file.yaml", good) + " --out " + out);
        EXPECT_EQ(r.code, 2) << r.output;
        EXPECT_NE(r.output.find("rkfem: --out " + out + ": cannot create the output directory"), std::string::npos)
            << r.output;
        EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    }
}

TEST(Decks, TheLastProgressLineShowsTheRunsEnergyRatio)
{
    // the final line used to print a constant 1.0000; it is the ledger's ratio, as summary.json's
    const fs::path out = fs::temp_directory_path() / "rkfem_test_decks" / "progress_ratio";
    const Result r = run("run " + std::string(RKFEM_SOURCE_DIR) + "/studies/decks/column_wave.yaml --out " +
                         out.string() + " --set 'parts.column.generator.size=[2 mm, 2 mm, 200 mm]'");
    ASSERT_EQ(r.code, 0) << r.output;
    const auto at = r.output.rfind("energy ratio ");
    ASSERT_NE(at, std::string::npos) << r.output;
    const double shown = std::stod(r.output.substr(at + 13));
    std::ifstream js(out / "summary.json");
    const std::string s((std::istreambuf_iterator<char>(js)), std::istreambuf_iterator<char>());
    auto field = [&](const std::string& key)
    {
        const auto p = s.find("\"" + key + "\": ");
        EXPECT_NE(p, std::string::npos) << key;
        return std::stod(s.substr(p + key.size() + 4));
    };
    const double total = field("kinetic") + field("internal") + field("hourglass") + field("bulk_viscosity") +
                         field("contact") + field("eroded") + field("damping");
    const double ref = field("kinetic0") + field("internal0") + field("external_work");
    EXPECT_NEAR(shown, total / ref, 1e-4);
    EXPECT_NE(r.output.substr(at + 13, 6), "1.0000") << r.output;
}

TEST(Decks, MaterialPointPathsThatLeaveFiniteNumbersAreRefused)
{
    // NaN / inf rows used to be written with exit 0, and steps past 2^31 wrapped around
    const std::string head =
        "title: t\nmaterial: {model: j2, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3, sigy: 300 MPa, etan: 1 GPa}\n";
    const std::pair<std::string, std::string> bad[] = {
        {"path: {type: uniaxial-stress, strain: 1e300, rate: 1 1/s, steps: 10}\n",
         ":3: path: the point's state is not finite at step 1"},
        {"path: {type: uniaxial-stress, strain: 0.01, rate: 4.9e-324 1/s, steps: 10}\n",
         ":3: path: the point's state is not finite"},
        {"path: {type: rotation, strain: 0.01, rate: 1 1/s, steps: 10, angle: 1e300}\n",
         "check path.strain, path.rate, path.angle"},
        {"path: {type: uniaxial-stress, strain: 0.01, rate: 1 1/s, steps: 4294967297}\n",
         ":3: path.steps: is above 10^8"},
        {"path: {type: uniaxial-stress, strain: 0.01, rate: 1 1/s, steps: 2147483648}\n",
         ":3: path.steps: is above 10^8"},
    };
    const fs::path out = fs::temp_directory_path() / "rkfem_test_decks" / "mp_bad_out";
    for (const auto& [path, expect] : bad)
    {
        fs::remove_all(out);
        const Result r = run("material-point " + write_deck("mp_bad.yaml", head + path) + " --out " + out.string());
        EXPECT_EQ(r.code, 2) << path << r.output;
        EXPECT_NE(r.output.find(expect), std::string::npos) << path << r.output;
        EXPECT_FALSE(fs::exists(out / "stress_strain.csv")) << path;
    }
}

TEST(Decks, AnEndTimeBeyondTenBillionStepsIsRefused)
{
    // end: 1e30 s used to run "forever"; max_steps bounds a run, so it lets the deck through
    const fs::path out = fs::temp_directory_path() / "rkfem_test_decks" / "endless";
    fs::remove_all(out);
    const std::string f = write_deck("endless.yaml", replace(good, "end: 1 us", "end: 1e30 s"));
    const Result r =
        run_shell(std::string("timeout 60 ") + RKFEM_EXE + " run " + f + " --out " + out.string() + " 2>&1");
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_NE(r.output.find("time.end: 1e+30 s would take about"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("; expected an end time within 10^10 steps"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out));
    const Result bounded = run("run " + f + " --out " + out.string() + " --quiet --set time.max_steps=5");
    EXPECT_EQ(bounded.code, 0) << bounded.output;
}

TEST(Decks, OverridesThatDoNotFitTheDeckGetALine)
{
    // each used to end in exit 1 "internal error" (stoul, yaml-cpp) or blame the deck for the --set
    const std::string f = write_deck("override_fit.yaml", good);
    const std::pair<std::string, std::string> cases[] = {
        {"boundary_conditions.foo=1",
         "--set boundary_conditions.foo=1: boundary_conditions.foo: 'foo' indexes a list; expected an index 0..0"},
        {"boundary_conditions.0.x.y=1", "--set boundary_conditions.0.x.y=1: "},
        {"title.x=1", "'title' is a value, not a section; expected a path through mappings and lists"},
        {"time.end=", "--set time.end=: time.end: has no value after '='; expected a value"},
        {"parts.col.generator.size.5=1", "index 5 is past the end; expected 0..2, or 3 to append an entry"},
        {"boundary_conditions.2.fixed=all", "index 2 is past the end; expected 0..0"},
    };
    for (const auto& [o, expect] : cases)
    {
        const Result r = run("check " + f + " --set '" + o + "'");
        EXPECT_EQ(r.code, 2) << o << ": " << r.output;
        EXPECT_NE(r.output.find(expect), std::string::npos) << o << ": " << r.output;
        EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    }
    // the list's size as the last key appends an entry (the check prints the resolved deck); not
    // as a key on the way to one
    const Result appended = run(
        "check " + f + " --set 'boundary_conditions.1={node_set: end, fixed: [x]}' --set 'boundary_conditions.2.x=1'");
    EXPECT_EQ(appended.code, 2) << appended.output;
    const Result append = run("check " + f + " --set 'boundary_conditions.1={node_set: end, fixed: [x]}'");
    EXPECT_EQ(append.code, 0) << append.output;
    EXPECT_NE(append.output.find("  - {node_set: end, velocity: {z: 10}}\n  - {node_set: end, fixed: [x]}\n"),
              std::string::npos)
        << append.output;
    const Result scalar = run("check " + write_deck("scalar_deck.yaml", "5\n") + " --set a.b=1");
    EXPECT_EQ(scalar.code, 2) << scalar.output;
    EXPECT_NE(scalar.output.find("the deck is a value, not a section"), std::string::npos) << scalar.output;
    const Result key = run("check " + write_deck("complex_key.yaml", "? [a, b]\n: 1\n"));
    EXPECT_EQ(key.code, 2) << key.output;
    EXPECT_NE(key.output.find("complex_key.yaml:1"), std::string::npos) << key.output;
    EXPECT_NE(key.output.find("expected mappings whose keys are plain names"), std::string::npos) << key.output;
}

TEST(Decks, ConvergenceSweepsThatCannotGiveARateAreRefused)
{
    // each used to run (rates -nan) or fail with exit 1 after writing convergence.csv
    const std::pair<std::string, std::string> bad[] = {
        {"resolutions: [2, 2]\ncases: [{formulation: rkpm}]\n",
         ":1: resolutions.1: 2 does not refine 2; expected increasing"},
        {"resolutions: [4, 2]\ncases: [{formulation: rkpm}]\n", ":1: resolutions.1: 2 does not refine 4"},
        {"resolutions: [2, 4]\ncases: [{formulation: rkpm, stabilization: -1}]\n",
         ":2: cases.0.stabilization: is negative"},
        {"resolutions: [2, 3]\ncases: [{formulation: fem-nodal, scheme: dni}]\n",
         ":2: cases.0.scheme: direct nodal integration of trilinear FE functions is undefined"},
        {"resolutions: [2, 3]\ncases: [{formulation: rkpm, normalized_support: 0.5}]\n",
         ":2: cases.0.normalized_support: is outside [1, 4]"},
        {"5\n", ": (file): is not a YAML mapping"},
        {"[1, 2]\n", ": (file): is not a YAML mapping"},
        {"? [a, b]\n: 1\n", ":1: (file): bad conversion; expected a sweep whose keys are plain names"},
    };
    const fs::path out = fs::temp_directory_path() / "rkfem_test_decks" / "sweep_out";
    for (const auto& [text, expect] : bad)
    {
        fs::remove_all(out);
        const Result r = run("convergence " + write_deck("sweep_bad.yaml", text) + " --out " + out.string());
        EXPECT_EQ(r.code, 2) << text << r.output;
        EXPECT_NE(r.output.find(expect), std::string::npos) << text << r.output;
        EXPECT_FALSE(fs::exists(out / "convergence.csv")) << text;
    }
}

TEST(Decks, MessagesArePrintableAndShort)
{
    // control characters (and NUL, which cut the line) as \xNN; a 5 MB value cut in the middle
    std::string ctl = replace(good, "end: 1 us", std::string("end: \"1 \x01\x07 us\""));
    const Result c = run("check " + write_deck("control_chars.yaml", ctl));
    EXPECT_EQ(c.code, 2) << c.output;
    EXPECT_NE(c.output.find("unexpected character '\\x01' in unit '\\x01\\x07 us'"), std::string::npos) << c.output;
    EXPECT_EQ(c.output.find('\x01'), std::string::npos);
    // one "; expected": parse_quantity's own expectation is not repeated
    EXPECT_EQ(c.output.find("; expected"), c.output.rfind("; expected")) << c.output;
    const Result big =
        run("check " +
            write_deck("big_value.yaml", replace(good, "end: 1 us", "end: \"" + std::string(5000000, 'x') + "\"")));
    EXPECT_EQ(big.code, 2);
    EXPECT_LT(big.output.size(), 600u) << big.output.substr(0, 600);
    EXPECT_NE(big.output.find("characters cut"), std::string::npos);
    EXPECT_NE(big.output.find("; expected a time"), std::string::npos);
}

namespace
{
/// Dataset `name` of results.h5's last step: its values (as doubles), bytes per value and filter count.
struct StoredField
{
    std::vector<double> values;
    std::size_t bytes = 0;
    int filters = 0;
};
StoredField last_step_field(const fs::path& out, const std::string& name)
{
    StoredField r;
    const hid_t f = H5Fopen((out / "results.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    EXPECT_GE(f, 0);
    const hid_t steps = H5Gopen2(f, "steps", H5P_DEFAULT);
    hsize_t n = 0;
    H5Gget_num_objs(steps, &n);
    char last[16];
    std::snprintf(last, sizeof last, "%06d", static_cast<int>(n) - 1);
    const hid_t d = H5Dopen2(steps, (std::string(last) + "/" + name).c_str(), H5P_DEFAULT);
    const hid_t type = H5Dget_type(d), space = H5Dget_space(d), dcpl = H5Dget_create_plist(d);
    r.bytes = H5Tget_size(type);
    r.filters = H5Pget_nfilters(dcpl);
    r.values.resize(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space)));
    H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, r.values.data());
    H5Pclose(dcpl);
    H5Sclose(space);
    H5Tclose(type);
    H5Dclose(d);
    H5Gclose(steps);
    H5Fclose(f);
    return r;
}
} // namespace

// output: {precision, compression}. The same run stored three ways: double (the values), single
// (each value is the double rounded to float, exactly; coordinates stay double), single with gzip
// (the same floats, bitwise, from a chunked and filtered dataset); the XDMF index states each
// dataset's precision so ParaView reads it; a level outside 0-9 is refused with its key.
TEST(Decks, OutputPrecisionAndCompression)
{
    std::map<std::string, fs::path> outs;
    for (const auto& [name, sets] : std::vector<std::pair<std::string, std::string>>{
             {"double", "--set output.precision=double"}, {"single", ""}, {"gzip", "--set output.compression=4"}})
    {
        outs[name] = fs::temp_directory_path() / ("rkfem_out_storage_" + name);
        fs::remove_all(outs[name]);
        const Result r =
            run("run " + write_deck("storage.yaml", good) + " --out " + outs[name].string() + " --quiet " + sets);
        ASSERT_EQ(r.code, 0) << r.output;
    }
    const StoredField d = last_step_field(outs["double"], "velocity"), s = last_step_field(outs["single"], "velocity"),
                      g = last_step_field(outs["gzip"], "velocity");
    EXPECT_EQ(d.bytes, 8u);
    EXPECT_EQ(s.bytes, 4u);
    EXPECT_EQ(g.bytes, 4u);
    EXPECT_EQ(s.filters, 0);
    EXPECT_EQ(g.filters, 2); // shuffle, deflate
    ASSERT_EQ(d.values.size(), s.values.size());
    double vmax = 0.0;
    for (std::size_t i = 0; i < d.values.size(); ++i)
    {
        EXPECT_EQ(s.values[i], static_cast<double>(static_cast<float>(d.values[i]))) << i;
        EXPECT_EQ(g.values[i], s.values[i]) << i;
        vmax = std::max(vmax, std::abs(d.values[i]));
    }
    EXPECT_GT(vmax, 0.0); // the driven end moves: the comparison is not of zeros
    EXPECT_EQ(last_step_field(outs["single"], "coordinates").bytes, 8u);
    EXPECT_EQ(last_step_field(outs["gzip"], "coordinates").values,
              last_step_field(outs["double"], "coordinates").values);
    std::ifstream x(outs["single"] / "results.xdmf");
    const std::string xdmf((std::istreambuf_iterator<char>(x)), std::istreambuf_iterator<char>());
    EXPECT_NE(xdmf.find("Precision=\"4\" Format=\"HDF\">results.h5:/steps/000000/velocity"), std::string::npos) << xdmf;
    EXPECT_NE(xdmf.find("Precision=\"8\" Format=\"HDF\">results.h5:/steps/000000/coordinates"), std::string::npos);
    expect_rejected("storage_level.yaml", good + "output: {compression: 12}\n",
                    ":" + std::to_string(std::count(good.begin(), good.end(), '\n') + 1) + ": output.compression",
                    "expected a gzip level from 0 (none) to 9 (smallest)");
}

// Nesting past yaml-cpp's depth guard: one located line that says so (it said "YAML syntax error:
// bad file").
TEST(Decks, DeepNestingIsNamed)
{
    const std::string deep =
        "title: x\ntime: {end: 1 us}\nparts: " + std::string(2100, '[') + std::string(2100, ']') + "\n";
    expect_rejected("deep_nesting.yaml", deep, ":3: deck", "nested deeper than the YAML reader allows");
}

TEST(Decks, KeywordMeshesResolveAgainstTheDeckAndTheResolvedDeckReadsBack)
{
    // a mesh file named relative to the deck, in millimetres: check reads it (10 elements) and
    // prints a resolved deck that names the unit as written and reads back the same
    std::ostringstream k;
    k << "*KEYWORD\n*NODE\n";
    for (int j = 0; j <= 10; ++j)
        for (int c = 0; c < 4; ++c)
            k << 4 * j + c + 1 << "," << (c == 1 || c == 2) << "," << (c >= 2) << "," << j << "\n";
    k << "*ELEMENT_SOLID\n";
    for (int j = 0; j < 10; ++j)
    {
        k << 1001 + j << ",3";
        for (int c = 0; c < 8; ++c)
            k << "," << 4 * (j + c / 4) + c % 4 + 1;
        k << "\n";
    }
    k << "*END\n";
    write_deck("column.k", k.str());
    std::string deck = replace(good, "generator: {type: box, size: [1 mm, 1 mm, 10 mm], element_size: 1 mm}",
                               "generator: {type: keyword, file: column.k, unit: mm, pid: 3}");
    const Result r = run("check " + write_deck("keyword.yaml", deck));
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("unit: mm, pid: [3]"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("10 elements"), std::string::npos) << r.output;
    const std::string resolved = r.output.substr(r.output.find("# resolved deck"));
    const Result again = run("check " + write_deck("keyword_resolved.yaml", resolved));
    EXPECT_EQ(again.code, 0) << again.output;
    // a unit that is not a length
    expect_rejected("keyword_unit.yaml", replace(deck, "unit: mm", "unit: kg"), ":6: parts.col.generator.unit",
                    "'kg' is not a length unit");
    // two cubes that touch but do not share their nodes (an unmerged mesh): noted, not refused
    write_deck("unmerged.k", "*NODE\n1,0,0,0\n2,1,0,0\n3,1,1,0\n4,0,1,0\n5,0,0,1\n6,1,0,1\n7,1,1,1\n8,0,1,1\n"
                             "9,0,0,1\n10,1,0,1\n11,1,1,1\n12,0,1,1\n13,0,0,2\n14,1,0,2\n15,1,1,2\n16,0,1,2\n"
                             "*ELEMENT_SOLID\n1,3,1,2,3,4,5,6,7,8\n2,3,9,10,11,12,13,14,15,16\n");
    const Result unmerged = run("check " + write_deck("unmerged.yaml", replace(deck, "column.k", "unmerged.k")));
    EXPECT_EQ(unmerged.code, 0) << unmerged.output;
    EXPECT_NE(unmerged.output.find("parts.col: 4 node(s) share their position with another node of the part (first: "
                                   "NIDs 5 and 9); the elements on either side are not connected there"),
              std::string::npos)
        << unmerged.output;
    // an element that inverts is named by the file's EID (its cell in results.h5 beside it)
    const fs::path out = fs::temp_directory_path() / "rkfem_out_keyword_unstable";
    fs::remove_all(out);
    const Result u = run(
        "run " +
        write_deck("keyword_unstable.yaml",
                   replace(deck, "boundary_conditions:\n  - {node_set: end, velocity: {z: 10 m/s}}\n",
                           "face_sets:\n  top: {part: col, select: {type: plane, point: [0, 0, 10 mm], "
                           "normal: [0, 0, 1]}}\nloads:\n  - {type: pressure, face_set: top, pressure: 1e16 Pa}\n")) +
        " --out " + out.string() + " --quiet");
    EXPECT_EQ(u.code, 3) << u.output;
    EXPECT_NE(
        u.output.find("element 1010 (the mesh file's EID; part 'col', cell 9 in results.h5) has non-positive volume"),
        std::string::npos)
        << u.output;
}
