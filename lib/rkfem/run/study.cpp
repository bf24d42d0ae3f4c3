#include "rkfem/run/study.hpp"

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
namespace
{
using deck_detail::Context;
using deck_detail::Section;
namespace fs = std::filesystem;
constexpr real_t nan = std::numeric_limits<real_t>::quiet_NaN();

const std::vector<std::string> history_kinds = {
    "max",   "min",   "abs_max", "time_of_max", "time_of_min", "time_of_abs_max",
    "first", "final", "at",      "event_load",  "mean"};

/// A display unit: "" (SI), "%" or a unit expression; its SI scale and dimension.
Unit display_unit(const Section& s, const std::string& key)
{
    const std::string text = s.text(key, "");
    if (text.empty())
        return {};
    if (text == "%")
        return {0.01, dim::none};
    std::string error;
    const auto u = parse_unit(text, &error);
    if (!u)
        s.fail(key, "'" + text + "' is not a unit: " + error, "expected a unit such as in, mm, us, min, MPa or %");
    return *u;
}

bool valid_name(const std::string& n)
{
    if (n.empty() || n.size() > 64 || n == "." || n == "..")
        return false;
    return std::all_of(n.begin(), n.end(),
                       [](char c)
                       { return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.'; });
}

StudyMetric read_metric(const Context& ctx, const std::string& name, const YAML::Node& n, const std::string& p)
{
    const Section s(ctx, n, p,
                    {"kind", "column", "response", "key", "time", "from", "to", "fraction", "scale", "unit"});
    StudyMetric m;
    m.name = name;
    m.loc = s.loc();
    if (!valid_name(name))
        throw DeckError(s.loc(), "'" + name + "' is not a metric name", "expected letters, digits, _ - . (at most 64)");
    std::vector<std::string> kinds = history_kinds;
    kinds.push_back("summary");
    m.kind = s.choice("kind", kinds, "");
    if (m.kind == "summary")
    {
        m.key = s.text("key");
        for (const char* k : {"column", "response", "time", "from", "to", "fraction"})
            if (s.has(k))
                s.fail(k, "is not used by kind summary", "expected key, scale, unit");
    }
    else
    {
        m.column = s.text("column");
        if (s.has("key"))
            s.fail("key", "is used by kind summary only", "expected column (a history.csv column)");
        if (m.kind == "at")
            m.time = s.quantity("time", dim::time);
        else if (s.has("time"))
            s.fail("time", "is used by kind at only", "remove it, or use kind: at");
        if (m.kind == "mean")
        {
            m.from = s.quantity("from", dim::time);
            m.to = s.quantity("to", dim::time);
            if (!(m.to > m.from))
                s.fail("to", "is not after from", "expected a window from < to");
        }
        else if (s.has("from") || s.has("to"))
            s.fail(s.has("from") ? "from" : "to", "is used by kind mean only", "remove it, or use kind: mean");
        if (m.kind == "event_load")
        {
            m.response = s.text("response");
            m.fraction = s.has("fraction") ? s.quantity("fraction", dim::none) : 0.1;
            if (!(m.fraction > 0 && m.fraction < 1))
                s.fail("fraction", "must lie between 0 and 1",
                       "expected a fraction of the initial stiffness, e.g. 0.1");
        }
        else if (s.has("response") || s.has("fraction"))
            s.fail(s.has("response") ? "response" : "fraction", "is used by kind event_load only",
                   "remove it, or use kind: event_load");
    }
    if (s.has("scale"))
    {
        // a factor of any dimension: -1, or "-35.37 1/in^2" (a reaction over an area is a stress)
        const std::string text = s.scalar_text("scale", "a factor such as -1 or \"1.27 1/in^2\"");
        char* end = nullptr;
        m.scale = std::strtod(text.c_str(), &end);
        std::string rest(end);
        rest.erase(0, rest.find_first_not_of(' '));
        if (end == text.c_str() || !std::isfinite(m.scale))
            s.fail("scale", "'" + text + "' is not a number", "expected a factor such as -1 or \"1.27 1/in^2\"");
        if (!rest.empty())
        {
            std::string error;
            const auto u = parse_unit(rest, &error);
            if (!u)
                s.fail("scale", "'" + rest + "' is not a unit: " + error,
                       "expected a factor such as -1 or \"1.27 1/in^2\"");
            m.scale *= u->scale;
        }
    }
    if (m.scale == 0)
        s.fail("scale", "is zero", "expected a non-zero factor such as -1");
    const Unit u = display_unit(s, "unit");
    m.unit = s.text("unit", "");
    m.unit_scale = u.scale;
    return m;
}

StudyCase read_case(const Context& ctx, const YAML::Node& n, const std::string& p, const std::string& base_deck,
                    const std::vector<StudyMetric>& metrics, const fs::path& dir)
{
    const Section s(ctx, n, p, {"name", "set", "deck", "published"});
    StudyCase c;
    c.loc = s.loc();
    c.name = s.text("name");
    if (!valid_name(c.name))
        s.fail("name", "'" + c.name + "' is not a case name (it names a directory)",
               "expected letters, digits, _ - . (at most 64)");
    c.deck = s.has("deck") ? (dir / s.text("deck")).lexically_normal().string() : base_deck;
    if (c.deck.empty())
        s.fail("deck", "missing, and the study has no deck", "expected a deck here or a study-level deck");
    if (s.has("set"))
    {
        const YAML::Node set = s.node("set");
        if (set.IsMap())
        {
            deck_detail::reject_repeated_keys(ctx, set, s.path("set"));
            for (const auto& kv : set)
            {
                const std::string key = kv.first.as<std::string>();
                if (!kv.second.IsScalar())
                    throw DeckError(deck_detail::locate(ctx, kv.second, s.path("set") + "." + key), "is not a scalar",
                                    "expected one value per override (write lists as \"[1, 2]\")");
                c.overrides.push_back(key + "=" + kv.second.Scalar());
            }
        }
        else if (set.IsSequence())
        {
            for (std::size_t i = 0; i < set.size(); ++i)
            {
                const std::string ip = s.path("set") + "." + std::to_string(i);
                if (!set[i].IsScalar() || set[i].Scalar().find('=') == std::string::npos)
                    throw DeckError(deck_detail::locate(ctx, set[i], ip), "is not key.path=value",
                                    "expected an override such as parts.beam.formulation=rkpm");
                c.overrides.push_back(set[i].Scalar());
            }
        }
        else
            s.fail("set", "is a scalar", "expected a mapping {key.path: value} or a list of \"key.path=value\"");
    }
    if (s.has("published"))
    {
        const YAML::Node pub = s.node("published");
        if (!pub.IsMap())
            s.fail("published", "is not a mapping", "expected {metric: {value: ..., source: ...}}");
        deck_detail::reject_repeated_keys(ctx, pub, s.path("published"));
        for (const auto& kv : pub)
        {
            const std::string mname = kv.first.as<std::string>();
            const std::string mp = s.path("published") + "." + mname;
            const auto m =
                std::find_if(metrics.begin(), metrics.end(), [&](const StudyMetric& x) { return x.name == mname; });
            if (m == metrics.end())
            {
                std::string names;
                for (const auto& x : metrics)
                    names += (names.empty() ? "" : ", ") + x.name;
                throw DeckError(deck_detail::locate(ctx, kv.first, mp), "'" + mname + "' is not a metric of this study",
                                "expected one of " + names);
            }
            const Section v(ctx, kv.second, mp, {"value", "source"});
            StudyPublished pv;
            pv.text = v.scalar_text("value", "a value");
            pv.source = v.text("source");
            // a bare number is in the metric's display unit; a value with a unit must match it
            Dimension d = dim::none;
            if (!m->unit.empty() && m->unit != "%")
            {
                std::string error;
                d = parse_unit(m->unit, &error)->dimension; // checked in read_metric
            }
            const real_t x = v.quantity("value", d); // DeckError on a unit of another dimension
            pv.value = parse_quantity(pv.text, d).has_unit ? x / m->unit_scale : x;
            c.published[mname] = pv;
        }
    }
    return c;
}

std::string csv_field(const std::string& s)
{
    if (s.find_first_of(",\"\n") == std::string::npos)
        return s;
    std::string out = "\"";
    for (char ch : s)
        out += ch == '"' ? std::string("\"\"") : std::string(1, ch == '\n' ? ' ' : ch);
    return out + "\"";
}

/// A table cell: 6 significant digits (table.md) or 12 (table.csv, as summary.json); "" for NaN.
std::string fmt(real_t v, int digits = 6)
{
    if (!std::isfinite(v))
        return "";
    char b[40];
    std::snprintf(b, sizeof b, "%.*g", digits, v);
    return b;
}

std::string one_line(std::string s)
{
    std::replace(s.begin(), s.end(), '\n', ' ');
    std::replace(s.begin(), s.end(), '|', '/');
    return s;
}

/// Fixed-length string dataset.
void write_strings(hid_t loc, const char* name, const std::vector<std::string>& items)
{
    std::size_t len = 1;
    for (const auto& s : items)
        len = std::max(len, s.size());
    std::vector<char> buf(len * std::max<std::size_t>(items.size(), 1), '\0');
    for (std::size_t i = 0; i < items.size(); ++i)
        std::copy(items[i].begin(), items[i].end(), buf.begin() + static_cast<std::ptrdiff_t>(i * len));
    const hid_t type = H5Tcopy(H5T_C_S1);
    H5Tset_size(type, len);
    const hsize_t dims[1] = {items.size()};
    const hid_t space = H5Screate_simple(1, dims, nullptr);
    const hid_t set = H5Dcreate2(loc, name, type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (set >= 0)
    {
        H5Dwrite(set, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data());
        H5Dclose(set);
    }
    H5Sclose(space);
    H5Tclose(type);
}

/// The data rows of a history.csv (whole lines after the header), -1 without the file.
long long history_csv_rows(const fs::path& p)
{
    std::ifstream in(p, std::ios::binary);
    if (!in)
        return -1;
    const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    const long long lines = static_cast<long long>(std::count(text.begin(), text.end(), '\n'));
    return lines - 1; // the header; a row cut short has no newline and does not count
}

void write_outputs(const Study& st, const std::vector<StudyCaseResult>& results, const fs::path& out)
{
    // table.csv: one row per case and metric (long form, for notebooks)
    {
        std::ostringstream csv; // written whole (write_file_whole)
        csv << "case,metric,unit,ours,published,rel_diff,source,status\n";
        for (std::size_t c = 0; c < results.size(); ++c)
            for (std::size_t k = 0; k < st.metrics.size(); ++k)
            {
                const auto it = st.cases[c].published.find(st.metrics[k].name);
                const real_t ours = results[c].values[k];
                const real_t pub = it == st.cases[c].published.end() ? nan : it->second.value;
                const real_t rel = std::isfinite(pub) && pub != 0 ? (ours - pub) / std::abs(pub) : nan;
                csv << csv_field(results[c].name) << "," << csv_field(st.metrics[k].name) << ","
                    << csv_field(st.metrics[k].unit) << "," << fmt(ours, 12) << "," << fmt(pub, 12) << ","
                    << fmt(rel, 12) << "," << csv_field(it == st.cases[c].published.end() ? "" : it->second.source)
                    << "," << results[c].status << "\n";
            }
        write_file_whole((out / "table.csv").string(), csv.str());
    }
    // table.md: a cell "ours (published[n], diff)" per case and metric; cases as rows (or, with
    // table_rows: metrics, metrics as rows, the layout of the seed's Table 2)
    {
        std::vector<std::vector<std::string>> cells(results.size(), std::vector<std::string>(st.metrics.size()));
        std::vector<std::string> sources;
        for (std::size_t c = 0; c < results.size(); ++c)
            for (std::size_t k = 0; k < st.metrics.size(); ++k)
            {
                const real_t ours = results[c].values[k];
                std::string cell = std::isfinite(ours) ? fmt(ours) : "-";
                const auto it = st.cases[c].published.find(st.metrics[k].name);
                if (it != st.cases[c].published.end())
                {
                    const real_t pub = it->second.value;
                    char tag[24]; // "[n]" (GCC 12 warns falsely about "[" + std::to_string(n))
                    std::snprintf(tag, sizeof tag, "[%zu]", sources.size() + 1);
                    sources.push_back(std::string(tag) + " " + results[c].name + " / " + st.metrics[k].name + ": " +
                                      it->second.source);
                    cell += " (" + fmt(pub) + tag;
                    if (std::isfinite(ours) && pub != 0)
                    {
                        char d[32];
                        std::snprintf(d, sizeof d, ", %+.1f%%", 100 * (ours - pub) / std::abs(pub));
                        cell += d;
                    }
                    cell += ")";
                }
                cells[c][k] = cell;
            }
        auto metric_label = [&](const StudyMetric& m) { return m.name + (m.unit.empty() ? "" : " [" + m.unit + "]"); };
        std::ostringstream md; // written whole (write_file_whole)
        md << "# " << one_line(st.title) << "\n\n";
        md << "Each cell: ours (published, relative difference). Study file: `" << st.path << "`.\n\n";
        if (!st.rows_are_metrics)
        {
            md << "| case | status |";
            for (const auto& m : st.metrics)
                md << " " << metric_label(m) << " |";
            md << "\n|---|---|";
            for (std::size_t k = 0; k < st.metrics.size(); ++k)
                md << "---:|";
            md << "\n";
            for (std::size_t c = 0; c < results.size(); ++c)
            {
                md << "| " << results[c].name << " | " << results[c].status << " |";
                for (std::size_t k = 0; k < st.metrics.size(); ++k)
                    md << " " << cells[c][k] << " |";
                md << "\n";
            }
        }
        else
        {
            md << "| metric |";
            for (const auto& r : results)
                md << " " << r.name << " |";
            md << "\n|---|";
            for (std::size_t c = 0; c < results.size(); ++c)
                md << "---:|";
            md << "\n| status |";
            for (const auto& r : results)
                md << " " << r.status << " |";
            md << "\n";
            for (std::size_t k = 0; k < st.metrics.size(); ++k)
            {
                md << "| " << metric_label(st.metrics[k]) << " |";
                for (std::size_t c = 0; c < results.size(); ++c)
                    md << " " << cells[c][k] << " |";
                md << "\n";
            }
        }
        if (!sources.empty())
        {
            md << "\nPublished values:\n\n";
            for (const auto& s : sources)
                md << "- " << one_line(s) << "\n";
        }
        bool any_failed = false;
        for (const auto& r : results)
            if (r.status == "failed" || r.status == "unstable" || r.status == "interrupted")
            {
                if (!any_failed)
                    md << "\nCases that did not complete:\n\n";
                any_failed = true;
                md << "- " << r.name << " (" << r.status << "): " << one_line(r.message) << "\n";
            }
        write_file_whole((out / "table.md").string(), md.str());
    }
    // study.h5: metric names and units, per case its values, published values and its history
    const std::string h5 = (out / "study.h5").string();
    const hid_t file = H5Fcreate(h5.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    if (file < 0)
        throw Error("HDF5: cannot create " + h5);
    std::vector<std::string> names, units, case_names, status;
    for (const auto& m : st.metrics)
    {
        names.push_back(m.name);
        units.push_back(m.unit);
    }
    for (const auto& r : results)
    {
        case_names.push_back(r.name);
        status.push_back(r.status);
    }
    write_strings(file, "metrics", names);
    write_strings(file, "units", units);
    write_strings(file, "cases", case_names);
    write_strings(file, "status", status);
    std::vector<real_t> ours, pub;
    for (std::size_t c = 0; c < results.size(); ++c)
        for (std::size_t k = 0; k < st.metrics.size(); ++k)
        {
            ours.push_back(results[c].values[k]);
            const auto it = st.cases[c].published.find(st.metrics[k].name);
            pub.push_back(it == st.cases[c].published.end() ? nan : it->second.value);
        }
    const hsize_t nc = results.size(), nm = st.metrics.size();
    write_dataset(file, "ours", ours.data(), nc, nm == 1 ? 1 : nm);
    write_dataset(file, "published", pub.data(), nc, nm == 1 ? 1 : nm);
    const hid_t g = H5Gcreate2(file, "histories", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    for (const auto& r : results)
    {
        const HistoryTable& h = r.history;
        if (h.columns.empty())
            continue;
        const hid_t cg = H5Gcreate2(g, r.name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
        write_strings(cg, "columns", h.columns);
        const std::size_t rows = h.values.empty() ? 0 : h.values[0].size();
        std::vector<real_t> data(rows * h.columns.size());
        for (std::size_t j = 0; j < h.columns.size(); ++j)
            for (std::size_t i = 0; i < rows; ++i)
                data[i * h.columns.size() + j] = h.values[j][i];
        write_dataset(cg, "history", data.data(), rows, h.columns.size());
        H5Gclose(cg);
    }
    H5Gclose(g);
    H5Fclose(file);
}

/// summary.json's number at a key path ("impact.actual_depth", "contacts.0.resultant.2").
YAML::Node summary_node(const YAML::Node& node, const std::string& key)
{
    // recursion with fresh handles, never `n = n[part]`: assigning a yaml-cpp node writes through
    // to the tree
    const std::size_t dot = key.find('.');
    const std::string part = key.substr(0, dot);
    auto descend = [&](const YAML::Node& child)
    { return dot == std::string::npos ? child : summary_node(child, key.substr(dot + 1)); };
    if (node.IsSequence())
    {
        if (part.empty() || part.size() > 9 || part.find_first_not_of("0123456789") != std::string::npos ||
            std::stoul(part) >= node.size())
            return YAML::Node(YAML::NodeType::Undefined);
        return descend(node[std::stoul(part)]);
    }
    if (node.IsMap() && node[part])
        return descend(node[part]);
    return YAML::Node(YAML::NodeType::Undefined);
}
} // namespace

const std::vector<real_t>* HistoryTable::column(const std::string& name) const
{
    for (std::size_t i = 0; i < columns.size(); ++i)
        if (columns[i] == name)
            return &values[i];
    return nullptr;
}

HistoryTable read_history_csv(const std::string& path)
{
    std::ifstream in(path);
    if (!in)
        throw Error("cannot read " + path);
    HistoryTable h;
    std::string line;
    if (!std::getline(in, line))
        return h;
    std::stringstream header(line);
    for (std::string c; std::getline(header, c, ',');)
        h.columns.push_back(c);
    h.values.resize(h.columns.size());
    while (std::getline(in, line))
    {
        if (line.empty())
            continue;
        std::vector<real_t> row;
        const char* p = line.c_str();
        for (std::size_t j = 0; j < h.columns.size(); ++j)
        {
            char* end = nullptr;
            const real_t v = std::strtod(p, &end);
            if (end == p)
                break;
            row.push_back(v);
            p = *end == ',' ? end + 1 : end;
        }
        if (row.size() != h.columns.size())
            break; // a row cut short (a run killed while writing): the table ends before it
        for (std::size_t j = 0; j < row.size(); ++j)
            h.values[j].push_back(row[j]);
    }
    return h;
}

real_t event_load(const std::vector<real_t>& load, const std::vector<real_t>& response, real_t fraction)
{
    const std::size_t n = std::min(load.size(), response.size());
    real_t lmax = 0;
    for (std::size_t i = 0; i < n; ++i)
        lmax = std::max(lmax, std::abs(load[i]));
    if (!(lmax > 0))
        return nan;
    std::size_t j = 0;
    while (j < n && std::abs(load[j]) < 0.1 * lmax)
        ++j;
    if (j >= n || !(std::abs(response[j]) > 0))
        return nan;
    const real_t k0 = std::abs(load[j]) / std::abs(response[j]);
    for (std::size_t i = j + 1; i < n; ++i)
    {
        const real_t dl = std::abs(load[i]) - std::abs(load[i - 1]);
        const real_t dd = std::abs(response[i]) - std::abs(response[i - 1]);
        if (dd <= 0)
            continue; // the response holds or unloads: no loss of stiffness
        if (dl / dd < fraction * k0)
            return std::abs(load[i - 1]);
    }
    return nan;
}

real_t extract_metric(const StudyMetric& m, const HistoryTable& h, const YAML::Node& summary)
{
    if (m.kind == "summary")
    {
        const YAML::Node n = summary_node(summary, m.key);
        if (n.IsDefined() && n.IsNull())
            return nan; // summary.json writes a value that is not finite as null
        if (!n.IsDefined() || !n.IsScalar())
            throw Error("metric " + m.name + ": summary.json has no number at '" + m.key + "'");
        try
        {
            return m.scale * n.as<real_t>();
        }
        catch (const YAML::Exception&)
        {
            throw Error("metric " + m.name + ": summary.json's '" + m.key + "' is not a number");
        }
    }
    const std::vector<real_t>* col = h.column(m.column);
    if (!col)
    {
        std::string names;
        for (const auto& c : h.columns)
            names += (names.empty() ? "" : ", ") + c;
        throw Error("metric " + m.name + ": history.csv has no column '" + m.column + "' (columns: " + names + ")");
    }
    const std::vector<real_t>* time = h.column("time");
    const std::vector<real_t>& v = *col;
    if (v.empty())
        return nan;
    if (m.kind == "first")
        return m.scale * v.front();
    if (m.kind == "final")
        return m.scale * v.back();
    if (m.kind == "event_load")
    {
        const std::vector<real_t>* r = h.column(m.response);
        if (!r)
            throw Error("metric " + m.name + ": history.csv has no column '" + m.response + "'");
        return m.scale * event_load(v, *r, m.fraction);
    }
    if (!time)
        throw Error("metric " + m.name + ": history.csv has no time column");
    // the column's piecewise linear interpolant at s (t.front() <= s <= t.back())
    const auto& t = *time;
    auto value_at = [&](real_t s)
    {
        const std::size_t i = std::upper_bound(t.begin(), t.end(), s) - t.begin();
        if (i >= t.size())
            return v.back();
        const real_t w = t[i] > t[i - 1] ? (s - t[i - 1]) / (t[i] - t[i - 1]) : 1.0;
        return (1 - w) * v[i - 1] + w * v[i];
    };
    if (m.kind == "at")
    {
        if (m.time < t.front() || m.time > t.back())
            return nan; // the run did not reach it
        return m.scale * value_at(m.time);
    }
    if (m.kind == "mean")
    {
        // the time average over [from, to] of the column's piecewise linear interpolant
        // (trapezoids, the window's ends interpolated); empty when the run does not cover it
        if (m.from < t.front() || m.to > t.back())
            return nan;
        real_t area = 0.0, t0 = m.from, v0 = value_at(m.from);
        for (std::size_t i = 0; i < t.size(); ++i)
            if (t[i] > m.from && t[i] < m.to)
            {
                area += 0.5 * (v0 + v[i]) * (t[i] - t0);
                t0 = t[i];
                v0 = v[i];
            }
        area += 0.5 * (v0 + value_at(m.to)) * (m.to - t0);
        return m.scale * area / (m.to - m.from);
    }
    // extrema of scale * value (so "max" of a downward displacement with scale -1 is its peak)
    std::size_t best = 0;
    for (std::size_t i = 1; i < v.size(); ++i)
    {
        const real_t a = m.scale * v[i], b = m.scale * v[best];
        const bool better = m.kind == "max" || m.kind == "time_of_max"   ? a > b
                            : m.kind == "min" || m.kind == "time_of_min" ? a < b
                                                                         : std::abs(a) > std::abs(b);
        if (better)
            best = i;
    }
    if (m.kind.rfind("time_of_", 0) == 0)
        return (*time)[best];
    return m.scale * v[best];
}

Study read_study(const std::string& path)
{
    const std::string text = read_deck_text(path, "a YAML study file");
    Context ctx;
    ctx.name = path;
    YAML::Node root;
    try
    {
        root = YAML::Load(text);
    }
    catch (const YAML::Exception& e)
    {
        throw DeckError({path + ":" + std::to_string(e.mark.line + 1), "(file)"}, e.msg, "expected a YAML study file");
    }
    try
    {
        Study st;
        st.path = path;
        const Section s(ctx, root, "", {"title", "deck", "metrics", "cases", "table_rows"});
        st.title = s.text("title", fs::path(path).stem().string());
        st.rows_are_metrics = s.choice("table_rows", {"cases", "metrics"}, "cases") == "metrics";
        const fs::path dir = fs::path(path).parent_path();
        const std::string base = s.has("deck") ? (dir / s.text("deck")).lexically_normal().string() : "";
        s.require("metrics", "a mapping of named metrics, e.g. {tip_peak: {kind: abs_max, column: tip_uz}}");
        const YAML::Node metrics = s.node("metrics");
        if (!metrics.IsMap() || metrics.size() == 0)
            s.fail("metrics", metrics.IsMap() ? "is empty" : "is not a mapping",
                   "expected named metrics, e.g. {tip_peak: {kind: abs_max, column: tip_uz}}");
        deck_detail::reject_repeated_keys(ctx, metrics, "metrics");
        for (const auto& kv : metrics)
            st.metrics.push_back(
                read_metric(ctx, kv.first.as<std::string>(), kv.second, "metrics." + kv.first.as<std::string>()));
        s.require("cases", "a list of cases, each {name, set, deck, published}");
        const YAML::Node cases = s.node("cases");
        if (!cases.IsSequence() || cases.size() == 0)
            s.fail("cases", cases.IsSequence() ? "is empty" : "is not a list",
                   "expected a list of cases, each {name, set, deck, published}");
        for (std::size_t i = 0; i < cases.size(); ++i)
        {
            StudyCase c = read_case(ctx, cases[i], "cases." + std::to_string(i), base, st.metrics, dir);
            for (std::size_t j = 0; j < st.cases.size(); ++j)
                if (st.cases[j].name == c.name)
                    throw DeckError(c.loc, "case name '" + c.name + "' given twice",
                                    "each case once (first as cases." + std::to_string(j) + ", " +
                                        st.cases[j].loc.where + ")");
            st.cases.push_back(std::move(c));
        }
        // the decks exist (checked last: the study's own keys first); a missing one ran every
        // case as failed, exit 4
        std::error_code ec;
        if (!base.empty() && !fs::is_regular_file(base, ec))
            s.fail("deck", "'" + base + "' is not a file", "expected the path of a deck, relative to the study file");
        for (const StudyCase& c : st.cases)
            if (!fs::is_regular_file(c.deck, ec))
                throw DeckError({c.loc.where, c.loc.path + ".deck"}, "'" + c.deck + "' is not a file",
                                "expected the path of a deck, relative to the study file");
        return st;
    }
    catch (const YAML::Exception& e)
    {
        throw DeckError({path + ":" + std::to_string(e.mark.line + 1), "(file)"}, e.msg,
                        "expected a study file whose keys are plain names");
    }
}

Study select_cases(const Study& st, const std::vector<std::string>& names)
{
    std::vector<std::string> wanted;
    for (const auto& n : names)
    {
        std::stringstream ss(n);
        for (std::string item; std::getline(ss, item, ',');)
            if (!item.empty())
                wanted.push_back(item);
    }
    Study out = st;
    out.cases.clear();
    for (const auto& w : wanted)
        if (std::none_of(st.cases.begin(), st.cases.end(), [&](const StudyCase& c) { return c.name == w; }))
        {
            std::string known;
            for (const auto& c : st.cases)
                known += (known.empty() ? "" : ", ") + c.name;
            throw DeckError({"--only " + w, "cases"}, "'" + w + "' is not a case of " + st.path,
                            "expected one of " + known);
        }
    for (const auto& c : st.cases)
        if (std::find(wanted.begin(), wanted.end(), c.name) != wanted.end())
            out.cases.push_back(c);
    return out;
}

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
