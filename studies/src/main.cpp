// rkfem: command-line driver.
//   rkfem check DECK [--set key.path=value ...]      validate, print the resolved deck in SI
//   rkfem run DECK --out DIR [--set ...] [--quiet] [--checkpoint-interval T [--checkpoint-keep N]]
//                                                    run, write DIR/results.h5 + .xdmf, history, summary
//   rkfem restart DIR [--until T] [--from FILE] [--quiet] [--checkpoint-interval T]
//                                                    continue a run from its checkpoint
//   rkfem convergence SWEEP --out DIR [--quiet]      manufactured-solution sweep -> DIR/convergence.{csv,h5}
//   rkfem material-point DECK --out DIR [--quiet]    one material along a strain path -> DIR/stress_strain.csv
//   rkfem study STUDY --out DIR [--quiet]            cases of a deck -> DIR/table.{csv,md}, study.h5, cases/
// Exit codes: 0 success, 2 bad input (one line naming deck, line and key), 3 run went unstable
// (output so far kept), 4 a study with cases that did not complete (table written), 1 other failure.
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <hdf5.h>
#include <initializer_list>
#include <iostream>
#include <new>
#include <sstream>
#include <string>
#include <sys/file.h>
#include <unistd.h>
#include <vector>

#include "rkfem/analysis/convergence_study.hpp"
#include "rkfem/analysis/material_point.hpp"
#include "rkfem/config/deck.hpp"
#include "rkfem/config/deck_schema.hpp"
#include "rkfem/config/keyword_deck.hpp"
#include "rkfem/core/allocator_tuning.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/core/file_output.hpp"
#include "rkfem/core/interrupt.hpp"
#include "rkfem/core/memory_limit.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/setup_progress.hpp"
#include "rkfem/core/state_archive.hpp"
#include "rkfem/core/units.hpp"
#include "rkfem/io/checkpoint.hpp"
#include "rkfem/io/keyword_export.hpp"
#include "rkfem/io/results_writer.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/run/check_report.hpp"
#include "rkfem/run/simulation.hpp"
#include "rkfem/run/study.hpp"
#include "rkfem/run/summary.hpp"

namespace
{
/// An allocation failed: the model outgrew what set-up estimated, or another limit
void out_of_memory()
{
    const rkfem::MemoryLimit limit = rkfem::usable_memory();
    std::fprintf(stderr,
                 "rkfem: error: out of memory (this process may use %.3g GB more, by %s); expected a model that fits: "
                 "a coarser mesh, fewer parts, or a larger limit\n",
                 limit.bytes / 1e9, limit.what);
}

/// Runs a subcommand body: 0 when it returns, 2 for bad input (the one-line DeckError), 1 otherwise.
template <class Body> int run_guarded(Body&& body)
{
    try
    {
        body();
        return 0;
    }
    catch (const rkfem::DeckError& e)
    {
        std::fprintf(stderr, "%s\n", e.what());
        return 2;
    }
    catch (const std::bad_alloc&)
    {
        out_of_memory();
        return 1;
    }
    catch (const std::exception& e)
    {
        std::fprintf(stderr, "rkfem: error: %s\n", e.what());
        return 1;
    }
}

int usage()
{
    std::fprintf(stderr,
                 "usage: rkfem check DECK [--set key.path=value ...]  (DECK: YAML, or MODEL.k --units SYSTEM)\n"
                 "       rkfem run DECK --out DIR [--set key.path=value ...] [--quiet] [--checkpoint-interval T]\n"
                 "       rkfem restart DIR [--until T] [--from FILE] [--quiet] [--checkpoint-interval T]\n"
                 "       rkfem convergence SWEEP --out DIR [--quiet]\n"
                 "       rkfem material-point DECK --out DIR [--quiet]\n"
                 "       rkfem study STUDY --out DIR [--only CASE[,CASE...]] [--quiet]\n"
                 "       rkfem import MODEL.k --units SYSTEM [--allow-unsupported] > deck.yaml\n"
                 "       rkfem export DECK [--set key.path=value ...] > MODEL.k\n");
    return 2;
}
} // namespace

