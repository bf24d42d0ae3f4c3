/// @file study_metrics.cpp
/// A case's metrics from its history.csv and summary.json.
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

} // namespace rkfem
