#pragma once
/// @file timoshenko_beam.hpp
/// Reference solution for cantilevers under a suddenly applied, held load (seed Problem 3): a
/// Timoshenko beam (shear deformation and rotary inertia) on many 2-node elements (linear w and
/// theta, shear integrated at one point, consistent mass), clamped at x = 0, solved by modal
/// superposition: w(x, t) = sum_i phi_i(x) phi_i . F (1 - cos(omega_i t)) / omega_i^2.
#include <vector>

#include "rkfem/core/types.hpp"

namespace rkfem
{
struct TimoshenkoBeam
{
    real_t E = 0.0, nu = 0.0, rho = 0.0;
    real_t width = 0.0, depth = 0.0, length = 0.0; ///< rectangular section width x depth
    real_t shear_factor = 0.0;                     ///< kappa; 0: Cowper's 10 (1 + nu) / (12 + 11 nu)
    int elements = 200;
};

struct StepResponse
{
    real_t static_tip = 0.0; ///< tip deflection under the held load
    real_t peak_tip = 0.0;   ///< largest tip deflection for t in [0, t_end]
    real_t peak_time = 0.0;
    real_t first_period = 0.0;
    std::vector<real_t> time, tip; ///< the tip history
};

/// A load per unit length q over x in [x0, length] (a pressure p on a patch of the top face:
/// q = p width), applied at t = 0 and held; the tip history sampled at n_samples times to t_end.
StepResponse step_response(const TimoshenkoBeam& beam, real_t q, real_t x0, real_t t_end, int n_samples = 20001);
} // namespace rkfem