/// `rkfem --help`, `rkfem SUBCOMMAND --help`: usage on stdout, exit 0.
int help(const std::string& command)
{
    struct Entry
    {
        const char *name, *line, *what;
    };
    static const Entry entries[] = {
        {"check", "rkfem check DECK [--set key.path=value ...]",
         "Reads and validates DECK, builds the model, prints the resolved deck in SI units and the model's size."},
        {"run",
         "rkfem run DECK --out DIR [--set key.path=value ...] [--quiet] [--checkpoint-interval T [--checkpoint-keep "
         "N]]",
         "Runs DECK to time.end: DIR/results.h5 + results.xdmf (ParaView), history.csv, summary.json.\n"
         "--checkpoint-interval T (a time with its unit, e.g. '10 us') writes DIR/checkpoint.h5 every T of\n"
         "simulated time and at the end; --checkpoint-keep N keeps\n"
         "the N newest (checkpoint.1.h5 the one before the newest, ...)."},
        {"restart", "rkfem restart DIR [--until T] [--from FILE] [--quiet] [--checkpoint-interval T]",
         "Continues the run in DIR from DIR/checkpoint.h5 (or FILE) to time.end, or to T: the same bits as the\n"
         "run that was not interrupted. The deck stored in the checkpoint rebuilds the model; output after the\n"
         "checkpoint is replaced. Checkpoints go on at the stored interval unless one is given."},
        {"convergence", "rkfem convergence SWEEP --out DIR [--quiet]",
         "Manufactured-solution convergence sweep: DIR/convergence.csv and convergence.h5."},
        {"material-point", "rkfem material-point DECK --out DIR [--quiet]",
         "One material along a strain path: DIR/stress_strain.csv and stress_strain.h5."},
        {"import", "rkfem import MODEL.k --units SYSTEM [--allow-unsupported] > deck.yaml",
         "Translates an LS-DYNA keyword deck (and the files it *INCLUDEs) into an rkfem deck on standard output,\n"
         "every value in SI with its unit; the mesh stays in MODEL.k (generator type keyword, named as typed, so\n"
         "write the deck in the current folder). SYSTEM names the model's consistent units: m-s-kg-N,\n"
         "mm-ms-kg-kN, mm-s-t-N, mm-ms-g-N, cm-us-g-Mbar, in-s-lbf-s2/in-lbf, ft-s-slug-lbf. A keyword outside the\n"
         "supported subset (docs/user/keyword-decks.md) is refused by name and line; --allow-unsupported\n"
         "lists and skips those instead. What maps approximately is said on standard error and in the deck.\n"
         "check and run take MODEL.k --units SYSTEM in place of a deck (run writes DIR/imported.yaml)."},
        {"export", "rkfem export DECK [--set key.path=value ...] > MODEL.k",
         "Writes DECK's model as an LS-DYNA keyword deck on standard output (m-s-kg-N, 17 digits: *NODE,\n"
         "*ELEMENT_SOLID, sets, parts, materials, conditions, loads, contacts), which\n"
         "'rkfem run MODEL.k --units m-s-kg-N' runs as DECK's run. What has no keyword form is refused by its deck\n"
         "key; rkfem settings that change nothing LS-DYNA computes are listed as comments."},
        {"schema", "rkfem schema [deck | material-point | study] [--markdown] > deck.schema.json",
         "Writes the JSON Schema (draft-07) of a run deck (or of a material-point deck or a study file) on\n"
         "standard output,"
         "generated from the key table the deck reader reads by, with every key's kind, unit, default and\n"
         "description; editors with a YAML language server validate and complete decks with it (a first line\n"
         "'# yaml-language-server: $schema=deck.schema.json'). --markdown writes the manual's deck reference\n"
         "(all three)."},
        {"study", "rkfem study STUDY --out DIR [--only CASE[,CASE...]] [--quiet]",
         "Runs a study's cases (a base deck with overrides, or their own decks) into DIR/cases/NAME, extracts its\n"
         "metrics and writes DIR/table.csv, DIR/table.md (ours beside the published values) and DIR/study.h5.\n"
         "A case that fails is recorded and the study goes on; a rerun skips cases that completed with the\n"
         "same resolved deck. --only runs (and tabulates) the named cases. Exit 0 when every case completed,\n"
         "4 when some did not, 2 for a bad study file."},
    };
    for (const Entry& e : entries)
        if (command == e.name)
        {
            std::printf("usage: %s\n\n%s\n", e.line, e.what);
            return 0;
        }
    std::printf("usage:\n");
    for (const Entry& e : entries)
        std::printf("  %s\n      %s\n", e.line, e.what);
    std::printf("\nrkfem SUBCOMMAND --help describes one subcommand; docs/ (the manual, scripts/docs builds it) "
                "describes the decks.\n");
    return 0;
}

bool command_takes_only(const char* command)
{
    return std::string(command) == "study";
}

