#pragma once
/// @file deck_schema.hpp
/// The deck's keys as one table: every section the reader reads, its keys, each key's kind
/// (a quantity of a dimension, a choice, a list, a subsection, ...), its default where it is a
/// constant, and a description. The reader takes its allowed keys from this table and checks
/// each read against it (deck_section.hpp), so the table cannot drift from what is read; `rkfem
/// schema` writes it as a JSON Schema (draft-07, for editors with a YAML language server) and
/// the manual's deck reference as Markdown.
#include <string>
#include <string_view>
#include <vector>

#include "rkfem/core/units.hpp"

namespace rkfem
{
/// What a key holds.
enum class KeyKind
{
    Quantity,      ///< a number with an optional unit of `dim` (bare: SI)
    Integer,       ///< a whole number
    Boolean,       ///< true | false
    Text,          ///< a name or a path
    Choice,        ///< one of `choices`
    Vec3,          ///< [x, y, z], each a quantity of `dim`
    Section,       ///< a mapping read as the section `sections[0]`
    Variants,      ///< a mapping whose `discriminator` key picks one of `sections`
    List,          ///< a list of mappings, each read as `sections` (one, or variants)
    Map,           ///< names to mappings, each read as `sections` (one, or variants)
    TimeFunction,  ///< a quantity of `dim`, or {value | curve | triangular, scale}
    Components,    ///< {x, y, z}, each a time function of `dim`
    Pairs,         ///< [[a, b], ...]: a of `dim`, b of `dim2`
    QuantityList,  ///< [v, ...] of `count` quantities of `dim`
    QuantityOr,    ///< a quantity of `dim`, or the word `word`
    BooleanOr,     ///< true | false, or a mapping read as `sections[0]`
    Names,         ///< a list of names
    IntegerOrList, ///< a whole number or a list of them
    NameOrList,    ///< a name (or tag) or a list of them
    Integers,      ///< a list of `count` whole numbers (0: any number, at least one)
    Segments,      ///< [[n1, n2, n3, n4], ...]
    Fixed,         ///< all, or a component x | y | z, or a list of them
    Settings,      ///< deck key paths to values (a study case's overrides)
};

/// One key of a section.
struct KeyDoc
{
    std::string name;
    KeyKind kind = KeyKind::Quantity;
    Dimension dim{};
    bool dim_from_use = false; ///< a time function's or component's dimension comes from where it is used
    std::vector<std::string> choices;
    std::vector<std::string> sections; ///< the section(s) a Section, Variants, List, Map or BooleanOr reads
    std::string discriminator;         ///< the key that picks the variant (type, model)
    Dimension dim2{};
    int count = 0;
    std::string word;
    bool required = false;
    std::string dflt; ///< the default as a deck writes it; empty: none, or computed (the description says)
    std::string description;
};

/// One section: a mapping of the deck, its keys, and what it is for.
struct SectionDoc
{
    std::string id; ///< e.g. "part", "contact.rigid-wall"
    std::string title;
    std::string description;
    std::vector<KeyDoc> keys;
    const KeyDoc* find(std::string_view key) const;
};

/// Every section: the run deck's ("deck" and below), the material-point deck's
/// ("material-point") and the study file's ("study").
const std::vector<SectionDoc>& deck_sections();

/// The section `id`; throws std::logic_error for an id the table lacks (a reader's bug).
const SectionDoc& deck_section(std::string_view id);

/// The keys `id` allows, in the table's order.
std::vector<std::string> deck_section_keys(std::string_view id);

/// A JSON Schema (draft-07) of a run deck (root "deck"), a material-point deck (root
/// "material-point") or a study file (root "study").
std::string deck_json_schema(std::string_view root);

/// The deck reference as Markdown: one table per section, the run deck's in the order a deck is
/// read, then the material-point deck's and the study file's (each section once).
std::string deck_reference_markdown();
} // namespace rkfem
