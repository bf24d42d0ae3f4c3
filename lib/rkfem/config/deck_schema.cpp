/// @file deck_schema.cpp
/// The key table (deck_keys.cpp) written as a JSON Schema (draft-07) and as the manual's deck
/// reference (Markdown).
#include "rkfem/config/deck_schema.hpp"

#include "rkfem/io/json_text.hpp"

#include <cstdio>
#include <set>
#include <sstream>

namespace rkfem
{
namespace
{
/// {"k1": v1, ...} from raw JSON values.
std::string object(const std::vector<std::pair<std::string, std::string>>& members)
{
    std::string out = "{";
    for (std::size_t i = 0; i < members.size(); ++i)
        out += (i ? ", " : "") + json_quote(members[i].first) + ": " + members[i].second;
    return out + "}";
}

std::string array(const std::vector<std::string>& items)
{
    std::string out = "[";
    for (std::size_t i = 0; i < items.size(); ++i)
        out += (i ? ", " : "") + items[i];
    return out + "]";
}

bool is_number(const std::string& s)
{
    if (s.empty())
        return false;
    char* end = nullptr;
    std::strtod(s.c_str(), &end);
    return end && *end == '\0';
}

/// A number with an optional unit after it, as parse_quantity reads it (a bare number is SI):
/// the unit one of the dimension's symbols, or an expression of symbols (m/s, kg/m^3, 1/s) that
/// the reader checks; a quantity whose dimension comes from its use takes any unit.
std::string quantity_pattern(Dimension d, bool from_use)
{
    std::string symbols;
    if (!from_use)
    {
        const std::string known = known_units_for(d);
        std::size_t start = 0;
        while (start < known.size())
        {
            std::size_t end = known.find(", ", start);
            if (end == std::string::npos)
                end = known.size();
            symbols += '|';
            symbols += known.substr(start, end - start);
            start = end + 2;
        }
    }
    const std::string any_symbol = "[A-Za-z%]+";
    const std::string expression = "[0-9A-Za-z%]*[/*^][0-9A-Za-z%/*^. ()-]*";
    std::string pattern = "^\\s*[-+]?([0-9]+\\.?[0-9]*|\\.[0-9]+)([eE][-+]?[0-9]+)?(\\s*(";
    pattern += from_use ? any_symbol + "|" + expression : expression + symbols;
    pattern += "))?\\s*$";
    return pattern;
}

std::string quantity_schema(Dimension d, bool from_use)
{
    const std::string what = from_use ? std::string("a number with a unit of the quantity it sets (bare: SI)")
                                      : describe(d) + "; a bare number is SI";
    return object(
        {{"anyOf", array({object({{"type", "\"number\""}}),
                          object({{"type", "\"string\""}, {"pattern", json_quote(quantity_pattern(d, from_use))}})})},
         {"description", json_quote(what)}});
}

std::string schema_ref(const std::string& id)
{
    return object({{"$ref", json_quote("#/definitions/" + id)}});
}

std::string integer_schema()
{
    return object({{"type", "\"integer\""}});
}

/// The discriminator's value of a variant section (its one choice).
std::string variant_value(const std::string& id, const std::string& discriminator)
{
    const KeyDoc* k = deck_section(id).find(discriminator);
    return k && k->choices.size() == 1 ? k->choices[0] : id;
}

/// One of sections, picked by the discriminator (or the one section).
std::string sections_schema(const std::vector<std::string>& ids, const std::string& discriminator)
{
    if (ids.size() == 1)
        return schema_ref(ids[0]);
    std::vector<std::string> values, cases;
    for (const auto& id : ids)
    {
        const std::string v = variant_value(id, discriminator);
        values.push_back(json_quote(v));
        cases.push_back(
            object({{"if", object({{"properties", object({{discriminator, object({{"const", json_quote(v)}})}})},
                                   {"required", array({json_quote(discriminator)})}})},
                    {"then", schema_ref(id)}}));
    }
    return object({{"type", "\"object\""},
                   {"required", array({json_quote(discriminator)})},
                   {"properties", object({{discriminator, object({{"enum", array(values)}})}})},
                   {"allOf", array(cases)}});
}

std::string enum_schema(const std::vector<std::string>& choices)
{
    std::vector<std::string> items;
    for (const auto& c : choices)
    {
        items.push_back(json_quote(c));
        if (is_number(c)) // YAML reads `order: 2` as a number
            items.push_back(c);
    }
    return object({{"enum", array(items)}});
}

std::string key_schema(const KeyDoc& k)
{
    const std::string q = quantity_schema(k.dim, k.dim_from_use);
    switch (k.kind)
    {
    case KeyKind::Quantity:
        return q;
    case KeyKind::Integer:
        return integer_schema();
    case KeyKind::Boolean:
        return object({{"type", "\"boolean\""}});
    case KeyKind::Text:
        return object({{"type", "\"string\""}});
    case KeyKind::Choice:
        return enum_schema(k.choices);
    case KeyKind::Vec3:
        return object({{"type", "\"array\""}, {"minItems", "3"}, {"maxItems", "3"}, {"items", q}});
    case KeyKind::Section:
        return schema_ref(k.sections[0]);
    case KeyKind::Variants:
        return sections_schema(k.sections, k.discriminator);
    case KeyKind::List:
        return object({{"type", "\"array\""}, {"items", sections_schema(k.sections, k.discriminator)}});
    case KeyKind::Map:
        return object({{"type", "\"object\""},
                       {"minProperties", k.required ? "1" : "0"},
                       {"additionalProperties", sections_schema(k.sections, k.discriminator)}});
    case KeyKind::TimeFunction:
        return object({{"anyOf", array({q, schema_ref("time-function")})}});
    case KeyKind::Components:
        return object({{"allOf", array({schema_ref("components")})}, {"minProperties", "1"}});
    case KeyKind::Pairs:
    {
        const std::string pair =
            object({{"type", "\"array\""},
                    {"items", array({q, quantity_schema(k.dim2, k.dim_from_use && k.dim2 == dim::none)})},
                    {"minItems", "2"},
                    {"maxItems", "2"}});
        return object({{"type", "\"array\""}, {"minItems", "2"}, {"items", pair}});
    }
    case KeyKind::QuantityList:
        return object({{"type", "\"array\""},
                       {"minItems", std::to_string(k.count)},
                       {"maxItems", std::to_string(k.count)},
                       {"items", q}});
    case KeyKind::QuantityOr:
        return object({{"anyOf", array({q, object({{"const", json_quote(k.word)}})})}});
    case KeyKind::BooleanOr:
        return object({{"anyOf", array({object({{"type", "\"boolean\""}}), schema_ref(k.sections[0])})}});
    case KeyKind::Names:
        return object({{"type", "\"array\""}, {"minItems", "1"}, {"items", object({{"type", "\"string\""}})}});
    case KeyKind::IntegerOrList:
        return object(
            {{"anyOf", array({integer_schema(),
                              object({{"type", "\"array\""}, {"minItems", "1"}, {"items", integer_schema()}})})}});
    case KeyKind::NameOrList:
    {
        const std::string one = object({{"type", "[\"string\", \"integer\"]"}});
        return object({{"anyOf", array({one, object({{"type", "\"array\""}, {"minItems", "1"}, {"items", one}})})}});
    }
    case KeyKind::Integers:
        return k.count > 0 ? object({{"type", "\"array\""},
                                     {"minItems", std::to_string(k.count)},
                                     {"maxItems", std::to_string(k.count)},
                                     {"items", integer_schema()}})
                           : object({{"type", "\"array\""}, {"minItems", "1"}, {"items", integer_schema()}});
    case KeyKind::Segments:
        return object(
            {{"type", "\"array\""},
             {"minItems", "1"},
             {"items",
              object({{"type", "\"array\""}, {"minItems", "4"}, {"maxItems", "4"}, {"items", integer_schema()}})}});
    case KeyKind::Settings:
        return object({{"type", "\"object\""}});
    case KeyKind::Fixed:
    {
        const std::string comp = object({{"enum", array({"\"x\"", "\"y\"", "\"z\""})}});
        return object({{"anyOf", array({object({{"enum", array({"\"all\"", "\"x\"", "\"y\"", "\"z\""})}}),
                                        object({{"type", "\"array\""}, {"minItems", "1"}, {"items", comp}})})}});
    }
    }
    return "{}";
}

/// The default as JSON, where the table gives one.
std::string default_json(const KeyDoc& k)
{
    if (k.dflt.empty())
        return "";
    if (k.kind == KeyKind::Boolean || (k.kind == KeyKind::BooleanOr && (k.dflt == "true" || k.dflt == "false")))
        return k.dflt;
    if (k.kind == KeyKind::Vec3)
        return k.dflt;
    if ((k.kind == KeyKind::Quantity || k.kind == KeyKind::Integer) && is_number(k.dflt))
        return k.dflt[0] == '.' ? "0" + k.dflt : k.dflt;
    return json_quote(k.dflt);
}

std::string section_schema(const SectionDoc& s)
{
    std::vector<std::pair<std::string, std::string>> props;
    std::vector<std::string> req;
    for (const auto& k : s.keys)
    {
        std::vector<std::pair<std::string, std::string>> p = {{"description", json_quote(k.description)},
                                                              {"allOf", array({key_schema(k)})}};
        if (const std::string d = default_json(k); !d.empty())
            p.emplace_back("default", d);
        props.emplace_back(k.name, object(p));
        if (k.required)
            req.push_back(json_quote(k.name));
    }
    std::vector<std::pair<std::string, std::string>> out = {{"type", "\"object\""},
                                                            {"title", json_quote(s.title)},
                                                            {"description", json_quote(s.description)},
                                                            {"properties", object(props)},
                                                            {"additionalProperties", "false"}};
    if (!req.empty())
        out.emplace_back("required", array(req));
    return object(out);
}

/// The sections reachable from root, root first, each once, in the order a deck reads them.
std::vector<const SectionDoc*> reachable(std::string_view root, std::set<std::string>& seen)
{
    std::vector<const SectionDoc*> out;
    auto visit = [&](const std::string& id, auto&& self) -> void
    {
        if (!seen.insert(id).second)
            return;
        const SectionDoc& s = deck_section(id);
        out.push_back(&s);
        for (const auto& k : s.keys)
        {
            for (const auto& child : k.sections)
                self(child, self);
            if (k.kind == KeyKind::TimeFunction)
                self("time-function", self);
            if (k.kind == KeyKind::Components)
                self("components", self);
        }
    };
    visit(std::string(root), visit);
    return out;
}

std::string escape_cell(const std::string& s)
{
    std::string out;
    for (const char c : s)
        out += c == '|' ? std::string("\\|") : std::string(1, c);
    return out;
}

std::string code_list(const std::vector<std::string>& items, const char* sep)
{
    std::string out;
    for (std::size_t i = 0; i < items.size(); ++i)
        out += (i ? sep : "") + ("`" + items[i] + "`");
    return out;
}

std::string titles(const std::vector<std::string>& ids)
{
    std::vector<std::string> t;
    for (const auto& id : ids)
        t.push_back(deck_section(id).title);
    return code_list(t, ", ");
}

/// What a key holds, in words.
std::string value_words(const KeyDoc& k)
{
    const std::string d = k.dim_from_use ? std::string("a quantity of the value it sets") : describe(k.dim);
    switch (k.kind)
    {
    case KeyKind::Quantity:
        return d;
    case KeyKind::Integer:
        return "an integer";
    case KeyKind::Boolean:
        return "true or false";
    case KeyKind::Text:
        return "a name";
    case KeyKind::Choice:
        return "one of " + code_list(k.choices, " | ");
    case KeyKind::Vec3:
        return "[x, y, z], each " + d;
    case KeyKind::Section:
        return "a mapping: " + titles(k.sections);
    case KeyKind::Variants:
        return "a mapping, by `" + k.discriminator + "`: " + titles(k.sections);
    case KeyKind::List:
        return "a list of mappings: " + titles(k.sections);
    case KeyKind::Map:
        return "names to mappings: " + titles(k.sections);
    case KeyKind::TimeFunction:
        return d + ", or a time function";
    case KeyKind::Components:
        return "{x, y, z}, each " + d + " or a time function";
    case KeyKind::Pairs:
        return "[[a, b], ...]: a " + (k.dim_from_use ? d : describe(k.dim)) + ", b " + describe(k.dim2);
    case KeyKind::QuantityList:
        return "a list of " + std::to_string(k.count) + ", each " + d;
    case KeyKind::QuantityOr:
        return d + ", or `" + k.word + "`";
    case KeyKind::BooleanOr:
        return "true, false or a mapping: " + titles(k.sections);
    case KeyKind::Names:
        return "a list of names";
    case KeyKind::IntegerOrList:
        return "an integer or a list of them";
    case KeyKind::NameOrList:
        return "a name or tag, or a list of them";
    case KeyKind::Integers:
        return k.count > 0 ? "a list of " + std::to_string(k.count) + " integers" : "a list of integers";
    case KeyKind::Segments:
        return "[[n1, n2, n3, n4], ...]";
    case KeyKind::Fixed:
        return "`all`, a component or a list of them";
    case KeyKind::Settings:
        return "a mapping of deck key paths to values";
    }
    return "";
}
} // namespace

std::string deck_json_schema(std::string_view root)
{
    std::vector<std::pair<std::string, std::string>> defs;
    std::set<std::string> seen;
    for (const SectionDoc* s : reachable(root, seen))
        defs.emplace_back(s->id, section_schema(*s));
    const SectionDoc& r = deck_section(root);
    return object({{"$schema", "\"http://json-schema.org/draft-07/schema#\""},
                   {"title", json_quote("rkfem: " + deck_section(root).title)},
                   {"description", json_quote(r.description + " Generated by `rkfem schema` from the reader's key "
                                                              "table; quantities take a unit (bare numbers are SI).")},
                   {"allOf", array({schema_ref(std::string(root))})},
                   {"definitions", object(defs)}}) +
           "\n";
}

std::string deck_reference_markdown()
{
    std::ostringstream md;
    std::set<std::string> seen;
    for (const char* root : {"deck", "material-point", "study"})
        for (const SectionDoc* s : reachable(root, seen))
        {
            md << (s->id == root ? "## " : "### ") << s->title << "\n\n" << s->description << "\n\n";
            md << "| key | value | default | description |\n|---|---|---|---|\n";
            for (const auto& k : s->keys)
            {
                md << "| `" << k.name << "`" << (k.required ? " (required)" : "") << " | "
                   << escape_cell(value_words(k)) << " | ";
                if (!k.dflt.empty())
                    md << '`' << escape_cell(k.dflt) << '`';
                md << " | " << escape_cell(k.description) << " |\n";
            }
            md << "\n";
        }
    return md.str();
}
} // namespace rkfem