/// One run owns its output directory: an advisory lock on DIR/.rkfem.lock (flock, released by
/// the system when the process ends, however it ends) held from before the first output to the
/// exit. Returns false, having said why on one line, when another process holds it.
bool lock_output_directory(const std::string& dir, const char* what)
{
    const std::string path = dir + "/.rkfem.lock";
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0)
    {
        std::fprintf(stderr, "rkfem: %s %s: cannot write in the output directory (%s); expected a writable directory\n",
                     what, dir.c_str(), std::strerror(errno));
        return false;
    }
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0)
    {
        char pid[32] = {};
        const ssize_t n = ::pread(fd, pid, sizeof pid - 1, 0);
        std::string who = n > 0 ? std::string(pid, static_cast<std::size_t>(n)) : std::string("?");
        while (!who.empty() && (who.back() == '\n' || who.back() == ' '))
            who.pop_back();
        std::fprintf(stderr,
                     "rkfem: %s %s: another rkfem (pid %s) is writing in this directory; expected a directory no other "
                     "run uses (nothing was written)\n",
                     what, dir.c_str(), who.c_str());
        ::close(fd);
        return false;
    }
    const std::string me = std::to_string(::getpid()) + "\n";
    if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, me.data(), me.size(), 0) < 0)
    {
        // the lock holds without the pid in it
    }
    return true; // the descriptor stays open (and locked) until the process ends
}

/// Every output NAME in DIR can be written where it goes (nothing not a regular file in the way);
/// otherwise one line and false.
bool outputs_writable(const std::string& dir, const char* what, std::initializer_list<const char*> names)
{
    for (const char* name : names)
        try
        {
            rkfem::require_writable_file_path(dir + "/" + name);
        }
        catch (const rkfem::Error& e)
        {
            std::fprintf(stderr, "rkfem: %s %s: %s\n", what, dir.c_str(), e.what());
            return false;
        }
    return true;
}

/// The command line: the subcommand, its file, and the options it took.
struct Args
{
    std::string command, deck_path;
    std::vector<std::string> overrides;
    std::string out_dir;
    bool quiet = false;
    std::vector<std::string> only;                // study: case names
    std::string checkpoint_interval, until, from; // times with units, as typed; a checkpoint file
    std::string units;                            // keyword decks: the unit system
    bool allow_unsupported = false;
    int checkpoint_keep = 1;
    double checkpoint_seconds = 0.0, until_seconds = 0.0; // the times, parsed
};

