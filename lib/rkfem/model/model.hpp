#pragma once
/// @file model.hpp
/// The model built from a deck: nodes of every part in one NodeSet, one mesh per part (`meshes`:
/// output, probes, contact surfaces, events), one list of integration blocks the step runs
/// (operators/force_block.hpp: a Gauss-point part's mesh block, a nodal part's block, a coupled
/// part's nodal block and FE side), the kinematic map, named node and face sets, boundary
/// conditions, loads, contact and probes. It implements the explicit operator (time/explicit_operator.hpp) the
/// steppers call, and the events between steps. Its definitions are split by concept:
/// model.cpp (build), model_conditions, model_loads, model_step, model_events, model_fields.
#include <array>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "rkfem/approximation/rk/kinematic_map.hpp"
#include "rkfem/config/deck.hpp"
#include "rkfem/contact/contact_algorithm.hpp"
#include "rkfem/discretization/hex_mesh.hpp"
#include "rkfem/discretization/node_set.hpp"
#include "rkfem/operators/contact_channel.hpp"
#include "rkfem/operators/energy_ledger.hpp"
#include "rkfem/operators/force_block.hpp"
#include "rkfem/operators/hex_block.hpp"
#include "rkfem/operators/nodal_block.hpp"
#include "rkfem/time/explicit_operator.hpp"
#include "rkfem/time/stepper.hpp"

namespace rkfem
{
class StateArchive;
class SemiLagrangianForceBlock;
struct ChangedRows;
struct PartInfo
{
    std::string name;
    index_t node_begin = 0, node_end = 0;
    /// The end of the part's own nodes: node_end, or where a refining part's pool of dormant
    /// particles begins (they come after its nodes, in no set, face or selection)
    index_t mesh_node_end = 0;
    index_t element_offset = 0; ///< first global element index of the part's block
    std::vector<Quad> faces;    ///< boundary faces (global node ids)
    std::map<std::string, std::vector<index_t>> named_faces;
    std::map<std::string, std::vector<index_t>> named_nodes; ///< cloud parts: generator node groups (global ids)
    std::vector<long long> element_ids, node_ids;            ///< the file's ids (keyword meshes), empty otherwise
    /// How messages name the part's element e and node i (local): the file's id, or "element 7"
    /// by the 0-based index, with the global one results.h5 uses
    std::string element_name(index_t e) const;
    std::string node_name(index_t i) const;
};

/// Prescribed motion of one degree of freedom (3 node + component).
struct DofCondition
{
    index_t dof = 0;
    BoundarySpec::Kind kind = BoundarySpec::Kind::Fixed;
    const TimeFunction* value = nullptr; ///< velocity or displacement history
    index_t source = 0;                  ///< the deck's boundary condition (index) that set it
};

/// Prescribed physical velocities on the particles of one rkpm part, one component: the mixed
/// transformation (Chen & Wang 2000) solves Lambda_bb v_b = g_b - Lambda_bi v_i each step, with
/// Lambda_IJ = Psi_J(X_I), so that u^h(X_b) follows the prescribed motion at every constrained
/// particle. Lambda_bb is factored once (total Lagrangian).
struct RkVelocityConstraint;

class Model final : public ExplicitOperator
{
  public:
    Model() = default;
    Model(Model&&) = default;
    Model& operator=(Model&&) = default;
    Model(const Model&) = delete; // holds pointers into its own deck
    Model& operator=(const Model&) = delete;

    /// Builds the mesh, sets, conditions and probes. Throws DeckError for input that is well
    /// formed but unusable (empty node set, inverted element).
    static Model build(const Deck& deck);

