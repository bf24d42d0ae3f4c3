/// @file study.cpp
/// Running a study's cases (each a run of the base deck with its settings), reusing whole ones.
#include "rkfem/run/study.hpp"
#include "rkfem/run/study_detail.hpp"

#include <hdf5.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iterator>
#include <limits>
#include <sstream>

#include "rkfem/config/deck_section.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/core/file_output.hpp"
#include "rkfem/core/interrupt.hpp"
#include "rkfem/core/units.hpp"
#include "rkfem/io/hdf5_dataset.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/run/check_report.hpp"
#include "rkfem/run/simulation.hpp"
#include "rkfem/run/summary.hpp"

namespace rkfem
{
using namespace study_detail;
namespace
{
long long history_csv_rows(const fs::path& p)
{
    std::ifstream in(p, std::ios::binary);
    if (!in)
        return -1;
    const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    const long long lines = static_cast<long long>(std::count(text.begin(), text.end(), '\n'));
    return lines - 1; // the header; a row cut short has no newline and does not count
}

} // namespace

std::vector<StudyCaseResult> run_study(const Study& st, const std::string& out_dir, bool progress)
{
    const fs::path out(out_dir);
    std::error_code ec;
    fs::create_directories(out / "cases", ec);
    if (ec)
        throw Error("cannot create " + (out / "cases").string() + ": " + ec.message());
    std::vector<StudyCaseResult> results;
    const auto wall0 = std::chrono::steady_clock::now();
    const std::size_t n = st.cases.size();
    for (std::size_t c = 0; c < n; ++c)
    {
        const StudyCase& sc = st.cases[c];
        StudyCaseResult r;
        r.name = sc.name;
        r.values.assign(st.metrics.size(), nan);
        const fs::path dir = out / "cases" / sc.name;
        const auto t0 = std::chrono::steady_clock::now();
        if (interrupt_signal() != 0)
        {
            // SIGINT / SIGTERM: the case that was running wrote its last state; later ones do not run
            r.status = "interrupted";
            r.message =
                std::string("not run: the study was interrupted by ") + interrupt_signal_name(interrupt_signal());
            results.push_back(std::move(r));
            continue;
        }
        try
        {
            const Deck deck = read_deck(sc.deck, sc.overrides);
            const std::string hash = resolved_deck_hash(deck);
            bool reuse = false;
            std::error_code ec;
            if (fs::exists(dir / "summary.json", ec))
            {
                try
                {
                    const YAML::Node old = YAML::LoadFile((dir / "summary.json").string());
                    // the same problem run to its end by this very build (a rebuilt solver,
                    // or a summary from before builds were recorded, runs again)
                    reuse = old["deck_hash"] && old["deck_hash"].as<std::string>() == hash && old["status"] &&
                            old["status"].as<std::string>() == "completed" && !solver_build_id().empty() &&
                            old["build"] && old["build"].as<std::string>() == solver_build_id();
                    // and its history whole: as many rows as the run wrote (a truncated or deleted
                    // history.csv runs the case again; its metrics came from what was left)
                    reuse = reuse && old["history_rows"] &&
                            history_csv_rows(dir / "history.csv") == old["history_rows"].as<long long>();
                }
                catch (const YAML::Exception&)
                {
                    reuse = false; // unreadable: run again
                }
            }
            if (reuse)
                r.status = "reused";
            else
            {
                if (progress)
                    std::fprintf(stderr, "study: [%zu/%zu] %s: running\n", c + 1, n, sc.name.c_str());
                fs::remove_all(dir, ec);
                fs::create_directories(dir, ec);
                if (ec)
                    throw Error("cannot create " + dir.string() + ": " + ec.message());
                Model model = Model::build(deck);
                check_step_budget(model);
                RunOptions opt;
                opt.setup_seconds = std::chrono::duration<real_t>(std::chrono::steady_clock::now() - t0).count();
                opt.out_dir = dir.string();
                opt.progress = progress;
                opt.deck_path = sc.deck;
                opt.overrides = sc.overrides;
                const RunSummary s = run_simulation(model, opt);
                r.status = s.status;
                r.message = s.message;
            }
            if (r.status == "completed" || r.status == "reused")
            {
                const YAML::Node summary = YAML::LoadFile((dir / "summary.json").string());
                r.history = read_history_csv((dir / "history.csv").string());
                for (std::size_t k = 0; k < st.metrics.size(); ++k)
                    r.values[k] = extract_metric(st.metrics[k], r.history, summary) / st.metrics[k].unit_scale;
                r.wall_seconds = summary["wall_seconds"] ? summary["wall_seconds"].as<real_t>() : 0.0;
            }
        }
        catch (const std::exception& e)
        {
            r.status = "failed";
            r.message = e.what();
        }
        // what a case that stopped early left (study.h5 carries every history there is)
        std::error_code ec;
        if (r.history.columns.empty() && fs::exists(dir / "history.csv", ec))
            r.history = read_history_csv((dir / "history.csv").string());
        const real_t took = std::chrono::duration<real_t>(std::chrono::steady_clock::now() - t0).count();
        if (progress)
        {
            const real_t elapsed = std::chrono::duration<real_t>(std::chrono::steady_clock::now() - wall0).count();
            std::fprintf(stderr, "study: [%zu/%zu] %s: %s in %.1f s%s%s (study %.0f s, ETA %.0f s)\n", c + 1, n,
                         sc.name.c_str(), r.status.c_str(), took, r.message.empty() ? "" : ": ",
                         one_line(r.message).c_str(), elapsed,
                         elapsed / static_cast<real_t>(c + 1) * static_cast<real_t>(n - c - 1));
        }
        results.push_back(std::move(r));
    }
    write_outputs(st, results, out);
    return results;
}
} // namespace rkfem