/// Reads the command line into `a`: -1 when it is whole, else the exit code (the usage printed, or
/// an option a subcommand does not take refused with one line).
int parse_args(int argc, char** argv, Args& a)
{
    auto& [command, deck_path, overrides, out_dir, quiet, only, checkpoint_interval, until, from, units,
           allow_unsupported, checkpoint_keep, checkpoint_seconds, until_seconds] = a;
    command = argv[1];
    deck_path = argv[2];
    const bool runs = command == "run" || command == "restart";
    for (int i = 3; i < argc; ++i)
    {
        const std::string arg = argv[i];
        if (arg == "--checkpoint-interval" && i + 1 < argc && runs)
            checkpoint_interval = argv[++i];
        else if (arg == "--checkpoint-keep" && i + 1 < argc && command == "run")
        {
            const std::string n = argv[++i];
            char* end = nullptr;
            const long k = std::strtol(n.c_str(), &end, 10);
            if (n.empty() || *end != '\0' || k < 1 || k > 1000)
            {
                std::fprintf(stderr, "rkfem: --checkpoint-keep %s: expected a whole number from 1 to 1000\n",
                             n.c_str());
                return 2;
            }
            checkpoint_keep = static_cast<int>(k);
        }
        else if (arg == "--until" && i + 1 < argc && command == "restart")
            until = argv[++i];
        else if (arg == "--from" && i + 1 < argc && command == "restart")
            from = argv[++i];
        else if (arg == "--set" && i + 1 < argc)
            overrides.emplace_back(argv[++i]);
        else if (arg.rfind("--set=", 0) == 0)
            overrides.emplace_back(arg.substr(6));
        else if (arg == "--out" && i + 1 < argc)
            out_dir = argv[++i];
        else if (arg == "--quiet")
            quiet = true;
        else if (arg == "--only" && i + 1 < argc && command_takes_only(argv[1]))
            only.emplace_back(argv[++i]);
        else if (arg == "--units" && i + 1 < argc && (command == "import" || command == "check" || command == "run"))
            units = argv[++i];
        else if (arg == "--allow-unsupported" && (command == "import" || command == "check" || command == "run"))
            allow_unsupported = true;
        else
        {
            std::fprintf(stderr, "rkfem: unknown argument '%s'\n", arg.c_str());
            return usage();
        }
    }
    if (command != "check" && command != "run" && command != "convergence" && command != "material-point" &&
        command != "study" && command != "restart" && command != "import" && command != "export")
        return usage();
    // keyword decks: a unit system, and only for them
    const bool keyword = rkfem::is_keyword_deck(deck_path);
    if (command == "import" && !keyword)
    {
        std::fprintf(stderr, "rkfem: import %s: expected an LS-DYNA keyword deck (.k, .key, .dyn or .kw)\n",
                     deck_path.c_str());
        return 2;
    }
    if ((command == "import" || command == "check" || command == "run") && keyword != !units.empty())
    {
        std::fprintf(
            stderr,
            keyword ? "rkfem: %s is an LS-DYNA keyword deck: --units SYSTEM names its consistent units (m-s-kg-N, "
                      "mm-ms-kg-kN, mm-s-t-N, mm-ms-g-N, cm-us-g-Mbar, in-s-lbf-s2/in-lbf, ft-s-slug-lbf)\n"
                    : "rkfem: --units is for LS-DYNA keyword decks (.k, .key, .dyn, .kw); %s is a YAML deck, whose "
                      "values carry their units\n",
            deck_path.c_str());
        return 2;
    }
    if (allow_unsupported && !keyword)
    {
        std::fprintf(stderr, "rkfem: --allow-unsupported is for LS-DYNA keyword decks\n");
        return 2;
    }
    if (command == "import" && (!overrides.empty() || !out_dir.empty()))
    {
        std::fprintf(stderr, "rkfem: import writes the deck on standard output and takes no --set or --out\n");
        return 2;
    }
    // a time typed on the command line, with its unit
    auto parse_time = [](const char* option, const std::string& text, double& value)
    {
        try
        {
            value = rkfem::parse_quantity(text, rkfem::dim::time).value_si;
        }
        catch (const rkfem::Error& e)
        {
            std::fprintf(stderr, "rkfem: %s %s: %s; expected a time such as '10 us'\n", option, text.c_str(), e.what());
            return false;
        }
        if (!(value > 0) || !std::isfinite(value))
        {
            std::fprintf(stderr, "rkfem: %s %s: expected a positive, finite time\n", option, text.c_str());
            return false;
        }
        return true;
    };
    if (!checkpoint_interval.empty() && !parse_time("--checkpoint-interval", checkpoint_interval, checkpoint_seconds))
        return 2;
    if (!until.empty() && !parse_time("--until", until, until_seconds))
        return 2;
    if (command == "restart" && (!overrides.empty() || !out_dir.empty()))
    {
        std::fprintf(stderr, "rkfem: restart takes no --set or --out: it continues DIR with the deck its checkpoint "
                             "holds (--until T changes the end time)\n");
        return 2;
    }
    // options a subcommand does not take are refused, not ignored
    if (!overrides.empty() && (command == "material-point" || command == "convergence" || command == "study"))
    {
        std::fprintf(stderr,
                     "rkfem: %s takes no --set (edit the file; --set applies to decks of check and run, and a study's "
                     "cases carry their own)\n",
                     command.c_str());
        return 2;
    }
    if (!out_dir.empty() && command == "check")
    {
        std::fprintf(stderr, "rkfem: check writes nothing and takes no --out (run writes DIR)\n");
        return 2;
    }
    // the others write a directory (restart's is DIR itself)
    if (!out_dir.empty() && command == "export")
    {
        std::fprintf(stderr, "rkfem: export writes the keyword deck on standard output and takes no --out\n");
        return 2;
    }
    if (out_dir.empty() && command != "check" && command != "restart" && command != "import" && command != "export")
    {
        std::fprintf(stderr, "rkfem: %s needs --out DIR\n", command.c_str());
        return 2;
    }
    return -1;
}

/// rkfem material-point DECK --out DIR
int material_point_command(const Args& a)
{
    return run_guarded(
        [&]
        {
            const rkfem::MaterialPointDeck d = rkfem::read_material_point_deck(a.deck_path);
            const auto h = rkfem::run_material_point(d);
            rkfem::write_material_point(h, a.out_dir);
            if (!a.quiet)
                std::printf("rkfem: %zu states; final stress xx %.6e Pa, plastic strain %.6e -> %s/stress_strain.csv\n",
                            h.size(), h.back().stress[0], h.back().plastic_strain, a.out_dir.c_str());
        });
}

