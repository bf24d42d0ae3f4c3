#pragma once
/// @file convergence_study.hpp
/// A convergence sweep over nodal schemes with the manufactured solution: read from a YAML sweep
/// definition (studies/sweeps/*.yaml), run every case at every resolution, write
/// DIR/convergence.csv and DIR/convergence.h5 (one group per case, named by MmsCase::table_name:
/// n, h, dofs, l2, h1, l2_rate, h1_rate, seconds) that notebooks/convergence.ipynb plots.
///
///   title: ...
///   resolutions: [8, 16]          # elements per side of the unit cube
///   cases:
///     - {formulation: rkpm, scheme: scni | sd-scni | dni | snni | sd-snni, stabilization: 1,
///        normalized_support: 1.25,
///        support: box, kernel: cubic-bspline, boundary: traction | dirichlet,
///        solver: auto | direct | pcg}
/// stabilization: c_s of MSCNI (scni) or of the face-gradient term (snni); snni and sd-snni are the
/// semi-Lagrangian block's SNNI tables on its cells (manufactured_solution.hpp).
#include <string>
#include <vector>

#include "rkfem/analysis/manufactured_solution.hpp"

namespace rkfem
{
struct ConvergenceSweep
{
    std::string title;
    std::vector<int> resolutions;
    std::vector<MmsCase> cases;
};

/// Throws DeckError ("FILE:LINE: key: problem; expected") for bad input.
ConvergenceSweep read_sweep(const std::string& path);

/// Runs the sweep; writes the CSV and HDF5 tables into out_dir; prints one line per solve
/// unless quiet. Returns the results, case-major.
std::vector<std::vector<MmsResult>> run_sweep(const ConvergenceSweep& s, const std::string& out_dir, bool quiet);
} // namespace rkfem
