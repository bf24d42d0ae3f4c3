// A built model as an LS-DYNA keyword deck (keyword_export.hpp): the inverse of
// config/keyword_deck.cpp on the subset both share, in m-s-kg-N with 17 significant digits.
#include "rkfem/io/keyword_export.hpp"

#include <algorithm>
#include <cstdio>
#include <map>
#include <set>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "rkfem/config/deck.hpp"
#include "rkfem/core/input_error.hpp"
#include "rkfem/model/model.hpp"

namespace rkfem
{
namespace
{
/// 17 significant digits: read back, the same double.
std::string g17(double v)
{
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    return buf;
}

/// A comma-separated card (a single field gets a comma too: without one, the card is read in fixed
/// 10-column fields and a 17-digit value would be cut)
std::string card(std::initializer_list<std::string> fields)
{
    std::string s;
    for (const std::string& f : fields)
        s += (s.empty() ? "" : ",") + f;
    if (fields.size() == 1)
        s += ",";
    return s + "\n";
}

std::string id(long long v)
{
    return std::to_string(v);
}

class Exporter
{
  public:
    explicit Exporter(const Model& m) : m_(m), d_(m.deck()) {}
    std::string run();

  private:
    const Model& m_;
    const Deck& d_;
    std::ostringstream os_;
    std::vector<std::string> dropped_;
    long long next_curve_ = 1, next_set_ = 1;
    std::map<std::string, long long> node_set_id_, segment_set_id_;
    /// what the keywords cannot say, carried whole as $rkfem lines: a part's keys, and the
    /// deck's sets, conditions, loads and contacts as one group (they name each other's sets)
    std::map<std::string, std::set<std::string>> carried_part_keys_;
    bool carry_conditions_ = false;
    void carry(const PartSpec& p, const std::string& key, const std::string& what)
    {
        carried_part_keys_[p.name].insert(key);
        dropped_.push_back("parts." + p.name + "." + key + ": " + what +
                           " has no keyword form: LS-DYNA reads the cards below, rkfem the $rkfem line");
    }
    template <class Write> void group(Write write);