/// rkfem study STUDY --out DIR [--only ...]
int study_command(const Args& a)
{
    rkfem::install_interrupt_handlers();
    int incomplete = 0;
    bool taken = false; // out_dir refused: another process writes in it, or an output is in the way
    const int rc = run_guarded(
        [&]
        {
            rkfem::Study st = rkfem::read_study(a.deck_path);
            if (!a.only.empty())
                st = rkfem::select_cases(st, a.only);
            // the study is valid: its directory, and nobody else writing in it
            std::error_code mk;
            std::filesystem::create_directories(a.out_dir, mk);
            std::error_code cases_ec;
            const auto cases = std::filesystem::status(a.out_dir + "/cases", cases_ec);
            if (!mk && std::filesystem::exists(cases) && !std::filesystem::is_directory(cases))
            {
                std::fprintf(stderr,
                             "rkfem: study --out %s: %s/cases exists and is not a directory; expected the folder of "
                             "the cases' outputs (move what is in the way)\n",
                             a.out_dir.c_str(), a.out_dir.c_str());
                taken = true;
                return;
            }
            if (!mk && (!lock_output_directory(a.out_dir, "study --out") ||
                        !outputs_writable(a.out_dir, "study --out", {"table.csv", "table.md", "study.h5"})))
            {
                taken = true;
                return;
            }
            for (const auto& r : rkfem::run_study(st, a.out_dir, !a.quiet))
                incomplete += r.status != "completed" && r.status != "reused";
            if (!a.quiet)
                std::fprintf(stderr, "rkfem: study %s: %zu case(s), %d not completed -> %s/table.md\n",
                             st.title.c_str(), st.cases.size(), incomplete, a.out_dir.c_str());
        });
    if (taken)
        return 2;
    if (rc == 0 && rkfem::interrupt_signal() != 0)
    {
        std::fprintf(stderr,
                     "rkfem: study interrupted by %s: the case running then wrote its last state, later "
                     "cases did not run; the table is written (%s/table.md)\n",
                     rkfem::interrupt_signal_name(rkfem::interrupt_signal()), a.out_dir.c_str());
        return 5;
    }
    return rc != 0 ? rc : incomplete > 0 ? 4 : 0;
}

/// An LS-DYNA keyword deck as rkfem deck text, its generators naming the model as `mesh_file`; what maps
/// approximately and what was skipped on standard error. Throws DeckError.
std::string import_keyword(const Args& a, const std::string& mesh_file)
{
    const rkfem::KeywordImport im =
        rkfem::import_keyword_deck(a.deck_path, rkfem::keyword_units(a.units), a.allow_unsupported, mesh_file);
    if (!a.quiet)
    {
        for (const std::string& n : im.notes)
            std::fprintf(stderr, "rkfem: import: note: %s\n", n.c_str());
        for (const std::string& k : im.skipped)
            std::fprintf(stderr, "rkfem: import: skipped (unsupported): %s\n", k.c_str());
    }
    return im.yaml;
}

/// rkfem import MODEL.k --units SYSTEM: the deck on standard output
int import_command(const Args& a)
{
    return run_guarded([&] { std::fputs(import_keyword(a, a.deck_path).c_str(), stdout); });
}

/// rkfem convergence SWEEP --out DIR
int convergence_command(const Args& a)
{
    return run_guarded([&] { rkfem::run_sweep(rkfem::read_sweep(a.deck_path), a.out_dir, a.quiet); });
}

/// A restart: the run's directory, its deck, overrides and checkpoint interval from the checkpoint
/// (--until T becomes one more override). -1, or the exit code with the message printed.
int read_restart(Args& a, rkfem::StateArchive& checkpoint, std::string& deck_text)
{
    auto& [command, deck_path, overrides, out_dir, quiet, only, checkpoint_interval, until, from, units,
           allow_unsupported, checkpoint_keep, checkpoint_seconds, until_seconds] = a;
    out_dir = deck_path; // restart DIR
    try
    {
        checkpoint = rkfem::read_checkpoint(from.empty() ? rkfem::newest_checkpoint(out_dir) : from);
        deck_text = checkpoint.text("run.deck_text");
        overrides.clear();
        std::istringstream os(checkpoint.text("run.overrides"));
        for (std::string line; std::getline(os, line);)
            overrides.push_back(line);
        if (checkpoint_seconds == 0.0)
            checkpoint_seconds = checkpoint.value<double>("run.checkpoint_interval");
    }
    catch (const rkfem::Error& e)
    {
        std::fprintf(stderr, "rkfem: restart %s: %s\n", out_dir.c_str(), e.what());
        return 2;
    }
    if (!until.empty())
        overrides.push_back("time.end=" + until);
    return -1;
}

