#pragma once
/// @file deck_section.hpp
/// Internal to the deck reader (config/deck*.cpp): the parsing context, a YAML mapping with a
/// fixed set of allowed keys that reads quantities with units and locates every error, and the
/// readers of the deck's sections, one file per concept (deck_parts.cpp: parts, generators,
/// materials; deck_conditions.cpp: selectors and sets, conditions, loads, time; deck.cpp: the
/// whole deck, overrides).
#include <algorithm>
#include <array>
#include <cmath>
#include <initializer_list>
#include <map>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>
#include <yaml-cpp/yaml.h>

#include "rkfem/config/deck.hpp"
#include "rkfem/config/deck_schema.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/core/units.hpp"

namespace rkfem::deck_detail
{
/// Levenshtein distance (suggestions for unknown keys).
std::size_t edit_distance(std::string_view a, std::string_view b);

inline std::string join(const std::vector<std::string>& items, const char* sep = ", ")
{
    std::string out;
    for (const auto& s : items)
        out += (out.empty() ? "" : sep) + s;
    return out;
}

/// Parsing context: deck name and which key paths came from --set.
struct Context
{
    std::string name;
    std::map<std::string, std::string> overridden; // path -> "path=value"
};

inline std::string child_path(const std::string& parent, const std::string& key)
{
    return parent.empty() ? key : parent + "." + key;
}

/// Where a node of the deck (or the --set that gave it) is.
SourceLocation locate(const Context& ctx, const YAML::Node& node, const std::string& path);

/// Throws DeckError at the second of two equal keys of a mapping (yaml-cpp keeps both of a
/// repeated key and [] reads the first): part, set and probe names, as any key, are given once.
inline void reject_repeated_keys(const Context& ctx, const YAML::Node& map, const std::string& path)
{
    std::map<std::string, YAML::Node> seen;
    for (const auto& kv : map)
    {
        const std::string key = kv.first.as<std::string>();
        if (const auto [it, fresh] = seen.emplace(key, kv.first); !fresh)
        {
            const YAML::Mark first = it->second.Mark();
            throw DeckError(locate(ctx, kv.first, child_path(path, key)), "key '" + key + "' given twice",
                            "each key once" + (first.is_null()
                                                   ? std::string()
                                                   : " (first given on line " + std::to_string(first.line + 1) + ")"));
        }
    }
}

/// A YAML mapping read as one section of the key table (deck_schema.hpp): the table's keys are
/// the allowed ones, and unknown keys are rejected at construction (with the closest allowed key
/// suggested). Each read checks the table's entry for the key (its kind, dimension, choices and
/// constant default) and throws std::logic_error where they differ: a reader that reads a key
/// otherwise than the table (and so the schema and the manual) says is a bug the suite finds.
class Section
{
  public:
    Section(const Context& ctx, const YAML::Node& node, std::string path, std::string_view id)
        : ctx_(ctx), node_(node), path_(std::move(path)), doc_(&deck_section(id))
    {
        if (!node_.IsMap())
            throw DeckError(locate(ctx_, node_, path_), node_.IsNull() ? "is empty" : "is not a mapping",
                            "expected keys: " + join(deck_section_keys(id)));
        reject_repeated_keys(ctx_, node_, path_);
        for (const auto& kv : node_)
        {
            const std::string key = kv.first.as<std::string>();
            if (doc_->find(key))
                continue;
            const std::vector<std::string> allowed = deck_section_keys(id);
            std::string best;
            std::size_t best_d = 1000;
            for (const auto& a : allowed)
            {
                const std::size_t d = edit_distance(key, a);
                if (d < best_d)
                {
                    best_d = d;
                    best = a;
                }
            }
            const std::string cp = child_path(path_, key);
            const bool close = best_d <= std::max<std::size_t>(2, key.size() / 3);
            throw DeckError(locate(ctx_, kv.first, cp), "unknown key '" + key + "'",
                            close ? "did you mean '" + best + "'? (valid keys: " + join(allowed) + ")"
                                  : "valid keys: " + join(allowed));
        }
    }

