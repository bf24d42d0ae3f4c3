#pragma once
/// @file kinematic_map.hpp
/// The one map between a node set's unknowns and physical nodal values. On RK particles the
/// unknowns are generalized coefficients d_J and the physical value at particle I is
///   u^h(X_I) = sum_J Lambda_IJ d_J,   Lambda_IJ = Psi_J(X_I);
/// every other node carries its physical value (an identity row). A force f acting at the
/// physical point X_I reaches the unknowns through the transpose, f_J += Lambda_IJ f, so its
/// work is the same in either space. Boundary conditions, loads, output, probes and contact
/// read and write physical values only through this map; it is built once per discretization
/// (reference configuration) and rebuilt by events that change the particles.
///
/// Rows are stored as shared stencils are (integration/stencil_table.hpp): each row relative to
/// its first column, and the particles whose rows have the same column offsets and values within
/// 1e-11 of their largest (the translates of a lattice or of a structured mesh's layers: the P1
/// cylinder's particles along its axis) share one stored row, whose values they all read (the
/// first in node order: a share moves a value by at most that tolerance, the round-off of its
/// construction). A cloud's rows are its own.
#include <vector>

#include "rkfem/core/types.hpp"

namespace rkfem
{
class KinematicMap
{
  public:
    /// n nodes, all carrying physical values.
    void reset(index_t n_nodes);
    /// Rows for nodes [begin, end): row i - begin is entries [offsets[i - begin], offsets[i -
    /// begin + 1]) of (columns, values), columns global node ids. A node whose row is the single
    /// entry (i, 1) carries its physical value; `coefficient` (per node of the range, or null:
    /// every node whose row is not that identity) says which nodes carry coefficients.
    void set_rows(index_t begin, index_t end, const std::vector<index_t>& offsets, const std::vector<index_t>& columns,
                  const std::vector<real_t>& values, const std::vector<char>* coefficient = nullptr);

    index_t size() const { return static_cast<index_t>(coefficient_.size()); }
    bool carries_coefficients(index_t node) const { return coefficient_[static_cast<std::size_t>(node)] != 0; }
    bool identity() const { return n_coefficient_nodes_ == 0; }

    /// Calls f(column, Lambda) for the entries of node I's row (one entry (I, 1) where the node
    /// carries its physical value).
    template <class F> void for_row(index_t node, F&& f) const
    {
        const std::size_t i = static_cast<std::size_t>(node);
        if (!coefficient_[i])
        {
            f(node, 1.0);
            return;
        }
        const std::size_t r = static_cast<std::size_t>(row_[i]);
        const index_t base = base_[i];
        for (index_t k = row_offsets_[r]; k < row_offsets_[r + 1]; ++k)
            f(base + row_columns_[k], row_values_[k]);
    }
    /// The entries the map stores (shared rows once) and those its rows have in all.
    std::size_t stored_entries() const { return row_columns_.size(); }
    std::size_t row_entries() const { return n_row_entries_; }

    /// Physical value at node I of a node-major 3-vector field of unknowns (u, v).
    Vec3 physical(const real_t* field, index_t node) const;
    /// The same for every node, into out (3 n values; may not alias field).
    void physical_field(const std::vector<real_t>& field, std::vector<real_t>& out) const;
    /// Physical position x0 + u^h at node I (x0: the reference positions, u: the unknowns).
    Vec3 position(const std::vector<real_t>& x0, const std::vector<real_t>& u, index_t node) const;
    /// Adds a force f acting at the physical point X_I to a node-major force array of unknowns.
    void spread(index_t node, const Vec3& f, real_t* force) const;

  private:
    std::vector<char> coefficient_;
    std::vector<index_t> row_;            ///< per node carrying coefficients: its stored row
    std::vector<index_t> base_;           ///< per node carrying coefficients: the column its row counts from
    std::vector<index_t> row_offsets_{0}; ///< stored row r: entries [row_offsets_[r], row_offsets_[r + 1])
    std::vector<index_t> row_columns_;    ///< per entry: column - base
    std::vector<real_t> row_values_;
    std::size_t n_row_entries_ = 0;
    index_t n_coefficient_nodes_ = 0;
};
} // namespace rkfem
