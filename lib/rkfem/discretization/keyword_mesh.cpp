#include "rkfem/discretization/keyword_mesh.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <unordered_map>
#include <vector>

#include "rkfem/core/error.hpp"
#include "rkfem/io/keyword_file.hpp"

namespace rkfem
{
namespace
{
struct Reader
{
    const GeneratorSpec& g;
    SourceLocation where;
    int line = 0;
    std::string file; // the file `line` is in (the mesh file or one it includes)

    [[noreturn]] void fail(const std::string& problem, const std::string& expected) const
    {
        throw DeckError(where,
                        (file.empty() ? g.mesh_file : file) + (line > 0 ? ":" + std::to_string(line) : std::string()) +
                            ": " + problem,
                        expected);
    }
    long long integer(const std::string& f, const char* what) const
    {
        long long v = 0;
        const auto r = std::from_chars(f.data(), f.data() + f.size(), v);
        if (f.empty() || r.ec != std::errc() || r.ptr != f.data() + f.size())
            fail(std::string(what) + " '" + f + "' is not an integer", "expected an integer field");
        return v;
    }
    real_t number(const std::string& f, const char* what) const
    {
        if (f.empty())
            return 0.0; // a blank coordinate field is 0, as LS-DYNA reads it
        std::size_t used = 0;
        real_t v = 0.0;
        try
        {
            v = std::stod(f, &used);
        }
        catch (const std::exception&)
        {
            used = 0;
        }
        if (used != f.size() || !std::isfinite(v))
            fail(std::string(what) + " '" + f + "' is not a number", "expected a coordinate field");
        return v;
    }
};

/// A solid's card: its eight NIDs, the line it is on and its EID.
struct Solid
{
    long long nodes[8];
    int line;
    long long eid;
    const std::string* file; // the file of its card
};

/// What the *NODE and *ELEMENT_SOLID cards hold: every node in the file's order, the solids asked for.
struct KeywordCards
{
    std::vector<real_t> x; // file order
    std::vector<long long> node_ids;
    std::unordered_map<long long, index_t> node_of; // NID -> index into x / 3
    std::unordered_map<long long, int> node_line;
    std::unordered_map<long long, int> element_line; // EID -> line of its card (every PID)
    std::vector<Solid> solids;
};

/// A two-card solid between its cards: EID and PID read, its node card next.
struct PendingSolid
{
    bool pending = false;      // two-card solid: EID, PID read, nodes next
    bool pending_take = false; // ...and its PID is among those asked for
    Solid pend{};
};

/// One *NODE card: its NID (once in the file) and coordinates, scaled by mesh_unit.
void read_node_card(Reader& rd, const GeneratorSpec& g, const std::string& text, KeywordCards& cards)
{
    auto& [x, node_ids, node_of, node_line, element_line, solids] = cards;
    const std::vector<std::string> f = keyword_fields(text, {8, 16, 16, 16});
    if (f.size() < 2)
        rd.fail("a *NODE card has no coordinates", "expected NID, X, Y, Z");
    const long long nid = rd.integer(f[0], "NID");
    if (node_of.count(nid))
        rd.fail("node " + std::to_string(nid) + " is defined again (first on line " + std::to_string(node_line[nid]) +
                    ")",
                "expected each NID once");
    node_of[nid] = static_cast<index_t>(node_ids.size());
    node_line[nid] = rd.line;
    node_ids.push_back(nid);
    for (int d = 0; d < 3; ++d)
        x.push_back(g.mesh_unit * (static_cast<std::size_t>(d + 1) < f.size()
                                       ? rd.number(f[static_cast<std::size_t>(d + 1)], "coordinate")
                                       : 0.0));
}

/// One *ELEMENT_SOLID card (EID, PID and N1..N8 on one card, or on two): a solid of the PIDs asked for is kept.
void read_solid_card(Reader& rd, const GeneratorSpec& g, const std::string& text, PendingSolid& p, KeywordCards& cards)
{
    auto& [pending, pending_take, pend] = p;
    const std::vector<std::string> f = keyword_fields(text, std::vector<int>(10, 8));
    std::size_t first = 0; // where the node ids start in f
    if (!pending)
    {
        pend = Solid{};
        pend.line = rd.line;
        pend.eid = rd.integer(f[0], "EID");
        if (const auto [it, fresh] = cards.element_line.emplace(pend.eid, rd.line); !fresh)
            rd.fail("element " + std::to_string(pend.eid) + " is defined again (first on line " +
                        std::to_string(it->second) + ")",
                    "expected each EID once in *ELEMENT_SOLID");
        const long long pid = f.size() > 1 ? rd.integer(f[1], "PID") : 0;
        const bool take =
            g.mesh_pids.empty() || std::find(g.mesh_pids.begin(), g.mesh_pids.end(), pid) != g.mesh_pids.end();
        std::size_t nonblank = 0;
        for (std::size_t k = 2; k < f.size(); ++k)
            nonblank += !f[k].empty();
        if (nonblank == 0)
        {
            pending = true; // two-card format
            pending_take = take;
            return;
        }
        if (!take)
            return;
        first = 2;
    }
    else
    {
        pending = false;
        if (!pending_take)
            return; // not among the PIDs
    }
    if (f.size() < first + 8)
        rd.fail("element " + std::to_string(pend.eid) + " has fewer than 8 nodes", "expected N1..N8 (8-node solids)");
    for (std::size_t k = first + 8; k < f.size(); ++k)
        if (!f[k].empty() && rd.integer(f[k], "node") != 0)
            rd.fail("element " + std::to_string(pend.eid) + " has more than 8 nodes",
                    "expected 8-node solids (fields 9 and 10 zero)");
    for (int a = 0; a < 8; ++a)
        pend.nodes[a] = rd.integer(f[first + static_cast<std::size_t>(a)], "node");
    cards.solids.push_back(pend);
}

/// The keyword file's cards (and those of the files it includes, in place): its nodes and the solids of the
/// PIDs asked for.
KeywordCards read_cards(Reader& rd, const GeneratorSpec& g, const std::vector<KeywordBlock>& blocks)
{
    KeywordCards cards;
    for (const KeywordBlock& b : blocks)
    {
        const bool node = b.keyword == "*NODE", solid = b.keyword == "*ELEMENT_SOLID";
        if (!node && !solid)
            continue;
        rd.file = b.file;
        PendingSolid p;
        for (const KeywordCard& c : b.cards)
        {
            if (c.blank())
                continue;
            rd.line = c.line;
            if (node)
                read_node_card(rd, g, c.text, cards);
            else
            {
                read_solid_card(rd, g, c.text, p, cards);
                if (!cards.solids.empty() && cards.solids.back().line == c.line)
                    cards.solids.back().file = &b.file;
            }
        }
        if (p.pending)
            rd.fail("the last solid's node card is missing", "expected N1..N8 after EID, PID");
    }
    return cards;
}

/// Numbers the nodes the solids use from 0, in the file's order, their coordinates into m.x: the new index of
/// each file node, -1 for the others.
std::vector<index_t> keep_used_nodes(Reader& rd, const KeywordCards& cards, HexMesh& m)
{
    const auto& [x, node_ids, node_of, node_line, element_line, solids] = cards;
    std::vector<index_t> new_index(node_ids.size(), -1);
    for (const Solid& s : solids)
        for (long long nid : s.nodes)
        {
            const auto it = node_of.find(nid);
            if (it == node_of.end())
            {
                rd.line = s.line;
                rd.file = s.file ? *s.file : std::string();
                rd.fail("element " + std::to_string(s.eid) + " names node " + std::to_string(nid) +
                            ", which no *NODE card defines",
                        "expected every node of a solid in *NODE");
            }
            new_index[static_cast<std::size_t>(it->second)] = 0;
        }
    index_t kept = 0;
    for (std::size_t i = 0; i < new_index.size(); ++i)
        if (new_index[i] == 0)
        {
            new_index[i] = kept++;
            m.x.insert(m.x.end(), {x[3 * i], x[3 * i + 1], x[3 * i + 2]});
        }
    return new_index;
}

/// The solids' connectivity and EIDs into m, then the kept nodes' NIDs; fails on a solid with a repeated node or
/// with the same eight nodes as another.
void add_solids(Reader& rd, const KeywordCards& cards, const std::vector<index_t>& new_index, HexMesh& m)
{
    const auto& [x, node_ids, node_of, node_line, element_line, solids] = cards;
    // the same eight nodes twice: two solids in one place (mass and stiffness doubled)
    std::map<std::array<long long, 8>, const Solid*> by_nodes;
    for (const Solid& s : solids)
    {
        rd.line = s.line;
        rd.file = s.file ? *s.file : std::string();
        // a wedge, pyramid or tetrahedron written as a hex repeats nodes (LS-DYNA runs them as
        // degenerate hexes, as the Gauss-point FE parts here do); fewer than 4 distinct nodes is no solid
        if (const int distinct = distinct_nodes(s.nodes); distinct < 4)
            rd.fail("element " + std::to_string(s.eid) + " has " + std::to_string(distinct) + " distinct nodes",
                    "expected a solid: a hexahedron, or a wedge, pyramid or tetrahedron written with repeated nodes");
        std::array<long long, 8> key;
        std::copy(std::begin(s.nodes), std::end(s.nodes), key.begin());
        std::sort(key.begin(), key.end());
        if (const auto [it, fresh] = by_nodes.emplace(key, &s); !fresh)
            rd.fail("element " + std::to_string(s.eid) + " has the same eight nodes as element " +
                        std::to_string(it->second->eid) + " (line " + std::to_string(it->second->line) + ")",
                    "expected one solid per place (a duplicate doubles its mass and stiffness)");
        for (int a = 0; a < 8; ++a)
            m.conn.push_back(new_index[static_cast<std::size_t>(node_of.at(s.nodes[a]))]);
        m.element_ids.push_back(s.eid);
    }
    for (std::size_t i = 0; i < new_index.size(); ++i)
        if (new_index[i] >= 0)
            m.node_ids.push_back(node_ids[i]);
}

/// Fails on an inverted or degenerate corner, named by the file's ids (the trilinear map must be one to one).
void check_corners(Reader& rd, const std::vector<Solid>& solids, const HexMesh& m)
{
    if (const HexCorner c = worst_corner(m); c.element >= 0 && !(c.scaled_jacobian > kDegenerateScaledJacobian))
    {
        const Solid& s = solids[static_cast<std::size_t>(c.element)];
        rd.line = s.line;
        rd.file = s.file ? *s.file : std::string();
        std::ostringstream what;
        what.precision(3);
        what << "element " << s.eid << " is " << (c.scaled_jacobian < 0.0 ? "inverted" : "degenerate")
             << " at its node " << s.nodes[c.corner] << " (scaled Jacobian " << c.scaled_jacobian << " there)";
        rd.fail(what.str(), "expected N1..N4 counter-clockwise seen from N5..N8, LS-DYNA's node order, and every "
                            "corner of a solid convex (scaled Jacobian above 0)");
    }
}
} // namespace

HexMesh read_keyword_mesh(const GeneratorSpec& g)
{
    Reader rd{g, {g.loc.where, g.loc.path + ".file"}, 0, {}};
    const std::vector<KeywordBlock> blocks = read_keyword_blocks(g.mesh_file, rd.where);
    const KeywordCards cards = read_cards(rd, g, blocks);
    rd.line = 0;
    rd.file.clear();
    if (cards.solids.empty())
        rd.fail(g.mesh_pids.empty() ? "has no *ELEMENT_SOLID elements" : "has no solids with the PIDs asked for",
                "expected 8-node solids" + std::string(g.mesh_pids.empty() ? "" : " of the parts named by pid"));

    // keep the nodes the selected solids use, in the file's order
    HexMesh m;
    const std::vector<index_t> new_index = keep_used_nodes(rd, cards, m);
    add_solids(rd, cards, new_index, m);
    check_corners(rd, cards.solids, m);
    m.faces = extract_boundary_faces(m.conn);
    std::vector<index_t>& all = m.named_faces["all"];
    for (index_t f = 0; f < static_cast<index_t>(m.faces.size()); ++f)
        all.push_back(f);
    return m;
}
} // namespace rkfem
