#pragma once
/// @file study.hpp
/// `rkfem study STUDY.yaml --out DIR`: a base deck, cases (overrides or their own deck), named
/// metrics extracted from each case's history.csv and summary.json, and published values set
/// beside them. Writes DIR/cases/NAME/ (each case's run), DIR/table.csv, DIR/table.md and
/// DIR/study.h5. A case that fails is recorded with its message and the study goes on; a case
/// whose summary.json says it completed with the same resolved deck (deck_hash) is not run again.
///
/// Study file:
///   title: Table 2 (seed), cantilever
///   deck: ../decks/p3_cantilever.yaml          # base deck, relative to the study file
///   table_rows: metrics                        # table.md's rows (default cases)
///   metrics:
///     tip_peak: {kind: abs_max, column: tip_uz, unit: in}
///     dt: {kind: summary, key: dt_first, unit: us}
///   cases:
///     - name: lfem_elastic
///       set: {loads.0.pressure: 500 psi}       # --set overrides (mapping, or a list of "k=v")
///       deck: other.yaml                       # optional: the case's own deck
///       published: {tip_peak: {value: 0.358 in, source: "Table 2, row 1, LFEM solids"}}
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "rkfem/config/deck.hpp"
#include "rkfem/core/types.hpp"

namespace YAML
{
class Node;
}

namespace rkfem
{
/// A named extractor. Kinds on a history column: max, min, abs_max (the extremum), time_of_max,
/// time_of_min, time_of_abs_max (its time), first, final, at (linearly interpolated at `time`);
/// event_load (the load when stiffness is lost, see event_load()); summary: a number in
/// summary.json by key path ("steps", "impact.actual_depth", "contacts.0.resultant.2").
struct StudyMetric
{
    std::string name;
    std::string kind;
    std::string column;          ///< history column (history kinds); event_load: the load column
    std::string response;        ///< event_load: the response (displacement) column
    std::string key;             ///< summary: key path
    real_t time = 0.0;           ///< at: [s]
    real_t from = 0.0, to = 0.0; ///< mean: the time window [s]
    real_t fraction = 0.1;       ///< event_load: tangent / initial stiffness that marks the event
    real_t scale = 1.0;          ///< multiplies the SI value (e.g. -1 for a downward displacement)
    std::string unit;            ///< display unit of table.csv/md ("" = SI; "%" = percent)
    real_t unit_scale = 1.0;     ///< SI value of one display unit
    SourceLocation loc;
};

struct StudyPublished
{
    real_t value = 0.0; ///< in the metric's display unit
    std::string text;   ///< as written
    std::string source; ///< table, row, column
};

struct StudyCase
{
    std::string name;
    std::string deck; ///< path of the case's deck (the study's when not given)
    std::vector<std::string> overrides;
    std::map<std::string, StudyPublished> published; ///< by metric name
    SourceLocation loc;
};

struct Study
{
    std::string path;
    std::string title;
    bool rows_are_metrics = false; ///< table_rows: metrics (table.md; the seed's Table 2 layout)
    std::vector<StudyMetric> metrics;
    std::vector<StudyCase> cases;
};

/// Reads and validates a study file (DeckError: FILE:LINE: key: what; expected). The decks and
/// overrides are checked when the cases run.
Study read_study(const std::string& path);

/// The study with only the named cases (comma-separated lists allowed), in the study's order.
/// Throws DeckError naming an unknown case and the known ones.
Study select_cases(const Study& study, const std::vector<std::string>& names);

/// history.csv as columns.
struct HistoryTable
{
    std::vector<std::string> columns;
    std::vector<std::vector<real_t>> values; ///< per column, one value per row
    const std::vector<real_t>* column(const std::string& name) const;
};
HistoryTable read_history_csv(const std::string& path);

/// Event load: with L the load column and D the response column (magnitudes), k0 the secant
/// stiffness L/D at the first row where L reaches 10% of its largest value, the event is the
/// first later row i whose tangent stiffness (L_i - L_{i-1}) / (D_i - D_{i-1}) falls below
/// `fraction` k0 (or turns negative, D running away while L still rises or holds); the value
/// is L_{i-1}, the last load carried at full stiffness. NaN when no row qualifies.
real_t event_load(const std::vector<real_t>& load, const std::vector<real_t>& response, real_t fraction);

/// One metric's SI value (times scale) from a case's history and summary.json (parsed). NaN
/// when the case lacks it; throws Error naming the metric when the column or key is unknown.
real_t extract_metric(const StudyMetric& m, const HistoryTable& history, const YAML::Node& summary);

struct StudyCaseResult
{
    std::string name;
    std::string status; ///< completed | reused | failed | unstable
    std::string message;
    std::vector<real_t> values; ///< per metric, display unit; NaN when missing
    HistoryTable history;       ///< the case's history.csv (no columns when it has none)
    real_t wall_seconds = 0.0;
};

/// Runs (or reuses) every case and writes the tables. `progress`: a line per case on stderr.
std::vector<StudyCaseResult> run_study(const Study& study, const std::string& out_dir, bool progress);
} // namespace rkfem
