#include "rkfem/config/deck.hpp"
#include "rkfem/config/deck_section.hpp"
#include "rkfem/config/erk_table_names.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <yaml-cpp/depthguard.h>
#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include "rkfem/core/error.hpp"
#include "rkfem/core/units.hpp"

namespace rkfem
{
using namespace deck_detail;

namespace
{
/// A message part as one printable line: control characters (NUL included) as \xNN, and a part
/// past 300 characters cut in the middle (a 5 MB value is not echoed whole).
std::string printable(const std::string& s)
{
    std::string out;
    for (const unsigned char c : s)
        if (c < 0x20 || c == 0x7f)
        {
            char b[8];
            std::snprintf(b, sizeof b, "\\x%02x", c);
            out += b;
        }
        else
            out += static_cast<char>(c);
    if (out.size() > 300)
        out = out.substr(0, 200) + "... (" + std::to_string(out.size() - 260) + " characters cut) ..." +
              out.substr(out.size() - 60);
    return out;
}

std::string format_error(const SourceLocation& loc, const std::string& problem, const std::string& expected)
{
    std::string msg = printable(loc.where) + ": " + (loc.path.empty() ? std::string("deck") : printable(loc.path)) +
                      ": " + printable(problem);
    if (!expected.empty())
        msg += "; " + printable(expected);
    return msg;
}
} // namespace

DeckError::DeckError(const SourceLocation& loc, const std::string& problem, const std::string& expected)
    : std::runtime_error(format_error(loc, problem, expected)), location(loc)
{
}

namespace
{
/// Applies "a.b.0.c=value" to the YAML tree.
void apply_override(YAML::Node root, const std::string& text, Context& ctx)
{
    const auto eq = text.find('=');
    if (eq == std::string::npos || eq == 0)
        throw DeckError({"--set " + text, ""}, "is not of the form key.path=value",
                        "expected e.g. --set parts.column.material.E=\"210 GPa\"");
    const std::string path = text.substr(0, eq);
    const std::string value = text.substr(eq + 1);
    if (value.find_first_not_of(" \t") == std::string::npos)
        throw DeckError({"--set " + text, path}, "has no value after '='",
                        "expected a value (~ removes the key, e.g. --set parts.column.hourglass=~)");
    std::vector<std::string> keys;
    std::stringstream ss(path);
    for (std::string k; std::getline(ss, k, '.');)
        keys.push_back(k);
    YAML::Node value_node;
    try
    {
        value_node = YAML::Load(value);
    }
    catch (const YAML::Exception& e)
    {
        throw DeckError({"--set " + text, path}, "value is not valid YAML (" + e.msg + ")", "");
    }
    // Walk with fresh handles (yaml-cpp nodes are references into the tree).
    // the last key may be the list's size: the value is appended (a contact, a condition)
    auto list_index = [&](const YAML::Node& list, const std::string& k, bool may_append)
    {
        std::string range = list.size() ? "0.." + std::to_string(list.size() - 1) : "none (the list is empty)";
        if (may_append)
            range += ", or " + std::to_string(list.size()) + " to append an entry";
        std::size_t idx = 0;
        if (k.empty() || k.find_first_not_of("0123456789") != std::string::npos || k.size() > 9)
            throw DeckError({"--set " + text, path}, "'" + k + "' indexes a list", "expected an index " + range);
        idx = std::stoul(k);
        if (idx > list.size() || (idx == list.size() && !may_append))
            throw DeckError({"--set " + text, path}, "index " + k + " is past the end", "expected " + range);
        return idx;
    };
    auto owner = [&](std::size_t i) { return i == 0 ? std::string("the deck") : "'" + keys[i - 1] + "'"; };
    std::vector<YAML::Node> chain{root};
    for (std::size_t i = 0; i + 1 < keys.size(); ++i)
    {
        YAML::Node cur = chain.back();
        const std::string& k = keys[i];
        if (cur.IsSequence())
            chain.push_back(cur[list_index(cur, k, false)]);
        else if (cur.IsMap() || cur.IsNull() || !cur.IsDefined())
        {
            if (!cur[k].IsDefined() || cur[k].IsNull())
                cur[k] = YAML::Node(YAML::NodeType::Map);
            chain.push_back(cur[k]);
        }
        else
            throw DeckError({"--set " + text, path}, owner(i) + " is a value, not a section",
                            "expected a path through mappings and lists");
    }
    YAML::Node last = chain.back();
    if (last.IsSequence())
    {
        const std::size_t idx = list_index(last, keys.back(), true);
        if (idx == last.size())
            last.push_back(value_node);
        else
            last[idx] = value_node;
    }
    else if (last.IsMap() || last.IsNull() || !last.IsDefined())
        last[keys.back()] = value_node;
    else
        throw DeckError({"--set " + text, path}, owner(keys.size() - 1) + " is a value, not a section",
                        "expected a path through mappings and lists");
    ctx.overridden[path] = text;
}

/// output: precision and compression, into out.
void read_output(const Context& ctx, const YAML::Node& root, OutputSpec& out)
{
    if (root["output"].IsDefined() && !root["output"].IsNull())
    {
        Section o(ctx, root["output"], "output", "output");
        out.single = o.choice("precision", {"single", "double"}, "single") == "single";
        const std::int64_t level = o.integer("compression", 0);
        if (level < 0 || level > 9)
            o.fail("compression", "is outside 0-9", "expected a gzip level from 0 (none) to 9 (smallest)");
        out.compression = static_cast<int>(level);
    }
}

/// parts: the mapping of part names to parts, each read in the deck's order, into out.
void read_parts(const Context& ctx, const YAML::Node& root, const Section& top, std::vector<PartSpec>& out)
{
    top.require("parts", "a mapping of part names to parts");
    const YAML::Node parts = root["parts"];
    if (!parts.IsMap() || parts.size() == 0)
        top.fail("parts", "is empty or not a mapping", "expected name: {generator, material, ...}");
    reject_repeated_keys(ctx, parts, "parts");
    for (const auto& kv : parts)
    {
        const std::string name = kv.first.as<std::string>();
        out.push_back(read_part(ctx, name, kv.second, "parts." + name));
    }
}

/// Throws at the first node or face set whose part is not a part of the deck.
void check_set_parts(const Deck& deck)
{
    auto check_part = [&](const SetSpec& s, const char* key)
    {
        if (s.part.empty())
            return;
        for (const auto& p : deck.parts)
            if (p.name == s.part)
                return;
        std::vector<std::string> names;
        for (const auto& p : deck.parts)
            names.push_back(p.name);
        throw DeckError({s.loc.where, std::string(key) + "." + s.name + ".part"}, "unknown part '" + s.part + "'",
                        "expected one of " + join(names));
    };
    for (const auto& s : deck.node_sets)
        check_part(s, "node_sets");
    for (const auto& s : deck.face_sets)
        check_part(s, "face_sets");
}

/// boundary_conditions, loads and contacts: lists of entries, each read by its reader, into the deck.
void read_conditions(const Context& ctx, const YAML::Node& root, const Section& top, Deck& deck)
{
    auto list = [&](const char* key, auto&& reader, auto& out)
    {
        const YAML::Node n = root[key];
        if (!n.IsDefined() || n.IsNull())
            return;
        if (!n.IsSequence())
            top.fail(key, "is not a list", "expected a list of entries (- ...)");
        for (std::size_t i = 0; i < n.size(); ++i)
            out.push_back(reader(ctx, n[i], std::string(key) + "." + std::to_string(i)));
    };
    list("boundary_conditions", read_boundary, deck.boundary_conditions);
    list("loads", read_load, deck.loads);
    list("contacts", read_contact, deck.contacts);
}

/// Throws at the first boundary condition or load whose set, or contact surface, the deck does not define.
void check_set_references(const Deck& deck)
{
    auto set_exists = [&](const std::vector<SetSpec>& sets, const std::string& name)
    { return std::any_of(sets.begin(), sets.end(), [&](const SetSpec& s) { return s.name == name; }); };
    auto names_of = [&](const std::vector<SetSpec>& sets)
    {
        std::vector<std::string> v;
        for (const auto& s : sets)
            v.push_back(s.name);
        return v.empty() ? std::string("(none defined)") : join(v);
    };
    for (std::size_t i = 0; i < deck.boundary_conditions.size(); ++i)
    {
        const auto& b = deck.boundary_conditions[i];
        if (!set_exists(deck.node_sets, b.node_set))
            throw DeckError({b.loc.where, b.loc.path + ".node_set"}, "unknown node set '" + b.node_set + "'",
                            "expected one of " + names_of(deck.node_sets));
    }
    for (const auto& l : deck.loads)
    {
        const bool face = l.kind == LoadSpec::Kind::Pressure;
        const auto& sets = face ? deck.face_sets : deck.node_sets;
        if (!set_exists(sets, l.set))
            throw DeckError({l.loc.where, l.loc.path + (face ? ".face_set" : ".node_set")},
                            "unknown " + std::string(face ? "face" : "node") + " set '" + l.set + "'",
                            "expected one of " + names_of(sets));
    }

    for (std::size_t i = 0; i < deck.contacts.size(); ++i)
    {
        const ContactSpec& c = deck.contacts[i];
        for (std::size_t k = 0; k < c.surfaces.size(); ++k)
        {
            const std::string& name = c.surfaces[k];
            const bool is_part =
                std::any_of(deck.parts.begin(), deck.parts.end(), [&](const PartSpec& p) { return p.name == name; });
            if (!is_part && !set_exists(deck.face_sets, name))
            {
                std::vector<std::string> names;
                for (const auto& p : deck.parts)
                    names.push_back(p.name);
                for (const auto& f : deck.face_sets)
                    names.push_back(f.name);
                throw DeckError({c.loc.where, c.loc.path + ".surfaces." + std::to_string(k)},
                                "unknown surface '" + name + "'", "expected a part or face-set name: " + join(names));
            }
        }
    }
}

/// The part a section's key names, when it names one (empty: none), is one of the deck's.
void require_part(const Section& s, const char* key, const std::string& name, const Deck& deck)
{
    if (name.empty() ||
        std::any_of(deck.parts.begin(), deck.parts.end(), [&](const PartSpec& p) { return p.name == name; }))
        return;
    std::vector<std::string> names;
    for (const auto& p : deck.parts)
        names.push_back(p.name);
    s.fail(key, "unknown part '" + name + "'", "expected one of " + join(names));
}

/// A measure's `direction` (unit; `fallback` when not given) and `damage` threshold (0.95 when not
/// given); `direction_is` and `damage_is` say what each is, for the errors.
void read_line(const Section& s, const Vec3& fallback, const std::string& direction_is, const std::string& damage_is,
               Vec3& direction, real_t& damage)
{
    direction = s.vec3("direction", dim::none, fallback);
    if (!(direction.norm() > 0.0))
        s.fail("direction", "is the zero vector", "expected " + direction_is);
    direction.normalize();
    damage = s.quantity("damage", dim::none, 0.95);
    if (!(damage > 0.0 && damage <= 1.0))
        s.fail("damage", "is outside (0, 1]", "expected " + damage_is);
}

/// impact: the target and projectile parts, point, direction and damage, into deck.impact.
void read_impact(const Context& ctx, const Section& top, Deck& deck)
{
    if (top.has("impact"))
    {
        Section s(ctx, top.node("impact"), "impact", "impact");
        ImpactSpec& im = deck.impact;
        im.active = true;
        im.target = s.text("target");
        im.projectile = s.text("projectile", "");
        im.point = s.vec3("point", dim::length);
        read_line(s, -Vec3::UnitZ(), "the shot line's direction, into the target",
                  "the damage at which material counts as gone (0.95)", im.direction, im.damage);
        require_part(s, "target", im.target, deck);
        require_part(s, "projectile", im.projectile, deck);
        if (im.target == im.projectile)
            s.fail("projectile", "is the target", "expected the projectile's part, not the target's");
        im.loc = s.loc();
    }
}

/// spall: the part, point, direction and damage, into deck.spall.
void read_spall(const Context& ctx, const Section& top, Deck& deck)
{
    if (!top.has("spall"))
        return;
    Section s(ctx, top.node("spall"), "spall", "spall");
    SpallSpec& sp = deck.spall;
    sp.active = true;
    sp.part = s.text("part");
    sp.point = s.vec3("point", dim::length);
    read_line(s, Vec3::UnitZ(), "the direction into the part from its back face",
              "the damage at which the material has cracked (0.95)", sp.direction, sp.damage);
    require_part(s, "part", sp.part, deck);
    sp.loc = s.loc();
}

/// probes: the mapping of probe names to points (and parts), into out.
void read_probes(const Context& ctx, const YAML::Node& root, const Section& top, std::vector<ProbeSpec>& out)
{
    const YAML::Node probes = root["probes"];
    if (probes.IsDefined() && !probes.IsNull())
    {
        if (!probes.IsMap())
            top.fail("probes", "is not a mapping", "expected name: {point: [x, y, z]}");
        reject_repeated_keys(ctx, probes, "probes");
        for (const auto& kv : probes)
        {
            const std::string name = kv.first.as<std::string>();
            Section s(ctx, kv.second, "probes." + name, "probe");
            ProbeSpec pr;
            pr.name = name;
            pr.point = s.vec3("point", dim::length);
            pr.part = s.text("part", "");
            pr.loc = s.loc();
            out.push_back(pr);
        }
    }
}

/// sections: the mapping of section names to planes (point, normal, part, tolerance), into out.
void read_section_planes(const Context& ctx, const YAML::Node& root, const Section& top, std::vector<SectionSpec>& out)
{
    const YAML::Node sections = root["sections"];
    if (sections.IsDefined() && !sections.IsNull())
    {
        if (!sections.IsMap())
            top.fail("sections", "is not a mapping", "expected name: {point: [x, y, z], normal: [nx, ny, nz], part}");
        reject_repeated_keys(ctx, sections, "sections");
        for (const auto& kv : sections)
        {
            const std::string name = kv.first.as<std::string>();
            Section s(ctx, kv.second, "sections." + name, "section-plane");
            SectionSpec sc;
            sc.name = name;
            sc.point = s.vec3("point", dim::length);
            sc.normal = s.vec3("normal", dim::none);
            if (!(sc.normal.norm() > 0))
                s.fail("normal", "is the zero vector", "expected the plane's normal, e.g. [0, 0, 1]");
            sc.normal.normalize();
            sc.part = s.text("part", "");
            sc.tolerance = s.has("tolerance") ? s.quantity("tolerance", dim::length) : -1.0;
            if (s.has("tolerance") && !(sc.tolerance >= 0))
                s.fail("tolerance", "is negative", "expected a length >= 0");
            sc.loc = s.loc();
            out.push_back(sc);
        }
    }
}

Deck build(const YAML::Node& root, Context& ctx)
{
    if (!root.IsMap())
        throw DeckError({ctx.name, ""}, "is not a YAML mapping", "expected top-level keys title, time, parts, ...");
    Section top(ctx, root, "", "deck");
    Deck deck;
    deck.path = ctx.name;
    deck.title = top.text("title", "");
    deck.time = read_time(ctx, root);
    deck.time_loc = locate(ctx, root["time"], "time");
    read_output(ctx, root, deck.output);
    read_parts(ctx, root, top, deck.parts);
    deck.node_sets = read_sets(ctx, root, "node_sets");
    deck.face_sets = read_sets(ctx, root, "face_sets");
    check_set_parts(deck);
    read_conditions(ctx, root, top, deck);
    check_set_references(deck);
    read_impact(ctx, top, deck);
    read_spall(ctx, top, deck);
    read_probes(ctx, root, top, deck.probes);
    read_section_planes(ctx, root, top, deck.sections);
    return deck;
}
} // namespace

namespace
{
/// Sees the documents of a stream and nothing else: where the second one starts.
class DocumentCounter : public YAML::EventHandler
{
  public:
    void OnDocumentStart(const YAML::Mark& mark) override
    {
        if (++documents == 2)
            second = mark;
    }
    void OnDocumentEnd() override {}
    void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
    void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
    void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t, const std::string&) override {}
    void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {}
    void OnSequenceEnd() override {}
    void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {}
    void OnMapEnd() override {}
    int documents = 0;
    YAML::Mark second = YAML::Mark::null_mark();
};

/// The one YAML document of a deck; a second one (after `---`) is refused, not ignored. The
/// documents are counted up to two: yaml-cpp 0.7's LoadAll never returns on some malformed
/// input (its parser hands out empty documents without reading on, found by the deck fuzzer).
YAML::Node load_document(const std::string& text, const std::string& name)
{
    YAML::Node doc;
    try
    {
        std::istringstream in(text);
        YAML::Parser parser(in);
        DocumentCounter counter;
        while (counter.documents < 2 && parser.HandleNextDocument(counter))
        {
        }
        if (counter.documents > 1)
            throw DeckError(
                {counter.second.is_null() ? name : name + ":" + std::to_string(counter.second.line + 1), ""},
                "holds more than one YAML document", "expected one document (remove the second after ---)");
        doc = YAML::Load(text);
    }
    catch (const YAML::DeepRecursion& e)
    {
        // yaml-cpp stops at a fixed depth and says only "bad file"
        throw DeckError({name + ":" + std::to_string(e.mark.line + 1), ""},
                        "nested deeper than the YAML reader allows (" + std::to_string(e.depth()) + " levels)",
                        "expected a deck nested a few levels deep");
    }
    catch (const YAML::Exception& e)
    {
        throw DeckError({name + ":" + std::to_string(e.mark.line + 1), ""}, "YAML syntax error: " + e.msg,
                        "expected a valid YAML document");
    }
    return doc;
}
} // namespace