    bool has(const std::string& key) const
    {
        doc(key);
        return node_[key].IsDefined() && !node_[key].IsNull();
    }
    YAML::Node node(const std::string& key) const
    {
        doc(key);
        return node_[key];
    }
    /// The table's entry for key; throws std::logic_error for a key the section's table lacks.
    const KeyDoc& doc(const std::string& key) const
    {
        if (const KeyDoc* k = doc_->find(key))
            return *k;
        throw std::logic_error("deck reader: section '" + doc_->id + "' reads key '" + key +
                               "', which the key table (deck_keys.cpp) does not list");
    }
    const YAML::Node& self() const { return node_; }
    std::string path(const std::string& key) const { return child_path(path_, key); }
    const std::string& path() const { return path_; }
    SourceLocation loc() const { return locate(ctx_, node_, path_); }
    SourceLocation loc(const std::string& key) const
    {
        return has(key) ? locate(ctx_, node_[key], path(key)) : SourceLocation{loc().where, path(key)};
    }
    const Context& ctx() const { return ctx_; }

    [[noreturn]] void fail(const std::string& key, const std::string& problem, const std::string& expected) const
    {
        throw DeckError(loc(key), problem, expected);
    }

    void require(const std::string& key, const std::string& expected) const
    {
        if (!has(key))
            throw DeckError(SourceLocation{loc().where, path(key)}, "missing required key", "expected " + expected);
    }

    std::string scalar_text(const std::string& key, const std::string& expected) const
    {
        const YAML::Node n = node_[key];
        if (!n.IsScalar())
            fail(key, n.IsSequence() ? "is a list" : "is a mapping", "expected " + expected);
        return n.Scalar();
    }

    real_t quantity(const std::string& key, Dimension d) const
    {
        check(key, {KeyKind::Quantity, KeyKind::QuantityOr}, d);
        require(key, describe(d));
        return quantity_of(node_[key], path(key), d);
    }
    real_t quantity(const std::string& key, Dimension d, real_t fallback) const
    {
        const KeyDoc& k = check(key, {KeyKind::Quantity, KeyKind::QuantityOr}, d);
        if (!k.dflt.empty() && !k.dim_from_use)
        {
            const real_t v = parse_quantity(k.dflt, d).value_si;
            if (!(std::abs(v - fallback) <= 1e-12 * std::abs(v)))
                mismatch(k, "default " + std::to_string(fallback));
        }
        return has(key) ? quantity(key, d) : fallback;
    }

    real_t quantity_of(const YAML::Node& n, const std::string& p, Dimension d) const
    {
        if (!n.IsScalar())
            throw DeckError(locate(ctx_, n, p), n.IsSequence() ? "is a list" : "is a mapping",
                            "expected " + describe(d));
        real_t v = 0.0;
        try
        {
            v = parse_quantity(n.Scalar(), d).value_si;
        }
        catch (const Error& e)
        {
            // parse_quantity's message may already say what it expected
            const std::string what = e.what();
            const auto k = what.find("; expected ");
            if (k != std::string::npos)
                throw DeckError(locate(ctx_, n, p), what.substr(0, k), what.substr(k + 2));
            throw DeckError(locate(ctx_, n, p), what, "expected " + describe(d));
        }
        if (!std::isfinite(v))
            throw DeckError(locate(ctx_, n, p), "'" + n.Scalar() + "' is not a finite number in SI units",
                            "expected a finite " + describe(d));
        return v;
    }

    real_t positive(const std::string& key, Dimension d) const
    {
        const real_t v = quantity(key, d);
        if (!(v > 0.0))
            fail(key, "must be positive (got " + scalar_text(key, "") + ")", "expected " + describe(d) + " > 0");
        return v;
    }

    long long integer(const std::string& key, long long fallback) const
    {
        const KeyDoc& k = check(key, {KeyKind::Integer}, dim::none);
        if (!k.dflt.empty() && k.dflt != std::to_string(fallback))
            mismatch(k, "default " + std::to_string(fallback));
        if (!has(key))
            return fallback;
        const std::string t = scalar_text(key, "an integer");
        try
        {
            std::size_t pos = 0;
            const long long v = std::stoll(t, &pos);
            if (pos != t.size())
                throw std::invalid_argument(t);
            return v;
        }
        catch (const std::exception&)
        {
            fail(key, "'" + t + "' is not an integer", "expected an integer");
        }
    }