/// The output directory of run and restart: made, locked, every output writable, and for a restart
/// the directory's own run. -1, or the exit code with the message printed.
int prepare_output(const Args& a, const rkfem::StateArchive& checkpoint)
{
    // the output directory must exist (or be made) and take a file, before the run starts
    std::error_code ec;
    std::filesystem::create_directories(a.out_dir, ec);
    if (ec)
    {
        std::fprintf(stderr, "rkfem: --out %s: cannot create the output directory (%s); expected a directory path\n",
                     a.out_dir.c_str(), ec.message().c_str());
        return 2;
    }
    // nobody else writing in it (the lock file's creation is also the write test), and every
    // output a run writes writable where it goes, before the run starts
    const char* what = a.command == "restart" ? "restart" : "--out";
    if (!lock_output_directory(a.out_dir, what) ||
        !outputs_writable(a.out_dir, "--out", {"results.h5", "results.xdmf", "history.csv", "summary.json"}))
        return 2;
    if (a.command == "restart")
    {
        // the checkpoint must be this directory's run's: a later run into the same directory
        // replaced its outputs, and splicing the old state onto them would mix two runs
        const std::string ours = checkpoint.has("run.run_id") ? checkpoint.text("run.run_id") : "";
        const std::string theirs = rkfem::results_run_id(a.out_dir);
        if (ours != theirs)
        {
            std::fprintf(stderr,
                         "rkfem: restart %s: the checkpoint belongs to run %s, the results.h5 beside it to run %s; "
                         "expected the checkpoint the run in this directory wrote (nothing was changed)\n",
                         a.out_dir.c_str(), ours.empty() ? "(none recorded)" : ours.c_str(),
                         theirs.empty() ? "(none: results.h5 is missing or cannot be read)" : theirs.c_str());
            return 2;
        }
    }
    return -1;
}