Deck parse_deck(const std::string& text, const std::string& name, const std::vector<std::string>& overrides)
{
    Context ctx{name, {}};
    YAML::Node root = load_document(text, name);
    try
    {
        for (const auto& o : overrides)
            apply_override(root, o, ctx);
        return build(root, ctx);
    }
    catch (const YAML::Exception& e)
    {
        // a key that is not a plain name (`? [a, b]`), or a node of an unexpected kind
        throw DeckError({e.mark.is_null() ? name : name + ":" + std::to_string(e.mark.line + 1), "(deck)"}, e.msg,
                        "expected mappings whose keys are plain names");
    }
}

MaterialPointDeck read_material_point_deck(const std::string& path)
{
    std::stringstream ss;
    ss << read_deck_text(path, "a readable YAML material-point deck");
    Context ctx{path, {}};
    const YAML::Node root = load_document(ss.str(), path);
    if (!root.IsMap())
        throw DeckError({path, ""}, "is not a YAML mapping", "expected top-level keys title, material, path");
    Section top(ctx, root, "", "material-point");
    MaterialPointDeck d;
    d.path = path;
    d.title = top.text("title", "");
    d.material = read_material(top);
    top.require("path", "a mapping with type, strain, rate, steps");
    Section p(ctx, top.node("path"), "path", "path");
    MaterialPathSpec& lp = d.load_path;
    lp.type = p.choice("type",
                       {"uniaxial-stress", "uniaxial-strain", "hydrostatic", "pure-shear", "triaxial", "rotation"}, "");
    lp.strain = p.quantity("strain", dim::none);
    if (lp.strain == 0.0)
        p.fail("strain", "is zero", "expected a nonzero final strain (negative for compression)");
    lp.rate = p.positive("rate", Dimension{0, 0, -1});
    lp.confinement = p.quantity("confinement", dim::pressure, 0.0);
    if (lp.confinement < 0)
        p.fail("confinement", "is negative", "expected a lateral pressure >= 0");
    lp.angle = p.quantity("angle", dim::none, 0.0);
    lp.length = p.quantity("length", dim::length, 0.0);
    if (lp.length < 0)
        p.fail("length", "is negative", "expected a crack-band length > 0 (or omit it for the model default)");
    const long long steps = p.integer("steps", 1000);
    if (steps < 1 || steps > 100000000)
        p.fail("steps", steps < 1 ? "is below 1" : "is above 10^8", "expected a number of steps from 1 to 10^8");
    lp.steps = static_cast<int>(steps);
    lp.loc = p.loc();
    return d;
}

std::string read_deck_text(const std::string& path, const std::string& expected)
{
    // a device (/dev/zero), a FIFO without a writer or a directory would hang or fail the read:
    // only regular files, and none past 64 MB (a deck is a few kB)
    std::error_code ec;
    const std::filesystem::file_status st = std::filesystem::status(path, ec);
    if (ec || !std::filesystem::exists(st))
        throw DeckError({path, ""}, "cannot be opened (no such file)", "expected " + expected);
    if (!std::filesystem::is_regular_file(st))
        throw DeckError({path, ""}, "is not a regular file", "expected " + expected);
    const auto size = std::filesystem::file_size(path, ec);
    if (!ec && size > (64u << 20))
        throw DeckError({path, ""}, "is " + std::to_string(size >> 20) + " MB",
                        "expected " + expected + " under 64 MB");
    std::ifstream in(path);
    if (!in)
        throw DeckError({path, ""}, "cannot be opened", "expected " + expected);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

Deck read_deck(const std::string& path, const std::vector<std::string>& overrides)
{
    return parse_deck(read_deck_text(path, "a readable YAML deck file"), path, overrides);
}
} // namespace rkfem
