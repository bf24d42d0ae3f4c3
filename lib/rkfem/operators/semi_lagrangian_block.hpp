#pragma once
/// @file semi_lagrangian_block.hpp
/// RK particles with kernels in the current configuration (semi-Lagrangian RKPM; Guan et al.
/// 2009, 2011; digest: ../shared/reference/rkpm-methods.md section 3), integrated by SNNI on
/// cells that move with the material: each particle L owns a parallelepiped (NodalBlock::cells:
/// its centre's offset c_L from the particle and half-edge vectors e_i; on meshes at first the
/// box of the node's dual cell, so the cells of a box mesh tile it; cubes of the particles'
/// volumes on clouds), and per step
///   Psi_J and grad Psi_J at the cell's six face centres x_f = x_L + c_L -+ e_i (the kernel
///     phi(x - x_J) with support a_J = a0_J max(1, (V_J / V0_J)^(1/3), w_J / w0_J), w the cell's
///     longest half-edge: it follows the particle's volume and its longest stretch,
///     and never falls below its start. Volume alone let a Taylor bar's foot blow up at 9 us: the
///     rim's particles spread apart around the hoop at constant volume until the kernels no
///     longer reached across),
///   b_J = (1 / V_L) sum_f Psi_J(x_f) A_f  (the smoothed gradient; A_f = -+ 4 e_j x e_k, the
///     face's outward area vector),
///   L_L = sum_J v_J (x) b_J,  D, W = sym, skew L;  sigma_L by the rate-form material (the one
///     every block uses: Jaumann rotation, then the constitutive update),
///   the cell moved as material lines move in the linear field L (e_i += dt L e_i, c_L += dt L
///     c_L), V_L = 8 det(e_1, e_2, e_3) (never squared up: the cell is the material's, as an
///     element is),
///   f_J += V_L (sigma_L - q 1) b_J.
/// One face-centre point per face integrates linear fields exactly on a parallelepiped, so b_J
/// reproduces them (sum_J x_J (x) b_J = 1) whatever the cell's shape; where cells tile the body
/// (a box mesh at the start) the integration constraint holds too, and it is lost where they
/// overlap or leave gaps (verification/operators/test_semi_lagrangian.cpp measures both).
/// Stabilization (SNNI alone has zero-energy modes: a sawtooth's face values vanish), ours: the
/// MSCNI term with the cell's face centres as sub-points, gradient g_fJ = grad Psi_J(x_f) - b_J,
///   D_f = sym(sum_J v_J (x) g_fJ),  sigma_f += dt c_s C : D_f (rotated with W_L),
///   f_J += (V_L / 6) sigma_f g_fJ.
/// sum_J g_fJ = 0 and sum_J x_J (x) g_fJ = 0 (linear reproduction), so the term vanishes for
/// linear fields (the patch test of the smoothed part is kept where SNNI keeps it) and conserves
/// linear and angular momentum, as the main term does (sum_J b_J = 0, sum_J x_J (x) b_J = 1).
/// On materials with history the face stresses' loads take the share of the step the particle's
/// material took elastically, their unloads the whole increment (the plastic scaling of the
/// assumed-strain hourglass form, kernels/assumed_strain_hourglass.hpp: scaled_hourglass_update;
/// `semi_lagrangian.plastic_scaling: true`, with tables rebuilt every step only; the reset
/// mode's face terms, the nodal blocks' pass, are unscaled). Off by default: an elastic term
/// beside a flowing material resists the flow (unscaled, the Taylor bar's foot comes out 29 %
/// narrow at c_s 1 and 13 % at c_s 0.25, and a J2 block sheared to strain 3 holds 13.1 kN against
/// the 1-point FE's 7.2 kN, which the scaled terms meet), but scaled, the Taylor bar's foot
/// (6.61 mm at 53 us, on its way to the literature's 7.05) went unstable at 53 us as its rim
/// flattened: where the material flows the scaled terms no longer hold the modes SNNI misses.
/// A small c_s (0.1) puts the Taylor bar within 3.1 % of the literature's length and foot: the
/// default stays 1 (kFaceGradientCoefficient says more). In concrete struck by an FSP the elastic
/// face stresses store the crushed region's energy and give it back: P6 case 2.1 at 1/2 in throws
/// the FSP out at 145 m/s by 60 us unscaled, and at 54 m/s scaled (apparent 0.85 in, actual
/// 2.00 in against KC-FEMFRE's 1.05 / 1.93; studies/tables/table3_p6.yaml), so concrete
/// penetration runs set plastic_scaling.
///
/// SD-SNNI (each cell's eight sub-cells) is a dynamic pass too (SemiLagrangianOptions::sub_cells,
/// points_sub_cells, tables rebuilt every step) and static tables (snni_operators; the
/// manufactured-solution sweeps, studies/sweeps: SNNI with the face-gradient term converges at L2
/// 2.06, H1 1.22 with tractions on the whole boundary at a/h 1.51, SD-SNNI at 1.80, 1.01).
///
/// The unknowns of the particles are their velocities (the first-order shortcut of the digest,
/// section 3.1): the particle moves with v_J, and the kinematic map takes them as physical values
/// (identity rows), so boundary conditions, loads, contact and output read them directly. For a
/// linear field v_J = v(x_J) is the exact RK interpolant; otherwise the interpolant at x_J differs
/// from v_J by O(h^2).
///
/// Neighbours: a list per particle L of every particle J within max(a_J + r_L, a_L + r_J) + skin
/// (box support: along each axis; sphere: distance; r: the farthest face centre of the cell),
/// rebuilt when twice the largest displacement since the build plus the largest growth of a
/// support and of a reach passes the skin.
/// Forces are assembled in a fixed order whatever the thread count and whenever the lists were
/// built: by the chunked scatter (kernels/chunked_scatter.hpp; chunks of particles in order, each
/// adding its particles' forces into a buffer over the nodes its rows reach, the buffers summed in
/// chunk order), or, where the particles' order has no locality, summed per particle over its list
/// in ascending order from per-pair forces. The state (stress, face stresses, volume ratio,
/// material history) lives in a NodalBlock (one stress point per particle), which output,
/// probes and checkpoints read as they read a Lagrangian block's.
#include <vector>