    [[noreturn]] void refuse(const SourceLocation& loc, const std::string& key, const std::string& what) const
    {
        throw DeckError({loc.where, key}, what + " has no LS-DYNA keyword form here",
                        "expected a deck of meshed FE or RK parts with the settings docs/user/keyword-decks.md "
                        "lists (export)");
    }
    long long curve(const TimeFunction& f, const SourceLocation& loc, const std::string& key);
    long long node_set(const std::string& name);
    long long segment_set(const std::string& name);
    void controls();
    void part(std::size_t ip);
    void material(const PartSpec& p, long long pid);
    void erosion(const PartSpec& p, long long pid);
    void mesh();
    void conditions();
    void loads();
    void contacts();
    std::string carried() const;
};

/// One line of flow YAML.
std::string flow(const YAML::Node& n)
{
    YAML::Emitter e;
    e.SetMapFormat(YAML::Flow);
    e.SetSeqFormat(YAML::Flow);
    e << n;
    std::string s = e.c_str();
    for (char& c : s)
        if (c == '\n')
            c = ' ';
    return s;
}

/// The rkfem settings no keyword carries, as `$rkfem: KEY.PATH: VALUE` comment lines: LS-DYNA skips
/// them, the import puts each back where it was (the RK and nodal-integration settings of RK parts,
/// the stepper, outputs, probes, sections, impact and spall measures), so the round trip keeps them.
std::string Exporter::carried() const
{
    const YAML::Node r = YAML::Load(to_yaml(d_, 17)); // 17 digits: the same doubles read back
    std::ostringstream os;
    static const std::set<std::string> by_keywords = {"generator",      "material",         "formulation", "hourglass",
                                                      "bulk_viscosity", "initial_velocity", "erosion"};
    for (const PartSpec& p : d_.parts)
    {
        const auto carried_keys = carried_part_keys_.find(p.name);
        for (const auto& kv : r["parts"][p.name])
            if (const std::string key = kv.first.as<std::string>();
                !by_keywords.count(key) ||
                (carried_keys != carried_part_keys_.end() && carried_keys->second.count(key)))
                os << "$rkfem: parts." << p.name << "." << key << ": " << flow(kv.second) << "\n";
    }
    const TimeSpec def;
    const TimeSpec& t = d_.time;
    const YAML::Node time = r["time"];
    const std::pair<const char*, bool> differs[] = {
        {"stepper", t.stepper != def.stepper},
        {"dt_max", t.dt_max != def.dt_max},
        {"energy_error_limit", t.energy_error_limit != def.energy_error_limit},
        {"mass_damping", t.mass_damping != def.mass_damping}};
    for (const auto& [key, changed] : differs)
        if (changed)
            os << "$rkfem: time." << key << ": " << flow(time[key]) << "\n";
    if (t.stepper == StepperKind::ArkodeErk)
        os << "$rkfem: time.erk_table: " << flow(time["erk_table"]) << "\n";
    for (const char* key : {"output", "probes", "sections", "impact", "spall"})
        if (r[key])
            os << "$rkfem: " << key << ": " << flow(r[key]) << "\n";
    if (carry_conditions_)
    {
        // a set a generator named (a cylinder's side) is no name of the imported mesh: a set on a
        // meshed part goes by the file's node numbers (ids) or faces (segments); a cloud's as written
        auto on_cloud = [&](const SetSpec& set)
        {
            for (const PartSpec& p : d_.parts)
                if (p.generator.type == GeneratorSpec::Type::Cloud && (set.part.empty() || set.part == p.name))
                    return true;
            return false;
        };
        for (const char* key : {"node_sets", "face_sets"})
        {
            const bool faces = std::string(key) == "face_sets";
            YAML::Node sets = r[key];
            for (const SetSpec& set : faces ? d_.face_sets : d_.node_sets)
            {
                if (on_cloud(set) || set.select.type != SelectorSpec::Type::Named)
                    continue;
                YAML::Node select(YAML::NodeType::Map);
                if (faces)
                {
                    select["type"] = "segments";
                    YAML::Node segs(YAML::NodeType::Sequence);
                    for (const Quad& q : m_.face_sets.at(set.name))
                    {
                        YAML::Node seg(YAML::NodeType::Sequence);
                        for (const index_t n : q)
                            seg.push_back(static_cast<long long>(n) + 1);
                        segs.push_back(seg);
                    }
                    select["segments"] = segs;
                }
                else
                {
                    select["type"] = "ids";
                    YAML::Node ids(YAML::NodeType::Sequence);
                    for (const index_t n : m_.node_sets.at(set.name))
                        ids.push_back(static_cast<long long>(n) + 1);
                    select["ids"] = ids;
                }
                sets[set.name]["select"] = select;
            }
        }
        for (const char* key : {"node_sets", "face_sets", "boundary_conditions", "loads", "contacts"})
            if (r[key])
                os << "$rkfem: " << key << ": " << flow(r[key]) << "\n";
    }
    return os.str();
}

long long Exporter::curve(const TimeFunction& f, const SourceLocation& loc, const std::string& key)
{
    const long long lcid = next_curve_++;
    std::ostringstream c;
    // SFA = SFO = 1: the function's scale goes in the SF field of the card that uses the curve, so
    // that the imported function multiplies as the deck's does (same bits)
    c << "*DEFINE_CURVE\n" << card({id(lcid), "0", "1.0", "1.0"});
    switch (f.kind)
    {
    case TimeFunction::Kind::Constant:
        c << card({"0", g17(f.value)}) << card({g17(d_.time.end > 0 ? d_.time.end : 1.0), g17(f.value)});
        break;
    case TimeFunction::Kind::Table:
        for (std::size_t i = 0; i < f.times.size(); ++i)
            c << card({g17(f.times[i]), g17(f.values[i])});
        break;
    case TimeFunction::Kind::Triangular:
        refuse(loc, key, "a triangular pulse (a jump at its start)");
    }
    os_ << c.str();
    return lcid;
}

/// A node list's cards: the NIDs (model index + 1), eight to a card.
void write_node_ids(std::ostream& os, const std::vector<index_t>& ids)
{
    for (std::size_t i = 0; i < ids.size(); i += 8)
    {
        std::string line;
        for (std::size_t k = i; k < std::min(ids.size(), i + 8); ++k)
        {
            if (k > i)
                line += ',';
            line += id(ids[k] + 1);
        }
        os << line << "\n";
    }
}

long long Exporter::node_set(const std::string& name)
{
    if (const auto it = node_set_id_.find(name); it != node_set_id_.end())
        return it->second;
    const long long sid = next_set_++;
    node_set_id_[name] = sid;
    os_ << "*SET_NODE_LIST_TITLE\n" << name << "\n" << card({id(sid)});
    write_node_ids(os_, m_.node_sets.at(name));
    return sid;
}

long long Exporter::segment_set(const std::string& name)
{
    if (const auto it = segment_set_id_.find(name); it != segment_set_id_.end())
        return it->second;
    const long long sid = next_set_++;
    segment_set_id_[name] = sid;
    os_ << "*SET_SEGMENT_TITLE\n" << name << "\n" << card({id(sid)});
    for (const Quad& q : m_.face_sets.at(name))
        os_ << card({id(q[0] + 1), id(q[1] + 1), id(q[2] + 1), id(q[3] + 1)});
    return sid;
}

void Exporter::controls()
{
    const TimeSpec& t = d_.time;
    os_ << "*CONTROL_TERMINATION\n" << card({g17(t.end), id(t.max_steps), g17(t.dt_min_fraction)});
    os_ << "*CONTROL_TIMESTEP\n" << card({"0", g17(t.dt_scale)});
    if (t.output_interval > 0)
        os_ << "*DATABASE_BINARY_D3PLOT\n" << card({g17(t.output_interval)});
    if (t.history_interval > 0)
        os_ << "*DATABASE_GLSTAT\n" << card({g17(t.history_interval)});
    if (t.dt_min_fraction == 0.0)
        dropped_.push_back("time.dt_min_fraction 0 is written as DTMIN 0, which the import reads as the default");
}

void Exporter::material(const PartSpec& p, long long pid)
{
    const MaterialSpec& m = p.material;
    const std::string at = "parts." + p.name + ".material";
    long long eosid = 0;
    if (m.model == "elastic")
        os_ << "*MAT_ELASTIC\n" << card({id(pid), g17(m.rho), g17(m.E), g17(m.nu)});
    else if (m.model == "j2")
    {
        if (!m.curve.empty())
        {
            TimeFunction ss; // the curve as (eps_p, sigma_y) points
            ss.kind = TimeFunction::Kind::Table;
            for (const auto& [e, s] : m.curve)
            {
                ss.times.push_back(e);
                ss.values.push_back(s);
            }
            const long long lcss = curve(ss, m.loc, at + ".curve");
            os_ << "*MAT_PIECEWISE_LINEAR_PLASTICITY\n"
                << card({id(pid), g17(m.rho), g17(m.E), g17(m.nu), "0", "0", g17(m.fail)})
                << card({g17(m.cs_c), g17(m.cs_p), id(lcss)});
        }
        else
            os_ << "*MAT_PLASTIC_KINEMATIC\n"
                << card({id(pid), g17(m.rho), g17(m.E), g17(m.nu), g17(m.sigy), g17(m.etan), "1.0"})
                << card({g17(m.cs_c), g17(m.cs_p), g17(m.fail)});
        if (m.eos_type == "gruneisen")
        {
            eosid = pid;
            os_ << "*EOS_GRUNEISEN\n"
                << card({id(pid), g17(m.eos_c0), g17(m.eos_s), "0", "0", g17(m.eos_gamma0), g17(m.eos_a)});
        }
        else if (!m.eos_type.empty() && m.eos_type != "linear")
            carry(p, "material", "EOS type " + m.eos_type);
    }
    else if (m.model == "kcc")
    {
        if (!m.overrides.empty() || !m.kcc_eta.empty() || !m.kcc_eos_strain.empty())
            carry(p, "material", "a K&C material with user-set parameters (the card below is the generated set)");
        else if (m.fracture_energy != 0.0)
            carry(p, "material",
                  "a K&C material's fracture_energy (crack-band softening; MAT_072R3's LOCWIDTH is a width)");
        long long lcrate = 0;
        if (m.rate_law.kind == RateLaw::Kind::CebMalvarRoss)
        {
            const RateLaw std_law = RateLaw::standard(m.fc);
            if (m.rate_law.compression_cap != std_law.compression_cap || m.rate_law.tension_cap != std_law.tension_cap)
                carry(p, "material", "a rate law with caps other than the default");
            lcrate = -1;
        }
        else if (m.rate_law.kind == RateLaw::Kind::Curve)
        {
            if (m.rate_law.compression_cap != 0.0 || m.rate_law.tension_cap != 0.0)
                carry(p, "material", "a rate curve with caps");
            TimeFunction c;
            c.kind = TimeFunction::Kind::Table;
            for (const auto& [r, dif] : m.rate_law.curve)
            {
                c.times.push_back(r);
                c.values.push_back(dif);
            }
            lcrate = curve(c, m.loc, at + ".rate_effects");
        }
        os_ << "*MAT_CONCRETE_DAMAGE_REL3\n"
            << card({id(pid), g17(m.rho), g17(m.nu)}) << card({"0", g17(-m.fc)})
            << card({"0", "0", "0", "0", "0", id(lcrate)});
        dropped_.push_back(at + ": E and fracture_energy are not written (LS-DYNA generates them from f'c as rkfem "
                                "does by default)");
    }
    else if (m.model == "cscm")
    {
        if (!m.overrides.empty())
            carry(p, "material", "a CSCM material with user-set parameters (the card below is the generated set)");
        os_ << "*MAT_CSCM_CONCRETE\n"
            << card({id(pid), g17(m.rho), "0", "0", m.rate_effects ? "1" : "0"}) << card({"0"})
            << card({g17(m.fc), g17(0.019), "0"});
    }
    else
        refuse(m.loc, at + ".model", "material model " + m.model);
    // the part card comes after its material so that the EOS ID is known
    const int ihq = p.hourglass.type == HourglassType::Viscous         ? 3
                    : p.hourglass.type == HourglassType::ViscousPlain  ? 1
                    : p.hourglass.type == HourglassType::Stiffness     ? 5
                    : p.hourglass.type == HourglassType::AssumedStrain ? 6
                                                                       : 0;
    if (ihq == 0 && p.formulation == Formulation::Fem1pt)
        carry(p, "hourglass", "hourglass type none (written as IHQ 3)");
    const HourglassSpec def;
    if ((p.hourglass.type == HourglassType::Stiffness && p.hourglass.plastic_scaling) ||
        (p.hourglass.type == HourglassType::AssumedStrain && !p.hourglass.plastic_scaling))
        dropped_.push_back("parts." + p.name + ".hourglass.plastic_scaling (IHQ 5 is read without it, IHQ 6 with)");
    // LS-DYNA reads a Q1 or Q2 of 0 as its default
    if (p.bulk_viscosity.linear == 0.0 || p.bulk_viscosity.quadratic == 0.0)
        carry(p, "bulk_viscosity", "a bulk viscosity coefficient of 0 (LS-DYNA reads 0 as its default)");
    os_ << "*HOURGLASS\n"
        << card({id(pid), id(ihq == 0 ? 3 : ihq), g17(p.hourglass.coefficient), "0", g17(p.bulk_viscosity.quadratic),
                 g17(p.bulk_viscosity.linear)});
    os_ << "*PART\n" << p.name << "\n" << card({id(pid), id(pid), id(pid), id(eosid), id(pid)});
}

void Exporter::erosion(const PartSpec& p, long long pid)
{
    const ElementCriteria& e = p.erosion;
    if (!e.active())
        return;
    if (e.damage > 0 || e.time_step > 0 || e.scaled_jacobian > 0 || e.aspect_ratio > 0)
    {
        carry(p, "erosion", "erosion by damage, time step or element shape (the card below has the other criteria)");
        if (!(e.plastic_strain > 0 || e.volumetric_strain > 0 || e.principal_strain > 0))
            return;
    }
    os_ << "*MAT_ADD_EROSION\n"
        << card({id(pid), "0", "0", "0", g17(e.plastic_strain), g17(e.volumetric_strain)})
        << card({"0", "0", "0", g17(e.principal_strain)});
}

void Exporter::part(std::size_t ip)
{
    const PartSpec& p = d_.parts[ip];
    const long long pid = static_cast<long long>(ip) + 1;
    const std::string at = "parts." + p.name;
    if (p.generator.type == GeneratorSpec::Type::Cloud)
    {
        // its sets select particles that the import makes anew: the sets and what names them go too
        carry(p, "generator", "a particle cloud (its particles are nodes without solids here)");
        carry_conditions_ = true;
    }
    if (p.formulation == Formulation::FemNodal)
        carry(p, "formulation", "formulation fem-nodal (written as ELFORM 1)");
    const int elform = p.formulation == Formulation::Fem1pt || p.formulation == Formulation::FemNodal ? 1
                       : p.formulation == Formulation::Fem2x2x2                                       ? 2
                       : p.semi_lagrangian                                                            ? 47
                                                                                                      : 41;
    os_ << "*SECTION_SOLID\n" << card({id(pid), id(elform)});
    material(p, pid);
    erosion(p, pid);
    if (p.initial_velocity != Vec3::Zero())
        os_ << "*INITIAL_VELOCITY_GENERATION\n"
            << card({id(pid), "2", "0", g17(p.initial_velocity[0]), g17(p.initial_velocity[1]),
                     g17(p.initial_velocity[2])})
            << card({"0", "0", "0", "0", "0", "0"});
}

void Exporter::mesh()
{
    os_ << "*NODE\n";
    for (index_t i = 0; i < m_.nodes.size(); ++i)
        os_ << card({id(i + 1), g17(m_.nodes.x0[3 * i]), g17(m_.nodes.x0[3 * i + 1]), g17(m_.nodes.x0[3 * i + 2])});
    os_ << "*ELEMENT_SOLID\n";
    long long eid = 1;
    for (const HexBlock& b : m_.meshes)
        for (index_t e = 0; e < b.n_elements(); ++e)
        {
            std::string line = id(eid++) + "," + id(b.part + 1);
            for (int a = 0; a < 8; ++a)
            {
                line += ',';
                line += id(b.conn[8 * static_cast<std::size_t>(e) + a] + 1);
            }
            os_ << line << "\n";
        }
}

void Exporter::conditions()
{
    for (const BoundarySpec& b : d_.boundary_conditions)
        group(
            [&]
            {
                const long long sid = node_set(b.node_set);
                if (b.kind == BoundarySpec::Kind::Fixed)
                {
                    os_ << "*BOUNDARY_SPC_SET\n"
                        << card({id(sid), "0", b.active[0] ? "1" : "0", b.active[1] ? "1" : "0",
                                 b.active[2] ? "1" : "0"});
                    return;
                }
                for (int k = 0; k < 3; ++k)
                    if (b.active[static_cast<std::size_t>(k)])
                    {
                        const long long lcid =
                            curve(b.value[static_cast<std::size_t>(k)], b.loc, "boundary_conditions");
                        os_ << "*BOUNDARY_PRESCRIBED_MOTION_SET\n"
                            << card({id(sid), id(k + 1), b.kind == BoundarySpec::Kind::Velocity ? "0" : "2", id(lcid),
                                     g17(b.value[static_cast<std::size_t>(k)].scale)});
                    }
            });
}

void Exporter::loads()
{
    for (const LoadSpec& l : d_.loads)
        group(
            [&]
            {
                if (l.kind == LoadSpec::Kind::Pressure)
                {
                    if (!m_.cloud_face_sets.at(l.set).empty())
                        refuse(l.loc, "loads", "a pressure on a particle cloud's facets");
                    const long long sid = segment_set(l.set);
                    const long long lcid = curve(l.pressure, l.loc, "loads.pressure");
                    os_ << "*LOAD_SEGMENT_SET\n" << card({id(sid), id(lcid), g17(l.pressure.scale)});
                    return;
                }
                // LS-DYNA applies the force to each node: a total splits by the scale factor
                const long long sid = node_set(l.set);
                const double share = l.total ? 1.0 / static_cast<double>(m_.node_sets.at(l.set).size()) : 1.0;
                if (l.total)
                    dropped_.push_back("loads: the total force on " + l.set + " is written per node, SF = scale / " +
                                       std::to_string(m_.node_sets.at(l.set).size()) + " (equal to round-off)");
                for (int k = 0; k < 3; ++k)
                    if (l.active[static_cast<std::size_t>(k)])
                    {
                        const long long lcid = curve(l.force[static_cast<std::size_t>(k)], l.loc, "loads.force");
                        os_ << "*LOAD_NODE_SET\n"
                            << card({id(sid), id(k + 1), id(lcid),
                                     g17(l.force[static_cast<std::size_t>(k)].scale * share)});
                    }
            });
}

void Exporter::contacts()
{
    auto pid_of = [&](const std::string& name) -> long long
    {
        for (std::size_t i = 0; i < d_.parts.size(); ++i)
            if (d_.parts[i].name == name)
                return static_cast<long long>(i) + 1;
        return 0;
    };
    for (const ContactSpec& c : d_.contacts)
        group(
            [&]
            {
                const ContactSpec def;
                if (c.kind == ContactSpec::Kind::Kernel)
                    refuse(c.loc, "contacts.type", "kernel contact");
                if (c.mortar || c.thickness != def.thickness || c.max_penetration != def.max_penetration)
                    refuse(c.loc, "contacts", "mortar contact, a thickness or max_penetration other than the default");
                const std::string friction = c.mu_static > 0 ? g17(c.mu_static) : "0";
                if (c.kind == ContactSpec::Kind::RigidWall)
                {
                    if (c.velocity != Vec3::Zero() || c.damping != 0.0 || c.penalty_scale != def.penalty_scale ||
                        (c.mu_dynamic != c.mu_static) || c.decay != 0.0)
                        refuse(c.loc, "contacts",
                               "a moving, damped or stiffened rigid wall, or one with dynamic friction");
                    // the wall's nodes: every node of its parts
                    std::vector<index_t> ids;
                    for (std::size_t ip = 0; ip < m_.parts.size(); ++ip)
                        if (c.surfaces.empty() ||
                            std::find(c.surfaces.begin(), c.surfaces.end(), m_.parts[ip].name) != c.surfaces.end())
                            for (index_t n = m_.parts[ip].node_begin; n < m_.parts[ip].node_end; ++n)
                                ids.push_back(n);
                    const long long sid = next_set_++;
                    os_ << "*SET_NODE_LIST\n" << card({id(sid)});
                    write_node_ids(os_, ids);
                    const Vec3 h = c.point + c.normal;
                    os_ << "*RIGIDWALL_PLANAR\n"
                        << card({id(sid)})
                        << card({g17(c.point[0]), g17(c.point[1]), g17(c.point[2]), g17(h[0]), g17(h[1]), g17(h[2]),
                                 friction});
                    return;
                }
                // a side: a part (3) or a face set (0); single surface: a part set (2) or all (5)
                auto side = [&](const std::string& name, long long& typ) -> long long
                {
                    if (const long long pid = pid_of(name); pid > 0)
                    {
                        typ = 3;
                        return pid;
                    }
                    typ = 0;
                    return segment_set(name);
                };
                long long sstyp = 5, mstyp = 0, ssid = 0, msid = 0;
                std::string kw = "*CONTACT_AUTOMATIC_SINGLE_SURFACE";
                if (c.kind == ContactSpec::Kind::SurfaceToSurface)
                {
                    kw = "*CONTACT_AUTOMATIC_SURFACE_TO_SURFACE";
                    ssid = side(c.surfaces[0], sstyp);
                    msid = side(c.surfaces[1], mstyp);
                }
                else if (!c.surfaces.empty())
                {
                    ssid = next_set_++;
                    sstyp = 2;
                    std::string line;
                    for (const std::string& s : c.surfaces)
                    {
                        const long long pid = pid_of(s);
                        if (pid == 0)
                            refuse(c.loc, "contacts.surfaces", "a single-surface contact on a face set");
                        if (!line.empty())
                            line += ',';
                        line += id(pid);
                    }
                    os_ << "*SET_PART_LIST\n" << card({id(ssid)}) << line << "\n";
                }
                const double factor = c.penalty_scale / 0.1;
                os_ << kw << "\n"
                    << card({id(ssid), id(msid), id(sstyp), id(mstyp)})
                    << card({friction, c.mu_static > 0 ? g17(c.mu_dynamic) : "0", g17(c.decay), "0",
                             g17(100.0 * c.damping)})
                    << card({g17(factor), g17(factor)}) << card({c.soft ? "1" : "0", g17(c.soft_scale)});
                if (c.penalty_scale != def.penalty_scale)
                    dropped_.push_back("contacts: penalty_scale " + g17(c.penalty_scale) +
                                       " is written as SFS = SFM = " + g17(factor) +
                                       " (times SLSFAC 0.1 on import: equal to round-off)");
            });
}

/// Writes one of the groups that name sets (conditions, loads, contacts); where one of them has no
/// keyword form, what it wrote is taken back and the whole group of sets, conditions, loads and
/// contacts is carried as $rkfem lines instead (the keywords keep what they can say, for LS-DYNA)
template <class Write> void Exporter::group(Write write)
{
    // where the output stood (the text itself is copied back only when an item fails: the mesh
    // cards before it may be hundreds of MB)
    const std::streamoff before = os_.tellp();
    const std::size_t notes = dropped_.size();
    const auto nodes = node_set_id_, segments = segment_set_id_;
    const long long sets = next_set_, curves = next_curve_;
    try
    {
        write();
    }
    catch (const DeckError& e)
    {
        std::string kept = os_.str();
        kept.resize(static_cast<std::size_t>(before));
        os_.str(kept);
        os_.seekp(0, std::ios_base::end);
        dropped_.resize(notes);
        node_set_id_ = nodes;
        segment_set_id_ = segments;
        next_set_ = sets;
        next_curve_ = curves;
        if (!carry_conditions_)
            dropped_.push_back(std::string(e.what()).substr(0, std::string(e.what()).find(" has no LS-DYNA")) +
                               " has no keyword form: the deck's sets, conditions, loads and contacts are carried "
                               "whole on $rkfem lines (rkfem reads those; LS-DYNA the cards below, without it)");
        carry_conditions_ = true;
    }
}

std::string Exporter::run()
{
    os_ << "*TITLE\n" << (d_.title.empty() ? "rkfem export" : d_.title) << "\n";
    controls();
    for (std::size_t ip = 0; ip < d_.parts.size(); ++ip)
        part(ip);
    mesh();
    conditions();
    loads();
    contacts();
    std::ostringstream head;
    head << "*KEYWORD\n$ exported by rkfem from " << d_.path << " (units m-s-kg-N: rkfem run FILE --units m-s-kg-N)\n";
    for (const std::string& s : dropped_)
        head << "$ note: " << s << "\n";
    head << "$ rkfem settings with no keyword, read back by rkfem's import (LS-DYNA skips them):\n" << carried();
    return head.str() + os_.str() + "*END\n";
}
} // namespace

std::string export_keyword_deck(const Model& model)
{
    return Exporter(model).run();
}
} // namespace rkfem
