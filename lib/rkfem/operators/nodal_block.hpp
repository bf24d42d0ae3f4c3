#pragma once
/// @file nodal_block.hpp
/// A part integrated by a nodal scheme (RK particles or nodal-integrated FE), total Lagrangian:
/// gradients G_pI are built once in the reference configuration (an IntegrationOperator), and
/// each step forms
///   F_p = 1 + sum_I u_I (x) G_pI,  Fdot_p = sum_I v_I (x) G_pI,  L_p = Fdot_p F_p^-1,
/// updates the rate-form material with (D, W) = sym/skew L_p, and scatters
///   f_I += V0_p P_p G_pI,  P_p = J_p sigma_p F_p^-T.
/// An optional stabilization operator (MSCNI or NSNI) adds, per sub-cell s with parent point L,
///   D_s = sym((sum_I v_I (x) g_sI) F_L^-1),  sigma_s += dt c_s C : D_s (rotated with W_L),
///   f_I += V0_s J_L sigma_s F_L^-T g_sI,
/// which vanishes for linear fields (g_s = b_s - b_L) and so keeps the patch test.
///
/// Nodal forces are assembled in a fixed order (chunked scatter or transpose gather, see
/// NodalBlock::Assembly), so results do not depend on the thread count. For RK parts the node unknowns are
/// generalized coefficients; `interpolation` (Psi_J(X_I) per node) gives physical values.
/// The force pass is in nodal_force.hpp, the builders from deck parts in nodal_block_build.hpp.
#include <memory>
#include <vector>

#include "rkfem/core/error.hpp"
#include "rkfem/core/huge_pages.hpp"

#include "rkfem/approximation/rk/rk_shape.hpp"
#include "rkfem/discretization/hex_mesh.hpp"
#include "rkfem/discretization/node_set.hpp"
#include "rkfem/discretization/voronoi_cells.hpp"
#include "rkfem/integration/integration_operator.hpp"
#include "rkfem/integration/stencil_table.hpp"
#include "rkfem/materials/elastic.hpp"
#include "rkfem/materials/point_history.hpp"
#include "rkfem/operators/bulk_viscosity.hpp"
#include "rkfem/operators/hex_block.hpp"
#include "rkfem/operators/kernels/chunked_scatter.hpp"