#include "rkfem/approximation/rk/rk_shape.hpp"
#include "rkfem/operators/force_block.hpp"
#include "rkfem/operators/kernels/chunked_scatter.hpp"

namespace rkfem
{
struct SemiLagrangianOptions
{
    RkParams rk;
    real_t skin = 0.0; ///< neighbour list skin [m]
    /// c_s of the face-gradient stabilization (0: plain SNNI; the deck's default is
    /// kFaceGradientCoefficient)
    real_t stabilization_coefficient = 1.0;
    /// The plain pass (points_plain: the algebra as written above, over each particle's whole
    /// neighbour row) instead of the fast one (points_fast: the row's particles that cover each
    /// face centre listed once, the RK functions of each centre formed on flat arrays over its
    /// list in vector lanes, L from the interpolated face velocities, each particle's force summed
    /// over the six centres before it is added); a test holds the fast one to the plain one.
    bool plain = false;
    /// 1: the tables are rebuilt every step by the block's own pass. N > 1: Lagrangian RK with a
    /// reference reset every N steps (the digest's section 3.7, LS-DYNA SPG's pseudo-Lagrangian
    /// kernel): at a reset the SNNI tables (b_J per particle, grad Psi_J(x_f) - b_J per face) are
    /// built in the current configuration, the cells moved by F since the last reset, and between
    /// resets the nodal blocks' pass (nodal_force.hpp) forms F = 1 + sum_J (u_J - u_J^reset)
    /// (x) b_J on them. The largest index_t never resets: Lagrangian RK integrated by SNNI
    /// (`kinematics: lagrangian` with `nodal_integration.scheme: snni`).
    index_t reset_interval = 1;
    /// Separation (every-step tables only): a particle whose material's damage index (K&C D,
    /// J2 failure, CSCM d: PlasticPoints::damage) reaches this value at a commit leaves the
    /// kernels: no particle's functions include it, it integrates nothing, its stress and cell
    /// are emptied, and it moves on with its mass and momentum (a fragment). 0: never. A particle
    /// whose cell's face centres too few particles cover (a singular moment matrix: it has come
    /// apart from the body) separates in the same way, whatever this value.
    real_t separation_damage = 0.0;
    /// Every-step tables on materials with history: the face stresses' loads take the share of
    /// the step the particle's material took elastically (see the file's note).
    bool plastic_scaling = false;
    /// SD-SNNI: each cell's eight half-size sub-cells, each an SNNI cell of
    /// its own (its smoothed gradient b^s_J from its six face centres, 36 distinct points per
    /// cell), the particle's stress from their mean gradient (SNNI on the cell with four points
    /// per face) and a stabilization stress per sub-cell from its departure, sigma_s += dt c_s C :
    /// sym(L_s - L), f_J += (V / 8) sum_s sigma_s (b^s_J - b_J): at c_s = 1 the stiffness of
    /// SD-SNNI, sum_s V_s B_s^T C B_s (snni_operators' SubCells tables, statically), exactly. The
    /// functions' values only are used. With reference resets (and Lagrangian SD-SNNI, never
    /// reset) the reference's tables are those SubCells tables and the nodal blocks' pass runs on them.
    bool sub_cells = false;
    /// How forces are assembled (plan_assembly): Automatic takes the chunked scatter where the
    /// particles' order is local enough; tests force either.
    Assembly assembly = Assembly::Automatic;
    /// Conversion into semi-Lagrangian regions (every-step tables only): every particle starts
    /// dormant, a node of the FE elements around it, outside the kernels and integrating nothing
    /// (as a separated particle, without counting as one), until activate() gives it a cell and
    /// the material of the elements' octants it takes over (Model::convert_to_semi_lagrangian).
    bool dormant = false;
    /// Refinement's pool: the last `spares` particles start dormant (no mass at their nodes) and
    /// wake as the children of a split (split(); Model::refine_particles).
    index_t spares = 0;
};

class SemiLagrangianForceBlock final : public ForceBlock
{
  public:
    /// `state`: a block of one stress point per particle (point p owned by node node_begin + p),
    /// its weights the particles' volumes V0 and its length0 their step lengths, as a Lagrangian
    /// build makes it; its operators' entries are not used and are released. `radius0`: the
    /// support radius of each particle at the start [m].
    /// `cells`: each particle's smoothing cell at the start (12 values, NodalBlock::cells), its
    /// volume the particle's (the nodal dual cell's box on meshes); empty: cubes of the volumes
    /// about the particles.
    SemiLagrangianForceBlock(NodalBlock state, std::vector<real_t> radius0, std::vector<real_t> cells,
                             SemiLagrangianOptions options);

