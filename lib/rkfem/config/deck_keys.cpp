/// @file deck_keys.cpp
/// The deck's key table (deck_schema.hpp): every section the reader reads, in the order a deck
/// is read. The reader's Section takes its allowed keys from here and checks each read's kind,
/// dimension, choices and default against the entry, so what this table says is what is read.
#include <stdexcept>

#include "rkfem/config/deck_schema.hpp"
#include "rkfem/config/erk_table_names.hpp"

namespace rkfem
{
namespace
{
// Builders of table entries, one per kind.
KeyDoc quantity(std::string name, Dimension d, std::string dflt, std::string description)
{
    KeyDoc k;
    k.name = std::move(name);
    k.kind = KeyKind::Quantity;
    k.dim = d;
    k.dflt = std::move(dflt);
    k.description = std::move(description);
    return k;
}
KeyDoc required(KeyDoc k)
{
    k.required = true;
    return k;
}
KeyDoc integer(std::string name, std::string dflt, std::string description)
{
    KeyDoc k = quantity(std::move(name), dim::none, std::move(dflt), std::move(description));
    k.kind = KeyKind::Integer;
    return k;
}
KeyDoc boolean(std::string name, std::string dflt, std::string description)
{
    KeyDoc k = quantity(std::move(name), dim::none, std::move(dflt), std::move(description));
    k.kind = KeyKind::Boolean;
    k.choices = {"true", "false"};
    return k;
}
KeyDoc text(std::string name, std::string dflt, std::string description)
{
    KeyDoc k = quantity(std::move(name), dim::none, std::move(dflt), std::move(description));
    k.kind = KeyKind::Text;
    return k;
}
KeyDoc choice(std::string name, std::vector<std::string> options, std::string dflt, std::string description)
{
    KeyDoc k = quantity(std::move(name), dim::none, std::move(dflt), std::move(description));
    k.kind = KeyKind::Choice;
    k.choices = std::move(options);
    return k;
}
KeyDoc vec3(std::string name, Dimension d, std::string dflt, std::string description)
{
    KeyDoc k = quantity(std::move(name), d, std::move(dflt), std::move(description));
    k.kind = KeyKind::Vec3;
    return k;
}
KeyDoc of_kind(KeyKind kind, std::string name, std::vector<std::string> sections, std::string description)
{
    KeyDoc k = quantity(std::move(name), dim::none, "", std::move(description));
    k.kind = kind;
    k.sections = std::move(sections);
    return k;
}
KeyDoc section(std::string name, std::string id, std::string description)
{
    return of_kind(KeyKind::Section, std::move(name), {std::move(id)}, std::move(description));
}
KeyDoc variants(std::string name, std::string discriminator, std::vector<std::string> ids, std::string description)
{
    KeyDoc k = of_kind(KeyKind::Variants, std::move(name), std::move(ids), std::move(description));
    k.discriminator = std::move(discriminator);
    return k;
}
KeyDoc list_of(KeyKind kind, std::string name, std::string discriminator, std::vector<std::string> ids,
               std::string description)
{
    KeyDoc k = of_kind(kind, std::move(name), std::move(ids), std::move(description));
    k.discriminator = std::move(discriminator);
    return k;
}
KeyDoc time_function(std::string name, Dimension d, std::string description)
{
    KeyDoc k = quantity(std::move(name), d, "", std::move(description));
    k.kind = KeyKind::TimeFunction;
    return k;
}
KeyDoc components(std::string name, Dimension d, std::string description)
{
    KeyDoc k = quantity(std::move(name), d, "", std::move(description));
    k.kind = KeyKind::Components;
    return k;
}
KeyDoc pairs(std::string name, Dimension a, Dimension b, std::string description)
{
    KeyDoc k = quantity(std::move(name), a, "", std::move(description));
    k.kind = KeyKind::Pairs;
    k.dim2 = b;
    return k;
}
KeyDoc quantity_list(std::string name, Dimension d, int count, std::string description)
{
    KeyDoc k = quantity(std::move(name), d, "", std::move(description));
    k.kind = KeyKind::QuantityList;
    k.count = count;
    return k;
}
KeyDoc quantity_or(std::string name, Dimension d, std::string word, std::string dflt, std::string description)
{
    KeyDoc k = quantity(std::move(name), d, std::move(dflt), std::move(description));
    k.kind = KeyKind::QuantityOr;
    k.word = std::move(word);
    return k;
}
KeyDoc plain(KeyKind kind, std::string name, std::string description, int count = 0)
{
    KeyDoc k = quantity(std::move(name), dim::none, "", std::move(description));
    k.kind = kind;
    k.count = count;
    return k;
}

// The dimensions without a name in dim::
constexpr Dimension per_time{0, 0, -1};
constexpr Dimension per_pressure{-1, 1, 2};
constexpr Dimension per_pressure2{-2, 2, 4};
constexpr Dimension fracture_energy{1, 0, -2};
constexpr Dimension per_velocity{0, -1, 1};

const std::string kTolerance = "how far from the surface a node may be and still be selected (default: a small "
                               "fraction of the part's smallest element)";

std::vector<SectionDoc> build_table()
{
    std::vector<SectionDoc> t;
    // --- the run deck ---
    t.push_back(
        {"deck",
         "The run deck",
         "A run deck's top level.",
         {text("title", "", "A line that names the run; written into summary.json and results.h5."),
          required(section("time", "time", "The run's end, output intervals and stepper.")),
          section("output", "output", "How results.h5 stores fields."),
          required(list_of(KeyKind::Map, "parts", "", {"part"}, "The parts, by name, in the order they are built.")),
          list_of(KeyKind::Map, "node_sets", "", {"set"}, "Named node sets, by name: a part and a selector."),
          list_of(KeyKind::Map, "face_sets", "", {"set"}, "Named face sets, by name: a part and a selector."),
          list_of(KeyKind::List, "boundary_conditions", "", {"boundary"},
                  "Fixed, velocity or displacement conditions on node sets."),
          list_of(KeyKind::List, "loads", "type", {"load.nodal_force", "load.pressure"},
                  "Nodal forces on node sets and pressures on face sets."),
          list_of(KeyKind::Map, "probes", "", {"probe"}, "Points whose displacement and velocity go into history.csv."),
          list_of(KeyKind::Map, "sections", "", {"section-plane"},
                  "Cut planes whose resultant force goes into history.csv."),
          list_of(KeyKind::List, "contacts", "type",
                  {"contact.surface-to-surface", "contact.single-surface", "contact.rigid-wall", "contact.kernel"},
                  "Contact definitions."),
          section("impact", "impact", "A projectile impact's target, shot line and crater measures."),
          section("spall", "spall", "A back face's spall measures: crack depth and fly-off velocity.")}});
    t.push_back(
        {"time",
         "time",
         "The run's end, output intervals and time stepper.",
         {required(quantity("end", dim::time, "", "The end time of the run.")),
          quantity("output_interval", dim::time, "0", "Field output interval (0: the start and the end)."),
          quantity("history_interval", dim::time, "0", "history.csv row interval (0: every step)."),
          quantity("dt_scale", dim::none, "0.9",
                   "The time step as a fraction of the stable step, LS-DYNA's TSSFAC; 0 < dt_scale <= 1."),
          quantity("dt_max", dim::time, "0", "A cap on the time step (0: none)."),
          integer("max_steps", "0", "Stop after this many steps (0: no limit)."),
          choice("stepper", {"central-difference", "arkode-cd", "arkode-erk"}, "arkode-cd",
                 "The time integrator: the central difference through SUNDIALS ARKODE (arkode-cd), the "
                 "hand-written central difference, or an explicit Runge-Kutta table through ARKODE (arkode-erk)."),
          choice("erk_table", erk_table_names(), "ARKODE_BOGACKI_SHAMPINE_4_2_3",
                 "The explicit Runge-Kutta table of stepper arkode-erk."),
          quantity("energy_error_limit", dim::none, "0.05",
                   "The run stops when the energy balance error exceeds this fraction."),
          quantity("dt_min_fraction", dim::none, "1e-5",
                   "A run whose stable step falls below this fraction of its first step stops as unstable "
                   "(LS-DYNA's DTMIN; 0: no floor)."),
          quantity("mass_damping", per_time, "0", "Mass-proportional damping rate (dynamic relaxation).")}});
    t.push_back({"output",
                 "output",
                 "How results.h5 stores the fields.",
                 {choice("precision", {"single", "double"}, "single",
                         "Fields as 32-bit floats (each double rounded once) or as doubles; coordinates stay 64-bit."),
                  integer("compression", "0", "gzip level 0 (none) to 9 (smallest) of every dataset.")}});
    // --- parts ---
    t.push_back(
        {"part",
         "parts.NAME",
         "A part: how its mesh or particles are made, its material and its formulation.",
         {required(variants("generator", "type",
                            {"generator.box", "generator.cylinder", "generator.projectile", "generator.cloud",
                             "generator.keyword", "generator.gmsh"},
                            "How the part's mesh or particles are made.")),
          required(variants("material", "model", {"material.elastic", "material.j2", "material.kcc", "material.cscm"},
                            "The part's material.")),
          choice("formulation", {"fem-1pt", "fem-2x2x2", "fem-nodal", "rkpm"}, "fem-1pt",
                 "1-point hexahedra with hourglass control, fully integrated hexahedra, nodally integrated FE, "
                 "or RK particles."),
          section("hourglass", "hourglass", "Hourglass control of fem-1pt parts."),
          section("bulk_viscosity", "bulk_viscosity", "Artificial bulk viscosity (shocks)."),
          section("nodal_integration", "nodal_integration", "Nodal integration of fem-nodal and rkpm parts."),
          section("rk", "rk", "RK shape functions of rkpm parts and RK regions."),
          vec3("initial_velocity", dim::velocity, "[0, 0, 0]", "The part's initial velocity."),
          list_of(KeyKind::List, "regions", "", {"region"},
                  "Volumes of an FE part (fem-nodal or fem-1pt) discretized by RK particles (FE-RK coupling)."),
          choice("transition", {"mixed", "ramp"}, "mixed",
                 "How FE and RK shape functions blend at a coupled part's interface."),
          section("erosion", "criteria.erosion",
                  "Element erosion (fem-1pt, fem-2x2x2): an element is deleted when any set criterion is met."),
          section("conversion", "criteria.conversion",
                  "Evolutionary coupling (fem-nodal): elements that meet any set criterion become RK particles."),
          choice("kinematics", {"lagrangian", "semi-lagrangian"}, "lagrangian",
                 "RK kernels in the reference (lagrangian) or the current configuration (semi-lagrangian, rkpm "
                 "parts)."),
          section("semi_lagrangian", "semi_lagrangian", "Settings of semi-Lagrangian RK particles."),
          section("refinement", "refinement",
                  "Adaptive refinement of semi-Lagrangian particles: splitting where an indicator is high, "
                  "merging where it has fallen.")}});
    t.push_back(
        {"generator.box",
         "generator: box",
         "A structured box of hexahedra.",
         {required(choice("type", {"box"}, "", "box")),
          vec3("origin", dim::length, "[0, 0, 0]", "The box's corner of least x, y, z."),
          required(vec3("size", dim::length, "", "The box's edges along x, y, z.")),
          quantity("element_size", dim::length, "", "The target element edge (required unless divisions is given)."),
          plain(KeyKind::Integers, "divisions", "Elements along x, y, z (instead of element_size).", 3)}});
    t.push_back(
        {"generator.cylinder",
         "generator: cylinder",
         "A solid cylinder along +z (or a tube with inner_radius).",
         {required(choice("type", {"cylinder"}, "", "cylinder")),
          vec3("origin", dim::length, "[0, 0, 0]", "The bottom centre."),
          required(quantity("radius", dim::length, "", "The outer radius.")),
          required(quantity("height", dim::length, "", "The height along +z.")),
          required(quantity("element_size", dim::length, "", "The target element edge.")),
          choice("core", {"butterfly", "ogrid"}, "butterfly", "How the core is meshed (no degenerate elements)."),
          quantity("inner_radius", dim::length, "", "A tube's inner radius (faces top, bottom, side, inner).")}});
    t.push_back({"generator.projectile",
                 "generator: projectile",
                 "A flat-nosed cylindrical projectile.",
                 {required(choice("type", {"projectile"}, "", "projectile")),
                  vec3("origin", dim::length, "[0, 0, 0]", "The nose centre."),
                  required(quantity("radius", dim::length, "", "The radius.")),
                  required(quantity("length", dim::length, "", "The length.")),
                  required(quantity("element_size", dim::length, "", "The target element edge.")),
                  choice("direction", {"-z", "+z"}, "-z", "The direction the nose points.")}});
    t.push_back({"generator.cloud",
                 "generator: cloud",
                 "RK particles without elements: a jittered lattice in a box or cylinder body, or a points file, "
                 "integrated on their Voronoi cells.",
                 {required(choice("type", {"cloud"}, "", "cloud")),
                  choice("body", {"box", "cylinder"}, "box", "The body the particles fill."),
                  vec3("origin", dim::length, "[0, 0, 0]", "The box's corner, or the cylinder's bottom centre."),
                  vec3("size", dim::length, "", "The box body's edges."),
                  quantity("radius", dim::length, "", "The cylinder body's radius."),
                  quantity("height", dim::length, "", "The cylinder body's height."),
                  quantity("spacing", dim::length, "", "The lattice spacing (or give points)."),
                  quantity("jitter", dim::none, "0.25",
                           "Random displacement of lattice points, a fraction of spacing, 0-0.45."),
                  integer("seed", "1", "The jitter's random seed."),
                  text("points", "", "A CSV file of x,y,z (relative paths from the deck's folder)."),
                  text("points_unit", "m", "The points file's length unit.")}});
    t.push_back({"generator.keyword",
                 "generator: keyword",
                 "The *NODE and *ELEMENT_SOLID cards of an LS-DYNA keyword file.",
                 {required(choice("type", {"keyword"}, "", "keyword")),
                  required(text("file", "", "The keyword file (relative paths from the deck's folder).")),
                  text("unit", "m", "The file's length unit."),
                  plain(KeyKind::IntegerOrList, "pid", "The PIDs of the solids to take (default all).")}});
    t.push_back({"generator.gmsh",
                 "generator: gmsh",
                 "A Gmsh mesh (ASCII MSH 4.1 or 2.2).",
                 {required(choice("type", {"gmsh"}, "", "gmsh")),
                  required(text("file", "", "The .msh file (relative paths from the deck's folder).")),
                  text("unit", "m", "The file's length unit."),
                  plain(KeyKind::NameOrList, "physical",
                        "The volume physical groups to take, by name or tag (default all).")}});
    // --- materials ---
    const KeyDoc rho = required(quantity("rho", dim::density, "", "Mass density."));
    t.push_back({"material.elastic",
                 "material: elastic",
                 "Hypoelastic, isotropic.",
                 {required(choice("model", {"elastic"}, "", "elastic")), rho,
                  required(quantity("E", dim::pressure, "", "Young's modulus.")),
                  required(quantity("nu", dim::none, "", "Poisson's ratio, -1 < nu < 0.5."))}});
    t.push_back(
        {"material.j2",
         "material: j2",
         "J2 plasticity with isotropic hardening, optional Cowper-Symonds rate effects, failure and EOS.",
         {required(choice("model", {"j2"}, "", "j2")), rho,
          required(quantity("E", dim::pressure, "", "Young's modulus.")),
          required(quantity("nu", dim::none, "", "Poisson's ratio, -1 < nu < 0.5.")),
          quantity("sigy", dim::pressure, "", "The initial yield stress (required unless curve is given)."),
          quantity("etan", dim::pressure, "0", "The linear hardening modulus, 0 <= etan < E."),
          pairs("curve", dim::none, dim::pressure,
                "Yield stress against effective plastic strain, [[0, sigy], [eps_p, stress], ...] (instead of sigy "
                "and etan)."),
          section("cowper_symonds", "cowper_symonds", "Cowper-Symonds strain-rate scaling of the yield stress."),
          quantity("fail", dim::none, "0", "The effective plastic strain at which a point fails (0: never)."),
          variants("eos", "type", {"eos.linear", "eos.gruneisen"}, "The pressure's equation of state.")}});
    t.push_back({"cowper_symonds",
                 "cowper_symonds",
                 "sigma_y scaled by 1 + (rate / C)^(1/P).",
                 {required(quantity("C", per_time, "", "C.")), required(quantity("P", dim::none, "", "P."))}});
    t.push_back({"eos.linear",
                 "eos: linear",
                 "Pressure from the bulk modulus (the default).",
                 {required(choice("type", {"linear"}, "", "linear"))}});
    t.push_back({"eos.gruneisen",
                 "eos: gruneisen",
                 "The Mie-Gruneisen EOS with a linear Us-up fit (LS-DYNA's *EOS_GRUNEISEN).",
                 {required(choice("type", {"gruneisen"}, "", "gruneisen")),
                  required(quantity("c0", dim::velocity, "", "The bulk sound speed, the intercept of Us-up.")),
                  required(quantity("s", dim::none, "", "The slope of Us against up, 0-10.")),
                  required(quantity("gamma0", dim::none, "", "Gruneisen's gamma, 0-10.")),
                  quantity("a", dim::none, "0", "The first-order volume correction, 0-10.")}});
    const std::vector<KeyDoc> concrete_common = {
        rho,
        required(quantity("fc", dim::pressure, "", "The unconfined compressive strength f'c.")),
        quantity_or("rate_effects", dim::none, "", "false", ""), // replaced below per model
        quantity_or("fracture_energy", fracture_energy, "auto", "",
                    "The fracture energy G_f for the crack-band regularization: auto (CEB-FIP from f'c), or a "
                    "value (0: none)."),
    };
    {
        SectionDoc kcc{"material.kcc",
                       "material: kcc",
                       "Karagozian & Case concrete, Release III (LS-DYNA's *MAT_072R3): three strength surfaces, "
                       "damage, the tabulated compaction EOS. Parameters are generated from f'c; any given here "
                       "override the generated ones.",
                       {required(choice("model", {"kcc"}, "", "kcc"))}};
        for (const auto& k : concrete_common)
            kcc.keys.push_back(k);
        kcc.keys[3] = KeyDoc{};
        kcc.keys[3].name = "rate_effects";
        kcc.keys[3].kind = KeyKind::BooleanOr;
        kcc.keys[3].sections = {"rate_effects"};
        kcc.keys[3].choices = {"true", "false"};
        kcc.keys[3].dflt = "false";
        kcc.keys[3].description = "Strain-rate enhancement: true (the standard law with its caps), false, or a "
                                  "mapping with a law or a curve.";
        kcc.keys.insert(kcc.keys.end(),
                        {quantity("E", dim::pressure, "", "Young's modulus (default 4700 sqrt(f'c / MPa) MPa, ACI)."),
                         quantity("nu", dim::none, "0.19", "Poisson's ratio."),
                         quantity("a0", dim::pressure, "", "Maximum surface a0."),
                         quantity("a1", dim::none, "", "Maximum surface a1."),
                         quantity("a2", per_pressure, "", "Maximum surface a2."),
                         quantity("a0y", dim::pressure, "", "Yield surface a0y."),
                         quantity("a1y", dim::none, "", "Yield surface a1y."),
                         quantity("a2y", per_pressure, "", "Yield surface a2y."),
                         quantity("a1f", dim::none, "", "Residual surface a1f."),
                         quantity("a2f", per_pressure, "", "Residual surface a2f."),
                         quantity("b1", dim::none, "", "Compressive damage scaling b1."),
                         quantity("b2", dim::none, "", "Tensile damage scaling b2."),
                         quantity("b3", dim::none, "", "Triaxial tensile damage scaling b3."),
                         quantity("omega", dim::none, "", "The fraction of associated dilatancy, 0-1."),
                         quantity("edrop", dim::none, "",
                                  "Post-peak dilatancy decay: omega eta(lambda)^edrop past the peak (0: none)."),
                         quantity("ft", dim::pressure, "", "The tensile strength."),
                         pairs("eta", dim::none, dim::none,
                               "The damage function [[lambda, eta], ...]: lambda from 0 increasing, eta in [0, 1] "
                               "reaching 1 once."),
                         section("eos", "kcc-eos", "The tabulated compaction EOS (*EOS_TABULATED_COMPACTION).")});
        t.push_back(kcc);
        SectionDoc cscm{"material.cscm",
                        "material: cscm",
                        "The continuous surface cap model (LS-DYNA's *MAT_CSCM_CONCRETE), parameters generated from "
                        "f'c (Murray's fits, 20-58 MPa); any given here override the generated ones.",
                        {required(choice("model", {"cscm"}, "", "cscm"))}};
        for (const auto& k : concrete_common)
            cscm.keys.push_back(k);
        cscm.keys[3] = boolean("rate_effects", "false", "Strain-rate effects (CSCM's own viscoplastic law).");
        cscm.keys.insert(cscm.keys.end(),
                         {quantity("E", dim::pressure, "", "Young's modulus (default 21.5 GPa (f'c / 10 MPa)^(1/3))."),
                          quantity("nu", dim::none, "0.2", "Poisson's ratio."),
                          quantity("alpha", dim::pressure, "", "Shear surface alpha."),
                          quantity("theta", dim::none, "", "Shear surface theta."),
                          quantity("lambda", dim::pressure, "", "Shear surface lambda."),
                          quantity("beta", per_pressure, "", "Shear surface beta."),
                          quantity("R", dim::none, "", "Cap aspect ratio R."),
                          quantity("X0", dim::pressure, "", "Initial cap position X0."),
                          quantity("W", dim::none, "", "Maximum plastic volume compaction W."),
                          quantity("D1", per_pressure, "", "Linear cap shape D1."),
                          quantity("D2", per_pressure2, "", "Quadratic cap shape D2."),
                          quantity("B", dim::none, "", "Ductile shape softening B."),
                          quantity("D", dim::none, "", "Brittle shape softening D."),
                          quantity("Gfc", fracture_energy, "", "Fracture energy in uniaxial compression."),
                          quantity("length", dim::length, "", "The crack-band length.")});
        t.push_back(cscm);
    }
    t.push_back({"rate_effects",
                 "rate_effects (kcc)",
                 "K&C rate enhancement: the standard law with caps, or a tabulated DIF curve (LS-DYNA's LCRATE).",
                 {choice("law", {"ceb-fip"}, "", "CEB-FIP in compression, Malvar-Ross in tension (or give curve)."),
                  pairs("curve", per_time, dim::none,
                        "[[rate, DIF], ...]: rates strictly increasing, negative rates tension as in LCRATE; DIF > 0."),
                  quantity_or("compression_cap", dim::none, "none", "",
                              "The largest compressive DIF, >= 1, or none (default: the law's own cap)."),
                  quantity_or("tension_cap", dim::none, "none", "",
                              "The largest tensile DIF, >= 1, or none (default: the law's own cap).")}});
    t.push_back({"kcc-eos",
                 "eos (kcc)",
                 "The 10-point tabulated compaction EOS (EOS_8).",
                 {required(quantity_list("strain", dim::none, 10, "Volumetric strains from 0, decreasing.")),
                  required(quantity_list("pressure", dim::pressure, 10, "Pressures, increasing.")),
                  required(quantity_list("unload_bulk", dim::pressure, 10, "Unloading bulk moduli, > 0."))}});
    // --- a part's formulation settings ---
    t.push_back(
        {"hourglass",
         "hourglass",
         "Hourglass control of 1-point hexahedra (LS-DYNA's *HOURGLASS).",
         {choice("type", {"viscous", "stiffness", "assumed-strain", "none", "viscous-plain"}, "viscous",
                 "Flanagan-Belytschko viscous (IHQ 3), stiffness (IHQ 5), Belytschko-Bindeman assumed strain (IHQ "
                 "6), none, or the plain viscous form (IHQ 1)."),
          quantity("coefficient", dim::none, "0.1", "QM, >= 0."),
          choice("plastic_scaling", {"true", "false"}, "",
                 "Scale the stiffness forms' increments where the material flows (default: true for "
                 "assumed-strain, false for stiffness).")}});
    t.push_back({"bulk_viscosity",
                 "bulk_viscosity",
                 "Artificial bulk viscosity (LS-DYNA's Q1, Q2).",
                 {quantity("linear", dim::none, "0.06", "The linear coefficient."),
                  quantity("quadratic", dim::none, "1.5", "The quadratic coefficient.")}});
    t.push_back(
        {"nodal_integration",
         "nodal_integration",
         "Nodal integration of fem-nodal and rkpm parts and of RK regions.",
         {choice("scheme", {"scni", "sd-scni", "dni", "snni", "sd-snni"}, "",
                 "Stabilized conforming (scni), its stress-point form (sd-scni), direct (dni), or stabilized "
                 "non-conforming on current cells (snni, semi-Lagrangian parts; their default; scni otherwise), "
                 "or on each cell's eight sub-cells (sd-snni, semi-Lagrangian parts rebuilt every step)."),
          choice("stabilization", {"mscni", "nsni", "face-gradient", "sub-cells", "none"}, "",
                 "The stabilization (default: nsni on rkpm parts, mscni on fem-nodal and coupled parts, "
                 "face-gradient for snni, sub-cells for sd-snni; none for sd-scni and dni)."),
          quantity("stabilization_coefficient", dim::none, "",
                   "c_s (default 0.25 for nsni, 1 for mscni, face-gradient and sub-cells)."),
          quantity("dt_factor", dim::none, "0", "The stable-step factor alpha in (0, 2] (0: the calibrated default)."),
          choice("plastic_scaling", {"true", "false"}, "false",
                 "Materials with history: the stabilization's loads (mscni, nsni) take the share of the step "
                 "the point's material took elastically, so flowing or softening material stores no elastic "
                 "stabilization energy (as IHQ 6 scales its hourglass stiffness)."),
          choice("facet_points", {"triangles", "faces"}, "",
                 "Where the nodal cells' facets take their points (default: faces on clouds, triangles on meshes).")}});
    t.push_back(
        {"rk",
         "rk",
         "RK shape functions.",
         {choice("order", {"1", "2"}, "1", "The order of the reproduced basis."),
          choice("kernel", {"cubic-bspline", "quintic-bspline", "gaussian"}, "cubic-bspline", "The kernel."),
          choice("support", {"box", "sphere"}, "box", "The kernel's support shape."),
          quantity("normalized_support", dim::none, "",
                   "a / h between 1 and 4, not an integer (default 1.51 on meshes, 1.35 on clouds)."),
          quantity("drop_tolerance", dim::none, "",
                   "Drop shape functions below this fraction (order 1; default 1e-5, 0 with order 2; not used by "
                   "the RK regions of coupled parts, which keep every function)."),
          choice("share_translates", {"true", "false"}, "true",
                 "Share the tables of particles whose neighbourhoods are translates.")}});
    t.push_back({"region",
                 "regions[i]",
                 "An RK region of an FE part.",
                 {choice("formulation", {"rkpm"}, "rkpm", "The region's formulation."),
                  required(variants("select", "type", {"selector.box", "selector.cylinder", "selector.sphere"},
                                    "The region's volume."))}});
    const std::vector<KeyDoc> criteria = {
        quantity("effective_plastic_strain", dim::none, "0", "Effective plastic strain (0: off)."),
        quantity("damage", dim::none, "0", "Damage index in (0, 1] (0: off)."),
        quantity("principal_strain", dim::none, "0", "Largest principal strain (0: off)."),
        quantity("volumetric_strain", dim::none, "0", "Volumetric strain magnitude (0: off)."),
        quantity("time_step", dim::time, "0", "The element's stable step below this (0: off)."),
        quantity("scaled_jacobian", dim::none, "0", "Smallest scaled corner Jacobian, in [0, 1) (0: off)."),
        quantity("aspect_ratio", dim::none, "0", "Longest over shortest edge, above 1 (0: off).")};
    t.push_back(
        {"criteria.erosion", "erosion", "Element erosion criteria: any one met deletes the element.", criteria});
    {
        SectionDoc c{"criteria.conversion", "conversion",
                     "Conversion criteria: any one met turns the element into RK particles.", criteria};
        c.keys.insert(c.keys.end(),
                      {quantity("interval", dim::time, "0", "Time between checks (0: after every step)."),
                       integer("buffer", "0", "Layers of neighbouring elements converted with them, 0-8."),
                       integer("max_per_event", "0", "Elements converted at most per check (0: no cap)."),
                       section("revert", "revert", "When converted elements return to FE.")});
        t.push_back(c);
    }
    t.push_back({"revert",
                 "conversion.revert",
                 "RK back to FE: an element whose measures are all on the benign side of these reverts.",
                 {quantity("scaled_jacobian", dim::none, "0",
                           "The scaled corner Jacobian at or above which an element is benign again."),
                  quantity("aspect_ratio", dim::none, "0", "The edge ratio at or below which it is benign again."),
                  quantity("damage", dim::none, "", "The damage at or below which it is benign again."),
                  quantity("effective_plastic_strain", dim::none, "",
                           "The effective plastic strain at or below which it is benign again.")}});
    t.push_back(
        {"refinement",
         "refinement",
         "Particle splitting and merging (rkpm parts with kinematics: semi-lagrangian): a particle whose indicator "
         "reaches the threshold splits into the eight half-size parallelepipeds of its cell, conserving mass and "
         "momentum; eight siblings all below coarsen_below merge back.",
         {quantity("damage", dim::none, "", "Split at this damage index (one indicator only)."),
          quantity("effective_plastic_strain", dim::none, "", "Split at this effective plastic strain."),
          quantity("pressure", dim::pressure, "", "Split at this |pressure|."),
          quantity("von_mises", dim::pressure, "", "Split at this sqrt(3 J2)."),
          quantity("coarsen_fraction", dim::none, "",
                   "Eight siblings all below this fraction of the threshold merge back (default: never)."),
          integer("max_level", "1", "Splits a particle of the start may go through, 1 or 2."),
          integer("max_new_particles", "0",
                  "Particles the part may gain, a multiple of 7 (0: 7 per particle of the start)."),
          quantity("interval", dim::time, "0", "Time between checks (0: after every step)."),
          list_of(KeyKind::List, "region", "", {"region"}, "Volumes outside which no particle splits.")}});
    t.push_back(
        {"semi_lagrangian",
         "semi_lagrangian",
         "Semi-Lagrangian RK particles.",
         {quantity("neighbour_skin", dim::none, "0.3",
                   "The neighbour search's skin, a fraction of the largest support radius (0: rebuild every step)."),
          quantity("reset_interval", dim::none, "1",
                   "1: kernels rebuilt every step; N > 1: Lagrangian RK reset to the current configuration every N "
                   "steps."),
          quantity("separation_damage", dim::none, "0",
                   "The damage at which a particle separates from its neighbours (0: never)."),
          choice("plastic_scaling", {"true", "false"}, "false",
                 "Scale the face terms by the material's elastic share.")}});
    // --- sets and selectors ---
    const std::vector<std::string> selectors = {"selector.named",    "selector.plane",  "selector.box",
                                                "selector.cylinder", "selector.sphere", "selector.ids",
                                                "selector.segments"};
    t.push_back({"set",
                 "node_sets.NAME, face_sets.NAME",
                 "A named set: the nodes or faces a selector picks, of one part or of all.",
                 {text("part", "", "The part (default: all parts)."),
                  required(variants("select", "type", selectors, "What to select."))}});
    t.push_back({"selector.named",
                 "select: named",
                 "A generator's named nodes or faces (box: xmin, ..., cylinder: top, bottom, side, all).",
                 {required(choice("type", {"named"}, "", "named")), required(text("name", "", "The name."))}});
    t.push_back({"selector.plane",
                 "select: plane",
                 "Nodes or faces on a plane.",
                 {required(choice("type", {"plane"}, "", "plane")),
                  required(vec3("point", dim::length, "", "A point of the plane.")),
                  required(vec3("normal", dim::none, "", "The plane's normal.")),
                  quantity("tolerance", dim::length, "", kTolerance)}});
    t.push_back({"selector.box",
                 "select: box",
                 "Nodes or faces in an axis-aligned box.",
                 {required(choice("type", {"box"}, "", "box")),
                  required(vec3("min", dim::length, "", "The corner of least x, y, z.")),
                  required(vec3("max", dim::length, "", "The corner of greatest x, y, z.")),
                  quantity("tolerance", dim::length, "", kTolerance)}});
    t.push_back({"selector.cylinder",
                 "select: cylinder",
                 "Nodes or faces on (within tolerance) or in a cylinder.",
                 {required(choice("type", {"cylinder"}, "", "cylinder")),
                  required(vec3("point", dim::length, "", "A point of the axis.")),
                  required(vec3("axis", dim::none, "", "The axis' direction.")),
                  required(quantity("radius", dim::length, "", "The radius.")),
                  quantity("tolerance", dim::length, "", kTolerance)}});
    t.push_back(
        {"selector.sphere",
         "select: sphere",
         "Nodes or faces in a sphere.",
         {required(choice("type", {"sphere"}, "", "sphere")), required(vec3("point", dim::length, "", "The centre.")),
          required(quantity("radius", dim::length, "", "The radius."))}});
    t.push_back({"selector.ids",
                 "select: ids",
                 "Nodes by a keyword mesh's node numbers.",
                 {required(choice("type", {"ids"}, "", "ids")),
                  required(plain(KeyKind::Integers, "ids", "The node numbers (NIDs)."))}});
    t.push_back({"selector.segments",
                 "select: segments",
                 "Faces by a keyword mesh's node numbers.",
                 {required(choice("type", {"segments"}, "", "segments")),
                  required(plain(KeyKind::Segments, "segments", "[[N1, N2, N3, N4], ...], boundary faces."))}});
    // --- conditions, loads, time functions ---
    t.push_back({"boundary",
                 "boundary_conditions[i]",
                 "One of fixed, velocity or displacement on a node set.",
                 {required(text("node_set", "", "The node set.")),
                  plain(KeyKind::Fixed, "fixed", "all, or the components held: x, y, z or a list of them."),
                  components("velocity", dim::velocity, "Prescribed velocity components."),
                  components("displacement", dim::length, "Prescribed displacement components.")}});
    t.push_back({"components",
                 "{x, y, z}",
                 "Components, each a value or a time function.",
                 {time_function("x", dim::none, "The x component."), time_function("y", dim::none, "The y component."),
                  time_function("z", dim::none, "The z component.")}});
    for (auto& k : t.back().keys)
        k.dim_from_use = true;
    t.push_back(
        {"load.nodal_force",
         "loads: nodal_force",
         "Forces on the nodes of a node set.",
         {required(choice("type", {"nodal_force"}, "", "nodal_force")), required(text("node_set", "", "The node set.")),
          required(components("force", dim::force, "The force components, on each node.")),
          boolean("total", "false", "The force is the set's total, shared by the nodes.")}});
    t.push_back(
        {"load.pressure",
         "loads: pressure",
         "A pressure on the faces of a face set (positive pushes into the part).",
         {required(choice("type", {"pressure"}, "", "pressure")), required(text("face_set", "", "The face set.")),
          required(time_function("pressure", dim::pressure, "The pressure."))}});
    t.push_back({"time-function",
                 "time function",
                 "A value of time: exactly one of value, curve or triangular, times scale.",
                 {quantity("value", dim::none, "", "A constant."),
                  pairs("curve", dim::time, dim::none, "[[t, value], ...], times strictly increasing."),
                  section("triangular", "triangular", "A triangular pulse."),
                  quantity("scale", dim::none, "1", "A factor on the function.")}});
    t.back().keys[0].dim_from_use = true;
    t.back().keys[1].dim_from_use = true;
    t.push_back({"triangular",
                 "triangular",
                 "A blast-like pulse: the peak at the arrival time, decaying linearly to zero over the duration; "
                 "zero before and after.",
                 {required(quantity("peak", dim::none, "", "The peak value, at the arrival.")),
                  required(quantity("duration", dim::time, "", "The decay time to zero.")),
                  quantity("start", dim::time, "0", "The arrival time.")}});
    t.back().keys[0].dim_from_use = true;
    // --- probes, sections, contacts, impact ---
    t.push_back({"probe",
                 "probes.NAME",
                 "A point whose displacement and velocity go into history.csv (the nearest node).",
                 {required(vec3("point", dim::length, "", "The point.")),
                  text("part", "", "The part to search (default: all).")}});
    t.push_back({"section-plane",
                 "sections.NAME",
                 "A cut plane whose resultant force goes into history.csv.",
                 {required(vec3("point", dim::length, "", "A point of the plane.")),
                  required(vec3("normal", dim::none, "", "The plane's normal.")),
                  text("part", "", "The part to cut (default: all)."),
                  quantity("tolerance", dim::length, "", "How far from the plane a node counts as on it.")}});
    const KeyDoc surfaces = plain(KeyKind::Names, "surfaces", "Part or face-set names.");
    const KeyDoc friction = section("friction", "friction", "Coulomb friction.");
    const std::vector<KeyDoc> penalty = {
        quantity("damping", dim::none, "0", "Contact damping, a fraction of critical (LS-DYNA's VDC; 20 % reads 0.2)."),
        choice("formulation", {"node-to-segment", "mortar"}, "node-to-segment",
               "Node-to-segment penalty (two-pass) or mortar (surface-to-surface only)."),
        choice("stiffness", {"soft", "segment"}, "soft",
               "The penalty stiffness: the larger of the segment's (penalty_scale K A / depth) and the soft "
               "constraint's (soft_scale m / dt0^2; LS-DYNA's SOFT 1), or the segment's alone (SOFT 0)."),
        quantity("penalty_scale", dim::none, "0.1", "The penalty scale factor, (0, 100]."),
        quantity("soft_scale", dim::none, "0.1", "The soft constraint's scale factor, (0, 0.8]."),
        quantity("thickness", dim::length, "0", "The contact thickness."),
        quantity("max_penetration", dim::none, "0.5",
                 "Penetration, as a fraction of the element depth, past which a node is released.")};
    for (const char* type : {"surface-to-surface", "single-surface"})
    {
        SectionDoc c{std::string("contact.") + type,
                     std::string("contacts: ") + type,
                     std::string(type) == "surface-to-surface"
                         ? "Two surfaces in contact (LS-DYNA's *CONTACT_AUTOMATIC_SURFACE_TO_SURFACE)."
                         : "Surfaces in contact with themselves and each other (LS-DYNA's "
                           "*CONTACT_AUTOMATIC_SINGLE_SURFACE).",
                     {required(choice("type", {type}, "", type)), surfaces, friction}};
        if (std::string(type) == "surface-to-surface")
            c.keys[1] = required(c.keys[1]);
        c.keys.insert(c.keys.end(), penalty.begin(), penalty.end());
        t.push_back(c);
    }
    t.push_back({"contact.rigid-wall",
                 "contacts: rigid-wall",
                 "A rigid plane wall (LS-DYNA's *RIGIDWALL_PLANAR), penalty form.",
                 {required(choice("type", {"rigid-wall"}, "", "rigid-wall")), surfaces, friction,
                  quantity("damping", dim::none, "0", "Contact damping, a fraction of critical."),
                  required(vec3("point", dim::length, "", "A point of the wall.")),
                  required(vec3("normal", dim::none, "", "The wall's normal, towards the nodes.")),
                  vec3("velocity", dim::velocity, "[0, 0, 0]", "The wall's velocity."),
                  quantity("penalty_scale", dim::none, "0.1", "The penalty scale factor, (0, 0.8].")}});
    t.push_back({"contact.kernel",
                 "contacts: kernel",
                 "Kernel contact between semi-Lagrangian RK parts (or one part's separated particles).",
                 {required(choice("type", {"kernel"}, "", "kernel")), required(surfaces), friction,
                  quantity("thickness", dim::length, "0", "The contact thickness.")}});
    t.push_back({"friction",
                 "friction",
                 "Coulomb friction, mu = dynamic + (static - dynamic) exp(-decay |v_rel|).",
                 {quantity("static", dim::none, "0", "The static coefficient."),
                  quantity("dynamic", dim::none, "", "The dynamic coefficient (default: static)."),
                  quantity("decay", per_velocity, "0", "The exponential decay coefficient.")}});
    t.push_back({"impact",
                 "impact",
                 "A projectile impact: the target and projectile parts and the shot line, for the crater measures in "
                 "summary.json.",
                 {required(text("target", "", "The target part.")), text("projectile", "", "The projectile part."),
                  required(vec3("point", dim::length, "", "The point of impact on the target's surface.")),
                  vec3("direction", dim::none, "[0, 0, -1]", "The shot line's direction, into the target."),
                  quantity("damage", dim::none, "0.95", "The damage at which material counts as gone.")}});
    t.push_back({"spall",
                 "spall",
                 "Spall at a back face: along a line into the part, the depth where the material first cracked "
                 "through and the velocity of the layer behind it (history.csv and summary.json).",
                 {required(text("part", "", "The part.")),
                  required(vec3("point", dim::length, "", "A point of the back face (reference).")),
                  vec3("direction", dim::none, "[0, 0, 1]", "Into the part, normal to the back face."),
                  quantity("damage", dim::none, "0.95", "The nodal damage at which the material has cracked.")}});
    // --- the material-point deck ---
    t.push_back(
        {"material-point",
         "The material-point deck",
         "One material point driven along a strain path (rkfem material-point).",
         {text("title", "", "A line that names the run."),
          required(variants("material", "model", {"material.elastic", "material.j2", "material.kcc", "material.cscm"},
                            "The material.")),
          required(section("path", "path", "The strain path."))}});
    t.push_back(
        {"path",
         "path",
         "The material point's strain path.",
         {required(choice("type",
                          {"uniaxial-stress", "uniaxial-strain", "hydrostatic", "pure-shear", "triaxial", "rotation"},
                          "", "The path.")),
          required(quantity("strain", dim::none, "", "The final strain, nonzero (negative: compression).")),
          required(quantity("rate", per_time, "", "The strain rate, > 0.")),
          quantity("confinement", dim::pressure, "0", "The lateral pressure of a triaxial path."),
          quantity("angle", dim::none, "0", "The rotation path's angle."),
          quantity("length", dim::length, "0", "The crack-band length (0: the model's default)."),
          integer("steps", "1000", "Steps along the path, 1 to 10^8.")}});
    // --- the study file ---
    t.push_back({"study",
                 "The study file",
                 "A study: a base deck, the metrics taken from each run, and the cases (rkfem study).",
                 {text("title", "", "The study's title (default: the file's name)."),
                  text("deck", "", "The base deck, relative to the study file (or give each case its deck)."),
                  required(list_of(KeyKind::Map, "metrics", "", {"study-metric"},
                                   "Named metrics, each one column of the "
                                   "table.")),
                  required(list_of(KeyKind::List, "cases", "", {"study-case"}, "The cases, in the table's order.")),
                  choice("table_rows", {"cases", "metrics"}, "cases", "What the table's rows are.")}});
    t.push_back({"study-metric",
                 "metrics.NAME",
                 "One number from each case's run: a summary.json key, or a history.csv column reduced.",
                 {required(choice("kind",
                                  {"max", "min", "abs_max", "time_of_max", "time_of_min", "time_of_abs_max", "first",
                                   "final", "at", "event_load", "mean", "summary"},
                                  "", "How the number is taken.")),
                  text("column", "", "The history.csv column (every kind but summary)."),
                  text("response", "", "event_load: the response column whose stiffness change marks the event."),
                  text("key", "", "summary: the summary.json key, dotted for nested ones (impact.apparent_depth)."),
                  quantity("time", dim::time, "", "at: the time."),
                  quantity("from", dim::time, "", "mean: the window's start."),
                  quantity("to", dim::time, "", "mean: the window's end."),
                  quantity("fraction", dim::none, "0.1", "event_load: the fraction of the initial stiffness."),
                  quantity("scale", dim::none, "1", "A factor of any dimension (-1, or \"1.27 1/in^2\")."),
                  text("unit", "", "The unit the table shows (a unit expression or %; default SI).")}});
    t.back().keys[8].dim_from_use = true;
    t.push_back({"study-case",
                 "cases[i]",
                 "One run: the base deck with overrides, or its own deck.",
                 {required(text("name", "", "The case's name (a folder under cases/).")),
                  plain(KeyKind::Settings, "set", "Deck key paths to values, as --set takes them."),
                  text("deck", "", "The case's own deck, relative to the study file."),
                  list_of(KeyKind::Map, "published", "", {"study-published"},
                          "Published values by metric name, shown beside ours.")}});
    t.push_back({"study-published",
                 "published.METRIC",
                 "A published value and where it comes from.",
                 {required(quantity("value", dim::none, "", "The value, in the metric's dimension.")),
                  required(text("source", "", "Where it is published (table, figure, page)."))}});
    t.back().keys[0].dim_from_use = true;
    return t;
}
} // namespace

const KeyDoc* SectionDoc::find(std::string_view key) const
{
    for (const auto& k : keys)
        if (k.name == key)
            return &k;
    return nullptr;
}

const std::vector<SectionDoc>& deck_sections()
{
    static const std::vector<SectionDoc> table = build_table();
    return table;
}

const SectionDoc& deck_section(std::string_view id)
{
    for (const auto& s : deck_sections())
        if (s.id == id)
            return s;
    throw std::logic_error("deck key table: no section '" + std::string(id) + "'");
}

std::vector<std::string> deck_section_keys(std::string_view id)
{
    std::vector<std::string> out;
    for (const auto& k : deck_section(id).keys)
        out.push_back(k.name);
    return out;
}
} // namespace rkfem