namespace rkfem
{
/// How a nodal block builds and runs its tables. Every choice gives the same numbers (the tests hold
/// one to the other); they trade memory and time. Set before initialize(); build_tables() sets the
/// prefetches from the tables' sizes.
struct NodalBlockOptions
{
    /// Shared stencils (point_stencils, stab_stencils) built by initialize() where sharing pays.
    bool share_stencils = true;
    /// Blocks whose operators never change in place (all but coupled parts): once a shared
    /// stencil table holds an operator's entries, build_tables() releases the operator's own
    /// nodes and gradients (on the P1 cylinder's particles 7.9 of 12.3 KB per particle) and marks
    /// it held in the table; offsets, weights, positions and owners stay. expand_operators()
    /// writes the entries back from the tables, the same bits (the operators were snapped to
    /// them), as build_tables() does first. Read a point's entries through point_view /
    /// stab_view, which take them from wherever they are.
    bool compact_operators = false;
    /// The force pass may write the stress field with streaming stores (core/stream_stores.hpp,
    /// store_batch8; only past kStreamBytes, with the chunked scatter). Off: plain stores, the
    /// same values (verification compares the two).
    bool stream_stress = true;
    /// The force pass asks for the next batch's stencils, lane by lane into the second-level
    /// cache, while it scatters this batch's forces (the gathers that read them first otherwise
    /// wait on memory, and the scatters, which find their stencils in cache, leave memory idle):
    /// the points' stencils while NSNI scatters (or the points do, without NSNI in the batches),
    /// NSNI's triplets while the points scatter. Only for tables that stream from memory: set
    /// where the per-point tables (an irregular cloud's, whose stencils are not shared) hold more
    /// than NodalBlock::prefetch_bytes together, for each table over 1 MiB; in cache the prefetches only cost.
    bool prefetch_points = false;
    bool prefetch_triplets = false;
};

struct NodalBlock
{
    /// The block's path choices (set before initialize(); build_tables() sets the prefetches).
    const NodalBlockOptions& options() const { return options_; }
    void set_options(const NodalBlockOptions& o) { options_ = o; }
    index_t part = 0;
    ElasticParams material;
    PlasticPoints plastic;                  ///< J2 / K&C history per stress point (inactive for elastic blocks)
    real_t stabilization_coefficient = 0.0; ///< c_s (MSCNI), 0: none
    /// the stabilization's loads scaled by the parent point's elastic share (NodalIntegrationSpec::
    /// plastic_scaling; inelastic materials only)
    bool stab_plastic_scaling = false;
    BulkViscositySpec bulk_viscosity;  ///< q = rho l (Q1 l trD^2 - Q2 c trD) for trD < 0, l = J^(1/3) l0
    real_t dt_factor = 1.0;            ///< alpha in dt = alpha J^(1/3) l0 / c
    std::vector<real_t> length0;       ///< per point: l0, the shortest mesh edge at the owner node [m]
    IntegrationOperator points;        ///< stress points (global node ids)
    IntegrationOperator stabilization; ///< MSCNI sub-cells or NSNI sub-points (empty: none)
    /// NSNI: the stabilization's sub-points come in threes, 3 p + i with parent p and the same
    /// nodes in the same order (build_nsni_stabilization); the force pass then forms a point's
    /// three in one pass over their nodes. initialize() checks the layout.
    bool stabilization_triplets = false;
    /// Shared stencils of `points` and `stabilization` (integration/stencil_table.hpp), built by
    /// initialize() when `options().share_stencils` is on and sharing pays (lattices, structured meshes);
    /// empty: the force pass reads the operators' own entries. initialize() snaps the operators
    /// to them; an operator changed afterwards needs initialize() again. Batches of 8 points
    /// with one stencil and consecutive bases (along lattice rows) take a whole-vector path.
    StencilTable point_stencils, stab_stencils;
    /// An operator held only in its shared stencil table (options().compact_operators).
    bool points_in_table = false, stab_in_table = false;
    /// NSNI with the chunked scatter: the sub-points' entries as triplets (integration/
    /// stencil_table.hpp, TripletTable: each point's three sub-points in one stencil of nodes and
    /// six Hessian values per entry), which the force pass reads (nsni_batch); built by
    /// build_tables() from the shared stencils or the operator. With options().compact_operators it is the
    /// only copy (stab_in_triplets: the sub-point stencils are released too, 52 bytes per
    /// entry where they took 84, and the sub-points' positions, their parents'), and
    /// expand_operators() writes them back.
    TripletTable stab_triplets;
    bool stab_in_triplets = false;
    void expand_operators();
    StencilView point_view(index_t p) const { return stencil_view(points, point_stencils, p); }
    /// Sub-point s's entries (not while they are held as triplets only: expand_operators() first)
    StencilView stab_view(index_t s) const
    {
        RKFEM_REQUIRE(!stab_in_triplets,
                      "nodal block: the stabilization's entries are held as triplets; expand_operators() first");
        return stencil_view(stabilization, stab_stencils, s);
    }
    /// RK parts, as built: physical value at node I = sum over k in [interp_offsets[i],
    /// interp_offsets[i+1]) of interp_values[k] * coefficient[interp_nodes[k]] (local node i);
    /// empty for FE parts. Model moves these rows into its KinematicMap (and empties them here).
    std::vector<index_t> interp_offsets, interp_nodes;
    /// RK parts: the shape functions (local node numbering, reference configuration), kept for
    /// set-up work that samples them (pressure faces); Model::build releases them when its
    /// set-up is done (null then, and for FE parts).
    std::shared_ptr<const RkShapeFunctions> rk;
    std::vector<real_t> interp_values;
    /// Coupled FE-RK parts: per local node, whether its unknowns are RK coefficients, and per
    /// element of the part's mesh, whether it is an FE element (no particle node); empty
    /// otherwise. With a fem-1pt FE side the FE elements are integrated by a 1-point block and
    /// this block holds the points of the other elements' nodes only.
    std::vector<char> particle, fe_element;
    /// Cloud parts: the Voronoi cells' facet points on the body's surface (reference position,
    /// outward n dA), where face loads act; empty for mesh parts.
    std::vector<CellFacetPoint> boundary_facets;
    /// point -> owner node CSR (local node i: points [owner_offsets[i], owner_offsets[i+1]))
    std::vector<index_t> owner_offsets, owner_points;
    index_t node_begin = 0, node_end = 0;