    ForcePassResult add_forces(NodeSet& nodes, real_t dt, bool add) override;
    void commit() override;
    index_t part_element(index_t) const override { return 0; }
    PointFault fault(index_t bad, const NodeSet& nodes) const override;
    NodalBlock* nodal_points() override { return &state_; }
    const NodalBlock* nodal_points() const override { return &state_; }

    /// Current volume of particle p (committed) [m^3].
    real_t volume(index_t p) const { return state_.points.weight[p] * state_.jacobian[p]; }
    /// Current support radius of particle p (committed cell) [m].
    real_t radius(index_t p) const;
    index_t n_particles() const { return state_.n_points(); }
    /// Times the neighbour lists were built, and their entries now.
    index_t rebuilds() const { return rebuilds_; }
    /// The body's outward normal at particle p in positions x (global, 3 per node): -grad rho / |grad
    /// rho| at x_p, rho(x) = sum_J V_J phi_aJ(x - x_J) the kernel sum over the particles of p's
    /// neighbour list that have not separated (the un-normalized density of the digest's kernel
    /// contact, section 3.6; sum_J Psi_J is 1 everywhere). Zero where the gradient vanishes to
    /// round-off (inside a uniform body), for a separated particle, and before the lists exist.
    Vec3 outward_normal(index_t p, const std::vector<real_t>& x) const;
    /// Whether particle p has separated (its committed cell is empty and it is not dormant).
    bool separated(index_t p) const { return state_.jacobian[p] == 0.0 && !dormant(p); }
    /// Whether particle p is dormant: an FE node not yet converted (SemiLagrangianOptions::dormant).
    bool dormant(index_t p) const { return !dormant_.empty() && dormant_[static_cast<std::size_t>(p)] != 0; }
    /// Particles that have separated.
    index_t free_particles() const
    {
        index_t n = 0;
        for (index_t p = 0; p < n_particles(); ++p)
            n += separated(p);
        return n;
    }
    /// Particles that take part (neither dormant nor separated).
    index_t active_particles() const
    {
        index_t n = 0;
        for (index_t p = 0; p < n_particles(); ++p)
            n += state_.jacobian[p] != 0.0;
        return n;
    }
    /// Conversion: particle p takes the cell `cell` (12 values, its current configuration) over
    /// the reference volume V0 (its material's, so that its volume ratio is the cell's volume
    /// over V0) and the width w0 its support's stretch is measured from (the longest half-edge of
    /// the same cell in the reference configuration). The caller sets its stress and history
    /// (nodal_points()); its face stresses start at zero where it was dormant. The lists are
    /// built again at the next pass.
    void activate(index_t p, const real_t* cell, real_t V0, real_t w0);
    /// The widths w0 (checkpoints keep them with the state, the dormant flags as 0/1 values).
    const std::vector<real_t>& widths0() const { return width0_; }
    std::vector<real_t> dormant_flags() const { return {dormant_.begin(), dormant_.end()}; }
    /// A checkpoint's activation (after its state is loaded into nodal_points()): the dormant
    /// flags and widths, the reference volumes from the points' weights.
    void restore_activation(const std::vector<real_t>& dormant, const std::vector<real_t>& w0);
    /// Refinement (Model::refine_particles; digest rkpm-methods.md section 6.2): particle p's
    /// cell splits into its eight half-size parallelepipeds, which tile it. Child k (bits 0-2 of k:
    /// the + side along e_1, e_2, e_3) sits at the centre of its own, xp + c + sum_i -+ e_i / 2;
    /// p is child 0 and the dormant particles spare[0..6] are children 1-7. Each child takes the
    /// cell (centred on it, half-edges e_i / 2), reference volume V0 / 8, width w0 / 2, support
    /// radius0 / 2 and step length l0 / 2, p's stress, face stresses, volume ratio and history
    /// (its crack band the cube root of its own V0), and p's level + 1. xp: p's position; the
    /// children's positions are written into x. The lists are built again at the next pass.
    void split(index_t p, const index_t (&spare)[7], const Vec3& xp, Vec3 (&x)[8]);
    /// Coarsening (Model::coarsen_particles): eight siblings (family[0] stays, the others become
    /// dormant again) merge into one particle at xs. Its cell: centred on the mean of their
    /// cells' centres (x[k] + c_k), half-edges twice their mean half-edges, scaled to the sum of
    /// their volumes (a split undone with no motion between gives the parent's cell back exactly);
    /// reference volume the sum of theirs, w0, radius0 and l0 twice family[0]'s; stress the
    /// volume-weighted mean, face stresses zero (the children's belong to their own cells'
    /// faces), history blended by reference volume (damage the largest: PlasticPoints::
    /// blend_point); level - 1.
    void merge(const index_t (&family)[8], const Vec3& xs, const Vec3 (&x)[8]);
    /// The times particle p's line of ancestors split (0: a particle of the start).
    int level(index_t p) const { return level_[static_cast<std::size_t>(p)]; }
    /// Refinement's checkpoint: the support radii and step lengths at the start (split halves
    /// them), the levels (as 0/1/2 values).
    const std::vector<real_t>& radii0() const { return radius0_; }
    std::vector<real_t> levels() const { return {level_.begin(), level_.end()}; }
    void restore_refinement(const std::vector<real_t>& radius0, const std::vector<real_t>& length0,
                            const std::vector<real_t>& levels);
    std::size_t neighbour_entries() const { return ids_.size(); }
    /// Whether the forces are assembled by the chunked scatter (else the per-pair gather).
    bool scatters() const { return !scatter_.empty(); }
    /// The bytes the block holds now: its state (stress, face stresses, cells, history), tables,
    /// neighbour lists and assembly buffers (vector capacities; for the speed issue's per-particle
    /// memory figure).
    std::size_t memory_bytes() const;
    const SemiLagrangianOptions& options() const { return opt_; }
    /// Runs the plain pass instead of the fast one (SemiLagrangianOptions::plain).
    void set_plain(bool plain) { opt_.plain = plain; }
    /// Assembles by `a` from the next pass on (SemiLagrangianOptions::assembly).
    void set_assembly(Assembly a)
    {
        opt_.assembly = a;
        if (rebuilds_ > 0)
            plan_assembly();
    }

