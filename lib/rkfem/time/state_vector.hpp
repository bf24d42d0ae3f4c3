#pragma once
/// @file state_vector.hpp
/// rkfem's N_Vector for the ARKODE steppers' state y = (u, v): two halves of n3 values each,
/// kept in the storages of one StatePool.
///
/// Fixed-step ERKStep in SUNDIALS 6.4.1 copies the whole state four times a step (the
/// interpolant's y_old, the stored right-hand side, y_n, the output vector) and takes a weighted
/// norm of it for a check that is moot at a fixed step (SUNDIALS 6.4.1 source: arkEvolve in
/// src/arkode/arkode.c, arkInterpUpdate_Hermite in src/arkode/arkode_interp.c). On a
/// 10^6-element model those passes cost more than half the element loop. Here
///  - a copy (N_VScale with c = 1) shares the storage, copy on write: an operation that writes a
///    vector whose storage is shared gives it a fresh storage from the pool first; it writes
///    every value, so nothing is copied;
///  - N_VConst only records the constant (materialized when a loop reads the vector), and a
///    weighted norm with constant weights c reads the vector only when c != 0;
///  - lend() moves a vector's halves into a NodeSet's u and v (std::vector swaps, no copy), so
///    the right-hand side works on the state in place; the storage takes a lent half back as
///    soon as an operation touches its values;
///  - the central-difference right-hand side's v' = (u' - v) / h is recorded, not stored
///    (overwrite_with_difference), and formed inside ERKStep's update z = y + h f.
/// Every loop is an rkfem -O3 OpenMP loop; reductions use the fixed-chunk sums of parallel.hpp,
/// so results do not depend on the thread count. Only the ARKODE stepper creates these vectors.
#include <memory>
#include <vector>

#include <sundials/sundials_nvector.h>

#include "rkfem/core/types.hpp"

namespace rkfem
{
struct StateStorage
{
    std::vector<real_t> half[2]; ///< u, v (n3 each)
    int refs = 0;                ///< vectors sharing it (and StateRefs holding it)
    /// Non-null: the v half is not written yet; its values are
    /// v_i = (u_i - diff_base->half[1][i]) * diff_scale (overwrite_with_difference). The storage
    /// holds a reference on diff_base until then.
    StateStorage* diff_base = nullptr;
    real_t diff_scale = 0.0;
};

class StatePool
{
  public:
    /// Vectors of 2 n3 values. Owned by shared_ptr: every vector of the pool holds it.
    static std::shared_ptr<StatePool> create(index_t n3);
    ~StatePool();
    StatePool(const StatePool&) = delete;
    StatePool& operator=(const StatePool&) = delete;

    /// A vector of this pool (ARKODE clones it), values 0.
    N_Vector make_vector(SUNContext ctx);
    index_t half_length() const { return n3_; }

    struct Halves
    {
        real_t* u;
        real_t* v;
    };
    /// y's values, for reading (a lent half is taken back, a constant is materialized).
    static Halves values(N_Vector y);
    /// y's values, for overwriting every entry: y gets a storage of its own first (its values
    /// are then undefined).
    static Halves overwrite(N_Vector y);
    /// For the central-difference right-hand side (u' = v(n+1/2), v' = (u' - v) / h): y's u half,
    /// for overwriting every entry; y's v half is recorded as (u'_i - x_v,i) * scale over x's v
    /// half, and written only when an operation reads it. The one operation that uses it,
    /// z = a x + b y (ERKStep's solution update), computes it on the fly: the update then reads
    /// three arrays, not four, and the right-hand side writes one, not two. Returns y's u.
    static real_t* overwrite_with_difference(N_Vector y, N_Vector x, real_t scale);

    /// Moves y's halves into u and v (swaps: u and v then hold y's values, y's storage holds
    /// the arrays u and v had). Ends an earlier lend first. The caller must not write them.
    void lend(N_Vector y, std::vector<real_t>& u, std::vector<real_t>& v);
    /// Gives the lent v half back to its storage (v gets its own array back); u stays lent.
    void return_v();
    /// Ends a lend leaving the lent values where they are: the NodeSet keeps the state, the
    /// storage keeps the arrays it got in exchange. For a pool about to go away.
    void detach();

    /// A reference that keeps a vector's current storage (and so its values) alive while ARKODE
    /// moves on: the stepper holds y(n) across a step, so the step's displacement increment
    /// needs no copy of u(n).
    class Ref
    {
      public:
        Ref() = default;
        explicit Ref(N_Vector y);
        Ref(Ref&& o) noexcept : pool_(std::move(o.pool_)), s_(o.s_) { o.s_ = nullptr; }
        Ref& operator=(Ref&& o) noexcept;
        ~Ref() { reset(); }
        void reset();
        /// The held values of half h (0: u, 1: v).
        const std::vector<real_t>& half(int h) const;

      private:
        std::shared_ptr<StatePool> pool_;
        StateStorage* s_ = nullptr;
    };

    /// Counters for tests and benchmarks.
    struct Counters
    {
        long storages = 0;                 ///< storages allocated so far (the pool's size)
        long passes = 0;                   ///< loops over all values of a vector (reads of a vector, writes)
        long shared_copies = 0;            ///< copies done by sharing a storage
        long fused_differences = 0;        ///< linear sums that computed a recorded v half on the fly
        long materialized_differences = 0; ///< recorded v halves written out because a loop read them
    };
    const Counters& counters() const { return counters_; }

    // ---- used by the vector operations (state_vector.cpp) ----
    StateStorage* acquire();
    void release(StateStorage* s);
    /// Ends the current lend (the storage takes its arrays back).
    void reclaim();
    bool is_lent(const StateStorage* s) const { return s != nullptr && s == lent_; }
    bool v_lent(const StateStorage* s) const { return is_lent(s) && lent_v_ != nullptr; }
    void count_pass(long n = 1) { counters_.passes += n; }
    void count_shared_copy() { ++counters_.shared_copies; }
    void count_difference(bool fused) { ++(fused ? counters_.fused_differences : counters_.materialized_differences); }

  private:
    explicit StatePool(index_t n3) : n3_(n3) {}
    index_t n3_;
    std::vector<std::unique_ptr<StateStorage>> all_;
    std::vector<StateStorage*> free_;
    StateStorage* lent_ = nullptr;
    std::vector<real_t>* lent_u_ = nullptr;
    std::vector<real_t>* lent_v_ = nullptr;
    Counters counters_;
    std::weak_ptr<StatePool> self_;
    friend class Ref;
};

/// True when y is a vector of a StatePool.
bool is_state_vector(N_Vector y);
} // namespace rkfem
