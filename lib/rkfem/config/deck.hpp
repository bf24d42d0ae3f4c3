#pragma once
/// @file deck.hpp
/// The input deck as typed structs. A YAML deck is parsed once, at the boundary, by read_deck();
/// every value is SI from then on. Each spec remembers the deck line it came from so that errors
/// found later (empty node set, inverted element) still name the line.
#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "rkfem/approximation/rk/rk_spec.hpp"
#include "rkfem/config/time_function.hpp"
#include "rkfem/core/input_error.hpp"
#include "rkfem/core/types.hpp"
#include "rkfem/discretization/formulation.hpp"
#include "rkfem/discretization/generator_spec.hpp"
#include "rkfem/integration/nodal/nodal_integration_spec.hpp"
#include "rkfem/io/output_spec.hpp"
#include "rkfem/materials/rate_law.hpp"
#include "rkfem/operators/bulk_viscosity.hpp"
#include "rkfem/operators/hourglass.hpp"
#include "rkfem/time/time_spec.hpp"

namespace rkfem
{

/// Material of a part: `elastic` (hypoelastic, Jaumann rate), `j2` (piecewise-linear J2
/// plasticity with Cowper-Symonds rate scaling and failure, LS-DYNA MAT_024 analog) or `kcc`
/// (K&C concrete Release III with every parameter generated from f'c).
struct MaterialSpec
{
    std::string model = "elastic";
    real_t rho = 0.0; ///< density [kg/m^3]
    real_t E = 0.0;   ///< Young's modulus [Pa]
    real_t nu = 0.0;  ///< Poisson's ratio [-]
    // j2
    real_t sigy = 0.0;                            ///< initial yield stress [Pa]
    real_t etan = 0.0;                            ///< tangent modulus of the total-strain curve [Pa] (bilinear)
    std::vector<std::pair<real_t, real_t>> curve; ///< (eps_p, sigma_y [Pa]); overrides sigy/etan
    real_t cs_c = 0.0, cs_p = 0.0;                ///< Cowper-Symonds C [1/s], P
    real_t fail = 0.0;                            ///< failure plastic strain (0: none)
    std::string eos_type;                         ///< j2: "" (incremental bulk), linear, gruneisen
    real_t eos_c0 = 0.0, eos_s = 0.0, eos_gamma0 = 0.0, eos_a = 0.0; ///< gruneisen
    // kcc (K&C concrete) and cscm (cap model): parameters generated from f'c; E and nu optional
    real_t fc = 0.0;
    bool rate_effects = false;    ///< cscm; kcc: rate_law.active()
    RateLaw rate_law;             ///< kcc: the DIF law (rate_effects: true | false | {law | curve, caps})
    real_t fracture_energy = 0.0; ///< G_f [J/m^2] for the crack-band scaling of b2; < 0: CEB-FIP (auto); 0: none
    /// kcc: the damage table (lambda, eta) and the EOS_8 table (10 strains <= 0, decreasing;
    /// pressures; unloading bulk moduli) in place of the generated ones (empty: generated)
    std::vector<std::pair<real_t, real_t>> kcc_eta;
    std::vector<real_t> kcc_eos_strain, kcc_eos_pressure, kcc_eos_unload;
    /// cscm: named parameter overrides of the generated set (alpha, theta, lambda, beta, R, X0, W,
    /// D1, D2, B, D, Gfc, length), SI
    std::vector<std::pair<std::string, real_t>> overrides;
    SourceLocation loc;
};

/// Per-element criteria read after each step from committed values (point averages over the
/// element, its nodes' points on nodal parts) and the element's shape; an element meets them
/// when any set criterion is met (0: off). Erosion removes such elements (LS-DYNA
/// *MAT_ADD_EROSION analog); conversion turns them into RK particles (seed Table 1, feature 4).
struct ElementCriteria
{
    real_t plastic_strain = 0.0;    ///< effective plastic strain
    real_t damage = 0.0;            ///< 0..1 damage index (K&C: delta - 1; CSCM d; J2: failed)
    real_t principal_strain = 0.0;  ///< largest principal logarithmic strain ln(lambda_max) (MXEPS)
    real_t volumetric_strain = 0.0; ///< V / V0 - 1, tension (VOLEPS)
    real_t time_step = 0.0;         ///< element step (V / A_max) / c below this [s] (DTMIN)
    /// the element's smallest scaled corner Jacobian, det(e1, e2, e3) / (|e1| |e2| |e3|) of the
    /// three edges at each corner, at or below this (1 for a box, 1 / sqrt(1 + gamma^2) sheared
    /// by gamma; 0: off)
    real_t scaled_jacobian = 0.0;
    real_t aspect_ratio = 0.0; ///< the longest of the 12 edges over the shortest at or above this (0: off)
    /// conversion only: the criteria are checked at the first step end at or past each multiple
    /// of this time [s] (0: after every step), so that elements convert in fewer, larger events
    real_t interval = 0.0;
    /// conversion only: layers of elements sharing a node with the triggered ones that convert
    /// with them (a buffer, so the RK region leads the distortion)
    int buffer = 0;
    /// conversion only: at most this many elements per event (0: no cap), the triggered ones
    /// first, then the buffer's, each in element order; the rest wait for the next check
    std::int64_t max_per_event = 0;
    /// conversion only: RK elements return to FE (seed Table 1 feature 4, both directions) where
    /// every measure given is benign at a check: the smallest scaled corner Jacobian at or above
    /// `scaled_jacobian`, the aspect ratio at or below `aspect_ratio`, the damage at or below
    /// `damage`, the effective plastic strain at or below `plastic_strain` (negative: not checked),
    /// and no element within `buffer` layers of node neighbours still needs RK
    struct Reversion
    {
        real_t scaled_jacobian = 0.0;
        real_t aspect_ratio = 0.0;
        real_t damage = -1.0;
        real_t plastic_strain = -1.0;
        bool active() const { return scaled_jacobian > 0 || aspect_ratio > 0 || damage >= 0 || plastic_strain >= 0; }
    } revert;
    bool active() const { return plastic_strain > 0 || damage > 0 || geometric(); }
    /// a criterion on the element's shape (a pass over its nodes per step)
    bool geometric() const
    {
        return principal_strain > 0 || volumetric_strain > 0 || time_step > 0 || scaled_jacobian > 0 ||
               aspect_ratio > 0;
    }
};

/// Geometric predicate or generator name selecting nodes (or faces whose 4 nodes all match).
struct SelectorSpec
{
    enum class Type
    {
        Named,    ///< generator set name: top, bottom, side, xmin, ..., nose, tail, all
        Plane,    ///< |(x - point) . n| <= tolerance
        Box,      ///< min <= x <= max (componentwise, with tolerance)
        Cylinder, ///< | distance to axis - radius | <= tolerance
        Sphere,   ///< |x - point| <= radius
        Ids,      ///< nodes whose keyword-file NID is in `ids` (keyword meshes; faces: all four nodes)
        Segments, ///< faces whose four NIDs are one of `segments`, in any order (keyword meshes)
    };
    Type type = Type::Named;
    std::string name;
    Vec3 point = Vec3::Zero();
    Vec3 normal = Vec3::UnitZ(); ///< plane normal or cylinder axis direction
    Vec3 min = Vec3::Zero();
    Vec3 max = Vec3::Zero();
    real_t radius = 0.0;
    real_t tolerance = -1.0;                        ///< < 0: 1e-6 of the part's bounding-box diagonal
    std::vector<long long> ids;                     ///< Ids: NIDs, sorted, each once
    std::vector<std::array<long long, 4>> segments; ///< Segments: each sorted; the list sorted
};

/// Adaptive refinement of a semi-Lagrangian RK part (issue #49; digest rkpm-methods.md section 6):
/// a particle whose indicator reaches `threshold` at a check splits into the eight half-size
/// parallelepipeds of its cell (Model::refine_particles), and eight siblings whose indicators have
/// all fallen below `coarsen_below` merge back into one (Model::coarsen_particles). The deck names
/// the indicator by its key (`pressure: 100 MPa`) and coarsening as a fraction of it.
struct RefinementSpec
{
    enum class Indicator
    {
        Damage,                 ///< the material's 0..1 damage index (PlasticPoints::damage)
        EffectivePlasticStrain, ///< the effective plastic strain
        Pressure,               ///< |p| [Pa]: where a stress wave or a penetrator's front is
        VonMises,               ///< sqrt(3 J2) [Pa]
    };
    static constexpr Indicator kIndicators[] = {Indicator::Damage, Indicator::EffectivePlasticStrain,
                                                Indicator::Pressure, Indicator::VonMises};
    /// The deck key that names an indicator (and gives its threshold)
    static const char* key(Indicator i)
    {
        constexpr const char* names[] = {"damage", "effective_plastic_strain", "pressure", "von_mises"};
        return names[static_cast<int>(i)];
    }
    /// Whether an indicator is a stress (its threshold has units of pressure)
    static bool is_stress(Indicator i) { return i == Indicator::Pressure || i == Indicator::VonMises; }
    Indicator indicator = Indicator::Damage;
    real_t threshold = 0.0;      ///< split at or above this (0: no refinement)
    real_t coarsen_below = -1.0; ///< merge siblings all below this (negative: never)
    int max_level = 1;           ///< splits a particle of the start may go through (1 or 2)
    /// particles the part may gain (the pool of dormant particles reserved at set-up; 0: seven per
    /// particle of the start, enough for every particle to split once)
    std::int64_t max_new_particles = 0;
    real_t interval = 0.0;            ///< checks at the first step end at or past each multiple [s] (0: every step)
    std::vector<SelectorSpec> region; ///< only particles inside one of these volumes split (empty: all)
    SourceLocation loc;
    bool active() const { return threshold > 0.0; }
};

struct PartSpec
{
    std::string name;
    GeneratorSpec generator;
    MaterialSpec material;
    Formulation formulation = Formulation::Fem1pt;
    /// rkpm parts: kernels in the reference configuration (false, total Lagrangian) or in the
    /// current one (`kinematics: semi-lagrangian`, operators/semi_lagrangian_block.hpp)
    bool semi_lagrangian = false;
    /// semi-Lagrangian parts: the neighbour lists' skin as a fraction of the largest support
    real_t neighbour_skin = 0.3;
    /// semi-Lagrangian parts: 1, tables rebuilt every step; N > 1, Lagrangian RK with a
    /// reference reset every N steps
    index_t reset_interval = 1;
    /// semi-Lagrangian parts: the damage index at which a particle leaves the kernels (0: never)
    real_t separation_damage = 0.0;
    /// semi-Lagrangian parts rebuilt every step: the face-gradient terms' loads scaled by the share
    /// of the step the material took elastically (SemiLagrangianOptions::plastic_scaling)
    bool sl_plastic_scaling = false;
    HourglassSpec hourglass;
    BulkViscositySpec bulk_viscosity;
    NodalIntegrationSpec nodal;
    RkSpec rk;
    Vec3 initial_velocity = Vec3::Zero();
    /// RK regions of an FE part (FE-RK coupling): elements whose centroid lies in any of them
    /// are RK (box, cylinder: within radius of the axis, sphere); empty: a single-kind part.
    ElementCriteria erosion;
    /// Evolutionary coupling (seed Table 1, feature 4): elements that meet these criteria turn
    /// into RK particles between steps (fem-nodal parts: the state stays at the nodes).
    ElementCriteria conversion;
    bool converts() const { return conversion.active(); }
    /// Adaptive refinement and coarsening (semi-Lagrangian rkpm parts)
    RefinementSpec refinement;
    std::vector<SelectorSpec> regions;
    std::string transition = "mixed"; ///< mixed | ramp (coupled parts)
    SourceLocation regions_loc;       ///< where `regions` is given
    /// Keys of another formulation given for this part (hourglass on rkpm, rk or
    /// nodal_integration on fem-1pt): checked, then ignored; one note each, in the resolved deck
    std::vector<std::string> ignored;
    SourceLocation loc;