    const Deck& deck() const { return deck_; }
    NodeSet nodes;
    /// One per part, same order: the part's mesh for output, probes, contact surfaces and events
    /// (conn, node range, reference volumes, the node -> element transpose, elastic constants). A
    /// Gauss-point FE part's (fem-1pt, fem-2x2x2) mesh block is also its integration block, which the
    /// block list refers to; the others are mesh_only. Its size is fixed once built (the list
    /// holds references into it).
    std::vector<HexBlock> meshes;
    /// The integration blocks the step runs (operators/force_block.hpp): n_blocks() of them in the
    /// order of the parts, for each part its nodal block and then its FE side, or its Gauss-point
    /// block. internal_forces and commit are loops over them.
    index_t n_blocks() const { return static_cast<index_t>(blocks_.size()); }
    ForceBlock& block(index_t k) { return *blocks_[static_cast<std::size_t>(k)].block; }
    const ForceBlock& block(index_t k) const { return *blocks_[static_cast<std::size_t>(k)].block; }
    /// The semi-Lagrangian RK block of a part (null: it has none).
    const SemiLagrangianForceBlock* semi_lagrangian_block(index_t part) const;
    SemiLagrangianForceBlock* semi_lagrangian_block(index_t part);
    /// The part's nodal block (fem-nodal, rkpm, the nodal side of a coupled part); null for
    /// Gauss-point FE parts.
    NodalBlock* nodal_block(index_t part);
    const NodalBlock* nodal_block(index_t part) const;
    /// A coupled part's fem-1pt FE side (the 1-point block of its FE elements, integrated beside
    /// its nodal block, which holds the transition and RK elements' nodes); null for none.
    FeSide* fe_side(index_t part);
    const FeSide* fe_side(index_t part) const;
    /// What the set-up decided that the user should read (the driver prints each as a warning,
    /// `check` lists them): a nodal part's step factor lowered to its measured critical value.
    std::vector<std::string> setup_notes;
    std::vector<PartInfo> parts;
    std::map<std::string, std::vector<index_t>> node_sets;
    std::map<std::string, std::vector<Quad>> face_sets;
    /// Face sets on cloud parts: boundary facet points of the particles' Voronoi cells.
    struct CloudFacet
    {
        index_t part = 0;
        Vec3 x = Vec3::Zero(), nda = Vec3::Zero(); ///< reference position, outward n dA
    };
    std::map<std::string, std::vector<CloudFacet>> cloud_face_sets;
    std::vector<DofCondition> conditions;
    std::vector<index_t> probe_nodes;                ///< one per deck probe
    std::vector<std::vector<index_t>> section_nodes; ///< per deck section: the nodes on its positive side
    /// Force across a deck section (LS-DYNA's SECFORC): what the material on the negative side
    /// exerts on the nodes of the positive side, -sum of their internal forces (every element's
    /// nodal forces sum to zero, so only the elements the plane cuts or touches contribute).
    /// On rkpm parts the generalized forces of the particles (the physical resultant when the
    /// kernels of the side's particles do not reach across the plane's other side).
    Vec3 section_force(index_t section) const;
    Energies energy;

    index_t n_elements() const;
    /// Global element index -> (block, local element).
    std::pair<index_t, index_t> locate_element(index_t global) const;

    /// Unknowns <-> physical nodal values (RK coefficients on particles, identity elsewhere):
    /// conditions, loads, output, probes and contact go through it.
    KinematicMap kinematics;
    /// Contact forces reach the nodes through this channel (own work term in the ledger).
    ContactChannel contact;
    /// Contact algorithms, evaluated in order in external_forces() on current positions; one
    /// per deck contact, same order.
    std::vector<std::unique_ptr<ContactAlgorithm>> contacts;
    /// The surface of parts or face sets (empty: every meshed part): a part's is the boundary of
    /// its current elements. Throws DeckError (at `loc`) for cloud parts.
    ContactSurface contact_surface(const std::vector<std::string>& names, const SourceLocation& loc) const;

