/// @file study_write.cpp
/// Writing a study's table: table.csv, table.md and table.h5, each whole or not at all.
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

/// table.csv: one row per case and metric (long form, for notebooks).
void write_table_csv(const Study& st, const std::vector<StudyCaseResult>& results, const fs::path& out)
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
                << csv_field(st.metrics[k].unit) << "," << fmt(ours, 12) << "," << fmt(pub, 12) << "," << fmt(rel, 12)
                << "," << csv_field(it == st.cases[c].published.end() ? "" : it->second.source) << ","
                << results[c].status << "\n";
        }
    write_file_whole((out / "table.csv").string(), csv.str());
}

/// table.md's cells "ours (published[n], diff)" per case and metric; each published value's source into `sources`.
std::vector<std::vector<std::string>> table_cells(const Study& st, const std::vector<StudyCaseResult>& results,
                                                  std::vector<std::string>& sources)
{
    std::vector<std::vector<std::string>> cells(results.size(), std::vector<std::string>(st.metrics.size()));
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
    return cells;
}

/// table.md: the cells with cases as rows (or, with table_rows: metrics, metrics as rows, the layout of the
/// seed's Table 2), the published values' sources and the cases that did not complete.
void write_table_md(const Study& st, const std::vector<StudyCaseResult>& results, const fs::path& out)
{
    std::vector<std::string> sources;
    const std::vector<std::vector<std::string>> cells = table_cells(st, results, sources);
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

/// study.h5: metric names and units, per case its values, published values and its history.
void write_study_h5(const Study& st, const std::vector<StudyCaseResult>& results, const fs::path& out)
{
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

/// The data rows of a history.csv (whole lines after the header), -1 without the file.
} // namespace

std::string study_detail::one_line(std::string s)
{
    std::replace(s.begin(), s.end(), '\n', ' ');
    std::replace(s.begin(), s.end(), '|', '/');
    return s;
}

/// Fixed-length string dataset.
void study_detail::write_outputs(const Study& st, const std::vector<StudyCaseResult>& results, const fs::path& out)
{
    write_table_csv(st, results, out);
    write_table_md(st, results, out);
    write_study_h5(st, results, out);
}

} // namespace rkfem