namespace
{
/// Set-up work that runs past 2 s says what it is doing and how far it is (on stderr).
void install_setup_progress()
{
    const bool tty = isatty(STDERR_FILENO) != 0;
    rkfem::setup_progress::install(
        [tty](const std::string& line, bool last)
        {
            if (tty)
                std::fprintf(stderr, "\rrkfem: %s\033[K%s", line.c_str(), last ? "\n" : "");
            else
                std::fprintf(stderr, "rkfem: %s\n", line.c_str());
            std::fflush(stderr);
        },
        2.0, tty ? 0.5 : 5.0);
}

/// A restart's data files are the ones its run read: -1, or 2 with the first file that differs printed.
int check_data_files(const rkfem::StateArchive& checkpoint, const rkfem::Deck& deck, const std::string& out_dir)
{
    // the keyword meshes and point files must be the ones the run read
    const std::string then = checkpoint.text("run.data_files"), now = rkfem::data_file_hashes(deck);
    if (then != now)
    {
        std::istringstream a(then), b(now);
        std::string la, lb;
        while (std::getline(a, la) && std::getline(b, lb) && la == lb)
        {
        }
        const std::string file = la.substr(0, la.find('\t'));
        std::fprintf(stderr,
                     "rkfem: restart %s: the data file %s is not the one the run read (its hash was %s, is "
                     "%s); expected the file as it was\n",
                     out_dir.c_str(), file.c_str(), la.substr(la.find('\t') + 1).c_str(),
                     lb.empty() ? "different" : lb.substr(lb.find('\t') + 1).c_str());
        return 2;
    }
    return -1;
}

/// A restart's model takes the checkpoint's state, which must be before the end time: -1, or 2 with why printed.
int load_restart_state(rkfem::Model& model, const rkfem::StateArchive& checkpoint, const rkfem::Deck& deck,
                       const std::string& out_dir)
{
    try
    {
        model.load_state(checkpoint);
    }
    catch (const rkfem::Error& e)
    {
        std::fprintf(stderr, "rkfem: restart %s: %s\n", out_dir.c_str(), e.what());
        return 2;
    }
    const double t = checkpoint.value<double>("run.t");
    if (!(deck.time.end > t))
    {
        std::fprintf(stderr,
                     "rkfem: restart %s: the checkpoint is at t = %.9g s, and the run ends at %.9g s; "
                     "expected --until past the checkpoint\n",
                     out_dir.c_str(), t, deck.time.end);
        return 2;
    }
    return -1;
}

/// rkfem check: the resolved deck in SI, the check report and the model's size on stdout.
void print_check(const rkfem::Deck& deck, rkfem::Model& model)
{
    std::cout << rkfem::to_yaml(deck);
    std::cout << rkfem::check_report(model);
    std::cout << "# " << model.nodes.size() << " nodes, " << model.n_elements() << " elements, " << model.parts.size()
              << " part(s)\n";
}

/// Unless --quiet: the deck's ignored keys and the set-up's notes as warnings, then the model's size.
void print_setup_notes(const Args& a, const rkfem::Deck& deck, const rkfem::Model& model)
{
    if (!a.quiet)
    {
        for (const auto& part : deck.parts)
            for (const auto& note : part.ignored)
                std::fprintf(stderr, "rkfem: warning: %s\n", note.c_str());
        for (const auto& note : model.setup_notes)
            std::fprintf(stderr, "rkfem: warning: %s\n", note.c_str());
    }
    if (!a.quiet)
        std::fprintf(stderr, "rkfem: %s: %d nodes, %d elements, %d thread(s)\n", a.deck_path.c_str(),
                     model.nodes.size(), model.n_elements(), rkfem::max_threads());
}

/// The options of run and restart (all but setup_seconds): output, deck, overrides, checkpoints, resume.
rkfem::RunOptions run_options(const Args& a, const rkfem::Deck& deck, const rkfem::StateArchive& checkpoint,
                              const std::string& deck_name, const std::string& deck_dir, const std::string& deck_text)
{
    rkfem::RunOptions opt;
    opt.out_dir = a.out_dir;
    opt.progress = !a.quiet;
    opt.deck_path = deck_name;
    opt.overrides = a.overrides;
    opt.checkpoint_interval = a.checkpoint_seconds;
    opt.checkpoint_keep = a.checkpoint_keep;
    opt.deck_text = deck_text;
    opt.deck_dir = deck_dir;
    if (a.checkpoint_seconds > 0)
        opt.data_files = a.command == "restart" && checkpoint.has("run.data_files") ? checkpoint.text("run.data_files")
                                                                                    : rkfem::data_file_hashes(deck);
    if (a.command == "restart")
    {
        opt.resume = &checkpoint;
        if (!a.until.empty()) // the stored overrides stay those of the run; --until is this restart's
            opt.overrides.pop_back();
    }
    return opt;
}

/// A run's exit code from its summary: 5 interrupted, 3 stopped (each said on one line), else 0 (and, unless
/// --quiet, its statistics).
int run_exit_code(const Args& a, const rkfem::RunSummary& s)
{
    if (s.status == "interrupted")
    {
        std::fprintf(stderr, "rkfem: %s; summary.json says so (output kept in %s)\n", s.message.c_str(),
                     a.out_dir.c_str());
        return 5;
    }
    if (s.status != "completed")
    {
        std::fprintf(stderr, "rkfem: run stopped: %s (output so far kept in %s)\n", s.message.c_str(),
                     a.out_dir.c_str());
        return 3;
    }
    if (!a.quiet)
        std::fprintf(stderr,
                     "rkfem: done: %lld steps to t = %.6g s in %.2f s (%.1f ns per "
                     "element-cycle), energy balance error %.2e, hourglass ratio %.3g\n",
                     static_cast<long long>(s.steps), s.end_time, s.wall_seconds, s.ns_per_element_cycle,
                     s.energy.balance_error(), s.energy.hourglass_ratio());
    return 0;
}
} // namespace