    // ---- the explicit operator (time/explicit_operator.hpp): phases the steppers call ----
    NodeSet& state() override { return nodes; }
    const NodeSet& state() const override { return nodes; }
    Energies& ledger() override { return energy; }
    /// Sets velocities of constrained dofs for the interval (t, t + dt) (half step) or at t.
    void impose_velocity(real_t t, real_t dt, bool half_step);
    /// The same on a velocity array other than nodes.v (3 n values; the unconstrained ones are
    /// read, as rkpm constraints need them); displacement conditions read nodes.u.
    void impose_velocity(real_t t, real_t dt, bool half_step, real_t* v) override;
    /// x = x0 + u.
    void update_coordinates() override;
    /// Nodal state from a stepper's vector: u, v (3 n each), then x = x0 + u, in one pass.
    void set_state(const real_t* u, const real_t* v) override;
    const std::vector<index_t>& constrained_dofs() const override { return constrained_dofs_; }
    std::vector<index_t> velocity_driven_dofs() const override;
    /// Internal forces (all blocks, assembled), stress trial state. Throws InstabilityError on a
    /// non-positive element volume.
    ForceReport internal_forces(real_t t, real_t dt, std::int64_t step) override;
    /// Loads at t into f_ext; contact algorithms into the contact channel.
    void external_forces(real_t t) override;
    real_t contact_step() const override;
    /// a = (f_ext + f_contact - f_int) / m - c v; zero on constrained dofs.
    void accelerations() override;
    /// Throws InstabilityError naming the first node (and its part), t and the step when a
    /// displacement or acceleration is not finite: update_coordinates (or set_state) and
    /// accelerations flag such values as they write x and a, and only then check scans.
    void check(real_t t, std::int64_t step) const override;
    /// Commits material trial state and books this step's energy increments.
    void commit() override;
    /// Recomputes kinetic energy; books external work over a step with displacement increment
    /// given by u - u_prev (uses stored previous external and reaction forces) and the contact
    /// channel's work.
    void update_energies(const real_t* u_prev, real_t dt) override;
    /// On: update_energies leaves the kinetic energy, its leapfrog correction and the parts'
    /// mass and momentum (a pass over every node) to refresh_motion(), which the run calls when
    /// something reads them (balance checks, history rows, outputs, checkpoints); with mass
    /// damping they are computed every step. Events refresh them before they change the model.
    /// Off (the default) they are computed every step.
    void defer_motion(bool on) { defer_motion_ = on; }
    /// Brings energy.kinetic, energy.kinetic_correction and part_summary()'s motion up to the last
    /// update_energies (the same numbers it would have computed then).
    void refresh_motion();

    /// True when the node's unknowns are RK coefficients (rkpm parts), not physical values.
    bool carries_coefficients(index_t node) const;
    /// Physical value of a node-major 3-vector field (u, v) at a node: the RK interpolant
    /// sum_J Psi_J(X_I) d_J on rkpm parts, the nodal value elsewhere.
    Vec3 physical(const std::vector<real_t>& field, index_t node) const;
    /// The same for every node.
    void physical_field(const std::vector<real_t>& field, std::vector<real_t>& out) const;

    /// Reaction of a deck boundary condition (index into deck().boundary_conditions): the sum over
    /// its constrained dofs of f_int - f_ext - f_contact + m a_prescribed, the force the supports
    /// put on the body (LS-DYNA's SPCFORC resultant), as of the last energy update. On rkpm parts
    /// the sum runs over the generalized forces of the constrained particles, whose resultant is
    /// the physical one when no other condition's particles share their kernels.
    Vec3 reaction(index_t condition) const;
    /// Every condition's reaction in one pass over the constrained dofs.
    void reactions(std::vector<Vec3>& out) const;

    /// Per-part sums (LS-DYNA's MATSUM): mass, momentum and kinetic energy of the part's nodes
    /// (on rkpm parts of the generalized velocities, as the ledger), and the internal, hourglass
    /// and bulk-viscosity energies its blocks booked. Summed over parts they are the ledger's.
    struct PartSummary
    {
        real_t mass = 0, kinetic = 0, internal = 0, hourglass = 0, bulk_viscosity = 0;
        Vec3 momentum = Vec3::Zero();
    };
    PartSummary part_summary(index_t part) const;

