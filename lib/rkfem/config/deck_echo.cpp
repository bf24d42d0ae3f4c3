#include <cctype>
#include <cstdio>
#include <sstream>

#include "rkfem/config/deck.hpp"

namespace rkfem
{
namespace
{
/// Significant digits of the echoed values (to_yaml's digits; 10 by default, 17 to read back the same
/// doubles)
thread_local int echo_digits = 10;

/// A string as a YAML scalar that reads back as the same string: plain when it is a simple name
/// (letters, digits, _ . - / not starting with a digit, - or .) and `quoted` is false; otherwise
/// double-quoted, with backslash, quote and control characters escaped.
std::string scalar(const std::string& s, bool quoted = false)
{
    bool plain =
        !quoted && !s.empty() && (std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_' || s[0] == '/');
    for (const char c : s)
        plain = plain && (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.' || c == '-' || c == '/');
    static const char* const reserved[] = {"true", "false", "yes", "no", "on", "off", "null", "y", "n"};
    for (const char* r : reserved)
    {
        std::string lower = s;
        for (char& c : lower)
            c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        plain = plain && lower != r;
    }
    if (plain)
        return s;
    std::string out = "\"";
    for (const char c : s)
    {
        const auto u = static_cast<unsigned char>(c);
        if (c == '"' || c == '\\')
            out += std::string("\\") + c;
        else if (u < 0x20 || u == 0x7f)
        {
            char buf[8];
            std::snprintf(buf, sizeof buf, "\\x%02x", u);
            out += buf;
        }
        else
            out += c;
    }
    return out + "\"";
}

std::string vec(const Vec3& v)
{
    std::ostringstream os;
    os.precision(echo_digits);
    os << "[" << v[0] << ", " << v[1] << ", " << v[2] << "]";
    return os.str();
}

std::string fn(const TimeFunction& f)
{
    std::ostringstream os;
    os.precision(echo_digits);
    switch (f.kind)
    {
    case TimeFunction::Kind::Constant:
        os << f.value * f.scale;
        break;
    case TimeFunction::Kind::Triangular:
        os << "{triangular: {peak: " << f.peak << ", duration: " << f.duration << ", start: " << f.start
           << "}, scale: " << f.scale << "}";
        break;
    case TimeFunction::Kind::Table:
        os << "{curve: [";
        for (std::size_t i = 0; i < f.times.size(); ++i)
            os << (i ? ", " : "") << "[" << f.times[i] << ", " << f.values[i] << "]";
        os << "], scale: " << f.scale << "}";
        break;
    }
    return os.str();
}

const char* selector_name(SelectorSpec::Type t)
{
    switch (t)
    {
    case SelectorSpec::Type::Named:
        return "named";
    case SelectorSpec::Type::Plane:
        return "plane";
    case SelectorSpec::Type::Box:
        return "box";
    case SelectorSpec::Type::Cylinder:
        return "cylinder";
    case SelectorSpec::Type::Sphere:
        return "sphere";
    case SelectorSpec::Type::Ids:
        return "ids";
    case SelectorSpec::Type::Segments:
        return "segments";
    }
    return "?";
}

void selector(std::ostringstream& os, const SelectorSpec& sel)
{
    os << "select: {type: " << selector_name(sel.type);
    switch (sel.type)
    {
    case SelectorSpec::Type::Named:
        os << ", name: " << scalar(sel.name);
        break;
    case SelectorSpec::Type::Plane:
        os << ", point: " << vec(sel.point) << ", normal: " << vec(sel.normal);
        break;
    case SelectorSpec::Type::Box:
        os << ", min: " << vec(sel.min) << ", max: " << vec(sel.max);
        break;
    case SelectorSpec::Type::Cylinder:
        os << ", point: " << vec(sel.point) << ", axis: " << vec(sel.normal) << ", radius: " << sel.radius;
        break;
    case SelectorSpec::Type::Sphere:
        os << ", point: " << vec(sel.point) << ", radius: " << sel.radius;
        break;
    case SelectorSpec::Type::Ids:
    {
        os << ", ids: [";
        for (std::size_t i = 0; i < sel.ids.size(); ++i)
            os << (i ? ", " : "") << sel.ids[i];
        os << "]";
        break;
    }
    case SelectorSpec::Type::Segments:
    {
        os << ", segments: [";
        for (std::size_t i = 0; i < sel.segments.size(); ++i)
        {
            const auto& g = sel.segments[i];
            os << (i ? ", " : "") << "[" << g[0] << ", " << g[1] << ", " << g[2] << ", " << g[3] << "]";
        }
        os << "]";
        break;
    }
    }
    if (sel.tolerance >= 0)
        os << ", tolerance: " << sel.tolerance;
    os << "}";
}

void sets(std::ostringstream& os, const char* key, const std::vector<SetSpec>& v)
{
    if (v.empty())
        return;
    os << key << ":\n";
    for (const auto& s : v)
    {
        os << "  " << scalar(s.name) << ": {";
        if (!s.part.empty())
            os << "part: " << scalar(s.part) << ", ";
        selector(os, s.select);
        os << "}\n";
    }
}

void components(std::ostringstream& os, const std::array<bool, 3>& active, const std::array<TimeFunction, 3>& f)
{
    os << "{";
    bool first = true;
    for (int k = 0; k < 3; ++k)
        if (active[k])
        {
            os << (first ? "" : ", ") << "xyz"[k] << ": " << fn(f[k]);
            first = false;
        }
    os << "}";
}

/// Writes the header comment, the title and the time and output settings.
void write_header(std::ostringstream& os, const Deck& d)
{
    os << "# resolved deck, SI units (kg, m, s, N, Pa)\n";
    os << "title: " << scalar(d.title, true) << "\n";
    os << "time: {end: " << d.time.end << ", output_interval: " << d.time.output_interval
       << ", history_interval: " << d.time.history_interval << ", dt_scale: " << d.time.dt_scale
       << ", dt_max: " << d.time.dt_max << ", max_steps: " << d.time.max_steps << ", stepper: "
       << (d.time.stepper == StepperKind::ArkodeCd    ? "arkode-cd"
           : d.time.stepper == StepperKind::ArkodeErk ? "arkode-erk"
                                                      : "central-difference")
       << (d.time.stepper == StepperKind::ArkodeErk ? ", erk_table: " + d.time.erk_table : std::string())
       << ", energy_error_limit: " << d.time.energy_error_limit << ", dt_min_fraction: " << d.time.dt_min_fraction
       << ", mass_damping: " << d.time.mass_damping << "}\n";
    os << "output: {precision: " << (d.output.single ? "single" : "double") << ", compression: " << d.output.compression
       << "}\n";
}

/// Writes a part's generator line: its type and geometry.
void write_generator(std::ostringstream& os, const GeneratorSpec& g)
{
    os << "    generator: {";
    switch (g.type)
    {
    case GeneratorSpec::Type::Box:
        os << "type: box, origin: " << vec(g.origin) << ", size: " << vec(g.size);
        if (g.divisions[0] > 0)
            os << ", divisions: [" << g.divisions[0] << ", " << g.divisions[1] << ", " << g.divisions[2] << "]";
        else
            os << ", element_size: " << g.element_size;
        break;
    case GeneratorSpec::Type::Cylinder:
        os << "type: cylinder, origin: " << vec(g.origin) << ", radius: " << g.radius << ", height: " << g.height
           << ", element_size: " << g.element_size;
        if (g.inner_radius > 0)
            os << ", inner_radius: " << g.inner_radius;
        else
            os << ", core: " << g.core;
        break;
    case GeneratorSpec::Type::Projectile:
        os << "type: projectile, origin: " << vec(g.origin) << ", radius: " << g.radius << ", length: " << g.height
           << ", element_size: " << g.element_size << ", direction: " << (g.direction < 0 ? "-z" : "+z");
        break;
    case GeneratorSpec::Type::Cloud:
        if (g.body == GeneratorSpec::Body::Box)
            os << "type: cloud, origin: " << vec(g.origin) << ", size: " << vec(g.size);
        else
            os << "type: cloud, body: cylinder, origin: " << vec(g.origin) << ", radius: " << g.radius
               << ", height: " << g.height;
        if (g.points_file.empty())
            os << ", spacing: " << g.element_size << ", jitter: " << g.jitter << ", seed: " << g.seed;
        else
            os << ", points: " << scalar(g.points_file) << ", points_unit: " << g.points_unit_name;
        break;
    case GeneratorSpec::Type::Gmsh:
        os << "type: gmsh, file: " << scalar(g.mesh_file) << ", unit: " << g.mesh_unit_name;
        if (!g.mesh_groups.empty())
        {
            os << ", physical: [";
            for (std::size_t i = 0; i < g.mesh_groups.size(); ++i)
                os << (i ? ", " : "") << scalar(g.mesh_groups[i]);
            os << "]";
        }
        break;
    case GeneratorSpec::Type::Keyword:
        os << "type: keyword, file: " << scalar(g.mesh_file) << ", unit: " << g.mesh_unit_name;
        if (!g.mesh_pids.empty())
        {
            os << ", pid: [";
            for (std::size_t i = 0; i < g.mesh_pids.size(); ++i)
                os << (i ? ", " : "") << g.mesh_pids[i];
            os << "]";
        }
        break;
    }
    os << "}\n";
}

/// Writes a j2 material's keys: hardening (curve or sigy, etan), Cowper-Symonds, fail and EOS.
void write_j2(std::ostringstream& os, const MaterialSpec& m)
{
    if (!m.curve.empty())
    {
        os << ", curve: [";
        for (std::size_t i = 0; i < m.curve.size(); ++i)
            os << (i ? ", " : "") << "[" << m.curve[i].first << ", " << m.curve[i].second << "]";
        os << "]";
    }
    else
        os << ", sigy: " << m.sigy << ", etan: " << m.etan;
    if (m.cs_c > 0)
        os << ", cowper_symonds: {C: " << m.cs_c << ", P: " << m.cs_p << "}";
    os << ", fail: " << m.fail;
    if (m.eos_type == "linear")
        os << ", eos: {type: linear}";
    else if (m.eos_type == "gruneisen")
        os << ", eos: {type: gruneisen, c0: " << m.eos_c0 << ", s: " << m.eos_s << ", gamma0: " << m.eos_gamma0
           << ", a: " << m.eos_a << "}";
}

/// Writes a kcc or cscm material's keys: fc, rate effects, fracture energy, overrides, eta and EOS tables.
void write_concrete(std::ostringstream& os, const MaterialSpec& m)
{
    os << ", fc: " << m.fc << ", rate_effects: ";
    const RateLaw& rl = m.rate_law;
    auto caps = [&]
    {
        os << "compression_cap: ";
        rl.compression_cap > 0.0 ? os << rl.compression_cap : os << "none";
        os << ", tension_cap: ";
        rl.tension_cap > 0.0 ? os << rl.tension_cap : os << "none";
        os << "}";
    };
    if (m.model == "cscm" || !rl.active())
        os << (m.rate_effects ? "true" : "false");
    else if (rl.kind == RateLaw::Kind::CebMalvarRoss)
    {
        os << "{law: ceb-fip, ";
        caps();
    }
    else
    {
        os << "{curve: [";
        for (std::size_t i = 0; i < rl.curve.size(); ++i)
            os << (i ? ", " : "") << "[" << rl.curve[i].first << ", " << rl.curve[i].second << "]";
        os << "], ";
        caps();
    }
    if (m.fracture_energy < 0)
        os << ", fracture_energy: auto";
    else
        os << ", fracture_energy: " << m.fracture_energy;
    for (const auto& [k, v] : m.overrides)
        os << ", " << k << ": " << v;
    if (!m.kcc_eta.empty())
    {
        os << ", eta: [";
        for (std::size_t i = 0; i < m.kcc_eta.size(); ++i)
            os << (i ? ", " : "") << "[" << m.kcc_eta[i].first << ", " << m.kcc_eta[i].second << "]";
        os << "]";
    }
    if (!m.kcc_eos_strain.empty())
    {
        auto list = [&](const std::vector<real_t>& v)
        {
            os << "[";
            for (std::size_t i = 0; i < v.size(); ++i)
                os << (i ? ", " : "") << v[i];
            os << "]";
        };
        os << ", eos: {strain: ";
        list(m.kcc_eos_strain);
        os << ", pressure: ";
        list(m.kcc_eos_pressure);
        os << ", unload_bulk: ";
        list(m.kcc_eos_unload);
        os << "}";
    }
}

/// Writes a part's material line.
void write_material(std::ostringstream& os, const MaterialSpec& m)
{
    os << "    material: {model: " << m.model << ", rho: " << m.rho << ", E: " << m.E << ", nu: " << m.nu;
    if (m.model == "j2")
        write_j2(os, m);
    if (m.model == "kcc" || m.model == "cscm")
        write_concrete(os, m);
    os << "}\n";
}

/// Writes a part's formulation and its options: nodal integration, regions, transition, rk, hourglass, bulk
/// viscosity, initial velocity, erosion and conversion.
void write_part_options(std::ostringstream& os, const PartSpec& p)
{
    os << "    formulation: "
       << (p.formulation == Formulation::Fem1pt     ? "fem-1pt"
           : p.formulation == Formulation::Fem2x2x2 ? "fem-2x2x2"
           : p.formulation == Formulation::FemNodal ? "fem-nodal"
                                                    : "rkpm")
       << "\n";
    if (p.semi_lagrangian)
        os << "    kinematics: semi-lagrangian\n    semi_lagrangian: {neighbour_skin: " << p.neighbour_skin
           << ", reset_interval: " << p.reset_interval << ", separation_damage: " << p.separation_damage
           << ", plastic_scaling: " << (p.sl_plastic_scaling ? "true" : "false") << "}\n";
    if (is_nodal(p.formulation) || p.coupled() || p.semi_lagrangian)
        os << "    nodal_integration: {scheme: " << p.nodal.scheme << ", stabilization: " << p.nodal.stabilization
           << ", stabilization_coefficient: " << p.nodal.stabilization_coefficient
           << ", dt_factor: " << p.nodal.dt_factor << ", facet_points: " << p.nodal.facet_points
           << ", plastic_scaling: " << (p.nodal.plastic_scaling ? "true" : "false") << "}\n";
    if (!p.regions.empty())
    {
        os << "    regions:\n";
        for (const auto& r : p.regions)
        {
            os << "      - {formulation: rkpm, ";
            selector(os, r);
            os << "}\n";
        }
    }
    if (p.refinement.active())
    {
        const RefinementSpec& f = p.refinement;
        os << "    refinement:\n      " << RefinementSpec::key(f.indicator) << ": " << f.threshold
           << (RefinementSpec::is_stress(f.indicator) ? " Pa" : "") << "\n";
        if (f.coarsen_below >= 0.0)
            os << "      coarsen_fraction: " << f.coarsen_below / f.threshold << "\n";
        os << "      max_level: " << f.max_level << "\n      max_new_particles: " << f.max_new_particles
           << "\n      interval: " << f.interval << " s\n";
        if (!f.region.empty())
        {
            os << "      region:\n";
            for (const auto& r : f.region)
            {
                os << "        - {";
                selector(os, r);
                os << "}\n";
            }
        }
    }
    if (p.coupled())
        os << "    transition: " << p.transition << "\n";
    if (p.formulation == Formulation::Rkpm || p.coupled() || p.semi_lagrangian)
        os << "    rk: {order: " << p.rk.order << ", kernel: " << p.rk.kernel << ", support: " << p.rk.support
           << ", normalized_support: " << p.rk.normalized_support << ", drop_tolerance: " << p.rk.drop_tolerance
           << ", share_translates: " << (p.rk.share_translates ? "true" : "false") << "}\n";
    if (p.formulation == Formulation::Fem1pt)
    {
        const char* t = p.hourglass.type == HourglassType::Viscous         ? "viscous"
                        : p.hourglass.type == HourglassType::Stiffness     ? "stiffness"
                        : p.hourglass.type == HourglassType::AssumedStrain ? "assumed-strain"
                        : p.hourglass.type == HourglassType::None          ? "none"
                                                                           : "viscous-plain";
        os << "    hourglass: {type: " << t << ", coefficient: " << p.hourglass.coefficient;
        if (p.hourglass.type == HourglassType::Stiffness || p.hourglass.type == HourglassType::AssumedStrain)
            os << ", plastic_scaling: " << (p.hourglass.plastic_scaling ? "true" : "false");
        os << "}\n";
    }
    os << "    bulk_viscosity: {linear: " << p.bulk_viscosity.linear << ", quadratic: " << p.bulk_viscosity.quadratic
       << "}\n";
    os << "    initial_velocity: " << vec(p.initial_velocity) << "\n";
    for (const auto& [key, c] : {std::pair{"erosion", &p.erosion}, std::pair{"conversion", &p.conversion}})
        if (c->active())
        {
            os << "    " << key << ": {effective_plastic_strain: " << c->plastic_strain << ", damage: " << c->damage
               << ", principal_strain: " << c->principal_strain << ", volumetric_strain: " << c->volumetric_strain
               << ", time_step: " << c->time_step << ", scaled_jacobian: " << c->scaled_jacobian
               << ", aspect_ratio: " << c->aspect_ratio;
            if (c == &p.conversion)
            {
                os << ", interval: " << c->interval << ", buffer: " << c->buffer
                   << ", max_per_event: " << c->max_per_event;
                const ElementCriteria::Reversion& r = c->revert;
                if (r.active())
                {
                    // the measures given only (the others off, which their keys cannot say)
                    std::string sep;
                    os << ", revert: {";
                    if (r.scaled_jacobian > 0)
                    {
                        os << "scaled_jacobian: " << r.scaled_jacobian;
                        sep = ", ";
                    }
                    if (r.aspect_ratio > 0)
                    {
                        os << sep << "aspect_ratio: " << r.aspect_ratio;
                        sep = ", ";
                    }
                    if (r.damage >= 0)
                    {
                        os << sep << "damage: " << r.damage;
                        sep = ", ";
                    }
                    if (r.plastic_strain >= 0)
                        os << sep << "effective_plastic_strain: " << r.plastic_strain;
                    os << "}";
                }
            }
            os << "}\n";
        }
}

/// Writes one part: its name, warnings, generator, material and options.
void write_part(std::ostringstream& os, const PartSpec& p)
{
    os << "  " << scalar(p.name) << ":\n";
    for (const auto& note : p.ignored)
        os << "    # warning: " << note << "\n";
    write_generator(os, p.generator);
    write_material(os, p.material);
    write_part_options(os, p);
}

/// Writes the boundary_conditions list.
void write_boundary_conditions(std::ostringstream& os, const std::vector<BoundarySpec>& bcs)
{
    if (!bcs.empty())
    {
        os << "boundary_conditions:\n";
        for (const auto& b : bcs)
        {
            os << "  - {node_set: " << scalar(b.node_set) << ", ";
            if (b.kind == BoundarySpec::Kind::Fixed)
            {
                os << "fixed: [";
                bool first = true;
                for (int k = 0; k < 3; ++k)
                    if (b.active[k])
                    {
                        os << (first ? "" : ", ") << "xyz"[k];
                        first = false;
                    }
                os << "]";
            }
            else
            {
                os << (b.kind == BoundarySpec::Kind::Velocity ? "velocity: " : "displacement: ");
                components(os, b.active, b.value);
            }
            os << "}\n";
        }
    }
}

/// Writes the loads list.
void write_loads(std::ostringstream& os, const std::vector<LoadSpec>& loads)
{
    if (!loads.empty())
    {
        os << "loads:\n";
        for (const auto& l : loads)
        {
            if (l.kind == LoadSpec::Kind::NodalForce)
            {
                os << "  - {type: nodal_force, node_set: " << scalar(l.set) << ", force: ";
                components(os, l.active, l.force);
                os << ", total: " << (l.total ? "true" : "false") << "}\n";
            }
            else
                os << "  - {type: pressure, face_set: " << scalar(l.set) << ", pressure: " << fn(l.pressure) << "}\n";
        }
    }
}

/// Writes the contacts list.
void write_contacts(std::ostringstream& os, const std::vector<ContactSpec>& contacts)
{
    if (!contacts.empty())
    {
        os << "contacts:\n";
        for (const auto& c : contacts)
        {
            os << "  - {type: "
               << (c.kind == ContactSpec::Kind::SurfaceToSurface ? "surface-to-surface"
                   : c.kind == ContactSpec::Kind::SingleSurface  ? "single-surface"
                   : c.kind == ContactSpec::Kind::Kernel         ? "kernel"
                                                                 : "rigid-wall");
            if (!c.surfaces.empty())
            {
                os << ", surfaces: [";
                for (std::size_t k = 0; k < c.surfaces.size(); ++k)
                    os << (k ? ", " : "") << scalar(c.surfaces[k]);
                os << "]";
            }
            if (c.kind == ContactSpec::Kind::Kernel)
            {
                os << ", thickness: " << c.thickness << ", friction: {static: " << c.mu_static
                   << ", dynamic: " << c.mu_dynamic << ", decay: " << c.decay << "}}\n";
                continue;
            }
            if (c.kind == ContactSpec::Kind::RigidWall)
                os << ", point: " << vec(c.point) << ", normal: " << vec(c.normal) << ", velocity: " << vec(c.velocity)
                   << ", penalty_scale: " << c.penalty_scale;
            else
                os << ", formulation: " << (c.mortar ? "mortar" : "node-to-segment")
                   << ", stiffness: " << (c.soft ? "soft" : "segment") << ", penalty_scale: " << c.penalty_scale
                   << ", soft_scale: " << c.soft_scale << ", thickness: " << c.thickness
                   << ", max_penetration: " << c.max_penetration;
            os << ", friction: {static: " << c.mu_static << ", dynamic: " << c.mu_dynamic << ", decay: " << c.decay
               << "}, damping: " << c.damping << "}\n";
        }
    }
}

/// Writes the spall line, when the deck has one.
void write_spall(std::ostringstream& os, const SpallSpec& spall)
{
    if (spall.active)
        os << "spall: {part: " << scalar(spall.part) << ", point: " << vec(spall.point)
           << ", direction: " << vec(spall.direction) << ", damage: " << spall.damage << "}\n";
}

/// Writes the impact line, when the deck has an impact.
void write_impact(std::ostringstream& os, const ImpactSpec& impact)
{
    if (impact.active)
        os << "impact: {target: " << scalar(impact.target)
           << (impact.projectile.empty() ? "" : ", projectile: " + scalar(impact.projectile))
           << ", point: " << vec(impact.point) << ", direction: " << vec(impact.direction)
           << ", damage: " << impact.damage << "}\n";
}

/// Writes the probes.
void write_probes(std::ostringstream& os, const std::vector<ProbeSpec>& probes)
{
    if (!probes.empty())
    {
        os << "probes:\n";
        for (const auto& p : probes)
            os << "  " << scalar(p.name) << ": {point: " << vec(p.point)
               << (p.part.empty() ? "" : ", part: " + scalar(p.part)) << "}\n";
    }
}

/// Writes the section planes.
void write_sections(std::ostringstream& os, const std::vector<SectionSpec>& sections)
{
    if (!sections.empty())
    {
        os << "sections:\n";
        for (const auto& s : sections)
        {
            os << "  " << scalar(s.name) << ": {point: " << vec(s.point) << ", normal: " << vec(s.normal)
               << (s.part.empty() ? "" : ", part: " + scalar(s.part));
            if (s.tolerance >= 0)
                os << ", tolerance: " << s.tolerance;
            os << "}\n";
        }
    }
}
} // namespace

std::string to_yaml(const Deck& d, int digits)
{
    struct Digits
    {
        int saved = echo_digits;
        ~Digits() { echo_digits = saved; }
    } restore;
    echo_digits = digits;
    std::ostringstream os;
    os.precision(echo_digits);
    write_header(os, d);
    os << "parts:\n";
    for (const auto& p : d.parts)
        write_part(os, p);
    sets(os, "node_sets", d.node_sets);
    sets(os, "face_sets", d.face_sets);
    write_boundary_conditions(os, d.boundary_conditions);
    write_loads(os, d.loads);
    write_contacts(os, d.contacts);
    write_impact(os, d.impact);
    write_spall(os, d.spall);
    write_probes(os, d.probes);
    write_sections(os, d.sections);
    return os.str();
}
} // namespace rkfem
