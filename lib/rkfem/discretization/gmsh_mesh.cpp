#include "rkfem/discretization/gmsh_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <unordered_map>
#include <vector>

#include "rkfem/core/error.hpp"

namespace rkfem
{
namespace
{
/// The file as whitespace-separated tokens, each with its line.
struct Tokens
{
    std::vector<std::string> text;
    std::vector<int> line;
    std::size_t at = 0;
};

struct Element
{
    long long id = 0;
    int type = 0;
    std::vector<long long> nodes;
    std::vector<int> physical; // its entity's physical tags
    int line = 0;
};

/// What the file holds, as read.
struct GmshFile
{
    double version = 0.0;
    std::map<std::pair<int, int>, std::string> names;                // (dim, physical tag) -> name
    std::map<std::pair<int, int>, std::vector<int>> entity_physical; // (dim, entity tag) -> physical tags (4.1)
    std::vector<long long> node_ids;
    std::vector<double> x;
    std::unordered_map<long long, std::size_t> node_of;
    std::vector<Element> volumes, surfaces, others;
};

int element_dimension(int type)
{
    switch (type)
    {
    case 15:
        return 0;
    case 1:
        return 1;
    case 2:
    case 3:
        return 2;
    case 4:
    case 5:
    case 6:
    case 7:
        return 3;
    default:
        return -1;
    }
}

int element_nodes(int type)
{
    static const std::map<int, int> n = {{15, 1}, {1, 2}, {2, 3}, {3, 4}, {4, 4}, {5, 8}, {6, 6}, {7, 5}};
    const auto it = n.find(type);
    return it == n.end() ? -1 : it->second;
}

class Reader
{
  public:
    explicit Reader(const GeneratorSpec& g) : g_(g) {}

    GmshFile read();

  private:
    const GeneratorSpec& g_;
    Tokens t_;
    GmshFile f_;

