// LS-DYNA keyword decks translated into rkfem decks (keyword_deck.hpp). One pass files the
// blocks by keyword; a second writes the YAML: title and time, parts (section, material, EOS,
// erosion, hourglass, initial velocity), sets, boundary conditions, loads and contacts.
#include "rkfem/config/keyword_deck.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>

#include "rkfem/core/error.hpp"
#include "rkfem/core/input_error.hpp"
#include "rkfem/io/keyword_file.hpp"

namespace rkfem
{
namespace
{
constexpr double kInch = 0.0254;
constexpr double kPoundForce = 4.4482216152605;

/// The shortest text that reads back as the same double.
std::string num(double v)
{
    if (v == 0.0)
        return "0";
    char buf[64];
    const auto r = std::to_chars(buf, buf + sizeof buf, v);
    return std::string(buf, r.ptr);
}

/// A converted value rounded to 15 significant digits, so that 1.17 Mbar is written 1.17e+11 Pa and
/// not 117000000000.00002 (the unit factors' products round in the last bit; inputs carry fewer digits)
double rounded(double v)
{
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.15g", v);
    return std::strtod(buf, nullptr);
}

/// Exponents of mass, length and time of a quantity (for the unit conversion).
struct Dim
{
    int m, l, t;
    const char* unit; // its SI symbol in the deck ("" for none)
};
constexpr Dim kNone{0, 0, 0, ""}, kLength{0, 1, 0, "m"}, kTime{0, 0, 1, "s"}, kVelocity{0, 1, -1, "m/s"},
    kStress{1, -1, -2, "Pa"}, kDensity{1, -3, 0, "kg/m^3"}, kForce{1, 1, -2, "N"}, kRate{0, 0, -1, "1/s"},
    kSlowness{0, -1, 1, "s/m"};

/// A keyword's base name: options that only add a title or ID card removed.
struct Keyword
{
    std::string base;
    std::size_t skip = 0; // cards before the data (a title, or an ID and heading)
};

bool ends_with(const std::string& s, const std::string& tail)
{
    return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

Keyword normalize(const std::string& kw)
{
    Keyword k{kw.substr(0, kw.find_first_of(" \t")), 0};
    if (ends_with(k.base, "_TITLE"))
    {
        k.base.resize(k.base.size() - 6);
        k.skip = 1;
    }
    if ((k.base.rfind("*CONTACT_", 0) == 0 || k.base.rfind("*RIGIDWALL_", 0) == 0) && ends_with(k.base, "_ID"))
    {
        k.base.resize(k.base.size() - 3);
        k.skip = 1;
    }
    static const std::map<std::string, std::string> alias = {
        {"*MAT_001", "*MAT_ELASTIC"},
        {"*MAT_003", "*MAT_PLASTIC_KINEMATIC"},
        {"*MAT_015", "*MAT_JOHNSON_COOK"},
        {"*MAT_024", "*MAT_PIECEWISE_LINEAR_PLASTICITY"},
        {"*MAT_072R3", "*MAT_CONCRETE_DAMAGE_REL3"},
        {"*MAT_159", "*MAT_CSCM_CONCRETE"},
        {"*MAT_CSCM", "*MAT_CSCM_CONCRETE"},
        {"*SET_NODE", "*SET_NODE_LIST"},
        {"*SET_PART", "*SET_PART_LIST"},
    };
    if (const auto it = alias.find(k.base); it != alias.end())
        k.base = it->second;
    return k;
}

/// The fields of one keyword block, past its title or ID cards, with the block's location for errors.
class Cards
{
  public:
    Cards(const KeywordBlock& b, std::size_t skip) : b_(b), skip_(skip) {}

    std::size_t size() const { return b_.cards.size() > skip_ ? b_.cards.size() - skip_ : 0; }
    bool has(std::size_t card) const { return card < size(); }
    /// a blank card: every field default (rows of repeated cards skip it)
    bool blank(std::size_t card) const { return !has(card) || b_.cards[skip_ + card].blank(); }
    std::vector<std::string> fields(std::size_t card, const std::vector<int>& widths = std::vector<int>(8, 10)) const
    {
        return has(card) ? keyword_fields(b_.cards[skip_ + card].text, widths) : std::vector<std::string>{};
    }
    /// field k of card `card` (10 columns wide), `fallback` when blank or absent
    double number(std::size_t card, std::size_t k, double fallback, const char* name,
                  const std::vector<int>& widths = std::vector<int>(8, 10)) const
    {
        const std::vector<std::string> f = fields(card, widths);
        double v = fallback;
        if (k < f.size() && !keyword_number(f[k], fallback, v))
            fail(card, name, "'" + f[k] + "' is not a number", "expected a number");
        return v;
    }
    long long integer(std::size_t card, std::size_t k, long long fallback, const char* name,
                      const std::vector<int>& widths = std::vector<int>(8, 10)) const
    {
        const double v = number(card, k, static_cast<double>(fallback), name, widths);
        if (v != std::floor(v) || std::abs(v) > 9e15)
        {
            std::string text = num(v); // (built in place: GCC 12 warns falsely on "'" + num(v))
            text.insert(0, 1, '\'');
            fail(card, name, text + "' is not an integer", "expected an integer ID or flag");
        }
        return static_cast<long long>(v);
    }
    std::string where(std::size_t card) const { return b_.where(static_cast<int>(skip_ + card)); }
    [[noreturn]] void fail(std::size_t card, const std::string& field, const std::string& problem,
                           const std::string& expected) const
    {
        throw DeckError({where(card), b_.keyword + (field.empty() ? "" : " " + field)}, problem, expected);
    }
    const KeywordBlock& block() const { return b_; }

  private:
    const KeywordBlock& b_;
    std::size_t skip_;
};

/// A *DEFINE_CURVE: points as written, scales and offsets applied.
struct Curve
{
    std::vector<double> x, y;
    std::string where;
};

struct PartCard
{
    long long pid = 0, secid = 0, mid = 0, eosid = 0, hgid = 0;
    std::string heading, name, where;
};

class Importer
{
  public:
    Importer(const KeywordUnits& u, bool allow, std::string mesh_file)
        : u_(u), allow_(allow), mesh_file_(std::move(mesh_file))
    {
    }

    KeywordImport run(const std::string& path);

  private:
    const KeywordUnits& u_;
    bool allow_;
    std::string mesh_file_;
    KeywordImport out_;
    std::vector<KeywordBlock> blocks_;
    std::string title_;
    std::vector<PartCard> parts_;
    std::map<long long, Cards> sections_, materials_, eos_, eos8_, hourglass_, erosion_;
    std::map<long long, std::string> material_kw_; // MID -> base keyword
    std::map<long long, Curve> curves_;
    std::map<long long, std::vector<long long>> node_sets_, part_sets_;
    std::map<long long, std::vector<std::array<long long, 4>>> segment_sets_;
    std::vector<Cards> spc_sets_, spc_nodes_, motions_, motion_nodes_, node_loads_, segment_loads_, contacts_, walls_,
        velocity_gens_, velocities_;
    std::vector<std::string> contact_kw_;
    std::map<long long, std::vector<long long>> part_nodes_; // PID -> its solids' NIDs, sorted
    std::map<long long, std::vector<long long>> tc_nodes_;   // *NODE's TC code (1-7) -> its NIDs
    std::map<long long, std::array<double, 3>> node_x_;      // NID -> coordinates (model units), for boxes
    std::map<long long, std::array<double, 6>> boxes_;       // *DEFINE_BOX: BOXID -> xmn xmx ymn ymx zmn zmx
    std::map<long long, bool> global_frames_;                // *DEFINE_COORDINATE_SYSTEM: CID -> is the global frame
    std::vector<Cards> general_sets_;                        // *SET_NODE_GENERAL, resolved once all is read
    std::vector<Cards> global_constraints_;                  // *CONSTRAINED_GLOBAL
    std::vector<std::string> plane_sets_;                    // their node sets (plane selectors), as deck lines
    void resolve_general_sets();
    void check_frame(const Cards& c, std::size_t card, std::size_t k, const char* field) const;
    // controls
    double end_ = -1.0, tssfac_ = 0.0, d3plot_ = 0.0, glstat_ = 0.0, dtmin_ = 0.0, slsfac_ = 0.0;
    long long endcyc_ = 0, ihq_ = 0;
    double qh_ = 0.0, q1_ = 0.0, q2_ = 0.0;
    std::string time_where_;
    // emitted sets
    std::set<long long> used_node_sets_, used_segment_sets_;
    std::vector<std::pair<std::string, std::vector<long long>>> extra_node_sets_;
    std::map<long long, std::vector<std::string>> part_velocity_; // PID -> [vx, vy, vz] text
    // `$rkfem: PATH: VALUE` comment lines of rkfem's export: settings no keyword carries
    std::map<std::string, std::vector<std::string>> carried_part_; // part name -> "KEY: VALUE"
    std::vector<std::string> carried_time_, carried_top_;
    std::set<std::string> carried_used_;
    void read_carried(const std::string& path);

    double scale(const Dim& d) const
    {
        return std::pow(u_.mass, d.m) * std::pow(u_.length, d.l) * std::pow(u_.time, d.t);
    }
    /// a value in model units in SI: as written where the system is SI (every digit), else rounded
    double si(double v, const Dim& d) const
    {
        const double sc = scale(d);
        return sc == 1.0 ? v : rounded(v * sc);
    }
    /// a value in model units as deck text: SI with its unit
    std::string q(double v, const Dim& d) const
    {
        const std::string n = num(si(v, d));
        return d.unit[0] ? n + " " + d.unit : n;
    }
    void note(const std::string& where, const std::string& what) { out_.notes.push_back(where + ": " + what); }
    void file(const KeywordBlock& b);
    void read_part(const Cards& c);
    void read_curve(const Cards& c);
    void read_id_list(const Cards& c, std::map<long long, std::vector<long long>>& sets, bool generate);
    void read_segments(const Cards& c);
    void read_controls(const std::string& base, const Cards& c);
    void read_solids();
    void name_parts();
    const PartCard& part(long long pid, const Cards& c, std::size_t card, const char* field) const;
    const Curve& curve(long long lcid, const Cards& c, std::size_t card, const char* field) const;
    std::vector<long long> parts_of_set(long long sid, const Cards& c, std::size_t card, const char* field) const;
    std::vector<long long> nodes_of_set(long long sid, const Cards& c, std::size_t card, const char* field);
    std::vector<long long> whole_parts(const std::vector<long long>& nids, const Cards& c, std::size_t card,
                                       const char* field) const;
    std::string time_function(const Curve& cv, double sf, double shift, const Dim& d) const;
    std::string material(const PartCard& p);
    std::string j2_from_plastic_kinematic(const Cards& c, const PartCard& p);
    std::string j2_from_piecewise(const Cards& c, const PartCard& p);
    std::string j2_from_johnson_cook(const Cards& c, const PartCard& p);
    std::string eos(const PartCard& p, const Cards& at);
    std::string concrete(const std::string& base, const Cards& c, const PartCard& p);
    std::string kcc_user_set(const Cards& c, const PartCard& p, double rho, double pr);
    std::string edrop(const Cards& c);
    std::string rate_effects(const Cards& c);
    std::string erosion(long long mid);
    void hourglass(const PartCard& p, const std::string& formulation, const std::set<std::string>& carried,
                   std::ostringstream& os);
    std::string formulation(const PartCard& p);
    void initial_velocities();
    std::string node_set_name(long long sid, const Cards& c, std::size_t card, const char* field);
    std::string segment_set_name(long long sid, const Cards& c, std::size_t card, const char* field);
    void boundary_conditions(std::ostringstream& os);
    void loads(std::ostringstream& os);
    void contacts(std::ostringstream& os);
    void emit(std::ostringstream& os);
};

void Importer::file(const KeywordBlock& b)
{
    const Keyword k = normalize(b.keyword);
    const std::string& base = k.base;
    const Cards c(b, k.skip);
    auto by_id = [&](std::map<long long, Cards>& m, const char* what)
    {
        const long long id = c.integer(0, 0, 0, what);
        if (!m.emplace(id, c).second)
            c.fail(0, what, what + std::string(" ") + std::to_string(id) + " is defined again",
                   "expected each ID once");
        return id;
    };
    if (base.empty())
        throw DeckError({b.where(0), "(before any keyword)"}, "a card before the first keyword",
                        "expected the file to start with *KEYWORD (cards belong to the keyword above them)");
    if (base == "*NODE")
    {
        // the mesh is the keyword generator's; the translational constraint code TC is a condition
        const std::vector<int> w{8, 16, 16, 16, 8, 8};
        for (std::size_t i = 0; i < c.size(); ++i)
        {
            if (c.blank(i))
                continue;
            const double tc = c.number(i, 4, 0.0, "TC", w);
            if (tc != 0.0 && (tc != std::floor(tc) || tc < 0.0 || tc > 7.0))
                c.fail(i, "TC", "TC " + num(tc) + " is not a constraint code",
                       "expected 0-7 (0 free, 1 x, 2 y, 3 z, "
                       "4 x y, 5 y z, 6 z x, 7 all)");
            const long long nid = c.integer(i, 0, 0, "NID", w);
            if (tc != 0.0)
                tc_nodes_[static_cast<long long>(tc)].push_back(nid);
            node_x_[nid] = {c.number(i, 1, 0.0, "X", w), c.number(i, 2, 0.0, "Y", w), c.number(i, 3, 0.0, "Z", w)};
        }
        return;
    }
    if (base == "*DEFINE_BOX")
    {
        std::array<double, 6> b{};
        const char* names[6] = {"XMN", "XMX", "YMN", "YMX", "ZMN", "ZMX"};
        for (std::size_t k = 0; k < 6; ++k)
            b[k] = c.number(0, k + 1, 0.0, names[k]);
        if (!boxes_.emplace(c.integer(0, 0, 0, "BOXID"), b).second)
            c.fail(0, "BOXID", "box " + std::to_string(c.integer(0, 0, 0, "BOXID")) + " is defined again",
                   "expected each BOXID once");
        return;
    }
    if (base == "*DEFINE_COORDINATE_SYSTEM")
    {
        // accepted where it is the global frame (origin 0, x axis along x, the xy plane through y), which
        // decks name for no other reason than that a field wants a CID; a rotated frame is refused where used
        const double o[3] = {c.number(0, 1, 0.0, "XO"), c.number(0, 2, 0.0, "YO"), c.number(0, 3, 0.0, "ZO")};
        const double l[3] = {c.number(0, 4, 0.0, "XL"), c.number(0, 5, 0.0, "YL"), c.number(0, 6, 0.0, "ZL")};
        const double p[3] = {c.number(1, 0, 0.0, "XP"), c.number(1, 1, 0.0, "YP"), c.number(1, 2, 0.0, "ZP")};
        const bool global = o[0] == 0 && o[1] == 0 && o[2] == 0 && l[0] > 0 && l[1] == 0 && l[2] == 0 && p[1] > 0 &&
                            p[2] == 0 && c.integer(0, 7, 0, "CIDL") == 0;
        global_frames_[c.integer(0, 0, 0, "CID")] = global;
        return;
    }
    if (base == "*SET_NODE_GENERAL")
    {
        general_sets_.push_back(c);
        return;
    }
    if (base == "*CONSTRAINED_GLOBAL")
    {
        global_constraints_.push_back(c);
        return;
    }
    if (base == "*KEYWORD" || base == "*ELEMENT_SOLID")
        return; // the mesh: read by the keyword generator (and read_solids for the parts' nodes)
    if (base == "*TITLE")
        title_ = c.has(0) ? b.cards[0].text : "";
    else if (base == "*PART")
        read_part(Cards(b, 0));
    else if (base == "*SECTION_SOLID")
        by_id(sections_, "SECID");
    else if (base == "*MAT_ELASTIC" || base == "*MAT_PLASTIC_KINEMATIC" || base == "*MAT_PIECEWISE_LINEAR_PLASTICITY" ||
             base == "*MAT_JOHNSON_COOK" || base == "*MAT_CONCRETE_DAMAGE_REL3" || base == "*MAT_CSCM_CONCRETE")
        material_kw_[by_id(materials_, "MID")] = base;
    else if (base == "*MAT_ADD_EROSION")
        by_id(erosion_, "MID");
    else if (base == "*EOS_GRUNEISEN")
        by_id(eos_, "EOSID");
    else if (base == "*EOS_TABULATED_COMPACTION")
        by_id(eos8_, "EOSID");
    else if (base == "*HOURGLASS")
        by_id(hourglass_, "HGID");
    else if (base == "*DEFINE_CURVE")
        read_curve(c);
    else if (base == "*SET_NODE_LIST" || base == "*SET_NODE_LIST_GENERATE")
        read_id_list(c, node_sets_, base == "*SET_NODE_LIST_GENERATE");
    else if (base == "*SET_PART_LIST")
        read_id_list(c, part_sets_, false);
    else if (base == "*SET_SEGMENT")
        read_segments(c);
    else if (base == "*BOUNDARY_SPC_SET")
        spc_sets_.push_back(c);
    else if (base == "*BOUNDARY_SPC_NODE")
        spc_nodes_.push_back(c);
    else if (base == "*BOUNDARY_PRESCRIBED_MOTION_SET")
        motions_.push_back(c);
    else if (base == "*BOUNDARY_PRESCRIBED_MOTION_NODE")
        motion_nodes_.push_back(c);
    else if (base == "*LOAD_NODE_SET")
        node_loads_.push_back(c);
    else if (base == "*LOAD_SEGMENT_SET")
        segment_loads_.push_back(c);
    else if (base == "*CONTACT_AUTOMATIC_SURFACE_TO_SURFACE" || base == "*CONTACT_ERODING_SURFACE_TO_SURFACE" ||
             base == "*CONTACT_SURFACE_TO_SURFACE" || base == "*CONTACT_AUTOMATIC_SINGLE_SURFACE" ||
             base == "*CONTACT_ERODING_SINGLE_SURFACE")
    {
        contacts_.push_back(c);
        contact_kw_.push_back(base);
    }
    else if (base == "*RIGIDWALL_PLANAR")
        walls_.push_back(c);
    else if (base == "*INITIAL_VELOCITY_GENERATION")
        velocity_gens_.push_back(c);
    else if (base == "*INITIAL_VELOCITY")
        velocities_.push_back(c);
    else if (base.rfind("*CONTROL_", 0) == 0 || base.rfind("*DATABASE_", 0) == 0)
        read_controls(base, c);
    else if (allow_)
        out_.skipped.push_back(b.keyword + " (" + b.where() + ")");
    else
        throw DeckError({b.where(), b.keyword}, "is not supported",
                        "expected the keywords docs/user/keyword-decks.md lists (--allow-unsupported lists "
                        "and skips the others)");
}

/// A CID field: 0, or a *DEFINE_COORDINATE_SYSTEM that is the global frame.
void Importer::check_frame(const Cards& c, std::size_t card, std::size_t k, const char* field) const
{
    const long long cid = c.integer(card, k, 0, field);
    if (cid == 0)
        return;
    const auto it = global_frames_.find(cid);
    if (it == global_frames_.end())
        c.fail(card, field, "coordinate system " + std::to_string(cid) + " is not defined",
               "expected 0 or the CID of a *DEFINE_COORDINATE_SYSTEM");
    if (!it->second)
        c.fail(card, field, "coordinate system " + std::to_string(cid) + " is not the global frame",
               "expected 0 or a system whose axes are the global ones (local frames are not supported)");
}

/// *SET_NODE_GENERAL: the union of its cards' options, ALL (every node), NODE (NIDs), PART (the
/// parts' solids' nodes) and BOX (the nodes inside *DEFINE_BOXes); the others refused by name.
void Importer::resolve_general_sets()
{
    for (const Cards& c : general_sets_)
    {
        const long long sid = c.integer(0, 0, 0, "SID");
        std::vector<long long> ids;
        for (std::size_t i = 1; i < c.size(); ++i)
        {
            if (c.blank(i))
                continue;
            const std::vector<std::string> f = c.fields(i);
            std::string option = f.empty() ? "" : f[0];
            std::transform(option.begin(), option.end(), option.begin(),
                           [](unsigned char ch) { return std::toupper(ch); });
            for (std::size_t k = 1; k < f.size(); ++k)
            {
                const long long e = c.integer(i, k, 0, "E");
                if (e == 0)
                    continue;
                if (option == "NODE")
                    ids.push_back(e);
                else if (option == "PART")
                {
                    part(e, c, i, "E");
                    const auto it = part_nodes_.find(e);
                    if (it != part_nodes_.end())
                        ids.insert(ids.end(), it->second.begin(), it->second.end());
                }
                else if (option == "BOX")
                {
                    const auto b = boxes_.find(e);
                    if (b == boxes_.end())
                        c.fail(i, "E", "box " + std::to_string(e) + " is not defined",
                               "expected a *DEFINE_BOX's BOXID");
                    const auto& x = b->second;
                    for (const auto& [nid, p] : node_x_)
                        if (p[0] >= x[0] && p[0] <= x[1] && p[1] >= x[2] && p[1] <= x[3] && p[2] >= x[4] &&
                            p[2] <= x[5])
                            ids.push_back(nid);
                }
            }
            if (option == "ALL")
                for (const auto& [nid, p] : node_x_)
                    ids.push_back(nid);
            else if (option != "NODE" && option != "PART" && option != "BOX")
                c.fail(i, "OPTION", "option '" + option + "' is not supported", "expected ALL, NODE, PART or BOX");
        }
        std::sort(ids.begin(), ids.end());
        ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
        if (ids.empty())
            c.fail(0, "SID", "set " + std::to_string(sid) + " selects no node", "expected options that select nodes");
        if (!node_sets_.emplace(sid, ids).second)
            c.fail(0, "SID", "node set " + std::to_string(sid) + " is defined again", "expected each SID once");
    }
}

void Importer::read_part(const Cards& c)
{
    PartCard p;
    p.heading = c.has(0) ? c.block().cards[0].text : "";
    if (!c.has(1))
        c.fail(0, "", "has no PID card", "expected a heading card, then PID SECID MID EOSID HGID");
    p.pid = c.integer(1, 0, 0, "PID");
    p.secid = c.integer(1, 1, 0, "SECID");
    p.mid = c.integer(1, 2, 0, "MID");
    p.eosid = c.integer(1, 3, 0, "EOSID");
    p.hgid = c.integer(1, 4, 0, "HGID");
    p.where = c.where(1);
    for (const PartCard& o : parts_)
        if (o.pid == p.pid)
            c.fail(1, "PID", "part " + std::to_string(p.pid) + " is defined again (first at " + o.where + ")",
                   "expected each PID once");
    if (c.integer(1, 7, 0, "TMID") != 0)
        c.fail(1, "TMID", "thermal materials are not supported", "expected TMID 0");
    parts_.push_back(p);
}

void Importer::read_curve(const Cards& c)
{
    const long long id = c.integer(0, 0, 0, "LCID");
    const double sfa = c.number(0, 2, 1.0, "SFA"), sfo = c.number(0, 3, 1.0, "SFO");
    const double offa = c.number(0, 4, 0.0, "OFFA"), offo = c.number(0, 5, 0.0, "OFFO");
    Curve cv;
    cv.where = c.where(0);
    for (std::size_t i = 1; i < c.size(); ++i)
    {
        if (c.blank(i))
            continue;
        const std::vector<int> w{20, 20};
        const double a = c.number(i, 0, 0.0, "A", w), o = c.number(i, 1, 0.0, "O", w);
        // LS-DYNA: the offsets apply first, then the scales
        cv.x.push_back((sfa == 0.0 ? 1.0 : sfa) * (a + offa));
        cv.y.push_back((sfo == 0.0 ? 1.0 : sfo) * (o + offo));
        if (cv.x.size() > 1 && !(cv.x.back() > cv.x[cv.x.size() - 2]))
            c.fail(i, "A", "abscissae are not increasing", "expected strictly increasing abscissae");
    }
    if (cv.x.size() < 2)
        c.fail(0, "", "has fewer than two points", "expected a curve of at least two points");
    if (!curves_.emplace(id, cv).second)
        c.fail(0, "LCID", "curve " + std::to_string(id) + " is defined again", "expected each LCID once");
}

void Importer::read_id_list(const Cards& c, std::map<long long, std::vector<long long>>& sets, bool generate)
{
    const long long sid = c.integer(0, 0, 0, "SID");
    std::vector<long long> ids;
    for (std::size_t i = 1; i < c.size(); ++i)
    {
        const std::vector<std::string> f = c.fields(i);
        if (c.blank(i))
            continue;
        if (generate)
        {
            for (std::size_t k = 0; k + 1 < f.size(); k += 2)
            {
                const long long a = c.integer(i, k, 0, "BBEG"), b = c.integer(i, k + 1, 0, "BEND");
                if (a == 0 && b == 0)
                    continue;
                if (b < a || b - a > 10000000)
                    c.fail(i, "BEND",
                           "the range " + std::to_string(a) + "-" + std::to_string(b) +
                               (b < a ? " is empty" : " holds more than 10^7 nodes"),
                           "expected BBEG <= BEND, a range of a mesh's nodes");
                for (long long n = a; n <= b; ++n)
                    ids.push_back(n);
            }
            continue;
        }
        for (std::size_t k = 0; k < f.size(); ++k)
            if (const long long id = c.integer(i, k, 0, "ID"); id != 0)
                ids.push_back(id);
    }
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    if (ids.empty())
        c.fail(0, "SID", "set " + std::to_string(sid) + " is empty", "expected at least one ID");
    if (!sets.emplace(sid, ids).second)
        c.fail(0, "SID", "set " + std::to_string(sid) + " is defined again", "expected each SID once per set kind");
}

void Importer::read_segments(const Cards& c)
{
    const long long sid = c.integer(0, 0, 0, "SID");
    std::vector<std::array<long long, 4>> segs;
    for (std::size_t i = 1; i < c.size(); ++i)
    {
        if (c.blank(i))
            continue;
        std::array<long long, 4> s{};
        for (std::size_t k = 0; k < 4; ++k)
            s[k] = c.integer(i, k, 0, "N");
        if (s[3] == 0)
            s[3] = s[2]; // a triangle
        if (s[0] == 0 || s[1] == 0 || s[2] == 0)
            c.fail(i, "N1", "a segment has fewer than three nodes", "expected N1 N2 N3 N4");
        std::sort(s.begin(), s.end());
        segs.push_back(s);
    }
    if (segs.empty())
        c.fail(0, "SID", "segment set " + std::to_string(sid) + " is empty", "expected at least one segment");
    if (!segment_sets_.emplace(sid, segs).second)
        c.fail(0, "SID", "segment set " + std::to_string(sid) + " is defined again", "expected each SID once");
}

void Importer::read_controls(const std::string& base, const Cards& c)
{
    if (base == "*CONTROL_TERMINATION")
    {
        end_ = c.number(0, 0, 0.0, "ENDTIM");
        endcyc_ = c.integer(0, 1, 0, "ENDCYC");
        dtmin_ = c.number(0, 2, 0.0, "DTMIN");
        time_where_ = c.where(0);
        if (c.number(0, 3, 0.0, "ENDENG") != 0.0 || c.number(0, 4, 0.0, "ENDMAS") != 0.0)
            note(c.where(0), "ENDENG and ENDMAS (stop on energy or mass change) are not read");
    }
    else if (base == "*CONTROL_TIMESTEP")
    {
        tssfac_ = c.number(0, 1, 0.0, "TSSFAC");
        if (c.number(0, 4, 0.0, "DT2MS") != 0.0)
            c.fail(0, "DT2MS", "mass scaling is not supported", "expected DT2MS 0");
        if (c.integer(0, 5, 0, "LCTM") != 0)
            c.fail(0, "LCTM", "a step limit curve is not supported", "expected LCTM 0 (time.dt_max is a constant)");
        if (c.number(0, 3, 0.0, "TSLIMT") != 0.0)
            note(c.where(0), "TSLIMT (the shell step floor) does not apply to solids; not read");
    }
    else if (base == "*CONTROL_HOURGLASS")
    {
        ihq_ = c.integer(0, 0, 0, "IHQ");
        qh_ = c.number(0, 1, 0.0, "QH");
    }
    else if (base == "*CONTROL_BULK_VISCOSITY")
    {
        q1_ = c.number(0, 0, 0.0, "Q1");
        q2_ = c.number(0, 1, 0.0, "Q2");
        if (const long long type = c.integer(0, 2, 1, "TYPE"); type != 1 && type != 0)
            note(c.where(0), "bulk viscosity TYPE " + std::to_string(type) + " is read as the standard form (1)");
    }
    else if (base == "*CONTROL_CONTACT")
    {
        slsfac_ = c.number(0, 0, 0.0, "SLSFAC");
    }
    else if (base == "*DATABASE_BINARY_D3PLOT")
        d3plot_ = c.number(0, 0, 0.0, "DT");
    else if (base == "*DATABASE_GLSTAT")
        glstat_ = c.number(0, 0, 0.0, "DT");
    else if (base.rfind("*DATABASE_", 0) == 0 || base == "*CONTROL_ENERGY" || base == "*CONTROL_OUTPUT" ||
             base == "*CONTROL_SOLID" || base == "*CONTROL_SHELL" || base == "*CONTROL_CPU" ||
             base == "*CONTROL_PARALLEL")
        note(c.block().where(), c.block().keyword +
                                    " asks for output or settings rkfem makes on its own (history.csv has the energies "
                                    "per part, results.h5 the fields); not read");
    else if (allow_)
        out_.skipped.push_back(c.block().keyword + " (" + c.block().where() + ")");
    else
        throw DeckError({c.block().where(), c.block().keyword}, "is not supported",
                        "expected the keywords docs/user/keyword-decks.md lists (--allow-unsupported lists "
                        "and skips the others)");
}

/// The solids' PIDs and nodes, so that sets can be checked against parts and parts that share nodes refused.
void Importer::read_solids()
{
    std::map<long long, long long> owner; // NID -> PID of the first solid on it
    for (const KeywordBlock& b : blocks_)
    {
        if (normalize(b.keyword).base != "*ELEMENT_SOLID")
            continue;
        const Cards c(b, 0);
        const std::vector<int> w(10, 8);
        for (std::size_t i = 0; i < c.size(); ++i)
        {
            if (c.blank(i))
                continue;
            const std::vector<std::string> f = c.fields(i, w);
            const long long pid = c.integer(i, 1, 0, "PID", w);
            std::size_t first = 2;
            bool blank = true;
            for (std::size_t k = 2; k < f.size(); ++k)
                blank = blank && f[k].empty();
            if (blank)
            {
                ++i; // two-card format: the nodes on the next card
                first = 0;
            }
            std::vector<long long>& nodes = part_nodes_[pid];
            for (std::size_t a = 0; a < 8; ++a)
            {
                const long long nid = c.integer(i, first + a, 0, "N", w);
                nodes.push_back(nid);
                const auto [it, fresh] = owner.emplace(nid, pid);
                if (!fresh && it->second != pid)
                    c.fail(i, "N",
                           "node " + std::to_string(nid) + " belongs to solids of parts " + std::to_string(it->second) +
                               " and " + std::to_string(pid),
                           "expected parts that share no nodes (rkfem parts are separate meshes: tie them with a "
                           "contact, or give the solids one PID)");
            }
        }
    }
    for (auto& [pid, nodes] : part_nodes_)
    {
        std::sort(nodes.begin(), nodes.end());
        nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
    }
}

void Importer::name_parts()
{
    std::set<std::string> taken;
    for (PartCard& p : parts_)
    {
        std::string n;
        for (char ch : p.heading)
        {
            const unsigned char c = static_cast<unsigned char>(ch);
            if (std::isalnum(c))
                n += static_cast<char>(std::tolower(c));
            else if (!n.empty() && n.back() != '_')
                n += '_';
        }
        while (!n.empty() && n.back() == '_')
            n.pop_back();
        if (n.empty() || std::isdigit(static_cast<unsigned char>(n[0])) || taken.count(n))
            n = "part_" + std::to_string(p.pid);
        taken.insert(n);
        p.name = n;
    }
}

const PartCard& Importer::part(long long pid, const Cards& c, std::size_t card, const char* field) const
{
    for (const PartCard& p : parts_)
        if (p.pid == pid)
            return p;
    c.fail(card, field, "part " + std::to_string(pid) + " is not defined", "expected a PID of a *PART");
}

const Curve& Importer::curve(long long lcid, const Cards& c, std::size_t card, const char* field) const
{
    const auto it = curves_.find(lcid);
    if (it == curves_.end())
        c.fail(card, field, "curve " + std::to_string(lcid) + " is not defined", "expected an LCID of a *DEFINE_CURVE");
    return it->second;
}

std::vector<long long> Importer::parts_of_set(long long sid, const Cards& c, std::size_t card, const char* field) const
{
    const auto it = part_sets_.find(sid);
    if (it == part_sets_.end())
        c.fail(card, field, "part set " + std::to_string(sid) + " is not defined",
               "expected an SID of a *SET_PART_LIST");
    for (long long pid : it->second)
        part(pid, c, card, field);
    return it->second;
}

std::vector<long long> Importer::nodes_of_set(long long sid, const Cards& c, std::size_t card, const char* field)
{
    const auto it = node_sets_.find(sid);
    if (it == node_sets_.end())
        c.fail(card, field, "node set " + std::to_string(sid) + " is not defined",
               "expected an SID of a *SET_NODE_LIST");
    return it->second;
}

/// The parts whose nodes `nids` are, each wholly; fails when the set takes part of a part.
std::vector<long long> Importer::whole_parts(const std::vector<long long>& nids, const Cards& c, std::size_t card,
                                             const char* field) const
{
    std::vector<long long> pids;
    std::size_t covered = 0;
    for (const PartCard& p : parts_)
    {
        const auto it = part_nodes_.find(p.pid);
        if (it == part_nodes_.end())
            continue;
        const std::vector<long long>& pn = it->second;
        std::size_t in = 0;
        for (long long n : pn)
            in += std::binary_search(nids.begin(), nids.end(), n);
        if (in == 0)
            continue;
        if (in != pn.size())
            c.fail(card, field,
                   "the node set holds " + std::to_string(in) + " of the " + std::to_string(pn.size()) +
                       " nodes of part " + std::to_string(p.pid),
                   "expected whole parts (rkfem sets initial velocities per part)");
        pids.push_back(p.pid);
        covered += in;
    }
    if (covered != nids.size())
        c.fail(card, field, std::to_string(nids.size() - covered) + " of the set's nodes are on no solid",
               "expected nodes of the parts' solids");
    return pids;
}

std::string Importer::time_function(const Curve& cv, double sf, double shift, const Dim& d) const
{
    std::ostringstream os;
    os << "{curve: [";
    for (std::size_t i = 0; i < cv.x.size(); ++i)
    {
        os << (i ? ", " : "") << "[" << num(si(cv.x[i] + shift, kTime)) << ", " << num(si(cv.y[i], d)) << "]";
    }
    os << "]";
    if (sf != 1.0)
        os << ", scale: " << num(sf);
    os << "}";
    return os.str();
}

std::string Importer::formulation(const PartCard& p)
{
    const auto it = sections_.find(p.secid);
    if (it == sections_.end())
        throw DeckError({p.where, "*PART SECID"}, "section " + std::to_string(p.secid) + " is not a *SECTION_SOLID",
                        "expected the SECID of a *SECTION_SOLID");
    const Cards& s = it->second;
    const long long elform = s.integer(0, 1, 1, "ELFORM");
    switch (elform)
    {
    case 0: // LS-DYNA's default solid, ELFORM 1, except on honeycomb materials
    case 1:
        return "fem-1pt";
    case 2:
        return "fem-2x2x2";
    case -1:
    case -2:
        note(s.where(0), "ELFORM " + std::to_string(elform) +
                             " (fully integrated, for poor aspect ratios) is run as rkfem's fem-2x2x2 (ELFORM 2)");
        return "fem-2x2x2";
    case 41:
        note(s.where(0), "ELFORM 41 (EFG) is run as Lagrangian RKPM particles at the mesh's nodes (formulation rkpm)");
        return "rkpm";
    case 47:
        note(s.where(0), "ELFORM 47 (SPG) is run as semi-Lagrangian RKPM particles (rkpm, kinematics semi-lagrangian)");
        return "rkpm-sl";
    default:
        s.fail(0, "ELFORM", "ELFORM " + std::to_string(elform) + " is not supported",
               "expected 1 (fem-1pt), 2, -1, -2 (fem-2x2x2), 41 (rkpm) or 47 (semi-Lagrangian rkpm)");
    }
}

std::string Importer::eos(const PartCard& p, const Cards& at)
{
    if (p.eosid == 0)
        return "";
    const auto it = eos_.find(p.eosid);
    if (it == eos_.end())
        at.fail(0, "EOSID",
                "EOS " + std::to_string(p.eosid) + " of part " + std::to_string(p.pid) + " is not an *EOS_GRUNEISEN",
                "expected the EOSID of an *EOS_GRUNEISEN");
    const Cards& e = it->second;
    const double c0 = e.number(0, 1, 0.0, "C"), s1 = e.number(0, 2, 0.0, "S1"), s2 = e.number(0, 3, 0.0, "S2"),
                 s3 = e.number(0, 4, 0.0, "S3"), g0 = e.number(0, 5, 0.0, "GAMAO"), a = e.number(0, 6, 0.0, "A"),
                 e0 = e.number(0, 7, 0.0, "E0");
    if (s2 != 0.0 || s3 != 0.0)
        e.fail(0, s2 != 0.0 ? "S2" : "S3", "the cubic Us-up fit is not supported",
               "expected S2 = S3 = 0 (rkfem's Gruneisen EOS is linear in up)");
    if (e0 != 0.0)
        note(e.where(0), "E0 (initial internal energy) is taken as 0");
    if (const double v0 = e.number(1, 0, 0.0, "V0"); v0 != 0.0 && v0 != 1.0)
        e.fail(1, "V0", "an initial relative volume other than 1 is not supported", "expected V0 0 or 1");
    return "eos: {type: gruneisen, c0: " + q(c0, kVelocity) + ", s: " + num(s1) + ", gamma0: " + num(g0) +
           ", a: " + num(a) + "}";
}

std::string Importer::j2_from_plastic_kinematic(const Cards& c, const PartCard& p)
{
    std::ostringstream os;
    os << "{model: j2, rho: " << q(c.number(0, 1, 0.0, "RO"), kDensity)
       << ", E: " << q(c.number(0, 2, 0.0, "E"), kStress) << ", nu: " << num(c.number(0, 3, 0.0, "PR"))
       << ", sigy: " << q(c.number(0, 4, 0.0, "SIGY"), kStress)
       << ", etan: " << q(c.number(0, 5, 0.0, "ETAN"), kStress);
    if (const double beta = c.number(0, 6, 0.0, "BETA"); beta != 1.0)
        note(c.where(0), "BETA " + num(beta) + " (kinematic hardening share) is run as isotropic hardening (BETA 1)");
    const double src = c.number(1, 0, 0.0, "SRC"), srp = c.number(1, 1, 0.0, "SRP"), fs = c.number(1, 2, 0.0, "FS");
    if (src > 0.0 && srp > 0.0)
        os << ", cowper_symonds: {C: " << q(src, kRate) << ", P: " << num(srp) << "}";
    if (fs > 0.0)
        os << ", fail: " << num(fs);
    if (c.number(1, 3, 0.0, "VP") != 0.0)
        note(c.where(1), "VP (viscoplastic rate formulation) is run as Cowper-Symonds scaling of the yield stress");
    if (const std::string e = eos(p, c); !e.empty())
        os << ", " << e;
    os << "}";
    return os.str();
}

std::string Importer::j2_from_piecewise(const Cards& c, const PartCard& p)
{
    std::ostringstream os;
    os << "{model: j2, rho: " << q(c.number(0, 1, 0.0, "RO"), kDensity)
       << ", E: " << q(c.number(0, 2, 0.0, "E"), kStress) << ", nu: " << num(c.number(0, 3, 0.0, "PR"));
    const double fail = c.number(0, 6, 0.0, "FAIL");
    const long long lcss = c.integer(1, 2, 0, "LCSS");
    if (c.integer(1, 3, 0, "LCSR") != 0)
        c.fail(1, "LCSR", "a strain-rate curve for the yield stress is not supported",
               "expected LCSR 0 (Cowper-Symonds C and P are)");
    std::vector<std::pair<double, double>> pts;
    if (lcss > 0)
    {
        const Curve& cv = curve(lcss, c, 1, "LCSS");
        for (std::size_t i = 0; i < cv.x.size(); ++i)
            pts.emplace_back(cv.x[i], cv.y[i]);
    }
    else
        for (std::size_t k = 0; k < 8; ++k)
        {
            const double eps = c.number(2, k, 0.0, "EPS"), es = c.number(3, k, 0.0, "ES");
            if (es != 0.0 || (k == 0 && c.has(3)))
                pts.emplace_back(eps, es);
        }
    if (pts.size() >= 2)
    {
        if (pts[0].first != 0.0)
            c.fail(lcss > 0 ? 1 : 2, lcss > 0 ? "LCSS" : "EPS1",
                   "the yield curve starts at plastic strain " + num(pts[0].first),
                   "expected the first point at plastic strain 0");
        os << ", curve: [";
        for (std::size_t i = 0; i < pts.size(); ++i)
            os << (i ? ", " : "") << "[" << num(pts[i].first) << ", " << q(pts[i].second, kStress) << "]";
        os << "]";
    }
    else
        os << ", sigy: " << q(c.number(0, 4, 0.0, "SIGY"), kStress)
           << ", etan: " << q(c.number(0, 5, 0.0, "ETAN"), kStress);
    const double cc = c.number(1, 0, 0.0, "C"), pp = c.number(1, 1, 0.0, "P");
    if (cc > 0.0 && pp > 0.0)
        os << ", cowper_symonds: {C: " << q(cc, kRate) << ", P: " << num(pp) << "}";
    if (fail < 0.0)
        c.fail(0, "FAIL", "a user failure subroutine is not supported", "expected FAIL >= 0");
    if (fail > 0.0 && fail < 1e20)
        os << ", fail: " << num(fail);
    if (const std::string e = eos(p, c); !e.empty())
        os << ", " << e;
    os << "}";
    return os.str();
}

std::string Importer::j2_from_johnson_cook(const Cards& c, const PartCard& p)
{
    const double rho = c.number(0, 1, 0.0, "RO"), g = c.number(0, 2, 0.0, "G"), pr = c.number(0, 4, 0.0, "PR");
    double e = c.number(0, 3, 0.0, "E");
    if (e == 0.0)
        e = 2.0 * g * (1.0 + pr);
    const double a = c.number(1, 0, 0.0, "A"), b = c.number(1, 1, 0.0, "B"), n = c.number(1, 2, 0.0, "N");
    if (!(a > 0.0))
        c.fail(1, "A", "the yield stress A is not positive", "expected A > 0");
    std::ostringstream os;
    os << "{model: j2, rho: " << q(rho, kDensity) << ", E: " << q(e, kStress) << ", nu: " << num(pr) << ", curve: [";
    // A + B eps^N at plastic strains from 0 to 3: the J2 curve is piecewise linear between these and
    // flat past the last
    const double eps[] = {0.0, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0};
    bool first = true;
    for (double x : eps)
    {
        os << (first ? "" : ", ") << "[" << num(x) << ", " << q(a + b * (x > 0.0 ? std::pow(x, n) : 0.0), kStress)
           << "]";
        first = false;
    }
    os << "]";
    note(c.where(1), "Johnson-Cook: A + B eps^N sampled at 16 plastic strains from 0 to 3 as the J2 curve");
    if (c.number(1, 3, 0.0, "C") != 0.0)
        note(c.where(1), "Johnson-Cook C (rate) is left out: rkfem's J2 scales by Cowper-Symonds only");
    if (c.number(1, 4, 0.0, "M") != 0.0)
        note(c.where(1), "Johnson-Cook M, TM, TR (thermal softening) are left out: rkfem's J2 is isothermal");
    const double d1 = c.number(2, 4, 0.0, "D1");
    bool damage_terms = false;
    for (std::size_t k = 5; k < 8; ++k)
        damage_terms = damage_terms || c.number(2, k, 0.0, "D") != 0.0;
    damage_terms = damage_terms || c.number(3, 0, 0.0, "D5") != 0.0;
    if (d1 > 0.0 && !damage_terms)
        os << ", fail: " << num(d1);
    else if (d1 != 0.0 || damage_terms)
        note(c.where(2), "Johnson-Cook failure D1-D5 is left out (only a constant D1 maps, to fail)");
    const std::string eo = eos(p, c);
    if (eo.empty())
        note(c.where(0),
             "MAT_JOHNSON_COOK without an EOS: rkfem's J2 takes its pressure from the elastic bulk modulus");
    else
        os << ", " << eo;
    os << "}";
    return os.str();
}

/// MAT_072R3 with A0 > 0: every parameter the user's. f'c (which rkfem's K&C needs for its rate law
/// and defaults) is the uniaxial strength of the maximum surface, f'c = a0 + (f'c / 3) / (a1 + a2 f'c
/// / 3); E from the EOS's first unloading bulk modulus and PR, K (1 - 2 nu) 3, as LS-DYNA takes it.
std::string Importer::kcc_user_set(const Cards& c, const PartCard& p, double rho, double pr)
{
    const double ft = c.number(1, 0, 0.0, "FT"), a0 = c.number(1, 1, 0.0, "A0"), a1 = c.number(1, 2, 0.0, "A1"),
                 a2 = c.number(1, 3, 0.0, "A2"), b1 = c.number(1, 4, 0.0, "B1"), omega = c.number(1, 5, 0.0, "OMEGA"),
                 a1f = c.number(1, 6, 0.0, "A1F"), b3 = c.number(4, 5, 0.0, "B3"), a0y = c.number(4, 6, 0.0, "A0Y"),
                 a1y = c.number(4, 7, 0.0, "A1Y"), b2 = c.number(6, 5, 0.0, "B2"), a2f = c.number(6, 6, 0.0, "A2F"),
                 a2y = c.number(6, 7, 0.0, "A2Y");
    if (!(a1 > 0.0) || a2 < 0.0)
        c.fail(1, "A1", "the maximum surface a0 + p / (a1 + a2 p) has a1 <= 0 or a2 < 0",
               "expected a0 > 0, a1 > 0, a2 >= 0 (user-set K&C)");
    // f'c on the maximum surface in uniaxial compression (p = f'c / 3): a contraction from 3 a0
    double fc = 3.0 * a0;
    for (int it = 0; it < 500; ++it)
    {
        const double next = a0 + (fc / 3.0) / (a1 + a2 * fc / 3.0);
        if (std::abs(next - fc) <= 1e-15 * next)
            break;
        fc = next;
    }
    std::ostringstream os;
    os << "{model: kcc, rho: " << q(rho, kDensity) << ", fc: " << q(fc, kStress);
    if (pr != 0.0)
        os << ", nu: " << num(pr);
    const Dim inverse_stress{-1, 1, 2, ""};
    os << ", a0: " << q(a0, kStress) << ", a1: " << num(a1) << ", a2: " << q(a2, inverse_stress)
       << ", a0y: " << q(a0y, kStress) << ", a1y: " << num(a1y) << ", a2y: " << q(a2y, inverse_stress)
       << ", a1f: " << num(a1f) << ", a2f: " << q(a2f, inverse_stress) << ", b1: " << num(b1) << ", b2: " << num(b2)
       << ", b3: " << num(b3) << ", omega: " << num(omega) << ", ft: " << q(ft, kStress);
    // the damage table: 13 (lambda, eta) pairs, NPTS of them if given
    const long long npts = c.integer(2, 7, 13, "NPTS");
    if (npts < 3 || npts > 13)
        c.fail(2, "NPTS", "NPTS " + std::to_string(npts) + " is outside 3-13", "expected 3 to 13 table points");
    os << ", eta: [";
    for (long long i = 0; i < npts; ++i)
    {
        const std::size_t card = i < 8 ? 3 : 4, k = static_cast<std::size_t>(i < 8 ? i : i - 8);
        const double lambda = c.number(card, k, 0.0, "LAMBDA"), eta = c.number(card + 2, k, 0.0, "ETA");
        os << (i ? ", " : "") << "[" << num(lambda) << ", " << num(eta) << "]";
    }
    os << "]";
    // the EOS: *EOS_TABULATED_COMPACTION (10 ln(V/V0), pressures and unloading bulk moduli, 16 columns)
    const auto it = eos8_.find(p.eosid);
    if (it == eos8_.end())
        c.fail(0, "MID", "part " + std::to_string(p.pid) + " of user-set K&C has no *EOS_TABULATED_COMPACTION",
               "expected the part's EOSID to name one (LS-DYNA's EOS_8, which MAT_072R3 needs)");
    const Cards& e = it->second;
    const std::vector<int> w(5, 16);
    auto row = [&](std::size_t first_card, const char* name, const Dim& d, bool as_number)
    {
        std::string out = "[";
        for (std::size_t i = 0; i < 10; ++i)
        {
            const double v = e.number(first_card + i / 5, i % 5, 0.0, name, w);
            out += (i ? ", " : "") + (as_number ? num(v) : q(v, d));
        }
        return out + "]";
    };
    const double k1 = e.number(7, 0, 0.0, "K1", w);
    os << ", eos: {strain: " << row(1, "EV", kNone, true) << ", pressure: " << row(3, "C", kStress, false)
       << ", unload_bulk: " << row(7, "K", kStress, false) << "}";
    if (k1 > 0.0)
        os << ", E: " << num(si(3.0 * k1 * (1.0 - 2.0 * pr), kStress));
    os << ", fracture_energy: 0";
    os << edrop(c) << rate_effects(c) << "}";
    note(c.where(1), "user-set K&C: f'c " + q(fc, kStress) + " from the maximum surface in uniaxial compression, E " +
                         "from the EOS's first unloading bulk modulus, b2 as given (fracture_energy 0: no crack-band "
                         "scaling)");
    return os.str();
}

/// MAT_072R3's EDROP as the kcc material's edrop (blank or 0: none, rkfem's default; LS-DYNA's
/// manual gives no formula, docs/theory/materials.md states rkfem's).
std::string Importer::edrop(const Cards& c)
{
    const double e = c.number(2, 2, 0.0, "EDROP");
    if (e < 0.0)
        c.fail(2, "EDROP", "EDROP " + num(e) + " is negative", "expected EDROP >= 0 (post-peak dilatancy decay)");
    return e > 0.0 ? ", edrop: " + num(e) : "";
}

/// MAT_072R3's LCRATE as the kcc material's rate_effects: 0 none, -1 rkfem's default law, else the curve.
std::string Importer::rate_effects(const Cards& c)
{
    const long long lcrate = c.integer(2, 5, 0, "LCRATE");
    if (lcrate == 0)
        return ", rate_effects: false";
    if (lcrate == -1)
    {
        note(c.where(2), "LCRATE -1 (LS-DYNA's built-in rate curve) is run with rkfem's default rate law "
                         "(CEB-FIP compression, Malvar-Ross tension, capped; docs/user/decks.md, rate_effects)");
        return ", rate_effects: true";
    }
    const Curve& cv = curve(lcrate, c, 2, "LCRATE");
    std::string out = ", rate_effects: {curve: [";
    for (std::size_t i = 0; i < cv.x.size(); ++i)
        out += (i ? ", [" : "[") + num(si(cv.x[i], kRate)) + ", " + num(cv.y[i]) + "]";
    return out + "]}";
}

std::string Importer::concrete(const std::string& base, const Cards& c, const PartCard& p)
{
    std::ostringstream os;
    const double rho = c.number(0, 1, 0.0, "RO");
    if (base == "*MAT_CONCRETE_DAMAGE_REL3")
    {
        const double pr = c.number(0, 2, 0.0, "PR"), a0 = c.number(1, 1, 0.0, "A0");
        if (a0 > 0.0)
            return kcc_user_set(c, p, rho, pr);
        if (a0 == 0.0)
            c.fail(1, "A0", "A0 is 0", "expected A0 = -f'c (generated parameters) or the user's a0 > 0");
        os << "{model: kcc, rho: " << q(rho, kDensity) << ", fc: " << q(-a0, kStress);
        if (pr != 0.0)
            os << ", nu: " << num(pr);
        os << edrop(c) << rate_effects(c);
        if (c.number(2, 6, 0.0, "LOCWIDTH") != 0.0)
            note(c.where(2), "LOCWIDTH is not read: rkfem's K&C scales softening by the element size (crack band) with "
                             "fracture_energy");
        os << "}";
        return os.str();
    }
    // *MAT_CSCM_CONCRETE
    const long long irate = c.integer(0, 4, 0, "IRATE");
    const double erode = c.number(0, 5, 0.0, "ERODE");
    const double fpc = c.number(2, 0, 0.0, "FPC");
    if (!(fpc > 0.0))
        c.fail(2, "FPC", "f'c is not positive", "expected the unconfined compressive strength");
    os << "{model: cscm, rho: " << q(rho, kDensity) << ", fc: " << q(fpc, kStress)
       << ", rate_effects: " << (irate == 1 ? "true" : "false") << "}";
    if (erode > 1.0)
        note(c.where(0), "ERODE " + num(erode) +
                             " (erosion at damage 0.99 and principal strain ERODE - 1) is not "
                             "mapped: give the part an erosion key");
    if (const double dagg = c.number(2, 1, 0.0, "DAGG"); dagg != 0.0 && std::abs(dagg * u_.length - 0.019) > 1e-9)
        note(c.where(2), "DAGG is not read: rkfem's CSCM generates its parameters for 19 mm aggregate");
    if (c.integer(0, 6, 0, "RECOV") != 0)
        note(c.where(0), "RECOV (modulus recovery) is not read");
    return os.str();
}

std::string Importer::erosion(long long mid)
{
    const auto it = erosion_.find(mid);
    if (it == erosion_.end())
        return "";
    const Cards& c = it->second;
    const double excl = c.number(0, 1, 0.0, "EXCL");
    auto value = [&](std::size_t card, std::size_t k, const char* name)
    {
        const double v = c.number(card, k, 0.0, name);
        return excl != 0.0 && v == excl ? 0.0 : v;
    };
    const struct
    {
        std::size_t card, k;
        const char* name;
    } refused[] = {{0, 2, "MXPRES"}, {0, 3, "MNEPS"}, {1, 0, "MNPRES"},  {1, 1, "SIGP1"},  {1, 2, "SIGVM"},
                   {1, 4, "EPSSH"},  {1, 5, "SIGTH"}, {1, 6, "IMPULSE"}, {1, 7, "FAILTM"}, {2, 0, "IDAM"}};
    for (const auto& r : refused)
        if (value(r.card, r.k, r.name) != 0.0)
            c.fail(r.card, r.name, std::string(r.name) + " is not supported",
                   "expected the criteria rkfem's erosion has: EFFEPS, VOLEPS, MXEPS (0 or EXCL for the others)");
    std::ostringstream os;
    const double effeps = value(0, 4, "EFFEPS"), voleps = value(0, 5, "VOLEPS"), mxeps = value(1, 3, "MXEPS");
    if (voleps < 0.0)
        c.fail(0, "VOLEPS", "a compressive volumetric strain criterion is not supported", "expected VOLEPS >= 0");
    std::string sep;
    os << "{";
    if (effeps > 0.0)
    {
        os << "effective_plastic_strain: " << num(effeps);
        sep = ", ";
    }
    if (voleps > 0.0)
    {
        os << sep << "volumetric_strain: " << num(voleps);
        sep = ", ";
    }
    if (mxeps > 0.0)
    {
        os << sep << "principal_strain: " << num(mxeps);
        note(c.where(1), "MXEPS is taken as rkfem's principal_strain, the largest principal logarithmic strain");
        sep = ", ";
    }
    os << "}";
    return sep.empty() ? "" : os.str();
}

std::string Importer::material(const PartCard& p)
{
    const auto it = materials_.find(p.mid);
    if (it == materials_.end())
        throw DeckError({p.where, "*PART MID"},
                        "material " + std::to_string(p.mid) + " of part " + std::to_string(p.pid) +
                            " is not defined (or not supported)",
                        "expected the MID of a supported *MAT_ keyword");
    const Cards& c = it->second;
    const std::string& base = material_kw_.at(p.mid);
    if (base == "*MAT_ELASTIC")
    {
        if (c.number(0, 4, 0.0, "DA") != 0.0 || c.number(0, 5, 0.0, "DB") != 0.0)
            note(c.where(0), "DA, DB (axial and bending damping of beams) do not apply to solids");
        if (p.eosid != 0)
            c.fail(0, "MID", "an EOS on an elastic material is not supported",
                   "expected EOSID 0 on *MAT_ELASTIC parts");
        return "{model: elastic, rho: " + q(c.number(0, 1, 0.0, "RO"), kDensity) +
               ", E: " + q(c.number(0, 2, 0.0, "E"), kStress) + ", nu: " + num(c.number(0, 3, 0.0, "PR")) + "}";
    }
    if (base == "*MAT_PLASTIC_KINEMATIC")
        return j2_from_plastic_kinematic(c, p);
    if (base == "*MAT_PIECEWISE_LINEAR_PLASTICITY")
        return j2_from_piecewise(c, p);
    if (base == "*MAT_JOHNSON_COOK")
        return j2_from_johnson_cook(c, p);
    if (p.eosid != 0 && !(base == "*MAT_CONCRETE_DAMAGE_REL3" && c.number(1, 1, 0.0, "A0") > 0.0))
        note(p.where, "EOSID " + std::to_string(p.eosid) + " is not read: the concrete models generate their own EOS");
    return concrete(base, c, p);
}

/// The part's hourglass and bulk_viscosity lines, each unless the export carried it ($rkfem).
void Importer::hourglass(const PartCard& p, const std::string& formulation, const std::set<std::string>& carried,
                         std::ostringstream& os)
{
    long long ihq = ihq_;
    double qm = qh_, q1 = q1_, q2 = q2_;
    if (p.hgid != 0)
    {
        const auto it = hourglass_.find(p.hgid);
        if (it == hourglass_.end())
            throw DeckError({p.where, "*PART HGID"}, "hourglass " + std::to_string(p.hgid) + " is not defined",
                            "expected the HGID of an *HOURGLASS");
        const Cards& h = it->second;
        if (const long long i = h.integer(0, 1, 0, "IHQ"); i != 0)
            ihq = i;
        if (const double v = h.number(0, 2, 0.0, "QM"); v != 0.0)
            qm = v;
        if (const double v = h.number(0, 4, 0.0, "Q1"); v != 0.0)
            q1 = v;
        if (const double v = h.number(0, 5, 0.0, "Q2"); v != 0.0)
            q2 = v;
        if (ihq < 0 || ihq > 6)
            h.fail(0, "IHQ", "IHQ " + std::to_string(ihq) + " is not supported",
                   "expected 1, 2, 3 (viscous), 4, 5 (stiffness) or 6 (assumed strain)");
    }
    if (formulation == "fem-1pt" && !carried.count("hourglass"))
    {
        // IHQ 0 and 1: LS-DYNA's standard viscous form on the raw base vectors (its default), which
        // rkfem has as viscous-plain; 2 and 3 the Flanagan-Belytschko viscous forms
        const char* type = ihq >= 6   ? "assumed-strain"
                           : ihq >= 4 ? "stiffness"
                           : ihq >= 2 ? "viscous"
                                      : "viscous-plain";
        os << "    hourglass: {type: " << type << ", coefficient: " << num(qm == 0.0 ? 0.1 : qm) << "}\n";
        if (ihq == 2)
            note(p.where, "IHQ 2 is run as rkfem's viscous form (Flanagan-Belytschko with exact volume: LS-DYNA's "
                          "IHQ 3)");
        if (ihq == 4)
            note(p.where, "IHQ 4 is run as rkfem's stiffness form (Flanagan-Belytschko exact volume: LS-DYNA's IHQ 5)");
    }
    if ((q1 != 0.0 || q2 != 0.0) && !carried.count("bulk_viscosity"))
        os << "    bulk_viscosity: {quadratic: " << num(q1 == 0.0 ? 1.5 : q1)
           << ", linear: " << num(q2 == 0.0 ? 0.06 : q2) << "}\n";
}

void Importer::initial_velocities()
{
    auto set_parts = [&](const std::vector<long long>& pids, const Cards& c, std::size_t card, std::size_t k0)
    {
        std::vector<std::string> v;
        for (std::size_t k = 0; k < 3; ++k)
            v.push_back(q(c.number(card, k0 + k, 0.0, k == 0 ? "VX" : k == 1 ? "VY" : "VZ"), kVelocity));
        for (long long pid : pids)
        {
            if (part_velocity_.count(pid))
                c.fail(card, "VX", "part " + std::to_string(pid) + " has an initial velocity already",
                       "expected one initial velocity per part");
            part_velocity_[pid] = v;
        }
    };
    for (const Cards& c : velocity_gens_)
    {
        if (c.number(0, 2, 0.0, "OMEGA") != 0.0)
            c.fail(0, "OMEGA", "an initial rotation is not supported", "expected OMEGA 0");
        check_frame(c, 0, 7, "ICID");
        const long long id = c.integer(0, 0, 0, "ID"), styp = c.integer(0, 1, 2, "STYP");
        std::vector<long long> pids;
        if (styp == 2)
            pids = {part(id, c, 0, "ID").pid};
        else if (styp == 1)
            pids = parts_of_set(id, c, 0, "ID");
        else if (styp == 3)
            pids = whole_parts(nodes_of_set(id, c, 0, "ID"), c, 0, "ID");
        else
            c.fail(0, "STYP", "STYP " + std::to_string(styp) + " is not supported",
                   "expected 1 (part set), 2 (part) or 3 (node set of whole parts)");
        set_parts(pids, c, 0, 3);
    }
    for (const Cards& c : velocities_)
    {
        const long long nsid = c.integer(0, 0, 0, "NSID");
        if (c.integer(0, 1, 0, "NSIDEX") != 0 || c.integer(0, 2, 0, "BOXID") != 0)
            c.fail(0, "NSIDEX", "exempted nodes and boxes are not supported", "expected NSIDEX 0 and BOXID 0");
        for (std::size_t k = 3; k < 6; ++k)
            if (c.number(1, k, 0.0, "VXR") != 0.0)
                c.fail(1, "VXR", "rotational velocities do not apply to solids' nodes", "expected VXR = VYR = VZR = 0");
        std::vector<long long> pids;
        if (nsid == 0)
            for (const PartCard& p : parts_)
                pids.push_back(p.pid);
        else
            pids = whole_parts(nodes_of_set(nsid, c, 0, "NSID"), c, 0, "NSID");
        set_parts(pids, c, 1, 0);
    }
}

std::string Importer::node_set_name(long long sid, const Cards& c, std::size_t card, const char* field)
{
    nodes_of_set(sid, c, card, field);
    used_node_sets_.insert(sid);
    return "nset_" + std::to_string(sid);
}

std::string Importer::segment_set_name(long long sid, const Cards& c, std::size_t card, const char* field)
{
    if (!segment_sets_.count(sid))
        c.fail(card, field, "segment set " + std::to_string(sid) + " is not defined",
               "expected an SID of a *SET_SEGMENT");
    used_segment_sets_.insert(sid);
    return "sseg_" + std::to_string(sid);
}

const char* axis(long long dof)
{
    return dof == 1 ? "x" : dof == 2 ? "y" : "z";
}

void Importer::boundary_conditions(std::ostringstream& os)
{
    std::vector<std::string> lines;
    auto fixed = [&](const Cards& c, std::size_t card, std::size_t k0, const std::string& set)
    {
        if (c.integer(card, k0 - 1, 0, "CID") != 0)
            c.fail(card, "CID", "a local coordinate system is not supported", "expected CID 0");
        std::string comps;
        for (std::size_t k = 0; k < 3; ++k)
            if (c.integer(card, k0 + k, 0, "DOF") != 0)
                comps += std::string(comps.empty() ? "" : ", ") + axis(static_cast<long long>(k + 1));
        if (!comps.empty())
            lines.push_back("  - {node_set: " + set + ", fixed: [" + comps + "]}");
    };
    for (const Cards& c : spc_sets_)
        for (std::size_t i = 0; i < c.size(); ++i)
            if (!c.blank(i))
                fixed(c, i, 2, node_set_name(c.integer(i, 0, 0, "NSID"), c, i, "NSID"));
    static const char* tc_axes[8] = {"", "x", "y", "z", "x, y", "y, z", "z, x", "x, y, z"};
    // *CONSTRAINED_GLOBAL: the nodes on a plane normal to an axis (symmetry planes), by TC's code
    for (const Cards& c : global_constraints_)
        for (std::size_t i = 0; i < c.size(); ++i)
        {
            if (c.blank(i))
                continue;
            const long long tc = c.integer(i, 0, 0, "TC"), dir = c.integer(i, 2, 0, "DIR");
            if (tc < 0 || tc > 7)
                c.fail(i, "TC", "TC " + std::to_string(tc) + " is not a constraint code",
                       "expected 0-7 (as *NODE's TC)");
            if (dir < 1 || dir > 3)
                c.fail(i, "DIR", "DIR " + std::to_string(dir) + " is not an axis", "expected 1, 2 or 3 (x, y, z)");
            if (c.integer(i, 1, 0, "RC") != 0)
                note(c.where(i), "RC (rotational constraints) does not apply to solids' nodes");
            if (tc == 0)
                continue;
            const double p[3] = {c.number(i, 3, 0.0, "X"), c.number(i, 4, 0.0, "Y"), c.number(i, 5, 0.0, "Z")};
            const double tol = c.number(i, 6, 0.0, "TOL");
            const std::string name = "constrained_global_" + std::to_string(i + 1);
            std::string normal = dir == 1 ? "[1, 0, 0]" : dir == 2 ? "[0, 1, 0]" : "[0, 0, 1]";
            plane_sets_.push_back("  " + name + ": {select: {type: plane, point: [" + q(p[0], kLength) + ", " +
                                  q(p[1], kLength) + ", " + q(p[2], kLength) + "], normal: " + normal +
                                  (tol > 0.0 ? ", tolerance: " + q(tol, kLength) : std::string()) + "}}");
            lines.push_back("  - {node_set: " + name + ", fixed: [" + tc_axes[tc] + "]}");
        }
    for (auto& [tc, nids] : tc_nodes_)
    {
        std::sort(nids.begin(), nids.end());
        const std::string name = "node_tc_" + std::to_string(tc);
        extra_node_sets_.push_back({name, nids});
        lines.push_back("  - {node_set: " + name + ", fixed: [" + tc_axes[tc] + "]}");
    }
    for (const Cards& c : spc_nodes_)
        for (std::size_t i = 0; i < c.size(); ++i)
        {
            if (c.blank(i))
                continue;
            const long long nid = c.integer(i, 0, 0, "NID");
            const std::string name = "spc_node_" + std::to_string(nid);
            extra_node_sets_.push_back({name, {nid}});
            fixed(c, i, 2, name);
        }
    auto motion = [&](const Cards& c, std::size_t i, const std::string& set)
    {
        const long long dof = c.integer(i, 1, 0, "DOF"), vad = c.integer(i, 2, 0, "VAD");
        const long long lcid = c.integer(i, 3, 0, "LCID");
        const double sf = c.number(i, 4, 1.0, "SF"), death = c.number(i, 6, 0.0, "DEATH"),
                     birth = c.number(i, 7, 0.0, "BIRTH");
        if (dof < 1 || dof > 3)
            c.fail(i, "DOF", "DOF " + std::to_string(dof) + " is not supported", "expected 1, 2 or 3 (x, y, z)");
        if (vad != 0 && vad != 2)
            c.fail(i, "VAD", "VAD " + std::to_string(vad) + " is not supported",
                   "expected 0 (velocity) or 2 (displacement)");
        if ((death != 0.0 && death < 1e20) || birth != 0.0)
            c.fail(i, death != 0.0 && death < 1e20 ? "DEATH" : "BIRTH", "birth and death times are not supported",
                   "expected BIRTH 0 and DEATH 0 or 1e28");
        const Curve& cv = curve(lcid, c, i, "LCID");
        lines.push_back("  - {node_set: " + set + ", " + (vad == 0 ? "velocity" : "displacement") + ": {" + axis(dof) +
                        ": " + time_function(cv, sf == 0.0 ? 1.0 : sf, 0.0, vad == 0 ? kVelocity : kLength) + "}}");
    };
    for (const Cards& c : motions_)
        for (std::size_t i = 0; i < c.size(); ++i)
            if (!c.blank(i))
                motion(c, i, node_set_name(c.integer(i, 0, 0, "NSID"), c, i, "NSID"));
    for (const Cards& c : motion_nodes_)
        for (std::size_t i = 0; i < c.size(); ++i)
        {
            if (c.blank(i))
                continue;
            const long long nid = c.integer(i, 0, 0, "NID");
            const std::string name = "motion_node_" + std::to_string(nid);
            extra_node_sets_.push_back({name, {nid}});
            motion(c, i, name);
        }
    if (lines.empty())
        return;
    os << "boundary_conditions:\n";
    for (const std::string& l : lines)
        os << l << "\n";
}

void Importer::loads(std::ostringstream& os)
{
    std::vector<std::string> lines;
    for (const Cards& c : node_loads_)
        for (std::size_t i = 0; i < c.size(); ++i)
        {
            if (c.blank(i))
                continue;
            const std::string set = node_set_name(c.integer(i, 0, 0, "NSID"), c, i, "NSID");
            const long long dof = c.integer(i, 1, 0, "DOF");
            if (dof < 1 || dof > 3)
                c.fail(i, "DOF", "DOF " + std::to_string(dof) + " is not supported", "expected 1, 2 or 3 (x, y, z)");
            if (c.integer(i, 4, 0, "CID") != 0)
                c.fail(i, "CID", "a local coordinate system is not supported", "expected CID 0");
            const double sf = c.number(i, 3, 1.0, "SF");
            const Curve& cv = curve(c.integer(i, 2, 0, "LCID"), c, i, "LCID");
            lines.push_back("  - {type: nodal_force, node_set: " + set + ", force: {" + axis(dof) + ": " +
                            time_function(cv, sf == 0.0 ? 1.0 : sf, 0.0, kForce) + "}, total: false}");
        }
    for (const Cards& c : segment_loads_)
        for (std::size_t i = 0; i < c.size(); ++i)
        {
            if (c.blank(i))
                continue;
            const std::string set = segment_set_name(c.integer(i, 0, 0, "SSID"), c, i, "SSID");
            const double sf = c.number(i, 2, 1.0, "SF"), at = c.number(i, 3, 0.0, "AT");
            const Curve& cv = curve(c.integer(i, 1, 0, "LCID"), c, i, "LCID");
            lines.push_back("  - {type: pressure, face_set: " + set +
                            ", pressure: " + time_function(cv, sf == 0.0 ? 1.0 : sf, at, kStress) + "}");
            if (at != 0.0)
                note(c.where(i), "AT (arrival time) shifts the curve by " + q(at, kTime));
        }
    if (lines.empty())
        return;
    os << "loads:\n";
    for (const std::string& l : lines)
        os << l << "\n";
}

void Importer::contacts(std::ostringstream& os)
{
    std::vector<std::string> lines;
    for (std::size_t n = 0; n < contacts_.size(); ++n)
    {
        const Cards& c = contacts_[n];
        const std::string& kw = contact_kw_[n];
        const bool single = kw.find("SINGLE_SURFACE") != std::string::npos;
        const bool eroding = kw.find("ERODING") != std::string::npos;
        if (kw == "*CONTACT_SURFACE_TO_SURFACE")
            note(c.where(0), "*CONTACT_SURFACE_TO_SURFACE is run as rkfem's surface-to-surface contact (two passes, "
                             "as the AUTOMATIC form)");
        // the surfaces a side names: part names, or a face set
        auto side = [&](long long id, long long typ, const char* field) -> std::vector<std::string>
        {
            if (typ == 3)
                return {part(id, c, 0, field).name};
            if (typ == 2)
            {
                std::vector<std::string> names;
                for (long long pid : parts_of_set(id, c, 0, field))
                    names.push_back(part(pid, c, 0, field).name);
                return names;
            }
            if (typ == 0 && !single)
                return {segment_set_name(id, c, 0, field)};
            if (typ == 5 || (single && id == 0))
                return {};
            c.fail(0, field, "surface type " + std::to_string(typ) + " is not supported",
                   "expected 0 (segment set), 2 (part set) or 3 (part)");
        };
        const long long ssid = c.integer(0, 0, 0, "SSID"), msid = c.integer(0, 1, 0, "MSID");
        const long long sstyp = c.integer(0, 2, 0, "SSTYP"), mstyp = c.integer(0, 3, 0, "MSTYP");
        if (c.integer(0, 4, 0, "SBOXID") != 0 || c.integer(0, 5, 0, "MBOXID") != 0)
            c.fail(0, "SBOXID", "boxes are not supported", "expected SBOXID = MBOXID = 0");
        const double fs = c.number(1, 0, 0.0, "FS"), fd = c.number(1, 1, 0.0, "FD"), dc = c.number(1, 2, 0.0, "DC");
        const double vdc = c.number(1, 4, 0.0, "VDC"), bt = c.number(1, 6, 0.0, "BT"), dt = c.number(1, 7, 0.0, "DT");
        if (bt != 0.0 || (dt != 0.0 && dt < 1e20))
            c.fail(1, bt != 0.0 ? "BT" : "DT", "birth and death times are not supported",
                   "expected BT 0 and DT 0 or 1e20");
        if (c.number(1, 3, 0.0, "VC") != 0.0)
            c.fail(1, "VC", "viscous friction is not supported", "expected VC 0");
        std::string common;
        if (fs > 0.0)
            common += ", friction: {static: " + num(fs) + ", dynamic: " + num(fd) +
                      (dc != 0.0 ? ", decay: " + q(dc, kSlowness) : std::string()) + "}";
        if (vdc > 0.0)
            common += ", damping: " + num(vdc / 100.0);
        const double sfs = c.number(2, 0, 1.0, "SFS"), sfm = c.number(2, 1, 1.0, "SFM");
        const double slsfac = slsfac_ == 0.0 ? 0.1 : slsfac_;
        const double factor = std::max(sfs == 0.0 ? 1.0 : sfs, sfm == 0.0 ? 1.0 : sfm);
        if (factor != 1.0 || slsfac != 0.1)
            common += ", penalty_scale: " + num(slsfac * factor);
        const std::size_t card_a = eroding ? 4 : 3; // eroding forms have a card of their own before the options
        const long long soft = c.integer(card_a, 0, 0, "SOFT");
        if (soft == 1)
        {
            const double sofscl = c.number(card_a, 1, 0.1, "SOFSCL");
            common += ", stiffness: soft, soft_scale: " + num(sofscl == 0.0 ? 0.1 : sofscl);
        }
        else if (soft == 0)
            common += ", stiffness: segment";
        else
            c.fail(card_a, "SOFT", "SOFT " + std::to_string(soft) + " is not supported",
                   "expected 0 (segment stiffness) or 1 (soft constraint)");
        if (eroding)
            note(c.where(0), kw + ": rkfem's surface contacts take the faces that erosion exposes, as the ERODING "
                                  "forms do");
        if (single)
        {
            const std::vector<std::string> s = side(ssid, sstyp, "SSID");
            std::string list;
            for (const std::string& name : s)
                list += (list.empty() ? "" : ", ") + name;
            lines.push_back("  - {type: single-surface" +
                            (list.empty() ? std::string() : ", surfaces: [" + list + "]") + common + "}");
            continue;
        }
        const std::vector<std::string> a = side(ssid, sstyp, "SSID"), b = side(msid, mstyp, "MSID");
        if (a.empty() || b.empty())
            c.fail(0, "SSTYP", "surface-to-surface contact needs two named sides",
                   "expected SSTYP and MSTYP 0, 2 or 3");
        for (const std::string& x : a)
            for (const std::string& y : b)
                lines.push_back("  - {type: surface-to-surface, surfaces: [" + x + ", " + y + "]" + common + "}");
    }
    for (const Cards& c : walls_)
    {
        const long long nsid = c.integer(0, 0, 0, "NSID");
        if (c.integer(0, 1, 0, "NSIDEX") != 0 || c.integer(0, 2, 0, "BOXID") != 0)
            c.fail(0, "NSIDEX", "exempted nodes and boxes are not supported", "expected NSIDEX 0 and BOXID 0");
        if (c.number(0, 3, 0.0, "OFFSET") != 0.0 || c.number(0, 4, 0.0, "BIRTH") != 0.0)
            c.fail(0, "OFFSET", "an offset or birth time is not supported", "expected OFFSET 0 and BIRTH 0");
        const double xt = c.number(1, 0, 0.0, "XT"), yt = c.number(1, 1, 0.0, "YT"), zt = c.number(1, 2, 0.0, "ZT");
        const double xh = c.number(1, 3, 0.0, "XH"), yh = c.number(1, 4, 0.0, "YH"), zh = c.number(1, 5, 0.0, "ZH");
        const double fric = c.number(1, 6, 0.0, "FRIC");
        if (xh == xt && yh == yt && zh == zt)
            c.fail(1, "XH", "the wall's normal has zero length", "expected a head point other than the tail");
        std::vector<long long> pids;
        if (nsid == 0)
            for (const PartCard& p : parts_)
                pids.push_back(p.pid);
        else
        {
            const std::vector<long long> nids = nodes_of_set(nsid, c, 0, "NSID");
            for (const PartCard& p : parts_)
            {
                const auto it = part_nodes_.find(p.pid);
                if (it != part_nodes_.end() &&
                    std::any_of(nids.begin(), nids.end(),
                                [&](long long n)
                                { return std::binary_search(it->second.begin(), it->second.end(), n); }))
                    pids.push_back(p.pid);
            }
            note(c.where(0), "the wall acts on every surface node of the parts its node set touches");
        }
        std::string list;
        for (long long pid : pids)
            list += (list.empty() ? "" : ", ") + part(pid, c, 0, "NSID").name;
        std::string line = "  - {type: rigid-wall, surfaces: [" + list + "], point: [" + q(xt, kLength) + ", " +
                           q(yt, kLength) + ", " + q(zt, kLength) + "], normal: [" + num(xh - xt) + ", " +
                           num(yh - yt) + ", " + num(zh - zt) + "]";
        if (fric > 0.0 && fric < 1.0)
            line += ", friction: {static: " + num(fric) + "}";
        else if (fric != 0.0)
            c.fail(1, "FRIC", "FRIC " + num(fric) + " (stick or special friction) is not supported",
                   "expected 0 <= FRIC < 1 (Coulomb)");
        lines.push_back(line + "}");
        note(c.where(0), "*RIGIDWALL_PLANAR is a penalty wall here (LS-DYNA's is a constraint)");
    }
    if (lines.empty())
        return;
    os << "contacts:\n";
    for (const std::string& l : lines)
        os << l << "\n";
}

void Importer::read_carried(const std::string& path)
{
    std::ifstream in(path);
    std::string line;
    int n = 0;
    while (std::getline(in, line))
    {
        ++n;
        if (line.rfind("$rkfem: ", 0) != 0)
            continue;
        const std::string body = line.substr(8);
        const auto colon = body.find(": ");
        if (colon == std::string::npos)
            throw DeckError({path + ":" + std::to_string(n), "$rkfem"}, "has no 'PATH: VALUE'",
                            "expected the lines rkfem's export writes, e.g. '$rkfem: parts.a.rk: {order: 1}'");
        const std::string key = body.substr(0, colon), value = body.substr(colon + 2);
        if (key.rfind("parts.", 0) == 0 && key.find('.', 6) != std::string::npos)
        {
            const auto dot = key.find('.', 6);
            carried_part_[key.substr(6, dot - 6)].push_back(key.substr(dot + 1) + ": " + value);
        }
        else if (key.rfind("time.", 0) == 0)
            carried_time_.push_back(key.substr(5) + ": " + value);
        else if (key.find('.') == std::string::npos)
            carried_top_.push_back(key + ": " + value);
        else
            throw DeckError({path + ":" + std::to_string(n), "$rkfem " + key}, "is not a part, time or top-level key",
                            "expected parts.NAME.KEY, time.KEY or KEY");
    }
}

void Importer::emit(std::ostringstream& os)
{
    if (end_ <= 0.0)
        throw DeckError(
            {time_where_.empty() ? blocks_.empty() ? std::string("(deck)") : blocks_.front().file : time_where_,
             "*CONTROL_TERMINATION ENDTIM"},
            time_where_.empty() ? "is missing" : "is not positive", "expected *CONTROL_TERMINATION with ENDTIM > 0");
    if (parts_.empty())
        throw DeckError({blocks_.empty() ? std::string("(deck)") : blocks_.front().file, "*PART"}, "no part is defined",
                        "expected at least one *PART with *SECTION_SOLID solids");
    std::string title = title_;
    while (!title.empty() && (title.back() == ' ' || title.back() == '\t'))
        title.pop_back();
    std::string quoted;
    for (char ch : title)
        quoted += ch == '"' || ch == '\\' ? std::string("\\") + ch : std::string(1, ch);
    os << "title: \"" << (quoted.empty() ? "imported LS-DYNA deck" : quoted) << "\"\n";
    os << "time:\n  end: " << q(end_, kTime) << "\n";
    if (d3plot_ > 0.0)
        os << "  output_interval: " << q(d3plot_, kTime) << "\n";
    if (glstat_ > 0.0)
        os << "  history_interval: " << q(glstat_, kTime) << "\n";
    if (tssfac_ > 0.0)
        os << "  dt_scale: " << num(std::min(tssfac_, 1.0)) << "\n";
    if (endcyc_ > 0)
        os << "  max_steps: " << endcyc_ << "\n";
    if (dtmin_ > 0.0)
        os << "  dt_min_fraction: " << num(dtmin_) << "\n";
    for (const std::string& l : carried_time_)
        os << "  " << l << "\n";
    initial_velocities();
    os << "parts:\n";
    for (const PartCard& p : parts_)
    {
        // a key rkfem's export carried whole ($rkfem line) stands for what the cards say of it
        std::set<std::string> carried;
        if (const auto it = carried_part_.find(p.name); it != carried_part_.end())
            for (const std::string& l : it->second)
                carried.insert(l.substr(0, l.find(':')));
        if (!part_nodes_.count(p.pid) && !carried.count("generator"))
            throw DeckError({p.where, "*PART PID"}, "part " + std::to_string(p.pid) + " has no *ELEMENT_SOLID solids",
                            "expected 8-node solids of each part (shells, beams and others are not supported)");
        std::string f = formulation(p);
        const std::string mat = material(p);
        os << "  " << p.name << ":\n";
        if (!carried.count("generator"))
            os << "    generator: {type: keyword, file: \"" << mesh_file_ << "\", unit: " << u_.length_unit
               << ", pid: " << p.pid << "}\n";
        if (!carried.count("material"))
            os << "    material: " << mat << "\n";
        if (!carried.count("formulation"))
            os << "    formulation: " << (f == "rkpm-sl" ? "rkpm" : f) << "\n";
        if (f == "rkpm-sl" && !carried.count("kinematics"))
            os << "    kinematics: semi-lagrangian\n";
        hourglass(p, f, carried, os);
        if (const std::string e = erosion(p.mid); !e.empty() && !carried.count("erosion"))
            os << "    erosion: " << e << "\n";
        if (const auto it = part_velocity_.find(p.pid);
            it != part_velocity_.end() && !carried.count("initial_velocity"))
            os << "    initial_velocity: [" << it->second[0] << ", " << it->second[1] << ", " << it->second[2] << "]\n";
        if (const auto it = carried_part_.find(p.name); it != carried_part_.end())
        {
            for (const std::string& l : it->second)
                os << "    " << l << "\n";
            carried_used_.insert(p.name);
        }
    }
    for (const auto& [name, lines] : carried_part_)
        if (!carried_used_.count(name))
            throw DeckError({blocks_.front().file, "$rkfem parts." + name}, "names no part of the deck",
                            "expected the name of a *PART (its heading, lower-cased)");
    // the sets, conditions, loads and contacts rkfem's export carried whole ($rkfem lines, where one
    // of them had no keyword form) stand for what the cards say of them: those are not translated
    const bool carried_conditions = std::any_of(carried_top_.begin(), carried_top_.end(),
                                                [](const std::string& l)
                                                {
                                                    const std::string k = l.substr(0, l.find(':'));
                                                    return k == "node_sets" || k == "face_sets" ||
                                                           k == "boundary_conditions" || k == "loads" ||
                                                           k == "contacts";
                                                });
    std::ostringstream rest;
    if (!carried_conditions)
    {
        boundary_conditions(rest);
        loads(rest);
        contacts(rest);
    }
    if (!used_node_sets_.empty() || !extra_node_sets_.empty() || !plane_sets_.empty())
    {
        os << "node_sets:\n";
        for (const std::string& l : plane_sets_)
            os << l << "\n";
        for (long long sid : used_node_sets_)
        {
            os << "  nset_" << sid << ": {select: {type: ids, ids: [";
            const std::vector<long long>& ids = node_sets_.at(sid);
            for (std::size_t i = 0; i < ids.size(); ++i)
                os << (i ? ", " : "") << ids[i];
            os << "]}}\n";
        }
        for (const auto& [name, ids] : extra_node_sets_)
        {
            os << "  " << name << ": {select: {type: ids, ids: [";
            for (std::size_t i = 0; i < ids.size(); ++i)
                os << (i ? ", " : "") << ids[i];
            os << "]}}\n";
        }
    }
    if (!used_segment_sets_.empty())
    {
        os << "face_sets:\n";
        for (long long sid : used_segment_sets_)
        {
            os << "  sseg_" << sid << ": {select: {type: segments, segments: [";
            const auto& segs = segment_sets_.at(sid);
            for (std::size_t i = 0; i < segs.size(); ++i)
                os << (i ? ", " : "") << "[" << segs[i][0] << ", " << segs[i][1] << ", " << segs[i][2] << ", "
                   << segs[i][3] << "]";
            os << "]}}\n";
        }
    }
    os << rest.str();
    for (const std::string& l : carried_top_)
        os << l << "\n";
}

KeywordImport Importer::run(const std::string& path)
{
    blocks_ = read_keyword_blocks(path, {path, "(keyword file)"});
    for (const KeywordBlock& b : blocks_)
        file(b);
    read_carried(path);
    read_solids();
    resolve_general_sets();
    name_parts();
    std::ostringstream body;
    emit(body);
    std::ostringstream os;
    os << "# rkfem deck imported from " << path << " (units " << u_.name << "; every value SI)\n";
    for (const std::string& n : out_.notes)
        os << "# note: " << n << "\n";
    for (const std::string& s : out_.skipped)
        os << "# skipped (unsupported): " << s << "\n";
    os << body.str();
    out_.yaml = os.str();
    return out_;
}
} // namespace

KeywordUnits keyword_units(const std::string& name)
{
    static const KeywordUnits systems[] = {
        {"m-s-kg-N", 1.0, 1.0, 1.0, "m"},
        {"mm-ms-kg-kN", 1e-3, 1e-3, 1.0, "mm"},
        {"mm-s-t-N", 1e-3, 1.0, 1e3, "mm"},
        {"mm-ms-g-N", 1e-3, 1e-3, 1e-3, "mm"},
        {"cm-us-g-Mbar", 1e-2, 1e-6, 1e-3, "cm"},
        {"in-s-lbf-s2/in-lbf", kInch, 1.0, kPoundForce / kInch, "in"},
        {"ft-s-slug-lbf", 0.3048, 1.0, kPoundForce / 0.3048, "ft"},
    };
    const std::string n = name == "SI" || name == "si" ? "m-s-kg-N" : name == "in-s-lbf" ? "in-s-lbf-s2/in-lbf" : name;
    std::string names;
    for (const KeywordUnits& u : systems)
    {
        if (u.name == n)
            return u;
        names += (names.empty() ? "" : ", ") + u.name;
    }
    throw DeckError({"--units", name}, "--units " + name + " is not a known unit system", "expected one of " + names);
}

bool is_keyword_deck(const std::string& path)
{
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    return ext == ".k" || ext == ".key" || ext == ".dyn" || ext == ".kw";
}

KeywordImport import_keyword_deck(const std::string& path, const KeywordUnits& units, bool allow_unsupported,
                                  const std::string& mesh_file)
{
    Importer im(units, allow_unsupported, mesh_file);
    return im.run(path);
}
} // namespace rkfem