    /// The smoothed gradients b_J at particle p in the positions x (global node ids of the
    /// particles of its neighbour list, 3 per entry), from its committed cell, and the direct
    /// gradients at its face centres (18 per entry, face-major) where asked. False: a singular
    /// moment matrix at a face centre. For tests and probes (allocates; rebuilds the lists).
    bool smoothed_gradient(index_t p, const std::vector<real_t>& x, std::vector<index_t>& nodes,
                           std::vector<real_t>& grad, std::vector<real_t>* face_gradients = nullptr);

    /// Smoothed gradients of nodal fields at particles, one list build for all (refinement: the
    /// linear part of v and u about a particle that splits): for each particle p of `particles`
    /// and each field f (3 values per node, global numbering), G = sum_J f_J (x) b_J(p) into out
    /// (9 values, row-major, per particle and field, fields inner). False where a particle's cell
    /// is not covered (a singular moment matrix). Allocates.
    bool field_gradients(const std::vector<index_t>& particles, const std::vector<real_t>& x,
                         const std::vector<const std::vector<real_t>*>& fields, std::vector<real_t>& out);

    /// The block's SNNI tables in positions x as integration operators, for static solves (the
    /// manufactured-solution sweep) and tests; global node ids, built by the plain pass's algebra
    /// (plain_gradient) on the committed cells. `points`: one per particle L, weight V_L, rows
    /// b_J; `stabilization`: its sub-points (parent L), by `sub`:
    /// - FaceCentres (SNNI with the block's face-gradient term): six per particle at the face
    ///   centres x_f, weight V_L / 6, rows grad Psi_J(x_f) - b_J;
    /// - SubCells (SD-SNNI): the cell's eight half-size parallelepipeds s, each its own SNNI cell
    ///   (b^s_J from its six face centres), weight V_L / 8, rows b^s_J - b_J, where the points'
    ///   rows are then the sub-cells' mean b_J = (1 / 8) sum_s b^s_J (SNNI on the cell with four
    ///   points per face: the sub-cells' shared faces cancel). With c_s = 1 the two terms'
    ///   stiffness is sum_s V_s B_s^T C B_s, SD-SNNI's, exactly (sum_s V_s (b^s - b) = 0).
    /// False where a cell's face centre is not covered (a singular moment matrix).
    enum class SubPoints
    {
        FaceCentres,
        SubCells,
    };
    bool snni_operators(const std::vector<real_t>& x, SubPoints sub, IntegrationOperator& points,
                        IntegrationOperator& stabilization);

