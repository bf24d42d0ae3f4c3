#pragma once
/// @file check_report.hpp
/// What `rkfem check` prints after the resolved deck, as YAML comments (LS-DYNA's d3hsp analog):
/// every generated material parameter (K&C, CSCM, J2) with its unit, per part, and which part and
/// element set the time step.
#include <string>

namespace rkfem
{
class Model;

/// The report; evaluates the internal forces once at t = 0 for the stable step (the model is
/// left with that trial state, so call it on a model that will not run).
std::string check_report(Model& model);

/// Throws DeckError at time.end when the run would take more than 10^10 steps of the elements'
/// stable step (end: 1e30 s ran "forever"), unless time.max_steps bounds it. Reads the mesh only.
void check_step_budget(const Model& model);
} // namespace rkfem