    /// Nodal stress (average of adjacent points) at node i, Voigt.
    Sym6 nodal_stress(index_t node) const;
    /// A point history value averaged over an element (its points; nodal parts: the points of
    /// the element's nodes), 0 for elastic parts.
    enum class History
    {
        PlasticStrain, ///< effective plastic strain
        Damage,        ///< 0..1 damage index (PlasticPoints::damage)
        KccDelta,      ///< K&C scaled damage delta, 0..2 (0 for other models)
    };
    real_t element_history(index_t block, index_t e, History h) const;
    /// The same averaged over the points a node owns (nodal parts; 0 elsewhere).
    real_t nodal_history(index_t node, History h) const;
    /// Cloud parts (generator type cloud) have no elements: their particles are the output cells.
    bool is_cloud(index_t part) const;
    /// Output cells: every element, then (per part, in part order) the particles of cloud parts
    /// and the particles a semi-Lagrangian conversion has made (output_particles).
    index_t n_cells() const;
    /// The nodes written as vertex cells after the elements, in part order: every particle of a
    /// cloud part, the particles of a converting fem-1pt part that are not dormant (fragments
    /// included).
    std::vector<index_t> output_particles() const;
    /// The stress points that node `node` owns as a particle: its part's nodal block, or the
    /// conversion's particles once it is one; null for FE nodes.
    const NodalBlock* particle_points(index_t node) const;
    /// What a step's force pass works through: the elements of Gauss-point FE parts (and of
    /// coupled parts' 1-point FE sides, and the particles a semi-Lagrangian conversion has made
    /// that have not separated), the stress points of nodal parts (one per particle or
    /// node under SCNI): the count that ns per element-cycle divides by.
    index_t n_work_items() const;
    real_t element_plastic_strain(index_t block, index_t e) const
    {
        return element_history(block, e, History::PlasticStrain);
    }
    /// Element stress (average over its points), Voigt.
    Sym6 element_stress(index_t block, index_t e) const;

    // ---- events between steps (the stepper is started again after one) ----
    /// Removes the elements of a Gauss-point FE block with keep[e] == 0 (erosion): the kept
    /// elements keep their state, the block's tables are rebuilt, the nodes keep their mass (a
    /// node no element holds any more flies free), and the output topology changes. The energy
    /// ledger continues: the removed elements' internal energy stays booked.
    void remove_elements(index_t block, const std::vector<char>& keep);
    /// The shape measures the erosion criteria read, of element e of a block: the largest
    /// principal logarithmic strain of its mean deformation gradient, V / V0 - 1, and its step
    /// (V / A_max) / c.
    struct ElementShape
    {
        real_t principal_strain = 0.0, volumetric_strain = 0.0, time_step = 0.0;
    };
    ElementShape element_shape(index_t block, index_t e) const;
    /// element_shape's time_step alone (the same value): the step budget's scan over every
    /// element needs no strains (an eigen-solve per element).
    real_t element_time_step(index_t block, index_t e) const;
    /// Element e's corners now (a coupled part's particles through the kinematic map) and at rest.
    void element_corners(index_t block, index_t e, real_t (&x)[8][3], real_t (&X)[8][3]) const;
    /// The model's own events after an accepted step (erosion and conversion by the parts'
    /// criteria); true when the discretization changed.
    bool apply_events(real_t t, std::int64_t step);
    /// After an event changed the discretization at the end of a step dt: the stepper starts
    /// again from this state; the kinetic energy the prescribed velocities' new map imposes is
    /// booked as external work, and what the new accelerations change in the leapfrog kinetic
    /// energy is booked by the ledger (Energies::book_event). Returns the new stable step.
    real_t restart_after_event(TimeStepper& stepper, real_t t, real_t dt);
    /// Does element e of a block meet the criteria (committed point values, current shape)?
    bool meets(const ElementCriteria& c, index_t block, index_t e) const;
    index_t eroded_elements() const { return eroded_elements_; }