    /// How nodal forces are assembled (chunked_scatter.hpp). Scatter: chunks of points add
    /// V0 P g, in point order, into their buffers; it streams the gradients once per step.
    /// Gather: each node sums over a transposed copy of its entries (streams them twice).
    using Assembly = rkfem::Assembly;
    ChunkedScatter scatter;     ///< stress-point chunks, then stabilization chunks (empty: gather)
    index_t n_point_chunks = 0; ///< how many of them are stress-point chunks
    bool scatter_assembly() const { return !scatter.empty(); }

    // transpose (node -> entries of points, then of stabilization), built by initialize(): for
    // slot q of local node i in [node_entry_offsets[i], node_entry_offsets[i + 1]), the point
    // (stabilization points numbered after the stress points) and a contiguous copy of its
    // gradient, so the assembly pass streams through memory
    std::vector<index_t> node_entry_offsets, node_point;
    std::vector<real_t> node_grad; ///< 3 per slot

    // state, component-major
    /// component k of point p at [k stress_stride + p]; the stride is n_points rounded up to a
    /// multiple of 8, so every batch of 8 points is one cache line per component
    LineVector<real_t> stress, stress_trial; ///< 6 x stress_stride [Pa]
    std::size_t stress_stride = 0;
    std::vector<real_t> stab_stress, stab_stress_trial; ///< 6 x n_stab [Pa]
    std::vector<real_t> jacobian;                       ///< n_points, det F (semi-Lagrangian: V / V0)
    /// Semi-Lagrangian blocks (semi_lagrangian_block.hpp): per particle its smoothing cell, the
    /// offset c of its centre from the particle, then its three half-edge vectors e_1, e_2, e_3
    /// (12 values); empty for the others.
    std::vector<real_t> cells, cells_trial;
    /// Semi-Lagrangian blocks with reference resets: per particle the displacement at the last
    /// reset (3 values), then per particle its volume and step length then (2 n values), then
    /// the steps since (1 value); the tables are those of that configuration. Empty otherwise.
    std::vector<real_t> reference;

    /// The threshold lies between the table sizes at which the column cloud's force pass lost
    /// with the prefetches and those at which it gained; where it lies depends on the machine's
    /// caches (measurements: docs/performance.md).
    static constexpr std::size_t prefetch_bytes = std::size_t{12} << 20;

    // per-step scratch
    std::vector<real_t>
        point_tensor;         ///< gather assembly: 9 x (n_points + n_stab), V0 P by columns ([9 p + 3 j + a] = P_aj)
    std::vector<real_t> finv; ///< 9 x n_points: F^-1 (row-major), for the stabilization's own pass (empty without one)
    std::vector<real_t> spin; ///< 3 x n_points: W of the point (the same)
    /// n_points with stab_plastic_scaling on an inelastic block: the share of the step the point's
    /// material took elastically (assumed_strain_tangent_share), which its sub-points' loads take
    std::vector<real_t> stab_share;
    std::vector<real_t> batch_sums; ///< per batch of stress points x 4: d_int, d_bv, dt_min, NSNI's d_stab (nsni_batch)
    std::vector<index_t> batch_idx; ///< per batch x 2: the point of dt_min, the first bad point (-1: none)
    std::vector<real_t> stab_energy; ///< n_stab: stabilization work of each sub-cell (the own pass's; NSNI in the
                                     ///< points' batches sums it per batch)

    index_t n_points() const { return points.n_points(); }
    index_t n_stab() const { return stabilization.n_points(); }
    /// Builds the tables (build_tables) and sizes the state (zero stress, fresh history).
    void initialize(Assembly assembly = Assembly::Automatic);
    /// The tables only (shared stencils, which snap the operators, the node transposes, scatter
    /// chunks, per-step scratch), from the operators; the material state is not touched, so an
    /// operator that changed (a rebuilt neighbourhood) keeps its points' state.
    void build_tables(Assembly assembly = Assembly::Automatic);
    void commit()
    {
        stress.swap(stress_trial);
        stab_stress.swap(stab_stress_trial);
        cells.swap(cells_trial);
        if (plastic.active())
            plastic.commit();
    }

  private:
    NodalBlockOptions options_;
};

/// Stress points per batch of the force pass (one AVX-512 register of doubles); point state
/// is laid out in whole batches.
inline constexpr int kPointLanes = 8;
} // namespace rkfem
