#pragma once
/// @file hex_block.hpp
/// One block of 8-node hexahedra with one material and one formulation, and the element kernels
/// that integrate it (updated Lagrangian: gradients from current coordinates, every step).
///
/// Per-point arrays are component-major: component c of point p is at [c * n_points + p], where a
/// 1-point block has n_points = n_elements and a 2x2x2 block has point p = 8 e + g.
/// Nodal forces are assembled in a fixed order whatever the thread count: 1-point blocks scatter
/// each chunk of elements into a buffer of the chunk's own (ChunkedScatter); otherwise the
/// element force buffer, n_elements x 8 x 3 ([24 e + 3 I + d]), is gathered through the node ->
/// (element, local node) transpose CSR.
#include <vector>

#include "rkfem/core/huge_pages.hpp"

#include "rkfem/discretization/formulation.hpp"
#include "rkfem/discretization/node_set.hpp"
#include "rkfem/materials/elastic.hpp"
#include "rkfem/materials/point_history.hpp"
#include "rkfem/operators/bulk_viscosity.hpp"
#include "rkfem/operators/hourglass.hpp"
#include "rkfem/operators/kernels/chunked_scatter.hpp"

namespace rkfem
{
struct HexBlock
{
    index_t part = 0;
    Formulation formulation = Formulation::Fem1pt;
    HourglassSpec hourglass;
    BulkViscositySpec bulk_viscosity;
    ElasticParams material;
    PlasticPoints plastic; ///< J2 / K&C history per point (inactive for elastic blocks)
    /// The mesh of a part integrated elsewhere (a nodal block, a coupled part's FE side), kept
    /// for output, probes and events: conn, reference volumes and the node -> element transpose,
    /// no element state and no force tables.
    bool mesh_only = false;

    std::vector<index_t> conn; ///< n_elements x 8, global node ids
    index_t node_begin = 0;    ///< this block's nodes are [node_begin, node_end)
    index_t node_end = 0;
    std::vector<index_t> node_elem_offsets; ///< (node_end - node_begin + 1)
    std::vector<index_t> node_elem_slots;   ///< 8 e + I, for each node in order
    /// 1-point kernel with AVX-512 (batches of 8 elements): per full batch, 3 x node id of node I
    /// of element 8 b + l at [64 b + 8 I + l] (one load per node of the batch for the vector
    /// gathers); empty in builds without AVX-512
    std::vector<index_t> gather_index;

    // state (committed / trial), component-major
    /// component k of point p at [k stress_stride + p]; the stride is n_points rounded up to a
    /// multiple of 8, so every batch of 8 points is one cache line per component
    LineVector<real_t> stress, stress_trial; ///< 6 x stress_stride [Pa]
    std::size_t stress_stride = 0;
    /// The force pass may write the stress field with streaming stores (core/stream_stores.hpp,
    /// store_batch8; only past kStreamBytes, with the chunked scatter). Off: plain stores, the
    /// same values (verification compares the two).
    bool stream_stress = true;
    /// The stiffness forms' hourglass state, hg_rows() x n_elements: the 12 stored generalized
    /// forces [N], then (assumed strain) the element's 3 frame sizes when they were last updated
    /// [m] (0: never), from which the stored forces follow the change of their stiffness
    std::vector<real_t> hg_force, hg_force_trial;
    static constexpr int kHgSizeRow = 12; ///< the first frame-size row of hg_force (assumed strain)
    int hg_rows() const { return hourglass.type == HourglassType::AssumedStrain ? 15 : 12; }
    std::vector<real_t> volume0; ///< n_elements, reference volume [m^3]

    /// Scatter assembly of 1-point blocks (chunks of elements, see chunked_scatter.hpp); empty:
    /// elem_force and the transpose gather
    ChunkedScatter scatter;

    /// Elements no other element of the block shares a node with (build_tables)
    std::vector<index_t> isolated;

    // per-step scratch
    std::vector<real_t> elem_force; ///< n_elements x 24 [N] (gather assembly only)
    std::vector<real_t> batch_sums; ///< n_batches x 4: d_int, d_hg, d_bv, dt_min
    std::vector<index_t> batch_idx; ///< n_batches x 2: dt element, bad element

    index_t n_elements() const { return static_cast<index_t>(conn.size() / 8); }
    index_t points_per_element() const { return formulation == Formulation::Fem1pt ? 1 : 8; }
    index_t n_points() const { return n_elements() * points_per_element(); }

    /// Sizes state arrays (zero state) and builds the assembly tables. Nodes must already hold
    /// coordinates. 1-point blocks scatter by default (chunks of elements); 2x2x2 blocks always
    /// gather.
    void initialize(const NodeSet& nodes, Assembly assembly = Assembly::Automatic);
    /// The tables only (reference volumes, node -> element transpose, gather indices, scatter
    /// chunks, scratch), from conn and the nodes' reference coordinates; state is not touched.
    void build_tables(const NodeSet& nodes, Assembly assembly = Assembly::Automatic);
    /// An event between steps: keeps the elements with keep[e] != 0, in order, with their
    /// committed state (stress, hourglass forces, material history), and rebuilds the tables.
    void remove_elements(const std::vector<char>& keep, const NodeSet& nodes);
    /// Commits trial state.
    void commit()
    {
        stress.swap(stress_trial);
        hg_force.swap(hg_force_trial);
        if (plastic.active())
            plastic.commit();
    }
};

/// Sums and extrema from one internal-force pass over a block.
struct ForcePassResult
{
    real_t d_internal = 0.0;  ///< stress work this step [J]
    real_t d_hourglass = 0.0; ///< hourglass work this step [J]
    real_t d_bulk_viscosity = 0.0;
    real_t dt_stable = kNoLimit; ///< before the scale factor [s]
    index_t dt_element = -1;     ///< element that controls dt
    index_t bad_element = -1;    ///< first element with non-positive volume (or NaN), -1 if none
};

/// Internal force pass: velocity gradient from v at current x, material update into trial state,
/// element forces into blk.elem_force; assembly is separate (assemble_block_forces).
ForcePassResult hex_internal_force(HexBlock& blk, const NodeSet& nodes, real_t dt);

/// f_int[node] = sum over the node's (element, local) slots, for the block's node range. Once
/// per force pass: with the chunked scatter it consumes the chunk sums (ChunkedScatter::reduce).
/// With `add` the block's sums are added to f_int (blocks whose node ranges overlap: the
/// caller zeroes f_int once per evaluation and every block adds).
void assemble_block_forces(HexBlock& blk, NodeSet& nodes, bool add = false);

/// The current volume of element e (exact for the trilinear hex, from nodes.x) [m^3].
real_t element_volume(const HexBlock& blk, const NodeSet& nodes, index_t e);

/// The stable step of an element no other element shares a node with: its uniform dilation
/// (breathing) mode has omega = 2 c / L sqrt(3 K / M), above the 2 c / L of the step V / A_max / c
/// by sqrt((1 + nu) / (1 - nu)) (1.36 at nu 0.3), so it takes V / A_max / c sqrt(M / (3 K)).
real_t lone_element_step(const HexBlock& blk, const NodeSet& nodes, index_t e);

/// Lumped mass rho V0 / 8 to each node of each element (a degenerate solid: rho V0 / n to each of its n distinct
/// nodes).
void add_lumped_mass(const HexBlock& blk, NodeSet& nodes);
} // namespace rkfem