  private:
    /// A particle's material update from its velocity gradient (trial stress, cell and volume, its
    /// energies and step in point_sums_); false on a non-positive or NaN volume.
    struct PointUpdate
    {
        real_t sig[6];
        real_t w[3];
        real_t q = 0.0; ///< bulk viscosity [Pa]
        real_t V = 0.0; ///< volume after the step [m^3]
        /// the share of the step's deviatoric strain the material took elastically (1: elastic;
        /// kernels/assumed_strain_hourglass.hpp, assumed_strain_tangent_share): the face terms' loads take it
        real_t share = 1.0;
    };
    /// `closing`: the largest speed of a covering particle relative to L (the step's velocity term).
    bool update_point(index_t L, const Mat3& Lg, real_t dt, real_t closing, PointUpdate& u);
    /// Face f's stabilization stress (trial, into sf) from its velocity gradient Lf, and its work.
    void update_face(index_t L, int f, const Mat3& Lf, const PointUpdate& u, real_t dt, real_t sf[6]);
    void points_plain(const NodeSet& nodes, real_t dt);
    /// The m sub-points' stabilization stresses (each from its departure L_s - L, into ss; none
    /// without a coefficient) and the particle's stress as the force terms take it, sigma - q 1
    /// less their mean (into sq).
    void stabilization_stresses(index_t L, const Mat3* departure, int m, const PointUpdate& u, real_t dt, real_t sq[6],
                                real_t (*ss)[6]);
    /// A pass's first look at particle L: false, or true with its trial state made free where it
    /// has separated.
    bool separated_at_start(index_t L);
    /// Particle L's trial state made free: empty cell, no stress, no forces, no step limit.
    void separate_trial(index_t L);
    /// Reference resets: the tables of the configuration x0 + u^reset (NodalBlock::reference),
    /// and the reset itself (the cells moved by F, the reference taken from the nodes).
    void build_reference_tables(const NodeSet& nodes);
    void reset_reference(const NodeSet& nodes);
    ForcePassResult reference_pass(NodeSet& nodes, real_t dt, bool add);
    bool resets() const { return opt_.reset_interval > 1; }
    void points_fast(const NodeSet& nodes, real_t dt);
    /// SD-SNNI's pass (SemiLagrangianOptions::sub_cells): written once, plainly (no fast twin).
    void points_sub_cells(const NodeSet& nodes, real_t dt);
    /// Stabilization sub-points per particle: 6 face centres, or SD-SNNI's 8 sub-cells.
    int subs() const { return opt_.sub_cells ? 8 : 6; }
    void update_neighbours(const std::vector<real_t>& x);
    void build_neighbours(const std::vector<real_t>& x);
    /// After a list build: the chunked scatter over the particles in order where their lists are
    /// local enough (as the nodal blocks' rule, nodal_block.cpp), else the pair forces and the
    /// lists' transpose for the gather.
    void plan_assembly();
    /// point(L, out) for every particle, where out(k) is where the force of L on the k-th
    /// particle of its row adds (3 values): its chunk's buffer, or its zeroed pair-force entry.
    template <class Point> void run_points(const char* label, Point&& point);
    /// The supports and the cells' reaches (radius_, cell_reach_) from the committed state.
    void extents();
    NodalBlock state_;
    std::vector<real_t> radius0_, radius_;
    std::vector<real_t> v0_;           ///< the particles' volumes at the start [m^3]
    std::vector<real_t> width0_;       ///< the cells' longest half-edges at the start [m]
    std::vector<real_t> u_rel_;        ///< reference resets: u - u^reset (3 per node up to node_end)
    bool tables_built_ = false;        ///< reference resets: the tables match NodalBlock::reference
    bool reset_due_ = false;           ///< reference resets: the next pass resets first
    std::vector<real_t> volume_trial_; ///< volume ratio V / V0 after the pass (committed on commit)
    SemiLagrangianOptions opt_;
    // neighbour lists (local particle numbers, ascending per row)
    std::vector<index_t> offsets_{0}, ids_;
    std::vector<index_t> transpose_; ///< gather: per entry (L, J), the entry (J, L) of J's row
    std::vector<real_t> x_built_;    ///< positions at the build (3 per particle)
    std::vector<real_t> cell_reach_; ///< per particle: its farthest face centre (along an axis for box kernels) [m]
    std::vector<real_t> radius_built_, reach_built_; ///< supports and reaches at the build [m]
    index_t rebuilds_ = 0;
    index_t uncovered_ = -1;         ///< snni_operators: the particle it stopped at
    std::vector<real_t> pair_force_; ///< gather: per entry (L, J), the force of L's point on J [N]
    ChunkedScatter scatter_;         ///< chunks of particles in order (empty: the gather)
    std::vector<real_t> point_sums_; ///< per particle: d_int, d_bv, d_stab, dt
    std::vector<char> bad_;          ///< per particle: a bad volume
    std::vector<char> free_;         ///< per particle: separated (its committed cell is empty)
    std::vector<char> dormant_;      ///< per particle: dormant (SemiLagrangianOptions::dormant); empty: none
    std::vector<char> level_;        ///< per particle: splits in its line (refinement)
    /// per particle: a particle of another level in its neighbour row (refinement's interfaces,
    /// whose step is halved: see add_forces); empty while every particle is of one level
    std::vector<char> mixed_;
};
} // namespace rkfem
