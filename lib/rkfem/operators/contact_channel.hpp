#pragma once
/// @file contact_channel.hpp
/// The channel contact forces reach the nodes through: unlike loads, whose dofs are fixed when
/// the model is built, contact touches different nodes every step. Each force evaluation starts
/// a pass (clear()), contact algorithms add their nodal forces, and the accelerations read `f`.
/// The work the forces do is booked by the trapezoid rule over the nodes touched at either end
/// of the step, so no full-size array of previous forces is kept: per step the cost is in
/// proportion to the nodes in contact, not to the model.
#include <vector>

#include "rkfem/core/types.hpp"

namespace rkfem
{
class StateArchive;
class KinematicMap;

class ContactChannel
{
  public:
    /// Forces then act at physical points: add() spreads a force at an RK particle's point to
    /// the coefficients of its row (null: every node carries its physical value).
    void set_map(const KinematicMap* map) { map_ = map; }
    /// Sizes the channel for n nodes, with no force anywhere. Its arrays (25 bytes a node) are
    /// allocated by the first force added, so a model without contact holds none; force()
    /// reads 0 until then.
    void resize(index_t n_nodes);
    /// Starts a force evaluation: zeroes the forces of this pass's nodes (the previous pass of the
    /// same step). The forces of the last committed step are kept for the work.
    void clear();
    /// Adds a force f acting at node i's physical point (serial: contact algorithms collect
    /// their forces, then add them); on RK particles it reaches the unknowns of the map's row.
    void add(index_t node, const Vec3& f);
    /// Nodes with a force in the current pass, in the order they were first touched.
    const std::vector<index_t>& nodes() const { return touched_; }
    bool empty() const { return touched_.empty() && prev_nodes_.empty(); }

    /// Work of the contact forces over a step, trapezoid in time: sum over dofs of
    /// 1/2 (f(n) + f(n+1)) . (u(n+1) - u(n)), f(n) the forces committed at the step's start.
    real_t step_work(const real_t* u, const real_t* u_prev) const;
    /// The current pass's forces become the step's start for the next step's work.
    void commit();
    /// The forces of this pass and of the last commit (a checkpoint's), and back.
    void save_state(StateArchive& archive) const;
    void load_state(const StateArchive& archive);

    std::vector<real_t>
        f; ///< 3 n, node-major, on the unknowns; zero on every node not in nodes(); empty before the first force
    /// f[j], and 0 before any force was added (f is empty until then)
    real_t force(std::size_t j) const { return f.empty() ? 0.0 : f[j]; }

  private:
    void add_unknown(index_t node, const Vec3& f);
    void allocate();
    index_t n_nodes_ = 0;
    const KinematicMap* map_ = nullptr;
    std::vector<index_t> touched_;
    std::vector<char> mark_;
    std::vector<index_t> prev_nodes_; ///< nodes touched at the last commit
    std::vector<real_t> prev_f_;      ///< their forces then, 3 per node
};
} // namespace rkfem
