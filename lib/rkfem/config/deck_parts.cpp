#include "rkfem/config/deck_section.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "rkfem/core/error.hpp"

namespace rkfem::deck_detail
{
namespace
{
/// A key that another formulation uses (hourglass on an rkpm part): read and checked, then
/// ignored with a note in the resolved deck, so a formulation sweep needs one override per case.
void ignore(PartSpec& p, const Section& s, const std::string& key, const std::string& formulation)
{
    p.ignored.push_back(s.path(key) + " (" + s.loc(key).where + "): formulation " + formulation +
                        " does not use it; ignored");
}

/// conversion.revert: when RK elements return to FE, each measure on the benign side of the
/// conversion's own (so that an element does not go back and forth between checks).
void read_reversion(const Context& ctx, const Section& e, ElementCriteria& c)
{
    Section r(ctx, e.node("revert"), e.path("revert"), "revert");
    ElementCriteria::Reversion& v = c.revert;
    v.scaled_jacobian = r.quantity("scaled_jacobian", dim::none, 0.0);
    if (r.has("scaled_jacobian") && !(v.scaled_jacobian > c.scaled_jacobian && v.scaled_jacobian <= 1.0))
        r.fail("scaled_jacobian", "is not above the conversion's scaled_jacobian and at most 1",
               "expected the smallest scaled corner Jacobian at or above which an element is benign again, above "
               "the conversion's (hysteresis)");
    v.aspect_ratio = r.quantity("aspect_ratio", dim::none, 0.0);
    if (r.has("aspect_ratio") && !(v.aspect_ratio >= 1.0 && (c.aspect_ratio == 0.0 || v.aspect_ratio < c.aspect_ratio)))
        r.fail("aspect_ratio", "is below 1 or not below the conversion's aspect_ratio",
               "expected the edge ratio at or below which an element is benign again");
    v.damage = r.has("damage") ? r.quantity("damage", dim::none) : -1.0;
    if (r.has("damage") && !(v.damage >= 0.0 && (c.damage == 0.0 || v.damage < c.damage)))
        r.fail("damage", "is negative or not below the conversion's damage",
               "expected the damage index at or below which an element is benign again");
    v.plastic_strain = r.has("effective_plastic_strain") ? r.quantity("effective_plastic_strain", dim::none) : -1.0;
    if (r.has("effective_plastic_strain") &&
        !(v.plastic_strain >= 0.0 && (c.plastic_strain == 0.0 || v.plastic_strain < c.plastic_strain)))
        r.fail("effective_plastic_strain", "is negative or not below the conversion's",
               "expected the effective plastic strain at or below which an element is benign again");
    if (!v.active())
        e.fail("revert", "has no measure",
               "expected scaled_jacobian, aspect_ratio, damage or effective_plastic_strain");
}

/// The element criteria under `key` (erosion, conversion): at least one set, none negative.
ElementCriteria read_criteria(const Context& ctx, const Section& s, const std::string& key, const PartSpec& p)
{
    Section e(ctx, s.node(key), s.path(key), "criteria." + key);
    ElementCriteria c;
    if (key == "conversion")
    {
        c.interval = e.quantity("interval", dim::time, 0.0);
        if (!(c.interval >= 0.0 && std::isfinite(c.interval)))
            e.fail("interval", "is negative or not finite", "expected a time >= 0 (0: check after every step)");
        const std::int64_t layers = e.integer("buffer", 0);
        if (layers < 0 || layers > 8)
            e.fail("buffer", "is outside 0-8", "expected the layers of neighbouring elements to convert with them");
        c.buffer = static_cast<int>(layers);
        c.max_per_event = e.integer("max_per_event", 0);
        if (c.max_per_event < 0)
            e.fail("max_per_event", "is negative", "expected a number of elements >= 1 (0: no cap)");
    }
    c.plastic_strain = e.quantity("effective_plastic_strain", dim::none, 0.0);
    c.damage = e.quantity("damage", dim::none, 0.0);
    c.principal_strain = e.quantity("principal_strain", dim::none, 0.0);
    c.volumetric_strain = e.quantity("volumetric_strain", dim::none, 0.0);
    c.time_step = e.quantity("time_step", dim::time, 0.0);
    c.scaled_jacobian = e.quantity("scaled_jacobian", dim::none, 0.0);
    if (!(c.scaled_jacobian >= 0.0 && c.scaled_jacobian < 1.0))
        e.fail("scaled_jacobian", "is outside [0, 1)",
               "expected the smallest scaled corner Jacobian at which an element counts as distorted (1: a box; "
               "0: off)");
    c.aspect_ratio = e.quantity("aspect_ratio", dim::none, 0.0);
    if (!(c.aspect_ratio == 0.0 || (c.aspect_ratio > 1.0 && std::isfinite(c.aspect_ratio))))
        e.fail("aspect_ratio", "is not above 1", "expected the longest over the shortest edge, above 1 (0: off)");
    for (const char* k : {"principal_strain", "volumetric_strain", "time_step"})
        if (e.has(k) && !(e.quantity(k, k == std::string("time_step") ? dim::time : dim::none) >= 0.0))
            e.fail(k, "is negative", "expected a value > 0 (0: off)");
    if (p.material.model == "elastic" && (c.plastic_strain > 0 || c.damage > 0))
        s.fail(key, "effective_plastic_strain and damage need a material with history",
               "expected material model j2, kcc or cscm, or the criteria principal_strain, volumetric_strain, "
               "time_step, scaled_jacobian, aspect_ratio");
    if (!(c.plastic_strain >= 0.0 && std::isfinite(c.plastic_strain)))
        e.fail("effective_plastic_strain", "is negative or not finite", "expected a strain > 0 (0: off)");
    if (!(c.damage >= 0.0 && c.damage <= 1.0))
        e.fail("damage", "is outside [0, 1]", "expected a damage index in (0, 1] (0: off)");
    if (key == "conversion" && e.has("revert"))
        read_reversion(ctx, e, c);
    if (!c.active())
        s.fail(key, "has no criterion",
               "expected effective_plastic_strain, damage, principal_strain, volumetric_strain, time_step, "
               "scaled_jacobian or aspect_ratio > 0");
    return c;
}

/// nodal_integration: scheme, stabilization (its default from the formulation and regions), its coefficient,
/// dt_factor and facet_points, into p.nodal; noted as ignored where the formulation does not use it.
void read_nodal_integration(const Context& ctx, const Section& s, const std::string& f, PartSpec& p)
{
    // the default stabilization of scheme scni: NSNI for RK parts (cheaper per step than MSCNI,
    // the same stable step and the same answers on the seed's P1 and P3; README,
    // nodal_integration; measurements: docs/performance.md), on meshes and clouds; MSCNI where
    // there are no RK second derivatives (fem-nodal, coupled parts)
    const std::string default_stab = p.semi_lagrangian                                         ? "face-gradient"
                                     : p.formulation == Formulation::Rkpm && !s.has("regions") ? "nsni"
                                                                                               : "mscni";
    p.nodal.stabilization = default_stab;
    auto default_coefficient = [](const std::string& stab) {
        return stab == "nsni" ? kNsniCoefficient : stab == "face-gradient" ? kFaceGradientCoefficient : 1.0;
    };
    p.nodal.stabilization_coefficient = default_coefficient(default_stab);
    p.nodal.facet_points = takes_cloud_defaults(p.generator) ? kCloudFacetPoints : "triangles";
    if (p.semi_lagrangian)
        p.nodal.scheme = "snni";
    if (s.has("nodal_integration"))
    {
        if (!is_nodal(p.formulation) && !s.has("regions") && !s.has("conversion"))
            ignore(p, s, "nodal_integration", f); // read (and checked) below, then not used
        Section ni(ctx, s.node("nodal_integration"), s.path("nodal_integration"), "nodal_integration");
        p.nodal.scheme =
            ni.choice("scheme", {"scni", "sd-scni", "dni", "snni", "sd-snni"}, p.semi_lagrangian ? "snni" : "scni");
        const bool sd = p.nodal.scheme == "sd-snni";
        if (p.semi_lagrangian && p.nodal.scheme != "snni" && !sd)
            ni.fail("scheme",
                    "semi-Lagrangian particles are integrated on cells about their current positions (SNNI); " +
                        p.nodal.scheme + " needs cells of the reference configuration",
                    "expected scheme: snni or sd-snni with kinematics: semi-lagrangian");
        if ((p.nodal.scheme == "snni" || sd) &&
            ((p.formulation != Formulation::Rkpm && !p.semi_lagrangian) || s.has("regions")))
            ni.fail("scheme", p.nodal.scheme + " integrates RK particles of an rkpm part on their own cells",
                    "expected scheme: scni, sd-scni or dni on a " + f +
                        (s.has("regions") ? " part with regions" : " part"));
        const bool snni = p.nodal.scheme == "snni";
        p.nodal.stabilization = ni.choice("stabilization", {"mscni", "nsni", "face-gradient", "sub-cells", "none"},
                                          snni                       ? "face-gradient"
                                          : sd                       ? "sub-cells"
                                          : p.nodal.scheme == "scni" ? default_stab
                                                                     : "none");
        if ((p.nodal.stabilization == "face-gradient") != (snni && p.nodal.stabilization != "none"))
            ni.fail("stabilization",
                    snni ? "SNNI is stabilized by face-gradient (or none)" : "face-gradient stabilizes scheme snni",
                    snni ? "expected stabilization: face-gradient or none"
                    : sd ? "expected stabilization: sub-cells or none"
                         : "expected stabilization: mscni, nsni or none");
        if ((p.nodal.stabilization == "sub-cells") != (sd && p.nodal.stabilization != "none"))
            ni.fail("stabilization",
                    sd ? "SD-SNNI is stabilized by its sub-cells (or none)" : "sub-cells stabilizes scheme sd-snni",
                    sd ? "expected stabilization: sub-cells or none" : "expected stabilization: mscni, nsni or none");
        if (p.nodal.stabilization != "none" && p.nodal.scheme != "scni" && p.nodal.scheme != "snni" && !sd)
            ni.fail("stabilization", p.nodal.stabilization + " stabilizes scheme scni only",
                    "expected stabilization: none with scheme " + p.nodal.scheme);
        if (p.nodal.stabilization == "nsni" && (p.formulation != Formulation::Rkpm || s.has("regions")))
            ni.fail("stabilization", "nsni needs the second derivatives of RK shape functions",
                    "expected stabilization: mscni or none on a " + f +
                        (s.has("regions") ? " part with regions" : " part"));
        p.nodal.stabilization_coefficient =
            ni.quantity("stabilization_coefficient", dim::none, default_coefficient(p.nodal.stabilization));
        if (!(p.nodal.stabilization_coefficient >= 0.0))
            ni.fail("stabilization_coefficient", "is negative", "expected c_s >= 0 (1 is the RKPM2D default)");
        p.nodal.dt_factor = ni.quantity("dt_factor", dim::none, 0.0);
        if (!(p.nodal.dt_factor >= 0.0 && p.nodal.dt_factor <= 2.0))
            ni.fail("dt_factor", "is outside [0, 2]", "expected alpha in (0, 2], or 0 for the calibrated default");
        p.nodal.plastic_scaling = ni.choice("plastic_scaling", {"true", "false"}, "false") == "true";
        if (p.nodal.plastic_scaling && (snni || sd))
            ni.fail("plastic_scaling", "scales the stabilization of Lagrangian nodal integration (mscni, nsni)",
                    "expected semi_lagrangian.plastic_scaling on a semi-Lagrangian part");
        p.nodal.facet_points = ni.choice("facet_points", {"triangles", "faces"}, p.nodal.facet_points);
        if (p.nodal.facet_points == "faces" && p.generator.type != GeneratorSpec::Type::Cloud)
            ni.fail("facet_points", "faces chooses the points on a cloud's Voronoi faces, and this part is a mesh",
                    "expected facet_points: triangles (or none) on a mesh part; its nodal cells' facets take 2 x 2 "
                    "Gauss points");
    }
}

/// kinematics (lagrangian | semi-lagrangian, rkpm parts) and semi_lagrangian.neighbour_skin, into p.
void read_kinematics(const Context& ctx, const Section& s, PartSpec& p)
{
    p.semi_lagrangian = s.choice("kinematics", {"lagrangian", "semi-lagrangian"}, "lagrangian") == "semi-lagrangian";
    // a converting fem-1pt part's RK regions may be semi-Lagrangian: its converted elements' nodes
    // become particles with kernels in the current configuration (Model::convert_to_semi_lagrangian)
    const bool converting = p.formulation == Formulation::Fem1pt && p.converts();
    if (p.semi_lagrangian && p.formulation != Formulation::Rkpm && !converting)
        s.fail("kinematics", "semi-lagrangian moves the kernels of RK particles with the material",
               "expected formulation: rkpm with kinematics: semi-lagrangian (or kinematics: lagrangian), or "
               "formulation: fem-1pt with conversion (its RK regions semi-Lagrangian)");
    if (p.semi_lagrangian && converting && s.has("regions"))
        s.fail("regions", "are Lagrangian RK regions, and this converting part's RK regions are semi-Lagrangian",
               "expected regions or kinematics: semi-lagrangian on a fem-1pt part, not both");
    if (p.semi_lagrangian && converting && p.conversion.revert.active())
        s.fail("conversion", "turns semi-Lagrangian particles back into FE elements (revert), which is not built",
               "expected conversion without revert on a part with kinematics: semi-lagrangian");
    if (!s.has("semi_lagrangian"))
        return;
    if (!p.semi_lagrangian)
        s.fail("semi_lagrangian", "sets up semi-Lagrangian RK particles, and this part's kinematics is lagrangian",
               "expected kinematics: semi-lagrangian with a semi_lagrangian section");
    Section sl(ctx, s.node("semi_lagrangian"), s.path("semi_lagrangian"), "semi_lagrangian");
    p.neighbour_skin = sl.quantity("neighbour_skin", dim::none, 0.3);
    if (!(p.neighbour_skin >= 0.0 && p.neighbour_skin <= 2.0))
        sl.fail("neighbour_skin", "is outside [0, 2]",
                "expected the skin as a fraction of the largest support radius (0: rebuild every step; 0.3 default)");
    const real_t every = sl.quantity("reset_interval", dim::none, 1.0);
    if (!(every >= 1.0 && every <= 1e6 && every == std::floor(every)))
        sl.fail("reset_interval", "is not a whole number of steps from 1 to 10^6",
                "expected 1 (kernels rebuilt every step) or N > 1 (Lagrangian RK reset to the current configuration "
                "every N steps)");
    p.reset_interval = static_cast<index_t>(every);
    if (converting && p.reset_interval > 1)
        sl.fail("reset_interval", "resets a reference that particles made by conversion do not have",
                "expected reset_interval: 1 on a converting part");
    p.separation_damage = sl.quantity("separation_damage", dim::none, 0.0);
    if (!(p.separation_damage >= 0.0 && p.separation_damage <= 1.0))
        sl.fail("separation_damage", "is outside [0, 1]",
                "expected the damage index (K&C D, J2 failure, CSCM d; 0..1) at which a particle separates, such "
                "as 0.99 (0: never)");
    if (p.separation_damage > 0.0 && p.reset_interval > 1)
        sl.fail("separation_damage",
                "separates particles from kernels rebuilt every step, and reset_interval is " +
                    std::to_string(p.reset_interval),
                "expected reset_interval: 1 with separation_damage");
    p.sl_plastic_scaling = sl.choice("plastic_scaling", {"true", "false"}, "false") == "true";
    if (p.sl_plastic_scaling && p.reset_interval > 1)
        sl.fail("plastic_scaling",
                "scales the face terms of tables rebuilt every step, and reset_interval is " +
                    std::to_string(p.reset_interval) + " (between resets the nodal blocks' stabilization is unscaled)",
                "expected reset_interval: 1 with plastic_scaling: true");
}

/// A list of volumes (box, cylinder or sphere selectors) under `key`: RK regions (each with its
/// formulation) or refinement's regions.
std::vector<SelectorSpec> read_volumes(const Context& ctx, const Section& s, const std::string& key,
                                       bool with_formulation)
{
    const YAML::Node rn = s.node(key);
    if (!rn.IsSequence() || rn.size() == 0)
        s.fail(key, "is not a non-empty list",
               "expected " + key + ": [{select: {type: box | cylinder | sphere, ...}}]");
    std::vector<SelectorSpec> out;
    for (std::size_t i = 0; i < rn.size(); ++i)
    {
        Section r(ctx, rn[i], s.path(key) + "." + std::to_string(i), "region");
        if (with_formulation)
            r.choice("formulation", {"rkpm"}, "rkpm");
        SelectorSpec sel = read_selector(r);
        if (sel.type != SelectorSpec::Type::Box && sel.type != SelectorSpec::Type::Cylinder &&
            sel.type != SelectorSpec::Type::Sphere)
            r.fail("select", "a region is a volume", "expected select type box, cylinder or sphere");
        out.push_back(sel);
    }
    return out;
}

/// refinement: the indicator, thresholds, levels, pool and region of a semi-Lagrangian part's
/// particle splitting and merging, into p.refinement.
void read_refinement(const Context& ctx, const Section& s, PartSpec& p)
{
    if (!(p.formulation == Formulation::Rkpm && p.semi_lagrangian) && !p.converts_to_semi_lagrangian())
        s.fail("refinement", "splits semi-Lagrangian RK particles",
               "expected formulation: rkpm with kinematics: semi-lagrangian on a part with refinement");
    if (p.reset_interval > 1)
        s.fail("refinement",
               "splits particles whose tables are rebuilt every step, and reset_interval is " +
                   std::to_string(p.reset_interval),
               "expected semi_lagrangian.reset_interval: 1 with refinement");
    if (p.nodal.scheme == "sd-snni")
        s.fail("refinement", "splits SNNI cells; SD-SNNI's sub-cells are not split with them",
               "expected nodal_integration.scheme: snni with refinement");
    Section r(ctx, s.node("refinement"), s.path("refinement"), "refinement");
    RefinementSpec& f = p.refinement;
    f.loc = r.loc();
    // one indicator, given as its threshold (the keys of conversion's criteria)
    int given = 0;
    for (const RefinementSpec::Indicator ind : RefinementSpec::kIndicators)
        if (const char* key = RefinementSpec::key(ind); r.has(key))
        {
            ++given;
            f.indicator = ind;
            f.threshold = r.quantity(key, RefinementSpec::is_stress(ind) ? dim::pressure : dim::none);
            if (!(f.threshold > 0.0))
                r.fail(key, "is not positive", "expected the value at which a particle splits, > 0");
        }
    if (given != 1)
        r.fail(given == 0 ? "damage" : "pressure", given == 0 ? "is missing" : "is one of several indicators given",
               "expected exactly one of damage, effective_plastic_strain, pressure or von_mises: the value of "
               "that indicator at which a particle splits");
    const real_t fraction = r.quantity("coarsen_fraction", dim::none, -1.0);
    if (r.has("coarsen_fraction") && !(fraction >= 0.0 && fraction < 1.0))
        r.fail("coarsen_fraction", "is not in [0, 1)",
               "expected the fraction of the threshold below which eight siblings merge back");
    f.coarsen_below = r.has("coarsen_fraction") ? fraction * f.threshold : -1.0;
    const long long levels = r.integer("max_level", 1);
    if (levels < 1 || levels > 2)
        r.fail("max_level", "is not 1 or 2",
               "expected 1 or 2 (each level halves the spacing and the stable step; the digest's limit is 2)");
    f.max_level = static_cast<int>(levels);
    f.max_new_particles = r.integer("max_new_particles", 0);
    if (f.max_new_particles < 0 || f.max_new_particles % 7 != 0)
        r.fail("max_new_particles", "is not a non-negative multiple of 7",
               "expected the particles the part may gain, 7 per split (0: 7 per particle of the start)");
    f.interval = r.quantity("interval", dim::time, 0.0);
    if (!(f.interval >= 0.0))
        r.fail("interval", "is negative", "expected the time between checks (0: after every step)");
    if (r.has("region"))
        f.region = read_volumes(ctx, r, "region", false);
}

/// regions: the RK volumes (box, cylinder or sphere selectors) of an FE part, into p.regions.
void read_regions(const Context& ctx, const Section& s, PartSpec& p)
{
    // FE-RK coupling: the RK regions of an FE part
    if (p.formulation != Formulation::FemNodal && p.formulation != Formulation::Fem1pt)
        s.fail("regions", "RK regions are coupled to an FE side of formulation fem-nodal or fem-1pt",
               "expected formulation: fem-nodal or fem-1pt on a part with regions");
    if (p.generator.type == GeneratorSpec::Type::Cloud)
        s.fail("regions", "a cloud part has no elements to divide", "remove regions");
    p.regions_loc = s.loc("regions");
    p.regions = read_volumes(ctx, s, "regions", true);
}

/// rk: order, kernel, support, normalized_support, drop_tolerance and share_translates of the RK shape
/// functions, into p.rk; noted as ignored where the formulation does not use it.
void read_rk(const Context& ctx, const Section& s, const std::string& f, PartSpec& p)
{
    if (p.formulation != Formulation::Rkpm && !p.coupled() && !p.semi_lagrangian)
        ignore(p, s, "rk", f);
    Section r(ctx, s.node("rk"), s.path("rk"), "rk");
    p.rk.loc = r.loc();
    const std::string order = r.choice("order", {"1", "2"}, "1");
    p.rk.order = order == "1" ? 1 : 2;
    p.rk.kernel = r.choice("kernel", {"cubic-bspline", "quintic-bspline", "gaussian"}, "cubic-bspline");
    p.rk.support = r.choice("support", {"box", "sphere"}, "box");
    p.rk.normalized_support = r.quantity("normalized_support", dim::none, p.rk.normalized_support);
    p.rk.drop_tolerance = r.quantity("drop_tolerance", dim::none, p.rk.order == 1 ? 1e-5 : 0.0);
    if (!(p.rk.drop_tolerance >= 0.0 && p.rk.drop_tolerance <= 1e-2))
        r.fail("drop_tolerance", "is outside [0, 0.01]",
               "expected a small fraction such as 1e-5 (0: keep every function)");
    p.rk.share_translates = r.choice("share_translates", {"true", "false"}, "true") == "true";
    if (p.rk.drop_tolerance > 0.0 && p.rk.order != 1)
        r.fail("drop_tolerance", "restores linear reproduction only", "expected drop_tolerance: 0 with order 2");
    const real_t c = p.rk.normalized_support;
    if (!(c >= 1.0 && c <= 4.0))
        r.fail("normalized_support", "is outside [1, 4]",
               "expected a / h between 1 and 4 (box 1.5-1.8, sphere 1.6-2.0)");
    if (std::abs(c - std::round(c)) < 1e-6)
        r.fail("normalized_support",
               "is an integer, which puts neighbours exactly on the support boundary of uniform grids",
               "expected a non-integer value such as " + std::to_string(std::round(c)).substr(0, 1) + ".01");
}

/// hourglass: type, coefficient and plastic_scaling of the hourglass control, into p.hourglass; noted as ignored
/// where the formulation does not use it.
void read_hourglass(const Context& ctx, const Section& s, const std::string& f, PartSpec& p)
{
    if (p.formulation != Formulation::Fem1pt)
        ignore(p, s, "hourglass", f);
    Section h(ctx, s.node("hourglass"), s.path("hourglass"), "hourglass");
    const std::string t =
        h.choice("type", {"viscous", "stiffness", "assumed-strain", "none", "viscous-plain"}, "viscous");
    p.hourglass.type = t == "viscous"          ? HourglassType::Viscous
                       : t == "stiffness"      ? HourglassType::Stiffness
                       : t == "assumed-strain" ? HourglassType::AssumedStrain
                       : t == "none"           ? HourglassType::None
                                               : HourglassType::ViscousPlain;
    p.hourglass.coefficient = h.quantity("coefficient", dim::none, 0.1);
    p.hourglass.plastic_scaling =
        h.choice("plastic_scaling", {"true", "false"},
                 p.hourglass.type == HourglassType::AssumedStrain ? "true" : "false") == "true";
    if (h.has("plastic_scaling") && p.hourglass.type != HourglassType::Stiffness &&
        p.hourglass.type != HourglassType::AssumedStrain)
        h.fail("plastic_scaling", "applies to the stiffness forms only",
               "expected type: stiffness or assumed-strain with plastic_scaling");
    if (!(p.hourglass.coefficient >= 0.0))
        h.fail("coefficient", "is negative", "expected QM >= 0 (LS-DYNA default 0.1)");
}
} // namespace

PartSpec read_part(const Context& ctx, const std::string& name, const YAML::Node& n, const std::string& path)
{
    Section s(ctx, n, path, "part");
    PartSpec p;
    p.name = name;
    p.loc = s.loc();
    p.generator = read_generator(s);
    // the cloud defaults (nodal_integration_spec.hpp), on jittered clouds and points files
    if (takes_cloud_defaults(p.generator))
        p.rk.normalized_support = kCloudNormalizedSupport;
    p.material = read_material(s);
    const std::string f = s.choice("formulation", {"fem-1pt", "fem-2x2x2", "fem-nodal", "rkpm"}, "fem-1pt");
    p.formulation = f == "fem-1pt"     ? Formulation::Fem1pt
                    : f == "fem-2x2x2" ? Formulation::Fem2x2x2
                    : f == "fem-nodal" ? Formulation::FemNodal
                                       : Formulation::Rkpm;
    if (s.has("conversion"))
    {
        // evolutionary coupling: fem-nodal state lives at the nodes on both sides, so conversion
        // moves none; a fem-1pt element's state goes to the particles that take its octants
        // (PlasticPoints::blend_point), which CSCM's history has no mean for
        if (p.formulation != Formulation::FemNodal && p.formulation != Formulation::Fem1pt)
            s.fail("conversion", "turns elements of fem-nodal or fem-1pt parts into RK particles",
                   "expected formulation: fem-nodal or fem-1pt on a part with conversion");
        if (p.formulation == Formulation::Fem1pt && p.material.model == "cscm")
            s.fail("conversion",
                   "moves a fem-1pt element's state to the particles by volume-weighted means, which CSCM's "
                   "history (thresholds set at first yield) has none of",
                   "expected formulation: fem-nodal for a converting CSCM part, or material model elastic, j2 or kcc");
        p.conversion = read_criteria(ctx, s, "conversion", p);
    }
    read_kinematics(ctx, s, p);
    read_nodal_integration(ctx, s, f, p);
    if (p.generator.type == GeneratorSpec::Type::Cloud)
    {
        // a cloud has no elements: RK particles integrated on their Voronoi cells
        if (p.formulation != Formulation::Rkpm)
            s.fail("formulation", "'" + f + "' needs elements, and a cloud part has none",
                   "expected formulation: rkpm");
    }
    if (s.has("regions"))
        read_regions(ctx, s, p);
    if (p.coupled())
    {
        p.transition = s.choice("transition", {"mixed", "ramp"}, "mixed");
        p.nodal.scheme = s.has("nodal_integration") ? p.nodal.scheme : "scni";
        if (p.nodal.scheme != "scni")
            s.fail("nodal_integration", "a coupled part is integrated by scheme scni (with or without mscni)",
                   "expected nodal_integration.scheme: scni");
    }
    else if (s.has("transition"))
        s.fail("transition", "is only used by parts with regions or conversion", "remove it or add regions");
    if (s.has("rk"))
        read_rk(ctx, s, f, p);
    if (s.has("refinement"))
        read_refinement(ctx, s, p);
    if (s.has("hourglass"))
        read_hourglass(ctx, s, f, p);
    if (p.formulation != Formulation::Fem1pt)
        p.hourglass.type = HourglassType::None;
    if (s.has("bulk_viscosity"))
    {
        Section b(ctx, s.node("bulk_viscosity"), s.path("bulk_viscosity"), "bulk_viscosity");
        p.bulk_viscosity.linear = b.quantity("linear", dim::none, 0.06);
        p.bulk_viscosity.quadratic = b.quantity("quadratic", dim::none, 1.5);
        if (p.bulk_viscosity.linear < 0 || p.bulk_viscosity.quadratic < 0)
            b.fail(p.bulk_viscosity.linear < 0 ? "linear" : "quadratic", "is negative", "expected a coefficient >= 0");
    }
    p.initial_velocity = s.vec3("initial_velocity", dim::velocity, Vec3::Zero());
    if (s.has("erosion"))
    {
        if (p.formulation != Formulation::Fem1pt && p.formulation != Formulation::Fem2x2x2)
            s.fail("erosion", "erodes elements of Gauss-point formulations only",
                   "expected formulation fem-1pt or fem-2x2x2 on a part with erosion");
        if (s.has("conversion"))
            s.fail("erosion", "deletes elements that a converting part turns into RK particles instead",
                   "expected erosion or conversion on a part, not both");
        p.erosion = read_criteria(ctx, s, "erosion", p);
    }
    return p;
}
} // namespace rkfem::deck_detail
