#pragma once
/// @file energy_ledger.hpp
/// The energy ledger of a run: the stored and dissipated energies, the work put in from outside
/// (loads, prescribed motion) and through contact, and the initial energies the balance is
/// measured from. The ledger starts once, at the first start of a stepper; a stepper started
/// again (after an event that changed the discretization, or any re-initialisation) continues it.
#include <vector>

#include "rkfem/core/types.hpp"
#include "rkfem/discretization/node_set.hpp"

namespace rkfem
{
struct Energies
{
    real_t kinetic = 0.0; ///< 1/2 m v.v at the full step
    /// -(dt^2 / 8) sum m a.a: turns `kinetic` into the leapfrog-consistent 1/2 m v(n-1/2).v(n+1/2),
    /// the kinetic energy that central difference conserves exactly for linear elasticity.
    real_t kinetic_correction = 0.0;
    real_t internal = 0.0;
    real_t hourglass = 0.0;
    real_t bulk_viscosity = 0.0;
    real_t damping = 0.0;       ///< dissipated by mass damping
    real_t external_work = 0.0; ///< loads and prescribed motion
    /// Sliding (contact) energy, LS-DYNA's sleout: minus the work the contact forces did on the
    /// nodes (stored in penalty springs while in contact, plus what friction dissipated).
    real_t contact = 0.0;
    /// Energy events took out of the mechanical system (erosion): at each event, the change of
    /// the leapfrog-consistent kinetic energy that the new accelerations make, with no work
    /// term behind it (the removed elements' last half impulse, book_event).
    real_t eroded = 0.0;
    real_t kinetic0 = 0.0, internal0 = 0.0; ///< leapfrog-consistent kinetic energy at t = 0

    real_t total() const { return kinetic + internal + hourglass + bulk_viscosity + contact; }
    /// |E_kin' + E_int + E_hg + E_bv + E_contact + E_damp + E_eroded - E_kin0' - E_int0 - W_ext| /
    /// max(energy scale), with E_kin' = kinetic + kinetic_correction (leapfrog-consistent kinetic
    /// energy)
    real_t balance_error() const;
    /// E_hg / (E_int + E_hg), 0 when there is no internal energy
    real_t hourglass_ratio() const;
    /// E_hg / total(), the seed's Table 3 energy ratio (LS-DYNA's glstat hourglass over total)
    real_t hourglass_to_total() const { return total() > 0 ? hourglass / total() : 0.0; }

    /// Records the initial energies from the current ones, the first time only: the start of a
    /// stepper calls it, and a restart in the middle of a run keeps the ledger's origin.
    void start()
    {
        if (started_)
            return;
        kinetic0 = kinetic + kinetic_correction;
        internal0 = internal;
        started_ = true;
    }
    bool started() const { return started_; }

    /// After an event that changed the forces at t(n+1) (accelerations a_old before, n.a after
    /// the stepper started again): the leapfrog-consistent kinetic energy 1/2 m v(n+1/2).v(n+3/2)
    /// now takes a_new where the ledger booked a_old, a change no work term accounts for. Books
    /// -1/2 sum m v(n+1/2) . (dt/2)(a_new - a_old) into `eroded`, v(n+1/2) = v - dt/2 a_old, dt
    /// the step that ended at the event; and sets the leapfrog correction of the kinetic energy
    /// from a_new (the restart measured it without one).
    void book_event(const NodeSet& n, const std::vector<real_t>& a_old, real_t dt);

  private:
    bool started_ = false;
};

/// What a force evaluation reports back to the stepper and the run loop.
struct ForceReport
{
    real_t dt_stable = kNoLimit; ///< before the scale factor
    index_t dt_element = -1;     ///< global element index controlling dt
};
} // namespace rkfem