    [[noreturn]] void fail(int line, const std::string& problem, const std::string& expected) const
    {
        throw DeckError({g_.loc.where, g_.loc.path + ".file"},
                        g_.mesh_file + (line > 0 ? ":" + std::to_string(line) : std::string()) + ": " + problem,
                        expected);
    }
    int line() const { return t_.at < t_.text.size() ? t_.line[t_.at] : (t_.line.empty() ? 0 : t_.line.back()); }
    const std::string& next(const char* what)
    {
        if (t_.at >= t_.text.size())
            fail(line(), std::string("ends before ") + what, "expected a whole MSH file");
        return t_.text[t_.at++];
    }
    long long integer(const char* what)
    {
        const std::string& s = next(what);
        std::size_t used = 0;
        long long v = 0;
        try
        {
            v = std::stoll(s, &used);
        }
        catch (const std::exception&)
        {
            used = 0;
        }
        if (used != s.size())
            fail(t_.line[t_.at - 1], std::string(what) + " '" + s + "' is not an integer", "expected an integer");
        return v;
    }
    double number(const char* what)
    {
        const std::string& s = next(what);
        std::size_t used = 0;
        double v = 0.0;
        try
        {
            v = std::stod(s, &used);
        }
        catch (const std::exception&)
        {
            used = 0;
        }
        if (used != s.size() || !std::isfinite(v))
            fail(t_.line[t_.at - 1], std::string(what) + " '" + s + "' is not a number", "expected a number");
        return v;
    }
    void expect_end(const std::string& section)
    {
        const int l = line();
        if (next(("$End" + section).c_str()) != "$End" + section)
            fail(l, "$" + section + " has more entries than its count", "expected $End" + section + " here");
    }
    void mesh_format();
    void physical_names();
    void entities();
    void nodes();
    void nodes_22();
    void elements();
    void elements_22();
    void add_node(long long id, double x, double y, double z, int line);
    void add_element(Element e);
};

void Reader::mesh_format()
{
    const int l = line();
    const std::string v = next("the version");
    f_.version = std::atof(v.c_str());
    const long long file_type = integer("the file type");
    integer("the data size");
    if (file_type != 0)
        fail(l, "is a binary MSH file", "expected ASCII (gmsh FILE.msh -save -format msh41 -bin 0 writes it)");
    if (v != "4.1" && v.rfind("2.", 0) != 0)
        fail(l, "is MSH version " + v, "expected 4.1 or 2.2 (gmsh FILE.msh -save -format msh41 rewrites it)");
    expect_end("MeshFormat");
}

void Reader::physical_names()
{
    const long long n = integer("the number of physical names");
    for (long long i = 0; i < n; ++i)
    {
        const int dim = static_cast<int>(integer("a physical group's dimension"));
        const int tag = static_cast<int>(integer("a physical tag"));
        std::string name = next("a physical name");
        // a quoted name may hold spaces: join tokens up to the closing quote
        while (name.size() < 2 || name.back() != '"')
            name += " " + next("the rest of a physical name");
        f_.names[{dim, tag}] = name.substr(1, name.size() - 2);
    }
    expect_end("PhysicalNames");
}

void Reader::entities()
{
    long long count[4];
    for (long long& c : count)
        c = integer("an entity count");
    for (int dim = 0; dim < 4; ++dim)
        for (long long i = 0; i < count[dim]; ++i)
        {
            const int tag = static_cast<int>(integer("an entity tag"));
            for (int k = 0; k < (dim == 0 ? 3 : 6); ++k)
                number("an entity's bounding box");
            const long long np = integer("a number of physical tags");
            std::vector<int>& tags = f_.entity_physical[{dim, tag}];
            for (long long k = 0; k < np; ++k)
                tags.push_back(static_cast<int>(integer("a physical tag")));
            if (dim > 0)
            {
                const long long nb = integer("a number of bounding entities");
                for (long long k = 0; k < nb; ++k)
                    integer("a bounding entity");
            }
        }
    expect_end("Entities");
}

void Reader::add_node(long long id, double x, double y, double z, int line)
{
    if (!f_.node_of.emplace(id, f_.node_ids.size()).second)
        fail(line, "node " + std::to_string(id) + " is defined again", "expected each node tag once");
    f_.node_ids.push_back(id);
    f_.x.insert(f_.x.end(), {g_.mesh_unit * x, g_.mesh_unit * y, g_.mesh_unit * z});
}

void Reader::nodes()
{
    const long long blocks = integer("the number of node blocks");
    integer("the number of nodes");
    integer("the smallest node tag");
    integer("the largest node tag");
    for (long long b = 0; b < blocks; ++b)
    {
        integer("a block's entity dimension");
        integer("a block's entity tag");
        const long long parametric = integer("the parametric flag");
        const long long n = integer("a block's node count");
        std::vector<long long> ids(static_cast<std::size_t>(std::max(n, 0LL)));
        std::vector<int> lines(ids.size());
        for (std::size_t i = 0; i < ids.size(); ++i)
        {
            lines[i] = line();
            ids[i] = integer("a node tag");
        }
        for (std::size_t i = 0; i < ids.size(); ++i)
        {
            const double x = number("a coordinate"), y = number("a coordinate"), z = number("a coordinate");
            if (parametric != 0)
                fail(lines[i], "has parametric node coordinates", "expected a mesh saved without them");
            add_node(ids[i], x, y, z, lines[i]);
        }
    }
    expect_end("Nodes");
}

void Reader::nodes_22()
{
    const long long n = integer("the number of nodes");
    for (long long i = 0; i < n; ++i)
    {
        const int l = line();
        const long long id = integer("a node number");
        const double x = number("a coordinate"), y = number("a coordinate"), z = number("a coordinate");
        add_node(id, x, y, z, l);
    }
    expect_end("Nodes");
}

void Reader::add_element(Element e)
{
    const int dim = element_dimension(e.type);
    if (dim < 0)
        fail(e.line, "element " + std::to_string(e.id) + " is of type " + std::to_string(e.type),
             "expected linear elements: 4-node tetrahedra (4), 8-node hexahedra (5), 6-node prisms (6), 5-node "
             "pyramids (7), triangles (2), quadrangles (3), lines (1), points (15)");
    for (long long n : e.nodes)
        if (!f_.node_of.count(n))
            fail(e.line,
                 "element " + std::to_string(e.id) + " names node " + std::to_string(n) +
                     ", which $Nodes does not define",
                 "expected every node of an element in $Nodes");
    (dim == 3 ? f_.volumes : dim == 2 ? f_.surfaces : f_.others).push_back(std::move(e));
}

void Reader::elements()
{
    const long long blocks = integer("the number of element blocks");
    integer("the number of elements");
    integer("the smallest element tag");
    integer("the largest element tag");
    for (long long b = 0; b < blocks; ++b)
    {
        const int dim = static_cast<int>(integer("a block's entity dimension"));
        const int tag = static_cast<int>(integer("a block's entity tag"));
        const int type = static_cast<int>(integer("a block's element type"));
        const long long n = integer("a block's element count");
        const int nn = element_nodes(type);
        const auto it = f_.entity_physical.find({dim, tag});
        for (long long i = 0; i < n; ++i)
        {
            Element e;
            e.line = line();
            e.id = integer("an element tag");
            e.type = type;
            if (nn < 0)
                add_element(e); // refused there, by type
            for (int k = 0; k < nn; ++k)
                e.nodes.push_back(integer("an element's node"));
            if (it != f_.entity_physical.end())
                e.physical = it->second;
            add_element(std::move(e));
        }
    }
    expect_end("Elements");
}

void Reader::elements_22()
{
    const long long n = integer("the number of elements");
    for (long long i = 0; i < n; ++i)
    {
        Element e;
        e.line = line();
        e.id = integer("an element number");
        e.type = static_cast<int>(integer("an element type"));
        const long long ntags = integer("a number of tags");
        for (long long k = 0; k < ntags; ++k)
        {
            const long long tag = integer("a tag");
            if (k == 0 && tag != 0)
                e.physical.push_back(static_cast<int>(tag));
        }
        const int nn = element_nodes(e.type);
        if (nn < 0)
            add_element(e);
        for (int k = 0; k < nn; ++k)
            e.nodes.push_back(integer("an element's node"));
        add_element(std::move(e));
    }
    expect_end("Elements");
}

GmshFile Reader::read()
{
    std::ifstream in(g_.mesh_file, std::ios::binary);
    if (!in)
        fail(0, "cannot be opened", "expected a Gmsh mesh file (.msh)");
    std::string text;
    int l = 0;
    while (std::getline(in, text))
    {
        ++l;
        std::istringstream s(text);
        for (std::string tok; s >> tok;)
        {
            t_.text.push_back(tok);
            t_.line.push_back(l);
        }
    }
    bool format = false, nodes_read = false;
    while (t_.at < t_.text.size())
    {
        const int at = line();
        const std::string section = next("a section");
        if (section.empty() || section[0] != '$')
            fail(at, "'" + section + "' is outside any section", "expected $MeshFormat, $Nodes, $Elements, ...");
        if (section == "$MeshFormat")
        {
            mesh_format();
            format = true;
            continue;
        }
        if (!format)
            fail(at, section + " comes before $MeshFormat", "expected the file to start with $MeshFormat");
        const bool v4 = f_.version >= 4.0;
        if (section == "$PhysicalNames")
            physical_names();
        else if (section == "$Entities" && v4)
            entities();
        else if (section == "$Nodes")
        {
            v4 ? nodes() : nodes_22();
            nodes_read = true;
        }
        else if (section == "$Elements")
        {
            if (!nodes_read)
                fail(at, "$Elements comes before $Nodes", "expected $Nodes first");
            v4 ? elements() : elements_22();
        }
        else
        {
            // a section we do not need ($PartitionedEntities, $NodeData, ...): skipped whole
            const std::string end = "$End" + section.substr(1);
            while (next(end.c_str()) != end)
            {
            }
        }
    }
    if (f_.volumes.empty())
        fail(0, "has no volume elements", "expected tetrahedra, hexahedra, prisms or pyramids");
    return f_;
}

/// A volume element's 8 hex corners (LS-DYNA's degenerate forms for the others).
std::array<long long, 8> hex_corners(const Element& e)
{
    const auto& n = e.nodes;
    switch (e.type)
    {
    case 5:
        return {n[0], n[1], n[2], n[3], n[4], n[5], n[6], n[7]};
    case 6: // prism
        return {n[0], n[1], n[2], n[2], n[3], n[4], n[5], n[5]};
    case 7: // pyramid
        return {n[0], n[1], n[2], n[3], n[4], n[4], n[4], n[4]};
    default: // tetrahedron
        return {n[0], n[1], n[2], n[2], n[3], n[3], n[3], n[3]};
    }
}

/// The group's name: its physical name, else its tag.
std::string group_name(const GmshFile& f, int dim, int tag)
{
    const auto it = f.names.find({dim, tag});
    return it != f.names.end() ? it->second : std::to_string(tag);
}
} // namespace

HexMesh read_gmsh_mesh(const GeneratorSpec& g)
{
    Reader rd(g);
    const GmshFile f = rd.read();
    const SourceLocation at{g.loc.where, g.loc.path + ".physical"};
    // the volumes asked for: by physical name or tag
    std::set<int> wanted;
    for (const std::string& name : g.mesh_groups)
    {
        bool found = false;
        for (const auto& [key, n] : f.names)
            if (key.first == 3 && (n == name || std::to_string(key.second) == name))
            {
                wanted.insert(key.second);
                found = true;
            }
        if (!found)
            for (const Element& e : f.volumes)
                for (int p : e.physical)
                    if (std::to_string(p) == name)
                    {
                        wanted.insert(p);
                        found = true;
                    }
        if (!found)
        {
            std::string have;
            for (const auto& [key, n] : f.names)
                if (key.first == 3)
                    have += (have.empty() ? "" : ", ") + n;
            throw DeckError(at, "no volume physical group is named or tagged '" + name + "'",
                            "expected one of the file's volume groups" + (have.empty() ? "" : ": " + have));
        }
    }
    std::vector<const Element*> taken;
    for (const Element& e : f.volumes)
        if (wanted.empty() || std::any_of(e.physical.begin(), e.physical.end(), [&](int p) { return wanted.count(p); }))
            taken.push_back(&e);
    if (taken.empty())
        throw DeckError(at, "selects no volume element", "expected groups with volume elements");

    // the nodes the taken elements use, in the file's order
    HexMesh m;
    std::vector<index_t> new_index(f.node_ids.size(), -1);
    for (const Element* e : taken)
        for (long long n : e->nodes)
            new_index[f.node_of.at(n)] = 0;
    index_t kept = 0;
    for (std::size_t i = 0; i < new_index.size(); ++i)
        if (new_index[i] == 0)
        {
            new_index[i] = kept++;
            m.x.insert(m.x.end(), {f.x[3 * i], f.x[3 * i + 1], f.x[3 * i + 2]});
            m.node_ids.push_back(f.node_ids[i]);
        }
    auto local = [&](long long id) { return new_index[f.node_of.at(id)]; };
    for (const Element* e : taken)
    {
        for (long long n : hex_corners(*e))
            m.conn.push_back(local(n));
        m.element_ids.push_back(e->id);
    }
    if (const HexCorner c = worst_corner(m); c.element >= 0 && !(c.scaled_jacobian > kDegenerateScaledJacobian))
    {
        const Element& e = *taken[static_cast<std::size_t>(c.element)];
        std::ostringstream what;
        what.precision(3);
        what << g.mesh_file << ":" << e.line << ": element " << e.id << " is "
             << (c.scaled_jacobian < 0.0 ? "inverted" : "degenerate") << " at its node "
             << m.node_ids[static_cast<std::size_t>(m.conn[8 * static_cast<std::size_t>(c.element) + c.corner])]
             << " (scaled Jacobian " << c.scaled_jacobian << " there)";
        throw DeckError({g.loc.where, g.loc.path + ".file"}, what.str(),
                        "expected Gmsh's node order (positive volumes) and every corner convex");
    }
    m.faces = extract_boundary_faces(m.conn);
    std::vector<index_t>& all = m.named_faces["all"];
    for (index_t fi = 0; fi < static_cast<index_t>(m.faces.size()); ++fi)
        all.push_back(fi);
    // surface groups: the boundary faces their elements cover (by their distinct nodes)
    std::map<std::vector<index_t>, index_t> face_of;
    for (index_t fi = 0; fi < static_cast<index_t>(m.faces.size()); ++fi)
    {
        std::vector<index_t> key(m.faces[static_cast<std::size_t>(fi)].begin(),
                                 m.faces[static_cast<std::size_t>(fi)].end());
        std::sort(key.begin(), key.end());
        key.erase(std::unique(key.begin(), key.end()), key.end());
        face_of.emplace(key, fi);
    }
    for (const Element& e : f.surfaces)
    {
        std::vector<index_t> key;
        for (long long n : e.nodes)
            key.push_back(new_index[f.node_of.at(n)]);
        if (std::find(key.begin(), key.end(), -1) != key.end())
            continue; // on volumes not taken
        std::sort(key.begin(), key.end());
        key.erase(std::unique(key.begin(), key.end()), key.end());
        const auto it = face_of.find(key);
        for (int p : e.physical)
        {
            std::vector<index_t>& faces = m.named_faces[group_name(f, 2, p)];
            if (it != face_of.end())
                faces.push_back(it->second);
        }
    }
    for (auto& [name, faces] : m.named_faces)
    {
        std::sort(faces.begin(), faces.end());
        faces.erase(std::unique(faces.begin(), faces.end()), faces.end());
    }
    // point and curve groups: their nodes
    for (const Element& e : f.others)
        for (int p : e.physical)
        {
            std::vector<index_t>& nodes = m.named_nodes[group_name(f, element_dimension(e.type), p)];
            for (long long n : e.nodes)
                if (const index_t i = new_index[f.node_of.at(n)]; i >= 0)
                    nodes.push_back(i);
        }
    for (auto& [name, nodes] : m.named_nodes)
    {
        std::sort(nodes.begin(), nodes.end());
        nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
    }
    return m;
}
} // namespace rkfem