    /// FE and RK in one part on one nodal block: RK regions, or conversion that makes Lagrangian
    /// ones during the run.
    bool coupled() const { return !regions.empty() || (converts() && !semi_lagrangian); }
    /// A fem-1pt part whose conversion makes semi-Lagrangian particles (an FE block and a block
    /// of particles, dormant until their elements convert).
    bool converts_to_semi_lagrangian() const { return converts() && semi_lagrangian; }
};

struct SetSpec
{
    std::string name;
    std::string part; ///< "" = every part
    SelectorSpec select;
    SourceLocation loc;
};

struct BoundarySpec
{
    enum class Kind
    {
        Fixed,
        Velocity,
        Displacement
    };
    Kind kind = Kind::Fixed;
    std::string node_set;
    std::array<bool, 3> active{false, false, false};
    std::array<TimeFunction, 3> value; ///< per component (velocity [m/s] or displacement [m])
    SourceLocation loc;
};

struct LoadSpec
{
    enum class Kind
    {
        NodalForce,
        Pressure
    };
    Kind kind = Kind::NodalForce;
    std::string set; ///< node set (nodal force) or face set (pressure)
    std::array<bool, 3> active{false, false, false};
    std::array<TimeFunction, 3> force; ///< nodal force per component [N]
    bool total = false;                ///< nodal force: value is the total, split equally
    TimeFunction pressure;             ///< pressure [Pa], positive pushes into the body
    SourceLocation loc;
};

struct ProbeSpec
{
    std::string name;
    Vec3 point = Vec3::Zero();
    std::string part; ///< "" = nearest node of any part
    SourceLocation loc;
};

/// A cross-section (deck key sections, LS-DYNA's *DATABASE_CROSS_SECTION_PLANE / SECFORC): the
/// nodes of `part` (all parts when empty) with (X - point) . normal >= -tolerance in the reference
/// configuration form the positive side; its force is what the material on the negative side
/// exerts on them.
struct SectionSpec
{
    std::string name;
    Vec3 point = Vec3::Zero(), normal = Vec3::UnitZ();
    std::string part;
    real_t tolerance = -1.0; ///< < 0: 1e-6 of the part's size
    SourceLocation loc;
};

/// One contact definition (deck key contacts): LS-DYNA's *CONTACT_AUTOMATIC_SURFACE_TO_SURFACE,
/// *CONTACT_AUTOMATIC_SINGLE_SURFACE and *RIGIDWALL_PLANAR (penalty) analogs.
struct ContactSpec
{
    enum class Kind
    {
        SurfaceToSurface,
        SingleSurface,
        RigidWall,
        Kernel ///< semi-Lagrangian RK bodies sharing normal velocities (contact/kernel_contact.hpp)
    };
    Kind kind = Kind::SurfaceToSurface;
    /// Part or face-set names: surface-to-surface two (each a part's boundary or a face set),
    /// single-surface and rigid-wall any number (their union; empty: every part); kernel two
    /// semi-Lagrangian RK parts, or one (its separated particles against it and each other)
    std::vector<std::string> surfaces;
    bool soft = true;             ///< stiffness: soft (max of segment and soft, SOFT = 1) | segment
    bool mortar = false;          ///< formulation: node-to-segment | mortar (surface-to-surface)
    real_t penalty_scale = 0.1;   ///< SLSFAC (segment stiffness K A / h); rigid wall: scale of m / dt0^2
    real_t soft_scale = 0.1;      ///< SOFSCL (soft stiffness m* / dt^2)
    real_t thickness = 0.0;       ///< [m]
    real_t max_penetration = 0.5; ///< of the element depth behind a segment
    real_t mu_static = 0.0, mu_dynamic = 0.0;
    real_t decay = 0.0; ///< [s/m]
    /// Viscous damping of the normal approach, fraction of critical (LS-DYNA's VDC / 100): 0..1
    real_t damping = 0.0;
    Vec3 point = Vec3::Zero(), normal = Vec3::UnitZ(), velocity = Vec3::Zero(); ///< rigid wall
    SourceLocation loc;
};

/// Impact measures (deck key impact): crater depths along the shot line, what the projectile
/// keeps and gives (analysis/impact.hpp).
struct ImpactSpec
{
    bool active = false;
    std::string target;              ///< the struck part
    std::string projectile;          ///< optional
    Vec3 point = Vec3::Zero();       ///< the point of impact on the target's original surface
    Vec3 direction = -Vec3::UnitZ(); ///< the shot line, into the target (unit)
    real_t damage = 0.95;            ///< actual crater: material at or above this damage is gone
    SourceLocation loc;
};

/// Spall measures (deck key spall; analysis/spall.hpp): along a line into a part from a point on
/// its back face, where the material has cracked through and how fast the layer behind flies off.
struct SpallSpec
{
    bool active = false;
    std::string part;
    Vec3 point = Vec3::Zero();      ///< a point of the back face (reference)
    Vec3 direction = Vec3::UnitZ(); ///< into the part, normal to the back face (unit)
    real_t damage = 0.95;           ///< the crack: nodal damage at or above this
    SourceLocation loc;
};

struct Deck
{
    std::string path;
    std::string title;
    TimeSpec time;
    OutputSpec output;
    std::vector<PartSpec> parts;
    std::vector<SetSpec> node_sets;
    std::vector<SetSpec> face_sets;
    std::vector<BoundarySpec> boundary_conditions;
    std::vector<LoadSpec> loads;
    std::vector<ProbeSpec> probes;
    std::vector<SectionSpec> sections;
    std::vector<ContactSpec> contacts;
    ImpactSpec impact;
    SpallSpec spall;
    SourceLocation time_loc;
};

/// A material-point deck (rkfem material-point): one material driven along a strain path.
struct MaterialPathSpec
{
    std::string type =
        "uniaxial-stress";    ///< uniaxial-stress | uniaxial-strain | hydrostatic | pure-shear | triaxial | rotation
    real_t strain = 0.0;      ///< final axial (volumetric, engineering shear) strain; < 0 compression
    real_t rate = 1.0;        ///< strain rate magnitude [1/s]
    real_t confinement = 0.0; ///< triaxial: lateral pressure [Pa]
    real_t angle = 0.0;       ///< rotation: rigid rotation about z after the strain [rad]
    real_t length = 0.0;      ///< crack-band length of the point (K&C b2, CSCM softening); 0: model default
    int steps = 1000;
    SourceLocation loc;
};

struct MaterialPointDeck
{
    std::string path;
    std::string title;
    MaterialSpec material;
    MaterialPathSpec load_path;
};

/// The text of a deck file: refuses, with a DeckError, what is not a regular file (devices,
/// FIFOs, directories) or is past 64 MB. `expected` completes the message.
std::string read_deck_text(const std::string& path, const std::string& expected);

/// Reads a material-point deck (keys title, material, path). Throws DeckError.
MaterialPointDeck read_material_point_deck(const std::string& path);

/// Reads and validates a deck. `overrides` are "key.path=value" strings applied to the YAML tree
/// before validation (sequence entries by index: loads.0.pressure=...). Throws DeckError.
Deck read_deck(const std::string& path, const std::vector<std::string>& overrides = {});

/// Same, from text (`name` is used in messages).
Deck parse_deck(const std::string& text, const std::string& name, const std::vector<std::string>& overrides = {});

/// The resolved deck in SI, as YAML (what `rkfem check` prints), values to `digits` significant
/// digits (17: read back, the same doubles; the keyword export's $rkfem lines).
std::string to_yaml(const Deck& deck, int digits = 10);
} // namespace rkfem