    /// Evolutionary coupling (seed Table 1, feature 4; Wu, Choi & Crawford 2013, Interaction and
    /// Multiscale Mechanics 6; transition: Huerta & Fernandez-Mendez 2000, IJNME 48, and
    /// coupled_shapes.hpp): the elements of a fem-nodal part with convert[e] != 0 become RK. Their
    /// nodes become particles whose coefficients take the nodes' current values (exact for linear
    /// fields: the new approximation reproduces them), neighbouring FE elements become transition
    /// elements (mixed interpolation or ramp, the part's `transition`), and the part's tables,
    /// kinematic map, RK constraints and loaded dofs are rebuilt in the reference configuration.
    /// No state moves: every point (one per node, then the MSCNI sub-cells) keeps its stress,
    /// history and weight, the nodes keep mass, u and v, so momentum and the energy ledger carry
    /// over exactly. Returns how many elements became RK. A fem-1pt part with kinematics:
    /// semi-lagrangian: the flags are per element of its FE block now, whose flagged elements
    /// become semi-Lagrangian particles (adaptivity/conversion_semi_lagrangian.cpp).
    index_t convert_elements(index_t part, const std::vector<char>& convert);
    /// Per element of a coupled part: 1 where it is RK (regions, then conversion); empty for
    /// other parts.
    const std::vector<char>& rk_elements(index_t part) const { return rk_elements_[static_cast<std::size_t>(part)]; }
    index_t converted_elements() const { return converted_elements_; }
    /// RK elements of a coupled fem-nodal part back to FE (flags per element of the part): the
    /// state stays at the nodes, so the event rebuilds tables only. Returns how many went back.
    index_t revert_elements(index_t part, const std::vector<char>& revert);
    index_t reverted_elements() const { return reverted_elements_; }
    /// Adaptive refinement of a semi-Lagrangian part (issue #49; deck `refinement`;
    /// adaptivity/refinement.cpp): each flagged particle (local numbering, active, below the
    /// deck's max_level) splits into the eight parallelepipeds of its cell
    /// (SemiLagrangianForceBlock::split), taking seven dormant particles of the part's pool while
    /// there are any. The children take the parent's conditions. Each child
    /// gets mass m / 8, and u and v from the particle's smoothed gradients, u_k = u_p + G_u (x_k -
    /// x_p), v_k = v_p + G_v (x_k - x_p), the velocities then shifted by one common vector so that
    /// their momentum is the particle's exactly (zero for a cell centred on its particle), so a
    /// linear field carries over to round-off; x0_k = x_k - u_k. The change of kinetic energy is
    /// booked with the events' (Energies::eroded). Returns how many particles split.
    index_t refine_particles(index_t part, const std::vector<char>& split);
    /// Coarsening: each family of eight siblings (the children of one split, none split again)
    /// whose flags (local numbering) are all set merges back into one particle
    /// (SemiLagrangianForceBlock::merge) at the siblings' centre of mass, with their summed mass,
    /// momentum and mean displacement; the others go back to the pool. Returns how many merged.
    index_t coarsen_particles(index_t part, const std::vector<char>& merge);
    index_t refined_particles() const { return refined_particles_; }
    index_t coarsened_particles() const { return coarsened_particles_; }
    /// A refining part's families (each the 8 local particles of one split, the kept one first).
    const std::vector<std::array<index_t, 8>>& families(index_t part) const
    {
        return families_[static_cast<std::size_t>(part)];
    }
    /// Is RK element e of part b benign by the conversion's revert measures?
    bool benign(const ElementCriteria::Reversion& r, index_t b, index_t e) const;
    /// Conversion events rebuild the whole part (true) or only the points where the
    /// approximation changed (false, the default); the same operators either way.
    void set_rebuild_whole_part(bool whole) { rebuild_whole_part_ = whole; }
    /// The output cell's discretization: 0 FE, 1 transition (an FE element with particle
    /// nodes), 2 RK (RK elements, rkpm parts, cloud particles).
    int element_zone(index_t block, index_t e) const;
    /// The elements events removed from one block: 8 global node ids and the reference volume
    /// of each (crater and eroded-mass measures, analysis/impact.hpp).
    struct ErodedElements
    {
        std::vector<index_t> conn;
        std::vector<real_t> volume0;
    };
    const ErodedElements& eroded(index_t block) const { return eroded_[static_cast<std::size_t>(block)]; }
    /// The elements a conversion into semi-Lagrangian particles removed from a block (their
    /// material lives on in the particles; PartSpec::converts_to_semi_lagrangian).
    const ErodedElements& converted(index_t block) const { return converted_[static_cast<std::size_t>(block)]; }
    /// Damage of the k-th element of converted(block): the mean of its nodes' particles'.
    real_t converted_element_damage(index_t block, std::size_t k) const;
    /// How many of a converting part's elements are RK now (coupled parts: its RK flags;
    /// semi-Lagrangian conversion: the elements handed to particles).
    index_t rk_element_count(index_t part) const;
    /// Incremented by every event that changes the cells (output writes a new mesh).
    int topology_version() const { return topology_version_; }

