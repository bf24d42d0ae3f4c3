#pragma once
/// @file kernel_contact.hpp
/// Contact between semi-Lagrangian RK bodies without surfaces (the digest's natural kernel
/// contact, ../shared/reference/rkpm-methods.md section 3.6, as we read Guan et al. 2011 and Chi
/// et al. 2015; the digest marks its formulas as reconstructed, so the rule is stated here in full):
/// where the bodies' particles meet, their normal velocities are shared, the tangential ones stay
/// free or are Coulomb-limited, pair by pair, so momentum is conserved to round-off.
///
/// Per force evaluation, with the particles' current positions x and the velocities they would
/// reach over the step without contact, v* = v + dt (f_ext - f_int + f_contact) / m (the
/// central-difference kick of the step's acceleration; dt the step just taken):
///   - the bodies' outward normals n_I at their particles near the other body: -grad rho / |grad
///     rho| of the body's kernel sum rho (SemiLagrangianForceBlock::outward_normal);
///   - the pair's normal, from I into J's body: unit(n_I - n_J) where the two face each other
///     (-n_I . n_J > 1/2); a separated particle (no normal) takes the other's, -n_J or n_I;
///     otherwise the line between the cells' centres;
///   - contact pairs: particles I, J of different bodies whose smoothing cells (the
///     parallelepipeds c, e_i of NodalBlock::cells; a separated particle's, whose cell is empty,
///     the cube of its starting volume) overlap, thickened by `thickness`, along each of the
///     cells' face normals and the pair's normal (separating axes; the edge-edge axes are left
///     out, so a pair may count a little before its cells meet at an edge). On a mesh the
///     surface nodes' cells end at the surface, and on a cloud the surface particles' cubes are
///     moved inside the body (Model::build_semi_lagrangian_part), so bodies meet when their
///     surfaces do;
///   - weight w_IJ: the smallest overlap along those axes over the extent there (0 at first
///     touch, 1 fully inside);
///   - the pair's masses: I's mass shared over its pairs by weight, m_I w_IJ / sum_K w_IK, and J's
///     the same way; the pair's reduced mass mu_IJ of the two shares;
///   - normal impulses: each pair's P_IJ >= 0 brings its two shares to their common normal
///     velocity, -P n_IJ on I and +P n_IJ on J; pair by pair in a fixed order from the velocities
///     the pairs before left (projected Gauss-Seidel: a pair's total never pulls), sweeps
///     repeated until no impulse changes by more than 1e-3 of the largest (at most 50): the
///     pairs of a particle then share its correction instead of each taking it whole, and once
///     settled the pairs move together along their normals, so the impulses do no work (a bonded
///     interface) while the bodies press, and receding pairs let go (no tensile force);
///   - Coulomb friction on the settled tangential relative velocity v_t: an impulse of at most
///     mu P and at most the one that stops the sliding (mu_IJ |v_t|);
///   - the impulses become forces P / dt in the contact channel.
/// Self-contact (one body, `surfaces: [A]`): a body's separated particles (fragments, ejecta,
/// crushed material that has left the kernels: SemiLagrangianOptions::separation_damage) meet
/// the body and each other by the same rule, pairs with at least one separated particle (two
/// intact particles interact through their kernels). Without it a fragment passes through the
/// body, and separated material under a penetrator carries no load.
/// Only the first touch of each pair is inelastic (its two shares meet at their common
/// velocity), and equal and opposite impulses conserve linear momentum exactly. The time step: dt <= (g + 0.5 min(l_I,
/// l_J)) / s over the candidate pairs that close at speed s along their line, g the distance still between their
/// reaches (0 within reach: the digest's 0.5 a / |v_A - v_B|, with the cell size l = V^(1/3) for a), so no pair comes
/// from apart to deeper than half a cell in one step; the model takes it for the step after the evaluation that found
/// it (ExplicitOperator::contact_step). The pairs are searched in lists with a skin (rebuilt when the motion since the
/// build exceeds it); the result depends only on which pairs meet, summed in particle order, so the bits do not depend
/// on the lists, the thread count or a restart.
#include <vector>

#include "rkfem/contact/contact_algorithm.hpp"
#include "rkfem/discretization/cell_list.hpp"