/// rkfem check DECK, run DECK --out DIR, restart DIR: a model built from a deck (a restart's from its
/// checkpoint), checked, then run.
int model_command(Args a)
{
    auto& [command, deck_path, overrides, out_dir, quiet, only, checkpoint_interval, until, from, units,
           allow_unsupported, checkpoint_keep, checkpoint_seconds, until_seconds] = a;
    if (command == "run" || command == "restart")
        rkfem::install_interrupt_handlers();
    // an LS-DYNA keyword deck runs as the deck it imports to (named after it, so that errors say where)
    const bool keyword = command != "restart" && rkfem::is_keyword_deck(deck_path);
    try
    {
        const auto setup_start = std::chrono::steady_clock::now();
        // restart: the deck, its overrides and the state come from the checkpoint
        rkfem::StateArchive checkpoint;
        std::string deck_text;
        if (command == "restart")
        {
            if (const int rc = read_restart(a, checkpoint, deck_text); rc >= 0)
                return rc;
        }
        else if (keyword)
            deck_text = import_keyword(a, std::filesystem::path(deck_path).filename().string());
        else if (command == "run" && checkpoint_seconds > 0)
            deck_text = rkfem::read_deck_text(deck_path, "expected a deck file");
        if (!quiet)
            install_setup_progress();
        const std::string deck_name = command == "restart" ? checkpoint.text("run.deck_path") : deck_path;
        // a restart reads the deck's data files from the deck's folder as the run found it
        // (absolute: the restart may start in another working folder)
        const std::string deck_dir = command == "restart"
                                         ? (checkpoint.has("run.deck_dir") ? checkpoint.text("run.deck_dir") : "")
                                         : std::filesystem::absolute(deck_path).parent_path().string();
        const std::string parse_name =
            deck_dir.empty() ? deck_name
                             : (std::filesystem::path(deck_dir) / std::filesystem::path(deck_name).filename()).string();
        const rkfem::Deck deck = command == "restart" ? rkfem::parse_deck(deck_text, parse_name, overrides)
                                 : keyword ? rkfem::parse_deck(deck_text, deck_path + " (imported)", overrides)
                                           : rkfem::read_deck(deck_path, overrides);
        if (command == "restart" && checkpoint.has("run.data_files"))
        {
            if (const int rc = check_data_files(checkpoint, deck, out_dir); rc >= 0)
                return rc;
        }
        rkfem::Model model = rkfem::Model::build(deck); // all validation before any output
        if (command == "restart")
        {
            if (const int rc = load_restart_state(model, checkpoint, deck, out_dir); rc >= 0)
                return rc;
        }
        rkfem::check_step_budget(model);
        if (command == "check")
        {
            print_check(deck, model);
            return 0;
        }
        if (command == "export")
        {
            std::fputs(rkfem::export_keyword_deck(model).c_str(), stdout);
            return 0;
        }
        if (const int rc = prepare_output(a, checkpoint); rc >= 0)
            return rc;
        if (keyword)
            rkfem::write_file_whole(out_dir + "/imported.yaml", deck_text);
        print_setup_notes(a, deck, model);
        rkfem::RunOptions opt = run_options(a, deck, checkpoint, deck_name, deck_dir, deck_text);
        opt.setup_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - setup_start).count();
        const rkfem::RunSummary s = rkfem::run_simulation(model, opt);
        return run_exit_code(a, s);
    }
    catch (const rkfem::DeckError& e)
    {
        std::fprintf(stderr, "%s\n", e.what());
        return 2;
    }
    catch (const rkfem::Error& e)
    {
        std::fprintf(stderr, "rkfem: error: %s\n", e.what());
        return 1;
    }
    catch (const std::bad_alloc&)
    {
        out_of_memory();
        return 1;
    }
    catch (const std::exception& e)
    {
        std::fprintf(stderr, "rkfem: internal error: %s\n", e.what());
        return 1;
    }
}

/// `rkfem schema [deck | material-point | study] [--markdown]`: the deck's JSON Schema or its Markdown reference.
int schema_command(int argc, char** argv)
{
    std::string root = "deck";
    bool markdown = false;
    for (int i = 2; i < argc; ++i)
    {
        const std::string arg = argv[i];
        if (arg == "--markdown")
            markdown = true;
        else if (arg == "deck" || arg == "material-point" || arg == "study")
            root = arg;
        else
        {
            std::fprintf(stderr,
                         "rkfem: schema: unknown argument '%s'; expected deck, material-point, study or --markdown\n",
                         arg.c_str());
            return 2;
        }
    }
    const std::string text = markdown ? rkfem::deck_reference_markdown() : rkfem::deck_json_schema(root);
    std::fwrite(text.data(), 1, text.size(), stdout);
    return std::fflush(stdout) == 0 ? 0 : 1;
}

int main(int argc, char** argv)
{
    rkfem::tune_allocator(argv); // glibc's malloc for the set-up's rows (re-executes once; core/allocator_tuning.hpp)
    // HDF5: every call's result is checked and reported on one line, so its own error stack is not
    // printed; and no clean-up at exit, where a file whose last flush failed (a full disk) made
    // HDF5's library termination crash (every file is closed by its owner before exit)
    H5dont_atexit();
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    for (int i = 1; i < argc; ++i)
        if (std::string(argv[i]) == "--help" || std::string(argv[i]) == "-h")
            return help(i > 1 ? argv[1] : "");
    if (argc >= 2 && std::string(argv[1]) == "schema")
        return schema_command(argc, argv);
    if (argc < 3)
        return usage();
    Args a;
    if (const int rc = parse_args(argc, argv, a); rc >= 0)
        return rc;
    if (a.command == "material-point")
        return material_point_command(a);
    if (a.command == "study")
        return study_command(a);
    if (a.command == "convergence")
        return convergence_command(a);
    if (a.command == "import")
        return import_command(a);
    return model_command(a);
}