    // ---- checkpoints ----
    /// The state between two steps that a checkpoint holds: nodal kinematics and masses, every
    /// block's committed material state, the energy ledger and its per-part and previous-step
    /// terms, and what erosion removed. load_state puts it back into a model freshly built from
    /// the same deck (erosion replayed on the rebuilt blocks, contact surfaces with it), after
    /// which the run continues with the same bits; contacts keep their search lists, spring
    /// offsets and penalty step, the contact channel its last forces.
    void save_state(StateArchive& archive) const;
    void load_state(const StateArchive& archive);

    /// Decides how the blocks assemble f_int: a block whose node range overlaps another's adds
    /// into it, and those ranges are zeroed once per evaluation; a block alone on its nodes
    /// writes them. Call again after an event changed the blocks.
    void plan_assembly();

  private:
    Deck deck_;
    // Model::build's steps, in order (model.cpp, model_sets.cpp)
    void build_part(std::size_t ip, const HexMesh& mesh, index_t& offset, index_t& elem_offset);
    void build_nodal_part(const PartSpec& ps, std::size_t ip, const HexMesh& mesh, index_t offset, const HexBlock& blk);
    /// `dormant`: the particles of a fem-1pt part's semi-Lagrangian conversion (no mass of their
    /// own; the part's FE block holds it).
    void build_semi_lagrangian_part(const PartSpec& ps, std::size_t ip, const HexMesh& mesh, index_t offset,
                                    bool dormant = false);
    /// The FE side's points take up the nodal block's K&C crack-band scales (shared: a converting
    /// part's blocks solve each length once).
    FeSide build_fe_side(const PartSpec& ps, const HexMesh& mesh, const HexBlock& blk, const NodalBlock& nb);
    std::vector<index_t> parts_named(const std::string& name) const;
    void build_node_sets();
    void build_face_sets();
    void build_conditions_and_loads();
    void build_probes_and_sections();
    void build_kinematic_map();
    void build_rk_face_loads();
    int topology_version_ = 0;
    index_t eroded_elements_ = 0;
    index_t converted_elements_ = 0;
    index_t reverted_elements_ = 0;
    index_t refined_particles_ = 0, coarsened_particles_ = 0;
    std::vector<std::vector<std::array<index_t, 8>>> families_; ///< per part (refinement)
    std::vector<real_t> next_refinement_check_;                 ///< per part (refinement.interval)
    /// The kinetic energy the events of this step changed themselves (refinement's interpolated
    /// velocities, coarsening's merged momenta), which restart_after_event books as an event's
    /// and not as the supports' work.
    real_t event_kinetic_ = 0.0;
    /// Refinement's checks after a step (apply_events): the particles whose indicator is at or
    /// past the threshold split, families all below coarsen_below merge.
    bool refinement_events(index_t part, real_t t);
    /// A check of an event every `interval` (0: every step), at the first step end at or past
    /// each multiple of it: false before `next`, else true with `next` moved to the next multiple.
    static bool check_due(real_t& next, real_t t, real_t interval);
    /// constrained_dofs_ from conditions (ascending)
    void collect_constrained_dofs();
    /// The conditions the deck set (Model::build), before refinement gave children theirs.
    std::vector<DofCondition> base_conditions_;
    /// conditions = the deck's, and each refined particle's children take their parent's
    /// (families in the order they were made); the per-condition state (reactions, prescribed
    /// velocities' last values) kept by dof, the plans rebuilt.
    void refresh_refined_conditions();
    std::vector<std::vector<char>> rk_elements_; ///< per part (coupled parts; empty otherwise)
    /// per part: the elements the deck's regions make RK (parts with regions; empty otherwise): they
    /// never revert
    std::vector<std::vector<char>> region_elements_;
    /// Conversion rebuilds the whole part's block (the plain path the incremental update is
    /// held to) instead of the points where the approximation changed.
    bool rebuild_whole_part_ = false;
    std::vector<real_t> next_conversion_check_; ///< per part (conversion.interval): time of the next check
    /// A coupled part's tables, map and the conditions' and loads' use of it rebuilt for a new
    /// set of RK elements; the points' state carries over.
    void set_rk_elements(index_t part, const std::vector<char>& rk);
    /// set_rk_elements for a part with a fem-1pt FE side: its nodal block and side built again for
    /// the RK elements rk (the block keeps its kinematic rows for the caller), each new point's
    /// state blended from the material it takes over (adaptivity/conversion_fe_side.cpp), the
    /// nodes' masses those of the new blocks with their momentum kept.
    /// A fem-1pt FE side and its nodal block built again for the RK set rk (the nodal block where
    /// the approximation changed only: update_fe_side_block; whole with set_rebuild_whole_part),
    /// the state handed over. Returns false and fills `changed` with the physical-value rows that
    /// changed; true where the new nodal block holds every node's row (the whole rebuild, also
    /// taken where no element is RK).
    bool rebuild_fe_side_part(index_t part, const HexMesh& mesh, const std::vector<char>& rk, ChangedRows& changed);
    /// Conversion's buffer layers and cap per event (ElementCriteria::buffer, max_per_event) on
    /// the triggered elements' flags (nonzero: convert).
    void buffer_and_cap(index_t part, const ElementCriteria& c, std::vector<char>& convert) const;
    /// convert_elements and revert_elements: the flagged elements RK (to_rk) or FE, the tables rebuilt;
    /// how many changed
    index_t flip_elements(index_t part, const std::vector<char>& flags, bool to_rk, const char* caller);
    /// RK elements of a converting part that go back to FE now: by a conversion (not a region),
    /// meeting none of its criteria and all its revert measures, and no element within the
    /// buffer's layers that stays RK
    void reversion_flags(index_t part, std::vector<char>& revert) const;
    /// The part's mesh in the reference configuration, local node numbering.
    HexMesh part_mesh(index_t part) const;
    /// Conversion into semi-Lagrangian particles (PartSpec::converts_to_semi_lagrangian;
    /// adaptivity/conversion_semi_lagrangian.cpp): the flagged elements of the part's 1-point
    /// block hand their octants to the particles at their corners, and leave the block. Returns
    /// how many converted.
    index_t convert_to_semi_lagrangian(index_t part, const std::vector<char>& convert);
    /// The elements of a Gauss-point block with keep[e] == 0 leave it, recorded in `record`.
    void drop_elements(index_t block, const std::vector<char>& keep, ErodedElements& record);
    std::vector<ErodedElements> eroded_;    ///< per block
    std::vector<ErodedElements> converted_; ///< per block (semi-Lagrangian conversion)
    /// The one list of integration blocks (operators/force_block.hpp), in the order of the parts;
    /// plan_assembly() decides which add and which write.
    struct PlannedBlock
    {
        std::unique_ptr<ForceBlock> block;
        index_t part = 0;
        bool add = false; ///< adds into f_int (its nodes are shared with another block) or writes them
    };
    std::vector<PlannedBlock> blocks_;
    std::vector<index_t> part_nodal_, part_fe_side_; ///< per part: index into blocks_, -1 for none
    std::vector<char> event_flags_;                  ///< apply_events' per-element flags (conversion, erosion), reused
    std::vector<real_t> event_a_;                    ///< restart_after_event's accelerations before the event, reused
    std::vector<std::pair<index_t, index_t>> shared_node_ranges_; ///< zeroed before the blocks add
    std::vector<std::shared_ptr<RkVelocityConstraint>> rk_constraints_;
    void build_rk_constraints();
    real_t dt_critical_ = 0.0; ///< the elements' critical step at the last force evaluation
    real_t dt_last_ = 0.0;     ///< the step of the last force evaluation (0: the start)
    std::vector<ContactSurface> contact_surfaces(const ContactSpec& c) const;
    void build_contacts();
    /// Refuses (DeckError at the contact) a part whose surface nodes start inside a contacted
    /// part deeper than the contact can hold them
    void check_initial_overlaps() const;
    /// After erosion: every contact's surfaces again from the remaining elements.
    void refresh_contact_surfaces();
    /// A kernel contact's bodies: the blocks of the semi-Lagrangian parts it names (DeckError else).
    std::vector<const SemiLagrangianForceBlock*> kernel_contact_bodies(const ContactSpec& c) const;
    /// The dofs any load can put a force on (ascending): f_ext is zero everywhere else, so the
    /// load pass zeroes and the external work sums only these. f_ext_prev_ is per loaded dof.
    std::vector<index_t> loaded_dofs_;
    void collect_loaded_dofs();
    std::vector<real_t> f_ext_prev_;
    std::vector<index_t> constrained_dofs_; ///< the dofs of `conditions`, ascending
    std::vector<real_t> reaction_prev_;
    std::vector<real_t> reaction_inertia_; ///< per condition: m a_p of the last step
    std::vector<real_t> bc_v_prev_;
    /// The conditions split for the per-step passes (plan_conditions). A `still` condition holds
    /// a node of a mesh at rest (fixed, no RK coefficients): its velocity is 0, its displacement
    /// never changes, so its reaction does no work and is read from the current forces when
    /// asked for (reactions(); reaction_prev_ holds it only after an event). The others, `moving`,
    /// book their work every step. still_dofs_ is ascending.
    std::vector<index_t> still_conditions_, still_dofs_, moving_conditions_;
    /// Per condition, in their order, what reactions() adds: its dof, its slot in the flat output
    /// (3 source + component) and whether it is still (1), still on a loaded dof (2), or stored (0)
    struct ReactionTerm
    {
        index_t dof = 0;
        int slot = 0;
        int still = 0;
    };
    std::vector<ReactionTerm> reaction_terms_;
    /// The forces are those of the last energy update (not after a restore, until the next)
    bool forces_current_ = false;
    /// The last update_coordinates / set_state met a non-finite u; the last accelerations() a
    /// non-finite a (check())
    bool nonfinite_u_ = false, nonfinite_a_ = false;
    void plan_conditions();
    /// A still condition's reaction from the current forces.
    real_t still_reaction(const ReactionTerm& c) const;
    /// reaction_prev_ with the still conditions' reactions from the current forces.
    void fill_still_reactions(std::vector<real_t>& reaction) const;
    real_t pending_int_ = 0, pending_hg_ = 0, pending_bv_ = 0;
    struct PartEnergy
    {
        real_t internal = 0, hourglass = 0, bulk_viscosity = 0;
    };
    std::vector<PartEnergy> part_energy_, part_pending_; ///< per part: committed, this evaluation's
    /// A part's kinetic energy, sum of m |a|^2, mass and momentum x y z, in one pass over its nodes.
    std::array<real_t, 6> part_motion(index_t part) const;
    std::vector<std::array<real_t, 6>> part_motion_; ///< per part, at the last update_energies
    bool defer_motion_ = false, motion_stale_ = false;
    real_t motion_dt_ = 0.0; ///< the step of a deferred update_energies
    void compute_motion(real_t dt);
    std::vector<std::pair<const LoadSpec*, std::vector<index_t>>> nodal_loads_;
    std::vector<std::pair<const LoadSpec*, const std::vector<Quad>*>> pressure_loads_;
    /// Per pressure load: its facets on cloud parts, Psi_I and grad Psi_I at each (CSR, reference
    /// configuration) and the reference N dA; the force is -p Psi_I n da on the current facet
    struct CloudFaceLoads
    {
        std::vector<index_t> offsets{0};
        std::vector<index_t> nodes;
        std::vector<real_t> psi;
        std::vector<Vec3> grad;
        std::vector<Vec3> nda;
    };
    std::vector<CloudFaceLoads> cloud_face_loads_;
    /// Pressure faces on rkpm parts: per face and 2x2 Gauss point, Psi_I at the reference point
    /// (CSR over face-major points), so loads reach the coefficients consistently.
    struct RkFaceLoads
    {
        std::vector<char> is_rk;            ///< per face of the load's set
        std::vector<index_t> point_offsets; ///< per face: 4 points; per point: CSR offsets
        std::vector<index_t> nodes;
        std::vector<real_t> psi;
    };
    std::vector<RkFaceLoads> rk_face_loads_; ///< one per pressure load
    void apply_external_forces(real_t t);
};
} // namespace rkfem