namespace rkfem
{
class SemiLagrangianForceBlock;

struct KernelContactParameters
{
    real_t thickness = 0.0; ///< cells meet at this gap [m]
    Friction friction;
};

class KernelContact final : public ContactAlgorithm
{
  public:
    /// The two bodies, or one (self-contact). Their blocks hold the particles' cells, volumes and kernels.
    KernelContact(std::vector<const SemiLagrangianForceBlock*> bodies, const KernelContactParameters& p);
    /// The blocks again, after an event rebuilt them (the same particles).
    void set_bodies(std::vector<const SemiLagrangianForceBlock*> bodies);
    void add_forces(const PhysicalNodes& nodes, const ContactClock& clock, ContactChannel& channel) override;
    real_t stable_step() const override { return dt_bound_; }
    void set_surfaces(std::vector<ContactSurface>) override {}
    void save_state(StateArchive& archive, const std::string& prefix) const override;
    void load_state(const StateArchive& archive, const std::string& prefix) override;
    Vec3 resultant() const override { return resultant_; }
    index_t active_nodes() const override { return active_; }
    index_t pairs() const { return n_pairs_; }
    index_t rebuilds() const { return rebuilds_; }
    /// Sweeps the last evaluation took to settle the impulses.
    int iterations() const { return iterations_; }

  private:
    /// The particles' current cells' extents and sizes, positions and trial velocities.
    void gather(const PhysicalNodes& nodes, const ContactClock& clock, const ContactChannel& channel);
    /// Candidate lists (pairs within both reaches, thickness and skin), rebuilt when the motion
    /// since the build passes the skin.
    void update_candidates();
    /// The pair's normal from k into j's body: unit(n_k - n_j) of the bodies' outward normals,
    /// the line between them where both vanish.
    Vec3 pair_normal(index_t k, index_t j) const;
    /// The pair's weight: the cells' overlap along the normal over their sizes, times one less
    /// the distance across it over the cells' extents across it; 0 apart.
    real_t overlap(index_t k, index_t j) const;

    std::vector<const SemiLagrangianForceBlock*> bodies_;
    KernelContactParameters p_;
    // per contact particle k (the bodies' particles, body by body): node id, body
    std::vector<index_t> node_;
    std::vector<int> body_;
    std::vector<real_t> x_, v_, m_; ///< positions, trial velocities (3 per particle), masses
    std::vector<real_t> cell_;      ///< 12 per particle: c, e1, e2, e3 (NodalBlock::cells; a cube for separated ones)
    std::vector<real_t> size_;      ///< l = V^(1/3)
    std::vector<real_t> reach_;     ///< bound on the cell's extent in any direction
    /// candidates: per particle, the partners j > k it may meet (the other body's; self-contact: where one has
    /// separated)
    std::vector<index_t> offsets_{0}, ids_;
    std::vector<real_t> x_built_; ///< positions at the last build
    real_t reach_built_ = 0.0, skin_ = 0.0;
    bool built_ = false;
    // per candidate entry: the pair's overlap weight (0: not in contact)
    std::vector<real_t> w_;
    std::vector<real_t> wsum_, dp_; ///< per particle: sum of weights, impulse (3)
    std::vector<real_t> normal_;    ///< per particle: its body's outward normal (3; zero where not near)
    // the pairs in contact: particles, normal (3), reduced mass, normal impulse, friction impulse (3)
    std::vector<index_t> pk_, pj_;
    std::vector<real_t> pn_, pmu_, pP_, ft_;
    static constexpr int kMaxIterations = 50;
    static constexpr real_t kTolerance = 1e-3; ///< of the largest impulse: the impulses have settled
    int iterations_ = 0;
    std::vector<char> near_;      ///< per particle: in a candidate pair
    std::vector<char> separated_; ///< per particle: separated (its cell empty)
    /// per particle: dormant (an FE node of a converting part, not yet a particle): in no pair
    std::vector<char> dormant_;
    index_t separated_built_ = 0; ///< self-contact: separated particles at the last build
    index_t dormant_built_ = 0;   ///< dormant particles at the last build
    real_t dt_bound_ = kNoLimit;
    Vec3 resultant_ = Vec3::Zero();
    index_t active_ = 0, n_pairs_ = 0, rebuilds_ = 0;
};
} // namespace rkfem