    std::string text(const std::string& key) const
    {
        check(key, {KeyKind::Text}, dim::none);
        require(key, "a name");
        return scalar_text(key, "a name");
    }
    std::string text(const std::string& key, const std::string& fallback) const
    {
        const KeyDoc& k = check(key, {KeyKind::Text}, dim::none);
        if (!k.dflt.empty() && k.dflt != fallback)
            mismatch(k, "default '" + fallback + "'");
        return has(key) ? scalar_text(key, "a name") : fallback;
    }

    std::string choice(const std::string& key, const std::vector<std::string>& options,
                       const std::string& fallback) const
    {
        const KeyDoc& k = check(key, {KeyKind::Choice, KeyKind::Boolean, KeyKind::BooleanOr}, dim::none);
        // a variant's discriminator lists its own value; the reader dispatches on all of them
        const bool discriminator = k.choices.size() == 1 && k.required;
        for (const auto& c : k.choices)
            if (std::find(options.begin(), options.end(), c) == options.end())
                mismatch(k, "choices " + join(options));
        if (!discriminator && options.size() != k.choices.size())
            mismatch(k, "choices " + join(options));
        if (!k.dflt.empty() && k.dflt != fallback)
            mismatch(k, "default '" + fallback + "'");
        if (!has(key) && !fallback.empty())
            return fallback;
        require(key, "one of " + join(options, " | "));
        const std::string v = scalar_text(key, "one of " + join(options, " | "));
        if (std::find(options.begin(), options.end(), v) == options.end())
            fail(key, "'" + v + "' is not a valid choice", "expected one of " + join(options, " | "));
        return v;
    }

    Vec3 vec3(const std::string& key, Dimension d) const
    {
        check(key, {KeyKind::Vec3}, d);
        require(key, "a list of 3 values, " + describe(d));
        const YAML::Node n = node_[key];
        if (!n.IsSequence() || n.size() != 3)
            fail(key, "is not a list of 3 values", "expected [x, y, z], each " + describe(d));
        Vec3 v;
        for (int i = 0; i < 3; ++i)
            v[i] = quantity_of(n[i], path(key) + "." + std::to_string(i), d);
        return v;
    }
    Vec3 vec3(const std::string& key, Dimension d, const Vec3& fallback) const
    {
        return has(key) ? vec3(key, d) : fallback;
    }

  private:
    /// The entry for key, checked to be of one of kinds and of dimension d.
    const KeyDoc& check(const std::string& key, std::initializer_list<KeyKind> kinds, Dimension d) const
    {
        const KeyDoc& k = doc(key);
        if (std::find(kinds.begin(), kinds.end(), k.kind) == kinds.end())
            mismatch(k, "another kind of value");
        if (!k.dim_from_use && !(k.dim == d))
            mismatch(k, describe(d));
        return k;
    }
    [[noreturn]] void mismatch(const KeyDoc& k, const std::string& read) const
    {
        throw std::logic_error("deck reader: key '" + k.name + "' of section '" + doc_->id + "' is read as " + read +
                               ", which its entry in the key table (deck_keys.cpp) does not say");
    }

    const Context& ctx_;
    YAML::Node node_;
    std::string path_;
    const SectionDoc* doc_;
};

TimeFunction read_time_function(const Section& parent, const YAML::Node& n, const std::string& p, Dimension d);
int component_index(const std::string& c);
void read_components(const Section& s, const std::string& key, Dimension d, std::array<bool, 3>& active,
                     std::array<TimeFunction, 3>& value);
SelectorSpec read_selector(const Section& parent);
std::vector<SetSpec> read_sets(const Context& ctx, const YAML::Node& root, const std::string& key);
BoundarySpec read_boundary(const Context& ctx, const YAML::Node& n, const std::string& p);
LoadSpec read_load(const Context& ctx, const YAML::Node& n, const std::string& p);
ContactSpec read_contact(const Context& ctx, const YAML::Node& n, const std::string& p);
TimeSpec read_time(const Context& ctx, const YAML::Node& root);
GeneratorSpec read_generator(const Section& part);
MaterialSpec read_material(const Section& part);
PartSpec read_part(const Context& ctx, const std::string& name, const YAML::Node& n, const std::string& path);
} // namespace rkfem::deck_detail
