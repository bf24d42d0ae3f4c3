/// @file study_read.cpp
/// Reading a study file: its cases, the metrics each extracts, the published values beside them.
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
using deck_detail::Context;
using deck_detail::Section;

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
    const Section s(ctx, n, p, "study-metric");
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
    const Section s(ctx, n, p, "study-case");
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
            const Section v(ctx, kv.second, mp, "study-published");
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

} // namespace

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
        const Section s(ctx, root, "", "study");
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

} // namespace rkfem
